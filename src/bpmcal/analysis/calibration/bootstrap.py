"""Bootstrap intervals of a calibration (:func:`bootstrap_intervals`).

Case resampling of the usable dataset rows (seeded): in each resample every model is
refitted with the terms selected on the full data (or re-selected, ``reselect``) and
the targets are inverted again, warm-started from the full-data solution. Percentile
intervals are reported for every calibrated parameter and for every response the
models predict at the full-data solution. Model-selection uncertainty is included only
with ``reselect``; a ``no-exact-fit`` calibration uses every resample's least-squares
compromise.

The method: ``docs/methods/calibration.md`` (section "Bootstrap").
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .._common import seed_from, usable_rows
from ..stepwise import RegressionModel, StepwiseRegression
from .inversion import InversionResult, Multistart, invert
from .space import SearchSpace, _check_targets


@dataclass
class BootstrapResults:
    """Outcome of :func:`bootstrap_intervals`.

    ``intervals``: one row per calibrated parameter (kind ``parameter``) and per response
    predicted at the full-data solution (kind ``response``): full-data estimate, bootstrap
    median, std, lower and upper percentile bound, number of resamples used. ``draws``: one
    row per resample. ``base``: the full-data :class:`InversionResult`.
    """

    base: InversionResult
    intervals: pd.DataFrame
    draws: pd.DataFrame
    level: float
    scheme: str
    rows: dict[str, int]

    @property
    def n_unreachable(self) -> int:
        return int((~self.draws["reachable"]).sum())

    def to_frame(self) -> pd.DataFrame:
        return self.intervals

    def summary(self) -> str:
        return "\n".join([
            f"Bootstrap ({self.scheme}): {len(self.draws)} resamples of {self.rows['n_used']} rows "
            f"({self.rows['n_dropped']} dropped), {100 * self.level:g} % percentile intervals; "
            f"{self.n_unreachable} resample(s) did not reach the targets and are excluded",
            f"full-data inversion: {self.base.status} - {self.base.message}", "", self.intervals.to_string()])


def bootstrap_intervals(df: pd.DataFrame, models: Mapping[str, RegressionModel],
                        targets: Mapping[str, float], fixed: Mapping[str, float],
                        space: SearchSpace, *, n_boot: int = 1000, level: float = 0.95,
                        seed: int = 0, reselect: StepwiseRegression | None = None,
                        candidates: Mapping[str, Sequence[str]] | None = None,
                        search: Multistart = Multistart(n_starts=0)) -> BootstrapResults:
    """Case-resampling bootstrap of the calibration (see the module docstring).

    ``models`` are the full-data models whose terms are refitted in every resample (or,
    with ``reselect``, re-selected from ``candidates``; use ``cv_folds=0`` there for
    speed). Each resample's inversion starts from the full-data solution plus
    ``search.n_starts`` Latin-hypercube points (``search.tol`` the residual that counts as
    met; each inversion's seed is drawn from ``seed``). ``space`` confines every inversion
    as in :func:`invert` (the design space, optionally narrowed).
    """
    if not isinstance(n_boot, (int, np.integer)) or n_boot < 2:
        raise ValueError(f"n_boot={n_boot!r}: expected an integer >= 2")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level={level!r}: expected a probability in (0, 1), e.g. 0.95")
    if reselect is not None and not candidates:
        raise ValueError("reselect needs candidates (response -> screened parameters)")
    responses, _ = _check_targets(targets, models)
    needed = list(dict.fromkeys([p for r in responses for p in models[r].params] + list(responses)
                                + [p for c in (candidates or {}).values() for p in c]))
    rows = usable_rows(df, needed)
    data = rows.data
    rng = np.random.default_rng(seed)
    base = invert(models, targets, fixed, space,
                  search=Multistart(seed=seed_from(rng), tol=search.tol))
    designs = {r: (models[r].design(data), data[r].to_numpy(float)) for r in responses}
    start = [{p: base.solution[p] for p in base.free}]
    recs = []
    for b in range(int(n_boot)):
        idx = rng.integers(0, len(data), len(data))
        if reselect is None:
            boot = {}
            for r in responses:
                X, y = designs[r]
                A = np.column_stack([np.ones(len(idx)), X[idx]])
                beta = np.linalg.lstsq(A, y[idx], rcond=None)[0]
                boot[r] = models[r].with_coefficients(beta[0], beta[1:])
        else:
            boot = reselect.fit(data.iloc[idx], {r: candidates[r] for r in responses}).final_models
        inv = invert(boot, targets, fixed, space,
                     search=Multistart(n_starts=search.n_starts, seed=seed_from(rng),
                                       tol=search.tol, diagnose=False),
                     x0=start)
        rec = {"resample": b, "status": inv.status, "reachable": inv.reachable}
        rec.update({p: inv.solution[p] for p in inv.free + inv.derived})
        rec.update({f"{r}@estimate": float(boot[r].predict(base.solution)) for r in responses})
        recs.append(rec)
    draws = pd.DataFrame.from_records(recs)
    q = [(1 - level) / 2, 1 - (1 - level) / 2]
    out = []
    quantities = [(p, "parameter", base.solution[p], p) for p in base.free + base.derived]
    quantities += [(r, "response", base.predicted[r], f"{r}@estimate") for r in responses]
    if base.status in ("no-exact-fit", "within-error"):
        # the targets cannot all be met: the calibrated set is the least-squares compromise,
        # and so is every resample's (an interior optimum, well defined): use those
        used = draws[draws["status"].isin(["ok", "non-unique", "no-exact-fit", "within-error"])]
    else:
        used = draws[draws["reachable"]]
    for name, kind, est, col in quantities:
        v = (used if kind == "parameter" else draws)[col].to_numpy(float)
        lo, hi = np.quantile(v, q) if len(v) else (np.nan, np.nan)
        out.append({"quantity": name, "kind": kind, "estimate": est,
                    "median": np.median(v) if len(v) else np.nan,
                    "std": np.std(v, ddof=1) if len(v) > 1 else np.nan,
                    "lower": lo, "upper": hi, "n": len(v)})
    scheme = ("case resampling, selection re-run in every resample" if reselect is not None
              else "case resampling, terms fixed at the full-data selection")
    return BootstrapResults(base=base, intervals=pd.DataFrame.from_records(out).set_index("quantity"),
                            draws=draws, level=float(level), scheme=scheme, rows=rows.describe())

