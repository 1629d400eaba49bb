"""The engine at the study's sizes inside real lab tests: particle-steps per CPU-second of
the UCS test's loading on bonded cylinders of about 1,000, 3,000 and 10,000 balls and of
the study's Brazilian disc (27.5 mm, scale 0.55), paired in one invocation.

Every case runs the lab test itself (``run_ucs`` / ``run_bts``: the study's loading
settings, its records, the Brazilian seating under servo control) for ``--steps`` steps
of loading (``max_steps``; the same steps at every size, so a smaller specimen records
as often per step as it does in the study), on a specimen of the given card built with
the study's genesis (pfc, relax ratio 0.01, sigma0 0.1 MPa; packings cached under
``--cache``, not timed). The loading is cut at ``--steps`` on purpose, so the tests'
refusal of a loading estimated to need more steps is bypassed. Each case runs in its
own process (``--threads``, default 1, as the study's jobs), ``--repeat`` times with the
order rotating; the table gives medians:

- particle-steps per CPU-second of the whole test call (engine, records, control) and of
  the engine alone (``Model.cycle``), their ratio to the largest cylinder's, and the
  share of the test's CPU outside the engine, and of it the records' measurements of
  the engine (``Model.energies``, ``Model.unbalanced_ratio``) and the Brazilian
  seating's servo control (``ServoLoop.control``, every step);
- bonds per ball at the start, records, engine calls, the peak RSS of the process (and
  in ``--json`` the neighbour-list rebuilds).

``--src DIR`` (repeatable) runs every case with each source tree in turn (``PYTHONPATH``;
numba's cache is keyed on the engine's sources): a before/after pair in one invocation,
with the ratio of each case's CPU per particle-step to the first tree's. ``--reference``
adds the engine's 10k-ball benchmark (``dem_throughput.py --n 10000``) as a case.

    python benchmarks/small_model_speed.py [--steps 4000] [--repeat 3] \
        [--src /tmp/before/src --src src] [--reference] [--json out.json]

The scales are for the default card (``CARD``: Rmin 0.8 mm, porosity 0.34, the other
parameters mid-range); the ball counts are printed. The host's CPU and load average
(before and after) are printed with the table: on a loaded host compare ratios measured
side by side, not absolute figures.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

#: the default card: Table 2 midpoints where the calibration fixes none
CARD = {"rmin_mm": 0.8, "porosity": 0.34, "pb_emod_GPa": 30.0, "pb_kratio": 2.5,
        "pb_ten_MPa": 30.0, "pb_coh_MPa": 21.4, "pb_fa_deg": 35.0, "fric": 0.35}
#: case -> (test, scale on the 50 x 100 mm cylinder or the 50 x 25 mm disc)
CASES = {"ucs_1k": ("ucs", 0.345), "ucs_3k": ("ucs", 0.5), "ucs_10k": ("ucs", 0.745),
         "bts_27.5mm": ("bts", 0.55)}
GENESIS = {"sigma0_MPa": 0.1, "genesis": "pfc", "relax_ratio": 0.01}


# ------------------------------------------------------------------ child: one case
class _Timers:
    """CPU seconds and calls of wrapped methods, each exclusive of the wrapped calls it
    makes (``energies`` may step the engine once: that is the engine's)."""

    def __init__(self):
        self.cpu, self.calls, self._stack, self._saved = {}, {}, [], []

    def wrap(self, owner, name: str, key: str) -> None:
        f = getattr(owner, name)
        self._saved.append((owner, name, f))
        self.cpu.setdefault(key, 0.0)
        self.calls.setdefault(key, 0)

        def timed(*a, **kw):
            self._stack.append(0.0)
            c = time.process_time()
            try:
                return f(*a, **kw)
            finally:
                dt = time.process_time() - c
                inner = self._stack.pop()
                self.cpu[key] += dt - inner
                self.calls[key] += 1
                if self._stack:
                    self._stack[-1] += dt

        setattr(owner, name, timed)

    def unwrap(self) -> None:
        for owner, name, f in reversed(self._saved):
            setattr(owner, name, f)


def _child(case: str, steps: int, cache: str, card: dict, threads: int) -> dict:
    from bpmcal.dem import Model
    from bpmcal.dem._jit import set_threads
    from bpmcal.lab import brazilian, servo, ucs
    from bpmcal.lab.brazilian import BTSSettings, run_bts
    from bpmcal.lab.runner import Geometry, bts_geometry, make_specimen
    from bpmcal.lab.ucs import UCSSettings, run_ucs

    set_threads(threads)
    test, scale = CASES[case]
    geo = (bts_geometry(scale=scale, **GENESIS) if test == "bts"
           else Geometry(scale=scale, **GENESIS))
    sp = make_specimen(card, 1, geo, cache=cache, threads=threads,
                       boundary="free" if test == "bts" else "platens")
    m = sp.model
    n, nb = m.n, m.n_bonds
    timers = _Timers()
    timers.wrap(Model, "cycle", "engine")
    timers.wrap(Model, "energies", "measure")  # the records' measurements of the engine
    timers.wrap(Model, "unbalanced_ratio", "measure")
    timers.wrap(servo.ServoLoop, "control", "servo")  # the seating's control, per step
    # the loading is cut at ``steps`` on purpose: no refusal of a loading estimated to
    # need more (budget.check_loading_steps; its bound only feeds the progress line)
    brazilian.loading_bound = ucs.loading_bound = lambda m, st, loading: st.max_steps
    s0, r0 = m.step, m.n_rebuilds
    c0 = time.process_time()
    if test == "bts":
        res = run_bts(sp, BTSSettings(max_steps=steps))
    else:
        res = run_ucs(sp, UCSSettings(max_steps=steps, end_cap=0.0))
    cpu = time.process_time() - c0
    timers.unwrap()
    ball_steps = n * (m.step - s0)
    eng = timers.cpu["engine"]
    return {"case": case, "balls": n, "bonds_per_ball": 2 * nb / n, "steps": m.step - s0,
            "loading_steps": int(res.summary["steps"]), "cpu_s": cpu,
            "engine_cpu_s": eng, "engine_calls": timers.calls["engine"],
            "records": int(res.summary["records"]), "rebuilds": m.n_rebuilds - r0,
            "particle_steps_per_cpu_s": ball_steps / cpu,
            "engine_particle_steps_per_cpu_s": ball_steps / eng,
            "outside_engine": 1.0 - eng / cpu,
            "measure_share": timers.cpu["measure"] / cpu,
            "servo_share": timers.cpu["servo"] / cpu,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def _reference(steps: int, threads: int) -> dict:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import dem_throughput
    d = dem_throughput.run(10000, threads, steps)
    return {"case": "bench_10k", "balls": d["n"], "bonds_per_ball": d["bonds_per_ball"],
            "steps": d["steps"], "loading_steps": d["steps"], "cpu_s": d["cpu_s"],
            "engine_cpu_s": d["cpu_s"], "engine_calls": 1, "records": 0,
            "rebuilds": d["rebuilds"], "particle_steps_per_cpu_s": d["particle_steps_per_cpu_s"],
            "engine_particle_steps_per_cpu_s": d["particle_steps_per_cpu_s"],
            "outside_engine": 0.0, "measure_share": 0.0, "servo_share": 0.0,
            "peak_rss_mb": d["peak_rss_mb"]}


# ------------------------------------------------------------------ parent
def host() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return f"{line.split(':', 1)[1].strip()} ({os.cpu_count()} CPUs)"
    except OSError:
        pass
    return f"unknown CPU ({os.cpu_count()} CPUs)"


def _run(src, case, a) -> dict:
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = str(Path(src).resolve())
    cmd = [sys.executable, __file__, "--child", case, "--steps", str(a.steps), "--cache",
           a.cache, "--threads", str(a.threads), "--card-json", json.dumps(a.card)]
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"case {case} (src {src}) failed:\n{p.stderr[-3000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def _median(rs, key):
    return statistics.median(r[key] for r in rs)


def table(runs, srcs, cases) -> dict:
    """Medians per (tree, case), each case's CPU per particle-step against the largest
    cylinder's (same tree) and against the first tree's (same case)."""
    med = {}
    for s in srcs:
        for c in cases:
            rs = [r for r in runs if r["src"] == s and r["case"] == c]
            med[(s, c)] = {k: _median(rs, k) for k in (
                "balls", "bonds_per_ball", "steps", "records", "engine_calls", "rebuilds",
                "particle_steps_per_cpu_s", "engine_particle_steps_per_cpu_s",
                "outside_engine", "measure_share", "servo_share", "peak_rss_mb")}
    big = "ucs_10k" if "ucs_10k" in cases else cases[-1]
    for s in srcs:
        for c in cases:
            d = med[(s, c)]
            d["vs_10k"] = (med[(s, big)]["particle_steps_per_cpu_s"]
                           / d["particle_steps_per_cpu_s"])
            d["vs_first_src"] = (med[(srcs[0], c)]["particle_steps_per_cpu_s"]
                                 / d["particle_steps_per_cpu_s"])
    return med


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=4000, help="loading steps of every case (>= 1)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated, of: "
                    + ", ".join(CASES))
    ap.add_argument("--src", action="append", default=None,
                    help="a source tree (its src/ directory); repeatable: paired trees")
    ap.add_argument("--reference", action="store_true",
                    help="add the engine's 10k-ball benchmark (dem_throughput.py) as a case")
    ap.add_argument("--cache", default=str(Path(os.environ.get(
        "BPMCAL_CACHE", Path.home() / ".cache" / "bpmcal")) / "small_model_speed"),
        help="specimen cache of the cases' packings")
    ap.add_argument("--card-json", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--json", default=None, help="write every run and the medians here")
    a = ap.parse_args(argv)
    a.card = json.loads(a.card_json) if a.card_json else dict(CARD)
    if a.steps < 1 or a.repeat < 1:
        ap.error(f"--steps {a.steps}, --repeat {a.repeat}: expected integers >= 1")
    if a.child:
        d = (_reference(a.steps, a.threads) if a.child == "bench_10k"
             else _child(a.child, a.steps, a.cache, a.card, a.threads))
        print(json.dumps(d))
        return
    cases = a.cases.split(",") + (["bench_10k"] if a.reference else [])
    bad = [c for c in cases if c not in CASES and c != "bench_10k"]
    if bad:
        ap.error(f"--cases: unknown {bad}; expected some of {', '.join(CASES)}")
    srcs = a.src or [""]
    load0 = os.getloadavg()
    print(f"host: {host()}; load average {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}; "
          f"threads {a.threads}; {a.steps} loading steps per case", flush=True)
    for s in srcs:  # the packings and the kernels (compiled or loaded), untimed
        for c in cases:
            _run(s, c, argparse.Namespace(**{**vars(a), "steps": 10}))
    runs = []
    order = [(s, c) for c in cases for s in srcs]
    for r in range(a.repeat):
        k = r % len(order)
        for s, c in order[k:] + order[:k]:
            d = _run(s, c, a)
            d.update(src=s, repeat=r)
            runs.append(d)
            print(f"  {c:11s} {s or '(installed)':28s} {d['balls']:6d} balls "
                  f"{d['particle_steps_per_cpu_s'] / 1e6:6.2f} M/CPU-s (engine "
                  f"{d['engine_particle_steps_per_cpu_s'] / 1e6:6.2f}), outside the engine "
                  f"{100 * d['outside_engine']:4.1f} % (measurements {100 * d['measure_share']:4.1f} %, "
                  f"servo {100 * d['servo_share']:4.1f} %)", flush=True)
    load1 = os.getloadavg()
    med = table(runs, srcs, cases)
    print(f"\nmedians of {a.repeat}; load average after {load1[0]:.2f} {load1[1]:.2f} "
          f"{load1[2]:.2f}")
    print("case        src                          balls bonds/ball steps recs calls "
          "M p-steps/CPU-s (engine) outside (measure servo)  cost vs 10k  vs first src  peak MB")
    for s, c in order:
        d = med[(s, c)]
        print(f"{c:11s} {(s or '(installed)')[-28:]:28s} {d['balls']:6.0f} {d['bonds_per_ball']:6.2f} "
              f"{d['steps']:6.0f} {d['records']:4.0f} {d['engine_calls']:5.0f} "
              f"{d['particle_steps_per_cpu_s'] / 1e6:10.2f} "
              f"({d['engine_particle_steps_per_cpu_s'] / 1e6:5.2f}) "
              f"{100 * d['outside_engine']:6.1f} % ({100 * d['measure_share']:4.1f} "
              f"{100 * d['servo_share']:4.1f})  {d['vs_10k']:8.3f}  {d['vs_first_src']:10.3f}"
              f"  {d['peak_rss_mb']:7.0f}")
    if a.json:
        out = {"host": host(), "load_average_before": list(load0),
               "load_average_after": list(load1), "steps": a.steps, "threads": a.threads,
               "repeat": a.repeat, "card": a.card, "srcs": srcs, "cases": cases,
               "median": {f"{s}|{c}": v for (s, c), v in med.items()}, "runs": runs}
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
