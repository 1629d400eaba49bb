"""Gather per-sample run files into one dataset table (``results/dataset.csv``).

One row per design sample: the design (sample id, the 8 parameters, seed), the
responses of its UCS run, ``status`` and ``error``:

- "ok": the run succeeded (``error`` empty);
- "failed": the run wrote a failure record (instability, unbuildable specimen, genesis
  step budget); ``error`` is its reason;
- "missing": no run file;
- "unreadable": the run file is not a readable bpmcal run file (truncated, corrupt,
  another format); ``error`` says what is wrong with it.

No sample is ever dropped; the analysis steps use the "ok" rows and say how many they left
out.

With the Brazilian run files of the samples (the study's ``bts`` job), each row also has
:data:`BTS_COLUMNS`: ``bts_MPa`` (sigma_t), ``bts_wall_s`` and ``bts_status`` /
``bts_error`` with the same four values and meanings for the Brazilian run. The two tests
are independent: a sample whose Brazilian test failed keeps its UCS responses and its
``status`` (and the other way round); ``bts_MPa`` is NaN unless ``bts_status`` is "ok".
The sigma_t analyses use the rows whose ``bts_status`` is "ok" (:func:`tensile_view`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .. import params as P
from ..io.h5 import RunFileError, read_summary

#: response columns of the dataset, in order
RESPONSE_COLUMNS = ("ucs_MPa", "E_GPa", "nu", "peak_strain", "u_pre_MJm3", "cracks_tension",
                    "cracks_shear", "crack_init_MPa", "n_balls", "n_bonds", "coordination",
                    "porosity_achieved", "locked_in_stress_MPa", "steps", "wall_s",
                    "genesis_s", "stop_reason")


#: Brazilian columns of the dataset (when the study runs the Brazilian test): summary key
#: of the run file -> column
BTS_RESPONSES = {"bts_MPa": "bts_MPa", "wall_s": "bts_wall_s"}
BTS_COLUMNS = (*BTS_RESPONSES.values(), "bts_status", "bts_error")


def _outcome(sid: str, path, keys) -> tuple[dict, str, str]:
    """Responses (``keys`` of the summary), status and error of one run file."""
    if path is None or not Path(path).exists():
        return {k: np.nan for k in keys}, "missing", f"no run file for {sid}"
    try:
        s = read_summary(path)
    except RunFileError as e:
        return {k: np.nan for k in keys}, "unreadable", str(e)
    status = s.get("status", "failed")
    vals = {k: s.get(k, np.nan) for k in keys}
    return vals, status, s.get("error", "")


def gather(design: pd.DataFrame, run_files: dict, bts_files: dict | None = None
           ) -> pd.DataFrame:
    """``run_files``: sample_id -> path of its HDF5 UCS run file; ``bts_files`` (optional):
    sample_id -> path of its Brazilian run file."""
    rows = []
    for rec in design.to_dict("records"):
        sid = rec["sample_id"]
        row = dict(rec)
        vals, row["status"], row["error"] = _outcome(sid, run_files.get(sid), RESPONSE_COLUMNS)
        row.update(vals)
        if bts_files is not None:
            vals, status, error = _outcome(sid, bts_files.get(sid), BTS_RESPONSES)
            if status != "ok":  # a failure record's sigma_t is no measurement
                vals["bts_MPa"] = np.nan
            row.update({c: vals[k] for k, c in BTS_RESPONSES.items()})
            row.update(bts_status=status, bts_error=error)
        rows.append(row)
    cols = ["sample_id", *P.PARAMS, "seed", *RESPONSE_COLUMNS, "status", "error",
            *(BTS_COLUMNS if bts_files is not None else ())]
    df = pd.DataFrame(rows)
    return df[[c for c in cols if c in df.columns]]


def has_tensile(df: pd.DataFrame) -> bool:
    """Whether a dataset has the Brazilian columns (older datasets and studies with
    ``bts.enabled: false`` do not)."""
    return P.TENSILE in df.columns and "bts_status" in df.columns


def tensile_view(df: pd.DataFrame) -> pd.DataFrame:
    """The dataset as the sigma_t analyses see it: ``status``/``error`` are the Brazilian
    run's (a sample whose UCS run failed but whose Brazilian run is ok has a usable
    sigma_t)."""
    return df.assign(status=df["bts_status"], error=df["bts_error"].fillna(""))


def status_report(df: pd.DataFrame) -> str:
    n = len(df)
    counts = df["status"].value_counts().to_dict()
    lines = [f"{n} samples: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))]
    bad = df[df["status"] != "ok"]
    for r in bad.itertuples():
        lines.append(f"  {r.sample_id}: {r.status}: {r.error}")
    ok = df[df["status"] == "ok"]
    for c in ("ucs_MPa", "E_GPa", "nu"):
        nonfinite = int((~np.isfinite(ok[c].astype(float))).sum())
        if nonfinite:
            lines.append(f"  {nonfinite} ok samples have a non-finite {c}")
    if len(ok):
        w = ok["wall_s"].astype(float)
        lines.append(f"  run time per sample: median {w.median():.1f} s, range "
                     f"{w.min():.1f}-{w.max():.1f} s, total {w.sum() / 60:.1f} core-min")
    if has_tensile(df):
        counts = df["bts_status"].value_counts().to_dict()
        lines.append("Brazilian tests: " + ", ".join(f"{v} {k}"
                                                      for k, v in sorted(counts.items())))
        for r in df[df["bts_status"] != "ok"].itertuples():
            lines.append(f"  {r.sample_id}: bts {r.bts_status}: {r.bts_error}")
        okb = df[df["bts_status"] == "ok"]
        if len(okb):
            w = okb["bts_wall_s"].astype(float)
            lines.append(f"  Brazilian run time per sample: median {w.median():.1f} s, range "
                         f"{w.min():.1f}-{w.max():.1f} s, total {w.sum() / 60:.1f} core-min")
    return "\n".join(lines)
