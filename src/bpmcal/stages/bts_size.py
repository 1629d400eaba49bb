"""σt at the lab's disc size (rule ``bts_size``): a verified card's Brazilian σt measured on
discs of a few diameters, its size curve fitted, and σt at the diameter of the lab's discs
(``bts_diameter_mm`` of the lab CSV) compared with the lab's σt.

Why: σt of a bonded disc falls with the disc's size (A1: 50 mm discs read 0.87 and 0.94
of the study's 27.5 mm disc on two sets of packings;
docs/measurements/2026-12-02-bts-disc-size.md), and the closed loop fits σt on the study's
disc (``bts.scale``), whatever disc the lab used. A lab row that names its disc's diameter
is compared here at that diameter.

The sizes (:func:`sizes_of`): the study's disc (as the card is tested on it: a
flat-jointed card's enlarged to its fewest balls across, ``lab.brazilian.resolved_disc``),
the lab's, and with ``middle`` their geometric mean; the other sizes are not enlarged.
Every disc is the study's (its loading, its genesis, the card's balls: a
larger disc has more balls across) with the contact cap scaled with the diameter from the
study's disc (``lab.brazilian.similar_contact_cap``: the same share of D on every disc;
the study's own disc keeps its cap), each seed's test run as the study runs it (an invalid
disc retested, ``bts.retests``). The seeds: ``seeds`` at every size, then one more at a
size while the standard error of its mean exceeds ``target_se`` of the mean, up to
``max_seeds`` (:class:`SizeSettings`); packing seeds ``first_seed`` + i.

The curve (:func:`fit_power_law`): σt = σ_ref (D / D_ref)^-k over the sizes with at least
two valid discs, D_ref the study's disc, weighted least squares of ln σt on ln D with each
size's standard error (the relative SE of the mean, the SE of its log); the parameters'
covariance is that of the weights, scaled up by the reduced χ² when there are more sizes
than parameters and the points scatter more than their errors. Two sizes give the exact
interpolation through both.

σt at the lab's size (:func:`sigma_at`): the lab's size's own mean and SE when it was
measured (``measured``), else the curve's value and its SE (``interpolated`` between the
measured sizes, ``extrapolated`` outside them); the table says which.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from ..dem.errors import InputError
from ..io.card import card_parameters, read_card
from ..io.checks import BadInput
from ..io.tables import write_table
from ..lab.brazilian import BTSSettings, resolved_disc, similar_contact_cap
from ..lab.run_context import RunContext
from ..lab.runner import Geometry
from ..params import BTS, validate_params
from .measure import RUNNERS

#: the lab's size is "the same" as a measured one within this relative difference
SAME_SIZE = 1e-6


@dataclass(frozen=True)
class SizeSettings:
    """How many seeds measure σt at each size (module docstring)."""

    seeds: int = 5
    max_seeds: int = 12
    target_se: float = 0.02
    first_seed: int = 301
    middle: bool = True

    def __post_init__(self):
        whole = (lambda v: isinstance(v, (int, np.integer)) and not isinstance(v, bool))
        if not (whole(self.seeds) and 2 <= self.seeds <= 1000):
            raise BadInput(f"seeds={self.seeds!r}: expected a whole number of seeds in "
                           "[2, 1000] per size")
        if not (whole(self.max_seeds) and self.seeds <= self.max_seeds <= 1000):
            raise BadInput(f"max_seeds={self.max_seeds!r}: expected a whole number in "
                           f"[seeds={self.seeds}, 1000]")
        if not (isinstance(self.target_se, (int, float)) and 0 < self.target_se < 1):
            raise BadInput(f"target_se={self.target_se!r}: expected a relative standard "
                           "error in (0, 1)")
        if not (whole(self.first_seed) and 0 <= self.first_seed
                and self.first_seed + self.max_seeds < 2 ** 32):
            raise BadInput(f"first_seed={self.first_seed!r}: expected a packing seed in "
                           f"[0, 2^32 - max_seeds)")


def sizes_of(study_mm: float, lab_mm: float, middle: bool = True) -> list[float]:
    """The disc diameters [mm] measured: the study's, the lab's and, with ``middle``, their
    geometric mean; in increasing order, the study's first among equals."""
    for name, v in (("the study's disc", study_mm), ("the lab's disc", lab_mm)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise BadInput(f"{name}: diameter {v!r} mm; expected a positive number")
    if abs(lab_mm - study_mm) <= SAME_SIZE * study_mm:
        return [float(study_mm)]
    sizes = [float(study_mm), float(lab_mm)]
    if middle:
        sizes.append(math.sqrt(study_mm * lab_mm))
    return sorted(sizes)


def fit_power_law(diameter_mm, mean, se, reference_mm: float) -> dict:
    """σt = sigma_ref (D / reference)^-k fitted to sizes ``diameter_mm`` with means ``mean``
    and standard errors ``se`` (module docstring); sizes whose mean or SE is not a positive
    number are left out. Returns the fit: ``sigma_ref_MPa``, ``k``, ``k_se``, the
    covariance of (ln sigma_ref, k) (``cov``), ``n_sizes``, ``chi2`` (NaN with fewer than
    two sizes: no curve)."""
    d, m, s = (np.asarray(v, float) for v in (diameter_mm, mean, se))
    ok = np.isfinite(d) & np.isfinite(m) & np.isfinite(s) & (d > 0) & (m > 0) & (s > 0)
    n = int(ok.sum())
    out = {"reference_mm": float(reference_mm), "n_sizes": n, "sigma_ref_MPa": math.nan,
           "k": math.nan, "k_se": math.nan, "cov": [[math.nan] * 2] * 2, "chi2": math.nan}
    if n < 2 or len(set(d[ok])) < 2:
        return out
    x = np.log(d[ok] / reference_mm)
    y = np.log(m[ok])
    w = (m[ok] / s[ok]) ** 2  # 1 / var(ln mean), var(ln m) = (se / m)^2
    X = np.column_stack([np.ones(n), -x])
    A = X.T @ (w[:, None] * X)
    cov = np.linalg.inv(A)
    beta = cov @ (X.T @ (w * y))
    chi2 = float(np.sum(w * (y - X @ beta) ** 2))
    if n > 2:
        cov = cov * max(1.0, chi2 / (n - 2))
    out.update(sigma_ref_MPa=float(np.exp(beta[0])), k=float(beta[1]),
               k_se=float(math.sqrt(cov[1, 1])), cov=cov.tolist(), chi2=chi2)
    return out


def curve_at(fit: dict, diameter_mm: float) -> tuple[float, float]:
    """σt of the fitted curve at ``diameter_mm`` and its standard error (from the fit's
    covariance: var ln σ = var ln σ_ref + x² var k - 2 x cov, x = ln(D / D_ref))."""
    if not math.isfinite(fit["k"]):
        return math.nan, math.nan
    x = math.log(diameter_mm / fit["reference_mm"])
    v = fit["sigma_ref_MPa"] * math.exp(-fit["k"] * x)
    c = fit["cov"]
    var = c[0][0] + x * x * c[1][1] - 2.0 * x * c[0][1]
    return v, v * math.sqrt(max(var, 0.0))


def sigma_at(sizes: pd.DataFrame, fit: dict, diameter_mm: float) -> dict:
    """σt at ``diameter_mm`` (module docstring): ``value``, ``se`` and ``method``
    (``measured``, ``interpolated``, ``extrapolated``, or ``not measured`` when the size
    has fewer than two valid discs and there is no curve)."""
    same = sizes[(sizes["diameter_mm"] - diameter_mm).abs() <= SAME_SIZE * diameter_mm]
    if len(same) and int(same["valid"].iloc[0]) >= 2:
        r = same.iloc[0]
        return {"value": float(r["mean_MPa"]), "se": float(r["se_MPa"]), "method": "measured"}
    v, se = curve_at(fit, diameter_mm)
    if not math.isfinite(v):
        return {"value": math.nan, "se": math.nan, "method": "not measured"}
    fitted = sizes.loc[sizes["valid"] >= 2, "diameter_mm"]
    inside = fitted.min() <= diameter_mm <= fitted.max()
    return {"value": v, "se": se, "method": "interpolated" if inside else "extrapolated"}


def _disc_at(disc: Geometry, st: BTSSettings, study_mm: float, d_mm: float):
    """The study's disc and settings at diameter ``d_mm``: its scale, the contact cap
    scaled with D, and no enlargement (the study's disc: its own, unchanged)."""
    if d_mm == study_mm:
        return disc, st
    return (replace(disc, scale=d_mm / disc.diameter_mm),
            replace(st, contact_cap=similar_contact_cap(st.contact_cap, d_mm, study_mm),
                    min_balls_across=0.0))


def _run_row(d_mm, seed, geo, st, out) -> dict:
    s = out.summary if out.status == "ok" else {}
    return {"diameter_mm": d_mm, "scale": geo.scale, "contact_cap": st.contact_cap,
            "seed": int(seed), "status": out.status,
            "valid": bool(s.get("bts_valid", False)), "discs": int(s.get("discs", 1)),
            "bts_MPa": float(s.get("bts_MPa", math.nan)),
            "bts_peak_MPa": float(s.get("bts_peak_MPa", math.nan)),
            "balls_across": float(s.get("balls_across", math.nan)),
            "n_balls": float(s.get("n_balls", math.nan)),
            "reason": out.error or s.get("discarded", "") or s.get("bts_invalid_reason", ""),
            "run": "" if out.path is None else str(out.path)}


def _se(v: np.ndarray) -> float:
    return float(np.std(v, ddof=1) / math.sqrt(v.size)) if v.size > 1 else math.nan


def run_sizes(params: dict, sizes_mm, disc: Geometry, st: BTSSettings, *, run_path,
              settings: SizeSettings = SizeSettings(), ctx: RunContext = RunContext(),
              note=None) -> pd.DataFrame:
    """σt of ``params`` on the discs of ``sizes_mm`` (the study's first, then the others;
    module docstring): one row per (size, seed) run (:func:`_run_row`).
    ``run_path(d_mm, seed)`` names each run file; ``note(text)`` receives a line per run."""
    study_mm = disc.scale * disc.diameter_mm
    rows: list[dict] = []
    count = {d: 0 for d in sizes_mm}

    def one(d):
        geo, sd = _disc_at(disc, st, study_mm, d)
        seed = settings.first_seed + count[d]
        count[d] += 1
        out = RUNNERS["bts"](run_path(d, seed), params, seed, geo, sd, **ctx.lab_kw())
        rows.append(_run_row(d, seed, geo, sd, out))
        if note:
            r = rows[-1]
            note(f"D {d:.4g} mm, seed {seed}: " + (
                f"σt {r['bts_MPa']:.3f} MPa" if r["valid"] else f"no σt ({r['status']}, "
                f"{r['reason'][:80]})"))

    for d in sizes_mm:
        for _ in range(settings.seeds):
            one(d)
    for d in sizes_mm:  # more seeds where the mean is not yet precise enough
        while count[d] < settings.max_seeds:
            v = np.array([r["bts_MPa"] for r in rows if r["diameter_mm"] == d and r["valid"]])
            if v.size >= 2 and _se(v) <= settings.target_se * float(v.mean()):
                break
            one(d)
    return pd.DataFrame(rows)


def size_table(runs: pd.DataFrame, study_mm: float, lab_mm: float) -> pd.DataFrame:
    """One row per size from :func:`run_sizes`' rows: its role, scale, cap (in mean ball
    diameters and as a share of D), balls across, seeds, valid seeds, discs tested, failed
    runs, σt mean, sd, SE (MPa) and SE in % of the mean."""
    rows = []
    for d, g in runs.groupby("diameter_mm", sort=True):
        v = g.loc[g["valid"], "bts_MPa"].to_numpy(float)
        across = float(g["balls_across"].mean())
        role = ("the study's disc" if abs(d - study_mm) <= SAME_SIZE * study_mm else
                "the lab's disc" if abs(d - lab_mm) <= SAME_SIZE * lab_mm else "between")
        mean = float(v.mean()) if v.size else math.nan
        se = _se(v)
        rows.append({"diameter_mm": float(d), "role": role, "scale": float(g["scale"].iloc[0]),
                     "contact_cap": float(g["contact_cap"].iloc[0]),
                     "cap_share_of_D": float(g["contact_cap"].iloc[0]) / across,
                     "balls_across": across, "seeds": len(g), "valid": int(v.size),
                     "discs": int(g["discs"].sum()),
                     "failed": int((g["status"] != "ok").sum()), "mean_MPa": mean,
                     "sd_MPa": float(np.std(v, ddof=1)) if v.size > 1 else math.nan,
                     "se_MPa": se, "se_pct": 100 * se / mean if v.size else math.nan})
    return pd.DataFrame(rows)


def fit_row(spec: str, sizes: pd.DataFrame, study_mm: float, lab_mm: float, lab: float,
            lab_se: float) -> dict:
    """The fit and the comparison with the lab: one row (module docstring)."""
    fit = fit_power_law(sizes["diameter_mm"], sizes["mean_MPa"],
                        sizes["se_MPa"].where(sizes["valid"] >= 2), study_mm)
    at = sigma_at(sizes, fit, lab_mm)
    both = math.hypot(at["se"], lab_se)
    return {"specimen": spec, "reference_mm": study_mm, "sizes_fitted": fit["n_sizes"],
            "sigma_ref_MPa": fit["sigma_ref_MPa"], "k": fit["k"], "k_se": fit["k_se"],
            "chi2": fit["chi2"], "lab_diameter_mm": lab_mm, "sigma_lab_size_MPa": at["value"],
            "sigma_lab_size_se": at["se"], "method": at["method"], "lab_bts_MPa": lab,
            "lab_bts_se": lab_se, "err_pct": 100 * (at["value"] / lab - 1),
            "z": (at["value"] - lab) / both if both > 0 else math.nan}


def bts_size(card, *, lab_diameter_mm: float, disc: Geometry, settings: BTSSettings,
             run_dir, runs_table, sizes_table, fit_table,
             size_settings: SizeSettings = SizeSettings(), ctx: RunContext = RunContext(),
             note=None) -> dict:
    """The stage (module docstring): the verified ``card``'s σt on the discs of
    :func:`sizes_of`, run files in ``run_dir`` (``d<D>mm_seed<s>.h5``), the runs, the
    sizes and the fit with the lab comparison written as tables (CSV + Markdown). Returns
    the three tables."""
    c = read_card(card, "--card", need=("parameters", "specimen", "targets"))
    lab = (c.get("lab") or {}).get(BTS)
    if BTS not in c["targets"] or lab is None:
        raise BadInput(f"--card {card}: no Brazilian σt target (bts_MPa): a size curve "
                       "compares the card's σt with the lab's at the lab's disc size")
    lab_se = float((c.get("target_se") or {}).get(BTS, 0.0))
    params = card_parameters(c)
    # the study's disc as the card is tested on it (a flat-jointed card's is enlarged to
    # its fewest balls across: lab.brazilian.resolved_disc); the other sizes are run at
    # their size, however coarse (the curve is of the size: _disc_at)
    disc = resolved_disc(disc, validate_params(params), settings)
    study_mm = disc.scale * disc.diameter_mm
    sizes_mm = sizes_of(study_mm, lab_diameter_mm, size_settings.middle)
    try:
        discs = [_disc_at(disc, settings, study_mm, d)[0] for d in sizes_mm]
    except InputError as e:  # the scaled contact cap past BTSSettings' bound
        raise BadInput(f"--lab-diameter {lab_diameter_mm:g} mm: the study's contact cap "
                       f"scaled with D to that disc is out of bounds ({e}); a size curve "
                       "reaches discs whose cap stays within them") from None
    ctx.check_budget(params, *discs)
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    runs = run_sizes(params, sizes_mm, disc, settings, settings=size_settings, ctx=ctx,
                     note=note, run_path=lambda d, s: run_dir / f"d{d:.6g}mm_seed{s}.h5")
    sizes = size_table(runs, study_mm, lab_diameter_mm)
    fit = pd.DataFrame([fit_row(str(c["specimen"]), sizes, study_mm, lab_diameter_mm,
                                float(lab), lab_se)])
    write_table(runs, runs_table, index=False)
    write_table(sizes, sizes_table, index=False)
    write_table(fit, fit_table, index=False)
    return {"runs": runs, "sizes": sizes, "fit": fit}
