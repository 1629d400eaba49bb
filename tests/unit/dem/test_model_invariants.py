"""Momentum conservation, determinism, bad input, blow-up detection, NUMBA_DISABLE_JIT."""
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from support.dem_util import box_pack, material, rng

from bpmcal.dem import InputError, InstabilityError, Material, Model
from bpmcal.dem._jit import set_threads


def free_cluster(seed=0, **mkw):
    g = rng(seed)
    R = 1e-3
    idx = np.array([(i, j, k) for i in range(4) for j in range(3) for k in range(3)], float)
    pos = idx * 2 * R + g.normal(0, 0.02 * R, idx.shape)
    r = R * g.uniform(0.97, 1.03, len(pos))
    m = Model(pos, r, 2294.0, material(**mkw), damping=0.0)
    m.bond(gap=0.05 * R)
    m.set_timestep(None)
    m.set_velocity(np.arange(m.n), vel=g.normal(0, 1.0, (m.n, 3)),
                   angvel=g.normal(0, 300.0, (m.n, 3)))
    return m


def test_free_bonded_cluster_conserves_linear_and_angular_momentum():
    # weak bonds (they break), friction and dashpots: still no external force
    m = free_cluster(pb_ten=3e6, pb_coh=3e6, fric=0.4, dp_nratio=0.2, dp_sratio=0.2)
    m.cycle(1)
    p0, L0 = m.momentum()
    pscale = (m.B.mass[:, None] * np.abs(m.B.vel)).sum()
    lscale = np.abs(L0).sum() + (m.B.inertia[:, None] * np.abs(m.B.angvel)).sum()
    m.cycle(3000)
    p, L = m.momentum()
    assert m.n_broken > 0
    assert np.abs(p - p0).max() < 1e-12 * pscale
    assert np.abs(L - L0).max() < 1e-11 * lscale


def _compression_state(threads, partitions=2):
    set_threads(threads)
    mat = material(fric=0.5, pb_ten=4e6, pb_coh=6e6)
    m, L = box_pack(200, seed=9, partitions=partitions)
    m.set_material(mat)
    m.bond(gap=0.0)
    m.set_wall_velocity(5, velocity=(0, 0, -0.5))
    m.set_timestep(None)
    m.cycle(2500)
    e = m.energies()
    bs = m.bond_state()
    return m.B.pos.copy(), m.B.vel.copy(), m.B.angvel.copy(), bs, e, m.n_broken


def test_two_runs_are_bitwise_identical():
    a = _compression_state(1)
    b = _compression_state(1)
    assert a[5] > 0
    for x, y in zip(a[:3], b[:3]):
        assert np.array_equal(x, y)
    for k in a[3]:
        assert np.array_equal(a[3][k], b[3][k])
    assert a[4] == b[4]


@pytest.mark.slow
@pytest.mark.skipif(os.cpu_count() < 2, reason="needs 2 cores")
def test_result_does_not_depend_on_thread_count():
    a = _compression_state(1)
    b = _compression_state(2)
    set_threads(1)
    for x, y in zip(a[:3], b[:3]):
        assert np.array_equal(x, y)
    assert a[5] == b[5]


def _lattice_after_one_step(partitions):
    """A bonded lattice (no overlaps, so no force before the first step) with random
    velocities and spins, weak bonds; the bond state after one step."""
    g = rng(5)
    R = 1e-3
    idx = np.array([(i, j, k) for i in range(10) for j in range(8) for k in range(8)], float)
    pos = idx * 2.02 * R
    m = Model(pos, np.full(len(pos), R), 2294.0, material(pb_ten=3e5, pb_coh=3e5),
              damping=0.0, partitions=partitions)
    nb = m.bond(gap=0.05 * R)
    m.set_timestep(None)
    m.set_velocity(np.arange(m.n), vel=g.normal(0, 1.0, (m.n, 3)),
                   angvel=g.normal(0, 300.0, (m.n, 3)))
    m.cycle(1)
    return m, nb


def test_bond_state_does_not_depend_on_where_partitions_cut_the_bond_blocks():
    # one step from a force-free start: each bond's new state depends only on its own
    # balls, so it must be bitwise the same whether the bond pairs are run as one range
    # or as partitions that begin inside a block of the bond state (a wrong lane offset
    # would put states into other bonds' slots)
    from bpmcal.dem.bondblock import BLK
    a, nb = _lattice_after_one_step(1)
    b, _ = _lattice_after_one_step(7)
    cuts = [int(c) for c in b.P.part[1:-1] if 0 < c < nb]
    assert nb > 3 * BLK and any(c % BLK for c in cuts), (nb, cuts)
    assert 0 < a.n_broken < nb
    sa, sb = a.bond_state(), b.bond_state()
    for k in sa:
        assert np.array_equal(sa[k], sb[k]), k
    assert np.array_equal(a.linear_shear_forces(), b.linear_shear_forces())
    ea, eb = a.breaks(), b.breaks()
    for k in ea:  # the break events: bond, step, position, normal, energy, stresses
        assert np.array_equal(ea[k], eb[k]), k


@pytest.mark.parametrize("kw, needle", [
    (dict(emod=-1.0), "emod=-1"),
    (dict(pb_emod=0.0), "pb_emod=0"),
    (dict(kratio=0.0), "kratio=0"),
    (dict(pb_fa=95.0), "pb_fa=95"),
    (dict(fric=float("nan")), "fric=nan"),
    (dict(pb_ten=-5.0), "pb_ten=-5"),
])
def test_bad_material_is_rejected_naming_the_value(kw, needle):
    base = dict(emod=10e9, kratio=2.0, fric=0.5, pb_emod=10e9, pb_kratio=2.0, pb_ten=1e7,
                pb_coh=1e7, pb_fa=30.0)
    base.update(kw)
    with pytest.raises(InputError, match=needle):
        Material(**base)


def test_bad_balls_are_rejected_naming_the_ball():
    mat = material()
    with pytest.raises(InputError, match="ball 1 has radius -0.001"):
        Model([[0, 0, 0], [1, 0, 0]], [1e-3, -1e-3], 2294.0, mat)
    with pytest.raises(InputError, match="ball 0 has non-finite"):
        Model([[np.nan, 0, 0]], [1e-3], 2294.0, mat)
    with pytest.raises(InputError, match="density"):
        Model([[0, 0, 0]], [1e-3], 0.0, mat)
    with pytest.raises(InputError, match="damping=1.5"):
        Model([[0, 0, 0]], [1e-3], 2294.0, mat, damping=1.5)


def test_timestep_above_stable_limit_is_refused():
    m, _ = box_pack(60, seed=1)
    dtc, _ = m.critical_timestep()
    with pytest.raises(InputError, match="above the stable limit"):
        m.set_timestep(1.5 * dtc)
    assert m.set_timestep(0.9 * dtc) == pytest.approx(0.9 * dtc)


def test_blow_up_stops_with_step_and_ball():
    m, _ = box_pack(60, seed=2, damping=0.0)
    dtc, _ = m.critical_timestep()
    m.prm[0] = 4.0 * dtc  # bypass the guard to provoke the instability
    s0 = m.step
    with pytest.raises(InstabilityError) as ei:
        m.cycle(5000)
    err = ei.value
    assert s0 < err.step < s0 + 5000
    assert 0 <= err.ball < m.n
    assert f"step {err.step}" in str(err) and f"ball {err.ball}" in str(err)


def test_numba_disable_jit_runs_the_same_physics():
    code = textwrap.dedent("""
        import math, sys
        sys.path.insert(0, %r)
        from support.dem_util import material, two_balls, bond_constants
        mat = material()
        m = two_balls(mat)
        m.set_velocity([1], vel=[1e-3, 0, 0])
        m.cycle(20)
        f, _ = m.ball_forces()
        c = bond_constants(mat)
        opening = m.B.pos[1, 0] - m.B.pos[0, 0] - 2e-3
        print(abs(f[1, 0] + c["knA"] * opening) / (c["knA"] * opening))
    """ % str(Path(__file__).resolve().parents[2]))
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert float(out.stdout.strip()) < 1e-9
