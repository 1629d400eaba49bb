"""Per-contact strengths (PFC's per-contact ``pb_ten``/``pb_coh``, ``fj_ten``/``fj_coh``):
the engine side of the strength scatter. A contact given its own strengths breaks at them,
not at the material's means, and each contact at its own; the strength factor (the lab's
caps) multiplies them; a material with other means resets them; bad values are refused.
The drawing itself is tested in tests/unit/lab/test_microstructure.py."""
import math

import numpy as np
import pytest
from support.dem_util import RHO, R, approach, bond_constants, material, rel, two_balls
from support.flatjoint_util import KN, fj_material, fj_two_balls

from bpmcal.dem import BOND_SHEAR, BOND_TENSION, FIX_ALL, InputError, Model
from bpmcal.dem import flatjoint as fj

TOL = 1e-9


def test_new_bonds_carry_the_materials_means_exactly(mat):
    m = two_balls(mat)
    ten, coh = m.bond_strengths
    assert ten.tolist() == [mat.pb_ten] and coh.tolist() == [mat.pb_coh]
    f = fj_two_balls()
    ten, coh = f.bond_strengths
    assert ten.tolist() == [f.material.fj_ten] and coh.tolist() == [f.material.fj_coh]


@pytest.mark.parametrize("ten", [7.5e6, 33e6])
def test_a_bond_breaks_in_tension_at_its_own_strength(mat, ten):
    m = two_balls(mat)
    m.set_bond_strengths([ten], [mat.pb_coh])
    c = bond_constants(mat)
    approach(m, lambda v: m.set_velocity([1], vel=[v, 0, 0]),
              lambda m: ten * c["area"] - m.bond_state()["fn"][0], c["knA"])
    ev = m.breaks()
    assert ev["mode"].tolist() == [BOND_TENSION]
    assert rel(ev["sigma"][0], ten) < TOL


def test_a_bond_breaks_in_shear_at_its_own_cohesion():
    mat = material(pb_ten=50e6, pb_coh=15e6, pb_fa=0.0, fric=10.0)
    coh = 9e6
    m = two_balls(mat)
    m.set_bond_strengths([mat.pb_ten], [coh])
    c = bond_constants(mat)
    approach(m, lambda v: m.set_velocity([1], vel=[0, v, 0]),
              lambda m: coh * c["area"] - np.linalg.norm(m.bond_state()["fs"][0]), c["ksA"])
    ev = m.breaks()
    assert ev["mode"].tolist() == [BOND_SHEAR]
    assert rel(ev["tau"][0], coh) < TOL


def test_the_strength_factor_multiplies_the_bonds_own_strength(mat):
    m = two_balls(mat)
    ten, factor = 12e6, 2.5
    m.set_bond_strengths(ten, mat.pb_coh)  # a scalar applies to every bond
    m.set_bond_strength_factors([factor])
    c = bond_constants(mat)
    approach(m, lambda v: m.set_velocity([1], vel=[v, 0, 0]),
              lambda m: factor * ten * c["area"] - m.bond_state()["fn"][0], c["knA"])
    assert rel(m.breaks()["sigma"][0], factor * ten) < TOL


def test_each_bond_breaks_at_its_own_strength(mat):
    """Two bonded pairs far apart, pulled open at the same rate: each breaks when its own
    normal stress reaches its own strength, the weaker one first."""
    d = 2 * R
    pos = [[0, 0, 0], [d, 0, 0], [0, 10 * R, 0], [d, 10 * R, 0]]
    m = Model(pos, [R] * 4, RHO, mat, damping=0.0)
    m.fix([0, 1, 2, 3], FIX_ALL)
    assert m.bond(gap=1e-12) == 2
    m.set_timestep(None)
    i, j = m.bond_pairs()
    assert sorted(zip(i.tolist(), j.tolist())) == [(0, 1), (2, 3)]
    strengths = np.where(i == 0, 14e6, 26e6)
    m.set_bond_strengths(strengths, mat.pb_coh)
    c = bond_constants(mat)
    v = 1e-4
    m.set_velocity([1, 3], vel=[[v, 0, 0], [v, 0, 0]])
    step = c["knA"] * v * m.dt / c["area"]  # normal stress per step
    while m.n_broken < 2:
        m.cycle(1)
    ev = m.breaks()
    assert ev["mode"].tolist() == [BOND_TENSION, BOND_TENSION]
    order = np.argsort(ev["step"])
    assert ev["bond"][order].tolist() == np.argsort(strengths).tolist()  # weaker first
    for k, s in zip(ev["bond"], ev["sigma"]):
        assert strengths[k] <= s < strengths[k] + step * (1 + 1e-9)


def test_a_flat_joint_breaks_at_its_own_strength():
    """T1 (pure tension) with the joint's own fj_ten: all elements break together at it."""
    ten = 6e6
    m = fj_two_balls()
    m.set_bond_strengths([ten], [m.material.fj_coh])
    v = 1e-2
    m.set_velocity([1], vel=[v, 0, 0])
    df = v * m.dt
    while m.n_broken == 0:
        m.cycle(1)
    d = m.B.pos[1, 0] - m.B.pos[0, 0] - 2 * R
    assert ten / KN <= d < ten / KN + df * 1.0000001
    assert (m.element_states == fj.E_TENSION).all()
    assert np.allclose(m.breaks()["sigma"], KN * d, rtol=1e-9)


def test_new_means_reset_the_contacts_strengths_the_same_means_keep_them(mat):
    m = two_balls(mat)
    m.set_bond_strengths([3e6], [4e6])
    m.set_material(mat.replace(fric=0.1))  # same means: the contact keeps its own
    assert [a.tolist() for a in m.bond_strengths] == [[3e6], [4e6]]
    m.set_material(mat.replace(pb_ten=2 * mat.pb_ten))  # PFC contact property: all contacts
    assert [a.tolist() for a in m.bond_strengths] == [[2 * mat.pb_ten], [mat.pb_coh]]
    f = fj_two_balls()
    f.set_bond_strengths([3e6], [4e6])
    f.set_material(fj_material(fj_coh=7e6))
    assert [a.tolist() for a in f.bond_strengths] == [[10e6], [7e6]]


@pytest.mark.parametrize("ten, coh", [([1.0, 2.0], [1.0]), ([-1.0], [1.0]),
                                      ([math.nan], [1.0]), ([1.0], [math.inf])])
def test_bad_contact_strengths_are_refused(mat, ten, coh):
    m = two_balls(mat)
    with pytest.raises(InputError, match="expected 1 finite values >= 0 Pa"):
        m.set_bond_strengths(ten, coh)
    assert [a.tolist() for a in m.bond_strengths] == [[mat.pb_ten], [mat.pb_coh]]


@pytest.mark.parametrize("name", ["pb_ten_sd", "pb_coh_sd"])
@pytest.mark.parametrize("bad", [-1.0, math.nan])
def test_a_negative_or_nan_sd_is_refused_by_the_material(mat, name, bad):
    with pytest.raises(InputError, match=name):
        mat.replace(**{name: bad})
    with pytest.raises(InputError, match="fj_" + name[3:]):
        fj_material(**{"fj_" + name[3:]: bad})
