"""The calibration stage (``workflow/rules/analysis.smk``, ``bpmcal calibrate``): invert the
regression models for every lab specimen, bootstrap intervals -> one material card per
specimen (``bpmcal.io.card``) and the calibration table. The ratio of the bond strengths
comes from the configuration, the ratio sweep's choice (:func:`chosen_ratio`) or, for a
specimen with a tensile-strength target, from σt itself.

The method: ``docs/methods/calibration.md``. The stage reads the files it is given,
checks them and its output paths before any work, and writes exactly the files it is
given (``bpmcal.io.study_files``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from .. import params as P
from ..analysis import PAPER_RATIO, bootstrap_intervals, invert
from ..analysis.calibration import (
    Multistart,
    SearchSpace,
    bts_strengths,
    check_calibration_space,
    tensile_target,
)
from ..analysis.calibration.reach import prediction_errors
from ..io.card import write_card
from ..io.checks import BadInput, read_json
from ..io.provenance import provenance
from ..io.tables import write_table
from ..params import BTS, TENSILE_RESPONSES
from .inputs import CSV, YAML, outputs, read_dataset, read_lab, read_models, usable
from .settings import SEED, Limit, check_fields, setting


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


@dataclass(frozen=True)
class CalibrationSettings:
    """The calibration's settings (the config's ``calibration`` section, ``bpmcal
    calibrate``'s options), checked when built: the ``fixed`` parameters (paper units),
    the ``free`` ones (None: the contact model's), the bond-strength ratio
    ``strength_ratio`` of the model's strength pair (None: both strengths free; the
    command's ``--ratio``, <= 0 there), the ``bounds`` narrowing the design ranges of free
    parameters, the bootstrap's resamples ``n_boot`` (0: none, else >= 2) and the
    ``seed`` of the inversion's starts and the bootstrap."""

    fixed: dict
    free: tuple | None = None
    strength_ratio: float | None = setting(
        PAPER_RATIO, Limit("float", 0.0, 20.0, lo_open=True, null=True,
                           what="the ratio of the strength pair; none: both free"))
    bounds: dict = field(default_factory=dict)
    n_boot: int = setting(200, Limit("int", 0, 100_000, what="bootstrap resamples"))
    seed: int = setting(13, SEED)

    def __post_init__(self):
        check_fields(self)
        fixed = self.fixed
        if not isinstance(fixed, dict):
            raise BadInput(f"--fixed {fixed!r}: expected a JSON object of parameter values")
        try:
            fixed = P.validate_params(fixed, require_all=False)
        except P.ParameterError as e:
            raise P.ParameterError(f"--fixed: {e}") from None
        object.__setattr__(self, "fixed", fixed)
        if self.n_boot == 1:
            raise P.ParameterError(f"--n-boot {self.n_boot}: expected 0 (no bootstrap) or an "
                                   "integer >= 2")
        free = self.free
        if free is not None:
            free = tuple(free)
            object.__setattr__(self, "free", free)
        if free:
            bad = [f for f in free if f not in P.ALL_PARAMS]
            if bad:
                known = P.model_of({**fixed, **dict.fromkeys(f for f in free
                                                             if f in P.ALL_PARAMS)})
                raise BadInput(f"--free {','.join(free)}: unknown parameter(s) {bad}; "
                               f"expected names from {list(known.params)}")
        bounds = {} if self.bounds is None else self.bounds
        if not isinstance(bounds, dict):
            raise BadInput(f"--bounds: expected a JSON mapping of parameter name to "
                           f"[low, high] (paper units), got {bounds!r}")
        object.__setattr__(self, "bounds", dict(bounds))


def calibrate(dataset, models, lab, *, cards, ranges: dict, settings: CalibrationSettings,
              ratio_from=None, table=None) -> dict:
    """Invert the final regression models for every lab specimen; bootstrap intervals;
    one material card per specimen: ``cards`` holds one file per lab specimen, named
    ``<specimen>.yaml`` (``bpmcal.io.study_files``); ``table``: the calibration table (optional).
    ``ranges`` is the design space the dataset was sampled over (the config's ``ranges``)
    and bounds the free parameters; ``settings`` (:class:`CalibrationSettings`) may narrow
    it. ``ratio_from``: the strength-ratio sweep's chosen JSON (its ratio replaces
    ``settings.strength_ratio`` when it chose one). ``n_boot=0`` skips the bootstrap (the
    initial calibration that only seeds the strength-ratio sweep needs the point estimate).

    Every card records the configured ``ranges``, the effective ``bounds`` of the calibrated
    parameters with the configured key each side comes from, and, when the targets are not
    met, ``widen``: which configured limit to move and how far (see
    :func:`bpmcal.analysis.invert`). Returns the table and a note on the ratio.

    A specimen whose lab row gives ``bts_MPa`` is also calibrated against σt (a ``bts_MPa``
    model in ``models`` is then required): σt sets its bond-strength ratio
    (:func:`bpmcal.analysis.calibration.bts_strengths`: ``pb_ten_MPa`` free, the card's
    ``ratio_ten_coh`` null), instead of the configured ratio or the sweep's choice. When
    the set of targets cannot be met at once (e.g. a σc/σt beyond the parallel-bond
    model's) the card is ``no-exact-fit``, keeps the least-squares compromise and lists
    every missed target (``missed``: target, value, predicted, error_pct) and what the
    models reach (``reach``). Every card records ``strength_ratio``: the ratio pb_ten/pb_coh
    of its parameters and what set it (:func:`_ratio_set_by`)."""
    lab_df = read_lab(lab)
    fixed, free, bounds = settings.fixed, settings.free, settings.bounds
    n_boot, seed = settings.n_boot, settings.seed
    ratio, note, jobs, with_bts = _check_calibrate_inputs(lab_df, cards, settings, ranges,
                                                          ratio_from)
    by_spec = {Path(c).stem: c for c in cards}
    df = read_dataset(dataset)
    model_set = read_models(models)
    _check_tensile_models(jobs, model_set, df, dataset, models, lab, n_boot)
    outputs(*((c, "--cards", YAML) for c in cards), (table, "--table", CSV))
    dnote = usable(df)
    errors = prediction_errors(df, model_set)  # a miss within them is no verdict
    if with_bts:
        note = "; ".join(x for x in (note, (
            f"the tensile strength sets the bond-strength ratio of {with_bts} "
            "(pb_ten_MPa free; the configured or swept ratio is not used for them)")) if x)
    rows = []
    for rec, targets in jobs:
        spec = str(rec["specimen"])
        s_free, s_ratio, ratio_by = bts_strengths(targets, free, fixed, ratio)
        space = SearchSpace(ranges=ranges, free=s_free, ratio=s_ratio, bounds=bounds)
        inv = invert(model_set, targets, fixed, space, search=Multistart(seed=seed),
                     errors=errors, target_se=lab_target_se(rec, targets))
        if n_boot:
            boot = bootstrap_intervals(df, model_set, targets, fixed, space, n_boot=n_boot,
                                       seed=seed)
            bootstrap = {"n_boot": n_boot, "scheme": boot.scheme,
                         "unreachable_resamples": boot.n_unreachable,
                         "intervals": boot.intervals.reset_index().to_dict("records")}
        else:
            bootstrap = {"n_boot": 0, "scheme": None, "unreachable_resamples": None,
                         "intervals": []}
        set_by = _ratio_set_by(ratio_by, s_ratio, ratio_from, note)
        card = calibration_card(
            spec, inv, rec, targets, ratio=s_ratio, set_by=set_by, bounds=bounds,
            bootstrap=bootstrap, dataset_note=dnote,
            provenance_record=provenance({"dataset": str(dataset), "models": str(models),
                                   "lab": str(lab), "fixed": fixed, "ratio": ratio,
                                   "seed": seed, "ranges": ranges, "bounds": bounds}))
        write_card(by_spec[spec], card)
        rows.append({"specimen": spec, "status": inv.status, **card["parameters"],
                     **{f"pred_{k}": v for k, v in inv.predicted.items()}})
    out = pd.DataFrame(rows).set_index("specimen")
    if table is not None:
        write_table(out, table)
    return {"table": out, "note": note}


def _check_calibrate_inputs(lab_df: pd.DataFrame, cards, settings: CalibrationSettings, ranges,
                            ratio_from) -> tuple[float | None, str, list, list]:
    """The checks :func:`calibrate` makes before it reads the dataset (``settings`` were
    checked when built): one card per lab specimen, valid ``ranges`` and a valid
    calibration space (also with σt setting the ratio, for the specimens with a tensile
    target). Returns the ratio used (:func:`chosen_ratio`), the note on it, the jobs (each
    lab row and its targets) and the specimens with a tensile target."""
    specs = [str(s) for s in lab_df["specimen"]]
    by_spec = {Path(c).stem: c for c in cards}
    if sorted(by_spec) != sorted(specs) or len(by_spec) != len(cards):
        raise BadInput(f"--cards {' '.join(map(str, cards))}: expected one card per lab "
                       f"specimen, named <specimen>.yaml: {specs}")
    ratio, note = chosen_ratio(ratio_from, settings.strength_ratio)
    if not isinstance(ranges, dict):
        raise BadInput(f"--ranges: expected a JSON mapping of parameter name to "
                       f"[low, high] (paper units), got {ranges!r}")
    free, fixed, bounds = settings.free, settings.fixed, settings.bounds
    check_calibration_space(free, fixed, ratio, ranges, bounds)
    jobs = [(rec, lab_targets(rec)) for rec in lab_df.to_dict("records")]
    with_bts = [str(rec["specimen"]) for rec, t in jobs if tensile_target(t)]
    if with_bts:  # σt sets the ratio of these specimens: their space must be valid too
        f_bts, r_bts, _ = bts_strengths({BTS: 1.0}, free, fixed, ratio)
        check_calibration_space(f_bts, fixed, r_bts, ranges, bounds)
    return ratio, note, jobs, with_bts


def _check_tensile_models(jobs: list, model_set, df: pd.DataFrame, dataset, models, lab, n_boot) -> None:
    """A specimen with a tensile-strength (or design-confinement triaxial strength) target
    needs its model (and, for the bootstrap, its dataset column)."""
    for resp in P.SAMPLE_TESTS:
        having = [str(rec["specimen"]) for rec, t in jobs if resp in t]
        if not having:
            continue
        test = {BTS: "a Brazilian", "dtt_MPa": "a direct-tension"}.get(
            resp, "a triaxial (triaxial.design_sigma3_MPa)")
        what = "a triaxial strength" if resp == P.TRI else "a tensile strength"
        if resp not in model_set:
            raise BadInput(f"--lab {lab}: specimen(s) {having} have {what} "
                           f"({resp}) but --models {models} has no model of {resp}: run the "
                           f"study with {test} test per sample, or leave {resp} empty")
        if n_boot and resp not in df.columns:
            raise BadInput(f"--dataset {dataset}: no {resp} column, which the bootstrap of "
                           f"the {resp} target of {having} refits")


def calibration_card(spec: str, inv, rec: dict, targets: dict, *, ratio: float | None, set_by: str,
                     bounds: dict, bootstrap: dict, dataset_note: str, provenance_record: dict) -> dict:
    """The material card of one lab specimen (``bpmcal.io.card``) from its inversion ``inv``
    (:class:`~bpmcal.analysis.InversionResult`), its lab row ``rec`` and ``targets``:
    ``ratio`` is the configured ratio of its inversion (None: both strengths free),
    ``set_by`` what set the strength ratio, ``bounds`` the configured narrowings."""
    model = P.model_of(inv.solution)
    ten, coh = model.strength
    names = [k for k in model.params if k in inv.solution]
    return {
        "specimen": spec,
        "status": inv.status,
        "message": inv.message,
        "ratio_ten_coh": ratio,
        "strength_ratio": {
            "value": float(inv.solution[ten] / inv.solution[coh]),
            "set_by": set_by},
        "parameters": {k: float(inv.solution[k]) for k in names},
        "roles": {k: ("free" if k in inv.free else "derived" if k in inv.derived
                      else "fixed") for k in names},
        "ranges": {k: [float(a), float(b)] for k, (a, b) in inv.ranges.items()},
        "calibration_bounds": {k: [float(a), float(b)] for k, (a, b) in bounds.items()},
        "bounds": {k: {"lower": lo, "upper": hi, "lower_from": inv.bound_origins[k]["lower"],
                       "upper_from": inv.bound_origins[k]["upper"]}
                   for k, (lo, hi) in inv.bounds.items()},
        "at_bound": [{"parameter": p, "side": side, "value": v} for p, side, v in inv.at_bound],
        "widen": inv.widen,
        "advice": inv.advice,
        "targets": targets,
        **({"target_se": se} if (se := lab_target_se(rec, targets)) else {}),
        "lab": {k: (None if (isinstance(v, float) and not math.isfinite(v)) else v)
                for k, v in rec.items() if k != "specimen"},
        "predicted": inv.predicted,
        "residuals_pct": {k: 100 * v for k, v in inv.residuals.items()},
        "missed": inv.missed,
        "reach": inv.reach,
        **({"reach_test": inv.reach_test} if inv.reach_test else {}),
        "alternatives": inv.alternatives.to_dict("records"),
        "bootstrap": bootstrap,
        "dataset_note": dataset_note,
        "provenance": provenance_record,
    }


def lab_targets(rec: dict) -> dict:
    """The calibration targets of one lab row: σc, E, ν, and σt when the row gives it:
    the Brazilian tensile strength (``bts_MPa``) or the direct-tension strength
    (``dtt_MPa``), an alternative (``study.config.read_lab`` refuses a row with both);
    and σ1 at the design confinement (``tri_MPa``) when the row gives it. An empty
    optional value is not a target."""
    targets = {k: float(rec[k]) for k in P.TARGETS}
    for r in P.SAMPLE_TESTS:
        v = rec.get(r)
        if v is not None and math.isfinite(float(v)):
            targets[r] = float(v)
    return targets


def lab_target_se(rec: dict, targets: dict) -> dict:
    """The standard errors the lab row gives for its targets (``<target>_se`` columns,
    :data:`bpmcal.study.lab_data.LAB_SE`; empty = none): target -> value."""
    out = {}
    for r in targets:
        v = rec.get(f"{r}_se")
        if v is not None and math.isfinite(float(v)):
            out[r] = float(v)
    return out


def _ratio_set_by(ratio_by: str, ratio: float | None, ratio_from, note: str) -> str:
    """What set a card's strength ratio (its ``strength_ratio.set_by``): a tensile target
    (``ratio_by``, :func:`~bpmcal.analysis.calibration.bts_strengths`), the ratio sweep
    (``ratio_from`` and no fallback in ``note``), the configured ``ratio`` or nothing."""
    return (f"{ratio_by} target" if ratio_by in TENSILE_RESPONSES else
            "ratio sweep" if ratio_from and not note_is_fallback(note)
            # the card-format-1 spelling, kept (the key is calibration.strength_ratio)
            else "config calibration.ratio" if ratio is not None
            else "both strengths free")


def note_is_fallback(note: str) -> bool:
    """Whether :func:`chosen_ratio`'s note says the sweep chose no ratio (the configured
    one was used)."""
    return "the sweep chose no ratio" in note
