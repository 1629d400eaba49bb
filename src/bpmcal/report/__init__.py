"""bpmcal.report: the regenerated paper - published values and the report builder."""
