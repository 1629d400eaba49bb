"""bpmcal.io: the files of bpmcal, below the lab: HDF5 run files (``h5``), atomic writes
(``atomic``), tables and figures (``tables``, ``figures``), material cards (``card``),
provenance, VTK export, safe names (``safe_names``), input/output checks (``checks``) and the
study's file contract (``study_files``)."""
