"""The strength-ratio sweep stages (``workflow/rules/fracture.smk``):

- :func:`sweep_plan`: the strength-ratio sweep's plan (one row per ratio);
- :func:`sweep_analyse`: crack counts per ratio, the chosen ratio, Figs. 4 and 5 and the
  ParaView files of the runs Fig. 5 shows.

Its DEM runs (``sweep_ucs``) are ``stages.runs``; the impact analysis is
``stages.impact_energy``.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from .. import params as P
from ..io.card import read_card
from ..io.checks import BadInput, read_model_table
from ..io.figures import save_figure
from ..io.h5 import read_cracks
from ..io.study_files import ratio_grid
from ..io.tables import write_csv, write_json, write_table
from ..io.vtk import export_run
from ..plots.fracture import fig_failure_patterns, fig_ratio_cracks
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
    p, _ = read_model_table(plan, "--plan",
                            lambda m: ["sample_id", "ratio", *m.strength, "extrapolated"],
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
