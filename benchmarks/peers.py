"""bpmcal side by side with its peers (LAMMPS frictional, YADE bonded): one table.

    python benchmarks/peers.py --n 10000 30000 --threads 1 2 --repeat 3 [--steps 1000]
                               [--peers lammps yade] [--src base=/tmp/base/src]
                               [--json results.json]

For every N and thread count, each repeat runs the peers and bpmcal one after the other
(never at the same time; the order rotates from one repeat to the next, so a burst of
load on a shared machine does not always hit the same code). The table gives the median
over the repeats of each code's particle-steps/s (wall clock, each code's own timer
around its stepping loop) and the ratios of the medians; the JSON has every run.

The host is described so that figures from different machines can be read side by side:
the CPU model (``lscpu``, /proc/cpuinfo), the CPU name LLVM compiles bpmcal for
(llvmlite), the cache sizes, and a memory-bandwidth probe: one thread multiplying a
float64 array in place (``a *= 1.0000001``, read + write counted, best of several passes)
at 4, 16 and 32 MB working sets. The 1-minute load average before and after every run is
kept: on a machine shared with other jobs a load above the thread count means the runs
competed for cores; the ``cpu`` columns (N * steps / CPU seconds of the run, one thread)
are then the better figure, but only a quiet machine gives the real wall-clock numbers.

The peers are ``peer_lammps.py`` and ``peer_yade.py`` (see their docstrings for what is
equivalent); a peer that is not installed is skipped with a note. ``--src NAME=PATH``
adds another bpmcal source tree (its ``src`` directory, e.g. a worktree of an earlier
commit) as one more code, run by this tree's ``dem_throughput.py`` in the same rotation:
a before/after comparison of an engine change side by side with the peers.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def _lscpu() -> dict:
    out = {}
    try:
        txt = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        return out
    for line in txt.splitlines():
        k, _, v = line.partition(":")
        out[k.strip()] = v.strip()
    return out


def host_info() -> dict:
    ls = _lscpu()
    model = ls.get("Model name", "")
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = model or line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    flags = ls.get("Flags", "").split()
    try:
        import llvmlite.binding as llvm
        llvm_cpu = llvm.get_host_cpu_name()
    except Exception:  # noqa: BLE001 - informative only
        llvm_cpu = "?"
    import numba
    return {"cpu_model": model, "cpu_family": ls.get("CPU family"), "cpu_model_id": ls.get("Model"),
            "llvm_host_cpu": llvm_cpu, "avx512f": "avx512f" in flags, "avx2": "avx2" in flags,
            "cores": os.cpu_count(), "l2": ls.get("L2 cache"), "l3": ls.get("L3 cache"),
            "hypervisor": ls.get("Hypervisor vendor"), "kernel": platform.release(),
            "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba.__version__}


def bandwidth_probe(sizes_mb=(4, 16, 32), seconds=0.4) -> dict:
    """Single-thread in-place multiply, GB/s (read + write bytes / time), best pass."""
    res = {}
    for mb in sizes_mb:
        a = np.full(int(mb * 2 ** 20) // 8, 1.0)
        f = 1.0000001
        a *= f  # touch the pages
        best = 0.0
        t_end = time.perf_counter() + seconds
        while time.perf_counter() < t_end:
            t0 = time.perf_counter()
            a *= f
            dt = time.perf_counter() - t0
            best = max(best, 2.0 * a.nbytes / dt / 1e9)
        res[f"{mb}MB"] = round(best, 1)
    return res


def _median(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else None


def _label(p: str) -> str:
    return {"lammps": "LAMMPS frictional", "yade": "YADE bonded"}.get(p, f"bpmcal {p}")


def run_case(n, threads, steps, repeat, peers, seed, log, srcs=None):
    import _peer
    import peer_lammps
    import peer_yade
    runners = {"bpmcal": lambda: _peer.run_bpmcal(n, threads, steps, seed)}
    for name, path in (srcs or {}).items():
        runners[name] = (lambda path=path: _peer.run_bpmcal(n, threads, steps, seed,
                                                            src=path))
    if "lammps" in peers:
        runners["lammps"] = lambda: peer_lammps.run_lammps(n, threads, steps, seed,
                                                           shutil.which("lmp"))
    if "yade" in peers:
        runners["yade"] = lambda: peer_yade.run_yade(n, threads, steps, seed,
                                                     shutil.which("yade"))
    names = list(runners)
    runs = {k: [] for k in names}
    for r in range(repeat):
        order = names[r % len(names):] + names[:r % len(names)]
        for name in order:
            load0 = os.getloadavg()[0]
            res = runners[name]()
            res["load1_before"] = round(load0, 2)
            res["load1_after"] = round(os.getloadavg()[0], 2)
            res["repeat"] = r
            runs[name].append(res)
            log(f"#   n={n} threads={threads} repeat {r + 1}/{repeat} {name:7s} "
                f"{res['particle_steps_per_s'] / 1e6:7.3f} M particle-steps/s "
                f"(load {res['load1_before']:.2f} -> {res['load1_after']:.2f})")
    out = {"n": n, "threads": threads, "steps": steps, "runs": runs, "median": {},
           "median_cpu": {}}
    for name in names:
        out["median"][name] = _median([x["particle_steps_per_s"] for x in runs[name]])
        out["median_cpu"][name] = _median([x.get("particle_steps_per_cpu_s") for x in runs[name]])
    for name in names:
        if name == "bpmcal":
            continue
        out[f"ratio_{name}"] = out["median"]["bpmcal"] / out["median"][name]
        per = [b["particle_steps_per_s"] / p["particle_steps_per_s"]
               for b, p in zip(runs["bpmcal"], runs[name])]
        out[f"ratio_{name}_per_repeat"] = per
        if threads == 1 and out["median_cpu"].get(name) and out["median_cpu"]["bpmcal"]:
            out[f"ratio_{name}_cpu"] = out["median_cpu"]["bpmcal"] / out["median_cpu"][name]
    loads = [x["load1_before"] for v in runs.values() for x in v] + \
        [x["load1_after"] for v in runs.values() for x in v]
    out["load1_range"] = [min(loads), max(loads)]
    return out


def table(cases, peers) -> str:
    def m(x):
        return "–" if x is None else f"{x / 1e6:.2f}"

    head = "| N | threads | bpmcal bonded | " + "".join(
        f"{_label(p)} | bpmcal / {p} | "
        for p in peers) + "bpmcal cpu (1 thread) | 1-min load |"
    sep = "|" + "---|" * (head.count("|") - 1)
    rows = [head, sep]
    one = {c["n"]: c for c in cases if c["threads"] == 1}
    for c in cases:
        cells = [f"{c['n']:,}", str(c["threads"]), m(c["median"]["bpmcal"])]
        for p in peers:
            cells.append(m(c["median"].get(p)))
            r = c.get(f"ratio_{p}")
            rc = c.get(f"ratio_{p}_cpu")
            cells.append("–" if r is None else f"{r:.2f}" + (f" (cpu {rc:.2f})" if rc else ""))
        cells.append(m(c["median_cpu"]["bpmcal"]) if c["threads"] == 1 else "–")
        cells.append(f"{c['load1_range'][0]:.2f}–{c['load1_range'][1]:.2f}")
        rows.append("| " + " | ".join(cells) + " |")
    rows.append("")
    rows.append("Medians of the repeats, million particle-steps per second (wall clock). "
                "Ratios: bpmcal median / peer median (cpu: the same with CPU seconds, one "
                "thread).")
    scal = []
    for c in cases:
        if c["threads"] > 1 and c["n"] in one:
            s = c["median"]["bpmcal"] / one[c["n"]]["median"]["bpmcal"]
            scal.append(f"bpmcal {c['threads']} threads / 1 thread at N = {c['n']:,}: {s:.2f}")
    return "\n".join(rows + scal)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[10000, 30000])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--steps", type=int, default=1000, help="timed steps (every code)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--peers", nargs="*", default=["lammps", "yade"],
                    choices=["lammps", "yade"])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--src", action="append", default=[], metavar="NAME=PATH",
                    help="another bpmcal source tree (its src directory) run as one more "
                         "code, e.g. base=/tmp/base/src (repeatable)")
    ap.add_argument("--json", default=None, help="also write everything to this JSON file")
    a = ap.parse_args(argv)
    srcs = {}
    for item in a.src:
        name, _, path = item.partition("=")
        if not name or name in ("bpmcal", "lammps", "yade") or not Path(path, "bpmcal").is_dir():
            ap.error(f"--src {item!r}: expected NAME=PATH with a new NAME and PATH a "
                     "directory holding the bpmcal package")
        srcs[name] = str(Path(path).resolve())

    def log(*x):
        print(*x, file=sys.stderr, flush=True)

    peers = []
    for p in a.peers:
        exe = {"lammps": "lmp", "yade": "yade"}[p]
        if shutil.which(exe) is None:
            log(f"# {p} skipped: `{exe}` is not on PATH (apt-get install -y "
                f"{'lammps' if p == 'lammps' else 'yade'})")
        else:
            peers.append(p)
    host = host_info()
    host["bandwidth_GBs"] = bandwidth_probe()
    log(f"# {host['cpu_model']} ({host['llvm_host_cpu']}), {host['cores']} cores, L3 "
        f"{host['l3']}; in-place multiply GB/s {host['bandwidth_GBs']}")
    t0 = time.strftime("%Y-%m-%dT%H:%M:%S")
    cases = []
    for n in a.n:
        for th in a.threads:
            cases.append(run_case(n, th, a.steps, a.repeat, peers, a.seed, log, srcs))
    host["bandwidth_GBs_after"] = bandwidth_probe()
    res = {"date_start": t0, "date_end": time.strftime("%Y-%m-%dT%H:%M:%S"), "host": host,
           "steps": a.steps, "repeat": a.repeat, "peers": peers, "srcs": srcs,
           "cases": cases}
    bw = host["bandwidth_GBs"]
    print(f"Host: {host['cpu_model']} (LLVM: {host['llvm_host_cpu']}, "
          f"{'AVX-512' if host['avx512f'] else 'AVX2' if host['avx2'] else 'no AVX2'}), "
          f"{host['cores']} cores, L2 {host['l2']}, L3 {host['l3']}; single-thread in-place "
          f"multiply: " + ", ".join(f"{v} GB/s at {k}" for k, v in bw.items())
          + f" (after the runs: {host['bandwidth_GBs_after']}).\n")
    print(table(cases, peers + list(srcs)))
    print()
    print(json.dumps(res))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
