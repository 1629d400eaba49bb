"""Whether the regression's miss is a limit of the model or the regression's own error
(:func:`reach_within_error`).

The inversion (:func:`~.inversion.invert`) solves the regression models as if they were
exact. They are not: each predicts a new DEM run only to its prediction error (the
residual scatter of the design runs about the fit, which holds the packing scatter and
the lack of fit, plus the coefficients' uncertainty: the ordinary least-squares
prediction interval of a new observation). A lab value is itself one specimen (or a mean
with the lab's standard error). So the question a ``no-exact-fit`` or ``unreachable``
answers is a test:

    χ²(θ) = Σ_r (model_r(θ) - target_r)² / (sd_obs,r(θ)² + se_r²),   θ in the bounds

If a card inside the bounds produced the targets, χ² there would follow the χ²
distribution with one degree of freedom per target, and its minimum over the bounds can
only be smaller; ``p_reach`` = P(χ²_k ≥ min χ²) is the probability that targets this far
from the models' reach arise from a card inside the bounds. Below :data:`REACH_ALPHA`
the targets are out of reach (``no-exact-fit`` or ``unreachable`` with the probability
stated); at or above it the miss is within the models' own error (``within-error``: the
closed loop, which measures the DEM, decides).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import minimize
from scipy.stats import chi2

from .._common import usable_rows
from ..stepwise import RegressionModel, design_matrix
from .fit import _lhs
from .space import CalibrationSpace

#: below this probability of reach the targets are out of the models' reach
REACH_ALPHA = 0.05


@dataclass(frozen=True)
class PredictionError:
    """A stepwise model's prediction error for a new run: ``cov`` the covariance of its
    coefficients (intercept first) and ``scale`` the residual variance, from an ordinary
    least-squares refit of its terms on the dataset (``n`` runs)."""

    model: RegressionModel
    cov: np.ndarray
    scale: float
    n: int

    def sd(self, point: Mapping[str, float]) -> float:
        """The sd of a new DEM run's response at ``point`` (the prediction interval's)."""
        x = np.concatenate([[1.0], design_matrix(point, self.model.terms)[0]]) \
            if self.model.terms else np.array([1.0])
        return float(math.sqrt(max(self.scale + x @ self.cov @ x, 0.0)))


def prediction_errors(df: pd.DataFrame, models: Mapping[str, RegressionModel]
                      ) -> dict[str, PredictionError]:
    """Every model's :class:`PredictionError` from the dataset it was fitted on (its usable
    rows: status ok, finite values)."""
    out = {}
    for r, m in models.items():
        if r not in df.columns:
            continue
        rows = usable_rows(df, list(m.params) + [r]).data
        X = np.column_stack([np.ones(len(rows)), design_matrix(rows, m.terms)]) \
            if m.terms else np.ones((len(rows), 1))
        y = np.asarray(rows[r], float)
        if len(y) <= X.shape[1]:
            continue
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        res = y - X @ beta
        s2 = float(res @ res / (len(y) - X.shape[1]))
        cov = s2 * np.linalg.pinv(X.T @ X)
        out[r] = PredictionError(m, cov, s2, len(y))
    return out


def reach_within_error(space: CalibrationSpace, models: Mapping[str, RegressionModel],
                       errors: Mapping[str, PredictionError], targets: Mapping[str, float],
                       target_se: Mapping[str, float] | None, x_starts, *, n_starts: int = 8,
                       seed: int = 0) -> dict:
    """The χ² test of the module docstring over the space's bounds, from ``x_starts`` (the
    inversion's best fit) and ``n_starts`` seeded Latin-hypercube points. Returns
    ``chi2_min``, ``dof``, ``p_reach``, ``reachable``, the point and each target's
    standardised miss there (``z``), or ``{}`` when a target has no prediction error."""
    resp = [r for r in targets]
    if any(r not in errors for r in resp):
        return {}
    se = {r: float((target_se or {}).get(r, 0.0) or 0.0) for r in resp}
    t = np.array([float(targets[r]) for r in resp])
    lo, width = space.lo, space.width

    def terms(u):
        point = space.full(lo + np.clip(u, 0.0, 1.0) * width)
        pred = np.array([models[r].predict(point) for r in resp])
        sd = np.array([math.hypot(errors[r].sd(point), se[r]) for r in resp])
        return (pred - t) / sd

    def f(u):
        z = terms(u)
        return float(z @ z)

    starts = [np.clip((np.asarray(x, float) - lo) / width, 0, 1) for x in x_starts]
    starts += list(_lhs(n_starts, len(space.free), seed))
    best = None
    for u0 in starts:
        res = minimize(f, u0, method="L-BFGS-B", bounds=[(0.0, 1.0)] * len(space.free))
        if best is None or res.fun < best.fun:
            best = res
    p = float(chi2.sf(best.fun, len(resp)))
    u = np.clip(best.x, 0.0, 1.0)
    return {"chi2_min": float(best.fun), "dof": len(resp), "p_reach": p,
            "reachable": p >= REACH_ALPHA, "alpha": REACH_ALPHA,
            "point": {k: float(v) for k, v in zip(space.free, lo + u * width)},
            "z": {r: float(v) for r, v in zip(resp, terms(u))}}


def reach_text(reach: dict) -> str:
    """The sentence a card's message gets from :func:`reach_within_error`."""
    zs = ", ".join(f"{r} {v:+.1f} sd" for r, v in reach["z"].items())
    if reach["reachable"]:
        return (f"the miss is within the models' own prediction error (the best card inside "
                f"the bounds misses by {zs}; χ² = {reach['chi2_min']:.2f} on {reach['dof']} "
                f"targets, p = {reach['p_reach']:.2f} that a card inside the bounds misses "
                "this far): the regression cannot tell, the closed loop decides")
    return (f"the targets are out of reach counting the models' own prediction error: the "
            f"best card inside the bounds misses by {zs} (χ² = {reach['chi2_min']:.1f} on "
            f"{reach['dof']} targets, p = {reach['p_reach']:.2g} that a card inside the bounds "
            "misses this far)")
