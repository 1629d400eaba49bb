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


def gather(design: pd.DataFrame, run_files: dict) -> pd.DataFrame:
    """``run_files``: sample_id -> path of its HDF5 run file."""
    rows = []
    for rec in design.to_dict("records"):
        sid = rec["sample_id"]
        row = dict(rec)
        path = run_files.get(sid)
        if path is None or not Path(path).exists():
            row.update({c: np.nan for c in RESPONSE_COLUMNS})
            row.update(status="missing", error=f"no run file for {sid}")
        else:
            try:
                s = read_summary(path)
            except RunFileError as e:
                row.update({c: np.nan for c in RESPONSE_COLUMNS})
                row.update(status="unreadable", error=str(e))
                rows.append(row)
                continue
            row.update({c: s.get(c, np.nan) for c in RESPONSE_COLUMNS})
            row["status"] = s.get("status", "failed")
            row["error"] = s.get("error", "")
        rows.append(row)
    cols = ["sample_id", *P.PARAMS, "seed", *RESPONSE_COLUMNS, "status", "error"]
    df = pd.DataFrame(rows)
    return df[[c for c in cols if c in df.columns]]


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
    return "\n".join(lines)
