"""The wall servo in the engine (``dem.servo_kernel``) against the same law run from Python:
the same state bit for bit, with the velocity held over several steps, gains updated
between chunks, the pieces of a long run and the pair list growing in the middle of a
chunk; and the law itself against its closed form on a wall with balls held still."""
import math

import numpy as np
import pytest
from support.lab_util import A1, SMALL

from bpmcal.dem.errors import InputError
from bpmcal.dem.slots import I_NPAIRS, I_REBUILD, P_SKIN
from bpmcal.lab import stepping
from bpmcal.lab.runner import make_specimen
from bpmcal.lab.servo import Servo, ServoLoop, WallTarget

SEED = 3


def _state(m) -> dict:
    out = {"prm": m.prm.copy(), "iprm": m.iprm.copy(), "eacc": m.eacc.copy()}
    for rec in ("B", "W"):
        for k, v in getattr(m, rec)._asdict().items():
            out[f"{rec}.{k}"] = np.array(v, copy=True)
    return out


def _cell(cache, callable_targets: bool, interval: int, gain_update: int):
    """A small bonded cylinder in its vessel, servoed toward 5 MPa all round (targets as
    :class:`WallTarget` for the engine's loop, or as Python functions of the same walls
    for the Python loop)."""
    sp = make_specimen(A1, SEED, SMALL, cache=cache, boundary="vessel")
    m = sp.model
    wl, (wb, wt) = sp.lateral_wall, sp.platens
    s = 5e6
    if callable_targets:
        def lat():
            r = m.wall_radius(wl)
            h = float(m.wall_position(wt)[2] - m.wall_position(wb)[2])
            return s * (2.0 * math.pi * r * h)

        def sec():
            r = m.wall_radius(wl)
            return s * (math.pi * r * r)
        targets = (lat, sec, sec)
    else:
        targets = (WallTarget.lateral(s, wl, wb, wt), WallTarget.section(s, wl),
                   WallTarget.section(s, wl))
    kw = dict(alpha=0.8, vmax=0.5, approach=0.05, feedforward=True)
    servos = [Servo(m, w, t, **kw) for w, t in zip((wl, wb, wt), targets)]
    return m, ServoLoop(m, servos, interval=interval, gain_update=gain_update)


@pytest.mark.parametrize("interval, gain_update", [(1, 10), (3, 7)])
def test_the_engines_servo_loop_gives_the_python_loops_state_bit_for_bit(
        cache, monkeypatch, interval, gain_update):
    monkeypatch.setattr(stepping, "FIRST_BALL_STEPS", 40 * 700)  # many pieces per run
    out = []
    for py in (True, False):
        stepping._rate = None
        m, loop = _cell(cache, py, interval, gain_update)
        assert loop.in_engine is (not py)
        for n in (1, 5, 200, 37, 400):
            loop.run(n, record=n > 100)
        out.append((_state(m), [s.K for s in loop.servos], [s.v for s in loop.servos],
                    loop._since_gain))
    (a, ka, va, ga), (b, kb, vb, gb) = out
    differ = [k for k in a if not np.array_equal(a[k], b[k], equal_nan=True)]
    assert differ == []
    assert ka == kb and va == vb and ga == gb
    assert all(k > 0 for k in ka)  # the walls touch the specimen: the law acted


def test_a_pair_list_that_grows_inside_a_chunk_gives_the_same_state(cache):
    """The engine breaks a chunk off when the pair list overflows; the rest of the chunk
    runs after the growth without a velocity update, as the Python loop runs it (a
    wider skin and a rebuild due make the list overflow after the chunk's first step)."""
    out = []
    for py in (True, False):
        m, loop = _cell(cache, py, 4, 10)
        loop.run(41)
        cap = int(m.iprm[I_NPAIRS])
        m._alloc_pairs(cap, old=m.P)  # no room left
        m.prm[P_SKIN] *= 2.0
        m.iprm[I_REBUILD] = 1
        loop.run(300)
        assert m.P.pi.shape[0] > cap  # it grew
        out.append(_state(m))
    a, b = out
    assert [k for k in a if not np.array_equal(a[k], b[k], equal_nan=True)] == []


def test_the_law_on_a_wall_against_balls_held_still(cache):
    """With the balls fixed, the update sets v = alpha (F - F*) / (K dt), K = pi E* sum(R)
    over the wall's contacts, the wall retreating along its normal; ``stop`` halts it."""
    m, cell = _cell(cache, False, 1, 10)
    cell.run(300)  # the platens on the specimen
    for s in cell.servos:
        s.stop()
    wb = cell.servos[1].w
    m.fix(np.arange(m.n))
    m.cycle(1)
    F = 0.999 * wall_force(m, wb)
    sv = Servo(m, wb, WallTarget.force(F), alpha=0.8, vmax=1e3)
    sv.update_gain()
    balls = m.wall_contact_balls(wb)
    K = math.pi * m.material.emod * m.radii[balls].sum()
    assert balls.size > 10 and sv.K == pytest.approx(K, rel=1e-12)
    err0 = wall_force(m, wb) - F
    sv.apply()
    assert sv.v == pytest.approx(0.8 * err0 / (K * m.dt), rel=1e-12) and sv.v > 0
    assert m.wall_velocity(wb) == pytest.approx(-sv.v * m.wall_normal(wb), rel=1e-12)
    sv.stop()
    assert m.wall_velocity(wb) == pytest.approx(np.zeros(3), abs=0.0)


def wall_force(m, w) -> float:
    f, n = m.wall_force(w), m.wall_normal(w)
    return -float(f @ n)


def test_targets_refuse_bad_values():
    with pytest.raises(InputError, match="kind 'torque'"):
        WallTarget("torque", 1.0)
    with pytest.raises(InputError, match="nan"):
        WallTarget.force(float("nan"))
