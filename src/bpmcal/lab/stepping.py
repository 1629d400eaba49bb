"""Run DEM steps in calls short enough for Ctrl-C.

Python handles a signal (SIGINT, SIGTERM) only between two bytecodes, never inside a
numba call: ``Model.cycle(n)`` on a large specimen can hold the interpreter for many
seconds. :func:`cycle` runs the same steps in consecutive calls of about ``CALL_S``
seconds each (sized from the ball count and the speed measured in the previous calls, of
any model: the machine's speed), so an interrupt is honoured within a fraction of a
second. Splitting is exact:
the engine's state after ``cycle(m, a + b)`` is bitwise that of ``m.cycle(a + b)``
(tested), only the state energies are recorded at the last step as before.

The virtual tests (genesis, UCS, impact and new ones) call ``cycle(m, n)`` instead of
``m.cycle(n)``.
"""
from __future__ import annotations

import time

#: target duration of one numba call [s]
CALL_S = 0.2
#: ball-steps of the first call, before any speed is measured (~0.1-0.5 s at 1-5 M
#: ball-steps/s, a loaded machine)
FIRST_BALL_STEPS = 500_000

_rate = None  # measured ball-steps per second (the last calls)


def cycle(m, nsteps: int, record: bool = True) -> None:
    """``m.cycle(nsteps, record)`` in interruptible pieces (same result)."""
    global _rate
    nsteps = int(nsteps)
    if nsteps <= 0:
        m.cycle(nsteps, record=record)
        return
    n = max(1, m.n)
    done = 0
    while done < nsteps:
        budget = CALL_S * _rate if _rate else FIRST_BALL_STEPS
        k = min(max(1, int(budget / n)), nsteps - done)
        t = time.perf_counter()
        m.cycle(k, record=record and done + k == nsteps)
        el = time.perf_counter() - t
        done += k
        if el > 1e-3:  # a measurable call: update the speed (fast to slow down)
            r = k * n / el
            _rate = r if _rate is None or r < _rate else 0.7 * _rate + 0.3 * r
