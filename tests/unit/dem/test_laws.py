"""Two bonded balls, each loading mode, against the closed-form values of docs/contact_laws.md.

Displacements are imposed by prescribing velocities (both balls fully fixed), so the
stiffnesses and failure thresholds are checked through the real stepping path.
"""
import math

import numpy as np
import pytest
from support.dem_util import R, approach, bond_constants, material, rel, two_balls

from bpmcal.dem import BOND_INTACT, BOND_SHEAR, BOND_TENSION, InputError, Model

TOL = 1e-9


def run(m, n):
    m.cycle(n)
    return m.ball_forces()


def test_axial_compression_stiffness_is_kn_plus_knbarA(mat):
    m = two_balls(mat)
    c = bond_constants(mat)
    v = 1e-3
    m.set_velocity([1], vel=[-v, 0, 0])
    f, _ = run(m, 200)
    overlap = 2 * R - (m.B.pos[1, 0] - m.B.pos[0, 0])
    assert overlap > 0
    assert rel(f[1, 0], (c["kn"] + c["knA"]) * overlap) < TOL
    assert rel(f[0, 0], -(c["kn"] + c["knA"]) * overlap) < TOL
    bs = m.bond_state()
    assert rel(-bs["fn"][0], c["knA"] * overlap) < TOL  # tension-positive bond force


def test_axial_tension_stiffness_is_knbarA_only(mat):
    m = two_balls(mat)
    c = bond_constants(mat)
    v = 1e-3
    m.set_velocity([1], vel=[v, 0, 0])
    f, _ = run(m, 200)
    opening = (m.B.pos[1, 0] - m.B.pos[0, 0]) - 2 * R
    assert opening > 0
    assert rel(f[1, 0], -c["knA"] * opening) < TOL  # linear part carries no tension
    e = m.energies()
    assert e["strain_linear"] == 0.0
    assert rel(e["strain_bond"], 0.5 * (c["knA"] * opening) ** 2 / c["knA"]) < 1e-8


def test_shear_stiffness_is_ks_plus_ksbarA(mat):
    overlap = 1e-5 * 2 * R
    m = two_balls(mat, overlap=overlap)
    c = bond_constants(mat)
    v = 1e-4
    m.set_velocity([1], vel=[0, v, 0])
    f, _ = run(m, 100)
    d = m.B.pos[1] - m.B.pos[0]
    n = d / np.linalg.norm(d)
    t = np.array([-n[1], n[0], 0.0])  # current tangent along the motion
    ds = m.B.pos[1, 1] - m.B.pos[0, 1]
    assert 0 < ds < 1e-4 * R
    # linear shear force below the Coulomb limit (no slip)
    assert c["ks"] * ds < mat.fric * c["kn"] * overlap
    assert rel(f[1] @ t, -(c["ks"] + c["ksA"]) * ds) < TOL
    assert rel(np.linalg.norm(m.linear_shear_forces()[0]), c["ks"] * ds) < TOL
    assert rel(np.linalg.norm(m.bond_state()["fs"][0]), c["ksA"] * ds) < TOL


def test_twisting_stiffness_is_ksbarJ(mat):
    m = two_balls(mat)
    c = bond_constants(mat)
    w = 2.0
    m.set_velocity([1], angvel=[w, 0, 0])
    f, mom = run(m, 150)
    theta = 150 * w * m.dt
    assert rel(mom[1, 0], -c["ksJ"] * theta) < TOL
    assert rel(mom[0, 0], c["ksJ"] * theta) < TOL
    assert np.abs(f).max() < 1e-12 * c["ksJ"] * theta / R  # no force from a pure twist


def test_bending_stiffness_is_knbarI(mat):
    m = two_balls(mat)
    c = bond_constants(mat)
    w = 2.0
    # equal and opposite rotations about z: relative rotation w*dt per step, no slip at
    # the contact point for equal radii
    m.set_velocity([0], angvel=[0, 0, -w / 2])
    m.set_velocity([1], angvel=[0, 0, w / 2])
    f, mom = run(m, 150)
    theta = 150 * w * m.dt
    assert rel(mom[1, 2], -c["knI"] * theta) < TOL
    assert rel(mom[0, 2], c["knI"] * theta) < TOL
    assert np.abs(m.bond_state()["fs"]).max() < 1e-12 * c["knI"] * theta / R


def test_tensile_failure_exactly_at_strength(mat):
    m = two_balls(mat)
    c = bond_constants(mat)
    approach(m, lambda v: m.set_velocity([1], vel=[v, 0, 0]),
              lambda m: mat.pb_ten * c["area"] - m.bond_state()["fn"][0], c["knA"])
    ev = m.breaks()
    assert ev["mode"].tolist() == [BOND_TENSION]
    sigma = ev["sigma"][0]
    assert sigma >= mat.pb_ten
    assert rel(sigma, mat.pb_ten) < TOL
    # released energy is the bond strain energy at failure
    assert rel(ev["energy"][0], 0.5 * (mat.pb_ten * c["area"]) ** 2 / c["knA"]) < 1e-6


def test_tensile_failure_with_bending_adds_moment_stress(mat):
    m = two_balls(mat)
    c = bond_constants(mat)
    # bend to 40 % of the tensile strength, hold, then pull
    w = 2.0
    sig_b = 0.4 * mat.pb_ten
    theta = sig_b * c["I"] / (c["rb"] * c["knI"])
    nb = int(theta / (w * m.dt))
    m.set_velocity([0], angvel=[0, 0, -w / 2])
    m.set_velocity([1], angvel=[0, 0, w / 2])
    m.cycle(nb)
    m.set_velocity([0, 1], angvel=[0, 0, 0])
    mb = np.linalg.norm(m.bond_state()["mb"][0])
    sig_m = mb * c["rb"] / c["I"]
    assert 0.35 * mat.pb_ten < sig_m < 0.45 * mat.pb_ten
    approach(m, lambda v: m.set_velocity([1], vel=[v, 0, 0]),
              lambda m: (mat.pb_ten - sig_m) * c["area"] - m.bond_state()["fn"][0], c["knA"])
    ev = m.breaks()
    assert ev["mode"].tolist() == [BOND_TENSION]
    # failure at sigma_n + M R / I = sigma_c: the axial part alone is sigma_c - sig_m
    assert rel(ev["sigma"][0], mat.pb_ten) < TOL
    assert rel(ev["sigma_n"][0], mat.pb_ten - sig_m) < 1e-8


@pytest.mark.parametrize("factor", [0.5, 3.0])
def test_strength_factor_scales_the_tensile_strength(mat, factor):
    """A bond with strength factor f fails in tension at f x pb_ten (the per-bond
    pb_ten of PFC), not at pb_ten."""
    m = two_balls(mat)
    assert m.bond_strength_factors.tolist() == [1.0]  # the default
    m.set_bond_strength_factors([factor])
    assert m.bond_strength_factors.tolist() == [factor]
    c = bond_constants(mat)
    approach(m, lambda v: m.set_velocity([1], vel=[v, 0, 0]),
              lambda m: factor * mat.pb_ten * c["area"] - m.bond_state()["fn"][0], c["knA"])
    ev = m.breaks()
    assert ev["mode"].tolist() == [BOND_TENSION]
    assert rel(ev["sigma"][0], factor * mat.pb_ten) < TOL


def test_strength_factors_are_checked_and_scalars_broadcast(mat):
    m = two_balls(mat)
    m.set_bond_strength_factors(2.5)
    assert m.bond_strength_factors.tolist() == [2.5]
    for bad in ([1.0, 1.0], [-1.0], [math.nan]):
        with pytest.raises(InputError):
            m.set_bond_strength_factors(bad)
    assert m.bond_strength_factors.tolist() == [2.5]


@pytest.mark.parametrize("sigma_n_frac, factor", [(-0.5, 1.0), (0.3, 1.0), (-0.5, 2.0)])
def test_shear_failure_at_mohr_coulomb_strength(sigma_n_frac, factor):
    """tau = f c - sigma tan(phi): the strength factor f scales the cohesion only."""
    mat = material(pb_ten=20e6, pb_coh=15e6, pb_fa=30.0, fric=10.0)
    m = two_balls(mat)
    m.set_bond_strength_factors([factor])
    c = bond_constants(mat)
    # normal load first
    sig_n = sigma_n_frac * mat.pb_ten  # tension positive
    vn = 1e-3 if sig_n > 0 else -1e-3
    steps_n = int(abs(sig_n) * c["area"] / (c["knA"] * abs(vn) * m.dt))
    m.set_velocity([1], vel=[vn, 0, 0])
    m.cycle(steps_n)
    m.set_velocity([1], vel=[0, 0, 0])
    fn = m.bond_state()["fn"][0]
    sigma = fn / c["area"]
    assert sigma == pytest.approx(sig_n, rel=1e-3)
    tan = math.tan(math.radians(mat.pb_fa))

    def remaining(m):  # (f c - sigma tan phi) A - |Fs|, sigma from the current normal force
        bs = m.bond_state()
        return (factor * mat.pb_coh * c["area"] - bs["fn"][0] * tan) \
            - np.linalg.norm(bs["fs"][0])

    approach(m, lambda v: m.set_velocity([1], vel=[0, v, 0]), remaining, c["ksA"])
    ev = m.breaks()
    assert ev["mode"].tolist() == [BOND_SHEAR]
    # shearing opens the pair a little (second order in the shear displacement)
    assert rel(ev["sigma_n"][0], sigma) < 0.05
    expected = factor * mat.pb_coh - ev["sigma_n"][0] * math.tan(math.radians(mat.pb_fa))
    assert ev["tau"][0] >= expected
    assert rel(ev["tau"][0], expected) < TOL


def test_after_failure_no_tension_and_coulomb_sliding():
    mat = material(pb_ten=5e6, pb_coh=50e6, fric=0.3)
    m = two_balls(mat)
    c = bond_constants(mat)
    m.set_velocity([1], vel=[1e-2, 0, 0])
    while m.n_broken == 0:
        m.cycle(20)
    m.cycle(20)  # separated: no force at all
    f, _ = m.ball_forces()
    assert np.all(f == 0.0)
    # push back into contact and slide: |Fs| = mu Fn exactly once slipping
    m.set_velocity([1], vel=[-1e-2, 0, 0])
    while m.B.pos[1, 0] - m.B.pos[0, 0] > 2 * R - 2e-7:
        m.cycle(5)
    m.set_velocity([1], vel=[0, 1e-2, 0])
    m.cycle(400)
    f, _ = m.ball_forces()
    d = m.B.pos[1] - m.B.pos[0]
    n = d / np.linalg.norm(d)
    fn = f[1] @ n
    fs = f[1] - fn * n
    assert fn > 0
    assert rel(np.linalg.norm(fs), mat.fric * fn) < TOL
    overlap = 2 * R - np.linalg.norm(d)
    assert rel(fn, c["kn"] * overlap) < 1e-8
    assert m.energies()["slip"] > 0
    assert m.bond_state()["state"][0] == BOND_TENSION


def test_broken_pair_recontacts_at_first_touch():
    """A bond installed with a reference gap (locked-in stress relief) breaks, the balls
    separate and are pushed back: the linear part repels from the first touch (PFC), not
    only once the overlap exceeds the old reference gap."""
    mat = material(pb_ten=5e6, pb_coh=50e6, fric=0.3)
    rg0 = -1.5e-6
    m = two_balls(mat, overlap=2e-6)
    m.set_bond_rgap([rg0])
    c = bond_constants(mat)

    def gap():
        return (m.B.pos[1, 0] - m.B.pos[0, 0]) - 2 * R

    m.set_velocity([1], vel=[1e-2, 0, 0])
    while m.n_broken == 0:
        m.cycle(1)
    m.cycle(1)
    # broken, still overlapping by less than the reference gap: no force, rgap kept (the
    # reference gap is dropped only where the linear force is zero under both)
    assert rg0 < gap() < 0.0
    f, _ = m.ball_forces()
    assert np.all(f == 0.0)
    assert m.bond_state()["rgap"][0] == rg0
    while gap() < 0.0:
        m.cycle(1)
    m.cycle(5)
    assert gap() > 0.0
    assert m.bond_state()["rgap"][0] == 0.0
    # push back along the axis: force from the first step with an overlap
    m.set_velocity([1], vel=[-1e-2, 0, 0])
    while gap() >= 0.0:
        f, _ = m.ball_forces()
        assert np.all(f == 0.0)
        m.cycle(1)
    first = True
    while gap() > 0.5 * rg0:  # overlaps below |rg0|: no force before this change
        f, _ = m.ball_forces()
        overlap = -gap()
        assert overlap > 0.0
        assert rel(f[1, 0], c["kn"] * overlap) < TOL
        assert rel(f[0, 0], -c["kn"] * overlap) < TOL
        if first:
            assert overlap < 1e-7  # really the first touch
            first = False
        m.cycle(1)
    overlap = -gap()
    assert rel(m.energies()["strain_linear"], 0.5 * c["kn"] * overlap ** 2) < 1e-8
    assert m.bond_state()["state"][0] == BOND_TENSION


def test_bond_created_with_zero_force_when_overlapped(mat):
    m = two_balls(mat, overlap=1e-6)
    c = bond_constants(mat)
    f, _ = m.ball_forces()
    # only the linear part carries the pre-existing overlap
    assert rel(f[1, 0], c["kn"] * 1e-6) < 1e-6
    bs = m.bond_state()
    assert bs["fn"][0] == 0.0 and bs["state"][0] == BOND_INTACT


def test_reference_gap_shifts_linear_force(mat):
    m = two_balls(mat, overlap=2e-6)
    c = bond_constants(mat)
    m.set_bond_rgap([-1.5e-6])  # overlap beyond 1.5 um loads the linear spring
    f, _ = m.ball_forces()
    assert rel(f[1, 0], c["kn"] * 0.5e-6) < 1e-6


def test_unequal_radii_use_min_radius_and_sum_length():
    mat = material()
    r1, r2 = 0.8e-3, 1.3e-3
    m = Model([[0, 0, 0], [r1 + r2, 0, 0]], [r1, r2], 2294.0, mat, damping=0.0)
    m.fix([0, 1])
    m.bond(gap=1e-12)
    m.set_timestep(None)
    m.set_velocity([1], vel=[1e-3, 0, 0])
    m.cycle(100)
    f, _ = m.ball_forces()
    c = bond_constants(mat, r1, r2)
    opening = m.B.pos[1, 0] - (r1 + r2)
    assert rel(-f[1, 0], mat.pb_emod / (r1 + r2) * math.pi * r1 ** 2 * opening) < 1e-8
    assert rel(c["knA"], mat.pb_emod / (r1 + r2) * math.pi * r1 ** 2) < 1e-14
