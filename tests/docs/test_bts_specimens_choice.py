"""The rule that chose the default study's discs per seed (``verification.tensile_specimens``,
benchmarks/bts_resolution.py): the seed CV expected of a k-disc mean and the chance that
five seeds read a CV above the target, against a simulation of that sampling."""
import sys

import numpy as np
import pytest
from support.repo import REPO

sys.path.insert(0, str(REPO / "benchmarks"))

import bts_resolution as B  # noqa: E402


@pytest.mark.parametrize("cv_disc,k", [(0.061, 1), (0.061, 3), (0.045, 2), (0.03, 1)])
def test_the_miss_chance_is_that_of_five_normal_seeds(cv_disc, k):
    cvk, p = B.expected_cv(cv_disc, k)
    assert cvk == pytest.approx(cv_disc / np.sqrt(k))
    rng = np.random.default_rng(5)
    # k discs per seed, N_CHECK seeds, 200,000 repeats: the sample CV of the seed means
    discs = 10.0 * (1 + cv_disc * rng.standard_normal((200_000, B.N_CHECK, k)))
    seeds = discs.mean(axis=2)
    cv = seeds.std(axis=1, ddof=1) / seeds.mean(axis=1)
    assert np.mean(cv > B.CV_TARGET) == pytest.approx(p, abs=0.01)


def test_the_rule_picks_the_smallest_count_under_the_accepted_chance():
    # a disc CV for which 2 discs miss too often and 3 do not, and one where 1 is enough
    cvs = {"x": (0.06, 9.0, 9.0, 120)}
    text = "\n".join(B._expected_table(cvs, "t"))
    assert "every card: **3**" in text
    assert "every card: **1**" in "\n".join(B._expected_table({"y": (0.02, 9, 9, 10)}, "t"))
    p2, p3 = B.expected_cv(0.06, 2)[1], B.expected_cv(0.06, 3)[1]
    assert p3 < B.MISS_ACCEPTED < p2
