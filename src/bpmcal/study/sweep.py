"""The bond-strength-ratio sweep (paper section 4.2, Figs. 4 and 5).

With a calibrated parameter set held otherwise fixed, the ratio a = sigma_cp / tau_cp runs
over a grid (0.5 to 2.0 by 0.1). For every a, tau_cp is chosen so that the regression's
predicted sigma_c stays at the calibration target (sigma_cp = a tau_cp; a bracketing
root search on the final sigma_c model) - the constraint the paper's procedure implies.
The root is searched from near zero up to four times the largest cohesion the sampled
ranges allow at that ratio (``max(ranges.pb_coh_MPa, ranges.pb_ten_MPa / a)``; a flat
joint's strength pair fj_ten_MPa / fj_coh_MPa likewise; the ranges
are the card's, i.e. the study's design space). A ratio whose tau_cp or sigma_cp falls
outside the sampled ranges is still run but flagged ``extrapolated``. A ratio for which
no tau_cp in that interval reaches the target (e.g. the refitted sigma_c model no longer
depends on tau_cp) is kept in the plan with
``status`` "unreachable" and the reason: its run becomes a failure record (``bpmcal ucs``
does not run it), the analysis leaves it out, and when no ratio is usable the chosen-ratio
file says so (``chosen_ratio`` null) and the calibration keeps the configured ratio.

Run names come from ``bpmcal.io.study_files`` (``ratio_id``: "a050" for a = 0.50, over
``ratio_grid``). The ratio is then chosen by a criterion on the simulated cracks: by default the tensile
share of all cracks closest to 60 % (the brittle/shear split the paper cites), or the
crack count closest to a target.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .. import params as P
from ..io.h5 import RunFileError, read_summary
from ..io.study_files import ratio_id

#: plan rows: "planned" (run it) or "unreachable" (no tau_cp gives the target)
PLANNED, UNREACHABLE = "planned", "unreachable"

#: the paper's grid of ratios a = sigma_cp / tau_cp: start, stop, step
DEFAULT_RATIOS = (0.5, 2.0, 0.1)


def sweep_plan(card: dict, ucs_model, ratios, seed: int) -> pd.DataFrame:
    """One row per ratio: sample_id ("a050" for a = 0.50), the 8 parameters, seed,
    ratio, extrapolated flag, status ("planned" or "unreachable") and reason.
    ``ucs_model``: the final regression model of sigma_c; ``card``: a material card (its
    ``ranges`` are the study's design space)."""
    from scipy.optimize import brentq

    if "ranges" not in card:
        raise P.ParameterError("the card has no 'ranges' (the design space); it was written by "
                               "an older bpmcal: rerun the calibrate step")

    ids = [ratio_id(a) for a in ratios]
    if len(set(ids)) != len(ids):
        raise P.ParameterError(f"ratios {list(ratios)}: two ratios share a run name "
                               "(a step finer than 0.01)")
    base = {k: float(v) for k, v in card["parameters"].items() if k != "contact_model"}
    model = P.model_of(base)
    TEN, COH = model.strength  # the model's strength pair (pb_ten/pb_coh, fj_ten/fj_coh)
    target = float(card["targets"]["ucs_MPa"])
    clo, chi = (float(v) for v in card["ranges"][COH])
    tlo, thi = (float(v) for v in card["ranges"][TEN])
    rows = []
    for a in ratios:
        def resid(coh):
            p = {**base, COH: coh, TEN: a * coh}
            return float(ucs_model.predict(pd.DataFrame([p]))[0]) - target
        top = 4.0 * max(chi, thi / a)
        grid = np.linspace(top / 600, top, 600)
        vals = np.array([resid(c) for c in grid])
        cross = np.flatnonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))
        if cross.size == 0 or not np.isfinite(vals).all():
            fin = vals[np.isfinite(vals)] + target
            if fin.size == 0:
                span = "the predicted sigma_c is not finite"
            elif np.ptp(fin) <= 1e-9 * max(1.0, abs(fin[0])):
                span = (f"the sigma_c model does not depend on the bond strengths: it predicts "
                        f"{fin[0]:.4g} MPa for every tau_cp")
            else:
                span = f"predicted sigma_c {fin.min():.4g}-{fin.max():.4g} MPa"
            rows.append({"sample_id": ratio_id(a), **base, COH: math.nan,
                         TEN: math.nan, "seed": int(seed), "ratio": a,
                         "extrapolated": False, "status": UNREACHABLE,
                         "reason": f"no tau_cp in [{grid[0]:.3g}, {top:.4g}] MPa gives the target sigma_c "
                                   f"{target:g} MPa at a = {a:g} ({span})"})
            continue
        # the root nearest the calibrated cohesion
        roots = [brentq(resid, grid[c], grid[c + 1]) for c in cross]
        coh = min(roots, key=lambda r: abs(r - base[COH]))
        ten = a * coh
        extrap = not (clo <= coh <= chi and tlo <= ten <= thi)
        rows.append({"sample_id": ratio_id(a), **base, COH: coh,
                     TEN: ten, "seed": int(seed), "ratio": a,
                     "extrapolated": extrap, "status": PLANNED, "reason": ""})
    cols = ["sample_id", *[k for k in model.params if k in base], "seed", "ratio",
            "extrapolated", "status", "reason"]
    return pd.DataFrame(rows)[cols]


def analyse_sweep(plan: pd.DataFrame, run_files, criterion="tensile_share", target=0.6):
    """Crack counts and proportions per ratio, and the chosen ratio. ``run_files``: the run
    file of every plan row, by sample_id. A run that failed, is unreadable or was not run
    (unreachable ratio) is a row with its status and reason and no counts; when no run is
    usable, ``chosen_ratio`` is None and ``reason`` says why."""
    rows = []
    TEN, COH = P.model_of(plan.columns).strength
    for r in plan.to_dict("records"):
        f = run_files.get(r["sample_id"])
        try:
            if f is None:
                raise RunFileError(f"no run file for {r['sample_id']}")
            s = read_summary(f)
            status, reason = s.get("status", "failed"), s.get("error", "")
        except RunFileError as e:
            s, status, reason = {}, "unreadable", str(e)
        if r.get("status", PLANNED) == UNREACHABLE:
            status, reason = UNREACHABLE, r.get("reason", "")
        ok = status == "ok"
        nt = float(s.get("cracks_tension", np.nan)) if ok else np.nan
        ns = float(s.get("cracks_shear", np.nan)) if ok else np.nan
        tot = nt + ns
        rows.append({"ratio": r["ratio"], "sample_id": r["sample_id"],
                     TEN: r[TEN], COH: r[COH],
                     "extrapolated": r["extrapolated"], "status": status,
                     "reason": "" if ok else reason,
                     "ucs_MPa": s.get("ucs_MPa", np.nan) if ok else np.nan,
                     "cracks_tension": nt, "cracks_shear": ns, "cracks_total": tot,
                     "tensile_share": nt / tot if tot > 0 else np.nan,
                     "shear_share": ns / tot if tot > 0 else np.nan,
                     "cracks_tension_peak": s.get("cracks_tension_peak", np.nan) if ok else np.nan,
                     "cracks_shear_peak": s.get("cracks_shear_peak", np.nan) if ok else np.nan})
    df = pd.DataFrame(rows)
    key = {"tensile_share": "tensile_share", "crack_count": "cracks_total"}[criterion]
    dist = (df[key].astype(float) - target).abs()
    if dist.notna().sum() == 0:
        bad = "; ".join(f"{r.sample_id}: {r.status}" for r in df.itertuples())
        return df, {"chosen_ratio": None, "criterion": criterion, "target": target,
                    "value": None, "sample_id": None,
                    "reason": f"no ratio of the sweep gave a usable run ({bad})"}
    best = int(dist.idxmin())
    chosen = {"chosen_ratio": float(df.loc[best, "ratio"]), "criterion": criterion,
              "target": target, "value": float(df.loc[best, key]),
              "sample_id": df.loc[best, "sample_id"]}
    return df, chosen
