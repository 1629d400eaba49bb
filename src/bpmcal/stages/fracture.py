"""The failure and fragmentation stages (``workflow/rules/fracture.smk``):

- :func:`sweep_plan`: the bond-strength-ratio sweep's plan (one row per ratio);
- :func:`sweep_analyse`: crack counts per ratio, the chosen ratio, Figs. 4 and 5 and the
  ParaView files of the runs Fig. 5 shows;
- :func:`impact_analyse`: the reference impact's energy table and Fig. 7, the velocity
  sweep's t10 table, the JK fit and its figure.

The DEM runs of both (``sweep_ucs``, ``impact``) are ``stages.runs``.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from .. import params as P
from ..io.card import read_card
from ..io.checks import BadInput, in_file, read_csv
from ..io.figures import save_figure
from ..io.h5 import RunFileError, check_run_file, read_cracks, read_inputs, read_series, read_summary
from ..io.study_files import ratio_grid
from ..io.tables import write_csv, write_json, write_table
from ..io.vtk import export_run
from ..lab.fragments import fit_jk
from ..plots.fracture import fig_failure_patterns, fig_impact, fig_ratio_cracks, fig_t10
from ..plots.style import fig_note
from ..study.sweep import DEFAULT_RATIOS, analyse_sweep
from ..study.sweep import sweep_plan as plan_rows
from . import defaults_of
from .inputs import CSV, JSON, PNG, check_ids, output_dirs, outputs, read_models, runs_by_id

# ------------------------------------------------------------------------ ratio sweep
#: the defaults of the sweep's choice (criterion, target)
_CHOICE = defaults_of(analyse_sweep)


def sweep_plan(card, models, *, ratios=DEFAULT_RATIOS, seed: int = 1, out) -> pd.DataFrame:
    """One row per ratio of ``ratios`` = (start, stop, step) -> ``out`` (CSV): the card's
    parameters with tau_cp chosen so that the regression's sigma_c stays at the target."""
    try:
        grid = ratio_grid(*ratios)
    except P.ParameterError as e:
        raise BadInput(f"--ratios {','.join(f'{x:g}' for x in ratios)}: {e}") from None
    c = read_card(card, "--card", need=("parameters", "targets"))
    if "ucs_MPa" not in (c["targets"] or {}):
        raise BadInput(f"--card {card}: no targets.ucs_MPa")
    model_set = read_models(models)
    outputs((out, "--out", CSV))
    plan = plan_rows(c, model_set["ucs_MPa"], grid, seed)
    write_csv(plan, out)
    return plan


def sweep_analyse(plan, runs, *, criterion=_CHOICE["criterion"], target=_CHOICE["target"],
                  table, chosen, fig4, fig5, vtk) -> tuple[pd.DataFrame, dict]:
    """Crack counts and proportions per ratio (``table``), the chosen ratio (``chosen``,
    JSON), Fig. 4 and Fig. 5; ``vtk``: the folder of the ParaView files of the runs Fig. 5
    shows (the first and last usable ratio, 1.0 and the chosen one). ``runs``: the run
    file of every plan row (``<sample_id>.h5``)."""
    head = read_csv(plan, "--plan", ["sample_id", "ratio", "extrapolated"],
                    dtype={"sample_id": str})
    try:
        pair = P.model_of([c for c in head.columns if c in P.ALL_PARAMS]).strength
    except P.ParameterError as e:
        raise BadInput(f"--plan {plan}: {e}") from None
    p = read_csv(plan, "--plan", ["sample_id", "ratio", *pair, "extrapolated"],
                 dtype={"sample_id": str})
    check_ids(p["sample_id"], f"--plan {plan}")
    files = runs_by_id(runs, "--runs", ids=list(p["sample_id"]))
    outputs((table, "--table", CSV), (chosen, "--chosen", JSON), (fig4, "--fig4", PNG),
            (fig5, "--fig5", PNG))
    output_dirs((vtk, "--vtk"))
    df, ch = analyse_sweep(p, files, criterion, target)
    write_table(df, table, index=False)
    write_json(chosen, ch)
    save_figure(fig_ratio_cracks(df, ch), fig4)
    ok = df[df["status"] == "ok"]
    show = sorted({ok["ratio"].iloc[0], ch["chosen_ratio"], 1.0, ok["ratio"].iloc[-1]}
                  & set(ok["ratio"])) if len(ok) else []
    panels = {}
    for r in show:
        sid = ok.loc[ok["ratio"] == r, "sample_id"].iloc[0]
        panels[f"a = {r:.1f}"] = read_cracks(files[sid])
        export_run(files[sid], Path(vtk) / sid)
    save_figure(fig_failure_patterns(panels), fig5)
    return df, ch


# ------------------------------------------------------------------------ impact
#: the columns of the t10 table, one row per impact velocity
T10_COLUMNS = ["velocity", "W_in_J", "G_f_J", "eta_f", "ecs_kWh_t", "t10_pct", "n_fragments",
               "largest_fragment_frac", "balls_per_t10_fragment"]


def impact_analyse(main, runs, *, energy, t10, jk_fit, fig7, fig_t10_png) -> dict:
    """The reference run ``main``: its energy budget over time (``energy``) and Fig. 7 (a
    note figure when the run failed); the velocity sweep ``runs``: t10 against specific
    energy (``t10``), the JK fit (``jk_fit``, JSON; null when it fails) and its figure.
    Runs that failed or are unreadable are rows with their status, left out of the fit.
    Returns the tables, the fit and what was left out (``notes``)."""
    check_run_file(main)
    for f in runs:
        in_file(f, "--runs")
    outputs((energy, "--energy", CSV), (t10, "--t10", CSV), (jk_fit, "--jk-fit", JSON),
            (fig7, "--fig7", PNG), (fig_t10_png, "--fig-t10", PNG))
    notes = []
    main_s = read_summary(main)
    if main_s.get("status") == "ok":
        ser = read_series(main)
        ser["cracks_total"] = ser["cracks_tension"] + ser["cracks_shear"]
        fig = fig_impact(ser, main_s)
    else:
        ser = pd.DataFrame({"status": [main_s.get("status")], "error": [main_s.get("error")]})
        fig = fig_note("Fig. 7 not available", f"the impact run {Path(main).name} failed: "
                       f"{main_s.get('error', '')}")
        notes.append(f"{main}: run failed ({main_s.get('error', '')}); Fig. 7 not drawn")
    write_table(ser, energy, index=False)
    save_figure(fig, fig7)
    rows = []
    for f in runs:
        try:
            s = read_summary(f)
        except RunFileError as e:
            s = {"status": "unreadable", "error": str(e)}
        if s.get("status") != "ok":
            v = read_inputs(f).get("impact_velocity") if s["status"] == "failed" else None
            notes.append(f"{f}: {s['status']} ({s.get('error', '')}); left out of the t10 fit")
            rows.append({"velocity": v, "status": s["status"], "error": s.get("error", "")})
            continue
        rows.append({**{c: s[c] for c in T10_COLUMNS}, "status": "ok", "error": ""})
    t = pd.DataFrame(rows, columns=[*T10_COLUMNS, "status", "error"]).sort_values("velocity")
    ok = t[t["status"] == "ok"]
    try:
        fit = fit_jk(ok["ecs_kWh_t"], ok["t10_pct"])
    except (ValueError, RuntimeError, TypeError) as e:
        fit = None
        notes.append(f"JK fit failed: {e}")
    write_table(t, t10, index=False)
    write_json(jk_fit, fit)
    save_figure(fig_t10(ok, fit), fig_t10_png)
    return {"energy": ser, "t10": t, "fit": fit, "notes": notes}
