"""Model.scale_density: PFC's per-ball density scaling for quasi-static runs. The scaled
masses give every ball a critical timestep of at least the chosen quantile of the balls'
own, never lower a mass, restore exactly, and leave a quasi-static answer (an elastic
bond's force at a displacement, a packing's static stiffness) unchanged while the run
needs fewer steps."""
import numpy as np
import pytest
from support.dem_util import RHO, box_pack, material

from bpmcal.dem import InputError, Model
from bpmcal.dem import diagnostics as D
from bpmcal.dem import flatjoint as FJ
from bpmcal.dem.model import I_NB, I_NPAIRS, I_NSLOTS


@pytest.fixture(scope="module")
def pack():
    m, L = box_pack(120, seed=3, mat=material())
    m.bond(gap=1e-5)
    m.set_timestep(None)
    return m


def _per_ball_dt(m, mass, inertia):
    F = m.Fj
    kt, kr = D.ball_stiffness(m.B.radius, m.P.pi, m.P.pj, int(m.iprm[I_NPAIRS]),
                              int(m.iprm[I_NB]), m.Bd.state, m.S.b, int(m.iprm[I_NSLOTS]),
                              m.prm, F.prm, F.flag[:, FJ.K_LIVE], FJ.twist_factor(F.geo))
    with np.errstate(divide="ignore"):
        return np.minimum(np.sqrt(mass / kt), np.sqrt(inertia / kr)), kt, kr


def test_the_critical_timestep_becomes_the_quantile_of_the_balls_own(pack):
    m = pack
    m0, i0 = m.masses.copy(), m.B.inertia.copy()
    t0, kt, kr = _per_ball_dt(m, m0, i0)
    dtc0, _ = m.critical_timestep()
    assert dtc0 == pytest.approx(np.nanmin(t0[np.isfinite(t0)]), rel=1e-12)
    for q in (0.1, 0.5, 0.9):
        out = m.scale_density(q)
        target = float(np.quantile(t0[np.isfinite(t0)], q))
        dtc, _ = m.critical_timestep()
        assert dtc == pytest.approx(target, rel=1e-9)
        assert out["dt_gain"] == pytest.approx(target / dtc0, rel=1e-9)
        assert (m.masses >= m0).all() and (m.B.inertia >= i0).all()
        slow = t0 >= target  # balls whose own timestep already reaches the target
        assert np.array_equal(m.masses[slow], m0[slow])
        assert out["mass_added"] == pytest.approx(m.masses.sum() / m0.sum() - 1, rel=1e-12)
        assert (m.masses > m0).any() or (m.B.inertia > i0).any()
    m.scale_density(None)  # the true masses back, bit for bit
    assert np.array_equal(m.masses, m0) and np.array_equal(m.B.inertia, i0)
    assert m.critical_timestep()[0] == dtc0


def test_a_second_call_replaces_the_first(pack):
    m = pack
    m.scale_density(0.5)
    once = m.masses.copy()
    m.scale_density(0.9)
    m.scale_density(0.5)
    assert np.array_equal(m.masses, once)  # from the true masses, not compounded
    assert m.scale_density(0) == {"dt_gain": 1.0, "mass_added": 0.0}
    m.scale_density(None)


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan"), True, "0.5"])
def test_a_quantile_outside_0_1_is_refused(pack, bad):
    with pytest.raises(InputError, match=r"quantile=.*expected a fraction in \[0, 1\]"):
        pack.scale_density(bad)


def test_gravity_is_refused():
    m = Model([[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0]], [1e-3, 1e-3], RHO, material(),
              gravity=(0.0, 0.0, -9.81))
    with pytest.raises(InputError, match="gravity"):
        m.scale_density(0.5)


def _compress(q):
    """A bonded box pack (the same for every call) squeezed along x by its wall at x = L
    moving in at a slow constant speed: the wall's force gained when it has moved 1e-6 m
    (a strain of about 1e-4), the steps it took, the timestep's gain and the box size."""
    m, L = box_pack(120, seed=3, mat=material())
    m.bond(gap=1e-5)
    gain = m.scale_density(q)["dt_gain"]
    m.set_timestep(None)
    m.cycle(1)
    f0 = float(m.wall_force(1)[0])  # the packing's own stress on the wall
    d, v = 1e-6, 2e-3
    steps = int(round(d / (v * m.dt)))
    m.set_wall_velocity(1, (-v, 0.0, 0.0))
    m.cycle(steps)
    return float(m.wall_force(1)[0]) - f0, steps, gain, L


def test_the_quasi_static_answer_is_unchanged_in_fewer_steps():
    """A slow squeeze of a bonded pack is quasi-static: the wall's force at a prescribed
    displacement is the pack's stiffness times it, whatever the inertial masses. With the
    masses scaled to the median ball's timestep it is the same to 0.2 % in fewer steps (by
    the timestep's gain)."""
    f0, n0, g0, L = _compress(None)
    f1, n1, g1, _ = _compress(0.5)
    assert g0 == 1.0 and g1 > 1.1
    assert n1 == pytest.approx(n0 / g1, rel=0.01)
    assert f0 > 0 and f1 == pytest.approx(f0, rel=0.002)
