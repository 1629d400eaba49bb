"""Fragments, t10 and the JK breakage model on data with known answers."""
import math

import numpy as np
import pytest

from bpmcal.lab import fragments as F


def test_fragments_count_components_of_a_hand_built_bond_graph():
    # balls 0-1-2 chain, 3-4 pair, 5 alone, 6-7 with a broken bond, 8-9-10 triangle
    i = [0, 1, 3, 6, 8, 9, 8]
    j = [1, 2, 4, 7, 9, 10, 10]
    intact = [1, 1, 1, 0, 1, 0, 1]
    lab = F.fragments(11, i, j, intact)
    groups = {frozenset(np.flatnonzero(lab == c)) for c in np.unique(lab)}
    assert groups == {frozenset({0, 1, 2}), frozenset({3, 4}), frozenset({5}), frozenset({6}),
                      frozenset({7}), frozenset({8, 9, 10})}


def test_fragment_sizes_are_equivalent_sphere_diameters():
    lab = np.array([0, 0, 1])
    r = np.array([1e-3, 1e-3, 2e-3])
    mass, size = F.fragment_sizes(lab, r, 2000.0)
    v0 = 2 * 4 / 3 * math.pi * 1e-9
    assert mass[0] == pytest.approx(2000 * v0)
    assert size[0] == pytest.approx((6 * v0 / math.pi) ** (1 / 3))
    assert size[1] == pytest.approx(4e-3)


def test_t10_is_mass_percent_below_a_tenth_of_the_original_size():
    mass = np.array([1.0, 2.0, 3.0, 4.0])
    size = np.array([0.5, 0.9, 1.1, 5.0])  # original size 10 -> t10 threshold 1.0
    assert F.t10(mass, size, 10.0) == pytest.approx(30.0)


def test_jk_fit_recovers_known_parameters():
    A, b = 45.0, 1.7
    ecs = np.array([0.1, 0.25, 0.5, 1.0, 2.0, 3.0])
    rng = np.random.default_rng(0)
    t10 = F.jk_model(ecs, A, b) * (1 + rng.normal(0, 0.002, ecs.size))
    fit = F.fit_jk(ecs, t10)
    assert fit["A"] == pytest.approx(A, rel=0.02)
    assert fit["b"] == pytest.approx(b, rel=0.03)
    assert fit["Ab"] == pytest.approx(A * b, rel=0.03)
    assert fit["r2"] > 0.999


def test_jk_fit_needs_two_points():
    with pytest.raises(ValueError, match="at least 2"):
        F.fit_jk([1.0], [10.0])
