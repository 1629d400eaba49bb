"""bpmcal.lab: the virtual rock laboratory: specimen genesis, the UCS, Brazilian, triaxial
and drop-hammer tests, fragments, resource budget. A test returns a result object
(``runner.LabRun``); writing it is a stage's job (``bpmcal.stages.runs``)."""
