"""Statistical analysis of the LHS dataset (paper sections 3, 4.1, 4.2).

- :mod:`.screening` — cross-validated XGBoost importance screening with a shadow-feature
  noise reference (Table 3); :class:`XGBScreening` → :class:`ScreeningResults`.
- :mod:`.stepwise` — three-stage bidirectional stepwise polynomial regression with VIF and
  hierarchy rules (Table 4, the regression equations); :class:`StepwiseRegression` →
  :class:`StepwiseResults` of :class:`RegressionModel` objects.
- :mod:`.calibration` — inversion of the models for lab targets (:func:`invert`),
  bootstrap intervals (:func:`bootstrap_intervals`), Newton-Broyden closed loop with the
  simulator (:class:`ClosedLoop`) and the scatter table of a tolerance against the
  packing-seed noise (:func:`scatter_table`); a package, its method in
  ``docs/methods/calibration.md``.

Each analysis uses only dataset rows with ``status == "ok"`` and reports how many it dropped.
"""
from .calibration import (
    DEFAULT_FREE,
    PAPER_FIXED,
    PAPER_RATIO,
    BootstrapResults,
    ClosedLoop,
    ClosedLoopResult,
    InversionResult,
    bootstrap_intervals,
    invert,
    scatter_table,
)
from .screening import (
    DEFAULT_XGB_PARAMS,
    IMPORTANCE_TYPES,
    ScreeningResults,
    XGBScreening,
    table3,
    table3_markdown,
)
from .stepwise import (
    STAGES,
    RegressionModel,
    StepwiseRegression,
    StepwiseResults,
    fit_terms,
    models_from_dict,
    vif,
)

__all__ = [
    "XGBScreening", "ScreeningResults", "table3", "table3_markdown", "IMPORTANCE_TYPES", "DEFAULT_XGB_PARAMS",
    "StepwiseRegression", "StepwiseResults", "RegressionModel", "fit_terms", "models_from_dict", "vif",
    "STAGES", "invert", "InversionResult", "bootstrap_intervals", "BootstrapResults", "ClosedLoop",
    "ClosedLoopResult", "scatter_table", "PAPER_RATIO", "PAPER_FIXED", "DEFAULT_FREE",
]
