"""The calibration stages (``workflow/rules/analysis.smk``), one function per job; each
reads the files it is given, checks them and its output paths before any work, and
writes exactly the files it is given:

- :func:`screen`: XGBoost screening -> Table 3, selected candidates, importance figure.
- :func:`regress`: stepwise regression -> Table 4, models.json, equations, summaries,
  fit table, predicted-vs-simulated figure.
- :func:`calibrate`: inversion for every lab specimen + bootstrap intervals -> one
  material card per specimen (``bpmcal.io.card``) and the calibration table.
- :func:`verify`: re-run the DEM with a card; closed loop (Newton-Broyden) until every
  response is within the tolerance or the rounds are used up -> verified card, rounds
  table, the best round's run file.
- :func:`seed_scatter`: one card, several packing seeds -> run files and scatter tables.
- :func:`verification_tables`: Tables 5 and 6 and Fig. 6 from the verified cards.

Tables are CSV with Markdown beside them, figures PNG with PDF beside them
(``bpmcal.io.layout``).
"""
from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from .. import params as P
from ..analysis import (
    PAPER_RATIO,
    ClosedLoop,
    StepwiseRegression,
    XGBScreening,
    bootstrap_intervals,
    invert,
    table3,
    table3_markdown,
)
from ..analysis import seed_scatter as scatter_table
from ..analysis._common import usable_rows
from ..analysis.calibration import (
    BTS,
    TENSILE,
    bts_strengths,
    check_calibration_space,
    tensile_target,
)
from ..analysis.screening import combine as combine_screenings
from ..analysis.stepwise import combine as combine_regressions
from ..io.atomic import write_text
from ..io.card import card_parameters, read_card, write_card
from ..io.checks import BadInput, read_json
from ..io.figures import save_figure
from ..io.h5 import read_series
from ..io.provenance import provenance
from ..io.tables import write_json, write_table
from ..lab.brazilian import BTSSettings
from ..lab.budget import check_budget
from ..lab.direct_tension import DTTSettings
from ..lab.runner import bts_geometry as _isrm_disc
from ..lab.runner import bts_inputs, ucs_inputs
from ..plots.calibration import fig_importance, fig_pred_vs_sim, fig_stress_strain
from ..study.gather import has_tensile, tensile_responses, tensile_view
from . import defaults_of
from .inputs import (
    CSV,
    H5,
    JSON,
    MD,
    PNG,
    TXT,
    YAML,
    output_dirs,
    outputs,
    read_dataset,
    read_lab,
    read_models,
    usable,
)
from .runs import run_bts_file, run_dtt_file, run_ucs_file, write_failure

#: the defaults of the stages are those of the analyses they run
_SCREEN, _REGR, _LOOP = defaults_of(XGBScreening), defaults_of(StepwiseRegression), defaults_of(ClosedLoop)


# ------------------------------------------------------------------------ screening
def screen(dataset, *, selected, table3_csv, figure, importance_table, cv_table,
           shadow_table, summary, threshold=_SCREEN["threshold"],
           importance=_SCREEN["select_by"], n_splits=_SCREEN["n_splits"],
           n_repeats=_SCREEN["n_repeats"], seed=_SCREEN["seed"]) -> dict:
    """XGBoost screening of ``dataset`` -> ``selected`` (JSON), Table 3, the importance
    figure and the supplementary tables (every importance type, CV R², shadow maxima) and
    ``summary`` (text). Returns the selection and the note on left-out samples."""
    df = read_dataset(dataset, min_ok=4)  # the smallest K-fold CV (2 folds) needs 4 rows
    outputs((selected, "--selected", JSON), (table3_csv, "--table3", CSV),
            (figure, "--figure", PNG), (importance_table, "--importance-table", CSV),
            (cv_table, "--cv-table", CSV), (shadow_table, "--shadow-table", CSV),
            (summary, "--summary", TXT))
    note = usable(df)
    n_ok = usable_rows(df, [*P.PARAMS, *P.TARGETS]).n_used
    if n_ok < 2 * n_splits:  # failed samples left too few rows for the configured CV
        k = n_ok // 2
        if k < 2:
            raise BadInput(f"--dataset {dataset}: only {n_ok} usable samples (status ok, "
                           "finite responses); the screening needs at least 4 - see the "
                           "dataset's status and error columns")
        note += f"; {n_splits}-fold CV needs {2 * n_splits} usable samples, so {k}-fold CV was used"
        n_splits = k
    res = XGBScreening(n_splits=n_splits, threshold=threshold, select_by=importance,
                       n_repeats=n_repeats, seed=seed).fit(df)
    for resp in tensile_responses(df):  # sigma_t: on the samples whose test is valid
        tv = tensile_view(df, resp)
        test = P.TENSILE_TESTS[resp]
        n_t = usable_rows(tv, [*P.PARAMS, resp]).n_used
        k = min(n_splits, n_t // 2)
        if k < 2:
            note += (f"; {resp} not screened: {n_t} samples have a valid {_TEST_NAME[test]} "
                     f"test, at least 4 are needed (see the dataset's {test}_status and "
                     f"{test}_error)")
        else:
            note += f"; {_RESP_NAME[resp]}: {tensile_note(tv, test)}"
            res = combine_screenings(res, XGBScreening(
                responses=(resp,), n_splits=k, threshold=threshold, select_by=importance,
                n_repeats=n_repeats, seed=seed).fit(tv))
    write_table(table3(res, importance=importance), table3_csv,
                markdown=table3_markdown(res, importance=importance))
    write_table(res.to_frame(), importance_table)
    write_table(res.cv_r2, cv_table)
    write_table(res.shadow_max, shadow_table)
    sel = {r: list(v) for r, v in res.selected.items()}
    write_json(selected, {"selected": sel, "threshold_pct": threshold, "importance": importance,
                          "note": note,
                          "provenance": provenance({"dataset": str(dataset), "seed": seed})})
    write_text(summary, res.summary() + "\n" + note + "\n")
    save_figure(fig_importance(res.to_frame(), res.shadow_max, importance, threshold), figure)
    return {"selected": sel, "note": note}


#: the tensile tests by name, for notes
_TEST_NAME = {"bts": "Brazilian", "dtt": "direct-tension"}
_RESP_NAME = {"bts_MPa": "sigma_t", "dtt_MPa": "sigma_t (direct tension)"}


def tensile_note(tv: pd.DataFrame, test: str = "bts") -> str:
    """How many samples the sigma_t analyses use (``tv``: the dataset's
    ``study.gather.tensile_view``), and which tensile tests they leave out, by reason
    (an invalid test - its fracture did not start in the disc's central zone, or next to
    a grip - is left out like a failed one: it measured no sigma_t)."""
    name = _TEST_NAME[test]
    bad = tv[tv["status"] != "ok"]
    if not len(bad):
        return f"{len(tv)} of {len(tv)} {name} tests used"
    parts = []
    for status, grp in bad.groupby("status", sort=True):
        parts.append(f"{len(grp)} {status}: {', '.join(grp['sample_id'])}")
    return (f"{len(tv) - len(bad)} of {len(tv)} {name} tests used ({len(bad)} left out: "
            + "; ".join(parts) + ")")


# ------------------------------------------------------------------------ regression
def regress(dataset, selected, *, models, equations, summaries, coefficients, candidates,
            table4, fit_table, figure, alpha_in=_REGR["alpha_in"],
            alpha_out=_REGR["alpha_out"], vif_max=_REGR["vif_max"],
            hierarchy=_REGR["hierarchy"], cv_folds=_REGR["cv_folds"],
            cv_repeats=_REGR["cv_repeats"], seed=_REGR["seed"]) -> dict:
    """Three-stage stepwise regression of the screened candidates -> ``models`` (JSON),
    ``equations`` (Markdown), ``summaries`` (text), the coefficient and candidate-term
    tables, Table 4, the fit table (adjusted and CV R² per stage) and the
    predicted-vs-simulated figure. Returns the note and the equations text."""
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
    reg = StepwiseRegression(alpha_in=alpha_in, alpha_out=alpha_out, vif_max=vif_max,
                             hierarchy=hierarchy, cv_folds=cv_folds, cv_repeats=cv_repeats,
                             seed=seed)
    chosen = dict(sel["selected"])
    tensile = {r: chosen.pop(r) for r in P.TENSILE_TESTS if r in chosen}  # own rows each
    res = reg.fit(df, chosen)
    for resp, terms in tensile.items():
        test = P.TENSILE_TESTS[resp]
        if not has_tensile(df, resp):
            raise BadInput(f"--selected {selected} screens {resp}, but --dataset "
                           f"{dataset} has no {_TEST_NAME[test]} columns ({resp}, "
                           f"{test}_status)")
        tv = tensile_view(df, resp)
        n_t = usable_rows(tv, [*P.PARAMS, resp]).n_used
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
    fitted = [r for r in P.TENSILE_TESTS if r in res.models]
    if fitted:  # sigma_t over the samples whose tensile test is valid
        keep = df["status"] == "ok"
        for r in fitted:
            keep |= df[f"{P.TENSILE_TESTS[r]}_status"] == "ok"
        ok = df[keep].copy()
        ok.loc[ok["status"] != "ok", list(chosen)] = np.nan
        for r in fitted:  # an invalid or failed test's value is not shown either
            ok.loc[ok[f"{P.TENSILE_TESTS[r]}_status"] != "ok", r] = np.nan
    save_figure(fig_pred_vs_sim(ok, res.predict(ok), res.fit_table()), figure)
    return {"note": note, "equations": text}


# ------------------------------------------------------------------------ calibration
def chosen_ratio(ratio_from, ratio: float | None) -> tuple[float | None, str]:
    """The ratio the calibration uses: the sweep's choice in ``ratio_from`` (its chosen
    JSON), or ``ratio`` when there is no sweep or it chose none; and a note saying which."""
    if not ratio_from:
        return ratio, ""
    ch = read_json(ratio_from, "--ratio-from")
    if not isinstance(ch, dict) or "chosen_ratio" not in ch:
        raise BadInput(f"--ratio-from {ratio_from}: no 'chosen_ratio' (expected the "
                       "chosen.json of 'bpmcal sweep-analyse')")
    if ch["chosen_ratio"] is None:
        shown = "none (both strengths free)" if ratio is None else f"{ratio:g}"
        return ratio, (f"--ratio-from {ratio_from}: the sweep chose no ratio "
                       f"({ch.get('reason', 'no usable run')}); using --ratio {shown}")
    a = P.as_number(ch["chosen_ratio"], f"--ratio-from {ratio_from}: chosen_ratio",
                    "a positive ratio", BadInput)
    if a <= 0:
        raise BadInput(f"--ratio-from {ratio_from}: chosen_ratio={a:g}: expected a positive "
                       "ratio")
    return a, ""


def calibrate(dataset, models, lab, *, cards, fixed: dict, ranges: dict, bounds=None,
              ratio: float | None = PAPER_RATIO, ratio_from=None, free=None, n_boot=200,
              seed=0, table=None) -> dict:
    """Invert the final regression models for every lab specimen; bootstrap intervals;
    one material card per specimen: ``cards`` holds one file per lab specimen, named
    ``<specimen>.yaml`` (``bpmcal.io.layout``); ``table``: the calibration table (optional).
    ``ranges`` is the design space the dataset was sampled over (the config's ``ranges``)
    and bounds the free parameters; ``bounds`` (the config's ``calibration.bounds``) may
    narrow it. ``ratio_from``: the strength-ratio sweep's chosen JSON (its ratio replaces
    ``ratio`` when it chose one). ``n_boot=0`` skips the bootstrap (the initial calibration
    that only seeds the strength-ratio sweep needs the point estimate).

    Every card records the configured ``ranges``, the effective ``bounds`` of the calibrated
    parameters with the configured key each side comes from, and, when the targets are not
    met, ``widen``: which configured limit to move and how far (see
    :func:`bpmcal.analysis.invert`). Returns the table and a note on the ratio.

    A specimen whose lab row gives ``bts_MPa`` is also calibrated against σt (a ``bts_MPa``
    model in ``models`` is then required): σt sets its bond-strength ratio
    (:func:`bpmcal.analysis.calibration.bts_strengths`: ``pb_ten_MPa`` free, the card's
    ``ratio_ten_coh`` null), instead of ``ratio`` or the sweep's choice. When the set of
    targets cannot be met at once (e.g. a σc/σt beyond the parallel-bond model's) the card
    is ``no-exact-fit``, keeps the least-squares compromise and lists every missed target
    (``missed``: target, value, predicted, error_pct) and what the models reach (``reach``).
    Every card records ``strength_ratio``: the ratio pb_ten/pb_coh of its parameters and
    what set it. A lab row without σt is calibrated exactly as before."""
    lab_df = read_lab(lab)
    specs = [str(s) for s in lab_df["specimen"]]
    by_spec = {Path(c).stem: c for c in cards}
    if sorted(by_spec) != sorted(specs) or len(by_spec) != len(cards):
        raise BadInput(f"--cards {' '.join(map(str, cards))}: expected one card per lab "
                       f"specimen, named <specimen>.yaml: {specs}")
    if not isinstance(fixed, dict):
        raise BadInput(f"--fixed {fixed!r}: expected a JSON object of parameter values")
    try:
        fixed = P.validate_params(fixed, require_all=False)
    except P.ParameterError as e:
        raise P.ParameterError(f"--fixed: {e}") from None
    if n_boot == 1:
        raise P.ParameterError(f"--n-boot {n_boot}: expected 0 (no bootstrap) or an integer "
                               ">= 2")
    if free:
        bad = [f for f in free if f not in P.PARAMS]
        if bad:
            raise BadInput(f"--free {','.join(free)}: unknown parameter(s) {bad}; expected "
                           f"names from {list(P.PARAMS)}")
    ratio, note = chosen_ratio(ratio_from, ratio)
    bounds = dict(bounds or {})
    for name, val in (("--ranges", ranges), ("--bounds", bounds)):
        if not isinstance(val, dict):
            raise BadInput(f"{name}: expected a JSON mapping of parameter name to "
                           f"[low, high] (paper units), got {val!r}")
    check_calibration_space(free, fixed, ratio, ranges, bounds)
    jobs = [(rec, lab_targets(rec)) for rec in lab_df.to_dict("records")]
    with_bts = [str(rec["specimen"]) for rec, t in jobs if tensile_target(t)]
    if with_bts:  # σt sets the ratio of these specimens: their space must be valid too
        f_bts, r_bts, _ = bts_strengths({BTS: 1.0}, free, fixed, ratio)
        check_calibration_space(f_bts, fixed, r_bts, ranges, bounds)
    df = read_dataset(dataset)
    model_set = read_models(models)
    for resp in TENSILE:
        having = [str(rec["specimen"]) for rec, t in jobs if resp in t]
        if not having:
            continue
        test = "a Brazilian" if resp == BTS else "a direct-tension"
        if resp not in model_set:
            raise BadInput(f"--lab {lab}: specimen(s) {having} have a tensile strength "
                           f"({resp}) but --models {models} has no model of {resp}: run the "
                           f"study with {test} test per sample, or leave {resp} empty")
        if n_boot and resp not in df.columns:
            raise BadInput(f"--dataset {dataset}: no {resp} column, which the bootstrap of "
                           f"the tensile-strength target of {having} refits")
    outputs(*((c, "--cards", YAML) for c in cards), (table, "--table", CSV))
    dnote = usable(df)
    if with_bts:
        note = "; ".join(x for x in (note, (
            f"the tensile strength sets the bond-strength ratio of {with_bts} "
            "(pb_ten_MPa free; the configured or swept ratio is not used for them)")) if x)
    rows = []
    for rec, targets in jobs:
        spec = str(rec["specimen"])
        s_free, s_ratio, ratio_by = bts_strengths(targets, free, fixed, ratio)
        inv = invert(model_set, targets, fixed, free=s_free, bounds=bounds, ratio=s_ratio,
                     ranges=ranges, seed=seed)
        if n_boot:
            boot = bootstrap_intervals(df, model_set, targets, fixed, free=s_free,
                                       bounds=bounds, ratio=s_ratio, ranges=ranges,
                                       n_boot=n_boot, seed=seed)
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
            "ratio_ten_coh": s_ratio,
            "strength_ratio": {
                "value": float(inv.solution["pb_ten_MPa"] / inv.solution["pb_coh_MPa"]),
                "set_by": (f"{ratio_by} target" if ratio_by in TENSILE else
                           "ratio sweep" if ratio_from and not note_is_fallback(note)
                           else "config calibration.ratio" if s_ratio is not None
                           else "both strengths free")},
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
            "missed": inv.missed,
            "reach": inv.reach,
            "alternatives": inv.alternatives.to_dict("records"),
            "bootstrap": bootstrap,
            "dataset_note": dnote,
            "provenance": provenance({"dataset": str(dataset), "models": str(models),
                                      "lab": str(lab), "fixed": fixed, "ratio": ratio,
                                      "seed": seed, "ranges": ranges, "bounds": bounds}),
        }
        write_card(by_spec[spec], card)
        rows.append({"specimen": spec, "status": inv.status, **card["parameters"],
                     **{f"pred_{k}": v for k, v in inv.predicted.items()}})
    out = pd.DataFrame(rows).set_index("specimen")
    if table is not None:
        write_table(out, table)
    return {"table": out, "note": note}


def lab_targets(rec: dict) -> dict:
    """The calibration targets of one lab row: σc, E, ν, and σt when the row gives it:
    the Brazilian tensile strength (``bts_MPa``) or the direct-tension strength
    (``dtt_MPa``), an alternative (``study.config.read_lab`` refuses a row with both); an
    empty optional value is not a target."""
    targets = {k: float(rec[k]) for k in P.TARGETS}
    for r in TENSILE:
        v = rec.get(r)
        if v is not None and math.isfinite(float(v)):
            targets[r] = float(v)
    return targets


def note_is_fallback(note: str) -> bool:
    """Whether :func:`chosen_ratio`'s note says the sweep chose no ratio (the configured
    one was used)."""
    return "the sweep chose no ratio" in note


# ------------------------------------------------------------------------ verification
#: responses a verified card records per round besides the targets
_EXTRA = ("u_pre_MJm3", "peak_strain", "cracks_tension", "cracks_shear")


def _responses(rows: list[dict], targets: dict) -> dict:
    """The seed mean of every response over the runs of one round (``rows``: one summary
    per seed), its seed spread (``seed_sd``, ``seed_cv``: sample standard deviation and
    coefficient of variation, NaN with one seed), ``n_seeds`` and the errors of the mean
    in % of the lab value. σt (``bts_MPa``) is among them when it is a target."""
    ok = [r for r in rows if r.get("status") == "ok"]
    scattered = [*P.TARGETS, *(r for r in TENSILE if r in targets)]
    d, sd, cv = {}, {}, {}
    for k in [*scattered, *_EXTRA]:
        v = np.array([float(r.get(k, math.nan)) for r in ok], float)
        v = v[np.isfinite(v)] if k in TENSILE else v  # an invalid test is no measurement
        d[k] = float(v.mean()) if len(v) else math.nan
        if k in scattered:
            sd[k] = float(v.std(ddof=1)) if len(v) > 1 else math.nan
            cv[k] = sd[k] / abs(d[k]) if len(v) > 1 and d[k] != 0 else math.nan
    d["errors_pct"] = {k: 100 * (d[k] / v - 1) for k, v in targets.items()}
    d["seed_sd"], d["seed_cv"] = sd, cv
    d["n_seeds"] = len(ok)
    d["seeds"] = [int(r["seed"]) for r in rows]
    d["run_status"] = "ok" if ok and len(ok) == len(rows) else "failed"
    return d


def _missed(resp: dict, targets: dict, rtol: float) -> list[dict]:
    """Every target the DEM misses by more than ``rtol``: target, value, dem, error_pct."""
    return [{"target": k, "value": v, "dem": resp[k], "error_pct": resp["errors_pct"][k]}
            for k, v in targets.items()
            if not abs(resp["errors_pct"][k]) <= 100 * rtol]  # NaN (a failed run) is missed


def disc_geometry(geometry):
    """The Brazilian disc (ISRM 50 x 25 mm) at the scale and with the genesis options of
    the UCS cylinder ``geometry``."""
    return _isrm_disc(scale=geometry.scale, sigma0_MPa=geometry.sigma0_MPa,
                      install_gap_mm=geometry.install_gap_mm,
                      relax_ratio=geometry.relax_ratio, genesis=geometry.genesis)


#: an invalid Brazilian test (its fracture did not start in the central zone) is no
#: measurement: the closed loop and the fresh-seed check run the disc again on the next
#: replacement seeds, seed + k x BTS_REPLACEMENT_STRIDE (k = 1, 2, ...), at most
#: BTS_MAX_REPLACEMENTS times, before σt of that seed counts as a failed measurement
BTS_REPLACEMENT_STRIDE = 100_000
BTS_MAX_REPLACEMENTS = 3


def valid_tensile_run(test: str, path_of, params: dict, seed: int, geometry, settings, *,
                      max_replacements: int = BTS_MAX_REPLACEMENTS, **kw):
    """A tensile test (``test``: "bts", the Brazilian disc ``geometry``; "dtt", the
    direct-tension cylinder) of ``params`` on packing ``seed`` that measures σt: an
    invalid run (``<test>_valid`` false) is replaced by the specimen of the next
    replacement seed (``seed + k x BTS_REPLACEMENT_STRIDE``), up to ``max_replacements``
    times; a failed run (instability, genesis) is not replaced (it is a failure, not a
    measurement of the wrong thing). ``path_of(seed, k)`` names the run file of attempt
    k. Returns (the outcome used, the packing seed it ran on, the reasons of the invalid
    attempts); the outcome has ``<test>_MPa`` NaN when every attempt was invalid."""
    run_file = run_bts_file if test == "bts" else run_dtt_file
    invalid = []
    for k in range(max_replacements + 1):
        s = int(seed) + k * BTS_REPLACEMENT_STRIDE
        b = run_file(path_of(s, k), params, s, geometry, settings, **kw)
        if b.status != "ok" or b.summary.get(f"{test}_valid", True):
            return b, s, invalid
        invalid.append(f"seed {s}: {b.summary.get(f'{test}_invalid_reason', 'invalid')}")
    return b, s, invalid


def valid_bts_run(path_of, params: dict, seed: int, disc, settings, **kw):
    """:func:`valid_tensile_run` of the Brazilian test."""
    return valid_tensile_run("bts", path_of, params, seed, disc, settings, **kw)


def _ucs_loop(c: dict, model_set, targets: dict, *, params: dict, run, seeds, geometry,
              settings, rtol, max_rounds, cache, threads, progress, genesis_max_steps,
              free=None, disc=None, bts_settings=None, bts_run=None, max_seeds=None,
              jacobian=None, range_margin=0.0, polish=True, cylinder=None,
              dtt_settings=None):
    """The closed loop on ``seeds``, growing to ``max_seeds`` (every round runs each seed
    into a temporary file: the UCS test and, when σt is a target, the Brazilian test on
    ``disc`` with the same seed; the first seed's run files of the best round become
    ``run`` and ``bts_run``). The first step follows the regression models' Jacobian, or
    ``jacobian`` (responses x free parameters, physical units) when given.
    Returns (ClosedLoopResult, per-round list of seed summaries, best round index)."""
    ratio = c.get("ratio_ten_coh")
    with_bts = BTS in targets
    by_round: list[list[dict]] = []
    paths: list[list[Path]] = []
    bts_paths: list[list[Path]] = []
    folder = Path(run).parent
    tmpdir = tempfile.mkdtemp(prefix=f".{Path(run).stem}.rounds.", dir=folder)
    try:
        last: list[dict] = []

        def simulate(params: dict, seed: int) -> dict:
            if not last or params != last[0]:  # a new point: a new round (grown seeds join theirs)
                last[:] = [dict(params)]
                by_round.append([])
                paths.append([])
                bts_paths.append([])
            k = len(by_round)
            res = run_ucs_file(Path(tmpdir) / f"round{k}_seed{seed}.h5", params, seed,
                               geometry, settings, cache=cache, threads=threads,
                               progress=progress, genesis_max_steps=genesis_max_steps)
            row = dict(res.summary, status=res.status, seed=seed)
            paths[-1].append(res.path)
            out = ({r: float(res.summary[r]) for r in targets if r not in TENSILE}
                   if res.status == "ok" else
                   {r: math.nan for r in targets if r not in TENSILE})
            for resp in (r for r in TENSILE if r in targets):  # σt: a valid test, or NaN
                test = P.TENSILE_TESTS[resp]
                geo, st = (disc, bts_settings) if test == "bts" else (cylinder, dtt_settings)
                b, used, invalid = valid_tensile_run(
                    test, lambda s, j, t=test: Path(tmpdir) / f"round{k}_seed{seed}.{t}{j}.h5",
                    params, seed, geo, st, cache=cache, threads=threads, progress=progress,
                    genesis_max_steps=genesis_max_steps)
                if test == "bts":
                    bts_paths[-1].append(b.path)
                row[resp] = float(b.summary[resp]) if b.status == "ok" else math.nan
                row[f"{test}_seed"], row[f"{test}_invalid"] = used, len(invalid)
                if b.status != "ok" or not math.isfinite(row[resp]):
                    row["status"] = "failed"
                out[resp] = row[resp]
            by_round[-1].append(row)
            return out

        free = free or [k for k, v in c["roles"].items() if v == "free"]
        jac = None if jacobian is None else pd.DataFrame.from_dict(jacobian, orient="index")
        if jac is not None and not (set(targets) <= set(jac.index) and set(free) <= set(jac.columns)
                                    and np.isfinite(jac.loc[list(targets), list(free)]
                                                    .to_numpy(float)).all()):
            jac = None  # learned for other targets or parameters: start from the models
        loop = ClosedLoop(simulate, targets, free=free, ratio=ratio,
                          models=model_set if jac is None else None, jacobian=jac,
                          rtol=rtol, max_rounds=max_rounds, ranges=c["ranges"],
                          bounds=c.get("calibration_bounds") or None, seeds=list(seeds),
                          max_seeds=max_seeds, margin=range_margin, polish=polish)
        res = loop.run(params)
        best = res.best_round  # converged, else the smallest max |error| of the seed mean
        os.replace(paths[best][0], run)  # the best round's first seed is the run file
        if bts_run is not None and with_bts:
            os.replace(bts_paths[best][0], bts_run)
    finally:
        for f in Path(tmpdir).glob("*"):
            f.unlink()
        os.rmdir(tmpdir)
    return res, by_round, best


def verify(card, models, *, out_card, rounds, run, geometry, settings, seed=1,
           seeds_per_round=3, rtol=_LOOP["rtol"], max_rounds=_LOOP["max_rounds"], cache=None,
           threads=None, free=None, progress=None, from_unreachable=False, max_balls=None,
           mem_budget_mb=None, genesis_max_steps=None, bts_geometry=None, bts_settings=None,
           bts_run=None, max_seeds=10, range_margin=0.25, polish=True, dtt_geometry=None,
           dtt_settings=None) -> dict:
    """Closed-loop verification of one material card: round 1 is the paper's single pass
    (the regression's answer), later rounds correct the free parameters with a
    Newton-Broyden step until every response is within the tolerance of the lab value,
    or ``max_rounds`` rounds are used up. Every round runs the candidate on
    ``seeds_per_round`` packing seeds (``seed``, ``seed + 1``, ...) and steers their mean;
    a target is met when the mean lies within max(``rtol``, 2 standard errors of the
    mean) of it (:class:`~bpmcal.analysis.ClosedLoop`), so the loop fits the rock, not
    one packing. A round costs ``seeds_per_round`` DEM runs. The seed set grows to
    ``max_seeds`` seeds (``seed + seeds_per_round``, ...; at most ``seeds_per_round``:
    no growth) once the means are within tolerance but their standard errors are too
    large to state them to ``rtol``, so the card is judged, and steered, on the mean of
    more packings (a fixed few packings' mean is itself off the rock's by ~CV/sqrt(k));
    later rounds run the grown set.

    Writes the verified card (``out_card``; per round shown, the seed mean of every
    response, its seed standard deviation ``seed_sd`` and coefficient of variation
    ``seed_cv``, and ``n_seeds``), the rounds table (``rounds``: parameters, seed means,
    seed CVs, standard errors, tolerances, errors and step of every round) and ``run``,
    the run file of the best round's first seed (each run goes to a temporary file; any
    run can be redone with ``bpmcal ucs --params ... --seed``, the runs being
    deterministic). The loop stays inside the card's bounds (its design ``ranges``,
    narrowed by its ``calibration_bounds``), each design range widened by
    ``range_margin`` of its width (config ``verification.range_margin``; never past a
    ``calibration_bounds`` narrowing or the parameter's physical domain): the regression
    only starts the loop, every round measures the DEM, so the loop may follow a target
    just outside the sampled space. The card records the bounds searched
    (``verification.loop_bounds``) and every parameter that ended outside its design range
    (``verification.outside_design``: value and range; the message says so too). The card
    records ``calibrated_at_scale``, the specimen scale the loop ran at. With ``polish``
    (config ``verification.polish``) a loop that converges with some mean more than one
    standard error from its target takes one more full Newton step towards the targets on
    the same seeds, if a round is left; that round is the card's when it is within
    tolerance too (:class:`~bpmcal.analysis.ClosedLoop`).

    A card whose inversion is ``unreachable`` is not a calibration: unless
    ``from_unreachable`` (config ``verification.from_unreachable``) the DEM is not run, the
    verified card says so (``verification.status: not-run`` with the reason and what to
    widen), ``rounds`` has its header only and ``run`` is a failure record ("not run: ...").
    Returns the verified card.

    Every target of the card is verified: a card with a tensile-strength target
    (``bts_MPa``) runs, in every round, a Brazilian test beside the UCS test (the same
    packing seed; the disc ``bts_geometry``, default the ISRM disc at the cylinder's scale
    and genesis options, :func:`disc_geometry`; loading ``bts_settings``, default
    ``BTSSettings()``), and the loop steers σt with the other responses; ``bts_run``
    (optional) receives the best round's Brazilian run file (a failure record when the
    card has no σt target). A card with a direct-tension target (``dtt_MPa``) runs the
    direct-tension test instead, on the cylinder ``dtt_geometry`` (default the UCS
    cylinder) with ``dtt_settings``. An invalid tensile test (its fracture at a contact
    or a grip) is no measurement: that seed's test is run again on replacement seeds
    (:func:`valid_tensile_run`), and the round fails only when none is valid. The verified
    card lists every target the best round misses by more than ``rtol``
    (``verification.missed``: target, lab value, DEM value, error in %); it is empty only
    when all are met."""
    c = read_card(card, "--card", need=("parameters", "targets", "roles"))
    if "ranges" not in c:
        raise P.ParameterError(f"--card {card}: the card has no 'ranges' (the design space); "
                               "rerun the calibrate step")
    if isinstance(seeds_per_round, bool) or not isinstance(seeds_per_round, int) \
            or seeds_per_round < 1:
        raise BadInput(f"--seeds-per-round {seeds_per_round!r}: expected an integer >= 1")
    model_set = read_models(models)
    targets = {k: float(v) for k, v in c["targets"].items()}
    with_bts = BTS in targets
    with_dtt = "dtt_MPa" in targets
    disc = bts_geometry or disc_geometry(geometry)
    bts_settings = bts_settings or BTSSettings()
    cylinder = dtt_geometry or geometry
    dtt_settings = dtt_settings or DTTSettings()
    if with_dtt and "dtt_MPa" not in model_set:
        raise BadInput(f"--card {card}: a direct-tension target (dtt_MPa) but --models "
                       f"{models} has no model of dtt_MPa")
    if with_bts and BTS not in model_set:
        raise BadInput(f"--card {card}: a tensile-strength target (bts_MPa) but --models "
                       f"{models} has no model of bts_MPa")
    if with_bts:  # the disc must hold 3 of the largest balls across, for every round
        rmin = (max(c["ranges"]["rmin_mm"]) if c["roles"].get("rmin_mm") == "free"
                else float(c["parameters"]["rmin_mm"]))
        rmax = P.RADIUS_RATIO * rmin
        dd, tt = disc.diameter_mm * disc.scale, disc.height_mm * disc.scale
        if min(dd, tt) < 6 * rmax:
            raise BadInput(f"--card {card}: a tensile-strength target (bts_MPa), but the "
                           f"Brazilian disc at scale {disc.scale:g} ({dd:g} x {tt:g} mm) is "
                           f"less than 3 ball diameters across for Rmax = {rmax:g} mm: use "
                           "a larger --scale")
    if max_balls is not None:
        check_budget(c["parameters"], geometry, max_balls=max_balls,
                     mem_budget_mb=mem_budget_mb)
        if with_bts:
            check_budget(c["parameters"], disc, max_balls=max_balls,
                         mem_budget_mb=mem_budget_mb)
        if with_dtt:
            check_budget(c["parameters"], cylinder, max_balls=max_balls,
                         mem_budget_mb=mem_budget_mb)
    outputs((out_card, "--out-card", YAML), (rounds, "--rounds", CSV), (run, "--run", H5),
            (bts_run, "--bts-run", H5))
    output_dirs((cache, "--specimen-cache"))
    if isinstance(max_seeds, bool) or not isinstance(max_seeds, int) or max_seeds < 1:
        raise BadInput(f"--max-seeds {max_seeds!r}: expected an integer >= 1")
    max_seeds = max(max_seeds, seeds_per_round)
    range_margin = _check_margin(range_margin)
    seeds = [int(seed) + i for i in range(seeds_per_round)]
    if c.get("status") == "unreachable" and not from_unreachable:
        reason = ("the calibration is unreachable, so the closed loop did not start from it "
                  "(verification.from_unreachable: false); " + str(c.get("message", "")))
        write_table(pd.DataFrame(columns=["round"]), rounds, index=False)
        write_failure(run, test="ucs", inputs=ucs_inputs(c["parameters"], seed, geometry,
                                                          settings),
                      error=f"not run: {reason}")
        if bts_run is not None:
            write_failure(bts_run, test="bts",
                          inputs=bts_inputs(c["parameters"], seed, disc, bts_settings),
                          error=f"not run: {reason}")
        verified = dict(c)
        verified["verification"] = {
            "status": "not-run", "message": reason, "rounds": 0, "rtol": rtol, "seed": seed,
            "seeds": seeds, "n_seeds": seeds_per_round, "max_seeds": max_seeds,
            "best_round": None, "single_pass": None, "closed_loop": None, "parameters": None,
            "widen": c.get("widen", []), "geometry": geometry.to_dict()}
        write_card(out_card, verified)
        return verified
    res, by_round, best = _ucs_loop(
        c, model_set, targets, params=c["parameters"], run=run, seeds=seeds,
        geometry=geometry, settings=settings, rtol=rtol, max_rounds=max_rounds, cache=cache,
        threads=threads, progress=progress, genesis_max_steps=genesis_max_steps, free=free,
        disc=disc, bts_settings=bts_settings, bts_run=bts_run, max_seeds=max_seeds,
        range_margin=range_margin, polish=bool(polish), cylinder=cylinder,
        dtt_settings=dtt_settings)
    write_table(res.history, rounds, index=False)
    message = res.message + _outside_text(res.outside, range_margin)
    if c.get("status") == "unreachable":
        message = ("started from an unreachable calibration at the user's request "
                   f"(verification.from_unreachable: true): {message}")
    verified = dict(c)
    verified.update({
        "calibrated_at_scale": float(geometry.scale),
        "verification": {
            "status": res.status, "message": message, "rounds": len(by_round),
            "runs": sum(len(r) for r in by_round), "rtol": rtol, "seed": seed,
            "seeds": [int(x) for x in res.seeds], "n_seeds": int(res.n_seeds),
            "seeds_per_round": seeds_per_round, "max_seeds": max_seeds, "polish": bool(polish),
            "best_round": best + 1, "run_seed": seeds[0],
            "jacobian": {r: {p: float(x) for p, x in row.items()}
                         for r, row in res.jacobian.iterrows()},
            "single_pass": _responses(by_round[0], targets),
            "closed_loop": _responses(by_round[best], targets),
            "parameters": {k: float(v) for k, v in res.params.items() if k in P.PARAMS},
            "geometry": geometry.to_dict(), **_loop_box(res, range_margin),
        }})
    v = verified["verification"]
    v["missed"] = _missed(v["closed_loop"], targets, rtol)
    if with_bts:
        v["bts_geometry"] = disc.to_dict()
    if with_dtt:
        v["dtt_geometry"] = cylinder.to_dict()
    write_card(out_card, verified)
    if bts_run is not None and not with_bts:
        write_failure(bts_run, test="bts", inputs=bts_inputs(c["parameters"], seed, disc,
                                                             bts_settings),
                      error="not run: the card has no tensile-strength target (bts_MPa)")
    return verified


def _check_margin(margin) -> float:
    if isinstance(margin, bool) or not isinstance(margin, (int, float)) \
            or not (math.isfinite(margin) and 0 <= margin <= 1):
        raise BadInput(f"--range-margin {margin!r}: expected a fraction of a range's width "
                       "in [0, 1]")
    return float(margin)


def _loop_box(res, margin: float) -> dict:
    """The card's record of the closed loop's bounds and what ended outside the design."""
    return {"range_margin": margin,
            "loop_bounds": {p: [float(a), float(b)] for p, (a, b) in res.loop_bounds.items()},
            "outside_design": {p: dict(v) for p, v in res.outside.items()}}


def _outside_items(outside: dict) -> str:
    """``pb_kratio 5.58 outside its range 1-5; ...`` for a card's ``outside_design``."""
    return "; ".join(f"{p} {v['value']:.3g} outside its range {v['range'][0]:g}-{v['range'][1]:g}"
                     for p, v in outside.items())


def _outside_text(outside: dict, margin: float) -> str:
    if not outside:
        return ""
    return (f"; outside the design space (range margin {margin:g}): {_outside_items(outside)}"
            " - the DEM was run there, the regression never sampled it")


def transfer(card, models, *, out_card, rounds, run, geometry, settings, seed=1,
             max_rounds=2, rtol=_LOOP["rtol"], z=2.0, cache=None, threads=None, progress=None,
             max_balls=None, mem_budget_mb=None, genesis_max_steps=None, bts_geometry=None,
             bts_settings=None, range_margin=0.25, dtt_settings=None) -> dict:
    """Full-size transfer of a verified card: run its parameters once (packing ``seed``)
    on the specimen of ``geometry`` (the study's ``transfer.scale``, 1.0 = the lab's
    50 x 100 mm) and, when a response misses its lab target by more than the seed scatter
    of one run at that size (max(``rtol``, ``z`` x the seed CV the verification measured x
    :func:`scatter_factor`, which shrinks it with the larger specimen's ball count)),
    continue the closed loop at that size for at most ``max_rounds`` more rounds of one
    run each: Newton-Broyden as in :func:`verify`, starting from the Jacobian the
    verification's loop had learned from the DEM (``verification.jacobian``; the
    regression's at the card's point for a card without one). The regression's Jacobian
    can be wrong where the loop ended - at a model's vertex its sign flips - while the
    DEM's relative sensitivities change little with the specimen size.

    Writes the transferred card (``out_card``: the verified card with a ``transfer``
    section - status ``within-scatter`` (no correction needed), ``corrected`` (met after
    corrections), ``max_rounds``/``stalled``/``failed`` (not met: the best round is
    kept), or ``not-run`` - the responses at transfer and of the best round, the
    tolerances, the parameters; and ``calibrated_at_scale``: the transfer's scale when the
    loop ran), the rounds table and ``run`` (the best round's run file). Readers take the
    transfer's parameters (:func:`bpmcal.io.card.card_parameters`). A card with a
    tensile-strength target runs its Brazilian test as :func:`verify` does: the disc
    ``bts_geometry`` (default the ISRM disc at the transfer's scale, :func:`disc_geometry`)
    loaded with ``bts_settings`` (default ``BTSSettings()``; the study passes its `bts`
    section, as to the verification); a direct-tension target runs its test on the
    transfer's cylinder with ``dtt_settings``. The loop's bounds are the verification's:
    the design ranges widened by ``range_margin`` of their width
    (``verification.range_margin``)."""
    c = read_card(card, "--card", need=("parameters", "targets", "roles", "ranges",
                                        "verification"))
    if isinstance(max_rounds, bool) or not isinstance(max_rounds, int) or max_rounds < 0:
        raise BadInput(f"--max-rounds {max_rounds!r}: expected an integer >= 0")
    range_margin = _check_margin(range_margin)
    model_set = read_models(models)
    params = card_parameters(c)
    if max_balls is not None:
        check_budget(params, geometry, max_balls=max_balls, mem_budget_mb=mem_budget_mb)
    outputs((out_card, "--out-card", YAML), (rounds, "--rounds", CSV), (run, "--run", H5))
    output_dirs((cache, "--specimen-cache"))
    targets = {k: float(v) for k, v in c["targets"].items()}
    v = c["verification"]
    base = {"scale": float(geometry.scale), "seed": int(seed), "max_rounds": max_rounds,
            "from_scale": c.get("calibrated_at_scale", (v.get("geometry") or {}).get("scale")),
            "geometry": geometry.to_dict()}
    if v.get("status") == "not-run" or not v.get("closed_loop"):
        reason = f"not run: the card's closed loop did not run ({v.get('message', '')})"
        write_table(pd.DataFrame(columns=["round"]), rounds, index=False)
        write_failure(run, test="ucs", inputs=ucs_inputs(params, seed, geometry, settings),
                      error=reason)
        out = dict(c)
        out["transfer"] = {"status": "not-run", "message": reason, "rounds": 0, **base,
                           "tolerance_pct": None, "at_transfer": None, "final": None,
                           "parameters": None}
        write_card(out_card, out)
        return out
    cv = (v["closed_loop"].get("seed_cv") or {})
    shrink = scatter_factor(v.get("geometry"), geometry)
    tol = {}
    for k in targets:
        x = float(cv.get(k, math.nan)) if cv.get(k) is not None else math.nan
        tol[k] = max(float(rtol), z * x * shrink) if math.isfinite(x) else float(rtol)
    res, by_round, best = _ucs_loop(
        c, model_set, targets, params=params, run=run, seeds=[int(seed)],
        geometry=geometry, settings=settings, rtol=tol, max_rounds=1 + max_rounds,
        cache=cache, threads=threads, progress=progress,
        genesis_max_steps=genesis_max_steps, disc=bts_geometry or disc_geometry(geometry),
        bts_settings=bts_settings or BTSSettings(), jacobian=v.get("jacobian"),
        range_margin=range_margin, cylinder=geometry,
        dtt_settings=dtt_settings or DTTSettings())
    write_table(res.history, rounds, index=False)
    if res.status == "converged":
        status = "within-scatter" if len(by_round) == 1 else "corrected"
    else:
        status = res.status
    out = dict(c)
    ran = status != "failed"
    if ran:
        out["calibrated_at_scale"] = float(geometry.scale)
    out["transfer"] = {
        "status": status, "message": res.message + _outside_text(res.outside, range_margin),
        "rounds": len(by_round), **_loop_box(res, range_margin),
        "corrections": len(by_round) - 1, **base, "best_round": best + 1,
        "tolerance_pct": {k: 100 * t for k, t in tol.items()}, "scatter_factor": shrink,
        "at_transfer": _responses(by_round[0], targets),
        "final": _responses(by_round[best], targets),
        "parameters": ({k: float(x) for k, x in res.params.items() if k in P.PARAMS}
                       if ran else None)}
    write_card(out_card, out)
    return out


def scatter_factor(verified_geometry: dict | None, geometry) -> float:
    """How much less one run of the specimen ``geometry`` scatters between packing seeds
    than one of the verification's (``verified_geometry``, the card's
    ``verification.geometry``): sqrt(V_verified / V), the specimens' volumes (the same
    balls, so their ball counts) - a response averaged over N independent grains scatters
    as 1/sqrt(N). Measured on B2's set, 10 seeds at scale 0.4 against 4 at full size (16 x
    the balls, 0.25 by this rule): CV ratios 0.34 (σc), 0.39 (E), 0.08 (ν). 1.0 when the
    card does not record its geometry."""
    def volume(g):  # Geometry.to_dict: the specimen's actual (scaled) size
        return float(g["diameter_mm"]) ** 2 * float(g["height_mm"])

    try:
        v0 = volume(verified_geometry or {})
    except (KeyError, TypeError, ValueError):
        return 1.0
    v1 = volume(geometry.to_dict())
    return math.sqrt(v0 / v1) if v0 > 0 and v1 > 0 else 1.0


def transfer_table(cards, *, table) -> pd.DataFrame:
    """One row per transferred card and response: the verified seed mean at the
    calibration scale, the full-size response at transfer and after the corrections,
    their errors in % of the lab value, the tolerance and the status."""
    loaded = [read_card(c, "--cards", need=("specimen", "targets", "verification",
                                            "transfer")) for c in cards]
    outputs((table, "--table", CSV))
    rows = []
    for c in loaded:
        t, v = c["transfer"], c["verification"]
        for k in P.TARGETS:
            def val(section, key=k):
                return (section or {}).get(key, math.nan) if section else math.nan

            def err(section, key=k):
                return ((section or {}).get("errors_pct") or {}).get(key, math.nan)
            rows.append({
                "specimen": c["specimen"], "response": k, "lab": c["targets"][k],
                "verified_scale": t.get("from_scale"),
                "verified_mean": val(v.get("closed_loop")),
                "verified_err_pct": err(v.get("closed_loop")),
                "scale": t["scale"], "at_transfer": val(t.get("at_transfer")),
                "at_transfer_err_pct": err(t.get("at_transfer")),
                "tolerance_pct": (t.get("tolerance_pct") or {}).get(k, math.nan),
                "final": val(t.get("final")), "final_err_pct": err(t.get("final")),
                "rounds": t.get("rounds"), "status": t["status"]})
    df = pd.DataFrame(rows)
    write_table(df, table, index=False)
    return df


def seed_scatter(card, *, runs, seeds, seed_runs, table, geometry, settings, rtol=_LOOP["rtol"],
                 cache=None, threads=None, max_balls=None, mem_budget_mb=None,
                 genesis_max_steps=None) -> pd.DataFrame:
    """One parameter set (a card's: :func:`card_parameters`, i.e. the closed loop's of a
    verified card, the transfer's of a transferred one), several packing seeds
    (``runs[i]`` is the run file of ``seeds[i]``): the scatter of the DEM responses
    (``seed_runs``: one row per seed; ``table``: coefficient of variation and noise floor
    per response), and whether the closed-loop tolerance is below it."""
    c = read_card(card, "--card", need=("parameters", "specimen"))
    params = card_parameters(c)
    if len(runs) != len(seeds):
        raise BadInput(f"--runs: {len(runs)} run file(s) for {len(seeds)} seed(s); expected "
                       "one per seed, in the order of --seeds")
    if max_balls is not None:
        check_budget(params, geometry, max_balls=max_balls, mem_budget_mb=mem_budget_mb)
    outputs(*((r, "--runs", H5) for r in runs), (seed_runs, "--seed-runs", CSV),
            (table, "--table", CSV))
    output_dirs((cache, "--specimen-cache"))
    rows = []
    for s, f in zip(seeds, runs):
        out = run_ucs_file(f, params, int(s), geometry, settings, cache=cache,
                           threads=threads, keep_particles=False,
                           genesis_max_steps=genesis_max_steps)
        r = dict(out.summary, status=out.status)
        rows.append({"seed": s, "status": r["status"],
                     **{k: r.get(k, math.nan) for k in (*P.TARGETS, "u_pre_MJm3")}})
    done = pd.DataFrame(rows)
    write_table(done, seed_runs, index=False)
    sc = scatter_table(done[done["status"] == "ok"], rtol=rtol)
    sc.insert(0, "specimen", c["specimen"])
    write_table(sc, table)
    return sc


def verification_tables(cards, runs, lab, *, table5, table6, figure) -> dict:
    """Tables 5 and 6 and Fig. 6 from the verified cards and their best rounds' run files
    (``runs[i]`` belongs to ``cards[i]``). Table 5 holds the seed mean of every response
    (single pass and closed loop), its seed standard deviation (``_sd``) and CV
    (``_cv_pct``), the error of the mean and ``n_seeds``. A card whose closed loop did not run
    (``not-run``) keeps its row, with empty responses, status ``not-run`` and the reason in
    ``note``; its Fig. 6 panel says why it has no curve. When some card has a tensile
    strength target, Table 5 also has the σt columns (empty for the specimens without
    one) and ``missed``: every target the closed loop misses by more than its tolerance,
    with the error in %."""
    if len(runs) != len(cards):
        raise BadInput(f"--runs: {len(runs)} run file(s) for {len(cards)} card(s); expected "
                       "one per card, in the same order")
    loaded = [read_card(c, "--cards", need=("specimen", "parameters", "targets",
                                            "verification", "lab")) for c in cards]
    lab_df = read_lab(lab)
    outputs((table5, "--table5", CSV), (table6, "--table6", CSV), (figure, "--figure", PNG))
    t5, t6, curves = [], [], {}
    tensile = [r for r in TENSILE if any(r in c["targets"] for c in loaded)]
    for c, run in zip(loaded, runs):
        spec = str(c["specimen"])
        v = c["verification"]
        row = {"specimen": spec}
        ran = v["status"] != "not-run"
        for which in ("single_pass", "closed_loop"):
            r = v[which] if ran else None
            for k in P.TARGETS:
                row[f"{which}_{k}"] = r[k] if ran else math.nan
                sd = (r.get("seed_sd") or {}).get(k) if ran else None
                cv = (r.get("seed_cv") or {}).get(k) if ran else None  # None: one seed (NaN)
                row[f"{which}_{k}_sd"] = math.nan if sd is None else float(sd)
                row[f"{which}_{k}_cv_pct"] = math.nan if cv is None else 100 * float(cv)
                row[f"{which}_{k}_err_pct"] = r["errors_pct"][k] if ran else math.nan
        for k in P.TARGETS:
            row[f"lab_{k}"] = c["targets"][k]
        row["n_seeds"] = v.get("n_seeds", 1)
        row["rounds"] = v["rounds"]
        row["status"] = v["status"]
        row["calibration_status"] = c.get("status")
        row["note"] = v["message"] if not ran else _outside_items(v.get("outside_design") or {})
        for resp in tensile:
            has = resp in c["targets"]
            for which in ("single_pass", "closed_loop"):
                row[f"{which}_{resp}"] = v[which][resp] if ran and has else math.nan
                row[f"{which}_{resp}_err_pct"] = (v[which]["errors_pct"][resp] if ran and has
                                                  else math.nan)
                cv = (v[which].get("seed_cv") or {}).get(resp) if ran and has else None
                row[f"{which}_{resp}_cv_pct"] = math.nan if cv is None else 100 * float(cv)
            row[f"lab_{resp}"] = c["targets"][resp] if has else math.nan
        if tensile:
            row["missed"] = "; ".join(f"{m['target']} {m['error_pct']:+.2f} %"
                                      for m in v.get("missed") or [])
        t5.append(row)
        up_lab = c["lab"].get("u_pre_MJm3")
        up_sim = v["closed_loop"]["u_pre_MJm3"] if ran else math.nan
        t6.append({"specimen": spec, "sim_Up_MJm3": up_sim, "lab_Up_MJm3": up_lab,
                   "rel_error_pct": (100 * abs(up_sim - up_lab) / up_lab
                                     if up_lab and ran else math.nan),
                   "sim_peak_strain": v["closed_loop"]["peak_strain"] if ran else math.nan})
        curves[spec] = read_series(run) if ran else f"not run: {c.get('status')} calibration"
    t5 = pd.DataFrame(t5).set_index("specimen")
    t6 = pd.DataFrame(t6).set_index("specimen")
    write_table(t5, table5)
    write_table(t6, table6)
    save_figure(fig_stress_strain(curves, lab_df), figure)
    return {"table5": t5, "table6": t6}
