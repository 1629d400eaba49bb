"""Gather per-sample run files into one dataset table (``results/dataset.csv``).

One row per design sample: the design (sample id, the 8 parameters, seed), the
responses of its UCS run, ``status`` and ``error``:

- "ok": the run succeeded (``error`` empty);
- "failed": the run wrote a failure record (instability, unbuildable specimen, genesis
  step budget); ``error`` is its reason;
- "missing": no run file;
- "unreadable": the run file is not a readable bpmcal run file (truncated, corrupt,
  another format); ``error`` says what is wrong with it.

- "incomplete": the run's loading stopped at a cut-off (``max_strain``, ``max_steps``)
  before the peak and the drop that define sigma_c (``lab.registry.incomplete_reason``);
  its measurement columns (:data:`MEASURES`) are NaN, ``error`` says why.

No sample is ever dropped; the analysis steps use the "ok" rows and say how many they left
out. Every run file must be the run of its design row: the test, the packing seed and the
parameters it records are checked against the row (:func:`check_run_of`), and a run file of
another test, seed or sample under a sample's name is refused (``BadInput``).

With the Brazilian run files of the samples (the study's ``bts`` job), each row also has
:data:`BTS_COLUMNS`: ``bts_MPa`` (sigma_t), ``bts_wall_s``, ``bts_status`` /
``bts_error`` with the same four values and meanings for the Brazilian run plus a fifth,

- "invalid": the run finished but is no valid Brazilian test (ISRM: its fracture did not
  start in the central zone, or did not split the disc along the loaded diameter;
  ``lab.validity``); ``bts_error`` is the reason,

and ``bts_valid`` (the run's verdict; empty for a run file without one), ``bts_peak_MPa``
(2 P / (pi D t) at the peak load: the number an invalid run measured, kept for inspection,
never a sigma_t), ``bts_balls_across`` (the disc's diameter in mean ball diameters) and
``bts_discs`` (the discs tested: more than one when an invalid disc was discarded and
another tested, ``bts.retests``; empty for a run file from before).
The two tests are independent: a sample whose Brazilian test failed keeps its UCS
responses and its ``status`` (and the other way round); ``bts_MPa`` is NaN unless
``bts_status`` is "ok". The sigma_t analyses use the rows whose ``bts_status`` is "ok"
(:func:`tensile_view`) and say how many they left out, and why.

The direct-tension test (``dtt``) gives the same columns under ``dtt_``; the triaxial
test at the design confinement (``tri``, ``triaxial.design_sigma3_MPa``) gives
:data:`TRI_COLUMNS` (``tri_MPa``: sigma1 at failure, ``tri_sigma3_MPa``, ``tri_wall_s``,
``tri_status``, ``tri_error``; no validity check: a run is ok or failed).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from .. import params as P
from ..io.checks import BadInput
from ..io.h5 import RunFileError, check_run_file, read_inputs, read_summary
from ..io.safe_names import clip, printable, shown
from ..lab.registry import SAMPLE_KINDS

#: response columns of the dataset, in order
RESPONSE_COLUMNS = ("ucs_MPa", "E_GPa", "nu", "peak_strain", "u_pre_MJm3", "cracks_tension",
                    "cracks_shear", "crack_init_MPa", "n_balls", "n_bonds", "coordination",
                    "porosity_achieved", "locked_in_stress_MPa", "steps", "wall_s",
                    "genesis_s", "stop_reason")


#: the per-sample tests besides the UCS test (``P.SAMPLE_TESTS``), by their sample key: the
#: Brazilian (``bts``), direct-tension (``dtt``) and triaxial test at the design confinement
#: (``tri``, ``triaxial.design_sigma3_MPa``; its sigma1 at failure is ``tri_MPa``), when the
#: study runs them: their summary keys -> dataset columns and the columns in order
#: (``lab.registry.LAB_TESTS``' ``responses`` and ``columns``)
_SAMPLE = {key: k for key, k in SAMPLE_KINDS.items() if key != "ucs"}
BTS_RESPONSES, BTS_COLUMNS = _SAMPLE["bts"].responses, _SAMPLE["bts"].columns
DTT_RESPONSES, DTT_COLUMNS = _SAMPLE["dtt"].responses, _SAMPLE["dtt"].columns
TRI_RESPONSES, TRI_COLUMNS = _SAMPLE["tri"].responses, _SAMPLE["tri"].columns
#: test -> (summary key -> column, the columns in order)
TEST_COLUMNS = {key: (k.responses, k.columns) for key, k in _SAMPLE.items()}
#: ``<test>_status`` of a finished run that is no valid test
INVALID = "invalid"
#: what an invalid run of each test is (the tests with a validity check)
_INVALID_WHAT = {key: k.invalid_what for key, k in _SAMPLE.items() if k.invalid_what}
#: the tests by name, for the status report
_TEST_TITLE = {"bts": "Brazilian", "dtt": "Direct-tension", "tri": "Triaxial (design sigma3)"}


#: summary keys that hold text or a verdict, not a number
_TEXT_KEYS = ("stop_reason", "bts_invalid_reason", "dtt_invalid_reason")
_BOOL_KEYS = ("bts_valid", "dtt_valid")
#: the UCS responses that are measurements (NaN in a row whose run is not "ok": an
#: incomplete run's stress at its cut-off is no sigma_c); the rest describe the run
MEASURES = ("ucs_MPa", "E_GPa", "nu", "peak_strain", "u_pre_MJm3", "crack_init_MPa")
#: the test a run file of each of a sample's runs records (``io.h5``'s ``test``)
RUN_TEST = {key: k.name for key, k in SAMPLE_KINDS.items()}


def _bad_value(k: str, v) -> bool:
    """Whether summary value ``v`` of key ``k`` is not what a run file holds there (a
    damaged or crafted file: text where a number belongs, an array)."""
    if k in _TEXT_KEYS:
        return not isinstance(v, str)
    if k in _BOOL_KEYS:
        return not isinstance(v, (bool, np.bool_))
    return isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer,
                                                                 np.floating))


def _absent(v) -> bool:
    """A design row's or run file's value that is not there (None, NaN, empty)."""
    if v is None or (isinstance(v, str) and not v.strip()):
        return True
    try:
        return math.isnan(float(v))
    except (TypeError, ValueError):
        return False


def check_run_of(path, rec: dict, model: P.ContactModel, kind: str) -> None:
    """A BadInput naming ``path`` unless its run is the one of design row ``rec`` (its
    ``sample_id``, the ``model``'s parameters, ``seed``): test ``RUN_TEST[kind]``, the same
    packing seed and parameters (to 1e-9). A run file of another test, seed or sample
    under a sample's name would be gathered as that sample's response."""
    s = check_run_file(path)
    sid = rec["sample_id"]
    what = f"{path}: not the {kind} run of design sample {sid}"
    if s.get("test") != RUN_TEST[kind]:
        raise BadInput(f"{what}: a run file of test {shown(s.get('test'))}, expected "
                       f"{RUN_TEST[kind]!r}")
    inp = read_inputs(path)
    got_model = inp.get("contact_model", P.DEFAULT_CONTACT_MODEL)
    if got_model != model.name:
        raise BadInput(f"{what}: its card is {shown(got_model)}, the design's {model.name}")
    quiet = {k: (model.defaults or {}).get(k) for k in model.quiet}
    for k in ("seed", *model.params):
        want, got = rec.get(k), inp.get(k)
        if k in quiet:  # an optional key left out at its default (no strength scatter)
            want = quiet[k] if _absent(want) else want
            got = quiet[k] if _absent(got) else got
        try:
            same = math.isclose(float(got), float(want), rel_tol=1e-9, abs_tol=1e-12) or (
                math.isnan(float(got)) and math.isnan(float(want)))
        except (TypeError, ValueError):
            same = False
        if not same:
            raise BadInput(f"{what}: its {k}={shown(got)}, the design row's {shown(want)} "
                           "(run it again: the design changed, or the file is another's)")


def _outcome(sid: str, path, keys) -> tuple[dict, str, str]:
    """Responses (``keys`` of the summary), status and error of one run file; a value of
    the wrong kind makes the file "unreadable"."""
    if path is None or not Path(path).exists():
        return {k: np.nan for k in keys}, "missing", f"no run file for {sid}"
    try:
        s = read_summary(path)
    except RunFileError as e:
        return {k: np.nan for k in keys}, "unreadable", str(e)
    status = s.get("status", "failed")
    vals = {k: s.get(k, np.nan) for k in keys}
    bad = [k for k, v in vals.items() if k in s and _bad_value(k, v)]
    if bad:
        return ({k: np.nan for k in keys}, "unreadable",
                f"{path}: summary {bad[0]}={shown(vals[bad[0]])}: not a value a run file "
                "holds there (damaged, or not written by bpmcal)")
    if status != "ok":  # no measurement (a failure record, or an incomplete run)
        vals.update({k: np.nan for k in MEASURES if k in vals})
    return vals, status, str(s.get("error", ""))


def _test_outcome(sid: str, path, test: str) -> dict:
    """The dataset columns of one sample's run file of a per-sample test (``test``:
    "bts", "dtt", "tri"): its responses, and its status, with "invalid" for a finished
    run that failed the test's validity check (the tensile tests; no strength value, the
    reason in ``<test>_error``)."""
    keys, _ = TEST_COLUMNS[test]
    checked = test in _INVALID_WHAT
    vals, status, error = _outcome(sid, path, [*keys, *([f"{test}_invalid_reason"]
                                                        if checked else [])])
    if checked:
        reason = vals.pop(f"{test}_invalid_reason")
        valid = vals.get(f"{test}_valid")
        if status == "ok" and isinstance(valid, (bool, np.bool_)) and not valid:
            status = INVALID  # finished, but not a valid test: no strength
            error = str(reason) if isinstance(reason, str) and reason else \
                f"not a valid {'Brazilian' if test == 'bts' else 'direct-tension'} test"
        if not isinstance(valid, (bool, np.bool_)):
            vals[f"{test}_valid"] = np.nan
    strength = next(k for k, c in keys.items() if c == f"{test}_MPa")
    if status != "ok":  # a failure record's or an invalid run's value is no measurement
        vals[strength] = np.nan
    row = {c: vals[k] for k, c in keys.items()}
    row.update({f"{test}_status": status, f"{test}_error": error})
    return row


def gather(design: pd.DataFrame, run_files: dict, bts_files: dict | None = None,
           dtt_files: dict | None = None, tri_files: dict | None = None) -> pd.DataFrame:
    """``run_files``: sample_id -> path of its HDF5 UCS run file; ``bts_files``,
    ``dtt_files`` and ``tri_files`` (optional): sample_id -> path of its Brazilian /
    direct-tension / design-confinement triaxial run file."""
    tests = {t: f for t, f in (("bts", bts_files), ("dtt", dtt_files), ("tri", tri_files))
             if f is not None}
    model = P.model_of(design.columns)
    rows = []
    for rec in design.to_dict("records"):
        sid = rec["sample_id"]
        for kind, files in (("ucs", run_files), *tests.items()):
            f = files.get(sid)
            if f is not None and Path(f).exists():
                try:
                    check_run_of(f, rec, model, kind)
                except RunFileError:
                    pass  # an unreadable file: its row says so
        row = dict(rec)
        vals, row["status"], row["error"] = _outcome(sid, run_files.get(sid), RESPONSE_COLUMNS)
        row.update(vals)
        for test, files in tests.items():
            row.update(_test_outcome(sid, files.get(sid), test))
        rows.append(row)
    cols = ["sample_id", *model.params, "seed", *RESPONSE_COLUMNS, "status", "error",
            *(c for t in tests for c in TEST_COLUMNS[t][1])]
    df = pd.DataFrame(rows)
    return df[[c for c in cols if c in df.columns]]


def has_tensile(df: pd.DataFrame, response: str = P.BTS) -> bool:
    """Whether a dataset has the columns of a per-sample test's response (``P.SAMPLE_TESTS``:
    ``bts_MPa`` by default, ``dtt_MPa``, ``tri_MPa``; older datasets and studies without
    that test do not)."""
    test = P.SAMPLE_TESTS[response]
    return response in df.columns and f"{test}_status" in df.columns


def tensile_responses(df: pd.DataFrame) -> list[str]:
    """The responses of the per-sample tests a dataset has (``P.SAMPLE_TESTS`` order: the
    tensile strengths, then the design-confinement triaxial strength)."""
    return [r for r in P.SAMPLE_TESTS if has_tensile(df, r)]


def tensile_view(df: pd.DataFrame, response: str = P.BTS) -> pd.DataFrame:
    """The dataset as the analyses of a per-sample test's response see it: ``status``/
    ``error`` are its test's (a sample whose UCS run failed but whose tensile or triaxial
    run is ok has a usable strength; an invalid or failed run leaves the row out)."""
    test = P.SAMPLE_TESTS[response]
    return df.assign(status=df[f"{test}_status"], error=df[f"{test}_error"].fillna(""))


def status_report(df: pd.DataFrame) -> str:
    n = len(df)
    counts = df["status"].value_counts().to_dict()
    lines = [f"{n} samples: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))]
    bad = df[df["status"] != "ok"]
    for r in bad.itertuples():
        lines.append(f"  {r.sample_id}: {r.status}: {printable(clip(r.error, 500))}")
    ok = df[df["status"] == "ok"]
    for c in ("ucs_MPa", "E_GPa", "nu"):
        nonfinite = int((~np.isfinite(ok[c].astype(float))).sum())
        if nonfinite:
            lines.append(f"  {nonfinite} ok samples have a non-finite {c}")
    if len(ok):
        w = ok["wall_s"].astype(float)
        lines.append(f"  run time per sample: median {w.median():.1f} s, range "
                     f"{w.min():.1f}-{w.max():.1f} s, total {w.sum() / 60:.1f} core-min")
    for resp in tensile_responses(df):
        test = P.SAMPLE_TESTS[resp]
        name = _TEST_TITLE[test]
        counts = df[f"{test}_status"].value_counts().to_dict()
        lines.append(f"{name} tests: " + ", ".join(f"{v} {k}"
                                                   for k, v in sorted(counts.items()))
                     + (f" (invalid: {_INVALID_WHAT[test]}; no strength)"
                        if counts.get(INVALID) else ""))
        for r in df[df[f"{test}_status"] != "ok"].itertuples():
            lines.append(f"  {r.sample_id}: {test} {getattr(r, f'{test}_status')}: "
                         f"{printable(clip(getattr(r, f'{test}_error'), 500))}")
        discs = df.get(f"{test}_discs")
        if discs is not None and (discs.astype(float) > 1).any():
            d = discs.astype(float)
            first = int(((d == 1) & (df[f"{test}_status"] == "ok")).sum())
            lines.append(f"  {int((d > 1).sum())} samples had an invalid first disc and "
                         f"tested another ({int((d - 1).clip(lower=0).sum())} discs "
                         f"discarded, their reasons in the run files); first discs valid: "
                         f"{first} of {int(d.notna().sum())}")
        okb = df[df[f"{test}_status"] == "ok"]
        if len(okb):
            w = okb[f"{test}_wall_s"].astype(float)
            lines.append(f"  {name} run time per sample: median {w.median():.1f} s, range "
                         f"{w.min():.1f}-{w.max():.1f} s, total {w.sum() / 60:.1f} core-min")
    return "\n".join(lines)
