"""Screening and regression of a flat-joint study's dataset: the stages take the contact
model's names from the dataset (the registry), hold no parallel-bond name, and find the
flat-joint parameters a planted response depends on."""
import json

import numpy as np
import pandas as pd
import pytest

from bpmcal import params as P
from bpmcal.stages.regression import RegressionSettings, regress
from bpmcal.stages.screening import ScreeningSettings, screen
from bpmcal.study.design import lhs_design

RANGES = {"rmin_mm": [0.6, 1.0], "porosity": [0.2, 0.36], "fj_emod_GPa": [40, 100],
          "fj_kratio": [1.5, 3.0], "fj_ten_MPa": [5, 20], "fj_coh_MPa": [50, 200],
          "fj_fa_deg": [0, 40], "fj_fric": [0.4, 0.8], "fj_nal": [3, 3]}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    d = lhs_design(RANGES, 80, 11)
    rng = np.random.default_rng(0)
    n = len(d)
    d["ucs_MPa"] = 1.1 * d["fj_coh_MPa"] + 8.0 * d["fj_ten_MPa"] + 5 + rng.normal(0, 2, n)
    d["E_GPa"] = 0.8 * d["fj_emod_GPa"] - 6.0 * d["fj_kratio"] + rng.normal(0, 0.5, n)
    d["nu"] = 0.05 * d["fj_kratio"] + 0.1 + rng.normal(0, 0.003, n)
    d["status"], d["error"] = "ok", ""
    f = tmp_path_factory.mktemp("fj") / "dataset.csv"
    d.to_csv(f, index=False)
    return f


@pytest.fixture(scope="module")
def stages(dataset, tmp_path_factory):
    """The screening and regression stages on ``dataset`` (their files), run once for the
    module: the calibrations below each read them."""
    o = tmp_path_factory.mktemp("fj_stages")
    out = _screen_and_regress(dataset, o)
    return o, out


def test_flat_joint_dataset_is_screened_and_regressed_on_its_own_names(stages):
    o, out = stages
    sel = out["selected"]
    assert set(sel["ucs_MPa"]) >= {"fj_coh_MPa", "fj_ten_MPa"}
    assert "fj_emod_GPa" in sel["E_GPa"] and "fj_kratio" in sel["nu"]
    t3 = pd.read_csv(o / "t3.csv", index_col=0)
    # the designed parameters, in the model's order; the fixed element count is no row
    assert list(t3.index) == [p for p in P.FLATJOINT.names if p in RANGES and p != "fj_nal"]
    models = json.loads((o / "models.json").read_text())
    text = json.dumps(models)
    assert "pb_" not in text and "fj_coh_MPa" in text
    fit = pd.read_csv(o / "fit.csv")
    assert fit.groupby("response")["adj_r2"].max().min() > 0.9


def _calibrated_card(dataset, stages, o, lab_csv: str) -> dict:
    """Calibrate ``dataset`` with the module's screening and regression (``stages``)
    against the lab CSV text ``lab_csv`` (strength ratio 0.08), the files in ``o``: the
    card of specimen G1."""
    from bpmcal.io.card import read_card
    from bpmcal.stages.calibration import CalibrationSettings, calibrate

    lab = o / "lab.csv"
    lab.write_text(lab_csv)
    (o / "cards").mkdir()
    fixed = {"rmin_mm": 0.8, "porosity": 0.3, "fj_fa_deg": 20.0, "fj_fric": 0.6, "fj_nal": 3.0}
    calibrate(dataset, stages[0] / "models.json", lab, cards=[o / "cards" / "G1.yaml"],
              ranges=dict(RANGES),
              settings=CalibrationSettings(fixed=fixed, strength_ratio=0.08, n_boot=0))
    return read_card(o / "cards" / "G1.yaml")


def _screen_and_regress(dataset, o):
    """The screening and regression stages on ``dataset``, their files in ``o``."""
    out = screen(dataset, selected=o / "sel.json", table3_csv=o / "t3.csv",
                 figure=o / "imp.png", importance_table=o / "imp.csv", cv_table=o / "cv.csv",
                 shadow_table=o / "sh.csv", summary=o / "s.txt",
                 settings=ScreeningSettings(n_repeats=1))
    regress(dataset, o / "sel.json", models=o / "models.json", equations=o / "eq.md",
            summaries=o / "sum.txt", coefficients=o / "coef.csv", candidates=o / "cand.csv",
            table4=o / "t4.csv", fit_table=o / "fit.csv", figure=o / "fit.png",
            settings=RegressionSettings(cv_repeats=1))
    return out


def test_a_flat_joint_card_is_calibrated_from_the_flat_joint_regression(dataset, stages,
                                                                       tmp_path):
    """The calibration stage on the flat-joint models: the card holds the flat joint's
    names, its strength ratio is fj_ten/fj_coh, and its predicted responses are the lab's."""
    card = _calibrated_card(dataset, stages, tmp_path,
                            "specimen,ucs_MPa,E_GPa,nu\nG1,180.0,55.0,0.22\n")
    assert card["status"] == "ok", card["message"]
    p = card["parameters"]
    assert not [k for k in p if k.startswith("pb_")]
    assert p["fj_ten_MPa"] == pytest.approx(0.08 * p["fj_coh_MPa"])
    assert card["strength_ratio"]["value"] == pytest.approx(0.08)
    assert card["roles"]["fj_ten_MPa"] == "derived" and card["roles"]["fj_coh_MPa"] == "free"


def test_the_labs_standard_errors_reach_the_card(dataset, stages, tmp_path):
    """A lab row with <target>_se columns: the card records them as target_se (the closed
    loop and the fresh-seed check read them there)."""
    card = _calibrated_card(dataset, stages, tmp_path,
                            "specimen,ucs_MPa,E_GPa,nu,ucs_MPa_se,nu_se\nG1,180.0,55.0,0.22,4.0,\n")
    assert card["target_se"] == {"ucs_MPa": 4.0}
