"""bpmcal.lab: the virtual rock laboratory: specimen genesis, the UCS, Brazilian,
direct-tension, triaxial and drop-hammer tests (the quasi-static ones on one driver,
``driver``; every test in one registry, ``registry``), the one seed scheme (``seeds``),
fragments, resource budget. A test returns a result object (``runner.LabRun``); writing it
is a stage's job (``bpmcal.stages.runs``)."""
