"""Throughput of the DEM engine on a dense bonded pack (the issue's reference case).

Pack: N spheres, radii uniform in [0.8, 1.328] mm, rho = 2294 kg/m^3, relaxed in a box
of six frictionless walls, every contact bonded (linear + parallel bond, E* = E-bar =
10 GPa, kappa = 2, strengths high enough that nothing breaks), friction 0.5, local damping
0.7; the timed run is a small-strain compression (top and bottom walls approach at
0.02 m/s each). Timing uses the code's own timer around ``Model.cycle`` after a warm-up;
JIT compile (or cache load) time is measured separately on a tiny model first.

    python benchmarks/dem_throughput.py --n 30000 --threads 1 --steps 2000 --json

Size sweep (``--sweep``): the same case at several ball counts, paired in one invocation,
each run in its own process with about ``--ball-steps`` particle-steps (steps = ball-steps
/ N), the sizes' order rotating from one repeat to the next; medians of the CPU seconds
per particle-step and their ratio to the largest size's:

    python benchmarks/dem_throughput.py --sweep 1000,2000,3000,10000 --repeat 3 \
        --threads 1 [--out results.json]

Packs are cached in ~/.cache/bpmcal/bench_pack_N.npz (the relaxation is not part of the
timed run) and numbered along a Morton curve, as the specimen genesis numbers balls.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

RMIN, RMAX, RHO = 0.8e-3, 1.328e-3, 2294.0
E_MOD = 10e9  # E* = E-bar [Pa]
WALL_SPEED = 0.02  # m/s, top and bottom walls (towards each other)


def _material(fric):
    from bpmcal.dem import Material
    return Material(emod=E_MOD, kratio=2.0, fric=fric, pb_emod=E_MOD, pb_kratio=2.0,
                    pb_ten=1e12, pb_coh=1e12, pb_fa=30.0)


def _box_walls(m, L):
    for ax in range(3):
        n = np.zeros(3)
        n[ax] = 1.0
        m.add_plane_wall(np.zeros(3), n)
        p = np.zeros(3)
        p[ax] = L
        m.add_plane_wall(p, -n)


def make_pack(n: int, seed: int = 1):
    """Relaxed dense pack (positions, radii, box size), cached on disk."""
    from bpmcal.dem import Model
    cache = Path(os.environ.get("BPMCAL_CACHE", Path.home() / ".cache" / "bpmcal"))
    f = cache / f"bench_pack_{n}_{seed}.npz"
    if f.exists():
        d = np.load(f)
        return _sorted(d["pos"], d["r"], float(d["L"]))
    rng = np.random.default_rng(seed)
    r = rng.uniform(RMIN, RMAX, n)
    L = ((4 / 3 * np.pi * r ** 3).sum() / 0.62) ** (1 / 3)
    pos = rng.uniform(RMAX, L - RMAX, (n, 3))
    m = Model(pos, r, RHO, _material(0.0), damping=0.7)
    _box_walls(m, L)
    m.set_timestep(None)
    m.set_speed_cap(0.02 * RMIN / m.dt)
    for _ in range(40):
        m.cycle(250)
        m.set_timestep(None)
    m.set_speed_cap(0)
    m.cycle(2000)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(f, pos=m.B.pos, r=r, L=L)
    return _sorted(m.B.pos.copy(), r, L)


def _sorted(pos, r, L):
    """Balls in Morton order, as bpmcal's specimen genesis numbers them."""
    from bpmcal.dem.order import morton_order
    o = morton_order(pos)
    return pos[o], r[o], L


def bench_model(n: int, seed: int = 1, threads=None, material=None):
    """The reference case, ready to cycle: (model, number of bonds). The time step is 0.8 x
    the critical step of the bonded pack (the peers use the same dt). ``material``: another
    material on the same pack and loading (``flatjoint_speed.py``: flat joints)."""
    from bpmcal.dem import Model
    pos, r, L = make_pack(n, seed)
    m = Model(pos, r, RHO, material or _material(0.5), damping=0.7, threads=threads)
    _box_walls(m, L)
    nb = m.bond(gap=0.0)
    m.set_wall_velocity(4, velocity=(0, 0, WALL_SPEED))
    m.set_wall_velocity(5, velocity=(0, 0, -WALL_SPEED))
    m.set_timestep(None)
    return m, nb


def run(n: int, threads: int, steps: int, seed: int = 1) -> dict:
    t0 = time.perf_counter()
    from bpmcal.dem import Model
    from bpmcal.dem._jit import set_threads
    set_threads(threads)
    # compile / cache-load time: every kernel on a tiny bonded model
    tiny = Model([[0, 0, 0], [2.0e-3, 0, 0], [0, 2.0e-3, 0]], [1e-3] * 3, RHO,
                 _material(0.5))
    tiny.add_plane_wall((0, 0, -1e-3), (0, 0, 1), velocity=(0, 0, 1e-3))
    tiny.add_cylinder_wall((0, 0, 0), (0, 0, 1), 0.01)
    tiny.bond(gap=1e-6)
    tiny.set_timestep(None)
    tiny.cycle(2)
    tiny.energies()
    compile_s = time.perf_counter() - t0

    m, nb = bench_model(n, seed, threads)
    m.cycle(200)  # warm-up (page faults, first rebuild)
    s0 = m.step
    c1 = time.process_time()
    t1 = time.perf_counter()
    m.cycle(steps)
    wall = time.perf_counter() - t1
    cpu = time.process_time() - c1
    ci, cj = m.contacts()
    npairs_active = ci.shape[0]  # intact bonds + touching unbonded pairs
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"n": n, "threads": threads, "steps": m.step - s0, "wall_s": wall,
            "particle_steps_per_s": n * steps / wall,
            # CPU seconds of the process (all threads): on a shared machine, with one
            # thread, N * steps / cpu_s is less sensitive to other processes than wall time
            "cpu_s": cpu, "particle_steps_per_cpu_s": n * steps / cpu,
            "contact_steps_per_s": npairs_active * steps / wall,
            "bonds": nb, "contacts_and_bonds": int(npairs_active),
            "bonds_per_ball": 2 * nb / n, "compile_s": compile_s, "peak_rss_mb": peak,
            "broken": m.n_broken, "rebuilds": m.n_rebuilds, "dt": m.dt,
            "skin": float(m.skin)}


def sweep(sizes, threads: int, ball_steps: float, repeat: int, seed: int = 1) -> dict:
    """``run`` at every size of ``sizes``, each in its own process, ``repeat`` times, the
    order rotating; medians per size and the ratio of each size's CPU seconds per
    particle-step to the largest size's (below 1: a particle-step costs less)."""
    import statistics
    import subprocess

    sizes = list(sizes)
    for n in sizes:  # the packs (cached on disk) and the kernels, untimed
        subprocess.run([sys.executable, __file__, "--n", str(n), "--steps", "10", "--threads",
                        str(threads), "--seed", str(seed), "--json"], check=True,
                       capture_output=True)
    runs = []
    for r in range(repeat):
        k = r % len(sizes)
        for n in sizes[k:] + sizes[:k]:
            steps = max(10, int(round(ball_steps / n)))
            p = subprocess.run([sys.executable, __file__, "--n", str(n), "--steps", str(steps),
                                "--threads", str(threads), "--seed", str(seed), "--json"],
                               check=True, capture_output=True, text=True)
            d = json.loads(p.stdout.strip().splitlines()[-1])
            d["repeat"] = r
            runs.append(d)
            print(f"n {n:6d}  steps {steps:6d}  {d['particle_steps_per_cpu_s'] / 1e6:6.2f} M "
                  f"particle-steps per CPU s  (wall {d['particle_steps_per_s'] / 1e6:6.2f} M/s)",
                  flush=True)
    med = {}
    for n in sizes:
        rs = [d for d in runs if d["n"] == n]
        med[n] = {"ns_per_particle_step_cpu": statistics.median(
                      1e9 * d["cpu_s"] / (d["n"] * d["steps"]) for d in rs),
                  "particle_steps_per_cpu_s": statistics.median(
                      d["particle_steps_per_cpu_s"] for d in rs),
                  "particle_steps_per_s": statistics.median(d["particle_steps_per_s"]
                                                            for d in rs),
                  "rebuilds": statistics.median(d["rebuilds"] for d in rs),
                  "steps": rs[0]["steps"]}
    top = med[max(sizes)]["ns_per_particle_step_cpu"]
    for n in sizes:
        med[n]["cost_vs_largest"] = med[n]["ns_per_particle_step_cpu"] / top
    return {"sizes": sizes, "threads": threads, "ball_steps": ball_steps, "repeat": repeat,
            "load_average_after": list(os.getloadavg()), "median": med, "runs": runs}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=30000)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--sweep", default=None, help="ball counts, comma-separated: size sweep")
    ap.add_argument("--ball-steps", type=float, default=2e7,
                    help="particle-steps of each sweep run (steps = this / N)")
    ap.add_argument("--repeat", type=int, default=3, help="repeats of the sweep")
    ap.add_argument("--out", default=None, help="the sweep's JSON record")
    a = ap.parse_args(argv)
    if a.sweep:
        rec = {"date": time.strftime("%Y-%m-%d"), "load_average_before": list(os.getloadavg()),
               **sweep([int(x) for x in a.sweep.split(",")], a.threads, a.ball_steps,
                       a.repeat, a.seed)}
        print(f"{'balls':>8s} {'ns/particle-step (CPU)':>24s} {'x largest':>10s}")
        for n in rec["sizes"]:
            m = rec["median"][n]
            print(f"{n:8d} {m['ns_per_particle_step_cpu']:24.1f} {m['cost_vs_largest']:10.3f}")
        if a.out:
            Path(a.out).write_text(json.dumps(rec, indent=1) + "\n")
        return 0
    res = run(a.n, a.threads, a.steps, a.seed)
    if a.json:
        print(json.dumps(res))
    else:
        for k, v in res.items():
            print(f"{k:24s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
