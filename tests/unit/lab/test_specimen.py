"""Specimen genesis: porosity, bonding, locked-in stress, determinism."""
import numpy as np
import pytest
from support.lab_util import A1, SMALL

from bpmcal.lab.packing_cache import get_packing
from bpmcal.lab.runner import make_specimen
from bpmcal.lab.specimen import SpecimenSpec


@pytest.mark.parametrize("rmin, n", [(0.6, 0.20), (1.0, 0.20), (0.6, 0.36), (1.0, 0.36)])
def test_genesis_reaches_requested_porosity_across_table2(rmin, n, cache):
    p = dict(A1, rmin_mm=rmin, porosity=n)
    sp = make_specimen(p, 5, SMALL, cache=cache)
    r = sp.report
    # nominal porosity (PFC ball distribute): only the enlargement of floaters moves it
    assert abs(r["porosity_achieved"] - n) < 0.005, r
    assert r["relax_converged"]
    assert 3.5 < r["coordination"] < 12
    # every contact at bonding time got a bond
    assert r["n_bonds"] == r["contacts_at_bonding"]
    # locked-in isotropic stress relieved to P&C's 0.1 MPa
    assert r["locked_in_stress_MPa"] <= 0.1 + 1e-12
    assert r["relaxed_stress_MPa"] > 0


def test_denser_packing_has_more_contacts(cache):
    z = [make_specimen(dict(A1, porosity=n), 5, SMALL, cache=cache).report["coordination"]
         for n in (0.22, 0.30, 0.36)]
    assert z[0] > z[1] > z[2]


def test_genesis_is_deterministic_and_cached(tmp_path):
    spec = SpecimenSpec.from_paper_units(0.8, 0.3, seed=11, scale=0.2)
    a = get_packing(spec, cache=tmp_path / "a")
    b = get_packing(spec, cache=tmp_path / "b")
    assert np.array_equal(a.pos, b.pos) and np.array_equal(a.radius, b.radius)
    c = get_packing(spec, cache=tmp_path / "a")  # from the cache file
    assert np.array_equal(a.pos, c.pos)
    d = get_packing(SpecimenSpec.from_paper_units(0.8, 0.3, seed=12, scale=0.2),
                    cache=tmp_path / "a")
    assert not np.array_equal(a.pos[: len(d.pos)], d.pos[: len(a.pos)])


@pytest.mark.slow
def test_packing_relaxes_with_the_threads_asked_for_and_the_same_result(tmp_path):
    """get_packing(threads=k) relaxes with k numba threads (a job given one core must not
    start two), and the packing is bit for bit the one of any other thread count."""
    from bpmcal.dem._jit import numba, set_threads

    spec = SpecimenSpec.from_paper_units(0.8, 0.3, seed=13, scale=0.2)
    before = numba.get_num_threads()
    packs = []
    try:
        for k in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            set_threads(numba.config.NUMBA_NUM_THREADS)
            packs.append(get_packing(spec, cache=tmp_path / f"t{k}", threads=k))
            assert numba.get_num_threads() == k
        for pk in packs[1:]:
            assert np.array_equal(pk.pos, packs[0].pos)
            assert np.array_equal(pk.radius, packs[0].radius)
    finally:
        set_threads(before)


def test_too_small_specimen_is_refused():
    from bpmcal.dem.errors import InputError
    with pytest.raises(InputError, match="too small"):
        SpecimenSpec.from_paper_units(1.0, 0.3, seed=1, scale=0.05)


def test_close_pairs_and_touching_count_match_brute_force():
    """The genesis's own neighbour search (numpy sweep, no tree): every pair within reach,
    and the count of pairs within an installation gap, as an O(n^2) search finds them."""
    from bpmcal.lab.specimen import _close_pairs, _count_touching

    g = np.random.default_rng(3)
    for n, box, gap in ((300, (0.02, 0.02, 0.04), 0.0), (500, (0.02, 0.02, 0.01), 5e-5),
                        (2, (0.01, 0.01, 0.01), 0.0), (1, (0.01, 0.01, 0.01), 0.0)):
        pos = g.uniform(0.0, box, (n, 3))
        r = g.uniform(0.8e-3, 1.33e-3, n)
        reach = 2.0 * r.max() + gap
        d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=2)
        bi, bj = np.nonzero(np.triu(d <= reach, 1))
        i, j = _close_pairs(pos, reach)
        assert np.all(i < j)
        assert set(zip(i.tolist(), j.tolist())) == set(zip(bi.tolist(), bj.tolist()))
        touching = np.triu(d - r[:, None] - r[None, :] <= gap, 1)
        assert _count_touching(pos, r, gap) == int(touching.sum())
