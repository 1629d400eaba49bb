"""The two genesis procedures (lab.specimen, ``genesis="bpmcal" | "pfc"``): bonds per ball,
zero linear force after the PFC-style relief, determinism, and the run-file record."""
import math
from dataclasses import replace

import numpy as np
import pytest
from support.lab_util import A1, FAST, SMALL

from bpmcal.dem.errors import InputError
from bpmcal.io import h5
from bpmcal.lab.packing_cache import get_packing
from bpmcal.lab.runner import Geometry, make_specimen
from bpmcal.lab.specimen import (
    DEFAULT_GENESIS,
    PFC_GAP_RATIO,
    SpecimenSpec,
    build_specimen,
    default_install_gap,
    paper_material,
)
from bpmcal.lab.ucs import run_ucs
from bpmcal.stages.runs import run_ucs_file

#: the first 3,000 steps of a test (before the peak): enough to compare two runs
SHORT = replace(FAST, max_steps=3_000)
MAT = paper_material(A1["pb_emod_GPa"], A1["pb_kratio"], A1["pb_ten_MPa"], A1["pb_coh_MPa"],
                     A1["pb_fa_deg"], A1["fric"])


@pytest.fixture(scope="module")
def packing(cache):
    return get_packing(SpecimenSpec.from_paper_units(0.8, 0.34, 3, scale=0.24), cache=cache)


def _linear_normal_forces(m):
    """kn max(0, rg - gap) of every bond pair [N], from the geometry (independent of the
    kernels): the force the linear part carries in the current configuration."""
    i, j = m.bond_pairs()
    r = np.minimum(m.B.radius[i], m.B.radius[j])
    L = m.B.radius[i] + m.B.radius[j]
    kn = math.pi * r * r * m.material.emod / L
    gap = m.pair_gaps(i, j)
    return kn * np.maximum(0.0, m.bond_state()["rgap"] - gap), gap


def test_pfc_genesis_bonds_more_pairs_per_ball_on_the_same_packing(packing):
    a = build_specimen(packing, MAT, genesis="bpmcal")
    b = build_specimen(packing, MAT, genesis="pfc")
    ra, rb = a.report, b.report
    assert ra["n_balls"] == rb["n_balls"]
    assert rb["install_gap_rmin"] == pytest.approx(PFC_GAP_RATIO)
    assert ra["install_gap_mm"] == 0.0
    assert rb["bonds_per_ball"] > ra["bonds_per_ball"] * 1.02, (ra, rb)
    # every pair within the gap got a bond (counted independently of the engine's lists)
    assert rb["n_bonds"] == rb["contacts_at_bonding"]
    assert rb["n_bonds"] > rb["overlapping_at_bonding"]
    for r in (ra, rb):
        assert r["bonds_per_ball"] == pytest.approx(2 * r["n_bonds"] / r["n_balls"])
        vol_cm3 = math.pi * (0.5 * 12.0) ** 2 * 24.0 / 1e3
        assert r["bonds_per_cm3"] == pytest.approx(r["n_bonds"] / vol_cm3)


def test_contacts_per_ball_counts_touching_balls_not_bonds(packing):
    """The run file's contact-based coordination: overlapping balls per ball, counted here
    by brute force over all pairs (not the engine's lists); below the bonds per ball when
    bonds span gaps (the PFC genesis's installation gap)."""
    sp = build_specimen(packing, MAT, genesis="pfc")
    m, r = sp.model, sp.report
    x, rad = m.positions, m.radii
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    touching = np.triu(d - rad[:, None] - rad[None, :] < 0.0, k=1)
    assert r["contacts_per_ball"] == pytest.approx(2.0 * touching.sum() / m.n, rel=1e-12)
    assert 0.0 < r["contacts_per_ball"] < r["bonds_per_ball"]


def test_pfc_genesis_leaves_no_force_in_the_linear_part(packing):
    sp = build_specimen(packing, MAT, genesis="pfc")
    m = sp.model
    fn, gap = _linear_normal_forces(m)
    assert np.count_nonzero(gap < 0) > 0.5 * gap.size  # the overlaps are still there
    # a contact force at P&C's 0.1 MPa on a ball of radius Rmin: the bpmcal genesis's
    # locked-in level, far above what is left after the PFC-style relief
    fref = 0.1e6 * math.pi * (0.8e-3) ** 2
    assert fn.max() < 1e-9 * fref, fn.max()
    assert m.energies()["strain_linear"] < 1e-20
    assert np.all(np.abs(m.W.force) < 1e-9 * fref)
    assert sp.report["locked_in_stress_MPa"] == 0.0
    assert sp.report["settle_free_ratio"] <= 1e-3
    # the bpmcal genesis keeps a locked-in stress of 0.1 MPa: its linear parts carry force
    fb, _ = _linear_normal_forces(build_specimen(packing, MAT, genesis="bpmcal").model)
    assert fb.max() > 1e-3 * fref


def test_pfc_genesis_linear_part_reacts_from_the_bonding_state(packing):
    """Pushing a bonded, overlapping pair further together loads its linear part at once
    (PFC's incremental mode after ``lin_force 0``); a bond pair bonded across a positive
    gap gets its linear force only once the surfaces touch."""
    sp = build_specimen(packing, MAT, genesis="pfc")
    m = sp.model
    i, j = m.bond_pairs()
    rg = m.bond_state()["rgap"]
    gap = m.pair_gaps(i, j)
    over = gap < 0
    assert np.allclose(rg[over], gap[over], rtol=0, atol=1e-15)
    assert np.all(rg[~over] == 0.0)


@pytest.mark.parametrize("genesis", ["bpmcal", "pfc"])
def test_both_geneses_are_deterministic(packing, genesis):
    runs = []
    for _ in range(2):
        sp = build_specimen(packing, MAT, genesis=genesis)
        res = run_ucs(sp, SHORT)
        runs.append((sp.model.B.pos.copy(), sp.model.bond_pairs(), res.summary["ucs_MPa"],
                     res.series["axial_stress"].copy()))
    (p0, b0, s0, ser0), (p1, b1, s1, ser1) = runs
    assert np.array_equal(p0, p1)
    assert np.array_equal(b0[0], b1[0]) and np.array_equal(b0[1], b1[1])
    assert s0 == s1 and np.array_equal(ser0, ser1)


def test_a_wide_installation_gap_bonds_every_pair_within_it(packing):
    """Gaps beyond the default Verlet skin (0.25 Rmin) are still bonded completely."""
    sp = build_specimen(packing, MAT, genesis="pfc", install_gap=0.4 * 0.8e-3)
    assert sp.report["n_bonds"] == sp.report["contacts_at_bonding"]


def test_genesis_choice_is_validated(packing):
    with pytest.raises(InputError, match="genesis='xyz'"):
        build_specimen(packing, MAT, genesis="xyz")
    with pytest.raises(InputError, match="genesis='PFC'"):
        Geometry(genesis="PFC")
    with pytest.raises(InputError, match="genesis"):
        default_install_gap("other", 1e-3)
    assert Geometry(genesis="pfc").install_gap(0.8) == pytest.approx(0.05)
    assert Geometry(genesis="pfc", install_gap_mm=0.0).install_gap(0.8) == 0.0
    assert Geometry(genesis="bpmcal").install_gap(0.8) == 0.0
    # the default genesis is pfc (the one closer to PFC3D on the paper's A1 set)
    assert Geometry().genesis == DEFAULT_GENESIS == "pfc"
    assert Geometry().install_gap(0.8) == pytest.approx(0.05)


def test_run_file_records_genesis_gap_coordination_and_bond_density(tmp_path, cache):
    geo = Geometry(scale=0.24, genesis="pfc")
    out = tmp_path / "pfc.h5"
    res = run_ucs_file(out, A1, 3, geo, SHORT, cache=cache)
    assert res.status == "incomplete"  # SHORT cuts the loading (for speed): no sigma_c, but
    assert "max_steps" in res.error  # the run is written whole, genesis and inputs too
    s, inp, g = h5.read_summary(out), h5.read_inputs(out), h5.read_genesis(out)
    assert g["genesis"] == "pfc" and g["bonds_per_cm3"] == s["bonds_per_cm3"]
    assert inp["genesis"] == "pfc" and s["genesis"] == "pfc"
    assert inp["install_gap_mm"] == pytest.approx(0.05)
    assert s["install_gap_mm"] == pytest.approx(0.05)
    for k in ("coordination", "bonds_per_ball", "bonds_per_cm3"):
        assert s[k] > 0
    sp = make_specimen(A1, 3, SMALL, cache=cache)  # the default genesis
    assert sp.report["genesis"] == "pfc" and sp.report["install_gap_mm"] == pytest.approx(0.05)
    sp = make_specimen(A1, 3, replace(SMALL, genesis="bpmcal"), cache=cache)
    assert sp.report["genesis"] == "bpmcal" and sp.report["install_gap_mm"] == 0.0
