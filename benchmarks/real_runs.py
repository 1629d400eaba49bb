"""Real UCS runs next to the throughput benchmark, in one invocation.

    python benchmarks/real_runs.py --design DESIGN.csv --samples s000 s001 s002 \
        [--scale 0.4] [--repeat 3] [--bench-n 10000] [--bench-steps 1000] [--json out.json]

Without ``--design`` the samples are the paper's A1 card on packing seeds 1, 2, 3.

Every repeat runs the reference benchmark (``dem_throughput.run``: N bonded balls, one
thread) and a UCS test of every sample at the given scale (``lab.runner.make_specimen``
then ``lab.ucs.run_ucs``, one thread, a fresh packing cache, so the genesis includes the
packing's relaxation as in a study), one after the other; the order of the benchmark and
the samples alternates from one repeat to the next. For each run it prints

- the UCS test's throughput: balls x test steps / seconds of ``run_ucs`` (wall clock and
  CPU seconds of the process), and its ratio to the benchmark's in the same repeat;
- the genesis share: seconds of ``make_specimen`` / (genesis + test), wall and CPU.

Medians over repeats and samples are printed at the end. CPU seconds are the better
figure on a shared machine (one thread: another process slows the wall clock, much less
the CPU time of this one). The host line is the one of ``peers.py``.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _study import design_samples  # noqa: E402


def ucs_run(params, seed, scale):
    from bpmcal.lab.runner import Geometry, make_specimen
    from bpmcal.lab.ucs import UCSSettings, run_ucs
    with tempfile.TemporaryDirectory() as cache:
        c0, t0 = time.process_time(), time.perf_counter()
        sp = make_specimen(params, seed, Geometry(scale=scale), cache=cache, threads=1)
        c1, t1 = time.process_time(), time.perf_counter()
        res = run_ucs(sp, UCSSettings())
        c2, t2 = time.process_time(), time.perf_counter()
    n = sp.model.n
    steps = int(res.summary["steps"])
    return {"n_balls": n, "test_steps": steps, "ucs_MPa": res.summary["ucs_MPa"],
            "genesis_wall_s": t1 - t0, "genesis_cpu_s": c1 - c0,
            "test_wall_s": t2 - t1, "test_cpu_s": c2 - c1,
            "particle_steps_per_s": n * steps / (t2 - t1),
            "particle_steps_per_cpu_s": n * steps / (c2 - c1),
            "genesis_share_wall": (t1 - t0) / (t2 - t0),
            "genesis_share_cpu": (c1 - c0) / (c2 - c0)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--design", default=None, help="design CSV (sample_id, seed, params)")
    ap.add_argument("--samples", nargs="*", default=["s000", "s001", "s002"])
    ap.add_argument("--scale", type=float, default=0.4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--bench-n", type=int, default=10000, help="0: no benchmark (genesis "
                    "share only, e.g. for an older bpmcal)")
    ap.add_argument("--bench-steps", type=int, default=1000)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    from dem_throughput import run as bench
    from peers import bandwidth_probe, host_info

    from bpmcal.dem._jit import set_threads
    set_threads(1)
    host = host_info()
    host["bandwidth_GBs"] = bandwidth_probe()
    print(f"# {host.get('cpu_model')} (LLVM {host.get('llvm_host_cpu')}), "
          f"in-place multiply GB/s {host.get('bandwidth_GBs')}", flush=True)
    todo = design_samples(a.design, a.samples, (1, 2, 3), "A1 seed {seed}")
    if a.bench_n > 0:
        bench(2000, 1, 10)  # compile / load every kernel once, outside the timings
    ucs_run(todo[0][1], todo[0][2], a.scale)
    runs = []
    for rep in range(a.repeat):
        order = ["bench", "ucs"] if rep % 2 == 0 else ["ucs", "bench"]
        b, u = None, []
        for what in order:
            if what == "bench" and a.bench_n > 0:
                b = bench(a.bench_n, 1, a.bench_steps)
                print(f"  repeat {rep + 1} bench N={a.bench_n}: "
                      f"{b['particle_steps_per_s'] / 1e6:.3f} M/s wall, "
                      f"{b['particle_steps_per_cpu_s'] / 1e6:.3f} M/s cpu", flush=True)
            elif what == "ucs":
                for name, p, seed in todo:
                    r = ucs_run(p, seed, a.scale)
                    r["sample"] = name
                    u.append(r)
                    print(f"  repeat {rep + 1} {name}: N={r['n_balls']} "
                          f"{r['particle_steps_per_s'] / 1e6:.3f} M/s wall, "
                          f"{r['particle_steps_per_cpu_s'] / 1e6:.3f} M/s cpu; genesis "
                          f"{r['genesis_wall_s']:.2f} s of {r['genesis_wall_s'] + r['test_wall_s']:.2f}"
                          f" s wall ({100 * r['genesis_share_wall']:.0f} %, cpu "
                          f"{100 * r['genesis_share_cpu']:.0f} %)", flush=True)
        for r in u:
            r["repeat"] = rep
            if b is not None:
                r["ratio_wall"] = r["particle_steps_per_s"] / b["particle_steps_per_s"]
                r["ratio_cpu"] = r["particle_steps_per_cpu_s"] / b["particle_steps_per_cpu_s"]
        runs.append({"bench": b, "ucs": u})
    med = lambda xs: statistics.median(xs)  # noqa: E731
    allu = [r for x in runs for r in x["ucs"]]
    summary = {
        "ucs_M_per_s": med([r["particle_steps_per_s"] for r in allu]) / 1e6,
        "ucs_M_per_cpu_s": med([r["particle_steps_per_cpu_s"] for r in allu]) / 1e6,
        "genesis_share_wall": med([r["genesis_share_wall"] for r in allu]),
        "genesis_share_cpu": med([r["genesis_share_cpu"] for r in allu]),
        "genesis_wall_s": med([r["genesis_wall_s"] for r in allu]),
        "test_wall_s": med([r["test_wall_s"] for r in allu]),
    }
    if a.bench_n > 0:
        summary.update({
            "bench_M_per_s": med([x["bench"]["particle_steps_per_s"] for x in runs]) / 1e6,
            "bench_M_per_cpu_s": med([x["bench"]["particle_steps_per_cpu_s"]
                                      for x in runs]) / 1e6,
            "ratio_wall": med([r["ratio_wall"] for r in allu]),
            "ratio_cpu": med([r["ratio_cpu"] for r in allu])})
    print(json.dumps({k: round(v, 4) for k, v in summary.items()}))
    if a.json:
        Path(a.json).write_text(json.dumps({"host": host, "args": vars(a), "runs": runs,
                                            "median": summary}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
