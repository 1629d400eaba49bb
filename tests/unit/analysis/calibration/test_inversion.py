"""Inversion of known regression models."""
import numpy as np
import pytest

from bpmcal.analysis.calibration import Multistart, SearchSpace, invert
from bpmcal.analysis.stepwise import RegressionModel
from bpmcal.params import ParameterError, table2_ranges

T2 = table2_ranges()  # the paper's design space
FIXED = {"porosity": 0.34, "rmin_mm": 0.8, "pb_fa_deg": 30.0, "fric": 0.4}
TRUTH = {"pb_emod_GPa": 20.0, "pb_kratio": 2.5, "pb_coh_MPa": 25.0}


def known_models(nu_quadratic=False):
    """Paper-like models with an interaction, in paper units."""
    ucs = RegressionModel("ucs_MPa", [("pb_coh_MPa",), ("pb_ten_MPa",), ("porosity",), ("pb_kratio",),
                                      ("pb_coh_MPa", "pb_ten_MPa")],
                          [1.2, 0.8, -300.0, -6.0, 0.02], 120.0)
    E = RegressionModel("E_GPa", [("pb_emod_GPa",), ("pb_kratio",)], [1.29, -0.3], 0.2)
    if nu_quadratic:  # maximum at kp* = 3: nu(3 ± 1) = 0.28
        nu = RegressionModel("nu", [("pb_kratio",), ("pb_kratio", "pb_kratio")], [0.12, -0.02], 0.12)
    else:
        nu = RegressionModel("nu", [("pb_kratio",)], [0.04], 0.1)
    return {"ucs_MPa": ucs, "E_GPa": E, "nu": nu}


def targets_at(models, params):
    return {r: m.predict(params) for r, m in models.items()}


def test_recovers_planted_parameters_with_ratio():
    models = known_models()
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 1.4 * TRUTH["pb_coh_MPa"]}
    res = invert(models,
                 targets_at(models, truth),
                 FIXED,
                 SearchSpace(ranges=T2),
                 search=Multistart(seed=3))
    assert res.status == "ok" and res.ok and res.unique
    for p, v in truth.items():
        np.testing.assert_allclose(res.solution[p], v, rtol=1e-7, err_msg=p)
    assert res.max_abs_residual < 1e-9
    assert res.bounds["pb_coh_MPa"] == pytest.approx((10.0, 50.0 / 1.4))
    assert res.to_frame().loc["pb_ten_MPa", "role"] == "derived"


def test_free_strengths_give_a_flagged_continuum():
    models = known_models()
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 30.0}
    res = invert(models,
                 targets_at(models, truth),
                 FIXED,
                 SearchSpace(ranges=T2, ratio=None),
                 search=Multistart(seed=3))
    assert res.status == "non-unique" and not res.ok and res.reachable
    alt = res.alternatives
    assert len(alt) >= 3 and alt["pb_ten_MPa"].max() - alt["pb_ten_MPa"].min() > 2.0
    np.testing.assert_allclose(alt["ucs_MPa"], targets_at(models, truth)["ucs_MPa"], rtol=1e-3)
    assert "continuum" in res.message


def test_out_of_range_target_is_reported_unreachable():
    models = known_models()
    top = {**FIXED, **TRUTH, "pb_coh_MPa": 50 / 1.4, "pb_ten_MPa": 50.0, "pb_kratio": 1.0}
    targets = targets_at(models, {**FIXED, **TRUTH, "pb_ten_MPa": 35.0})
    targets["ucs_MPa"] = 1.3 * models["ucs_MPa"].predict(top)  # beyond the strongest corner
    res = invert(models, targets, FIXED, SearchSpace(ranges=T2), search=Multistart(seed=3))
    assert res.status == "unreachable" and not res.ok and not res.reachable
    # the bound that stops it is named with the configured range it comes from
    assert ("pb_coh_MPa at the upper bound 35.7143 (= upper bound 50 of ranges.pb_ten_MPa / ratio 1.4"
            in res.message)
    assert res.residuals["ucs_MPa"] < -0.05
    lo, hi = res.bounds["pb_coh_MPa"]
    assert lo <= res.solution["pb_coh_MPa"] <= hi
    assert res.bound_origins["pb_coh_MPa"]["upper"] == "ranges.pb_ten_MPa / ratio 1.4"
    # the recorded edge is the bound itself, to the bit (the card stores it)
    assert ("pb_coh_MPa", "upper", hi) in res.at_bound and hi == 50 / 1.4


def test_two_solutions_are_flagged():
    models = known_models(nu_quadratic=True)
    truth = {**FIXED, **TRUTH, "pb_kratio": 2.0}
    truth["pb_ten_MPa"] = 1.4 * truth["pb_coh_MPa"]
    targets = {"nu": targets_at(models, truth)["nu"]}
    res = invert({"nu": models["nu"]},
                 targets,
                 FIXED,
                 SearchSpace(ranges=T2, free=["pb_kratio"], ratio=None),
                 search=Multistart(seed=1))
    assert res.status == "non-unique"
    np.testing.assert_allclose(sorted(res.alternatives["pb_kratio"]), [2.0, 4.0], rtol=1e-6)


def test_bad_inputs_name_the_problem():
    models = known_models()
    targets = {"ucs_MPa": 60.0, "E_GPa": 14.0, "nu": 0.25}
    with pytest.raises(ParameterError, match="pb_ten_MPa is derived"):
        invert(models,
               targets,
               FIXED,
               SearchSpace(ranges=T2, free=["pb_emod_GPa", "pb_kratio", "pb_coh_MPa", "pb_ten_MPa"]))
    with pytest.raises(ParameterError, match="porosity"):
        invert(models, targets, {"rmin_mm": 0.8}, SearchSpace(ranges=T2))
    with pytest.raises(ValueError, match="nu=0.0"):
        invert(models, {**targets, "nu": 0.0}, FIXED, SearchSpace(ranges=T2))
    with pytest.raises(ParameterError, match="bounds"):
        invert(models, targets, FIXED, SearchSpace(ranges=T2, bounds={"pb_kratio": (3.0, 2.0)}))


# ------------------------------------------------------------- bounds from the design space
WIDE = {**T2, "pb_emod_GPa": (30.0, 120.0), "pb_kratio": (1.0, 8.0), "pb_ten_MPa": (50.0, 300.0),
        "pb_coh_MPa": (50.0, 300.0)}
STRONG = {"pb_emod_GPa": 85.0, "pb_kratio": 6.5, "pb_coh_MPa": 150.0}  # outside Table 2 in all three


def test_widened_ranges_recover_a_planted_point_outside_table2():
    models = known_models()
    truth = {**FIXED, **STRONG, "pb_ten_MPa": 1.4 * STRONG["pb_coh_MPa"]}
    targets = targets_at(models, truth)
    res = invert(models, targets, FIXED, SearchSpace(ranges=WIDE), search=Multistart(seed=5))
    assert res.status == "ok", res.message
    for p, v in truth.items():
        np.testing.assert_allclose(res.solution[p], v, rtol=1e-7, err_msg=p)
    # the bounds are the configured ranges (cohesion cut by the tensile range / ratio)
    assert res.bounds["pb_emod_GPa"] == (30.0, 120.0) and res.bounds["pb_kratio"] == (1.0, 8.0)
    assert res.bounds["pb_coh_MPa"] == pytest.approx((50.0, 300.0 / 1.4))
    assert res.ranges == WIDE
    # the same targets with the paper's ranges: unreachable, and the advice names what to widen
    narrow = invert(models, targets, FIXED, SearchSpace(ranges=T2), search=Multistart(seed=5))
    assert narrow.status == "unreachable"
    keys = {w["key"]: w["needed"] for w in narrow.widen}
    assert set(keys) == {"ranges.pb_emod_GPa", "ranges.pb_kratio", "ranges.pb_coh_MPa", "ranges.pb_ten_MPa"}
    np.testing.assert_allclose([keys[f"ranges.{p}"] for p in truth if p in STRONG or p == "pb_ten_MPa"],
                               [truth[p] for p in truth if p in STRONG or p == "pb_ten_MPa"], rtol=1e-6)
    assert "widen ranges.pb_emod_GPa above 85" in narrow.message


def test_bounds_narrow_the_ranges_but_never_widen_them():
    models = known_models()
    truth = {**FIXED, **STRONG, "pb_ten_MPa": 1.4 * STRONG["pb_coh_MPa"]}
    targets = targets_at(models, truth)
    res = invert(models,
                 targets,
                 FIXED,
                 SearchSpace(ranges=WIDE, bounds={"pb_emod_GPa": (60.0, 100.0),
                                                  "pb_ten_MPa": (100.0, 280.0)}),
                 search=Multistart(seed=5))
    assert res.ok
    assert res.bounds["pb_emod_GPa"] == (60.0, 100.0)
    assert res.bounds["pb_coh_MPa"] == pytest.approx((100.0 / 1.4, 200.0))
    assert res.bound_origins["pb_emod_GPa"] == {"lower": "calibration.bounds.pb_emod_GPa",
                                                "upper": "calibration.bounds.pb_emod_GPa"}
    assert res.bound_origins["pb_coh_MPa"] == {"lower": "calibration.bounds.pb_ten_MPa / ratio 1.4",
                                               "upper": "calibration.bounds.pb_ten_MPa / ratio 1.4"}
    # a bound that stops the targets is named as such, and widening it needs no new design
    tight = invert(models,
                   targets,
                   FIXED,
                   SearchSpace(ranges=WIDE, bounds={"pb_emod_GPa": (60.0, 80.0)}),
                   search=Multistart(seed=5))
    assert tight.status == "unreachable"
    assert "pb_emod_GPa at the upper bound 80 of calibration.bounds.pb_emod_GPa" in tight.message
    assert tight.widen == [{"parameter": "pb_emod_GPa", "side": "upper", "bound": 80.0,
                            "key": "calibration.bounds.pb_emod_GPa", "needed": pytest.approx(85.0),
                            "beyond_ranges": False, "reaches_targets": True}]
    assert "rerun the design" not in tight.advice
    with pytest.raises(ParameterError, match=r"calibration.bounds.pb_emod_GPa=\[20, 100\] reaches beyond "
                                             r"ranges.pb_emod_GPa=\[30, 120\], the sampled space"):
        invert(models, targets, FIXED, SearchSpace(ranges=WIDE, bounds={"pb_emod_GPa": (20.0, 100.0)}))
    with pytest.raises(ParameterError, match="calibration.bounds.porosity: porosity is not calibrated"):
        invert(models, targets, FIXED, SearchSpace(ranges=WIDE, bounds={"porosity": (0.3, 0.35)}))
    with pytest.raises(ParameterError, match=r"fixed porosity=0.4 is outside ranges.porosity=\[0.2, 0.36\]"):
        invert(models, targets, {**FIXED, "porosity": 0.4}, SearchSpace(ranges=WIDE))
    with pytest.raises(ParameterError, match=r"ranges lacks \['pb_kratio'\]"):
        invert(models,
               targets,
               FIXED,
               SearchSpace(ranges={k: v for k, v in WIDE.items() if k != "pb_kratio"}))
    with pytest.raises(TypeError, match="ranges"):
        SearchSpace()  # no default design space


def test_no_exact_fit_says_when_widening_cannot_help():
    models = known_models(nu_quadratic=True)  # nu peaks at 0.30 for kp* = 3
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 1.4 * TRUTH["pb_coh_MPa"]}
    targets = {**targets_at(models, truth), "nu": 0.32}
    res = invert(models, targets, FIXED, SearchSpace(ranges=T2), search=Multistart(seed=2))
    assert res.status == "no-exact-fit"
    assert "no bound of the configured ranges is active" in res.message
    assert res.widen == [] and "widening the ranges does not help" in res.advice
    assert "calibration.free" in res.advice
    # at a bound, with a target beyond the models' reach even extrapolated: the best compromise
    # (the nu peak at kp* = 3) says how far to widen, and what it still misses
    res = invert(models,
                 targets,
                 FIXED,
                 SearchSpace(ranges={**T2, "pb_kratio": (1.0, 2.5)}),
                 search=Multistart(seed=2))
    assert res.status == "unreachable"
    assert res.widen == [{"parameter": "pb_kratio", "side": "upper", "key": "ranges.pb_kratio",
                          "bound": 2.5, "needed": pytest.approx(3.0, rel=1e-6), "beyond_ranges": True,
                          "reaches_targets": False}]
    assert "widen ranges.pb_kratio above 3 (its upper bound is now 2.5)" in res.advice
    assert "What it still misses (nu -6.25 %)" in res.advice


def test_closed_loop_runs_outside_table2_inside_the_configured_ranges():
    from bpmcal.analysis.calibration import ClosedLoop, LoopSteps, SearchSpace

    models = known_models()
    truth = {**FIXED, **STRONG, "pb_ten_MPa": 1.4 * STRONG["pb_coh_MPa"]}
    targets = targets_at(models, truth)
    start = invert(models, targets, FIXED, SearchSpace(ranges=WIDE), search=Multistart(seed=5)).solution

    def dem(p):  # the models with a 10 % bias in strength
        out = targets_at(models, p)
        return {**out, "ucs_MPa": 0.9 * out["ucs_MPa"]}

    res = ClosedLoop(dem,
                     targets,
                     space=SearchSpace(ranges=WIDE),
                     steps=LoopSteps(max_rounds=8),
                     models=models).run(start)
    assert res.converged and res.params["pb_coh_MPa"] > 150.0 > 50 / 1.4
    with pytest.raises(ParameterError, match=r"pb_coh_MPa=150 outside \[10, 35.7143\] \(ranges.pb_coh_MPa .. "
                                                 r"ranges.pb_ten_MPa / ratio 1.4\)"):
        ClosedLoop(dem,
                   targets,
                   space=SearchSpace(ranges=T2),
                   models=models).run(start)
