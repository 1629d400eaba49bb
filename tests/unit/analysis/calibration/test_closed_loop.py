"""Closed-loop correction against a synthetic "DEM" = regression model with a known bias."""
import numpy as np
import pandas as pd
import pytest

from bpmcal.analysis.calibration import (
    ClosedLoop,
    LoopSeeds,
    LoopSteps,
    Multistart,
    SearchSpace,
    invert,
    scatter_table,
)
from bpmcal.analysis.stepwise import RegressionModel
from bpmcal.params import table2_ranges

T2 = table2_ranges()  # the paper's design space
FIXED = {"porosity": 0.34, "rmin_mm": 0.8, "pb_fa_deg": 30.0, "fric": 0.4}
MODELS = {
    "ucs_MPa": RegressionModel("ucs_MPa", [("pb_coh_MPa",), ("pb_ten_MPa",), ("porosity",), ("pb_kratio",),
                                           ("pb_coh_MPa", "pb_ten_MPa")],
                               [1.2, 0.8, -300.0, -6.0, 0.02], 120.0),
    "E_GPa": RegressionModel("E_GPa", [("pb_emod_GPa",), ("pb_kratio",)], [1.29, -0.3], 0.2),
    "nu": RegressionModel("nu", [("pb_kratio",)], [0.04], 0.1),
}
TARGETS = {"ucs_MPa": 62.0, "E_GPa": 14.0, "nu": 0.24}


class BiasedDEM:
    """The regression model with multiplicative and additive bias plus 0.1 % noise."""

    def __init__(self, seed=0, noise=0.001):
        self.rng = np.random.default_rng(seed)
        self.noise = noise
        self.calls = []

    def __call__(self, params):
        self.calls.append(dict(params))
        m = {r: MODELS[r].predict(params) for r in MODELS}
        out = {"ucs_MPa": 1.12 * m["ucs_MPa"] - 4.0, "E_GPa": 0.9 * m["E_GPa"] + 0.6, "nu": 1.06 * m["nu"]}
        return {r: v * (1 + self.noise * self.rng.standard_normal()) for r, v in out.items()}


@pytest.fixture(scope="module")
def start():
    inv = invert(MODELS, TARGETS, FIXED, SearchSpace(ranges=T2), search=Multistart(seed=0))
    assert inv.ok
    return inv.solution


def test_converges_within_a_few_rounds(start):
    dem = BiasedDEM()
    res = ClosedLoop(dem,
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     models=MODELS).run(start)
    assert res.converged and res.n_rounds <= 4
    h = res.history
    assert h.loc[0, "max_abs_err"] > 0.05  # the bias is real: the regression answer is off
    assert h["max_abs_err"].iloc[-1] <= 0.01
    for r, t in TARGETS.items():  # recorded errors = (simulated - target) / target
        np.testing.assert_allclose(h[f"err_{r}"], (h[r] - t) / t, rtol=1e-12)
    assert len(dem.calls) == res.n_rounds
    for call in dem.calls:  # ratio constraint, fixed values and bounds hold in every round
        assert call["pb_ten_MPa"] == pytest.approx(1.4 * call["pb_coh_MPa"])
        assert {k: call[k] for k in FIXED} == FIXED
        assert 1.0 <= call["pb_kratio"] <= 5.0 and 10.0 <= call["pb_coh_MPa"] <= 50 / 1.4
    assert res.params == dem.calls[-1]


def test_broyden_update_satisfies_the_secant_condition(start):
    res = ClosedLoop(BiasedDEM(noise=0.0),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=1e-4, max_rounds=3),
                     models=MODELS).run(start)
    h = res.history
    assert h["broyden_update"].iloc[-1]
    free = list(res.jacobian.columns)
    dx = (h[free].iloc[-1] - h[free].iloc[-2]).to_numpy()
    dy = (h[list(TARGETS)].iloc[-1] - h[list(TARGETS)].iloc[-2]).to_numpy()
    np.testing.assert_allclose(res.jacobian.to_numpy() @ dx, dy, rtol=1e-8, atol=1e-12)


def test_unreachable_target_does_not_converge(start):
    res = ClosedLoop(BiasedDEM(),
                     {**TARGETS, "ucs_MPa": 400.0},
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(max_rounds=6),
                     models=MODELS).run(start)
    assert not res.converged and res.status in ("stalled", "max_rounds")
    assert "pb_coh_MPa" in res.message
    assert res.params["pb_coh_MPa"] <= 50 / 1.4 + 1e-9


def test_failed_simulation_stops_the_loop(start):
    broken = lambda p: {"ucs_MPa": np.nan, "E_GPa": 14.0, "nu": 0.2}
    res = ClosedLoop(broken,
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     models=MODELS).run(start)
    assert res.status == "failed" and res.n_rounds == 1


def test_explicit_jacobian_and_input_checks(start):
    J = pd.DataFrame(np.diag([1.3, 0.04, 2.0]), index=["E_GPa", "nu", "ucs_MPa"],
                     columns=["pb_emod_GPa", "pb_kratio", "pb_coh_MPa"])
    res = ClosedLoop(BiasedDEM(),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(max_rounds=12),
                     jacobian=J).run(start)
    assert res.converged
    with pytest.raises(ValueError, match="exactly one"):
        ClosedLoop(BiasedDEM(),
                   TARGETS,
                   space=SearchSpace(ranges=T2))
    with pytest.raises(ValueError, match="pb_ten_MPa"):
        ClosedLoop(BiasedDEM(),
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   models=MODELS).run({**start, "pb_ten_MPa": 20.0})


def test_the_scatter_table_flags_tolerances_below_noise():
    sims = pd.DataFrame({"ucs_MPa": [60.0, 62.0, 61.0, 63.0], "E_GPa": [14.0, 14.01, 13.99, 14.0],
                         "nu": [0.25, 0.26, 0.24, 0.25]})
    out = scatter_table(sims, rtol=0.01)
    cv = sims.std(ddof=1) / sims.mean()
    np.testing.assert_allclose(out["cv"], cv[list(out.index)], rtol=1e-12)
    assert out.loc["ucs_MPa", "noise_limited"] and not out.loc["E_GPa", "noise_limited"]
    four = scatter_table(sims, rtol=0.025, n_per_round=4)  # averaging 4 seeds halves the noise floor
    np.testing.assert_allclose(four["noise_floor"], out["noise_floor"] / 2)
    assert not four.loc["ucs_MPa", "noise_limited"]
    with pytest.raises(ValueError, match="at least 2"):
        scatter_table(sims.iloc[:1])


# -- seed-averaged loop ---------------------------------------------------------------------
#: planted packing-seed scatter (CV per response), as measured on the DEM at scale 0.4
SEED_CV = {"ucs_MPa": 0.03, "E_GPa": 0.015, "nu": 0.03}


def planted_truth(params):
    """The population mean of the synthetic DEM over packing seeds (no noise)."""
    m = {r: MODELS[r].predict(params) for r in MODELS}
    return {"ucs_MPa": 1.12 * m["ucs_MPa"] - 4.0, "E_GPa": 0.9 * m["E_GPa"] + 0.6, "nu": 1.06 * m["nu"]}


class SeedDEM:
    """The biased DEM whose every packing seed adds its own fixed relative offset (normal,
    CV ``SEED_CV``), the same for every parameter set - as a packing does; ``realisation``
    draws a new set of packings."""

    def __init__(self, realisation=0):
        self.realisation = realisation
        self.calls = []

    def offset(self, seed):
        g = np.random.default_rng([self.realisation, seed])
        return {r: SEED_CV[r] * g.standard_normal() for r in SEED_CV}

    def __call__(self, params, seed):
        self.calls.append((dict(params), seed))
        t, o = planted_truth(params), self.offset(seed)
        return {r: t[r] * (1 + o[r]) for r in t}


def _truth_errors(res):
    t = planted_truth(res.params)
    return np.array([t[r] / TARGETS[r] - 1 for r in TARGETS])


def test_seed_averaged_round_records_mean_cv_se_and_tolerance(start):
    dem = SeedDEM(3)
    res = ClosedLoop(dem,
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     models=MODELS).run(start)
    assert res.n_seeds == 3 and res.seeds == (1, 2, 3)  # the default: 3 seeds per round
    assert res.n_simulations == 3 * res.n_rounds == len(dem.calls)
    assert [s for _, s in dem.calls] == [1, 2, 3] * res.n_rounds  # the same seeds every round
    h, smp = res.history, res.samples
    pooled = np.zeros(len(TARGETS))
    for i, row in h.iterrows():
        ys = smp[smp["round"] == row["round"]]
        assert list(ys["seed"]) == [1, 2, 3] and row["n_seeds"] == 3
        for j, r in enumerate(TARGETS):
            v = ys[r].to_numpy()
            assert row[r] == pytest.approx(v.mean(), rel=1e-14)
            assert row[f"cv_{r}"] == pytest.approx(v.std(ddof=1) / v.mean(), rel=1e-12)
            pooled[j] += 2 * row[f"cv_{r}"] ** 2
            se = np.sqrt(pooled[j] / (2 * (i + 1))) / np.sqrt(3)  # pooled over the rounds so far
            assert row[f"se_{r}"] == pytest.approx(se, rel=1e-12)
            assert row[f"tol_{r}"] == pytest.approx(max(0.01, 2 * se), rel=1e-12)
            assert row[f"err_{r}"] == pytest.approx(row[r] / TARGETS[r] - 1, rel=1e-10, abs=1e-14)
    assert res.converged
    last = h.iloc[-1]
    assert all(abs(last[f"err_{r}"]) <= last[f"tol_{r}"] for r in TARGETS)
    assert res.responses == {r: last[r] for r in TARGETS}
    assert res.seed_cv == {r: last[f"cv_{r}"] for r in TARGETS}


def test_seed_averaged_loop_brackets_the_planted_truth_single_seed_does_not(start):
    """Over many sets of packings, the planted truth at the returned parameters lies within
    z standard errors of the reported mean in most cases (nominal ~90 % with the pooled
    SE's few degrees of freedom; 84 % measured over 100 sets), while the single-seed loop's
    'converged within 1 %' misses the truth whenever its one packing is off by more than
    that (CV 3 % here): its bracket holds almost never."""
    def coverage(k):
        inside = []
        for rs in range(60):
            res = ClosedLoop(SeedDEM(rs),
                             TARGETS,
                             space=SearchSpace(ranges=T2),
                             steps=LoopSteps(rtol=0.01, max_rounds=8),
                             seeding=LoopSeeds(seeds_per_round=k),
                             models=MODELS).run(start)
            h = res.history.set_index("round").loc[int(res.history["max_abs_err"].idxmin())]
            t = planted_truth(res.params)
            inside += [abs(res.responses[r] - t[r]) / TARGETS[r] <= 2 * h[f"se_{r}"] + 1e-15
                       for r in ("ucs_MPa", "nu")]
        return np.mean(inside)

    assert coverage(3) >= 0.75
    assert coverage(1) <= 0.05


def test_more_seeds_converge_closer_to_the_planted_truth(start):
    """The error of the planted truth at the returned parameters shrinks with the seeds per
    round (the loop fits the mean of k packings, not one packing)."""
    def errors(k):
        return np.array([_truth_errors(ClosedLoop(SeedDEM(rs),
                                                  TARGETS,
                                                  space=SearchSpace(ranges=T2),
                                                  steps=LoopSteps(rtol=0.01, max_rounds=8),
                                                  seeding=LoopSeeds(seeds_per_round=k),
                                                  models=MODELS).run(start))
                         for rs in range(150)])
    e1, e8 = errors(1), errors(8)
    rms1, rms8 = np.sqrt((e1 ** 2).mean(axis=0)), np.sqrt((e8 ** 2).mean(axis=0))
    ucs, nu = list(TARGETS).index("ucs_MPa"), list(TARGETS).index("nu")
    for j in (ucs, nu):  # CV 3 %: single seed 2.8 %, 8 seeds 1.1 % (measured, 200 sets)
        assert rms1[j] > 0.02
        assert rms8[j] < 0.6 * rms1[j]
        # the loop stops on entering the tolerance band from the side it started on, so
        # the mean error is not zero, but it stays inside rtol (0.35 % measured)
        assert abs(e8[:, j].mean()) < 0.01


def test_seed_arguments_are_checked():
    one_arg = lambda p: {"ucs_MPa": 1.0, "E_GPa": 1.0, "nu": 0.2}  # noqa: E731
    with pytest.raises(ValueError, match="takes no seed"):
        ClosedLoop(one_arg,
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   seeding=LoopSeeds(seeds_per_round=3),
                   models=MODELS)
    with pytest.raises(ValueError, match="takes no seed"):
        ClosedLoop(one_arg,
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   seeding=LoopSeeds(seeds=[1, 2]),
                   models=MODELS)
    assert ClosedLoop(one_arg,
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      models=MODELS).seeds == (None,)
    dem = SeedDEM()
    assert ClosedLoop(dem,
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      seeding=LoopSeeds(seeds=[7, 9]),
                      models=MODELS).seeds == (7, 9)
    assert ClosedLoop(dem,
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      seeding=LoopSeeds(seeds_per_round=5),
                      models=MODELS).seeds_per_round == 5
    for bad in (LoopSeeds(seeds_per_round=0), LoopSeeds(seeds_per_round=2.0),
                LoopSeeds(seeds=[1, 1]), LoopSeeds(seeds=[]), LoopSeeds(seeds=[1, -2]),
                LoopSeeds(seeds=[1, 2], seeds_per_round=3), LoopSeeds(max_seeds=0),
                LoopSeeds(max_seeds=4.0), LoopSeeds(max_seeds=True), LoopSeeds(max_seeds="10")):
        with pytest.raises(ValueError):
            ClosedLoop(dem, TARGETS, space=SearchSpace(ranges=T2), models=MODELS, seeding=bad)
    with pytest.raises(ValueError):
        ClosedLoop(dem, TARGETS, space=SearchSpace(ranges=T2), models=MODELS,
                   steps=LoopSteps(z=-1.0))


def test_a_failed_seed_fails_the_round_and_names_the_seed(start):
    def flaky(params, seed):
        out = planted_truth(params)
        return {**out, "ucs_MPa": np.nan} if seed == 2 else out
    res = ClosedLoop(flaky,
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     models=MODELS).run(start)
    assert res.status == "failed" and "seed 2" in res.message and res.n_rounds == 1
    assert len(res.samples) == 3


# -- bounds and a growing seed set ----------------------------------------------------------
def test_a_parameter_held_at_its_bound_lets_the_others_meet_their_targets(start):
    """ν = 0.34 needs pb_kratio > 5 (ν is at most 1.06 x 0.3 = 0.318 inside the ranges):
    the loop holds pb_kratio at its bound and solves the step for the other parameters, so
    σc and E still reach their targets; a Newton step for all three, cut at the bound
    afterwards, would keep moving them to make up for a kratio move that never happens."""
    targets = {**TARGETS, "nu": 0.34}
    res = ClosedLoop(BiasedDEM(noise=0.0),
                     targets,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     models=MODELS).run(start)
    assert not res.converged and res.status in ("max_rounds", "stalled")
    assert res.params["pb_kratio"] == pytest.approx(5.0)
    h = res.history
    assert h["clipped"].fillna("").str.contains("pb_kratio").any()
    last = h.iloc[-1]
    assert abs(last["err_ucs_MPa"]) <= 0.01 and abs(last["err_E_GPa"]) <= 0.01
    assert last["err_nu"] < -0.05  # the unreachable target is still reported as missed


def test_a_margin_lets_the_loop_follow_a_target_just_outside_the_design_space(start):
    """The same ν = 0.34 needs pb_kratio = (0.34 / 1.06 - 0.1) / 0.04 = 5.52: with the loop
    allowed a quarter of each range past the design space (pb_kratio up to 6) it converges
    there, and the result says which parameter left the sampled space; without the margin
    it is held at 5 (the test above)."""
    targets = {**TARGETS, "nu": 0.34}
    dem = BiasedDEM(noise=0.0)
    res = ClosedLoop(dem,
                     targets,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8, margin=0.25),
                     models=MODELS).run(start)
    assert res.converged
    assert res.params["pb_kratio"] == pytest.approx((0.34 / 1.06 - 0.1) / 0.04, rel=0.01)
    assert set(res.outside) == {"pb_kratio"}
    assert res.outside["pb_kratio"]["range"] == [1.0, 5.0]
    assert res.outside["pb_kratio"]["value"] == pytest.approx(res.params["pb_kratio"])
    lo, hi = res.loop_bounds["pb_kratio"]
    assert hi == pytest.approx(6.0) and 0 < lo < 1e-2  # 1 - 0.25 x 4 = 0 is not a ratio: kept > 0
    assert max(c["pb_kratio"] for c in dem.calls) <= 6.0 + 1e-12
    assert res.loop_bounds["pb_emod_GPa"] == pytest.approx((0.0 + 1e-3 * 40, 60.0))


def test_a_target_beyond_the_margin_is_held_at_the_widened_bound_and_named(start):
    targets = {**TARGETS, "nu": 0.37}  # pb_kratio 6.23 > 5 + 0.25 x 4
    res = ClosedLoop(BiasedDEM(noise=0.0),
                     targets,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8, margin=0.25),
                     models=MODELS).run(start)
    assert not res.converged
    assert res.params["pb_kratio"] == pytest.approx(6.0)
    last = res.history.iloc[-1]
    assert abs(last["err_ucs_MPa"]) <= 0.01 and abs(last["err_E_GPa"]) <= 0.01
    if res.status == "stalled":
        assert "widened by the margin 0.25" in res.message


def test_the_margin_never_widens_a_configured_narrowing(start):
    """``bounds`` are the user's limits, not the sampled space: the margin leaves them."""
    targets = {**TARGETS, "nu": 0.34}
    res = ClosedLoop(BiasedDEM(noise=0.0),
                     targets,
                     space=SearchSpace(ranges=T2, bounds={"pb_kratio": [1.0, 4.5]}),
                     steps=LoopSteps(rtol=0.01, max_rounds=8, margin=0.25),
                     models=MODELS).run(start)
    assert not res.converged
    assert res.params["pb_kratio"] == pytest.approx(4.5)
    assert res.loop_bounds["pb_kratio"][1] == pytest.approx(4.5)
    assert res.loop_bounds["pb_kratio"][0] < 1.0  # the lower side is still a design range


def test_a_start_outside_the_design_space_needs_the_margin(start):
    """A transfer starts from a verified card that may lie past a range (inside the margin)."""
    outside = {**start, "pb_kratio": 5.4}
    with pytest.raises(ValueError, match="pb_kratio=5.4 outside"):
        ClosedLoop(BiasedDEM(),
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   models=MODELS).run(outside)
    res = ClosedLoop(BiasedDEM(),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(max_rounds=1, margin=0.25),
                     models=MODELS).run(outside)
    assert res.history.loc[0, "pb_kratio"] == 5.4
    with pytest.raises(ValueError, match=r"outside \[0.8, 5.2\].*widened by the margin 0.05"):
        ClosedLoop(BiasedDEM(),
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   steps=LoopSteps(margin=0.05),
                   models=MODELS).run(outside)
    for bad in (-0.1, 1.5, float("nan"), True, "0.2"):
        with pytest.raises(ValueError, match="margin"):
            ClosedLoop(BiasedDEM(),
                       TARGETS,
                       space=SearchSpace(ranges=T2),
                       steps=LoopSteps(margin=bad),
                       models=MODELS)


class OffsetDEM(SeedDEM):
    """SeedDEM with the packing offsets planted seed by seed: seeds 1-3 sit 2 % high in
    every response on average, seeds 1-10 average exactly zero."""
    DEV = {1: 0.0, 2: 0.04, 3: 0.02, 4: -0.03, 5: -0.02, 6: -0.01, 7: 0.0, 8: -0.01,
           9: 0.01, 10: 0.0}

    def offset(self, seed):
        return {r: self.DEV[seed] for r in SEED_CV}


def test_a_grown_seed_set_removes_the_bias_of_the_first_seeds(start):
    assert np.mean([OffsetDEM.DEV[s] for s in (1, 2, 3)]) == pytest.approx(0.02)
    assert np.mean(list(OffsetDEM.DEV.values())) == pytest.approx(0.0, abs=1e-15)
    fixed = ClosedLoop(OffsetDEM(),
                       TARGETS,
                       space=SearchSpace(ranges=T2),
                       steps=LoopSteps(rtol=0.01, max_rounds=8),
                       models=MODELS).run(start)
    assert fixed.converged and fixed.n_seeds == 3
    # the three packings are fitted: the rock (planted truth) sits ~2 % below the targets
    assert all(-0.045 < e < -0.005 for e in _truth_errors(fixed))
    dem = OffsetDEM()
    grown = ClosedLoop(dem,
                       TARGETS,
                       space=SearchSpace(ranges=T2),
                       steps=LoopSteps(rtol=0.01, max_rounds=8),
                       seeding=LoopSeeds(max_seeds=10),
                       models=MODELS).run(start)
    assert grown.converged and grown.n_seeds == 10 and grown.seeds == tuple(range(1, 11))
    h = grown.history
    g = h.index[h["grown"] > 0]
    assert len(g) == 1 and h.loc[g[0], "grown"] == 7 and h.loc[g[0], "n_seeds"] == 10
    assert (h["n_seeds"].iloc[:g[0]] == 3).all() and (h["n_seeds"].iloc[g[0]:] == 10).all()
    calls = [s for _, s in dem.calls]  # seeds 4-10 first run at the grown round's point
    first = {s: calls.index(s) for s in range(4, 11)}
    assert calls[3 * g[0]: 3 * g[0] + 10] == [1, 2, 3, *range(4, 11)]
    assert min(first.values()) == 3 * g[0] + 3
    # the mean of all ten packings is the rock's: within the tolerance of the targets
    se = h.iloc[-1][[f"se_{r}" for r in TARGETS]].to_numpy(float)
    assert np.all(np.abs(_truth_errors(grown)) <= np.maximum(0.01, 2 * se) + 1e-12)


def test_growing_the_seed_set_brings_fresh_packings_closer_to_the_targets(start):
    """Over many sets of packings (CV 3 / 1.5 / 3 %), the loop that grows its three seeds to
    ten leaves the rock (planted truth) closer to the targets than the fixed three seeds
    (RMS error 1.74 / 1.23 / 1.59 % -> 1.08 / 0.63 / 1.10 % measured over 200 sets, at
    3.1 x the runs); the fixed ten seeds from the start cost about as much."""
    def errors(**kw):
        out, runs = [], []
        for rs in range(100):
            res = ClosedLoop(SeedDEM(rs),
                             TARGETS,
                             space=SearchSpace(ranges=T2),
                             steps=LoopSteps(rtol=0.01, max_rounds=8),
                             models=MODELS,
                             seeding=LoopSeeds(**kw)).run(start)
            out.append(_truth_errors(res))
            runs.append(res.n_simulations)
        return np.sqrt((np.array(out) ** 2).mean(axis=0)), np.mean(runs)
    rms3, runs3 = errors(seeds_per_round=3)
    rms10, runs10 = errors(seeds_per_round=3, max_seeds=10)
    assert np.all(rms10 < 0.8 * rms3)
    assert runs10 > runs3  # growth is paid for in runs


# -- polishing ------------------------------------------------------------------------------
class TinyScatterDEM(SeedDEM):
    """Three packings 0.1 % apart: the standard error (~0.06 %) is far below rtol, so the
    loop converges anywhere inside the 1 % band - here 0.39 % low in E."""
    DEV = {1: -0.001, 2: 0.001, 3: 0.0}

    def offset(self, seed):
        return {r: self.DEV[seed] for r in SEED_CV}


def test_a_converged_loop_polishes_towards_the_targets(start):
    plain = ClosedLoop(TinyScatterDEM(),
                       TARGETS,
                       space=SearchSpace(ranges=T2),
                       steps=LoopSteps(rtol=0.01, max_rounds=8, polish=False),
                       models=MODELS).run(start)
    assert plain.converged and "polish" not in plain.message
    assert np.max(np.abs(_truth_errors(plain))) > 0.003  # inside 1 %, but well off
    res = ClosedLoop(TinyScatterDEM(),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     models=MODELS).run(start)
    h = res.history
    assert res.converged and "polishing step" in res.message
    assert res.n_rounds == plain.n_rounds + 1 and res.best_round == res.n_rounds - 1
    assert list(h["polish"].iloc[:-1]) == [False] * (len(h) - 2) + [True]
    # the polishing step starts where the plain loop stopped, with a full Newton step
    conv = h.iloc[-2]
    assert all(conv[p] == pytest.approx(plain.params[p]) for p in ("pb_emod_GPa", "pb_kratio"))
    assert np.max(np.abs(_truth_errors(res))) < 0.1 * np.max(np.abs(_truth_errors(plain)))


def test_a_polishing_step_that_leaves_the_tolerance_keeps_the_converged_round(start):
    """E jumps by 3 % past pb_emod_GPa = 12.1 (between the converged point, 12.08, and
    the polished one, 12.12): the polished round misses E, so the card is the round before."""
    class Step(TinyScatterDEM):
        def __call__(self, params, seed):
            out = super().__call__(params, seed)
            if params["pb_emod_GPa"] > 12.1:
                out["E_GPa"] *= 1.03
            return out

    res = ClosedLoop(Step(),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     models=MODELS).run(start)
    h = res.history
    assert res.converged and res.best_round == len(h) - 2
    assert h["err_E_GPa"].iloc[-1] > 0.02 and bool(h["polish"].iloc[-2])
    assert res.params["pb_emod_GPa"] == pytest.approx(h["pb_emod_GPa"].iloc[-2])
    assert res.responses["E_GPa"] == pytest.approx(h["E_GPa"].iloc[-2])
    assert "left the tolerance in E_GPa" in res.message


def test_a_failed_polishing_round_leaves_the_converged_card(start):
    class Fails(TinyScatterDEM):
        def __call__(self, params, seed):
            out = super().__call__(params, seed)
            if params["pb_emod_GPa"] > 12.1 and seed == 2:  # the polished point only
                out["ucs_MPa"] = float("nan")
            return out

    res = ClosedLoop(Fails(),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     models=MODELS).run(start)
    h = res.history
    assert res.converged and res.best_round == len(h) - 2 and bool(h["polish"].iloc[-2])
    assert "polishing round" in res.message and "seed 2" in res.message
    assert res.params["pb_emod_GPa"] == pytest.approx(h["pb_emod_GPa"].iloc[-2])


def test_no_polishing_without_a_round_left_or_a_standard_error(start):
    last = ClosedLoop(TinyScatterDEM(),
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      steps=LoopSteps(rtol=0.01, max_rounds=3),
                      models=MODELS).run(start)  # converges in round 3 of 3
    assert last.converged and last.n_rounds == 3 and "polish" not in last.message
    one = ClosedLoop(BiasedDEM(),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     models=MODELS).run(start)  # one seed: no standard error to judge a miss by
    assert one.converged and not one.history["polish"].fillna(False).any()
    with pytest.raises(ValueError, match="polish"):
        ClosedLoop(BiasedDEM(),
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   steps=LoopSteps(polish="yes"),
                   models=MODELS)


def test_polishing_brings_the_rock_closer_to_the_targets(start):
    """Over 100 sets of packings (CV 3 / 1.5 / 3 %, seed set grown 3 -> 10 once within
    tolerance: grow_within 1), RMS error of the planted truth at the returned parameters
    1.24 / 0.67 / 1.20 % without polishing, 0.98 / 0.51 / 1.09 % with it (measured), for
    ~25 % more runs; the share of cards whose 5 fresh packings put every target within 2
    standard errors rises from 42 to 46 %."""
    def errors(polish):
        out, runs = [], []
        for rs in range(100):
            res = ClosedLoop(SeedDEM(rs),
                             TARGETS,
                             space=SearchSpace(ranges=T2),
                             steps=LoopSteps(rtol=0.01, max_rounds=8, polish=polish),
                             seeding=LoopSeeds(seeds_per_round=3, max_seeds=10, grow_within=1),
                             models=MODELS).run(start)
            out.append(_truth_errors(res))
            runs.append(res.n_simulations)
        return np.sqrt((np.array(out) ** 2).mean(axis=0)), np.mean(runs)
    rms0, runs0 = errors(False)
    rms1, runs1 = errors(True)
    assert np.all(rms1 < 0.95 * rms0)
    assert runs0 < runs1 < 1.5 * runs0


def test_growing_near_the_targets_brings_the_rock_closer_than_growing_at_them(start):
    """The same 100 sets of packings, no polishing: a seed set grown once every mean is
    within 2 tolerances (the default) steers the 10 seeds' mean for the last rounds, not
    the first 3 seeds': RMS error of the planted truth 1.05 / 0.66 / 1.09 % against
    1.24 / 0.67 / 1.20 % when it grows only within tolerance (measured), for ~8 % more
    runs."""
    def errors(grow_within):
        out, runs = [], []
        for rs in range(100):
            res = ClosedLoop(SeedDEM(rs),
                             TARGETS,
                             space=SearchSpace(ranges=T2),
                             steps=LoopSteps(rtol=0.01, max_rounds=8, polish=False),
                             seeding=LoopSeeds(seeds_per_round=3, max_seeds=10, grow_within=grow_within),
                             models=MODELS).run(start)
            assert res.converged
            out.append(_truth_errors(res))
            runs.append(res.n_simulations)
        return np.sqrt((np.array(out) ** 2).mean(axis=0)), np.mean(runs)
    at, runs_at = errors(1.0)
    near, runs_near = errors(2.0)
    assert np.all(near < at) and near[0] < 0.9 * at[0]  # sigma_c, the most scattered
    assert runs_at < runs_near < 1.25 * runs_at


class OffsetSeeds:
    """A rock whose responses do not depend on the card: every target times (1 + the
    seed's offset), ``offsets`` seed -> relative offset of sigma_c (E and nu: none)."""

    def __init__(self, offsets):
        self.offsets = offsets

    def __call__(self, params, seed):
        return {r: v * (1 + (self.offsets.get(seed, 0.0) if r == "ucs_MPa" else 0.0))
                for r, v in TARGETS.items()}


def test_the_seed_set_grows_within_grow_within_tolerances(start):
    """Round 1's 3 seeds read sigma_c +0.5, +2.0, +3.5 %: mean +2.0 %, SE 0.87 %,
    tolerance 2 SE = 1.73 %: 1.15 tolerances off. With grow_within 2 the seed set grows in
    round 1 (judged then on the 10 seeds, mean +0.6 %: converged); with 1 it does not."""
    dem = OffsetSeeds({1: 0.005, 2: 0.020, 3: 0.035})
    kw = dict(models=MODELS, space=SearchSpace(ranges=T2),
              steps=LoopSteps(rtol=0.01, max_rounds=2, polish=False))
    near = ClosedLoop(dem,
                      TARGETS,
                      seeding=LoopSeeds(grow_within=2.0, max_seeds=10),
                      **kw).run(start)
    h = near.history
    assert h["grown"].iloc[0] == 7 and h["n_seeds"].iloc[0] == 10
    assert near.converged and near.n_rounds == 1
    at = ClosedLoop(dem,
                    TARGETS,
                    seeding=LoopSeeds(grow_within=1.0, max_seeds=10),
                    **kw).run(start)
    assert at.history["grown"].iloc[0] == 0 and at.history["n_seeds"].iloc[0] == 3


@pytest.mark.parametrize("bad", [0.5, 0, -2, float("nan"), float("inf"), True, "2"])
def test_a_bad_grow_within_is_refused(start, bad):
    with pytest.raises(ValueError, match="grow_within"):
        ClosedLoop(SeedDEM(0),
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   seeding=LoopSeeds(grow_within=bad),
                   models=MODELS)


# -- four targets with a noisy sigma_t: weighted steps, trust region, probing ----------------
#: a planted sigma_t model and a 'DEM' whose strength balance differs from the regression's
#: (sigma_c gains from pb_ten, sigma_t from pb_coh): the loop must learn it from the runs
MODELS4 = {**MODELS, "bts_MPa": RegressionModel(
    "bts_MPa", [("pb_ten_MPa",), ("pb_coh_MPa",), ("pb_ten_MPa", "pb_coh_MPa")],
    [0.12, 0.15, 0.002], 1.0)}
CV4 = {"ucs_MPa": 0.025, "E_GPa": 0.01, "nu": 0.015, "bts_MPa": 0.08}
FREE4 = ["pb_emod_GPa", "pb_kratio", "pb_ten_MPa", "pb_coh_MPa"]
ROCK4 = {**FIXED, "pb_emod_GPa": 14.0, "pb_kratio": 3.2, "pb_ten_MPa": 30.0, "pb_coh_MPa": 20.0}


def truth4(p):
    m = {r: MODELS4[r].predict(p) for r in MODELS4}
    return {"ucs_MPa": 1.1 * m["ucs_MPa"] - 3 + 0.1 * p["pb_ten_MPa"], "E_GPa": 0.9 * m["E_GPa"] + 0.6,
            "nu": 1.06 * m["nu"], "bts_MPa": 0.85 * m["bts_MPa"] + 0.05 * p["pb_coh_MPa"]}


TARGETS4 = truth4(ROCK4)


class NoisyDEM:
    """Packing scatter per response (``CV4``; sigma_t's as a valid Brazilian disc's, ~8 %):
    a seed's offset is partly its own (correlation ``rho`` between parameter sets)."""

    def __init__(self, realisation, rho=0.8):
        self.r, self.rho = realisation, rho

    def __call__(self, params, seed):
        g = np.random.default_rng([self.r, seed])
        h = np.random.default_rng([self.r, seed, int(1e6 * sum(params.values())) % 2 ** 31])
        t = truth4(params)
        return {k: v * (1 + CV4[k] * (self.rho * g.standard_normal()
                                      + np.sqrt(1 - self.rho ** 2) * h.standard_normal()))
                for k, v in t.items()}


def _loop4(rs, seeding=LoopSeeds(seeds_per_round=3, max_seeds=10), **kw):
    start = {**FIXED, "pb_emod_GPa": 14.0 * 0.93, "pb_kratio": 3.2 * 1.08,
             "pb_ten_MPa": 30.0 * 1.12, "pb_coh_MPa": 20.0 * 0.9}
    steps = LoopSteps(**{"rtol": 0.01, "max_rounds": 8, **kw})
    return ClosedLoop(NoisyDEM(rs),
                      TARGETS4,
                      space=SearchSpace(ranges=T2, free=FREE4, ratio=None),
                      models=MODELS4,
                      steps=steps,
                      seeding=seeding).run(start)


def test_four_targets_with_a_noisy_sigma_t_converge(start):
    """sigma_c, E, nu and a sigma_t eight times noisier than E, both strengths free, the
    regression's strength balance wrong: the loop meets all four within max(rtol, 2 SE) in
    most realisations (45 of 50 measured with the weighted, trust-region steps and probing;
    the plain damped Gauss-Newton steps of before met 34)."""
    res = [_loop4(rs) for rs in range(50)]
    assert sum(r.converged for r in res) >= 40
    for r in res:
        if r.converged:
            h = r.history.iloc[r.best_round]
            assert all(abs(h[f"err_{k}"]) <= h[f"tol_{k}"] for k in TARGETS4)


def test_a_round_worse_than_the_best_is_not_stepped_from(start):
    """The trust region: after a round whose weighted misfit sum (e/tol)² exceeds the best
    round's, the next step starts from the best round, capped at half the rejected step."""
    seen = 0
    for rs in range(20):
        h = _loop4(rs).history
        merit = [float(np.sum([(row[f"err_{k}"] / row[f"tol_{k}"]) ** 2 for k in TARGETS4]))
                 for _, row in h.iterrows()]
        free_u = {p: T2[p] for p in FREE4}
        for i in range(1, len(h) - 1):
            if h.loc[i, "accepted"] is False or h.loc[i, "accepted"] == False:  # noqa: E712
                if h.loc[i, "n_seeds"] != h.loc[i - 1, "n_seeds"]:
                    continue
                seen += 1
                best = max(j for j in range(i) if h.loc[j, "accepted"])
                assert merit[i] > min(merit[j] for j in range(i) if h.loc[j, "n_seeds"]
                                      == h.loc[i, "n_seeds"]) - 1e-12
                # the next round lies within the halved cap of the best round
                rej = max(abs(h.loc[i, p] - h.loc[best, p]) / (free_u[p][1] - free_u[p][0])
                          for p in FREE4)
                nxt = max(abs(h.loc[i + 1, p] - h.loc[best, p]) / (free_u[p][1] - free_u[p][0])
                          for p in FREE4)
                assert nxt <= 0.5 * rej + 1e-9
                assert h.loc[i, "step_cap"] == pytest.approx(0.5 * rej)
    assert seen >= 3  # the rule was exercised


def test_a_parameter_held_at_its_bound_is_probed(start):
    """From a start at pb_ten's lower bound (where a wrong regression put it), the steps
    hold pb_ten there - its column of the Jacobian is the regression's, never measured -
    though the rock needs more: after two rounds at the bound the step moves it into the
    box, and the loop then meets all four targets (at pb_ten 10 it cannot: sigma_t stays
    10 % high, measured)."""
    s = {**FIXED, "pb_emod_GPa": 13.2, "pb_kratio": 3.4, "pb_ten_MPa": 10.0, "pb_coh_MPa": 39.7}
    res = ClosedLoop(NoisyDEM(0, rho=1.0),
                     TARGETS4,
                     space=SearchSpace(ranges=T2, free=FREE4, ratio=None),
                     steps=LoopSteps(rtol=0.01, max_rounds=10),
                     seeding=LoopSeeds(seeds_per_round=3, max_seeds=10),
                     models=MODELS4).run(s)
    h = res.history
    probed = h.index[h["probed"].fillna("").str.contains("pb_ten_MPa")]
    assert len(probed) >= 1
    i = probed[0]
    assert (h.loc[:i, "pb_ten_MPa"] == 10.0).all() and h.loc[i + 1, "pb_ten_MPa"] > 10.0
    assert res.converged and res.params["pb_ten_MPa"] > 12.0


# -- the Jacobian and the trust region under noise -----------------------------------------
def _loop_for_broyden():
    loop = ClosedLoop(SeedDEM(),
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      seeding=LoopSeeds(seeds_per_round=4),
                      models=MODELS)
    return loop, np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def test_a_change_within_its_noise_barely_moves_the_jacobian_row():
    """Two rounds on the same 4 seeds: ucs changes by 5 % in every seed (no scatter in the
    change: its row takes the full secant), nu changes by +6, -6, +6, -6 % (mean 0, paired
    SE 3.5 %: a residual of -1.2 % is mostly noise, its row moves by ~10 % of the secant)."""
    loop, J = _loop_for_broyden()
    t = np.abs(loop.t)
    prev_ys = np.tile(t, (4, 1))
    ys = prev_ys.copy()
    ys[:, list(loop.responses).index("ucs_MPa")] *= 1.05
    i_nu = list(loop.responses).index("nu")
    ys[:, i_nu] *= 1 + np.array([0.06, -0.06, 0.06, -0.06]) + 0.0
    u0, u1 = np.array([0.3, 0.3, 0.3]), np.array([0.3, 0.3, 0.312])
    e0 = prev_ys.mean(axis=0) / t - 1
    e1 = ys.mean(axis=0) / t - 1
    J1, rows = loop.step_rule.broyden_update(J, (u0, e0, prev_ys), u1, e1, ys)
    s = u1 - u0
    i_ucs = list(loop.responses).index("ucs_MPa")
    full = J + np.outer((e1 - e0) - J @ s, s) / (s @ s)  # the plain Broyden update
    np.testing.assert_allclose(J1[i_ucs], full[i_ucs], rtol=1e-9)  # the signal: all of it
    moved = np.abs(J1[i_nu] - J[i_nu]).max() / np.abs(full[i_nu] - J[i_nu]).max()
    assert 0.0 < moved < 0.15  # the noise: a small part
    assert "ucs_MPa" in rows and "nu" not in rows
    # one seed: no standard error, the plain update
    e1_one = ys[0] / t - 1
    J2, rows2 = loop.step_rule.broyden_update(J, (u0, e0, prev_ys[:1]), u1, e1_one, ys[:1])
    np.testing.assert_allclose(J2, J + np.outer((e1_one - e0) - J @ s, s) / (s @ s))
    assert rows2 == list(loop.responses)  # no standard error: every row, fully
    # other seeds (a grown set): no update
    assert loop.step_rule.broyden_update(J, (u0, e0, prev_ys[:3]), u1, e1, ys)[1] == []


def test_the_trust_region_grows_again_after_good_capped_steps():
    """The rule, round by round: a worse round halves the cap (to half the step that led
    to it); a better round reached by a step the cap cut doubles it, up to max_step; a
    better round reached by a smaller step leaves it."""
    from bpmcal.analysis.calibration.seed_policy import Round
    from bpmcal.analysis.calibration.step_rule import TrustRegion

    loop = ClosedLoop(SeedDEM(),
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      steps=LoopSteps(max_step=0.2),
                      seeding=LoopSeeds(seeds_per_round=3),
                      models=MODELS)
    space = loop._space({**FIXED, "pb_emod_GPa": 14.0, "pb_kratio": 3.0,
                         "pb_coh_MPa": 20.0, "pb_ten_MPa": 28.0})
    box = space.loop_box(0.0)
    J = np.eye(3)
    trust = TrustRegion(0.2, 3)
    tol = np.full(3, 0.01)

    def rnd(u, err):
        e = np.full(3, err)
        rec = {}
        _, u_new = loop.step_rule.next_point(space, box, J, np.array(u), Round(
            np.zeros((3, 3)), [1, 2, 3], [], 0, [], None, None, None, tol, e), False, trust, rec)
        return rec, u_new

    rec, _ = rnd([0.5, 0.5, 0.2], 0.5)  # the first round: the base
    assert rec["accepted"] and trust.cap == 0.2
    rec, _ = rnd([0.5, 0.5, 0.4], 0.8)  # worse, after a step of 0.2: cut to 0.1
    assert not rec["accepted"] and trust.cap == pytest.approx(0.1)
    rec, _ = rnd([0.5, 0.5, 0.3], 0.3)  # better, by a step of 0.1 = the cap: doubled
    assert rec["accepted"] and trust.cap == pytest.approx(0.2)
    rec, _ = rnd([0.5, 0.5, 0.5], 0.2)  # better, by 0.2 = the cap, at max_step: stays
    assert rec["accepted"] and trust.cap == pytest.approx(0.2)
    rec, _ = rnd([0.5, 0.5, 0.6], 0.5)  # worse, by 0.1: cut to 0.05
    assert not rec["accepted"] and trust.cap == pytest.approx(0.05)
    rec, _ = rnd([0.5, 0.5, 0.52], 0.1)  # better, by 0.02 < the cap: it stays
    assert rec["accepted"] and trust.cap == pytest.approx(0.05)


def test_a_target_with_its_own_standard_error_is_met_within_both_errors(start):
    """The lab value is a mean too (target_se): the rock itself (the planted truth),
    measured on three packings 0.1 % apart, is 3 % off a sigma_c target whose standard error
    is 2 %: within max(1 %, 2 sqrt(SE² + 2 %²)) at once, while an exact target sends the
    loop away from the rock to fit that 3 %."""
    truth = dict(start)
    t = planted_truth(truth)
    targets = {**t, "ucs_MPa": 1.03 * t["ucs_MPa"]}
    se = {"ucs_MPa": 0.02 * targets["ucs_MPa"]}

    def loop(**kw):
        return ClosedLoop(TinyScatterDEM(),
                          targets,
                          space=SearchSpace(ranges=T2),
                          steps=LoopSteps(rtol=0.01, max_rounds=4, polish=False),
                          models=MODELS,
                          **kw).run(truth)

    both = loop(target_se=se)
    h = both.history
    assert both.converged and both.n_rounds == 1
    assert h.loc[0, "tol_ucs_MPa"] == pytest.approx(
        2 * np.hypot(h.loc[0, "se_ucs_MPa"], 0.02), rel=1e-9)
    exact = loop()
    assert exact.history.loc[0, "tol_ucs_MPa"] == pytest.approx(0.01)
    assert exact.n_rounds > 1 and exact.params != truth
    with pytest.raises(ValueError, match="target_se.ucs_MPa"):
        ClosedLoop(TinyScatterDEM(),
                   targets,
                   space=SearchSpace(ranges=T2),
                   models=MODELS,
                   target_se={"ucs_MPa": -1.0})
    with pytest.raises(ValueError, match="'bts_MPa' is not a target"):
        ClosedLoop(TinyScatterDEM(),
                   targets,
                   space=SearchSpace(ranges=T2),
                   models=MODELS,
                   target_se={"bts_MPa": 1.0})


# -- the history update: every judged round at once -----------------------------------------
def _judged(e, se):
    """A judged round with relative errors ``e`` and standard errors ``se`` (tolerance 2 SE,
    at least 1 %), as :meth:`SeedPolicy.run_round` returns it."""
    from bpmcal.analysis.calibration.seed_policy import Round

    e, se = np.asarray(e, float), np.asarray(se, float)
    return Round(np.zeros((3, len(e))), [1, 2, 3], [], 0, [], e, np.zeros(len(e)), se,
                  np.maximum(0.01, 2 * se), e)


def test_history_update_recovers_a_linear_response_once_the_steps_span_the_space():
    """A linear simulator without noise (SE 1e-6), n + 1 rounds whose steps span the n parameters: the
    fit is the true Jacobian, whatever the (wrong) starting estimate; Broyden, from the same
    rounds taken in turn, is not (it knows the last step's secant only)."""
    loop = ClosedLoop(SeedDEM(),
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      steps=LoopSteps(update="history"),
                      seeding=LoopSeeds(seeds_per_round=3),
                      models=MODELS)
    rng = np.random.default_rng(5)
    J_true = rng.normal(size=(3, 3))
    J0 = J_true + rng.normal(scale=0.8, size=(3, 3))
    us = [np.array([0.4, 0.5, 0.5]), np.array([0.5, 0.5, 0.5]), np.array([0.45, 0.6, 0.5]),
          np.array([0.45, 0.55, 0.42])]
    memory = [(u, _judged(J_true @ (u - 0.5) + 0.02, np.full(3, 1e-6))) for u in us]
    (_, _, J), moved = loop.step_rule.history_jacobian(J0, memory)
    np.testing.assert_allclose(J, J_true, atol=2e-3)
    assert set(moved) <= set(loop.responses)
    Jb = J0
    for (u0, r0), (u1, r1) in zip(memory, memory[1:]):
        Jb, _ = loop.step_rule.broyden_update(Jb, (u0, r0.e, r0.ys), u1, r1.e, r1.ys)
    assert np.abs(Jb - J_true).max() > 0.1


def test_history_update_of_two_rounds_is_broydens_least_change_update():
    """Two rounds, no noise (SE 1e-6): the secant condition holds and the change of each row lies
    along the step (Broyden's least-change update from the starting estimate)."""
    loop = ClosedLoop(SeedDEM(),
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      steps=LoopSteps(update="history"),
                      seeding=LoopSeeds(seeds_per_round=3),
                      models=MODELS)
    J0 = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.3], [0.1, 0.0, 1.0]])
    u0, u1 = np.array([0.5, 0.5, 0.5]), np.array([0.55, 0.47, 0.5])
    e0, e1 = np.array([0.1, -0.05, 0.08]), np.array([0.02, 0.01, 0.2])
    (_, _, J), _ = loop.step_rule.history_jacobian(J0, [(u0, _judged(e0, np.full(3, 1e-6))),
                                                        (u1, _judged(e1, np.full(3, 1e-6)))])
    s = u1 - u0
    np.testing.assert_allclose(J @ s, e1 - e0, atol=1e-4)
    broyden = J0 + np.outer((e1 - e0) - J0 @ s, s) / (s @ s)
    np.testing.assert_allclose(J, broyden, atol=1e-3)


def test_history_update_weighs_each_round_by_its_noise():
    """A change within its response's scatter barely moves the row; the same change
    measured precisely moves it fully."""
    loop = ClosedLoop(SeedDEM(),
                      TARGETS,
                      space=SearchSpace(ranges=T2),
                      steps=LoopSteps(update="history"),
                      seeding=LoopSeeds(seeds_per_round=3),
                      models=MODELS)
    J0 = np.eye(3)
    u0, u1 = np.array([0.5, 0.5, 0.5]), np.array([0.5, 0.5, 0.52])
    e0, e1 = np.zeros(3), np.array([0.0, 0.0, 0.05])  # the third: 2.5 per unit, not 1
    quiet = loop.step_rule.history_jacobian(J0, [(u0, _judged(e0, np.full(3, 1e-4))),
                                                 (u1, _judged(e1, np.full(3, 1e-4)))])[0][2]
    noisy = loop.step_rule.history_jacobian(J0, [(u0, _judged(e0, np.full(3, 0.05))),
                                                 (u1, _judged(e1, np.full(3, 0.05)))])[0][2]
    assert quiet[2, 2] == pytest.approx(2.5, rel=1e-3)
    # the secant's slope 2.5 has variance 2 · 0.05² / 0.02² = 12.5 against the prior's 1²:
    # the posterior moves 1 / 13.5 of the way
    assert noisy[2, 2] == pytest.approx(1.0 + 1.5 / 13.5, rel=1e-3)


def test_history_loop_converges_on_the_biased_dem(start):
    res = ClosedLoop(BiasedDEM(),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8, update="history"),
                     models=MODELS).run(start)
    assert res.converged and res.n_rounds <= 4
    assert res.history.loc[0, "max_abs_err"] > 0.05


def test_unknown_update_rule_is_refused():
    with pytest.raises(ValueError, match="update='secant'"):
        ClosedLoop(SeedDEM(),
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   steps=LoopSteps(update="secant"),
                   models=MODELS)


def test_every_judged_round_is_reported(start):
    """A loop whose rounds take minutes tells its progress: one line per round with every
    response's error and tolerance."""
    lines = []
    res = ClosedLoop(BiasedDEM(),
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     models=MODELS,
                     report=lines.append).run(start)
    assert len(lines) == res.n_rounds
    h = res.history
    for i, ln in enumerate(lines):
        assert ln.startswith(f"closed loop round {i + 1} (1 seed): ")
        assert f"ucs_MPa {100 * h['err_ucs_MPa'].iloc[i]:+.1f} %" in ln
    assert lines[-1].endswith("3 of 3 within tolerance")


def test_a_rounds_seeds_run_at_once_take_the_same_path(start):
    """simulate_seeds (a round's seeds in one call, e.g. side by side on several CPUs)
    gives the loop the same rounds, steps, seed growth and card as one seed at a time."""
    kw = dict(models=MODELS, steps=LoopSteps(rtol=0.01, max_rounds=8), space=SearchSpace(ranges=T2),
              seeding=LoopSeeds(seeds_per_round=3, max_seeds=10))
    one = ClosedLoop(SeedDEM(2), TARGETS, **kw).run(start)
    dem, batches = SeedDEM(2), []

    def at_once(params, seeds):
        batches.append(list(seeds))
        return [dem(params, s) for s in seeds]

    many = ClosedLoop(lambda p, seed: pytest.fail("one seed asked for"), TARGETS,
                      simulate_seeds=at_once, **kw).run(start)
    pd.testing.assert_frame_equal(many.history, one.history)
    assert many.params == one.params and many.seeds == one.seeds
    assert batches[0] == [1, 2, 3] and len(batches) == len(one.history) + (one.seeds != (1, 2, 3))
    assert one.seeds == tuple(range(1, 11))  # the seed set grew: its new seeds in one call too
    assert [4, 5, 6, 7, 8, 9, 10] in batches
    with pytest.raises(ValueError, match="returned 1 result.s. for 3 seed"):
        ClosedLoop(SeedDEM(2), TARGETS, simulate_seeds=lambda p, s: [{}], **kw).run(start)


class CappedDEM(SeedDEM):
    """SeedDEM that, like the stage's loop, does not run the costly test of ``resp`` past
    the first ``cap`` seeds of the set (returns NaN there) and records what it was asked."""

    def __init__(self, realisation=0, resp="ucs_MPa", cap=4, first=1):
        super().__init__(realisation)
        self.resp, self.cap, self.first = resp, cap, first

    def __call__(self, params, seed):
        out = super().__call__(params, seed)
        if seed - self.first >= self.cap:
            out[self.resp] = np.nan
        return out


def test_a_seed_cap_judges_that_response_on_its_first_seeds_only(start):
    """With max_seeds 10 and ucs_MPa capped at 4: a grown round's ucs_MPa mean, CV and
    standard error are those of its first four seeds (the NaN the simulator returns past
    the cap is no failure), every other response is judged on all ten, and the history
    records the capped response's seed count."""
    dem = CappedDEM(5)
    res = ClosedLoop(dem,
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     steps=LoopSteps(rtol=0.01, max_rounds=8),
                     seeding=LoopSeeds(max_seeds=10, seed_caps={"ucs_MPa": 4}),
                     models=MODELS).run(start)
    assert res.status != "failed"
    h, smp = res.history, res.samples
    grown = h[h["n_seeds"] == 10]
    assert len(grown), "the seed set grew"
    assert (h["n_ucs_MPa"] == np.minimum(h["n_seeds"], 4)).all()
    pooled, dof = np.zeros(len(TARGETS)), np.zeros(len(TARGETS))
    for _, row in h.iterrows():
        ys = smp[smp["round"] == row["round"]]
        for j, r in enumerate(TARGETS):
            v = ys[r].to_numpy(float)[: (4 if r == "ucs_MPa" else len(ys))]
            assert np.isfinite(v).all()
            assert row[r] == pytest.approx(v.mean(), rel=1e-12)
            cv = v.std(ddof=1) / v.mean()
            assert row[f"cv_{r}"] == pytest.approx(cv, rel=1e-9)
            pooled[j] += (len(v) - 1) * cv ** 2
            dof[j] += len(v) - 1
            se = np.sqrt(pooled[j] / dof[j]) / np.sqrt(len(v))
            assert row[f"se_{r}"] == pytest.approx(se, rel=1e-9)
        # past the cap the samples hold NaN for the capped response, never a value
        assert ys["ucs_MPa"].iloc[4:].isna().all() and ys["E_GPa"].notna().all()


def test_a_seed_cap_does_not_grow_the_set_for_the_capped_response(start):
    """A seed set grows only for a response a grown set measures on more seeds: when only
    the capped response's standard error is too large, the set stays; without the cap the
    same loop grows it."""
    def dem(params, seed):  # ucs scatters 6 %, E and nu do not at all
        t = planted_truth(params)
        g = np.random.default_rng([11, seed]).standard_normal()
        return {**t, "ucs_MPa": t["ucs_MPa"] * (1 + 0.06 * g)}

    kw = dict(models=MODELS, steps=LoopSteps(rtol=0.02, max_rounds=8), space=SearchSpace(ranges=T2))
    free = ClosedLoop(dem, TARGETS, seeding=LoopSeeds(max_seeds=10), **kw).run(start)
    capped = ClosedLoop(dem,
                        TARGETS,
                        seeding=LoopSeeds(seed_caps={"ucs_MPa": 3}, max_seeds=10),
                        **kw).run(start)
    assert free.history["grown"].sum() > 0
    assert capped.history["grown"].sum() == 0 and (capped.history["n_seeds"] == 3).all()


def test_a_failed_run_within_the_cap_still_fails_the_round(start):
    def dem(params, seed):
        out = planted_truth(params)
        return {**out, "ucs_MPa": np.nan} if seed == 2 else out
    res = ClosedLoop(dem,
                     TARGETS,
                     space=SearchSpace(ranges=T2),
                     seeding=LoopSeeds(seed_caps={"ucs_MPa": 2}),
                     models=MODELS).run(start)
    assert res.status == "failed" and "seed 2" in res.message


def test_bad_seed_caps_are_refused(start):
    for bad in ({"sigma_t": 3}, {"ucs_MPa": 0}, {"ucs_MPa": 2.5}, {"ucs_MPa": True}, [3]):
        with pytest.raises(ValueError, match="seed_caps"):
            ClosedLoop(SeedDEM(),
                       TARGETS,
                       space=SearchSpace(ranges=T2),
                       seeding=LoopSeeds(seed_caps=bad),
                       models=MODELS)


# -- the starting Jacobian's signs ---------------------------------------------------------
#: a quadratic sigma_c that turns over inside the design range (its vertex in pb_coh at
#: 40 MPa): the shape a regression of a strength that saturates takes
TURNED = {**MODELS4, "ucs_MPa": RegressionModel(
    "ucs_MPa", [("pb_ten_MPa",), ("pb_coh_MPa",), ("pb_coh_MPa", "pb_coh_MPa")],
    [1.2, 2.0, -0.025], 10.0)}


def test_a_strength_falling_with_a_bond_strength_starts_the_loop_flat():
    """Past the vertex the regression's ∂σc/∂τcp is negative; the loop starts from 0 there
    (a stronger bond never weakens the specimen), lists it, and reports it; the stiffness
    rows and a Jacobian given by the caller (measured by an earlier loop) keep their
    signs."""
    s = {**FIXED, "pb_emod_GPa": 14.0, "pb_kratio": 3.2, "pb_ten_MPa": 30.0, "pb_coh_MPa": 45.0}
    assert TURNED["ucs_MPa"].gradient(s)["pb_coh_MPa"] < 0
    notes = []
    loop = ClosedLoop(NoisyDEM(0),
                      TARGETS4,
                      space=SearchSpace(ranges=T2, free=FREE4, ratio=None),
                      steps=LoopSteps(max_rounds=1),
                      seeding=LoopSeeds(seeds_per_round=3),
                      models=TURNED,
                      report=notes.append)
    space = loop._space(s)
    J = loop._initial_jacobian(space, space.x(space.u(space.free_values(s))))
    i, j = list(loop.responses).index("ucs_MPa"), list(space.free).index("pb_coh_MPa")
    assert J[i, j] == 0.0
    assert [(h["response"], h["parameter"]) for h in loop.sign_held] == [("ucs_MPa", "pb_coh_MPa")]
    assert loop.sign_held[0]["regression"] == pytest.approx(TURNED["ucs_MPa"].gradient(s)["pb_coh_MPa"])
    assert "ucs_MPa against pb_coh_MPa" in notes[0]
    res = loop.run(s)
    assert res.sign_held == loop.sign_held
    # E falls with kp* in the regression: not a strength, kept
    k = list(space.free).index("pb_kratio")
    assert J[list(loop.responses).index("E_GPa"), k] < 0
    # the same slopes given as a Jacobian: measured, not held
    jac = pd.DataFrame({p: [TURNED[r].gradient(s).get(p, 0.0) for r in TARGETS4] for p in FREE4},
                       index=list(TARGETS4))
    given = ClosedLoop(NoisyDEM(0),
                       TARGETS4,
                       space=SearchSpace(ranges=T2, free=FREE4, ratio=None),
                       steps=LoopSteps(max_rounds=1),
                       seeding=LoopSeeds(seeds_per_round=3),
                       jacobian=jac)
    Jg = given._initial_jacobian(space, space.x(space.u(space.free_values(s))))
    assert Jg[i, j] < 0 and given.sign_held == []




def test_the_auto_budget_is_two_rounds_per_free_parameter(start):
    """max_rounds "auto" (the default) gives a loop that never meets its tolerance 6
    rounds with the paper's three free parameters and 8 with both strengths free; the
    result states the budget. On the four-target synthetic rock above, 6 rounds met the
    targets in 40 of 50 realisations, 8 in 46 (docs/calibration.md)."""
    dem = BiasedDEM()
    three = ClosedLoop(dem,
                       TARGETS,
                       space=SearchSpace(ranges=T2),
                       steps=LoopSteps(rtol=1e-7),
                       models=MODELS).run(start)
    assert three.status == "max_rounds" and three.n_rounds == 6 == three.max_rounds
    assert len(dem.calls) == 6 and "within 6 rounds" in three.message
    four = _loop4(0, LoopSeeds(seeds_per_round=1), rtol=1e-7, max_rounds="auto")
    assert four.status == "max_rounds" and four.n_rounds == 8 == four.max_rounds
    assert len(four.jacobian.columns) == 4
    fixed = ClosedLoop(BiasedDEM(),
                       TARGETS,
                       space=SearchSpace(ranges=T2),
                       steps=LoopSteps(rtol=1e-7, max_rounds=3),
                       models=MODELS).run(start)
    assert fixed.n_rounds == 3 == fixed.max_rounds


@pytest.mark.parametrize("bad", ["Auto", "", 0, -2, 2.5, True, None, 51])
def test_a_bad_round_budget_is_refused_naming_it(bad):
    """ClosedLoop checks its keywords as LoopSettings checks its fields: one set of limits
    (the round budget at most bpmcal.analysis.calibration.loop_settings.MAX_ROUNDS)."""
    with pytest.raises(ValueError, match=r"max_rounds=.*expected an integer in 1 \.\. 50, "
                                         "or 'auto'"):
        ClosedLoop(BiasedDEM(),
                   TARGETS,
                   space=SearchSpace(ranges=T2),
                   steps=LoopSteps(max_rounds=bad),
                   models=MODELS)
