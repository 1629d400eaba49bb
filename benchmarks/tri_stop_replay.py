"""What a lighter stop rule would save on triaxial tests that already ran: replay the stop
check of the lab-test driver (``lab.driver.load``, formerly ``stepping.load_to_failure``)
on each run file's recorded series.

    python benchmarks/tri_stop_replay.py run RESULTS/tri --rule 0.9,0.0005 --rule 0.8,0.001 \\
        --out benchmarks/results/results_tri_stop_replay_DATE.json
    python benchmarks/tri_stop_replay.py markdown benchmarks/results/results_tri_stop_replay_DATE.json \\
        --out docs/measurements/DATE-tri-stop-replay.md

A run is deterministic, so up to a stop it is the same run: the check is made once per
record, on the deviator q and the axial strain the series holds (q below ``stop_drop`` x
the running peak, at least min(``post_peak_strain``, half the peak strain) past it). For
every rule and run: the record where the rule would stop, whether the run's peak lies
before it (then σ1 is the same), and the fraction of the run's steps it needs. The run's
own rule is replayed too: it must stop at the run's last record (a check of the replay).
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import shlex
import sys
from pathlib import Path

import numpy as np
from _study import cpu_model

from bpmcal.io.h5 import read_inputs, read_series, read_summary


def stop_index(q, eps, stop_drop: float, post_peak_strain: float) -> int | None:
    """The record at which the driver's stop check first holds, or None."""
    peak, peak_eps = -np.inf, 0.0
    for i, (s, e) in enumerate(zip(q, eps)):
        if i == 0:
            continue  # the record before the loading starts
        if s > peak:
            peak, peak_eps = s, e
        if peak > 0 and s < stop_drop * peak and e - peak_eps >= min(post_peak_strain,
                                                                    0.5 * peak_eps):
            return i
    return None


def replay(path: Path, rules) -> dict:
    s, inp, summ = read_series(path), read_inputs(path), read_summary(path)
    q, eps, steps = (np.asarray(s[k], float) for k in ("deviator", "axial_strain", "step"))
    own = (float(inp["triaxial_stop_drop"]), float(inp["triaxial_post_peak_strain"]))
    out = {"run": path.stem, "stop_reason": summ["stop_reason"], "steps": int(steps[-1]),
           "sigma1_MPa": float(summ["sigma1_MPa"]), "own_rule": list(own)}
    i_own = stop_index(q, eps, *own)
    out["own_rule_replayed"] = (i_own == len(q) - 1 if summ["stop_reason"] == "post_peak_drop"
                                else i_own is None)
    ip = int(np.argmax(q[1:])) + 1
    out["rules"] = {}
    for drop, pps in rules:
        i = stop_index(q, eps, drop, pps)
        i = len(q) - 1 if i is None else i
        out["rules"][f"{drop:g},{pps:g}"] = {"peak_kept": bool(ip <= i),
                                              "step_fraction": float(steps[i] / steps[-1])}
    return out


def run(args) -> int:
    rules = [tuple(float(x) for x in r.split(",")) for r in args.rule]
    files = sorted(Path(args.folder).glob("*.h5"))
    runs = [replay(f, rules) for f in files if read_summary(f).get("status") == "ok"]
    rec = {"date": dt.date.today().isoformat(), "cpu_model": cpu_model(),
           "command": "python benchmarks/tri_stop_replay.py " + shlex.join(sys.argv[1:]),
           "folder": str(args.folder), "note": args.note, "runs": runs,
           "n_files": len(files)}
    Path(args.out).write_text(json.dumps(rec, indent=1) + "\n")
    print(markdown(rec))
    return 0


def markdown(rec: dict) -> str:
    runs = rec["runs"]
    lines = [f"# Triaxial stop rules replayed on recorded runs ({rec['date']})", "",
             "| | |", "|---|---|", f"| date | {rec['date']} |", f"| host | {rec['cpu_model']} |",
             f"| command | `{rec['command']}` |", "",
             f"{len(runs)} finished runs of {rec['n_files']} files in `{rec['folder']}`."
             + (f" {rec['note']}" if rec.get("note") else ""), "",
             f"The runs' own rule, replayed, stops where the run stopped in "
             f"{sum(r['own_rule_replayed'] for r in runs)} of {len(runs)}.", "",
             "| rule (stop_drop, post_peak_strain) | peak kept (σ1 unchanged) | steps needed: "
             "median | min | max |", "|---|---|---|---|---|"]
    for key in runs[0]["rules"] if runs else []:
        fr = np.array([r["rules"][key]["step_fraction"] for r in runs])
        kept = sum(r["rules"][key]["peak_kept"] for r in runs)
        lines.append(f"| {key} | {kept} of {len(runs)} | {100 * np.median(fr):.0f} % | "
                     f"{100 * fr.min():.0f} % | {100 * fr.max():.0f} % |")
    total = sum(r["steps"] for r in runs)
    for key in runs[0]["rules"] if runs else []:
        saved = sum(r["steps"] * (1 - r["rules"][key]["step_fraction"]) for r in runs)
        lines.append(f"\nRule {key}: {100 * saved / total:.0f} % of all the runs' loading "
                     "steps saved.")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("folder")
    r.add_argument("--rule", action="append", required=True,
                   help="stop_drop,post_peak_strain (repeatable)")
    r.add_argument("--note", default="")
    r.add_argument("--out", required=True)
    m = sub.add_parser("markdown")
    m.add_argument("json")
    m.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    if a.cmd == "run":
        return run(a)
    Path(a.out).write_text(markdown(json.loads(Path(a.json).read_text())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
