"""A measurement record of a closed loop read from its log: the per-round progress lines
that ``bpmcal verify`` and ``bpmcal transfer`` write (``closed loop round N (k seeds):
<response> <error> % (tol <tol> %), ...``), for a loop that is still running or was
stopped before it wrote its rounds table; optionally the summaries of other run files
(``--runs``: e.g. a probe of the card beside the loop).

    python benchmarks/loop_log_record.py LOG --commit SHA --title "..." --note "..." \\
        [--runs A.h5 B.h5 ...] --out benchmarks/results/results_NAME_DATE.json \\
        --markdown docs/measurements/DATE-NAME.md
"""
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from _study import record_header, write_record

from bpmcal import params as P
from bpmcal.io.h5 import read_inputs, read_summary

LINE = re.compile(r"closed loop round (\d+) \((\d+) seeds?\): (.*); (\d+) of (\d+) within tolerance")
ITEM = re.compile(r"(\w+) ([+-]\d+(?:\.\d+)?) % \(tol (\d+(?:\.\d+)?) %\)")
KEYS = ("ucs_MPa", "E_GPa", "nu", "sigma1_MPa", "sigma3_MPa", "dtt_MPa", "bts_MPa",
        "status", "stop_reason")


def rounds(log: Path) -> list[dict]:
    """Every round line of ``log``: round, seeds, per response error and tolerance (%)."""
    out = []
    for m in LINE.finditer(log.read_text(errors="replace")):
        items = {r: {"err_pct": float(e), "tol_pct": float(t)} for r, e, t in ITEM.findall(m[3])}
        out.append({"round": int(m[1]), "seeds": int(m[2]), "responses": items,
                    "within": int(m[4]), "of": int(m[5])})
    return out


def run_rows(files: list[str]) -> list[dict]:
    rows = []
    for f in files:
        s, i = read_summary(f), read_inputs(f)
        rows.append({"file": Path(f).name, "seed": i.get("seed"),
                     "params": {k: v for k, v in i.items() if k in P.ALL_PARAMS},
                     **{k: s.get(k) for k in KEYS if s.get(k) is not None}})
    return rows


def markdown(rec: dict) -> str:
    lines = [f"# {rec['title']} ({rec['date']})", "", "| | |", "|---|---|",
             f"| date | {rec['date']} |", f"| commit | {rec['commit']} |",
             f"| host | {rec['cpu_model']} ({rec['cpus']} CPUs) |",
             f"| load | {', '.join(f'{x:.2f}' for x in rec['load_average'])} |",
             f"| command | `{rec['command']}` |", "", rec["note"], ""]
    rs = rec["rounds"]
    if rs:
        resp = list(rs[0]["responses"])
        lines += [f"The loop's rounds, from `{rec['log']}` (error of the seed mean, in % of "
                  "the target; tolerance in brackets):", "",
                  "| round | seeds | " + " | ".join(resp) + " | within tolerance |",
                  "|---|---|" + "---|" * len(resp) + "---|"]
        for r in rs:
            cells = [f"{r['responses'][k]['err_pct']:+.1f} ({r['responses'][k]['tol_pct']:.1f})"
                     for k in resp]
            lines.append(f"| {r['round']} | {r['seeds']} | " + " | ".join(cells)
                         + f" | {r['within']} of {r['of']} |")
    if rec["runs"]:
        varied = [k for k in rec["runs"][0]["params"]
                  if len({r["params"].get(k) for r in rec["runs"]}) > 1]
        lines += ["", "Other runs (the parameters they differ in: "
                  + (", ".join(varied) or "none") + "):", "",
                  "| file | seed | " + " | ".join(varied + list(KEYS[:-2])) + " | status | stop |",
                  "|---|---|" + "---|" * (len(varied) + len(KEYS) - 2) + "---|---|"]
        for r in rec["runs"]:
            cells = [f"{r['params'][k]:.4g}" for k in varied]
            cells += [f"{r[k]:.4g}" if isinstance(r.get(k), float) else "–" for k in KEYS[:-2]]
            lines.append(f"| {r['file']} | {r['seed']} | " + " | ".join(cells)
                         + f" | {r.get('status', '–')} | {r.get('stop_reason', '–')} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("--commit", required=True)
    ap.add_argument("--title", required=True)
    ap.add_argument("--note", default="")
    ap.add_argument("--runs", nargs="*", default=[])
    ap.add_argument("--out", required=True)
    ap.add_argument("--markdown", required=True)
    a = ap.parse_args(argv)
    rec = {**record_header("loop_log_record.py", argv), "commit": a.commit, "title": a.title,
           "note": a.note, "log": a.log, "rounds": rounds(Path(a.log)),
           "runs": run_rows(a.runs)}
    write_record(rec, a.out, a.markdown, markdown, default=float)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
