"""bpmcal.io: HDF5 run files, VTK export, provenance, material cards."""
