"""Fragments after a fracture test, the t10 breakage index and the JK breakage model.

- A *fragment* is a connected group of balls still joined by intact bonds
  (scipy.sparse.csgraph connected components on the intact-bond graph); an isolated ball
  is a fragment of one ball.
- Fragment size: the diameter of the sphere with the fragment's solid volume (the summed
  ball volumes), d = (6 V / pi)^(1/3).
- t10: mass percentage of fragments smaller than one tenth of the original size; the
  original size is the equivalent-sphere diameter of the specimen's solid volume (for the
  50 x 100 mm cylinder at n = 0.34: ~63 mm).
- Specific energy E_cs [kWh/t] = input energy / specimen mass (1 kWh/t = 3600 J/kg).
- JK breakage model (Napier-Munn et al. 1996): t10 = A (1 - exp(-b E_cs)), fitted by
  least squares; A x b is the usual hardness index.

Resolution: a fragment of t10 size contains about (t10 size / mean ball diameter)^3
balls; below ~30 balls t10 measures the ball size more than the rock (reported as
``balls_per_t10_fragment``).
"""
from __future__ import annotations

import math

import numpy as np

from ..exact_math import libm_exp, libm_pow

KWH_PER_T = 3600.0  # J/kg in 1 kWh/t


def fragments(n_balls: int, bond_i, bond_j, intact) -> np.ndarray:
    """Fragment label of every ball (connected components of the intact bonds)."""
    # scipy is imported here, not at module level: every DEM job imports this module (the
    # morphology of its run) and scipy.optimize alone costs ~0.35 s of start-up per job
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    bi = np.asarray(bond_i)[np.asarray(intact, bool)]
    bj = np.asarray(bond_j)[np.asarray(intact, bool)]
    g = coo_matrix((np.ones(bi.size), (bi, bj)), shape=(n_balls, n_balls))
    _, labels = connected_components(g, directed=False)
    return labels


def fragment_sizes(labels, radius, density: float) -> tuple[np.ndarray, np.ndarray]:
    """(mass [kg], equivalent-sphere diameter [m]) of every fragment."""
    vol = 4.0 / 3.0 * np.pi * libm_pow(radius, 3)
    v = np.bincount(labels, weights=vol)
    return v * density, libm_pow(6.0 * v / np.pi, 1.0 / 3.0)


def passing(mass, size, x) -> float:
    """Mass percentage of fragments smaller than size ``x``."""
    mass = np.asarray(mass, float)
    return 100.0 * float(mass[np.asarray(size) < x].sum() / mass.sum())


def t10(mass, size, original_size: float) -> float:
    """t10: mass % passing one tenth of the original size."""
    return passing(mass, size, original_size / 10.0)


def jk_model(ecs, A, b):
    return A * (1.0 - libm_exp(-b * np.asarray(ecs, float)))


def fit_jk(ecs, t10_values) -> dict:
    """Least-squares fit of t10 = A (1 - exp(-b Ecs)); A limited to (0, 100]."""
    from scipy.optimize import curve_fit

    x = np.asarray(ecs, float)
    y = np.asarray(t10_values, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 2:
        raise ValueError(f"JK fit needs at least 2 points, got {x.size}")
    a0 = min(100.0, max(1.0, 1.2 * y.max()))
    b0 = max(1e-3, -math.log(max(1e-6, 1 - min(0.99, y[np.argmax(x)] / a0))) / max(x.max(), 1e-9))
    (A, b), cov = curve_fit(jk_model, x, y, p0=(a0, b0), bounds=([1e-9, 1e-9], [100.0, np.inf]),
                            maxfev=20000)
    res = y - jk_model(x, A, b)
    ss = float(((y - y.mean()) ** 2).sum())
    return {"A": float(A), "b": float(b), "Ab": float(A * b),
            "A_se": float(math.sqrt(cov[0, 0])) if np.isfinite(cov[0, 0]) else math.nan,
            "b_se": float(math.sqrt(cov[1, 1])) if np.isfinite(cov[1, 1]) else math.nan,
            "r2": 1.0 - float((res ** 2).sum()) / ss if ss > 0 else math.nan,
            "n": int(x.size)}
