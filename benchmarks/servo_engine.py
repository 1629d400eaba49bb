"""The wall servo inside the engine, paired in one invocation against the same loop run
from Python and against a baseline source tree (the servo as it was before), for
``bpmcal`` commands that servo-control walls (the triaxial test; a sample job, whose
Brazilian disc is seated by a servo):

- ``engine``: this tree, ``lab.servo.IN_ENGINE`` True (the law applied in numba between
  steps, ``dem.servo_kernel``);
- ``python``: this tree, ``IN_ENGINE`` False (the loop in Python, the law through the same
  numba helpers: the same state bit for bit, checked on the run files' responses);
- ``baseline`` (with ``--baseline-src DIR``): the ``src`` of another checkout, e.g. a
  clone of the commit before the change (its own arithmetic: its responses differ in the
  last bits and, through them, as packing scatter).

Each way runs as its own process (``python -c`` calling ``bpmcal.cli.main``), the ways
alternating, ``--repeat`` times per command after one warm-up run of each (kernels
compiled and packings cached); CPU seconds are the finished child's (``getrusage``).

    python benchmarks/servo_engine.py --repeat 3 --baseline-src /tmp/old/src \\
        --json R.json --run 'triaxial --params B1.yaml --sigma3 10 --out /tmp/t.h5 ...'

Prints per command the median CPU seconds of each way and their ratios to the engine
way; ``--json`` writes every run.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shlex
import statistics
import subprocess
import sys
from pathlib import Path

_KEYS = ("sigma1_MPa", "E_GPa", "nu", "steps", "bts_MPa", "bts_valid", "discs", "ucs_MPa",
         "seat_steps")
_SRC = str(Path(__file__).resolve().parents[1] / "src")
_CODE = ("import sys; from bpmcal.lab import servo; servo.IN_ENGINE = {flag}; "
         "from bpmcal.cli import main; sys.exit(main(sys.argv[1:]))")


def _responses(argv: list[str]) -> dict:
    from bpmcal.io import h5

    out = {}
    for flag in ("--out", "--bts-out"):
        if flag in argv:
            s = h5.read_summary(argv[argv.index(flag) + 1])
            out.update({f"{flag[2:]}:{k}": s[k] for k in _KEYS if k in s})
    return out


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_once(way: str, argv: list[str], baseline: str | None) -> dict:
    src = baseline if way == "baseline" else _SRC
    code = (_CODE.format(flag=way == "engine") if way != "baseline" else
            "import sys; from bpmcal.cli import main; sys.exit(main(sys.argv[1:]))")
    env = {**os.environ, "PYTHONPATH": src}
    c0 = _children_cpu()
    p = subprocess.run([sys.executable, "-c", code, *argv], env=env,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    cpu = _children_cpu() - c0
    if p.returncode != 0:
        raise SystemExit(f"{way}: {' '.join(argv[:3])} failed: {p.stderr[-400:]}")
    return {"way": way, "cpu_s": cpu, "responses": _responses(argv)}


def _cpu_model() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def main(args=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", action="append", required=True,
                    help="a bpmcal command line (quoted), repeatable")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--baseline-src", default=None,
                    help="the src directory of the checkout to compare with")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(args)
    ways = ["engine", "python"] + (["baseline"] if a.baseline_src else [])
    rows = []
    for cmd in a.run:
        argv = shlex.split(cmd)
        for w in ways:  # warm-up: kernels compiled and loaded, packings cached
            run_once(w, argv, a.baseline_src)
        runs = {w: [] for w in ways}
        for _ in range(a.repeat):
            for w in ways:
                runs[w].append(run_once(w, argv, a.baseline_src))
        med = {w: statistics.median(r["cpu_s"] for r in runs[w]) for w in ways}
        same = all(r["responses"] == runs["engine"][0]["responses"]
                   for r in runs["engine"] + runs["python"])
        row = {"command": cmd, "runs": runs, "median_cpu_s": med, "same_results": same,
               "over_engine": {w: med[w] / med["engine"] for w in ways}}
        rows.append(row)
        base = runs.get("baseline", [{}])[0].get("responses")
        print(f"{' '.join(argv[:5])} ...: " + ", ".join(
            f"{w} {med[w]:.2f} s" for w in ways) + "; " + ", ".join(
            f"{w}/engine {med[w] / med['engine']:.3f}" for w in ways[1:])
              + f"; engine = python: {same}; engine {runs['engine'][0]['responses']}"
              + (f"; baseline {base}" if base else ""), flush=True)
    tot = {w: sum(r["median_cpu_s"][w] for r in rows) for w in ways}
    print("all commands: " + ", ".join(f"{w} {tot[w]:.1f} s" for w in ways) + "; " +
          ", ".join(f"{w}/engine {tot[w] / tot['engine']:.3f}" for w in ways[1:]))
    print(f"host: {_cpu_model()}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"host": _cpu_model(), "repeat": a.repeat, "ways": ways,
                       "baseline_src": a.baseline_src, "rows": rows, "total_cpu_s": tot},
                      fh, indent=1)
    return 0 if all(r["same_results"] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
