"""The genesis share of every sample job of a finished study: the time its specimens took
to pack, bond and settle (the UCS cylinder's and the Brazilian discs') over the job's
time, from the run files the job wrote (``results/ucs/<id>.h5``, ``results/bts/<id>.h5``:
``genesis_s`` and ``wall_s`` of each test; a Brazilian run that tested several discs
records the time of all of them in ``wall_s`` and the genesis of the disc kept). The
record: the share per sample (median, largest, how many above ``--limit``) and the
samples above it, with their genesis and test times, so that the reason for each can be
read off.

    python benchmarks/study_genesis_share.py --study CLONE/results --label LABEL \\
        --out benchmarks/results/results_study_genesis_share_DATE.json \\
        --markdown docs/measurements/DATE-genesis-share.md

The times are those the runs measured in their own process (wall clock): a study run on a
busy host inflates them all alike, the share much less.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd
from _study import record_header, write_record


def shares(results: Path) -> pd.DataFrame:
    """One row per sample: the genesis and total time of its UCS and Brazilian tests."""
    from bpmcal.io.h5 import read_summary

    ds = pd.read_csv(results / "dataset.csv")
    rows = []
    for r in ds.itertuples():
        u = read_summary(results / "ucs" / f"{r.sample_id}.h5")
        bf = results / "bts" / f"{r.sample_id}.h5"
        b = read_summary(bf) if bf.is_file() else {}
        g = float(u.get("genesis_s", 0.0)) + float(b.get("genesis_s", 0.0))
        w = float(u.get("wall_s", 0.0)) + float(b.get("wall_s", 0.0))
        rows.append({"sample_id": r.sample_id, "n_balls": int(u.get("n_balls", 0)),
                     "ucs_genesis_s": float(u.get("genesis_s", 0.0)),
                     "ucs_wall_s": float(u.get("wall_s", 0.0)),
                     "bts_genesis_s": float(b.get("genesis_s", 0.0)),
                     "bts_wall_s": float(b.get("wall_s", 0.0)),
                     "bts_discs": int(b.get("discs", 1)) if b else 0,
                     "share": g / w if w > 0 else float("nan")})
    return pd.DataFrame(rows)


def record(results: Path, label: str, limit: float, argv) -> dict:
    t = shares(results)
    above = t[t["share"] > limit].sort_values("share", ascending=False)
    return {**record_header("study_genesis_share.py", argv), "study": label, "limit": limit,
            "samples": len(t),
            "share_median": float(t["share"].median()), "share_max": float(t["share"].max()),
            "n_above": int(len(above)), "genesis_total_s": float(
                (t["ucs_genesis_s"] + t["bts_genesis_s"]).sum()),
            "wall_total_s": float((t["ucs_wall_s"] + t["bts_wall_s"]).sum()),
            "above": above.to_dict("records")}


def markdown(rec: dict) -> str:
    lines = [f"# The genesis share of the sample jobs: {rec['date']}", "",
             f"Host: {rec['cpu_model']} ({rec['cpus']} CPUs); load average when recorded "
             f"{', '.join(f'{x:.2f}' for x in rec['load_average'])}. Study: {rec['study']}.",
             "", f"Command: `{rec['command']}`", "",
             f"{rec['samples']} sample jobs; genesis share (the UCS cylinder's and the "
             f"Brazilian disc's genesis over the job's two tests, each run's own wall clock): "
             f"median {100 * rec['share_median']:.1f} %, largest "
             f"{100 * rec['share_max']:.1f} %; {rec['n_above']} above "
             f"{100 * rec['limit']:.0f} %; genesis over all jobs "
             f"{100 * rec['genesis_total_s'] / rec['wall_total_s']:.1f} % of their time.", "",
             "| sample | balls (cylinder) | UCS genesis (s) | UCS run (s) | Brazilian genesis "
             "(s) | Brazilian run (s) | discs | share |", "|---|---|---|---|---|---|---|---|"]
    for r in rec["above"]:
        lines.append(f"| {r['sample_id']} | {r['n_balls']} | {r['ucs_genesis_s']:.2f} | "
                     f"{r['ucs_wall_s']:.2f} | {r['bts_genesis_s']:.2f} | "
                     f"{r['bts_wall_s']:.2f} | {r['bts_discs']} | {100 * r['share']:.1f} % |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", required=True, help="the finished study's results folder")
    ap.add_argument("--label", required=True, help="which study run this is (commit, notes)")
    ap.add_argument("--limit", type=float, default=0.2, help="the share to report above")
    ap.add_argument("--out", default=None)
    ap.add_argument("--markdown", default=None)
    a = ap.parse_args(argv)
    write_record(record(Path(a.study), a.label, a.limit, argv), a.out, a.markdown, markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
