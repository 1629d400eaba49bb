"""At how many balls does a second thread pay? One thread against two on the reference
case of ``dem_throughput.py`` (a bonded pack in a box under a small compression; the
parallel bond, and flat joints 1 x 3 with ``--flatjoint``), alone on the machine.

    python benchmarks/thread_threshold.py [--sizes 1000,2000,4000,8000,16000,32000] \\
        [--repeat 3] [--ball-steps 2e7] [--json benchmarks/results/results_thread_threshold_DATE.json]

Each size runs in its own process per thread count (``dem_throughput.py --json``), the
counts alternating, ``--repeat`` times; steps = ball-steps / balls (the same work at every
size). The table gives the median wall time and the speed-up of two threads (1-thread wall
over 2-thread wall, medians). ``bpmcal.dem.threads.MIN_BALLS_PER_THREAD`` is read from it:
the smallest size per thread at which two threads were clearly faster.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from peers import host_info  # noqa: E402


def one(n, threads, steps, flatjoint):
    code = ("import sys, json; sys.path.insert(0, %r); import dem_throughput as d; " % str(HERE))
    if flatjoint:
        code += ("from flatjoint_speed import _fj_material; from bpmcal.dem._jit import "
                 "set_threads; set_threads(%d); import time; m, nb = d.bench_model(%d, "
                 "material=_fj_material(1, 3)); m.cycle(100); t = time.perf_counter(); "
                 "m.cycle(%d); print(json.dumps({'wall_s': time.perf_counter() - t}))"
                 % (threads, n, steps))
    else:
        code += "print(json.dumps(d.run(%d, %d, %d)))" % (n, threads, steps)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out.strip().splitlines()[-1])["wall_s"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1000,2000,4000,8000,16000,32000")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--ball-steps", type=float, default=2e7)
    ap.add_argument("--flatjoint", action="store_true")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    sizes = [int(s) for s in a.sizes.split(",")]
    load0 = os.getloadavg()
    rows = []
    for n in sizes:
        steps = max(100, int(a.ball_steps / n))
        w = {1: [], 2: []}
        for r in range(a.repeat):
            for th in ((1, 2) if r % 2 == 0 else (2, 1)):
                w[th].append(one(n, th, steps, a.flatjoint))
        m1, m2 = statistics.median(w[1]), statistics.median(w[2])
        rows.append({"n": n, "steps": steps, "wall_1": w[1], "wall_2": w[2],
                     "median_1": m1, "median_2": m2, "speedup": m1 / m2})
        print(f"N {n:6d}  steps {steps:6d}  1 thread {m1:6.2f} s  2 threads {m2:6.2f} s  "
              f"speed-up {m1 / m2:5.2f}", flush=True)
    if a.json:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=HERE).stdout.strip()
        Path(a.json).write_text(json.dumps({
            "date": time.strftime("%Y-%m-%d"), "commit": commit, "host": host_info(),
            "load_start": load0, "load_end": os.getloadavg(),
            "command": "python benchmarks/thread_threshold.py " + " ".join(argv or sys.argv[1:]),
            "args": vars(a), "rows": rows}, indent=1))
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
