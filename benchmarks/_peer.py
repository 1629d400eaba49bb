"""What ``peer_lammps.py`` and ``peer_yade.py`` share: bpmcal's side of a peer comparison
(``benchmarks/dem_throughput.py --json`` in a subprocess), their command line, and the
loop that runs the peer, then bpmcal (never at the same time), and prints one JSON object::

    {"n", "threads", "steps", "bpmcal": {...}, "<peer>": {...},
     "ratio_particle_steps": bpmcal / peer, "date", "loadavg_1_5_15_before", ..._after}

A peer that is not installed is reported (with how to install it) and the exit code is 0:
these are benchmarks, not tests. ``peers.py`` runs the same functions repeatedly.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

HERE = Path(__file__).resolve().parent


def install_msg(title: str, exe: str, package: str, script: str) -> str:
    """What to print when the peer's executable is not on PATH."""
    return (f"{title} is not installed (no `{exe}` on PATH), so the peer comparison was not "
            f"run.\nInstall it with:  apt-get install -y {package}   (Debian/Ubuntu package, "
            f"as root)\nthen rerun:       python benchmarks/{script} --n 10000 --threads 1 "
            f"--steps 1000")


def run_bpmcal(n: int, threads: int, steps: int, seed: int = 1,
               timeout: float = 3600.0, src: str | None = None) -> dict:
    """``dem_throughput.py`` in a fresh process; ``src``: another bpmcal source tree (its
    ``src`` directory) to import instead of the installed one."""
    env = dict(os.environ, NUMBA_THREADING_LAYER="omp")
    if src:
        env["PYTHONPATH"] = str(src)
    cmd = [sys.executable, str(HERE / "dem_throughput.py"), "--n", str(n), "--threads",
           str(threads), "--steps", str(steps), "--seed", str(seed), "--json"]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-30:])
        raise RuntimeError(f"dem_throughput.py failed (exit {proc.returncode}):\n{tail}")
    return json.loads(lines[-1])


def parser(doc: str, exe_option: str, exe_help: str,
           bpmcal_steps: bool = False) -> argparse.ArgumentParser:
    """The peer script's command line; ``exe_option`` (``--lmp``, ``--yade``) names the
    peer's executable, its default the option's name."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10000)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--steps", type=int, default=1000, help="timed steps (both codes)")
    if bpmcal_steps:
        ap.add_argument("--bpmcal-steps", type=int, default=None,
                        help="timed steps for bpmcal only (default: --steps)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(exe_option, default=exe_option[2:], help=exe_help)
    ap.add_argument("--json", action="store_true", help="print only the JSON object")
    return ap


def side_by_side(a: argparse.Namespace, name: str, title: str, exe: str | None,
                 version: Callable[[str], str], run_peer: Callable[..., dict],
                 install: str) -> int:
    """Run the peer ``name`` (``run_peer(n, threads, steps, seed, exe)``), then bpmcal, and
    print the JSON object (``--json``: only it, the progress on stderr). ``exe`` None: the
    peer is not installed, say so (``install``) and return 0."""
    if exe is None:
        if a.json:
            print(json.dumps({"n": a.n, "threads": a.threads, "steps": a.steps, name: None,
                              "skipped": f"{name} not installed: apt-get install -y {name}"}))
            print(install, file=sys.stderr)
        else:
            print(install)
        return 0
    log = (lambda *x: print(*x, file=sys.stderr, flush=True)) if a.json else \
        (lambda *x: print(*x, flush=True))
    log(f"# {time.strftime('%Y-%m-%d %H:%M:%S')}  n={a.n} threads={a.threads} "
        f"steps={a.steps}; {version(exe)}")
    load0 = os.getloadavg()
    log(f"# running {title} ...")
    pr = run_peer(a.n, a.threads, a.steps, a.seed, exe)
    log(f"#   {name:6s} {pr['particle_steps_per_s'] / 1e6:8.3f} M particle-steps/s "
        f"({pr['wall_s']:.2f} s for {pr['steps']} steps)")
    log("# running bpmcal (benchmarks/dem_throughput.py) ...")
    bp = run_bpmcal(a.n, a.threads, getattr(a, "bpmcal_steps", None) or a.steps, a.seed)
    log(f"#   bpmcal {bp['particle_steps_per_s'] / 1e6:8.3f} M particle-steps/s "
        f"({bp['wall_s']:.2f} s for {bp['steps']} steps)")
    res = {"n": a.n, "threads": a.threads, "steps": a.steps, "bpmcal": bp, name: pr,
           "ratio_particle_steps": bp["particle_steps_per_s"] / pr["particle_steps_per_s"],
           "date": time.strftime("%Y-%m-%dT%H:%M:%S"),
           # the machine is shared: a 1-min load average well above `threads` at the end
           # means other processes competed for the cores during the runs
           "loadavg_1_5_15_before": [round(x, 2) for x in load0],
           "loadavg_1_5_15_after": [round(x, 2) for x in os.getloadavg()]}
    if a.json:
        print(json.dumps(res))
    else:
        print(json.dumps(res, indent=1))
        print(f"bpmcal / {name} particle-steps/s: {res['ratio_particle_steps']:.2f}")
    return 0
