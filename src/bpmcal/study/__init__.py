"""bpmcal.study: the study's definition, below the analysis: config validation and the lab
table (``config``), the LHS design (``design``), the dataset gathered from run files
(``gather``), the strength-ratio sweep plan (``sweep``) and the paper's published values
(``paper``)."""
