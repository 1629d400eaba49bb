"""bpmcal: calibrated bonded-particle (DEM) models of rock from laboratory tests."""
__version__ = "0.1.0"
