"""The screening stage (``workflow/rules/analysis.smk``, ``bpmcal screen``): XGBoost
importance screening of the dataset -> the selected candidates, Table 3, the importance
figure and the supplementary tables; σt (Brazilian or direct tension) is screened on the
samples whose tensile test is valid (:func:`tensile_note` says how many).

The stage reads the files it is given, checks them and its output paths before any work,
and writes exactly the files it is given (``bpmcal.io.study_files``).
"""
from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from .. import params as P
from ..analysis import XGBScreening, table3, table3_markdown
from ..analysis._common import dataset_params, usable_rows
from ..analysis.screening import IMPORTANCE_TYPES, RULES
from ..analysis.screening import combine as combine_screenings
from ..io.atomic import write_text
from ..io.checks import BadInput
from ..io.figures import save_figure
from ..io.provenance import provenance
from ..io.tables import write_json, write_table
from ..plots.calibration import fig_importance
from ..study.gather import tensile_responses, tensile_view
from . import defaults_of
from .inputs import CSV, JSON, PNG, TXT, outputs, read_dataset, usable
from .settings import SEED, Limit, check_fields, setting

#: the defaults of the stage are those of the analysis it runs
_SCREEN = defaults_of(XGBScreening)
#: the selection rule of σt, which the paper does not screen: every parameter is a
#: candidate and the stepwise regression chooses (analysis.screening, docs/measurements)
TENSILE_RULE = "all"


@dataclass(frozen=True)
class ScreeningSettings:
    """The screening's settings (the config's ``screening`` section, ``bpmcal screen``'s
    options; ``threshold`` is the key ``threshold_pct``), checked when built: the
    selection ``threshold`` [%], the ``importance`` type that drives it, the selection
    ``rule`` of σc, E and ν and ``tensile_rule`` of σt (``analysis.screening.RULES``), the
    CV folds ``n_splits``, the permutation repeats ``n_repeats`` and the ``seed``."""

    threshold: float = setting(_SCREEN["threshold"], Limit("float", 0.0, 100.0))
    importance: str = setting(_SCREEN["importance"], Limit("choice", words=IMPORTANCE_TYPES))
    rule: str = setting(_SCREEN["rule"], Limit("choice", words=RULES))
    tensile_rule: str = setting(TENSILE_RULE, Limit("choice", words=RULES))
    n_splits: int = setting(_SCREEN["n_splits"], Limit("int", 2, 20))
    n_repeats: int = setting(_SCREEN["n_repeats"], Limit("int", 1, 100))
    seed: int = setting(_SCREEN["seed"], SEED)

    def __post_init__(self):
        check_fields(self)


def screen(dataset, *, selected, table3_csv, figure, importance_table, cv_table,
           shadow_table, summary, settings: ScreeningSettings = ScreeningSettings()) -> dict:
    """XGBoost screening of ``dataset`` -> ``selected`` (JSON), Table 3, the importance
    figure and the supplementary tables (every importance type, CV R², shadow maxima) and
    ``summary`` (text), as ``settings`` say (:class:`ScreeningSettings`: ``rule`` selects
    the candidates of σc, E and ν, ``tensile_rule`` those of σt). Returns the selection
    and the note on left-out samples."""
    s = settings
    threshold, importance, n_splits, seed = s.threshold, s.importance, s.n_splits, s.seed
    n_repeats, rule, tensile_rule = s.n_repeats, s.rule, s.tensile_rule
    df = read_dataset(dataset, min_ok=4)  # the smallest K-fold CV (2 folds) needs 4 rows
    outputs((selected, "--selected", JSON), (table3_csv, "--table3", CSV),
            (figure, "--figure", PNG), (importance_table, "--importance-table", CSV),
            (cv_table, "--cv-table", CSV), (shadow_table, "--shadow-table", CSV),
            (summary, "--summary", TXT))
    note = usable(df)
    designed = dataset_params(df)
    n_ok = usable_rows(df, [*designed, *P.TARGETS]).n_used
    if n_ok < 2 * n_splits:  # failed samples left too few rows for the configured CV
        k = n_ok // 2
        if k < 2:
            raise BadInput(f"--dataset {dataset}: only {n_ok} usable samples (status ok, "
                           "finite responses); the screening needs at least 4 - see the "
                           "dataset's status and error columns")
        note += f"; {n_splits}-fold CV needs {2 * n_splits} usable samples, so {k}-fold CV was used"
        n_splits = k
    res = XGBScreening(designed, n_splits=n_splits, threshold=threshold, importance=importance,
                       n_repeats=n_repeats, seed=seed, rule=rule).fit(df)
    for resp in tensile_responses(df):  # sigma_t, sigma1(sigma3): on the samples whose test is valid
        tv = tensile_view(df, resp)
        test = P.SAMPLE_TESTS[resp]
        n_t = usable_rows(tv, [*designed, resp]).n_used
        k = min(n_splits, n_t // 2)
        if k < 2:
            note += (f"; {resp} not screened: {n_t} samples have a valid {_TEST_NAME[test]} "
                     f"test, at least 4 are needed (see the dataset's {test}_status and "
                     f"{test}_error)")
        else:
            note += f"; {_RESP_NAME[resp]}: {tensile_note(tv, test)}"
            res = combine_screenings(res, XGBScreening(
                designed, responses=(resp,), n_splits=k, threshold=threshold, importance=importance,
                n_repeats=n_repeats, seed=seed,
                rule=tensile_rule if resp in P.TENSILE_TESTS else rule).fit(tv))
    write_table(table3(res, importance=importance), table3_csv,
                markdown=table3_markdown(res, importance=importance))
    write_table(res.to_frame(), importance_table)
    write_table(res.cv_r2, cv_table)
    write_table(res.shadow_max, shadow_table)
    sel = {r: list(v) for r, v in res.selected.items()}
    write_json(selected, {"selected": sel, "threshold_pct": threshold, "importance": importance,
                          "rule": {r: res.rule_of(r) for r in res.responses}, "note": note,
                          "provenance": provenance({"dataset": str(dataset), "seed": seed})})
    write_text(summary, res.summary() + "\n" + note + "\n")
    save_figure(fig_importance(res.to_frame(), res.shadow_max, importance, threshold), figure)
    return {"selected": sel, "note": note}


#: the tensile tests by name, for notes
_TEST_NAME = {"bts": "Brazilian", "dtt": "direct-tension", "tri": "triaxial"}
_RESP_NAME = {"bts_MPa": "sigma_t", "dtt_MPa": "sigma_t (direct tension)",
              "tri_MPa": "sigma1 at the design sigma3"}


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
