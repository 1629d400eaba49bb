"""Multi-start bounded least squares of the relative residuals of regression models.

The shared solver of the inversion (:mod:`.inversion`) and of the "what to widen"
search (:mod:`.widen`): minimise Σ_k r_k², ``r_k = (model_k(x) - target_k) / |target_k|``,
over a box of the free parameters (``scipy.optimize.least_squares``, method ``trf``,
the models' analytic Jacobian), from the given points and seeded Latin-hypercube
starts in the unit cube. Every start's end point is kept (sum of squares, max |r|, x,
r), best first, so the caller can tell one solution from several and a bound from an
interior optimum.

The method: ``docs/methods/calibration.md`` (section "Inversion").
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import qmc

from .space import CalibrationSpace


def _fmt_pct(responses, r) -> str:
    return ", ".join(f"{name} {100 * v:+.2f} %" for name, v in zip(responses, r))


def _lhs(n: int, d: int, seed: int) -> np.ndarray:
    return qmc.LatinHypercube(d=d, seed=np.random.default_rng(seed)).random(n) if n > 0 else np.empty((0, d))


def _fit(space: CalibrationSpace, models, responses, t, lo, hi, x_starts, n_starts: int,
         seed: int) -> list[tuple]:
    """Multi-start bounded least squares of the relative residuals in the box [lo, hi] of the
    free parameters; one (sum of squares, max |r|, x, r) per start, best first."""
    width = hi - lo
    scale = np.abs(t)

    def resid_x(x):
        point = space.full(x)
        return (np.array([models[r].predict(point) for r in responses]) - t) / scale

    def resid(u):
        return resid_x(lo + u * width)

    def jac(u):
        return space.jacobian(models, responses, lo + u * width) * width / scale[:, None]

    starts = [np.clip((np.asarray(x, float) - lo) / width, 0.0, 1.0) for x in x_starts]
    starts += list(_lhs(int(n_starts), len(space.free), seed))
    if not starts:
        raise ValueError("no starting point: expected n_starts > 0 or x0")
    fits = []
    for u0 in starts:
        sol = least_squares(resid, u0, jac=jac, bounds=(0.0, 1.0), method="trf", xtol=1e-12, ftol=1e-12,
                            gtol=1e-12)
        u = np.clip(sol.x, 0.0, 1.0)
        r = resid(u)
        fits.append((float(r @ r), float(np.max(np.abs(r))), lo + u * width, r))
    fits.sort(key=lambda f: f[0])
    return fits

