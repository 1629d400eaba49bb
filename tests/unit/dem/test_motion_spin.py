"""Translation only (``Model.set_spin(False)``): for frictionless balls and walls without
bonds or dashpots every force is central, so the spins never act back on the positions;
the genesis relaxation runs this way. Same positions bit for bit; refused otherwise."""
import numpy as np
import pytest
from support.dem_util import RHO, material, rng

from bpmcal.dem import InputError, Model


def overlapped_vessel(spin: bool, mat=None):
    """An overlapped random cloud in a frictionless cylinder with two end planes (the
    genesis's vessel), speeds capped while the overlaps clear, as in the relaxation."""
    g = rng(31)
    n = 300
    R, H = 6e-3, 12e-3
    r = g.uniform(0.8e-3, 1.3e-3, n)
    rho = np.sqrt(g.uniform(0, 1, n)) * (R - r)
    phi = g.uniform(0, 2 * np.pi, n)
    z = r + g.uniform(0, 1, n) * (H - 2 * r)
    pos = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])
    m = Model(pos, r, RHO, mat or material(fric=0.0), damping=0.5, skin=2e-4)
    m.add_cylinder_wall((0, 0, 0), (0, 0, 1), R)
    m.add_plane_wall((0, 0, 0), (0, 0, 1))
    m.add_plane_wall((0, 0, H), (0, 0, -1))
    m.set_spin(spin)
    m.set_timestep(None)
    m.set_speed_cap(0.02 * 0.8e-3 / m.dt)
    return m


def test_translation_only_moves_the_balls_bit_for_bit_as_with_rotation():
    a = overlapped_vessel(True)
    b = overlapped_vessel(False)
    for steps in (300, 300, 700):
        a.cycle(steps)
        b.cycle(steps)
        a.set_timestep(None)
        b.set_timestep(None)
    a.set_speed_cap(0.0)
    b.set_speed_cap(0.0)
    a.cycle(1500)
    b.cycle(1500)
    assert a.n_rebuilds > 10 and a.n_rebuilds == b.n_rebuilds
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(np.abs(a.velocities), np.abs(b.velocities))  # up to signed zeros
    assert a.unbalanced_ratio() == b.unbalanced_ratio()
    # with rotation the central forces leave round-off moments and spins behind; without
    # it the spins stay exactly zero
    assert np.abs(a.angular_velocities).max() > 0.0
    assert not np.any(b.angular_velocities)


def test_translation_only_is_refused_when_a_force_is_not_central():
    with pytest.raises(InputError, match="friction"):
        overlapped_vessel(False, mat=material(fric=0.3))
    with pytest.raises(InputError, match="dashpots"):
        overlapped_vessel(False, mat=material(fric=0.0, dp_nratio=0.5))
    m = overlapped_vessel(True)
    m.set_wall_friction(0, 0.2)
    with pytest.raises(InputError, match="wall friction"):
        m.set_spin(False)
    m = overlapped_vessel(True)
    m.bond(gap=0.0)
    with pytest.raises(InputError, match="bonds"):
        m.set_spin(False)
    # a change after switching rotation off: the next cycle refuses to run
    m = overlapped_vessel(False)
    m.cycle(10)
    m.set_material(material(fric=0.4))
    with pytest.raises(InputError, match="set_spin"):
        m.cycle(1)
    m.set_spin(True)
    m.cycle(1)
