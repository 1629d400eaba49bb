"""bpmcal.study: experimental design and dataset gathering for the calibration study."""
