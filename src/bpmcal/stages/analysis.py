"""The former single module of the calibration stages, now one module per job family;
every name is re-exported here so that ``bpmcal.stages.analysis`` keeps working:

- :mod:`.screening` — :func:`screen`, :func:`tensile_note`;
- :mod:`.regression` — :func:`regress`;
- :mod:`.calibration` — :func:`calibrate`, :func:`chosen_ratio`, :func:`lab_targets`,
  :func:`note_is_fallback`;
- :mod:`.verification` — :func:`verify`, :func:`seed_scatter`,
  :func:`verification_tables`, :func:`disc_geometry`, :func:`valid_tensile_run`,
  :func:`valid_bts_run` (the DEM runners are looked up there: patch
  ``bpmcal.stages.verification.run_ucs_file`` etc., not this module);
- :mod:`.transfer` — :func:`transfer`, :func:`scatter_factor`, :func:`transfer_table`.

New code imports from those modules.
"""
from ..io.checks import BadInput
from .calibration import calibrate, chosen_ratio, lab_targets, note_is_fallback
from .regression import regress
from .screening import screen, tensile_note
from .transfer import scatter_factor, transfer, transfer_table
from .verification import (
    BTS_MAX_REPLACEMENTS,
    BTS_REPLACEMENT_STRIDE,
    disc_geometry,
    seed_scatter,
    valid_bts_run,
    valid_tensile_run,
    verification_tables,
    verify,
)

__all__ = ["BadInput", "screen", "tensile_note", "regress", "calibrate", "chosen_ratio", "lab_targets",
           "note_is_fallback", "verify", "seed_scatter", "verification_tables", "disc_geometry",
           "valid_tensile_run", "valid_bts_run", "BTS_REPLACEMENT_STRIDE", "BTS_MAX_REPLACEMENTS",
           "transfer", "scatter_factor", "transfer_table"]
