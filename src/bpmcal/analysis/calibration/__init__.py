"""Calibration of the meso-parameters from laboratory targets (paper section 4.2):
inversion of the regression models, bootstrap uncertainty and a closed-loop corrector.

The method, with every rule and default, is described in ``docs/methods/calibration.md``.
The package holds one concept per module:

- :mod:`.space` — the calibration space (:class:`CalibrationSpace`: free, fixed and
  derived parameters, bounds and where they come from, the unit cube),
  :func:`bts_strengths`, :func:`check_calibration_space`;
- :mod:`.fit` — the multi-start bounded least squares shared by the next two;
- :mod:`.inversion` — :func:`invert` → :class:`InversionResult`;
- :mod:`.widen` — which configured limit to widen when the targets are out of reach;
- :mod:`.bootstrap` — :func:`bootstrap_intervals` → :class:`BootstrapResults`;
- :mod:`.loop_settings` — :class:`LoopSettings`, every option of a closed loop on the
  DEM as one validated value, and the one table of their limits;
- :mod:`.closed_loop` — :class:`ClosedLoop` → :class:`ClosedLoopResult`, the loop's
  driver; its step rule (the Jacobian, its updates, the step and the trust region) in
  :mod:`.step_rule`, its seed-set policy (the seeds a round runs, its judgement, when
  the set grows) in :mod:`.seed_policy`;
- :mod:`.scatter` — :func:`scatter_table`, the packing-seed noise floor of a tolerance
  (the seed scatter job that runs the DEM for it is ``bpmcal.stages.seed_scatter``).
"""
from .bootstrap import BootstrapResults, bootstrap_intervals
from .closed_loop import ClosedLoop, ClosedLoopResult, LoopSeeds, LoopSteps
from .inversion import InversionResult, Multistart, invert
from .loop_settings import UPDATES, LoopSettings
from .scatter import scatter_table
from .space import (
    DEFAULT_FREE,
    PAPER_FIXED,
    PAPER_RATIO,
    CalibrationSpace,
    SearchSpace,
    bts_strengths,
    check_calibration_space,
    tensile_target,
)

__all__ = ["UPDATES", "PAPER_RATIO", "PAPER_FIXED", "DEFAULT_FREE", "tensile_target", "bts_strengths",
           "CalibrationSpace", "check_calibration_space", "InversionResult", "Multistart", "invert",
           "BootstrapResults",
           "bootstrap_intervals", "ClosedLoop", "ClosedLoopResult", "LoopSeeds", "LoopSteps", "SearchSpace",
           "LoopSettings", "scatter_table"]
