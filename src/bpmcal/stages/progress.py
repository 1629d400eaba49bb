"""Progress of a long run on stderr: a one-line bar on a terminal, plain log lines (every
``every`` seconds) in a log file. Stages and lab tests take any callable ``progress(d)``;
this is the one the ``bpmcal`` command passes."""
from __future__ import annotations

import sys
import time


def _duration(s: float) -> str:
    """``s`` seconds as 42 s, 7 min or 3.5 h."""
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


class Progress:
    """A one-line progress bar on a terminal, plain log lines (every ``every`` s) otherwise."""

    def __init__(self, label: str, stream=None, every: float = 10.0, enabled: bool = True):
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.label = label
        self.every = every
        self.enabled = enabled
        self._last = 0.0
        self._t0 = time.perf_counter()

    def __call__(self, d: dict):
        if not self.enabled:
            return
        now = time.perf_counter()
        if "note" in d:  # an event worth a line of its own (never throttled)
            if self.tty:
                self.stream.write("\n")
            self.stream.write(f"{self.label}: {d['note']}\n")
            self.stream.flush()
            return
        if not self.tty and now - self._last < self.every:
            return
        self._last = now
        if "phase" in d:  # genesis: phase, steps, ratio, target, wall_s (of the phase)
            rate = d.get("steps", 0) / max(d.get("wall_s", 0.0), 1e-9)
            self._write(f"{self.label}: genesis, {d['phase']:16s} unbalanced-force ratio "
                        f"{d.get('ratio', 0):9.3g} (target {d.get('target', 0):g})  "
                        f"{d.get('steps', 0):8d} steps  {rate:8.0f} steps/s")
            return
        rate = d.get("steps", 0) / max(d.get("wall_s", now - self._t0), 1e-9)
        line = (f"{self.label}: strain {d.get('strain', 0) * 100:6.3f} %  stress "
                f"{d.get('stress_MPa', 0):7.2f} MPa (peak {d.get('peak_MPa', 0):7.2f})  cracks "
                f"{d.get('cracks', 0):6d}  {d.get('steps', 0):8d} steps  {rate:8.0f} steps/s")
        b, n, eps, top = (d.get("bound_steps"), d.get("steps", 0), d.get("strain", 0.0),
                          d.get("max_strain"))
        if b and n <= b:  # the loading's step estimate: an upper bound so far
            left = (b - n) / max(rate, 1e-9)
            line += f"  {100.0 * n / b:5.1f} % of at most {b} steps, ETA <= {_duration(left)}"
        elif b and top and 0 < eps < top:  # past the estimate (a confined card fails later):
            left = (top - eps) / eps * n / max(rate, 1e-9)  # the max strain is the bound
            line += (f"  past the estimate of {b} steps; {100.0 * eps / top:5.1f} % of the "
                     f"max strain {100.0 * top:g} %, ETA <= {_duration(left)}")
        self._write(line)

    def _write(self, line: str):
        if self.tty:
            self.stream.write("\r" + line)
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def done(self, msg: str = ""):
        if self.enabled and self.tty:
            self.stream.write("\n")
        if msg and self.enabled:
            self.stream.write(msg + "\n")
            self.stream.flush()
