"""bpmcal.report: the regenerated paper (or the user's rock) from the study's files
(``build``); the paper's published values are ``bpmcal.study.paper``."""
