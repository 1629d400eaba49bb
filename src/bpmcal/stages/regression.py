"""The regression stage (``workflow/rules/analysis.smk``, ``bpmcal regress``): three-stage
stepwise regression of the screened candidates -> models.json, the equations, summaries,
coefficient and candidate tables, Table 4, the fit table and the predicted-vs-simulated
figure; σt is regressed on the samples whose tensile test is valid.

The stage reads the files it is given, checks them and its output paths before any work,
and writes exactly the files it is given (``bpmcal.io.study_files``).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .. import params as P
from ..analysis import StepwiseRegression
from ..analysis._common import dataset_params, usable_rows
from ..analysis.stepwise import HIERARCHIES
from ..analysis.stepwise import combine as combine_regressions
from ..io.atomic import write_text
from ..io.checks import BadInput, read_json
from ..io.figures import save_figure
from ..io.provenance import provenance
from ..io.tables import write_json, write_table
from ..plots.calibration import fig_pred_vs_sim
from ..study.gather import has_tensile, tensile_view
from . import defaults_of
from .inputs import CSV, JSON, MD, PNG, TXT, outputs, read_dataset, usable
from .screening import _RESP_NAME, _TEST_NAME, tensile_note
from .settings import SEED, Limit, check_fields, setting

#: the defaults of the stage are those of the analysis it runs
_REGR = defaults_of(StepwiseRegression)


@dataclass(frozen=True)
class RegressionSettings:
    """The stepwise regression's settings (the config's ``regression`` section, ``bpmcal
    regress``'s options), checked when built: the entry and removal p-values
    ``alpha_in`` and ``alpha_out``, the VIF limit ``vif_max``, the terms' ``hierarchy``,
    the cross-validation's ``cv_folds`` and ``cv_repeats`` and its ``seed``
    (:class:`~bpmcal.analysis.StepwiseRegression`)."""

    alpha_in: float = setting(_REGR["alpha_in"], Limit("float", 0.0, 0.5, lo_open=True))
    alpha_out: float = setting(_REGR["alpha_out"], Limit("float", 0.0, 0.5, lo_open=True))
    vif_max: float = setting(_REGR["vif_max"], Limit("float", 1.0))
    hierarchy: str = setting(_REGR["hierarchy"], Limit("choice", words=HIERARCHIES))
    cv_folds: int = setting(_REGR["cv_folds"], Limit("int", 2, 20))
    cv_repeats: int = setting(_REGR["cv_repeats"], Limit("int", 1, 100))
    seed: int = setting(_REGR["seed"], SEED)

    def __post_init__(self):
        check_fields(self)


def regress(dataset, selected, *, models, equations, summaries, coefficients, candidates,
            table4, fit_table, figure, settings: RegressionSettings = RegressionSettings()
            ) -> dict:
    """Three-stage stepwise regression of the screened candidates -> ``models`` (JSON),
    ``equations`` (Markdown), ``summaries`` (text), the coefficient and candidate-term
    tables, Table 4, the fit table (adjusted and CV R² per stage) and the
    predicted-vs-simulated figure, as ``settings`` say (:class:`RegressionSettings`).
    Returns the note and the equations text."""
    cv_folds, seed = settings.cv_folds, settings.seed
    df = read_dataset(dataset, min_ok=max(cv_folds, 4))
    sel = read_json(selected, "--selected")
    if not isinstance(sel, dict) or not isinstance(sel.get("selected"), dict):
        raise BadInput(f"--selected {selected}: not a selected.json of 'bpmcal screen' "
                       "(no 'selected' mapping)")
    outputs((models, "--models", JSON), (equations, "--equations", MD),
            (summaries, "--summaries", TXT), (coefficients, "--coefficients", CSV),
            (candidates, "--candidates", CSV), (table4, "--table4", CSV),
            (fit_table, "--fit-table", CSV), (figure, "--figure", PNG))
    note = usable(df)
    reg = StepwiseRegression(**asdict(settings))
    chosen = dict(sel["selected"])
    tensile = {r: chosen.pop(r) for r in P.SAMPLE_TESTS if r in chosen}  # own rows each
    res = reg.fit(df, chosen)
    for resp, terms in tensile.items():
        test = P.SAMPLE_TESTS[resp]
        if not has_tensile(df, resp):
            raise BadInput(f"--selected {selected} screens {resp}, but --dataset "
                           f"{dataset} has no {_TEST_NAME[test]} columns ({resp}, "
                           f"{test}_status)")
        tv = tensile_view(df, resp)
        n_t = usable_rows(tv, [*dataset_params(df), resp]).n_used
        if n_t < max(cv_folds, 4):
            note += (f"; {resp} not regressed: {n_t} samples have a valid "
                     f"{_TEST_NAME[test]} test, at least {max(cv_folds, 4)} are needed")
        else:
            note += f"; {_RESP_NAME[resp]}: {tensile_note(tv, test)}"
            res = combine_regressions(res, reg.fit(tv, {resp: terms}))
    d = res.to_dict()
    d["note"] = note
    d["provenance"] = provenance({"dataset": str(dataset), "seed": seed})
    write_json(models, d, indent=1)
    write_table(res.table4_terms("retained"), table4)
    write_table(res.table4_terms("candidates"), candidates)
    write_table(res.fit_table(), fit_table)
    write_table(res.to_frame(), coefficients)
    eq = ["# Regression equations (physical units, paper style)", ""]
    for stage in res.fit_table().index.get_level_values("stage").unique():
        eq.append(f"## stage: {stage}")
        for r, e in res.equations(stage=stage).items():
            row = res.fit_table().loc[(r, stage)]
            eq.append(f"- `{e}`  (adj. R² = {row['adj_r2']:.3f}, CV R² = "
                      f"{row['cv_r2_mean']:.3f})")
        eq.append("")
    eq.append(note)
    text = "\n".join(eq) + "\n"
    write_text(equations, text)
    write_text(summaries, res.summary() + "\n")
    ok = df[df["status"] == "ok"]
    fitted = [r for r in P.SAMPLE_TESTS if r in res.models]
    if fitted:  # sigma_t (sigma1) over the samples whose tensile (triaxial) test is valid
        keep = df["status"] == "ok"
        for r in fitted:
            keep |= df[f"{P.SAMPLE_TESTS[r]}_status"] == "ok"
        ok = df[keep].copy()
        ok.loc[ok["status"] != "ok", list(chosen)] = np.nan
        for r in fitted:  # an invalid or failed test's value is not shown either
            ok.loc[ok[f"{P.SAMPLE_TESTS[r]}_status"] != "ok", r] = np.nan
    save_figure(fig_pred_vs_sim(ok, res.predict(ok), res.fit_table()), figure)
    return {"note": note, "equations": text}
