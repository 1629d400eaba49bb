"""How many tensile specimens a seed needs (bpmcal.analysis.calibration.specimens): the
pooled specimen CV against groups of known scatter, and the count rule against a
simulation of the seed CV read over 5 seeds."""
import math

import numpy as np
import pytest

from bpmcal.analysis.calibration import specimens as S


def test_the_pooled_cv_ignores_the_groups_means():
    # three parameter sets whose σt differs 3x: the spread of the means is not scatter
    rng = np.random.default_rng(3)
    groups = [m * (1 + 0.08 * rng.standard_normal(400)) for m in (5.0, 10.0, 15.0)]
    cv, dof = S.pooled_cv(groups)
    assert dof == 3 * 399 and cv == pytest.approx(0.08, rel=0.05)
    assert math.isnan(S.pooled_cv([[1.0], [2.0]])[0]) and S.pooled_cv([[1.0], [2.0]])[1] == 0


def test_nan_specimens_count_no_degree_of_freedom():
    cv, dof = S.pooled_cv([[10.0, 11.0, math.nan], [5.0, 5.5]])
    assert dof == 2
    assert cv == pytest.approx(math.sqrt(2 * (0.5 / 10.5) ** 2 + 2 * (0.25 / 5.25) ** 2) / math.sqrt(2))


@pytest.mark.parametrize("cv", [0.02, 0.06, 0.12])
def test_the_count_is_the_smallest_whose_five_seeds_rarely_read_above_the_target(cv):
    k = S.specimens_needed(cv, 0.05)
    rng = np.random.default_rng(11)

    def miss(k):  # the chance, simulated, that 5 seeds of k specimens read a CV above 5 %
        seeds = (10.0 * (1 + cv * rng.standard_normal((100_000, 5, k)))).mean(axis=2)
        return np.mean(seeds.std(axis=1, ddof=1) / seeds.mean(axis=1) > 0.05)

    assert miss(k) < S.MISS_ACCEPTED + 0.01
    if k > 1:
        assert miss(k - 1) > S.MISS_ACCEPTED - 0.01


def test_the_count_stays_within_its_bounds():
    assert S.specimens_needed(0.01, 0.05, least=3) == 3  # never fewer than now
    assert S.specimens_needed(0.30, 0.05, most=12) == 12  # out of reach: the cap
    assert S.specimens_needed(0.06, 0.05) == 3  # the default study's discs (~6 %): 3
