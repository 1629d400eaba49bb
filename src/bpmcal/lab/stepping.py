"""Run DEM steps in calls short enough for Ctrl-C.

Python handles a signal (SIGINT, SIGTERM) only between two bytecodes, never inside a
numba call: ``Model.cycle(n)`` on a large specimen can hold the interpreter for many
seconds. :func:`cycle` runs the same steps in consecutive calls of about ``CALL_S``
seconds each (sized from the ball count and the speed measured in the previous calls, of
any model: the machine's speed), so an interrupt is honoured within a fraction of a
second. Splitting is exact:
the engine's state after ``cycle(m, a + b)`` is bitwise that of ``m.cycle(a + b)``
(tested), only the state energies are recorded at the last step as before.

The virtual tests (genesis, every lab test through ``lab.driver``, the impact) call
``cycle(m, n)`` instead of ``m.cycle(n)``.
"""
from __future__ import annotations

import time
from contextlib import contextmanager

from ..cost import LEDGER
from ..dem.material import expected_failure_strain, stiffest_spring
from .budget import Loading, check_loading_steps

#: target duration of one numba call [s]
CALL_S = 0.2
#: ball-steps of the first call, before any speed is measured (~0.1-0.5 s at 1-5 M
#: ball-steps/s, a loaded machine)
FIRST_BALL_STEPS = 500_000

_rate = None  # measured ball-steps per second (the last calls)

#: seconds between two heartbeats (:func:`heartbeat`) during a long ``cycle``
HEARTBEAT_S = 5.0
_beat = [None, 0.0, HEARTBEAT_S]  # callback, time of the last beat, interval


@contextmanager
def heartbeat(fn, every: float | None = None):
    """Inside the block, :func:`cycle` calls ``fn()`` between its pieces whenever ``every``
    seconds (default :data:`HEARTBEAT_S`) have passed since the last call (or since the
    block began): a lab test's progress line keeps coming while one record interval takes
    minutes."""
    prev = list(_beat)
    _beat[:] = [fn, time.perf_counter(), float(HEARTBEAT_S if every is None else every)]
    try:
        yield
    finally:
        _beat[:] = prev


def beat_now() -> None:
    """Restart the heartbeat's interval (the caller has just reported progress itself)."""
    _beat[1] = time.perf_counter()


def cycle(m, nsteps: int, record: bool = True, run=None, quantum: int = 1) -> None:
    """``m.cycle(nsteps, record)`` in interruptible pieces (same result). ``run(k, rec)``
    takes the steps instead of ``m.cycle`` (a servo loop in the engine,
    ``Model.cycle_servo``); every piece but the last is then a multiple of ``quantum``
    steps (the loop's chunk: a piece never ends inside one)."""
    global _rate
    nsteps = int(nsteps)
    run = m.cycle if run is None else run
    if nsteps <= 0:
        run(nsteps, record)
        return
    n = max(1, m.n)
    q = max(1, int(quantum))
    done = 0
    while done < nsteps:
        budget = CALL_S * _rate if _rate else FIRST_BALL_STEPS
        k = max(1, int(budget / n))
        k = min(max(q, k - k % q), nsteps - done)
        t = time.perf_counter()
        c0 = LEDGER.engine_start()  # the cost ledger: CPU and ball-steps of the engine
        try:
            run(k, record and done + k == nsteps)
        finally:
            LEDGER.engine_end(c0, k * n)
        el = time.perf_counter() - t
        done += k
        if el > 1e-3:  # a measurable call: update the speed (fast to slow down)
            r = k * n / el
            _rate = r if _rate is None or r < _rate else 0.7 * _rate + 0.3 * r
        if _beat[0] is not None and done < nsteps:
            now = time.perf_counter()
            if now - _beat[1] >= _beat[2]:
                _beat[1] = now
                _beat[0]()


def loading_bound(m, settings, loading: Loading) -> int:
    """``budget.check_loading_steps`` for ``loading`` (``budget.Loading``) on model ``m``
    with the test's ``settings`` (``max_strain``, ``max_steps``): the loading's step
    bound, or a ``StepBudgetError``."""
    return check_loading_steps(
        loading, dt=m.dt, max_strain=settings.max_strain, max_steps=settings.max_steps,
        n_balls=m.n, ball_steps_per_s=_rate, spring=stiffest_spring(m.material),
        failure_strain=expected_failure_strain(m.material, loading.tension))


class LoadingProgress:
    """Progress of a lab test's loading: ``tell(**values)`` passes the latest values (kept
    between calls: a heartbeat may update only the strain) to ``progress`` with the steps
    so far, the wall time, the loading's step estimate (``bound_steps``,
    ``budget.check_loading_steps``: a bound unless the card fails later than its bonds'
    strength over modulus says, as a confined one does) and the test's ``max_strain``
    (where the loading stops at the latest), from which a progress line shows percent and
    ETA."""

    def __init__(self, progress, m, step0: int, bound: int, max_strain: float | None = None):
        self.progress = progress
        self.m = m
        self.step0 = step0
        self.bound = int(bound)
        self.max_strain = max_strain
        self.last = {}
        self.t0 = time.perf_counter()

    def __call__(self, **values):
        self.last.update(values)
        beat_now()
        if self.progress is not None:
            self.progress({**self.last, "steps": self.m.step - self.step0,
                           "wall_s": time.perf_counter() - self.t0,
                           "bound_steps": self.bound, "max_strain": self.max_strain})
