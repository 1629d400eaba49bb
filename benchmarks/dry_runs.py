"""The test suite's Snakemake dry runs, two ways side by side: a new interpreter per dry
run (``python -m snakemake -n``) against a fork of a process that has Snakemake imported
(``tests/support/repo.py``: ``run_snakemake`` does this for a command that runs no job).
The workflow tests make a few hundred dry runs (the rerun-map test one per config key).

    python benchmarks/dry_runs.py --runs 60 --out benchmarks/results/results_dry_runs_DATE.json

Each way runs ``--runs`` dry runs of the smoke config in the repository, two at a time as
the rerun-map test does; the ways alternate in blocks of 20 so a change of load hits both.
Prints and records the wall time per dry run (total wall / runs, two at a time), the
host's busy CPU time per dry run (``/proc/stat``: every process on the host, so run it on
a quiet machine; the forked dry runs are children of the fork server, which no rusage of
this process counts), and whether every dry run's job table was the same.
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

from _study import REPO, cpu_model

sys.path.insert(0, str(REPO / "tests"))
from support.repo import run_snakemake, scheduled_jobs  # noqa: E402

ARGS = ["-n", "--nolock", "--configfile", "config/smoke.yaml"]


def _subprocess(_):
    return subprocess.run([sys.executable, "-m", "snakemake", *ARGS], cwd=REPO,
                          capture_output=True, text=True)


def _forked(_):
    return run_snakemake(REPO, *ARGS)


def _busy_s() -> float:
    """The host's busy CPU seconds so far (/proc/stat: all but idle and iowait)."""
    with open("/proc/stat") as fh:
        f = [int(x) for x in fh.readline().split()[1:]]
    return (sum(f) - f[3] - f[4]) / os.sysconf("SC_CLK_TCK")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=60)
    ap.add_argument("--out")
    a = ap.parse_args()
    ways = {"subprocess": _subprocess, "forked": _forked}
    wall = dict.fromkeys(ways, 0.0)
    cpu = dict.fromkeys(ways, 0.0)
    tables, codes = set(), []
    load0 = os.getloadavg()
    with ThreadPoolExecutor(2) as ex:
        for start in range(0, a.runs, 20):
            n = min(20, a.runs - start)
            for name, fn in ways.items():
                c0 = _busy_s()
                t0 = time.perf_counter()
                rs = list(ex.map(fn, range(n)))
                wall[name] += time.perf_counter() - t0
                cpu[name] += _busy_s() - c0
                codes += [r.returncode for r in rs]
                tables |= {tuple(sorted(scheduled_jobs(r.stdout + r.stderr).items())) for r in rs}
    rec = {"date": dt.date.today().isoformat(), "cpu_model": cpu_model(),
           "cpus": os.cpu_count(), "load_average_start": load0,
           "load_average_end": os.getloadavg(), "command": " ".join(sys.argv),
           "runs_each": a.runs,
           "wall_s_per_run": {k: v / a.runs for k, v in wall.items()},
           "host_busy_cpu_s_per_run": {k: v / a.runs for k, v in cpu.items()},
           "exit_codes": sorted(set(codes)), "same_job_table": len(tables) == 1}
    print(json.dumps(rec, indent=1))
    if a.out:
        with open(a.out, "w") as fh:
            json.dump(rec, fh, indent=1)


if __name__ == "__main__":
    main()
