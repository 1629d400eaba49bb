"""The rigid-body hammer: momentum transfer against closed-form collisions."""
import math

import numpy as np
import pytest

from bpmcal.dem import Material, Model

R = 1e-3
MAT = Material(emod=10e9, kratio=2.0, fric=0.0, pb_emod=10e9, pb_kratio=2.0, pb_ten=1e12,
               pb_coh=1e12, pb_fa=30.0)


def hit(n_balls=1, bonded=False, M=0.05, v0=2.0, mat=MAT, steps=16000):
    pos = [[0.0, 0.0, R + 2 * R * k] for k in range(n_balls)]
    m = Model(pos, [R] * n_balls, 2294.0, mat, damping=0.0)
    if bonded:
        m.bond(gap=1e-9)
    top = 2 * R * n_balls
    w = m.add_plane_wall((0, 0, top + 1e-6), (0, 0, -1), velocity=(0, 0, -v0), mass=M)
    m.set_timestep(None, safety=0.05)
    e0 = m.energies()
    m.cycle(steps)
    return m, w, e0


def test_hammer_on_a_free_ball_is_an_elastic_collision():
    M, v0 = 0.05, 2.0
    m, w, e0 = hit(M=M, v0=v0)
    mb = m.B.mass[0]
    assert float(np.abs(m.W.force[w]).max()) == 0.0  # separated
    vb = m.B.vel[0, 2]
    vh = m.W.vel[w, 2]
    # momentum: exact (round-off)
    assert M * vh + mb * vb == pytest.approx(-M * v0, rel=1e-12)
    # elastic: the 1-D closed form (the contact is resolved in ~60 steps)
    assert vb == pytest.approx(-2 * M / (M + mb) * v0, rel=1e-3)
    assert vh == pytest.approx(-(M - mb) / (M + mb) * v0, rel=1e-3)


def test_hammer_on_a_bonded_pair_conserves_momentum_and_energy():
    M, v0 = 0.05, 1.0
    m, w, e0 = hit(n_balls=2, bonded=True, M=M, v0=v0, steps=24000)
    p = M * m.W.vel[w, 2] + (m.B.mass * m.B.vel[:, 2]).sum()
    assert p == pytest.approx(-M * v0, rel=1e-12)
    e = m.energies()
    b = Model.energy_balance(e, e0)
    # the hammer is part of the system: its kinetic energy is in kinetic_walls
    assert abs(b["error"]) < 1e-3 * 0.5 * M * v0 ** 2


def test_dashpot_collision_has_the_linear_restitution_coefficient():
    beta = 0.2
    mat = MAT.replace(dp_nratio=beta, dp_sratio=0.0)
    M = 1e3  # an (almost) immovable hammer: the ball bounces off it
    m, w, e0 = hit(M=M, v0=1.0, mat=mat)
    vb = m.B.vel[0, 2]
    e_expected = math.exp(-beta * math.pi / math.sqrt(1 - beta ** 2))
    # ball leaves at (1 + e) v0 relative to the ground (hammer at -v0): rebound speed
    v_rel_after = vb - m.W.vel[w, 2]
    assert -v_rel_after / 1.0 == pytest.approx(e_expected, rel=5e-3)
