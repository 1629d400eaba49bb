"""The analysis stages of the study, one function per workflow rule (the CLI calls them).

- :func:`screen`: XGBoost screening -> Table 3, selected candidates, importance figure.
- :func:`regress`: stepwise regression -> Table 4, models.json, equations, summaries,
  predicted-vs-simulated figure.
- :func:`calibrate`: inversion for every lab specimen + bootstrap intervals -> one
  material card (YAML) per specimen.
- :func:`verify`: re-run the DEM with a card; closed loop (Newton-Broyden) until every
  response is within the tolerance or the rounds are used up -> rounds table, run files.
- :func:`seed_scatter_runs`: one parameter set, several packing seeds -> scatter table.
- :func:`verification_tables`: Tables 5 and 6 and Fig. 6 from the verification outputs.

All tables are written as CSV and Markdown (``.md`` beside), figures as PNG and PDF.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from .. import __version__
from .. import params as P
from ..io.atomic import atomic_path, write_text  # noqa: F401  (write_text: re-exported)
from ..io.provenance import config_hash, git_commit


# ------------------------------------------------------------------------ small helpers
def write_table(df: pd.DataFrame, path, index=True, floatfmt=".4g") -> list[Path]:
    """CSV + Markdown (same stem), atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=index)
    md = write_text(path.with_suffix(".md"), df.to_markdown(index=index, floatfmt=floatfmt) + "\n")
    return [path, md]


def write_yaml(path, d: dict) -> Path:
    return write_text(path, yaml.safe_dump(_plain(d), sort_keys=False))


def _plain(v):
    """numpy/pandas scalars and NaN -> plain YAML-able Python."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return None if not math.isfinite(f) else f
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def provenance(**inputs) -> dict:
    return {"bpmcal_version": __version__, "git_commit": git_commit(),
            "inputs_hash": config_hash(inputs)}


def load_ok(dataset_csv) -> tuple[pd.DataFrame, str]:
    df = pd.read_csv(dataset_csv)
    ok = df[df["status"] == "ok"]
    note = (f"{len(ok)} of {len(df)} samples used"
            + (f" ({len(df) - len(ok)} failed/missing dropped: "
               f"{', '.join(df.loc[df['status'] != 'ok', 'sample_id'])})"
               if len(ok) < len(df) else ""))
    return df, note


# ------------------------------------------------------------------------ screening
def screen(dataset_csv, out_dir, tables_dir, figures_dir, *, threshold=10.0,
           importance="gain", n_splits=5, n_repeats=10, seed=0) -> dict:
    from ..analysis import XGBScreening, table3, table3_markdown
    from ..plots.calibration import fig_importance
    from ..plots.style import save

    df, note = load_ok(dataset_csv)
    from ..analysis._common import usable_rows

    n_ok = usable_rows(df, [*P.PARAMS, *P.TARGETS]).n_used
    if n_ok < 2 * n_splits:  # failed samples left too few rows for the configured CV
        k = n_ok // 2
        if k < 2:
            raise P.ParameterError(f"{dataset_csv}: only {n_ok} usable samples (status ok, "
                                   "finite responses); the screening needs at least 4 - see "
                                   "the dataset's status and error columns")
        note += (f"; {n_splits}-fold CV needs {2 * n_splits} usable samples, so {k}-fold CV "
                 "was used")
        n_splits = k
    res = XGBScreening(n_splits=n_splits, threshold=threshold, select_by=importance,
                       n_repeats=n_repeats, seed=seed).fit(df)
    out, tab, fig = Path(out_dir), Path(tables_dir), Path(figures_dir)
    t3 = table3(res, importance=importance)
    write_table(t3, tab / "table3_importance.csv")
    write_text(tab / "table3_importance.md",
               table3_markdown(res, importance=importance) + "\n")
    write_table(res.to_frame(), out / "importance_all_types.csv")
    write_table(res.cv_r2, out / "xgb_cv_r2.csv")
    write_table(res.shadow_max, out / "shadow_max.csv")
    sel = {r: list(v) for r, v in res.selected.items()}
    write_text(out / "selected.json", json.dumps(
        {"selected": sel, "threshold_pct": threshold, "importance": importance,
         "note": note, "provenance": provenance(dataset=str(dataset_csv), seed=seed)},
        indent=2) + "\n")
    write_text(out / "summary.txt", res.summary() + "\n" + note + "\n")
    save(fig_importance(res.to_frame(), res.shadow_max, importance, threshold),
         fig / "screening_importance.png")
    return {"selected": sel, "note": note}


# ------------------------------------------------------------------------ regression
def regress(dataset_csv, selected_json, out_dir, tables_dir, figures_dir, *, alpha_in=0.05,
            alpha_out=0.05, vif_max=10.0, hierarchy="strong", cv_folds=5, cv_repeats=10,
            seed=0) -> dict:
    from ..analysis import StepwiseRegression
    from ..plots.calibration import fig_pred_vs_sim
    from ..plots.style import save

    df, note = load_ok(dataset_csv)
    sel = json.loads(Path(selected_json).read_text())["selected"]
    res = StepwiseRegression(alpha_in=alpha_in, alpha_out=alpha_out, vif_max=vif_max,
                             hierarchy=hierarchy, cv_folds=cv_folds, cv_repeats=cv_repeats,
                             seed=seed).fit(df, sel)
    out, tab, fig = Path(out_dir), Path(tables_dir), Path(figures_dir)
    d = res.to_dict()
    d["note"] = note
    d["provenance"] = provenance(dataset=str(dataset_csv), seed=seed)
    write_text(out / "models.json", json.dumps(_plain(d), indent=1) + "\n")
    write_table(res.table4_terms("retained"), tab / "table4_terms.csv")
    write_table(res.table4_terms("candidates"), out / "table4_candidate_terms.csv")
    write_table(res.fit_table(), tab / "regression_fit.csv")
    write_table(res.to_frame(), out / "coefficients.csv")
    eq = ["# Regression equations (physical units, paper style)", ""]
    for stage in res.fit_table().index.get_level_values("stage").unique():
        eq.append(f"## stage: {stage}")
        for r, e in res.equations(stage=stage).items():
            row = res.fit_table().loc[(r, stage)]
            eq.append(f"- `{e}`  (adj. R² = {row['adj_r2']:.3f}, CV R² = "
                      f"{row['cv_r2_mean']:.3f})")
        eq.append("")
    eq.append(note)
    write_text(out / "equations.md", "\n".join(eq) + "\n")
    write_text(out / "summaries.txt", res.summary() + "\n")
    ok = df[df["status"] == "ok"]
    pred = res.predict(ok)
    save(fig_pred_vs_sim(ok, pred, res.fit_table()), fig / "regression_fit.png")
    return {"note": note}


# ------------------------------------------------------------------------ calibration
def calibrate(dataset_csv, models_json, lab_csv, out_dir, *, fixed: dict, ranges: dict, bounds=None,
              ratio=1.4, free=None, n_boot=200, seed=0, tables_dir=None) -> dict:
    """Invert the final regression models for every lab specimen; bootstrap intervals;
    one material card per specimen (YAML). ``ranges`` is the design space the dataset was
    sampled over (the config's ``ranges``) and bounds the free parameters; ``bounds`` (the
    config's ``calibration.bounds``) may narrow it. ``n_boot=0`` skips the bootstrap (the
    initial calibration that only seeds the strength-ratio sweep needs the point estimate).

    Every card records the configured ``ranges``, the effective ``bounds`` of the calibrated
    parameters with the configured key each side comes from, and, when the targets are not
    met, ``widen``: which configured limit to move and how far (see
    :func:`bpmcal.analysis.invert`)."""
    from ..analysis import bootstrap_intervals, invert, models_from_dict
    from ..io.paths import child_path
    from .config import load_lab

    df, note = load_ok(dataset_csv)
    models = models_from_dict(json.loads(Path(models_json).read_text()))
    lab = load_lab(lab_csv)  # specimen names checked: they become file names
    out = Path(out_dir)
    bounds = dict(bounds or {})
    rows = []
    for rec in lab.to_dict("records"):
        spec = str(rec["specimen"])
        card_path = child_path(out, spec, ".yaml")  # never outside out_dir
        targets = {k: float(rec[k]) for k in P.TARGETS}
        inv = invert(models, targets, fixed, free=free, bounds=bounds, ratio=ratio, ranges=ranges,
                     seed=seed)
        if n_boot:
            boot = bootstrap_intervals(df, models, targets, fixed, free=free, bounds=bounds,
                                       ratio=ratio, ranges=ranges, n_boot=n_boot, seed=seed)
            bootstrap = {"n_boot": n_boot, "scheme": boot.scheme,
                         "unreachable_resamples": boot.n_unreachable,
                         "intervals": boot.intervals.reset_index().to_dict("records")}
        else:
            bootstrap = {"n_boot": 0, "scheme": None, "unreachable_resamples": None,
                         "intervals": []}
        card = {
            "specimen": spec,
            "status": inv.status,
            "message": inv.message,
            "ratio_ten_coh": ratio,
            "parameters": {k: float(inv.solution[k]) for k in P.PARAMS},
            "roles": {k: ("free" if k in inv.free else "derived" if k in inv.derived
                          else "fixed") for k in P.PARAMS},
            "ranges": {k: [float(a), float(b)] for k, (a, b) in inv.ranges.items()},
            "calibration_bounds": {k: [float(a), float(b)] for k, (a, b) in bounds.items()},
            "bounds": {k: {"lower": lo, "upper": hi, "lower_from": inv.bound_origins[k]["lower"],
                           "upper_from": inv.bound_origins[k]["upper"]}
                       for k, (lo, hi) in inv.bounds.items()},
            "at_bound": [{"parameter": p, "side": side, "value": v} for p, side, v in inv.at_bound],
            "widen": inv.widen,
            "advice": inv.advice,
            "targets": targets,
            "lab": {k: (None if (isinstance(v, float) and not math.isfinite(v)) else v)
                    for k, v in rec.items() if k != "specimen"},
            "predicted": inv.predicted,
            "residuals_pct": {k: 100 * v for k, v in inv.residuals.items()},
            "alternatives": inv.alternatives.to_dict("records"),
            "bootstrap": bootstrap,
            "dataset_note": note,
            "provenance": provenance(dataset=str(dataset_csv), models=str(models_json),
                                     lab=str(lab_csv), fixed=fixed, ratio=ratio, seed=seed,
                                     ranges=ranges, bounds=bounds),
        }
        write_yaml(card_path, card)
        row = {"specimen": spec, "status": inv.status, **card["parameters"],
               **{f"pred_{k}": v for k, v in inv.predicted.items()}}
        rows.append(row)
    table = pd.DataFrame(rows).set_index("specimen")
    if tables_dir is not None:
        write_table(table, Path(tables_dir) / "calibration.csv")
    return {"table": table}


def read_card(path) -> dict:
    return yaml.safe_load(Path(path).read_text())


# ------------------------------------------------------------------------ verification
def verify(card_path, models_json, out_dir, *, geometry, settings, seed=1, rtol=0.01,
           max_rounds=5, cache=None, threads=None, free=None, progress=None,
           from_unreachable=False) -> dict:
    """Closed-loop verification of one material card: round 1 is the paper's single pass
    (the regression's answer), later rounds correct the free parameters with a
    Newton-Broyden step until every response is within ``rtol`` (relative) of the lab
    value, or ``max_rounds`` DEM runs are used up. Every round is a run file. The loop
    stays inside the card's bounds (its design ``ranges``, narrowed by its
    ``calibration_bounds``).

    A card whose inversion is ``unreachable`` is not a calibration: unless
    ``from_unreachable`` (config ``verification.from_unreachable``) the DEM is not run, and
    the verified card says so (``verification.status: not-run`` with the reason and what to
    widen); ``rounds.csv`` then has its header only."""
    from ..analysis import ClosedLoop, models_from_dict
    from ..io.h5 import read_summary
    from ..lab.runner import run_ucs_file

    card = read_card(card_path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if "ranges" not in card:
        raise P.ParameterError(f"{card_path}: the card has no 'ranges' (the design space); it was "
                               "written by an older bpmcal: rerun the calibrate step")
    targets = {k: float(v) for k, v in card["targets"].items()}
    if card.get("status") == "unreachable" and not from_unreachable:
        reason = ("the calibration is unreachable, so the closed loop did not start from it "
                  "(verification.from_unreachable: false); " + str(card.get("message", "")))
        write_table(pd.DataFrame(columns=["run_file", "round"]), out / "rounds.csv", index=False)
        verified = dict(card)
        verified["verification"] = {
            "status": "not-run", "message": reason, "rounds": 0, "rtol": rtol, "seed": seed,
            "best_round": None, "single_pass": None, "closed_loop": None, "parameters": None,
            "widen": card.get("widen", []), "geometry": geometry.to_dict()}
        write_yaml(out / "card.yaml", verified)
        return verified
    models = models_from_dict(json.loads(Path(models_json).read_text()))
    ratio = card.get("ratio_ten_coh")
    runs = []

    def simulate(params: dict) -> dict:
        k = len(runs) + 1
        f = out / f"round{k}.h5"
        res = run_ucs_file(f, params, seed, geometry, settings, cache=cache, threads=threads,
                           progress=progress)
        runs.append(f)
        if res.status != "ok":
            return {r: float("nan") for r in targets}
        s = read_summary(f)
        return {r: float(s[r]) for r in [*targets, "u_pre_MJm3", "peak_strain"]}

    free = free or [k for k, v in card["roles"].items() if v == "free"]
    loop = ClosedLoop(simulate, targets, free=free, ratio=ratio, models=models, rtol=rtol,
                      max_rounds=max_rounds, ranges=card["ranges"],
                      bounds=card.get("calibration_bounds") or None)
    res = loop.run(card["parameters"])
    hist = res.history.copy()
    hist.insert(0, "run_file", [str(f.name) for f in runs][: len(hist)])
    write_table(hist, out / "rounds.csv", index=False)
    best_round = int(np.argmin([_max_err(read_summary(f), targets) for f in runs])) + 1
    message = res.message
    if card.get("status") == "unreachable":
        message = ("started from an unreachable calibration at the user's request "
                   f"(verification.from_unreachable: true): {message}")
    verified = dict(card)
    verified.update({
        "verification": {
            "status": res.status, "message": message, "rounds": len(runs),
            "rtol": rtol, "seed": seed, "best_round": best_round,
            "single_pass": _responses(read_summary(runs[0]), targets),
            "closed_loop": _responses(read_summary(runs[best_round - 1]), targets),
            "parameters": {k: float(v) for k, v in res.params.items() if k in P.PARAMS},
            "geometry": geometry.to_dict(),
        }})
    write_yaml(out / "card.yaml", verified)
    return verified


def _max_err(s, targets):
    if s.get("status") != "ok":
        return math.inf
    return max(abs(float(s[k]) / v - 1) for k, v in targets.items())


def _responses(s, targets) -> dict:
    d = {k: float(s.get(k, math.nan)) for k in [*P.TARGETS, "u_pre_MJm3", "peak_strain",
                                                  "cracks_tension", "cracks_shear"]}
    d["errors_pct"] = {k: 100 * (d[k] / v - 1) for k, v in targets.items()}
    d["run_status"] = s.get("status")
    return d


def seed_scatter_runs(card_path, out_dir, *, geometry, settings, seeds, rtol=0.01,
                      cache=None, threads=None) -> pd.DataFrame:
    """One parameter set (a card's), several packing seeds: the scatter of the DEM
    responses, and whether the closed-loop tolerance is below it."""
    from ..analysis import seed_scatter
    from ..io.h5 import read_summary
    from ..lab.runner import run_ucs_file

    card = read_card(card_path)
    out = Path(out_dir)
    rows = []
    for s in seeds:
        f = out / f"seed{s}.h5"
        run_ucs_file(f, card["parameters"], int(s), geometry, settings, cache=cache,
                     threads=threads, keep_particles=False)
        r = read_summary(f)
        rows.append({"seed": s, "status": r["status"],
                     **{k: r.get(k, math.nan) for k in (*P.TARGETS, "u_pre_MJm3")}})
    runs = pd.DataFrame(rows)
    write_table(runs, out / "seed_runs.csv", index=False)
    sc = seed_scatter(runs[runs["status"] == "ok"], rtol=rtol)
    sc.insert(0, "specimen", card["specimen"])
    write_table(sc, out / "seed_scatter.csv")
    return sc


def verification_tables(cards: dict, lab_csv, tables_dir, figures_dir,
                        scatter_csv=None) -> dict:
    """Tables 5 and 6 and Fig. 6 from the verified cards (specimen -> card path). A card
    whose closed loop did not run (``not-run``) keeps its row, with empty responses, status
    ``not-run`` and the reason in ``note``; its Fig. 6 panel says why it has no curve."""
    from ..io.h5 import read_series
    from ..plots.calibration import fig_stress_strain
    from ..plots.style import save
    from .config import load_lab

    lab = load_lab(lab_csv)
    t5, t6, curves = [], [], {}
    for spec, path in cards.items():
        c = read_card(path)
        v = c["verification"]
        row = {"specimen": spec}
        ran = v["status"] != "not-run"
        for which in ("single_pass", "closed_loop"):
            r = v[which] if ran else None
            for k in P.TARGETS:
                row[f"{which}_{k}"] = r[k] if ran else math.nan
                row[f"{which}_{k}_err_pct"] = r["errors_pct"][k] if ran else math.nan
        for k in P.TARGETS:
            row[f"lab_{k}"] = c["targets"][k]
        row["rounds"] = v["rounds"]
        row["status"] = v["status"]
        row["calibration_status"] = c.get("status")
        row["note"] = "" if ran else v["message"]
        t5.append(row)
        up_lab = c["lab"].get("u_pre_MJm3")
        up_sim = v["closed_loop"]["u_pre_MJm3"] if ran else math.nan
        t6.append({"specimen": spec, "sim_Up_MJm3": up_sim, "lab_Up_MJm3": up_lab,
                   "rel_error_pct": (100 * abs(up_sim - up_lab) / up_lab
                                     if up_lab and ran else math.nan),
                   "sim_peak_strain": v["closed_loop"]["peak_strain"] if ran else math.nan})
        if ran:
            best = Path(path).parent / f"round{v['best_round']}.h5"
            curves[spec] = read_series(best)
        else:
            curves[spec] = f"not run: {c.get('status')} calibration"
    t5 = pd.DataFrame(t5).set_index("specimen")
    t6 = pd.DataFrame(t6).set_index("specimen")
    tab, fig = Path(tables_dir), Path(figures_dir)
    write_table(t5, tab / "table5_verification.csv")
    write_table(t6, tab / "table6_prepeak_energy.csv")
    save(fig_stress_strain(curves, lab), fig / "fig6_stress_strain.png")
    return {"table5": t5, "table6": t6}
