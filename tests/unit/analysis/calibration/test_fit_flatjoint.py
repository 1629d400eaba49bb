"""Calibration in the flat joint's names: the calibration space takes the strength pair
(fj_ten_MPa, fj_coh_MPa) and the default free set from the contact-model registry; the
inversion and the closed loop solve a planted flat-joint card back."""
import pytest

from bpmcal import params as P
from bpmcal.analysis.calibration import (
    CalibrationSpace,
    ClosedLoop,
    LoopSeeds,
    SearchSpace,
    bts_strengths,
    invert,
)
from bpmcal.analysis.stepwise import RegressionModel

RANGES = {"rmin_mm": (0.6, 1.0), "porosity": (0.2, 0.36), "fj_emod_GPa": (40.0, 100.0),
          "fj_kratio": (1.5, 3.0), "fj_ten_MPa": (5.0, 20.0), "fj_coh_MPa": (50.0, 200.0),
          "fj_fa_deg": (0.0, 40.0), "fj_fric": (0.4, 0.8)}
FIXED = {"rmin_mm": 0.8, "porosity": 0.3, "fj_fa_deg": 20.0, "fj_fric": 0.6}
MODELS = {
    "ucs_MPa": RegressionModel("ucs_MPa", [("fj_coh_MPa",), ("fj_ten_MPa",)], [0.9, 3.0], 10.0),
    "E_GPa": RegressionModel("E_GPa", [("fj_emod_GPa",), ("fj_kratio",)], [0.8, -4.0], 5.0),
    "nu": RegressionModel("nu", [("fj_kratio",)], [0.06], 0.08),
    P.BTS: RegressionModel(P.BTS, [("fj_ten_MPa",), ("fj_coh_MPa",)], [0.5, 0.01], 1.0),
}
TRUTH = {**FIXED, "fj_emod_GPa": 75.0, "fj_kratio": 2.2, "fj_ten_MPa": 12.0, "fj_coh_MPa": 140.0}


def targets(card):
    return {r: m.predict(card) for r, m in MODELS.items()}


def test_the_space_takes_the_flat_joint_strength_pair():
    sp = CalibrationSpace(None, FIXED, 0.1, RANGES, None)
    assert sp.model is P.FLATJOINT
    assert sp.free == P.FLATJOINT.free and sp.derived == ("fj_ten_MPa",)
    # the cohesion's box is cut where ratio x cohesion leaves the tensile range: 50..200
    assert sp.bounds()["fj_coh_MPa"] == pytest.approx((50.0, 200.0))
    assert CalibrationSpace(None, FIXED, 0.05, RANGES, None).bounds()["fj_coh_MPa"] == \
        pytest.approx((100.0, 200.0))
    free, ratio, by = bts_strengths({P.BTS: 10.0}, None, FIXED, 0.1)
    assert free == (*P.FLATJOINT.free, "fj_ten_MPa") and ratio is None and by == P.BTS
    with pytest.raises(P.ParameterError, match="mixed card"):
        CalibrationSpace(None, {**FIXED, "pb_fa_deg": 30.0}, 0.1, RANGES, None)


def test_a_planted_flat_joint_card_is_solved_back_and_the_loop_meets_it():
    t = targets(TRUTH)
    inv = invert(MODELS,
                 t,
                 FIXED,
                 SearchSpace(ranges=RANGES, free=(*P.FLATJOINT.free, "fj_ten_MPa"), ratio=None))
    assert inv.ok
    for k in ("fj_emod_GPa", "fj_kratio", "fj_ten_MPa", "fj_coh_MPa"):
        assert inv.solution[k] == pytest.approx(TRUTH[k], rel=1e-3)

    def dem(params, seed):  # the regression with a bias: the loop must correct it
        y = targets(params)
        return {"ucs_MPa": 1.05 * y["ucs_MPa"], "E_GPa": 0.97 * y["E_GPa"], "nu": y["nu"],
                P.BTS: 1.04 * y[P.BTS]}

    res = ClosedLoop(dem,
                     t,
                     space=SearchSpace(ranges=RANGES, free=(*P.FLATJOINT.free, "fj_ten_MPa"), ratio=None),
                     seeding=LoopSeeds(seeds_per_round=1),
                     models=MODELS).run(inv.solution)
    assert res.converged
    assert set(res.params) == set(FIXED) | {"fj_emod_GPa", "fj_kratio", "fj_ten_MPa", "fj_coh_MPa"}
    got = dem(res.params, 1)
    assert all(abs(got[r] / t[r] - 1) <= 0.01 for r in t)


@pytest.mark.parametrize("ratio, needle", [
    (10.0, "try `contact_model: linearpbond`"),  # below the reach: the other model
    (60.0, "widen fj_coh_MPa upwards"),  # above: more interlocking
    (30.0, None),  # inside the reach: no advice
])
def test_a_sigma_c_over_sigma_t_out_of_reach_gets_the_registrys_advice(ratio, needle):
    from bpmcal.analysis.calibration.inversion import _ratio_advice
    sp = CalibrationSpace(None, FIXED, 0.1, RANGES, None)
    msg = _ratio_advice(sp, {"ucs_MPa": 200.0, P.BTS: 200.0 / ratio}, 200.0 / ratio,
                        {"ucs_over_bts": (20.0, 35.0)})
    assert (needle in msg) if needle else msg == ""
