"""A measurement record of the test suite's tiers: the fast tier (``-m "not slow"``) and
the whole suite (what CI runs), each timed as one ``pytest`` process, with the counts
pytest reports, the host's CPU, the load average before and after, and the commit.

    python benchmarks/test_tiers.py --out benchmarks/results/results_test_tiers_DATE.json \\
        --markdown docs/measurements/DATE-test-tiers.md

``--tiers fast`` times the fast tier only. Run it on a quiet machine with a warm numba
cache (a fresh clone first compiles the kernels: run the fast tier once before). The
record says which: it counts the compiled kernels in the test run's numba cache before the
first tier (``numba_cache``: warm if there are any; the cache tests/conftest.py gives the
test run, ``.cache/test/bpmcal`` or ``$BPMCAL_CACHE``).
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

from _study import REPO, cpu_model

#: tier -> the pytest arguments after ``python -m pytest -q -ra``
TIERS = {"fast": ["-m", "not slow"], "full": []}


def _commit() -> str:
    r = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
                       capture_output=True, text=True)
    return r.stdout.strip() or "unknown"


def _counts(tail: str) -> dict:
    """pytest's final line, e.g. '702 passed, 57 deselected, 2 skipped in 76.5s'."""
    return {k: int(n) for n, k in re.findall(
        r"(\d+) (passed|failed|skipped|deselected|errors?|xfailed|xpassed)", tail)}


def numba_cache() -> dict:
    """The numba cache the test run will use (tests/conftest.py's choice: $NUMBA_CACHE_DIR,
    else $BPMCAL_CACHE, else .cache/test/bpmcal, each keyed on the engine's source as
    bpmcal.dem._jit does) and how many compiled kernels it holds now."""
    if "NUMBA_CACHE_DIR" in os.environ:
        d = Path(os.environ["NUMBA_CACHE_DIR"])
    else:
        base = Path(os.environ.get("BPMCAL_CACHE", REPO / ".cache" / "test" / "bpmcal"))
        key = subprocess.run([sys.executable, "-c", "from bpmcal.dem._jit import _source_hash;"
                              " print(_source_hash())"], capture_output=True, text=True,
                             check=True).stdout.strip()
        d = base / "numba" / key
    n = len(list(d.rglob("*.nbc"))) if d.is_dir() else 0
    where = d.relative_to(REPO) if d.is_relative_to(REPO) else d
    return {"dir": str(where), "kernels": n, "state": "warm" if n else "cold"}


def time_tier(name: str) -> dict:
    cmd = [sys.executable, "-m", "pytest", "-q", "-ra", "-p", "no:cacheprovider",
           *TIERS[name]]
    load0 = os.getloadavg()
    t0, c0 = time.time(), os.times()
    r = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    wall, c1 = time.time() - t0, os.times()
    last = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else ""
    return {"tier": name, "command": shlex.join(["python", *cmd[1:]]), "rc": r.returncode,
            "wall_s": wall, "cpu_s": (c1.children_user - c0.children_user)
            + (c1.children_system - c0.children_system), "counts": _counts(last),
            "load_before": load0, "load_after": os.getloadavg()}


def markdown(rec: dict) -> str:
    lines = [f"# The test suite's tiers: {rec['date']}", "",
             f"Host: {rec['cpu_model']} ({rec['cpus']} CPUs), commit {rec['commit']}.", "",
             f"Command: `{rec['command']}`", ""]
    if rec.get("note"):
        lines += [rec["note"], ""]
    nc = rec.get("numba_cache")
    if nc:  # recorded from 2026-12 on
        lines += [f"Numba cache before the first tier: **{nc['state']}** ({nc['kernels']} "
                  f"compiled kernels in `{nc['dir']}`"
                  + ("" if nc["kernels"] else "; the first tier compiled them") + ").", ""]
    lines += ["| tier | pytest command | wall | CPU (children) | passed | skipped | deselected "
              "| failed | load (1 min) before / after |", "|---|---|---|---|---|---|---|---|---|"]
    for t in rec["tiers"]:
        c = t["counts"]
        lines.append(f"| {t['tier']} | `{t['command']}` | {t['wall_s'] / 60:.1f} min | "
                     f"{t['cpu_s'] / 60:.1f} min | {c.get('passed', 0)} | {c.get('skipped', 0)} | "
                     f"{c.get('deselected', 0)} | {c.get('failed', 0) + c.get('errors', 0)} | "
                     f"{t['load_before'][0]:.2f} / {t['load_after'][0]:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiers", default="fast,full")
    ap.add_argument("--note", default="")
    ap.add_argument("--out", required=True)
    ap.add_argument("--markdown", default=None)
    a = ap.parse_args(argv)
    names = a.tiers.split(",")
    bad = [n for n in names if n not in TIERS]
    if bad:
        ap.error(f"--tiers: unknown tier(s) {bad}; expected some of {sorted(TIERS)}")
    rec = {"date": dt.date.today().isoformat(), "cpu_model": cpu_model(),
           "cpus": os.cpu_count(), "commit": _commit(),
           "command": "python benchmarks/test_tiers.py " + shlex.join(argv), "note": a.note,
           "numba_cache": numba_cache(), "tiers": [time_tier(n) for n in names]}
    Path(a.out).write_text(json.dumps(rec, indent=1) + "\n")
    text = markdown(rec)
    if a.markdown:
        Path(a.markdown).write_text(text)
    print(text)
    return max(t["rc"] for t in rec["tiers"])


if __name__ == "__main__":
    raise SystemExit(main())
