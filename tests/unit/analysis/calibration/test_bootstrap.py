"""Bootstrap intervals of the calibration: coverage on repeated synthetic datasets."""
import numpy as np
import pytest

from bpmcal.analysis.calibration import SearchSpace, bootstrap_intervals
from bpmcal.analysis.stepwise import RegressionModel, StepwiseRegression
from bpmcal.params import table2_ranges

T2 = table2_ranges()  # the paper's design space
SPACE = SearchSpace(ranges=T2)
FIXED = {"porosity": 0.34, "rmin_mm": 0.8}
TRUTH = {"pb_emod_GPa": 20.0, "pb_kratio": 2.5, "pb_coh_MPa": 25.0, "pb_ten_MPa": 35.0}
TERMS = {"ucs_MPa": [("pb_coh_MPa",), ("pb_ten_MPa",), ("porosity",), ("pb_kratio",)],
         "E_GPa": [("pb_emod_GPa",), ("pb_kratio",)],
         "nu": [("pb_kratio",)]}
COEF = {"ucs_MPa": ([1.2, 0.8, -300.0, -6.0], 120.0), "E_GPa": ([1.29, -0.3], 0.2), "nu": ([0.04], 0.1)}
NOISE = {"ucs_MPa": 3.0, "E_GPa": 0.8, "nu": 0.01}
TRUE_MODELS = {r: RegressionModel(r, TERMS[r], *COEF[r]) for r in TERMS}
TARGETS = {r: m.predict({**FIXED, **TRUTH}) for r, m in TRUE_MODELS.items()}


def dataset(design, seed):
    df = design(150, seed)
    rng = np.random.default_rng(seed + 1000)
    for r, m in TRUE_MODELS.items():
        df[r] = m.predict(df) + rng.normal(0, NOISE[r], len(df))
    return df


def fitted(df):
    ok = df[df["status"] == "ok"]
    return {r: RegressionModel(r, TERMS[r], np.zeros(len(TERMS[r])), 0.0).refit(ok) for r in TERMS}


@pytest.mark.slow
def test_percentile_intervals_cover_truth_at_nominal_rate(design):
    n_sets, covered = 40, {p: 0 for p in TRUTH}
    for i in range(n_sets):
        df = dataset(design, seed=100 + i)
        boot = bootstrap_intervals(df, fitted(df), TARGETS, FIXED, SPACE, n_boot=100, seed=i)
        assert boot.n_unreachable == 0
        iv = boot.intervals
        for p, v in TRUTH.items():
            covered[p] += iv.loc[p, "lower"] <= v <= iv.loc[p, "upper"]
    for p, k in covered.items():
        assert 0.8 <= k / n_sets <= 1.0, (p, k)


def test_intervals_shrink_with_less_noise_and_report_rows(design):
    df = dataset(design, seed=7)
    df.loc[[3, 4], "status"] = "failed"
    wide = bootstrap_intervals(df, fitted(df), TARGETS, FIXED, SPACE, n_boot=60, seed=1)
    quiet = df.copy()  # the same data with a tenth of the noise: ~10x narrower intervals
    for r, m in TRUE_MODELS.items():
        quiet[r] = m.predict(df) + 0.1 * (df[r] - m.predict(df))
    narrow = bootstrap_intervals(quiet, fitted(quiet), TARGETS, FIXED, SPACE, n_boot=60, seed=1)
    for p in TRUTH:
        w_narrow, w_wide = (b.intervals.loc[p, "upper"] - b.intervals.loc[p, "lower"] for b in (narrow, wide))
        assert 0.05 * w_wide < w_narrow < 0.2 * w_wide, p
    assert wide.rows["n_dropped"] == 2 and wide.rows["n_used"] == 148
    assert len(wide.draws) == 60
    np.testing.assert_allclose(wide.intervals.loc["pb_ten_MPa", "estimate"],
                               1.4 * wide.intervals.loc["pb_coh_MPa", "estimate"])
    resp = wide.intervals[wide.intervals["kind"] == "response"]
    assert (resp["lower"] < resp["estimate"]).all() and (resp["estimate"] < resp["upper"]).all()


def test_reselection_scheme(design):
    df = dataset(design, seed=9)
    cands = {"ucs_MPa": ("pb_coh_MPa", "pb_ten_MPa", "porosity", "pb_kratio"),
             "E_GPa": ("pb_emod_GPa", "pb_kratio"), "nu": ("pb_kratio",)}
    boot = bootstrap_intervals(df, fitted(df), TARGETS, FIXED, SPACE, n_boot=4, seed=2,
                               reselect=StepwiseRegression(cv_folds=0), candidates=cands)
    assert "re-run" in boot.scheme
    assert np.isfinite(boot.intervals[["lower", "upper"]].to_numpy()).all()
    with pytest.raises(ValueError, match="candidates"):
        bootstrap_intervals(df, fitted(df), TARGETS, FIXED, SPACE, n_boot=4,
                            reselect=StepwiseRegression())
