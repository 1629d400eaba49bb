"""What a ``bpmcal`` process costs besides its work: one command run again and again, in
two ways alternating, its CPU seconds counted by the kernel (``getrusage`` of the
finished child) and by the command's own cost line (``bpmcal.cost``):

- ``quick``: ``python -m bpmcal.cli ...``, as the workflow's jobs run (the process ends
  without tearing the interpreter down: ``bpmcal.cli._end``);
- ``teardown``: the same command through ``bpmcal.cli.main(argv)`` in a script that
  then exits as Python does (every module freed, numba's and LLVM's objects among them).

    python benchmarks/job_overhead.py --repeat 5 -- ucs --params A1.yaml --out /tmp/u.h5 ...

Prints, per way, the median CPU seconds of the process and of its cost line, and their
difference (what the cost line does not see: the end of the process). The command's
output files are overwritten by every run; give it a warm specimen cache to time the
start and end of a job, an empty one per run (``--fresh-cache DIR``) for a whole job.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys

_LINE = re.compile(r"^bpmcal \S+: cost (\{.*\})\s*$", re.M)
_TEARDOWN = "import sys; from bpmcal.cli import main; sys.exit(main(sys.argv[1:]))"


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_once(way: str, argv: list[str]) -> dict:
    cmd = ([sys.executable, "-m", "bpmcal.cli"] if way == "quick"
           else [sys.executable, "-c", _TEARDOWN]) + argv
    env = {**os.environ, "BPMCAL_COST": "1"}
    c0 = _children_cpu()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    outside = _children_cpu() - c0
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{p.stderr[-2000:]}")
    m = _LINE.findall(p.stderr)
    line = json.loads(m[-1]) if m else {}
    inside = line.get("cpu_s", float("nan")) + line.get("children_cpu_s", 0.0)
    return {"way": way, "outside_cpu_s": outside, "cost_line_cpu_s": inside,
            "unbooked_s": outside - inside}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fresh-cache", default=None,
                    help="a specimen cache folder emptied before every run")
    ap.add_argument("--json", default=None)
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the bpmcal command")
    a = ap.parse_args(argv)
    cmd = a.command[1:] if a.command[:1] == ["--"] else a.command
    runs = []
    for r in range(a.repeat + 1):  # the first pair warms numba's cache, untimed
        for way in (("quick", "teardown") if r % 2 == 0 else ("teardown", "quick")):
            if a.fresh_cache:
                shutil.rmtree(a.fresh_cache, ignore_errors=True)
            d = run_once(way, cmd)
            if r:
                runs.append({**d, "repeat": r})
    med = {w: {k: statistics.median(x[k] for x in runs if x["way"] == w)
               for k in ("outside_cpu_s", "cost_line_cpu_s", "unbooked_s")}
           for w in ("quick", "teardown")}
    for w, m in med.items():
        print(f"{w:9s} process {m['outside_cpu_s']:.3f} CPU s, cost line "
              f"{m['cost_line_cpu_s']:.3f}, not in the cost line {m['unbooked_s']:.3f}")
    print(f"teardown - quick: {med['teardown']['outside_cpu_s'] - med['quick']['outside_cpu_s']:.3f}"
          " CPU s per process")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"command": cmd, "load_average": list(os.getloadavg()), "runs": runs,
                       "median": med}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
