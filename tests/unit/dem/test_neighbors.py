"""Neighbour search (cell grid + Verlet skin) against brute force; capacity growth;
contact history across rebuilds."""
import numpy as np
from support.dem_util import box_pack, material, rng

from bpmcal.dem import Model


def brute_pairs(pos, r, cutoff):
    d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=2)
    lim = r[:, None] + r[None, :] + cutoff
    i, j = np.nonzero(np.triu(d < lim, 1))
    return set(zip(i.tolist(), j.tolist()))


def listed(m):
    i, j = m.pairs()
    return set(zip(i.tolist(), j.tolist()))


def random_cloud(n, seed, L=0.02, overlap=True):
    """Random balls in a cube; without ``overlap`` positions are drawn by rejection."""
    g = rng(seed)
    r = g.uniform(0.6e-3, 1.0e-3, n)
    if overlap:
        return g.uniform(0, L, (n, 3)), r
    pos = np.empty((n, 3))
    for i in range(n):
        while True:
            p = g.uniform(0, L, 3)
            if i == 0 or np.all(np.linalg.norm(pos[:i] - p, axis=1) > r[:i] + r[i]):
                pos[i] = p
                break
    return pos, r


def test_verlet_list_matches_brute_force_on_random_packings():
    for seed in range(3):
        pos, r = random_cloud(400, seed)
        m = Model(pos, r, 2294.0, material(), skin=2e-4)
        assert listed(m) == brute_pairs(pos, r, 2e-4)


def test_after_random_moves_and_rebuilds():
    pos, r = random_cloud(300, 7)
    m = Model(pos, r, 2294.0, material(), skin=1.5e-4)
    g = rng(8)
    for _ in range(4):
        new = m.B.pos + g.normal(0, 1e-3, m.B.pos.shape)
        m.set_positions(np.arange(m.n), new)
        assert listed(m) == brute_pairs(new, r, 1.5e-4)


def test_dynamic_run_never_misses_a_contact():
    """Balls flying around undamped: at every check all touching pairs are listed."""
    pos, r = random_cloud(200, 3, L=0.012, overlap=False)
    m = Model(pos, r, 2294.0, material(fric=0.0), damping=0.0, skin=1e-4)
    m.set_velocity(np.arange(m.n), vel=rng(4).normal(0, 2.0, (m.n, 3)))
    m.set_timestep(None)
    rebuilds0 = m.n_rebuilds
    for _ in range(30):
        m.cycle(37)
        touching = brute_pairs(m.B.pos, r, 0.0)
        assert touching <= listed(m)
    assert m.n_rebuilds > rebuilds0 + 3  # the skin criterion did trigger rebuilds


def test_overflow_grows_capacity_and_loses_no_pair():
    pos, r = random_cloud(500, 11, L=0.015)
    m = Model(pos, r, 2294.0, material(), skin=2e-4, pair_capacity=8, slot_capacity=2)
    m.add_plane_wall((0, 0, 0), (0, 0, 1))
    m.add_plane_wall((0, 0, 0.015), (0, 0, -1))
    assert listed(m) == brute_pairs(pos, r, 2e-4)
    assert m.P.pi.shape[0] >= len(listed(m))
    near = np.flatnonzero((pos[:, 2] - r < 2e-4) | (0.015 - pos[:, 2] - r < 2e-4))
    assert m.n_wall_slots == near.size  # every ball near a wall has its slot


def test_bonds_are_not_searched_and_survive_separation():
    m, L = box_pack(120, seed=5)
    m.bond(gap=0.0)
    nb = m.n_bonds
    bi, bj = m.bond_pairs()
    i, j = m.pairs()
    verlet = set(zip(i[nb:].tolist(), j[nb:].tolist()))
    assert not (verlet & set(zip(bi.tolist(), bj.tolist())))
    # all bond pairs plus the Verlet pairs are exactly the brute-force neighbour set
    assert set(zip(i.tolist(), j.tolist())) == brute_pairs(m.B.pos, m.B.radius,
                                                            m.prm[17]) | set(
        zip(bi.tolist(), bj.tolist()))


def test_shear_history_survives_rebuild():
    mat = material(fric=0.5)
    R = 1e-3
    # two unbonded balls in contact, sheared, then a forced rebuild
    m = Model([[0, 0, 0], [2 * R - 2e-6, 0, 0]], [R, R], 2294.0, mat, damping=0.0)
    m.fix([0, 1])
    m.set_timestep(None)
    m.set_velocity([1], vel=[0, 1e-3, 0])
    m.cycle(50)
    fs = m.linear_shear_forces()[0].copy()
    assert np.linalg.norm(fs) > 0
    m.set_positions([0, 1], m.B.pos.copy())  # forces a rebuild, no motion
    assert np.array_equal(m.linear_shear_forces()[0], fs)
    m.cycle(1)
    assert np.linalg.norm(m.linear_shear_forces()[0]) > np.linalg.norm(fs)


def test_pair_list_is_sorted_by_row_then_partner():
    """The pair list is in increasing (i, j) order after every rebuild, however the cells
    are searched: the order fixes the summation order of the forces (bitwise results)."""
    pos, r = random_cloud(400, 21)
    m = Model(pos, r, 2294.0, material(), skin=2e-4)
    g = rng(22)
    for _ in range(3):
        i, j = m.pairs()
        assert np.all(i < j)
        key = i.astype(np.int64) * m.n + j
        assert np.all(np.diff(key) > 0)
        m.set_positions(np.arange(m.n), m.B.pos + g.normal(0, 1e-3, m.B.pos.shape))
