"""The engine's wall-servo loop (``dem.servo_kernel``) on four balls between two plates,
small enough to run without numba's JIT: the engine's loop and the Python loop give the
same state bit for bit, and the servoed plate settles on its target force."""
import numpy as np
from support.dem_util import RHO, material

from bpmcal.dem import Model
from bpmcal.lab.servo import Servo, ServoLoop, WallTarget

R = 1e-3


def _column(engine: bool):
    pos = np.array([[x, y, R] for x in (R, 3 * R) for y in (R, 3 * R)])
    pos[:, 2] += np.array([0.0, 1e-4, 2e-4, 3e-4]) * R  # not quite level
    m = Model(pos, np.full(4, R), RHO, material(fric=0.3), damping=0.7)
    m.add_plane_wall((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    top = m.add_plane_wall((0.0, 0.0, 2.001 * R), (0.0, 0.0, -1.0))
    m.set_timestep(None)
    F = 5.0
    target = WallTarget.force(F) if engine else (lambda: F)
    sv = Servo(m, top, target, alpha=0.8, vmax=0.5, approach=0.5)
    return m, ServoLoop(m, [sv], interval=2, gain_update=3), F


def test_engine_and_python_loops_agree_and_the_plate_reaches_its_target():
    out = []
    for engine in (True, False):
        m, loop, F = _column(engine)
        assert loop.in_engine is engine
        for n in (1, 4, 25, 600):
            loop.run(n)
        out.append((m.positions.copy(), m.velocities.copy(), m.wall_position(1),
                    loop.servos[0].force(), loop.servos[0].K))
    (pa, va, wa, fa, ka), (pb, vb, wb, fb, kb) = out
    assert np.array_equal(pa, pb) and np.array_equal(va, vb) and np.array_equal(wa, wb)
    assert fa == fb and ka == kb and ka > 0.0
    assert abs(fa - F) < 0.05 * F  # the plate settled on its target
