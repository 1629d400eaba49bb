"""Closed-loop correction against a synthetic "DEM" = regression model with a known bias."""
import numpy as np
import pandas as pd
import pytest

from bpmcal.analysis.calibration import ClosedLoop, invert, seed_scatter
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
    inv = invert(MODELS, TARGETS, FIXED, seed=0, ranges=T2)
    assert inv.ok
    return inv.solution


def test_converges_within_a_few_rounds(start):
    dem = BiasedDEM()
    res = ClosedLoop(dem, TARGETS, models=MODELS, rtol=0.01, max_rounds=8, ranges=T2).run(start)
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
    res = ClosedLoop(BiasedDEM(noise=0.0), TARGETS, models=MODELS, rtol=1e-4, max_rounds=3,
                     ranges=T2).run(start)
    h = res.history
    assert h["broyden_update"].iloc[-1]
    free = list(res.jacobian.columns)
    dx = (h[free].iloc[-1] - h[free].iloc[-2]).to_numpy()
    dy = (h[list(TARGETS)].iloc[-1] - h[list(TARGETS)].iloc[-2]).to_numpy()
    np.testing.assert_allclose(res.jacobian.to_numpy() @ dx, dy, rtol=1e-8, atol=1e-12)


def test_unreachable_target_does_not_converge(start):
    res = ClosedLoop(BiasedDEM(), {**TARGETS, "ucs_MPa": 400.0}, models=MODELS, max_rounds=6,
                     ranges=T2).run(start)
    assert not res.converged and res.status in ("stalled", "max_rounds")
    assert "pb_coh_MPa" in res.message
    assert res.params["pb_coh_MPa"] <= 50 / 1.4 + 1e-9


def test_failed_simulation_stops_the_loop(start):
    broken = lambda p: {"ucs_MPa": np.nan, "E_GPa": 14.0, "nu": 0.2}
    res = ClosedLoop(broken, TARGETS, models=MODELS, ranges=T2).run(start)
    assert res.status == "failed" and res.n_rounds == 1


def test_explicit_jacobian_and_input_checks(start):
    J = pd.DataFrame(np.diag([1.3, 0.04, 2.0]), index=["E_GPa", "nu", "ucs_MPa"],
                     columns=["pb_emod_GPa", "pb_kratio", "pb_coh_MPa"])
    res = ClosedLoop(BiasedDEM(), TARGETS, jacobian=J, max_rounds=12, ranges=T2).run(start)
    assert res.converged
    with pytest.raises(ValueError, match="exactly one"):
        ClosedLoop(BiasedDEM(), TARGETS, ranges=T2)
    with pytest.raises(ValueError, match="pb_ten_MPa"):
        ClosedLoop(BiasedDEM(), TARGETS, models=MODELS, ranges=T2).run({**start, "pb_ten_MPa": 20.0})


def test_seed_scatter_flags_tolerances_below_noise():
    sims = pd.DataFrame({"ucs_MPa": [60.0, 62.0, 61.0, 63.0], "E_GPa": [14.0, 14.01, 13.99, 14.0],
                         "nu": [0.25, 0.26, 0.24, 0.25]})
    out = seed_scatter(sims, rtol=0.01)
    cv = sims.std(ddof=1) / sims.mean()
    np.testing.assert_allclose(out["cv"], cv[list(out.index)], rtol=1e-12)
    assert out.loc["ucs_MPa", "noise_limited"] and not out.loc["E_GPa", "noise_limited"]
    four = seed_scatter(sims, rtol=0.025, n_per_round=4)  # averaging 4 seeds halves the noise floor
    np.testing.assert_allclose(four["noise_floor"], out["noise_floor"] / 2)
    assert not four.loc["ucs_MPa", "noise_limited"]
    with pytest.raises(ValueError, match="at least 2"):
        seed_scatter(sims.iloc[:1])
