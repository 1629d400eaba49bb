"""The impact analysis stage (``workflow/rules/fracture.smk``): :func:`impact_analyse`,
the reference impact's energy table and Fig. 7, the velocity sweep's t10 table, the JK
fit and its figure. The impact runs (``impact``) are ``stages.runs``.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..io.checks import in_file
from ..io.figures import save_figure
from ..io.h5 import RunFileError, check_run_file, read_inputs, read_series, read_summary
from ..io.tables import write_json, write_table
from ..lab.fragments import fit_jk
from ..plots.fracture import fig_impact, fig_t10
from ..plots.style import fig_note
from .inputs import CSV, JSON, PNG, outputs

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
