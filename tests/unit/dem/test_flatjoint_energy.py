"""Energy bookkeeping of flat joints: bonded elastic motion conserves energy, slip and
breakage dissipate, and the budget closes (the flat-joint counterpart of test_energy)."""
import numpy as np
from support.dem_util import box_pack, rng, total
from support.flatjoint_util import fj_material

from bpmcal.dem import Model


def _two_ball(vel, angvel, steps=10_000, **kw):
    mat = fj_material(fj_ten=1e9, fj_coh=1e9, **kw)
    R = 1e-3
    m = Model([[0, 0, 0], [1.9 * R, 0, 0]], [R, 0.9 * R], 2294.0, mat, damping=0.0)
    assert m.bond(gap=0.0) == 1
    m.set_timestep(None)
    m.set_velocity([0, 1], vel=vel, angvel=angvel)
    e0 = total(m.energies())
    m.cycle(steps)
    assert (m.element_states == 3).all()
    return (total(m.energies()) - e0) / e0


def test_bonded_oscillator_axial_and_twist_conserves_to_roundoff():
    """Axial vibration (through tension and compression) and twist of one bonded flat
    joint between free balls: linear in the displacements, so the step-consistent
    energies balance to round-off over 10^4 steps. (The amplitude, ~0.3 um, is large
    enough that the absolute gap |x_j - x_i| - R_i - R_j, which is what the interface
    reads, is resolved to ~1e-12 of it: at 100 x smaller amplitudes the balance is still
    closed to the position round-off, ~1e-9 of that tiny energy.)"""
    drift = _two_ball([[0, 0, 0], [1.0, 0, 0]], [[3000.0, 0, 0], [-1000.0, 0, 0]])
    assert abs(drift) < 1e-10, drift


def test_bonded_oscillator_in_bending_conserves_to_the_integrators_order():
    """Bending and shear turn the interface frame every step: the drift over a fixed
    number of steps is small and first order in that rotation."""
    drift = _two_ball([[0, 0.005, 0], [0, -0.005, 0.003]], [[0, 20.0, 0], [0, 0, -20.0]])
    assert abs(drift) < 1e-4, drift


def _fj_cluster(n_side=3, seed=0, gap=0.01, **kw):
    g = rng(seed)
    R = 1e-3
    idx = np.array([(i, j, k) for i in range(n_side) for j in range(n_side)
                    for k in range(n_side)], float)
    pos = idx * (2 + gap) * R + g.normal(0, 1e-3 * gap * R, idx.shape)
    r = R * g.uniform(0.999, 1.0, len(pos))
    m = Model(pos, r, 2294.0, fj_material(**kw), damping=0.0)
    assert m.bond(gap=3 * gap * R) >= 2 * n_side ** 3
    m.set_timestep(None)
    return m


def test_undamped_flat_jointed_cluster_conserves_energy():
    m = _fj_cluster(fj_ten=1e9, fj_coh=1e9, fj_nr=2, fj_nal=4)
    g = rng(1)
    m.set_velocity(np.arange(m.n), vel=g.normal(0, 0.05, (m.n, 3)),
                   angvel=g.normal(0, 20.0, (m.n, 3)))
    e0 = total(m.energies())
    worst = 0.0
    for _ in range(20):
        m.cycle(500)
        e = m.energies()
        assert e["damping"] == 0.0 and e["released"] == 0.0
        worst = max(worst, abs(total(e) - e0) / e0)
    assert worst < 1e-4, worst


def test_damped_compression_with_element_breakage_and_slip_balances():
    mat = fj_material(fj_emod=10e9, fj_ten=3e6, fj_coh=6e6, fj_fric=0.5)
    m, L = box_pack(250, seed=3)
    m.set_material(mat)
    assert m.bond(gap=0.0) > 300
    m.set_wall_velocity(5, velocity=(0, 0, -0.5))
    m.set_timestep(None)
    e0 = m.energies()
    checks = []
    for _ in range(12):
        m.cycle(400)
        b = Model.energy_balance(m.energies(), e0)
        checks.append(b["rel_error"])
    e = m.energies()
    nt, ns = m.crack_counts()
    assert nt + ns > 30, (nt, ns)
    assert len(m.breaks()["step"]) == nt + ns
    assert e["released"] > 0 and e["slip"] > 0 and e["damping"] > 0
    assert (e["released"] - e0["released"]) / b["input"] > 1e-4
    assert max(checks) < 1e-3, checks
