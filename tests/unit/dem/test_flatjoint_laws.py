"""One flat joint between two balls, each loading mode, against the closed forms of
docs/flatjoint-spec.md §8 (T1-T8) and docs/contact_laws.md.

Common set-up (docs/flatjoint-spec.md §8): R1 = R2 = 1 mm, lambda = 1, E* = 50 GPa (k_n = 2.5e13 Pa/m),
kappa* = 2, 1 x 3 elements, sigma_b = 10 MPa, c_b = 20 MPa, phi_b = 30 deg, mu = 0.5.
Ball 0 at the origin, ball 1 on +x; n = x, the frame's s = y, t = z, so the elements'
centroids lie at 60, 180 and 300 degrees from y towards z. Motion is prescribed (both
balls fully fixed), so the stepping path is what is tested.
"""
import math

import numpy as np
import pytest
from support.dem_util import RHO, rel
from support.flatjoint_util import INERTIA, KN, KS, RHO_E, TOL, A, R, fj_material, fj_two_balls

from bpmcal.dem import InputError, Model
from bpmcal.dem import flatjoint as fj


def spin_both(m, w_i, w_j):
    m.set_velocity([0, 1], vel=np.zeros((2, 3)), angvel=np.array([w_i, w_j], float))


def test_element_table_matches_the_closed_forms():
    for nr, nal in ((1, 3), (1, 4), (2, 4), (2, 3), (3, 1), (1, 1)):
        tab = fj.element_table(nr, nal)
        assert tab.shape == (nr * nal, fj.NG)
        assert rel(tab[:, fj.G_A].sum(), math.pi) < 1e-14
        # first moments vanish and the second moments sum to pi/4 (isotropic disk)
        assert abs((tab[:, fj.G_A] * tab[:, fj.G_XS]).sum()) < 1e-14
        assert abs((tab[:, fj.G_A] * tab[:, fj.G_XT]).sum()) < 1e-14
        assert rel(tab[:, fj.G_ISS].sum(), math.pi / 4) < 1e-13
        assert rel(tab[:, fj.G_ITT].sum(), math.pi / 4) < 1e-13
        assert abs(tab[:, fj.G_IST].sum()) < 1e-14
    rho = np.hypot(*fj.element_table(1, 3)[:, [fj.G_XS, fj.G_XT]].T)
    assert np.allclose(rho, 0.55133, atol=5e-6)
    t24 = fj.element_table(2, 4)
    assert np.allclose(np.hypot(t24[:, fj.G_XS], t24[:, fj.G_XT]),
                       [0.30011] * 4 + [0.70025] * 4, atol=5e-6)
    assert np.allclose(t24[:, fj.G_A] / math.pi, [0.0625] * 4 + [0.1875] * 4)


def test_T1_pure_tension_breaks_all_elements_at_sigma_b():
    m = fj_two_balls()
    v = 1e-2
    m.set_velocity([1], vel=[v, 0, 0])
    df = v * m.dt
    nbreak = None
    for s in range(1, 400):
        m.cycle(1)
        f, _ = m.ball_forces()
        d = m.B.pos[1, 0] - m.B.pos[0, 0] - 2 * R
        if (m.element_states == fj.E_BONDED).all():
            assert rel(f[1, 0], -KN * A * d) < TOL
            assert d < 10e6 / KN
        else:
            nbreak = s
            break
    assert nbreak is not None
    assert 10e6 / KN <= d < 10e6 / KN + df * 1.0000001
    assert (m.element_states == fj.E_TENSION).all()  # all three together
    assert np.abs(f).max() == 0.0  # open, unbonded: no force
    ev = m.breaks()
    assert len(ev["step"]) == 3 and set(ev["element"]) == {0, 1, 2}
    # released: 1/2 k_n A d_old d_new (step-consistent), 6.283e-6 J at d = sigma_b/k_n
    d0 = d - df
    assert rel(ev["energy"].sum(), 0.5 * KN * A * d0 * d) < 1e-6
    assert rel(ev["energy"].sum(), 0.5 * A * 10e6 ** 2 / KN) < 2 * df / d
    assert np.allclose(ev["sigma"], KN * d, rtol=1e-9)
    assert m.crack_counts() == (3, 0)
    assert m.bond_states[0] == 1


def _shear_by_spins(m, target, w=2.0):
    """Shear the interface without moving the centres: both balls spin the same way about
    z, so the contact point of ball 1 moves by -2 R theta along y relative to ball 0."""
    spin_both(m, [0, 0, w], [0, 0, w])
    return 2 * R * w * m.dt


def test_T2_pure_shear_breaks_at_cohesion_then_carries_nothing():
    m = fj_two_balls()
    step = _shear_by_spins(m, 0)
    ds = 0.0
    for _ in range(4000):
        m.cycle(1)
        ds += step
        f, _ = m.ball_forces()
        if not (m.element_states == fj.E_BONDED).all():
            break
        assert rel(f[1, 1], KS * A * ds) < 1e-9  # restoring: ball 1 moved towards -y
        assert abs(f[1, 0]) < 1e-9 * KS * A * ds
    assert 20e6 / KS <= ds < 20e6 / KS + step * 1.0000001
    assert (m.element_states == fj.E_SHEAR).all()
    m.cycle(5)
    f, _ = m.ball_forces()
    assert np.abs(f).max() == 0.0  # no normal force, so no friction


def test_T2b_shear_under_compression_rebuilds_to_the_friction_limit():
    m = fj_two_balls()
    g = -2.0e-7  # sigma = -5 MPa
    n = 200
    m.set_velocity([1], vel=[g / (n * m.dt), 0, 0])
    m.cycle(n)
    m.set_velocity([1], vel=[0, 0, 0])
    f, _ = m.ball_forces()
    d = m.B.pos[1, 0] - 2 * R
    assert rel(-d * KN / 1e6, 5.0) < 1e-6
    sig = KN * d  # compression negative
    step = _shear_by_spins(m, 0)
    peak = 0.0
    ds = 0.0
    hist = []
    for _ in range(4000):
        m.cycle(1)
        ds += step
        f, _ = m.ball_forces()
        hist.append((ds, f[1, 1]))
        if (m.element_states == fj.E_BONDED).all():
            peak = max(peak, f[1, 1])
    tau_c = 20e6 - sig * math.tan(math.radians(30.0))
    assert rel(tau_c / 1e6, 22.887) < 1e-4
    assert 0 < tau_c * A - peak <= KS * A * step * 1.0000001
    # after the break: zero, then rebuilt over mu |sigma| / k_s and slipping at mu N
    resid = 0.5 * (-sig) * A
    ds_b = next(x for x, fy in hist if fy < 0.5 * peak)
    after = [(x - ds_b, fy) for x, fy in hist if x >= ds_b]
    assert after[0][1] < KS * A * step * 1.0000001
    for x, fy in after:
        if x < resid / (KS * A) - step:
            assert fy < resid
    assert rel(after[-1][1], resid) < 1e-9
    assert rel(resid, 7.854) < 1e-3


def _bend(m, w):
    """Bend about t = z: the balls spin in opposite directions (no shear at the contact
    point); relative rotation w dt per step."""
    spin_both(m, [0, 0, -0.5 * w], [0, 0, 0.5 * w])


def test_T3_bending_breaks_the_element_at_180_deg_first_and_T3b_after():
    m = fj_two_balls()
    w = 1.0
    _bend(m, w)
    dth = w * m.dt
    th = 0.0
    for _ in range(5000):
        m.cycle(1)
        th += dth
        f, mom = m.ball_forces()
        st = m.element_states[0]
        if (st == fj.E_BONDED).all():
            assert rel(mom[1, 2], -KN * INERTIA * th) < 1e-9
            assert np.abs(f).max() < 1e-9 * KN * INERTIA * th / R
        else:
            break
    th_f = 10e6 / (KN * RHO_E)
    assert rel(th_f, 7.2552e-4) < 1e-4
    assert th_f * (1 - 1e-4) <= th < th_f * (1 + 1e-4) + dth
    # the element at 180 deg (index 1: centroid at -rho along s) broke in tension
    assert list(st) == [fj.E_BONDED, fj.E_TENSION, fj.E_BONDED]
    ev = m.breaks()
    assert rel(ev["sigma"][0], KN * RHO_E * th) < 1e-3
    # T3b: the broken element is open; bending stiffness 0.52883 k_n I; a net compression
    # k_n A_e rho theta on ball 1 (pushing it to +x)
    th0 = th
    m0 = mom[1, 2]
    m.cycle(50)
    th += 50 * dth
    f, mom = m.ball_forces()
    ae = A / 3
    tab = fj.element_table(1, 3)
    ratio = 1 - tab[1, fj.G_ISS] / (math.pi / 4)
    assert rel(ratio, 0.52883) < 1e-4
    assert rel(mom[1, 2] - m0, -ratio * KN * INERTIA * (th - th0)) < 1e-6
    rho_exact = math.hypot(tab[0, fj.G_XS], tab[0, fj.G_XT]) * R
    assert rel(f[1, 0], KN * ae * rho_exact * th) < 1e-6


def test_T4_twist_breaks_all_elements_in_shear():
    m = fj_two_balls()
    w = 5.0
    spin_both(m, [0, 0, 0], [w, 0, 0])
    dth = w * m.dt
    th = 0.0
    tab = fj.element_table(1, 3)
    rho = math.hypot(tab[0, fj.G_XS], tab[0, fj.G_XT]) * R
    for _ in range(5000):
        m.cycle(1)
        th += dth
        f, mom = m.ball_forces()
        if not (m.element_states == fj.E_BONDED).all():
            break
        assert rel(mom[1, 0], -KS * A * rho ** 2 * th) < 1e-9
        assert rel(mom[0, 0], KS * A * rho ** 2 * th) < 1e-9
    assert rel(KS * A * rho ** 2, 11.937) < 1e-4
    th_f = 20e6 / (KS * rho)
    assert th_f <= th < th_f + dth * 1.0000001
    assert (m.element_states == fj.E_SHEAR).all()


def _interface(gs, theta, axis_angle, nr, nal, rad=R):
    """Normal force (compression positive) and moment about the axis of a fully unbonded
    interface with gap field g = gs - theta * (p . e), e the in-plane unit vector at
    ``axis_angle`` (a rotation theta about the axis perpendicular to e)."""
    tab = fj.element_table(nr, nal)
    ws = -theta * math.cos(axis_angle)
    wt = -theta * math.sin(axis_angle)
    brk = np.empty(8)
    fn = qs = qt = 0.0
    for e in range(nr * nal):
        f, a, b, _ = fj.unbonded_element(
            KN, tab[e, fj.G_A] * rad ** 2, tab[e, fj.G_XS] * rad, tab[e, fj.G_XT] * rad,
            tab[e, fj.G_ISS] * rad ** 4, tab[e, fj.G_ITT] * rad ** 4, tab[e, fj.G_IST] * rad ** 4,
            gs, ws, wt, tab[e, fj.G_RA] * rad, tab[e, fj.G_RB] * rad, tab[e, fj.G_P0],
            tab[e, fj.G_P1], tab[e, fj.G_C0], tab[e, fj.G_S0], tab[e, fj.G_C1],
            tab[e, fj.G_S1], brk)
        fn += f
        qs += a
        qt += b
    mom = qs * math.cos(axis_angle) + qt * math.sin(axis_angle)
    return -fn, -mom


@pytest.mark.parametrize("nr,nal,axis", [(1, 3, 0.0), (2, 4, 0.0), (1, 3, 0.7), (3, 5, 2.1)])
def test_T5_a_fully_broken_closed_joint_resists_rotation_up_to_N_R(nr, nal, axis):
    n_force = 31.4159265  # -10 MPa over A
    d0 = 4e-7
    # linear (fully closed) up to theta = d0 / R: kern at R/4
    n, mo = _interface(-d0, d0 / R, axis, nr, nal)
    assert rel(n, n_force) < 1e-6
    assert rel(mo / (n * R), 0.25) < 1e-6
    for k, gs, ratio in ((2, -3.5942981e-7, 0.422035), (4, -1.1562207e-7, 0.561179),
                         (10, 1.0832653e-6, 0.696150), (100, 2.8639551e-5, 0.879452)):
        n, mo = _interface(gs, k * d0 / R, axis, nr, nal)
        assert rel(n, n_force) < 1e-6, (k, n)
        assert abs(mo / (n * R) - ratio) < 2e-6, (k, mo / (n * R))


def test_T6_gapped_contact_carries_load_only_after_closing():
    m = fj_two_balls()
    m.set_flatjoint_types([fj.MT_GAPPED], gap0=1e-7)
    assert m.bond_states[0] == 3  # never bonded
    v = 1e-2
    m.set_velocity([1], vel=[-v, 0, 0])
    for _ in range(300):
        m.cycle(1)
        f, _ = m.ball_forces()
        delta = 2 * R - m.B.pos[1, 0]
        if delta <= 1e-7:
            assert f[1, 0] == 0.0
        else:
            assert rel(f[1, 0], KN * A * (delta - 1e-7)) < 1e-6
    assert delta > 2e-7
    assert m.crack_counts() == (0, 0)


def _loaded_pair():
    m = fj_two_balls()
    # load: tension, bending and twist, all below strength
    m.set_velocity([1], vel=[2e-3, 0, 0], angvel=[10.0, 3.0, 0.0])
    m.set_velocity([0], angvel=[0, -3.0, 0.0])
    m.cycle(100)
    spin_both(m, [0, 0, 0], [0, 0, 0])
    return m


def _rotate_rigidly(m, ax, th, nsteps):
    """Rotate the pair about ``ax`` through its midpoint by ``th`` per step: chord
    velocities (each step an exact rotation of the centres) and spins at the orbit rate."""
    ax = np.asarray(ax, float) / np.linalg.norm(ax)
    dt = m.dt
    c = 0.5 * (m.B.pos[0] + m.B.pos[1])
    K = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
    rot = np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K
    total = np.eye(3)
    for _ in range(nsteps):
        x = m.B.pos.copy()
        m.set_velocity([0, 1], vel=((x - c) @ rot.T + c - x) / dt,
                       angvel=[th / dt * ax, th / dt * ax])
        m.cycle(1)
        total = rot @ total
    return total


@pytest.mark.parametrize("axis", [(0, 0, 1), (0, 0.6, 0.8), (1, 0, 0)])
def test_T7_rigid_motion_of_a_loaded_pair_leaves_the_joint_unchanged(axis):
    """Orbit about axes perpendicular to the pair, and spin about its own axis: forces and
    moments co-rotate, theta_b and the element states stay. (About an axis oblique to the
    pair, the first-order increments of the scheme creep by O(rotation per step) per
    radian, as for any incremental shear law: see the next test.)"""
    m = _loaded_pair()
    f0, mom0 = m.ball_forces()
    st0 = m.flatjoint_state()
    assert (m.element_states == fj.E_BONDED).all() and np.abs(f0[1]).max() > 1.0
    total = _rotate_rigidly(m, axis, 1e-4, 4000)
    f1, mom1 = m.ball_forces()
    assert np.linalg.norm(total - np.eye(3)) > 0.3
    for a, b in ((f1[1], f0[1]), (mom1[1], mom0[1]), (f1[0], f0[0]), (mom1[0], mom0[0])):
        assert np.linalg.norm(a - total @ b) < 1e-4 * np.linalg.norm(b)
    st1 = m.flatjoint_state()
    assert np.allclose(st1["theta_b"], st0["theta_b"], rtol=1e-4, atol=0)
    assert np.allclose(st1["shear"], st0["shear"], rtol=0, atol=1e-4 * np.abs(st0["shear"]).max())
    assert (m.element_states == fj.E_BONDED).all()


def test_T7_oblique_rotation_creeps_at_first_order_in_the_step():
    """About an oblique axis the error after a fixed angle halves when the rotation per
    step halves: the scheme is consistent (first order), not biased."""
    errs = []
    for th in (2e-4, 1e-4):
        m = _loaded_pair()
        f0, _ = m.ball_forces()
        total = _rotate_rigidly(m, (0.3, 0.5, 0.8), th, int(round(0.2 / th)))
        f1, _ = m.ball_forces()
        errs.append(np.linalg.norm(f1[1] - total @ f0[1]) / np.linalg.norm(f0[1]))
    assert 0.4 < errs[1] / errs[0] < 0.6


def test_T8_timestep_uses_the_interface_stiffnesses():
    m = fj_two_balls()
    m.fix([0, 1], 0)  # free balls (fully fixed ones do not limit the timestep)
    dtc, _ = m.critical_timestep()
    mass = RHO * 4 / 3 * math.pi * R ** 3
    inertia = 0.4 * mass * R * R
    k_tran = max(KN, KS) * A
    k_twist = KS * fj.twist_factor(fj.element_table(1, 3)) * R ** 4
    k_rot = KS * A * R * R + max(KN * INERTIA, k_twist)
    assert rel(k_tran, 7.854e7) < 1e-4 and rel(KN * INERTIA, 19.635) < 1e-4
    assert rel(dtc, min(math.sqrt(mass / k_tran), math.sqrt(inertia / k_rot))) < 1e-12


def test_installation_is_force_free_at_any_gap_and_types_are_checked():
    for gap in (-3e-6, 0.0, 5e-5):
        m = fj_two_balls(gap=gap)
        f, mom = m.ball_forces()
        assert np.abs(f).max() < 1e-12 and np.abs(mom).max() < 1e-15
    with pytest.raises(InputError, match="flat-joint types"):
        m.set_flatjoint_types([5])
    with pytest.raises(InputError, match="rgap"):
        Model([[0, 0, 0], [2 * R, 0, 0]], [R, R], RHO, fj_material()).bond(0.0, rgap=[0.0])


@pytest.mark.parametrize("kw,msg", [
    (dict(fj_nr=0), "fj_nr=0"), (dict(fj_nr=1.5), "fj_nr=1.5"), (dict(fj_nal=True), "fj_nal"),
    (dict(fj_ten=-1.0), "fj_ten"), (dict(fj_fa=90.0), "fj_fa"), (dict(fj_emod=0.0), "fj_emod")])
def test_bad_flat_joint_properties_name_the_value(kw, msg):
    with pytest.raises(InputError, match=msg):
        fj_material(**kw)


def test_slit_joint_resists_moment_under_compression_where_a_broken_bond_cannot():
    """A slit (unbonded, closed) flat joint under compression returns a moment when
    bent; it is frictional in shear and carries no tension."""
    m = fj_two_balls()
    m.set_flatjoint_types([fj.MT_SLIT])
    m.set_velocity([1], vel=[-1e-4, 0, 0])
    m.cycle(40)
    spin_both(m, [0, 0, 0], [0, 0, 0])
    f, _ = m.ball_forces()
    assert f[1, 0] > 0
    _bend(m, 1.0)
    m.cycle(5)
    _, mom = m.ball_forces()
    assert mom[1, 2] < 0
    m.set_velocity([0, 1], vel=[[0, 0, 0], [1e-3, 0, 0]], angvel=np.zeros((2, 3)))
    m.cycle(200)
    f, mom = m.ball_forces()
    assert np.abs(f).max() == 0.0 and np.abs(mom).max() == 0.0


@pytest.mark.parametrize("nr,nal", [(1, 1), (1, 2), (2, 3), (3, 5), (1, 8)])
def test_gap_range_matches_dense_sampling_of_every_element(nr, nal):
    """The smallest and largest gap over each element (corners and the outer arc's
    extremes, found by cross products) against a dense sampling of the sector."""
    tab = fj.element_table(nr, nal)
    g = np.random.default_rng(7)
    for _ in range(40):
        gs, ws, wt = g.normal(0, 1e-7), g.normal(0, 1e-4), g.normal(0, 1e-4)
        for e in range(nr * nal):
            a, b = tab[e, fj.G_RA] * R, tab[e, fj.G_RB] * R
            p0, p1 = tab[e, fj.G_P0], tab[e, fj.G_P1]
            lo, hi = fj.gap_range(gs, ws, wt, a, b, p0, p1, tab[e, fj.G_C0], tab[e, fj.G_S0],
                                  tab[e, fj.G_C1], tab[e, fj.G_S1])
            r, phi = np.meshgrid(np.linspace(a, b, 5), np.linspace(p0, p1, 4001))
            gg = gs + r * (ws * np.cos(phi) + wt * np.sin(phi))
            tol = 1e-6 * b * math.hypot(ws, wt)
            assert lo <= gg.min() + 1e-15 and hi >= gg.max() - 1e-15
            assert lo >= gg.min() - tol and hi <= gg.max() + tol
