"""The ratio sweep (bpmcal.study.sweep): the plan keeps the predicted sigma_c at the target,
and the analysis picks the ratio whose tensile share is closest to the target."""
import numpy as np
import pandas as pd
import pytest
from support.paper import A1

from bpmcal.analysis import fit_terms
from bpmcal.io.study_files import ratio_grid
from bpmcal.study.sweep import analyse_sweep, sweep_plan


@pytest.mark.slow
def test_sweep_plan_holds_the_predicted_ucs_at_the_target():
    rng = np.random.default_rng(0)
    df = pd.DataFrame({k: rng.uniform(10, 50, 80) for k in ("pb_ten_MPa", "pb_coh_MPa")})
    df["ucs_MPa"] = 1.2 * df["pb_ten_MPa"] + 2.0 * df["pb_coh_MPa"] - 0.01 * df["pb_coh_MPa"] ** 2
    df["status"] = "ok"
    model = fit_terms(df, "ucs_MPa", ["pb_ten_MPa", "pb_coh_MPa", ("pb_coh_MPa", "pb_coh_MPa")])
    ranges = {"pb_ten_MPa": [15.0, 50.0], "pb_coh_MPa": [15.0, 50.0]}
    card = {"parameters": dict(A1), "targets": {"ucs_MPa": 60.0}, "ranges": ranges}
    plan = sweep_plan(card, model, ratio_grid(0.5, 2.0, 0.1), seed=3)
    assert list(plan["sample_id"])[:3] == ["a050", "a060", "a070"] and len(plan) == 16
    assert np.allclose(plan["pb_ten_MPa"], plan["ratio"] * plan["pb_coh_MPa"])
    assert np.allclose(model.predict(plan), 60.0, atol=1e-6)
    assert (plan["seed"] == 3).all()
    # "extrapolated" is judged against the card's ranges (the study's design space)
    inside = plan[["pb_ten_MPa", "pb_coh_MPa"]].apply(lambda c: c.between(15.0, 50.0)).all(axis=1)
    assert (plan["extrapolated"] == ~inside).all() and plan["extrapolated"].any()
    wide = sweep_plan({**card, "ranges": {"pb_ten_MPa": [1.0, 200.0], "pb_coh_MPa": [1.0, 200.0]}},
                      model, ratio_grid(0.5, 2.0, 0.1), seed=3)
    assert not wide["extrapolated"].any()
    np.testing.assert_allclose(wide["pb_coh_MPa"], plan["pb_coh_MPa"], rtol=1e-9)


def test_sweep_choice_picks_the_tensile_share_closest_to_the_target(tmp_path):
    from bpmcal.io.h5 import RunRecord, write_run
    plan = pd.DataFrame({"sample_id": ["a050", "a100", "a150"], "ratio": [0.5, 1.0, 1.5],
                         "pb_ten_MPa": [10, 20, 30], "pb_coh_MPa": [20, 20, 20],
                         "extrapolated": [False] * 3})
    for sid, nt, ns in (("a050", 10, 90), ("a100", 55, 45), ("a150", 90, 10)):
        write_run(tmp_path / f"{sid}.h5",
                  RunRecord(test="ucs",
                            inputs={},
                            summary={"cracks_tension": nt, "cracks_shear": ns, "ucs_MPa": 50.0}))
    runs = {sid: tmp_path / f"{sid}.h5" for sid in plan["sample_id"]}
    df, chosen = analyse_sweep(plan, runs, "tensile_share", 0.6)
    assert chosen["chosen_ratio"] == 1.0
    assert df["tensile_share"].tolist() == [0.1, 0.55, 0.9]


def test_a_flat_joint_card_sweeps_its_own_strength_pair():
    """The plan of a flat-joint card varies fj_ten_MPa = a x fj_coh_MPa (the registry's
    strength pair), keeps the predicted sigma_c at the target and writes the card's names."""
    from bpmcal import params as P
    from bpmcal.analysis.stepwise import RegressionModel

    model = RegressionModel("ucs_MPa", [("fj_coh_MPa",), ("fj_ten_MPa",)], [0.9, 3.0], 10.0)
    card = {"parameters": {"rmin_mm": 0.8, "porosity": 0.3, "fj_emod_GPa": 70.0,
                           "fj_kratio": 2.5, "fj_ten_MPa": 10.0, "fj_coh_MPa": 150.0,
                           "fj_fa_deg": 30.0, "fj_fric": 0.6, "contact_model": "flatjoint"},
            "targets": {"ucs_MPa": 175.0},
            "ranges": {"fj_ten_MPa": [5.0, 20.0], "fj_coh_MPa": [50.0, 250.0]}}
    plan = sweep_plan(card, model, ratio_grid(0.05, 0.1, 0.01), seed=2)
    assert not [c for c in plan.columns if c.startswith("pb_")]
    assert list(plan.columns[1:9]) == [k for k in P.FLATJOINT.names if k in card["parameters"]]
    assert np.allclose(plan["fj_ten_MPa"], plan["ratio"] * plan["fj_coh_MPa"])
    assert np.allclose(model.predict(plan), 175.0, atol=1e-6)
    table, _ = analyse_sweep(plan, {})
    assert {"fj_ten_MPa", "fj_coh_MPa"} <= set(table.columns)
