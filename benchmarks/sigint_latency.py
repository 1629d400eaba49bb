"""How fast does `bpmcal ucs` honour Ctrl-C (SIGINT)?

Starts `bpmcal ucs`, sends SIGINT after a delay and measures the time from the signal to
the process exit. Also checks the exit code (130), that no output file and no temporary
file are left. Prints every trial and the median / maximum latency. Two cases:

- ``--case genesis``: a specimen slow to settle (pb_kratio = 1e-6 makes the timestep
  ~300 x shorter; the step budget lifted; 1e-9 is now refused before genesis): the
  signal arrives during the genesis;
- ``--case test``: the A1 set loaded slowly (platens at 1e-4 m/s: ~25,000 steps between
  two records, one numba call before the calls were split): the signal arrives during
  the UCS test.

    python benchmarks/sigint_latency.py [--case genesis] [--scale 0.5] [--trials 5]

The engine runs in numba calls of about ``bpmcal.lab.stepping.CALL_S`` (0.2 s); Python
handles the signal when the current call returns.
"""
from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bpmcal.study.paper import A1  # the paper's card


def trial(d: Path, case: str, scale: float, delay: float, threads: int
          ) -> tuple[float, int, list]:
    params = d / "p.yaml"
    p = dict(A1, pb_kratio=1e-6) if case == "genesis" else A1
    params.write_text("".join(f"{k}: {v}\n" for k, v in p.items()))
    out = d / "run" / "r.h5"
    cmd = [sys.executable, "-m", "bpmcal.cli", "ucs", "--params", str(params), "--out",
           str(out), "--scale", str(scale), "--threads", str(threads),
           "--specimen-cache", str(d / "cache")]
    cmd += (["--genesis-max-steps", "10000000"] if case == "genesis"
            else ["--platen-velocity", "1e-4"])
    # SIGINT at its default in the child, as for a user at a terminal (a background job of
    # a non-interactive shell inherits it ignored)
    p = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(delay)
    if p.poll() is not None:
        raise RuntimeError(f"finished before the signal: {p.stderr.read()}")
    t0 = time.perf_counter()
    p.send_signal(signal.SIGINT)
    p.wait()
    lat = time.perf_counter() - t0
    left = [f.name for f in out.parent.iterdir()] if out.parent.exists() else []
    return lat, p.returncode, left


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=["genesis", "test"], default="genesis")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--threads", type=int, default=1)
    a = ap.parse_args()
    os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
    lats = []
    with tempfile.TemporaryDirectory() as tmp:
        if a.case == "test":  # build the packing once: the signal then hits the test
            trial(Path(tmp), a.case, a.scale, 60.0, a.threads)
        for k in range(a.trials):
            delay = (4.0 if a.case == "genesis" else 15.0) + 3.0 * k
            lat, rc, left = trial(Path(tmp), a.case, a.scale, delay, a.threads)
            lats.append(lat)
            print(f"trial {k + 1}: SIGINT after {delay:.0f} s -> exit {rc} in {lat:.3f} s, "
                  f"files left in the output folder: {left or 'none'}")
    print(f"latency: median {statistics.median(lats):.3f} s, max {max(lats):.3f} s "
          f"({a.case}, {a.trials} trials, scale {a.scale}, {a.threads} thread(s))")


if __name__ == "__main__":
    main()
