"""Flat joints beside parallel bonds: throughput on the same pack, side by side.

    python benchmarks/flatjoint_speed.py --n 10000 --threads 1 --steps 1000 --repeat 3 \
        [--json benchmarks/results/results_flatjoint_speed.json]

The pack and loading are ``dem_throughput.py``'s (N balls, radii 0.8-1.328 mm, relaxed in
a box, every touching pair bonded, a small-strain compression, strengths high enough
that nothing breaks). The same pack is run with the linear parallel bond
(``linearpbond``) and with flat joints of 1 x 3 and 2 x 4 elements (``flatjoint``,
E* = 10 GPa, kappa* = 2, all bonded, force-free installation). Each repeat runs the three
models one after the other in one process, the order rotating between repeats; the table
gives the median of particle-steps per CPU-second (one thread: CPU time is less
sensitive to other processes than wall time), the ratio of the medians to the parallel
bond's and the paired ratio: the median over the repeats of each repeat's ratio (on a host
whose speed drifts from one repeat to the next, the models of one repeat see the same
host; use many short repeats there, e.g. ``--steps 300 --repeat 15``).

Bytes per particle-step: an accounting of the contact state each model reads and writes
in one step (the arrays of the installed pairs, per ball), not a hardware counter; the
ball arrays and force buffers, which both models touch alike, are left out.
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from dem_throughput import E_MOD, bench_model  # noqa: E402
from peers import host_info  # noqa: E402

MODELS = ("linearpbond", "flatjoint 1x3", "flatjoint 2x4")


def _fj_material(nr, nal):
    from bpmcal.dem import FlatJointMaterial
    return FlatJointMaterial(fj_emod=E_MOD, fj_kratio=2.0, fj_ten=1e12, fj_coh=1e12,
                             fj_fa=30.0, fj_fric=0.5, fj_nr=nr, fj_nal=nal)


def build(model: str, n: int, seed: int = 1):
    """``dem_throughput.bench_model`` with the model's material."""
    if model == "linearpbond":
        return bench_model(n, seed)
    nr, nal = (int(x) for x in model.split()[1].split("x"))
    return bench_model(n, seed, material=_fj_material(nr, nal))


def state_bytes(m) -> tuple[float, float]:
    """(read, written) bytes of the installed pairs' state per ball and step."""
    nb, n = m.n_bonds, m.n
    if m.contact_model == "linearpbond":
        from bpmcal.dem import bondblock as bb
        assert bb.NSF == 17
        return nb * (14 * 8 + 8) / n, nb * 13 * 8 / n  # bytes_per_step.py's rows + i, j
    F = m.Fj
    ne = F.es.shape[1]
    # per contact: frame, theta_b, g_ref, g_0, strength factor read (8 floats), flags
    # (2 B), element states (ne B), element shear forces (ne x 16 B), i, j (8 B);
    # written: frame, theta_b, the force of the evaluation (8 floats), shear forces,
    # slip flags (ne B)
    rd = 8 * 8 + 2 + ne + 16 * ne + 8
    wr = 8 * 8 + 16 * ne + ne
    return nb * rd / n, nb * wr / n


def run_one(model, n, steps, seed, log):
    import resource
    m, nb = build(model, n, seed)
    m.cycle(100)  # warm-up
    c0 = time.process_time()
    t0 = time.perf_counter()
    m.cycle(steps)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    rd, wr = state_bytes(m)
    res = {"model": model, "n": n, "steps": steps, "contacts": nb, "wall_s": wall, "cpu_s": cpu,
           "psteps_per_cpu_s": n * steps / cpu, "psteps_per_s": n * steps / wall,
           "state_bytes_read": rd, "state_bytes_written": wr,
           "broken": m.n_broken, "dt": m.dt,
           "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}
    log(f"  {model:14s} {res['psteps_per_cpu_s'] / 1e6:7.3f} M particle-steps/CPU-s "
        f"({cpu:.2f} CPU-s, {nb} contacts)")
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10000)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", default=None, help="write every run and the medians here")
    a = ap.parse_args(argv)
    from bpmcal.dem._jit import set_threads
    set_threads(a.threads)
    log = lambda *x: print(*x, flush=True)  # noqa: E731
    t0 = time.perf_counter()
    for model in MODELS:  # compile / load every kernel before timing
        m, _ = build(model, a.n, a.seed)
        m.cycle(2)
    log(f"compile/cache load and packs: {time.perf_counter() - t0:.1f} s")
    runs = []
    for r in range(a.repeat):
        order = MODELS[r % 3:] + MODELS[:r % 3]
        log(f"repeat {r + 1}/{a.repeat}")
        for model in order:
            runs.append(run_one(model, a.n, a.steps, a.seed, log))
    med = {mo: statistics.median(x["psteps_per_cpu_s"] for x in runs if x["model"] == mo)
           for mo in MODELS}
    # paired: each repeat's ratio to the parallel bond of the same repeat (the models of a
    # repeat run within seconds of each other, so a host whose speed drifts between
    # repeats moves both alike), then the median over the repeats
    paired = {}
    for mo in MODELS:
        rat = []
        for r in range(a.repeat):
            rep = runs[3 * r:3 * r + 3]
            x = next(q for q in rep if q["model"] == mo)
            y = next(q for q in rep if q["model"] == "linearpbond")
            rat.append(x["psteps_per_cpu_s"] / y["psteps_per_cpu_s"])
        paired[mo] = rat
    rows = []
    for mo in MODELS:
        one = next(x for x in runs if x["model"] == mo)
        rows.append({"model": mo, "psteps_per_cpu_s": med[mo],
                     "ratio_to_pbond": med[mo] / med["linearpbond"],
                     "ratio_paired_median": statistics.median(paired[mo]),
                     "ratio_paired": paired[mo],
                     "state_bytes_read": one["state_bytes_read"],
                     "state_bytes_written": one["state_bytes_written"],
                     "contacts_per_ball": 2 * one["contacts"] / a.n})
    log(f"\n{'model':14s} {'M p-steps/CPU-s':>16s} {'x pbond':>8s} {'paired':>7s} "
        f"{'B read':>8s} {'B written':>10s}  (per particle-step; N = {a.n}, "
        f"{a.threads} thread)")
    for x in rows:
        log(f"{x['model']:14s} {x['psteps_per_cpu_s'] / 1e6:16.3f} {x['ratio_to_pbond']:8.3f} "
            f"{x['ratio_paired_median']:7.3f} {x['state_bytes_read']:8.0f} "
            f"{x['state_bytes_written']:10.0f}")
    if a.json:
        import os
        import subprocess
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=HERE).stdout.strip()
        out = {"date": time.strftime("%Y-%m-%d"), "commit": commit, "host": host_info(),
               "python": platform.python_version(), "load_1min": os.getloadavg()[0],
               "command": "python benchmarks/flatjoint_speed.py " + " ".join(argv or sys.argv[1:]),
               "args": vars(a), "medians": rows, "runs": runs}
        Path(a.json).write_text(json.dumps(out, indent=1))
        log(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
