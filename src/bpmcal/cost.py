"""What a process spends its CPU on, phase by phase: the ledger behind the run files'
``/cost`` group and the cost line of a job's log, which the cost model of a study reads
(``benchmarks/cost_model.py``).

A phase is a named block of work, ``with phase("genesis"): ...``; phases nest, and each
is booked under its path (``ucs/genesis/packing``). The ledger books the CPU seconds of
the process (``time.process_time``: every thread of it) to the innermost phase running,
so no second is booked twice, and the ball-steps the engine runs (``lab.stepping.cycle``
books them, with the CPU of the engine's calls, to the phase ``engine`` inside the phase
that runs them). Three phases are booked by the ledger itself:

- ``start``: the process's CPU seconds before :func:`begin` (the start of the ``bpmcal``
  command): the interpreter, the imports and the parsing of the command line (the
  parser of a DEM command imports the engine, numba with it);
- ``kernels``: numba's loading of a kernel at its first call in the process (from the
  on-disk cache, or compiling it), wherever that call happens; its time is taken out of
  the phase that made the call; ``kernels_setup``: inside the first of them, the
  one-time set-up of numba's compiler context. :func:`meter_numba` installs the meter
  (``dem._jit`` does, on import).

What no phase holds is ``other`` (argument checks, the gaps between phases).
:meth:`Ledger.take` returns what was booked since the last ``take`` of the same name: a
run file records its share of the process (``stages.runs``: everything since the run
file before it, its own writing included), a worker process of a ``stages.pool`` pool
returns its share with each run, and :func:`job_cost` gives the whole process (with
the shares of its workers) for the cost line of a job's log (``bpmcal`` prints it when
``BPMCAL_COST`` is set: the workflow sets it).

No number of a run depends on the ledger: it reads clocks and counts steps.
"""
from __future__ import annotations

import json
import os
import resource
import sys
import time

_clock = time.process_time

#: environment variable: when set (to anything but "" or "0"), ``bpmcal`` prints the cost
#: line of the job (``job_cost``) at its end, on standard error
COST_ENV = "BPMCAL_COST"
#: the cost line's prefix (after ``bpmcal <command>: ``)
COST_TAG = "cost "


class _Phase:
    """One open phase of the ledger (a context manager; cheaper than a generator)."""

    __slots__ = ("ledger", "path", "c0", "kids", "steps", "engine")

    def __init__(self, ledger: "Ledger", path: str):
        self.ledger = ledger
        self.path = path
        self.c0 = 0.0
        self.kids = 0.0
        self.steps = 0
        self.engine = f"{path}/engine"  # where the engine's calls inside it are booked

    def __enter__(self) -> "_Phase":
        self.c0 = _clock()
        self.ledger.stack.append(self)
        return self

    def __exit__(self, *exc) -> None:
        self.ledger._close(self)


class Ledger:
    """The CPU seconds and ball-steps of one process by phase path, cumulative since the
    process began (module doc)."""

    def __init__(self):
        self.cpu: dict[str, float] = {}
        self.ball_steps: dict[str, int] = {}
        self.calls: dict[str, int] = {}  # phases ended, by path (not the engine's calls)
        self.stack: list[_Phase] = []
        self.marks: dict[str, tuple] = {}
        self.workers: dict[str, float] = {}  # CPU of worker processes, by phase path
        self.worker_steps: dict[str, int] = {}
        self.worker_calls: dict[str, int] = {}
        self.begun = False
        self._loose_kids = 0.0  # time of the phases closed with none open around them

    def path(self) -> str:
        """The path of the innermost open phase ("" when none is open)."""
        return self.stack[-1].path if self.stack else ""

    def phase(self, name: str, flat: bool = False) -> _Phase:
        """A phase inside the one open now (``flat``: booked under ``name`` alone,
        wherever it runs; its time is still taken out of the open phase)."""
        parent = self.path()
        if flat or not parent:
            path = name
        else:
            path = f"{parent}/{name}"
        return _Phase(self, path)

    def _close(self, ph: _Phase) -> None:
        dt = _clock() - ph.c0
        stack = self.stack
        while stack and stack[-1] is not ph:  # a phase left open by an exception
            self._close(stack[-1])
        if stack:
            stack.pop()
        self.cpu[ph.path] = self.cpu.get(ph.path, 0.0) + dt - ph.kids
        if ph.steps:
            self.ball_steps[ph.path] = self.ball_steps.get(ph.path, 0) + ph.steps
        else:
            self.calls[ph.path] = self.calls.get(ph.path, 0) + 1
        if stack:
            stack[-1].kids += dt
        else:
            self._loose_kids += dt  # booked at the top level (engine_end reads it)

    def engine(self, ball_steps: int) -> _Phase:
        """The phase ``engine`` inside the open one, booking ``ball_steps`` (a model's
        balls x the steps of one call of the engine)."""
        ph = self.phase("engine")
        ph.steps = int(ball_steps)
        return ph

    def engine_start(self) -> tuple:
        """The clock before a call of the engine (:meth:`engine_end` books it): the same
        booking as a :meth:`engine` phase for less work (``lab.stepping.cycle`` calls the
        engine thousands of times in a test). Opaque to the caller: the clock and the time
        the open phase's children had booked so far."""
        top = self.stack[-1] if self.stack else None
        return (_clock(), top.kids if top is not None else self._loose_kids)

    def engine_end(self, c0: tuple, ball_steps: int) -> None:
        """Book a call of the engine that began at ``c0`` (:meth:`engine_start`) and ran
        ``ball_steps`` ball-steps to the phase ``engine`` inside the open one. A phase
        that ran and closed inside the call (numba compiling or loading a kernel at its
        first call: the flat phase ``kernels``) keeps its own time: the engine is booked
        the call's time less that, so no second is booked twice."""
        t0, kids0 = c0
        top = self.stack[-1] if self.stack else None
        inner = (top.kids if top is not None else self._loose_kids) - kids0
        dt = _clock() - t0 - inner
        path = top.engine if top is not None else "engine"
        self.cpu[path] = self.cpu.get(path, 0.0) + dt
        self.ball_steps[path] = self.ball_steps.get(path, 0) + ball_steps
        if top is not None:
            top.kids += dt

    def _flush(self) -> float:
        """Book the open phases' time so far (they go on from now); the clock now."""
        now = _clock()
        for ph in reversed(self.stack):  # innermost first: its time is its parent's child
            dt = now - ph.c0
            self.cpu[ph.path] = self.cpu.get(ph.path, 0.0) + dt - ph.kids
            ph.c0, ph.kids = now, 0.0
        return now

    def begin(self) -> None:
        """The start of the command: the CPU seconds so far are ``start``."""
        if not self.begun:
            self.begun = True
            self.cpu["start"] = self.cpu.get("start", 0.0) + _clock()

    def _snapshot(self) -> tuple:
        now = self._flush()
        return (now, dict(self.cpu), dict(self.ball_steps), dict(self.calls))

    def take(self, name: str) -> dict:
        """What was booked since the last ``take(name)`` (the first: since the process
        began): ``cpu_s`` (the process's CPU seconds in between), ``phases`` (CPU seconds
        by phase path, ``other`` = what no phase holds), ``ball_steps`` (by phase path)
        and ``calls`` (the phases that ended, by path; the engine's calls are not
        counted)."""
        now, cpu, steps, calls = self._snapshot()
        t0, cpu0, steps0, calls0 = self.marks.get(name, (0.0, {}, {}, {}))
        self.marks[name] = (now, cpu, steps, calls)
        phases = {k: v - cpu0.get(k, 0.0) for k, v in cpu.items()}
        phases = {k: v for k, v in phases.items() if v > 0.0}
        total = now - t0
        phases["other"] = total - sum(phases.values())
        bs = {k: v - steps0.get(k, 0) for k, v in steps.items()}
        nc = {k: v - calls0.get(k, 0) for k, v in calls.items()}
        return {"cpu_s": total, "phases": phases,
                "ball_steps": {k: v for k, v in bs.items() if v},
                "calls": {k: v for k, v in nc.items() if v}}

    def add_worker(self, share: dict) -> None:
        """A worker process's share (its ``take``) of this process's work."""
        for k, v in share.get("phases", {}).items():
            self.workers[k] = self.workers.get(k, 0.0) + v
        for k, v in share.get("ball_steps", {}).items():
            self.worker_steps[k] = self.worker_steps.get(k, 0) + v
        for k, v in share.get("calls", {}).items():
            self.worker_calls[k] = self.worker_calls.get(k, 0) + v


#: the ledger of this process
LEDGER = Ledger()


def phase(name: str, flat: bool = False) -> _Phase:
    """``LEDGER.phase``: ``with phase("genesis"): ...``."""
    return LEDGER.phase(name, flat)


def begin() -> None:
    """``LEDGER.begin``: called by ``bpmcal`` when its command starts."""
    LEDGER.begin()


def _metered(owner, name: str, phase_name: str) -> bool:
    """Wrap method ``name`` of class ``owner`` so that its calls are booked to the flat
    phase ``phase_name``; False when there is no such method."""
    f = getattr(owner, name, None)
    if f is None:
        return False
    if getattr(f, "_bpmcal_metered", False):
        return True

    def metered(self, *args, **kws):
        with LEDGER.phase(phase_name, flat=True):
            return f(self, *args, **kws)

    metered._bpmcal_metered = True
    metered.__doc__ = f.__doc__
    setattr(owner, name, metered)
    return True


def meter_numba() -> bool:
    """Book numba's loading (or compiling) of each kernel at its first call to the flat
    phase ``kernels``, and the one-time set-up of its compiler context inside the first
    one (the registries of its implementations, which import scipy.linalg) to
    ``kernels_setup``: wraps the two numba methods they run in (the dispatcher's, which
    a call without a matching compiled version goes through, and the CPU context's); the
    kernels and their results are untouched. False when numba has no such methods
    (another numba version: nothing is booked)."""
    try:
        from numba.core.cpu import CPUContext
        from numba.core.dispatcher import Dispatcher
    except ImportError:
        return False
    return (_metered(Dispatcher, "_compile_for_args", "kernels")
            and _metered(CPUContext, "load_additional_registries", "kernels_setup"))


def job_cost() -> dict:
    """The whole process so far, for the cost line of a job's log: ``cpu_s`` (this
    process), ``children_cpu_s`` (its finished child processes, the workers of a pool
    among them), ``phases`` and ``ball_steps`` of this process and ``worker_phases`` /
    ``worker_ball_steps`` (what its workers reported), ``max_rss_mb``."""
    own = LEDGER.take("job")
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    me = resource.getrusage(resource.RUSAGE_SELF)
    return {"cpu_s": round(own["cpu_s"], 6),
            "children_cpu_s": round(ch.ru_utime + ch.ru_stime, 6),
            "phases": {k: round(v, 6) for k, v in sorted(own["phases"].items())},
            "ball_steps": dict(sorted(own["ball_steps"].items())),
            "worker_phases": {k: round(v, 6) for k, v in sorted(LEDGER.workers.items())},
            "worker_ball_steps": dict(sorted(LEDGER.worker_steps.items())),
            "calls": dict(sorted(own["calls"].items())),
            "worker_calls": dict(sorted(LEDGER.worker_calls.items())),
            "max_rss_mb": round(me.ru_maxrss / 1024.0, 1)}


def cost_line_wanted() -> bool:
    """Whether ``bpmcal`` prints the cost line (``BPMCAL_COST``)."""
    return os.environ.get(COST_ENV, "") not in ("", "0")


def print_cost_line(where: str) -> None:
    """With ``BPMCAL_COST`` set: ``<where>: cost {JSON of job_cost()}`` on standard error,
    one line (the cost model reads it from the job's log)."""
    if not cost_line_wanted():
        return
    try:
        line = f"{where}: {COST_TAG}{json.dumps(job_cost(), separators=(',', ':'))}"
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # a closed stderr: the line is not needed to finish
        pass
