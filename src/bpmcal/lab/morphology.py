"""Failure morphology from the crack positions and the bonds of a run: where the specimen
fails, along which plane, and into how many pieces. Pure functions (numpy in, numbers
out), applied to every UCS, triaxial and Brazilian run (``run_summary``).

Definitions (a crack is a broken bond located at its contact point, ``Model.breaks()``):

- **Crack heights** ``h = (z - z_bottom) / H`` along the loading axis (the cylinder axis;
  for a Brazilian disc the loaded diameter, ``h = (y - y_c + D/2) / D``).
  ``height_median`` is the median of ``h``; ``height_bottom_third`` / ``height_top_third``
  / ``height_middle_third`` the fractions of the cracks in each third; ``location`` says
  where the median lies: ``"bottom"`` (h < 0.4), ``"top"`` (h > 0.6) or ``"middle"``.
- **Principal fracture plane**: a robust plane fit to the crack positions. RANSAC
  (``n_trials`` planes through three cracks drawn with a seeded generator; the plane with
  the most cracks within ``half_thickness`` of it wins), then refined by principal
  component analysis of its inliers (the normal is the direction of least spread),
  re-selecting the inliers and repeating until they no longer change (at most 10 times).
  Deterministic for a given seed. Reported:
  ``plane_dip_deg``, the angle between the plane and the plane normal to the loading axis
  (0: a horizontal plane parallel to the platens; 90: an axial split; a UCS shear band in
  rock typically dips 55-75 degrees), ``plane_angle_to_axis_deg = 90 - dip``;
  ``plane_axis_height``, the height h at which the plane crosses the specimen's axis
  (NaN for a plane parallel to it); ``plane_offset``, the distance of the plane from the
  specimen's centre over D; ``plane_fraction``, the share of the cracks on it (how
  localised the failure is); ``plane_h_lo`` / ``plane_h_hi``, the 5th and 95th
  percentiles of the heights of its cracks (the extent of the fracture: a band "from an
  end face toward the middle of the side" runs from h ~ 0 or 1 to h ~ 0.5);
  ``plane_rms``, the rms distance of its cracks from it over D.
- **Fragments** at the end of the test: connected groups of balls still joined by intact
  bonds (``fragments.fragments``); ``fragments`` counts those of at least
  ``min_fraction`` (1 %) of the specimen's solid volume, ``largest_fragment`` is the
  volume fraction of the largest, ``detached_balls`` the balls without any intact bond.

The plane is fitted to the cracks formed from the peak to the end of the test (the
macro-fracture forms after the peak; the cracks before it are diffuse), or to all cracks
of the loading when fewer than ``MIN_CRACKS`` formed after the peak.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exact_math import libm_pow
from .fragments import fragments as fragment_labels

#: fewest cracks a plane is fitted to (NaN below)
MIN_CRACKS = 20


def crack_heights(coord, low: float, length: float) -> np.ndarray:
    """Normalised positions ``(coord - low) / length`` along the loading axis."""
    if not (length > 0 and math.isfinite(length)):
        raise ValueError(f"length={length!r}: expected a positive length")
    return (np.asarray(coord, float) - float(low)) / float(length)


def height_distribution(h) -> dict:
    """Median and thirds of normalised crack heights ``h`` (module docstring)."""
    h = np.asarray(h, float)
    if h.size == 0:
        return {"height_median": math.nan, "height_bottom_third": math.nan,
                "height_middle_third": math.nan, "height_top_third": math.nan,
                "location": "none"}
    med = float(np.median(h))
    bot = float(np.mean(h < 1.0 / 3.0))
    top = float(np.mean(h > 2.0 / 3.0))
    return {"height_median": med, "height_bottom_third": bot,
            "height_middle_third": 1.0 - bot - top, "height_top_third": top,
            "location": "bottom" if med < 0.4 else "top" if med > 0.6 else "middle"}


def _pca_plane(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c = p.mean(axis=0)
    w, v = np.linalg.eigh(np.cov((p - c).T))
    return v[:, 0], c  # eigenvalues ascending: the normal is the least-spread direction


def fit_plane(points, half_thickness: float, *, n_trials: int = 400, seed: int = 0) -> dict:
    """Robust plane through a cloud of points (RANSAC + PCA refinement, module docstring).

    Returns ``normal`` (unit; its sign fixed so that its z component is >= 0, else its y,
    else its x component), ``centre`` (mean of the inliers), ``inliers`` (bool mask),
    ``fraction`` (of the points that are inliers) and ``rms`` (rms distance of the
    inliers from the plane)."""
    p = np.asarray(points, float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points: expected an (n, 3) array, got shape {p.shape}")
    if not (half_thickness > 0):
        raise ValueError(f"half_thickness={half_thickness!r}: expected > 0")
    n = p.shape[0]
    if n < 3:
        raise ValueError(f"{n} point(s): a plane needs at least 3")
    rng = np.random.default_rng(seed)
    idx = np.array([rng.choice(n, 3, replace=False) for _ in range(int(n_trials))])
    a, b, c = p[idx[:, 0]], p[idx[:, 1]], p[idx[:, 2]]
    nrm = np.cross(b - a, c - a)
    ln = np.linalg.norm(nrm, axis=1)
    ok = ln > 1e-12 * max(1.0, float(np.abs(p).max()) ** 2)
    best, best_count = None, -1
    for k in np.flatnonzero(ok):
        u = nrm[k] / ln[k]
        count = int(np.count_nonzero(np.abs((p - a[k]) @ u) <= half_thickness))
        if count > best_count:
            best, best_count = (u, a[k]), count
    if best is None:  # all triples collinear
        u, c0 = _pca_plane(p)
    else:
        u, c0 = best
    inl = np.abs((p - c0) @ u) <= half_thickness
    for _ in range(10):
        if inl.sum() < 3:
            break
        u, c0 = _pca_plane(p[inl])
        new = np.abs((p - c0) @ u) <= half_thickness
        if np.array_equal(new, inl):
            break
        inl = new
    for comp in (2, 1, 0):
        if abs(u[comp]) > 1e-12:
            if u[comp] < 0:
                u = -u
            break
    d = (p[inl] - c0) @ u
    return {"normal": u, "centre": c0, "inliers": inl, "fraction": float(inl.mean()),
            "rms": float(np.sqrt(np.mean(d * d))) if inl.any() else math.nan}


def plane_geometry(normal, centre, axis: int, low: float, length: float,
                   centre_point) -> dict:
    """Dip, axis crossing height and offset of a plane in a specimen whose loading axis is
    coordinate ``axis`` (0, 1, 2), running from ``low`` over ``length``, with its centre
    (a point on the axis at mid-length) ``centre_point``."""
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    c = np.asarray(centre, float)
    o = np.asarray(centre_point, float)
    na = abs(float(n[axis]))
    dip = math.degrees(math.acos(min(1.0, na)))
    # the axis line: o + t e_axis; n.(o + t e - c) = 0 -> t = n.(c - o) / n_axis
    if na > 1e-9:
        t = float(n @ (c - o)) / float(n[axis])
        h_axis = (o[axis] + t - low) / length
    else:
        h_axis = math.nan
    return {"plane_dip_deg": dip, "plane_angle_to_axis_deg": 90.0 - dip,
            "plane_axis_height": h_axis,
            "plane_offset": abs(float(n @ (c - o))) / length}


def fragment_stats(n_balls: int, bond_i, bond_j, intact, radius,
                   min_fraction: float = 0.01) -> dict:
    """Fragments at the end of a test (module docstring)."""
    labels = fragment_labels(int(n_balls), bond_i, bond_j, intact)
    vol = np.bincount(labels, weights=libm_pow(np.asarray(radius, float), 3))
    frac = vol / vol.sum()
    sizes = np.bincount(labels)
    return {"fragments": int(np.count_nonzero(frac >= min_fraction)),
            "largest_fragment": float(frac.max()),
            "detached_balls": int(np.count_nonzero(sizes == 1))}


@dataclass(frozen=True)
class Frame:
    """Where a specimen's cracks are measured: the loading ``axis`` (0, 1, 2), the
    specimen's extent along it (``low``, ``length``), its ``centre_point``, its ``width``
    (the diameter: ``plane_offset`` and ``plane_rms`` are in units of it) and the
    fracture plane's ``half_thickness`` (the fit's band) [m]."""

    axis: int
    low: float
    length: float
    centre_point: tuple
    width: float
    half_thickness: float


def run_summary(cracks: dict, peak_step: int, frame: Frame, *, n_balls: int, bond_i, bond_j,
                bond_state, radius, seed: int = 0) -> dict:
    """All morphology metrics of one run (module docstring). ``cracks``: the run's crack
    events (``pos``, ``step`` relative to the start of loading; genesis cracks, step < 0,
    are left out); ``peak_step`` the step of the peak; ``frame`` the specimen's loading
    frame (:class:`Frame`); ``bond_state`` 0 for intact bonds."""
    axis, low, length = frame.axis, frame.low, frame.length
    centre_point, width, half_thickness = frame.centre_point, frame.width, frame.half_thickness
    pos = np.asarray(cracks["pos"], float).reshape(-1, 3)
    step = np.asarray(cracks["step"])
    loading = step >= 0
    h_all = crack_heights(pos[loading, axis], low, length)
    out = {f"crack_{k}": v for k, v in height_distribution(h_all).items()}
    h_pre = crack_heights(pos[loading & (step <= peak_step), axis], low, length)
    out["crack_height_median_peak"] = height_distribution(h_pre)["height_median"]
    post = loading & (step >= peak_step)
    use = post if np.count_nonzero(post) >= MIN_CRACKS else loading
    keys = ("plane_dip_deg", "plane_angle_to_axis_deg", "plane_axis_height", "plane_offset",
            "plane_fraction", "plane_h_lo", "plane_h_hi", "plane_rms")
    if np.count_nonzero(use) >= MIN_CRACKS:
        fit = fit_plane(pos[use], half_thickness, seed=seed)
        g = plane_geometry(fit["normal"], fit["centre"], axis, low, length, centre_point)
        g["plane_offset"] = g["plane_offset"] * length / width
        hp = crack_heights(pos[use][fit["inliers"], axis], low, length)
        g.update({"plane_fraction": fit["fraction"],
                  "plane_h_lo": float(np.percentile(hp, 5)),
                  "plane_h_hi": float(np.percentile(hp, 95)),
                  "plane_rms": fit["rms"] / width})
        out.update(g)
        out["plane_cracks"] = "post-peak" if use is post else "all"
    else:
        out.update({k: math.nan for k in keys})
        out["plane_cracks"] = "none"
    out.update(fragment_stats(n_balls, bond_i, bond_j, np.asarray(bond_state) == 0, radius))
    return out
