"""Inversion of known regression models."""
import numpy as np
import pytest

from bpmcal.analysis.calibration import invert
from bpmcal.analysis.stepwise import RegressionModel
from bpmcal.params import ParameterError

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
    res = invert(models, targets_at(models, truth), FIXED, seed=3)
    assert res.status == "ok" and res.ok and res.unique
    for p, v in truth.items():
        np.testing.assert_allclose(res.solution[p], v, rtol=1e-7, err_msg=p)
    assert res.max_abs_residual < 1e-9
    assert res.bounds["pb_coh_MPa"] == pytest.approx((10.0, 50.0 / 1.4))
    assert res.to_frame().loc["pb_ten_MPa", "role"] == "derived"


def test_free_strengths_give_a_flagged_continuum():
    models = known_models()
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 30.0}
    res = invert(models, targets_at(models, truth), FIXED, ratio=None, seed=3)
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
    res = invert(models, targets, FIXED, seed=3)
    assert res.status == "unreachable" and not res.ok and not res.reachable
    assert "pb_coh_MPa at its upper bound" in res.message
    assert res.residuals["ucs_MPa"] < -0.05
    lo, hi = res.bounds["pb_coh_MPa"]
    assert lo <= res.solution["pb_coh_MPa"] <= hi


def test_two_solutions_are_flagged():
    models = known_models(nu_quadratic=True)
    truth = {**FIXED, **TRUTH, "pb_kratio": 2.0}
    truth["pb_ten_MPa"] = 1.4 * truth["pb_coh_MPa"]
    targets = {"nu": targets_at(models, truth)["nu"]}
    res = invert({"nu": models["nu"]}, targets, FIXED, free=["pb_kratio"], ratio=None, seed=1)
    assert res.status == "non-unique"
    np.testing.assert_allclose(sorted(res.alternatives["pb_kratio"]), [2.0, 4.0], rtol=1e-6)


def test_bad_inputs_name_the_problem():
    models = known_models()
    targets = {"ucs_MPa": 60.0, "E_GPa": 14.0, "nu": 0.25}
    with pytest.raises(ParameterError, match="pb_ten_MPa is derived"):
        invert(models, targets, FIXED, free=["pb_emod_GPa", "pb_kratio", "pb_coh_MPa", "pb_ten_MPa"])
    with pytest.raises(ParameterError, match="porosity"):
        invert(models, targets, {"rmin_mm": 0.8})
    with pytest.raises(ValueError, match="nu=0.0"):
        invert(models, {**targets, "nu": 0.0}, FIXED)
    with pytest.raises(ParameterError, match="bounds"):
        invert(models, targets, FIXED, bounds={"pb_kratio": (3.0, 2.0)})
