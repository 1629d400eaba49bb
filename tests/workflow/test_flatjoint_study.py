"""The study with flat joints (contact_model: flatjoint), end to end at smoke size: the
Lac du Bonnet flat-joint example's overlay runs the design, the sample jobs (UCS and
direct tension), screening, regression, calibration, the closed loop and the fresh-seed
check on flat-joint cards, with the flat joint's names throughout. (The impact and
triaxial jobs run flat-joint cards through the same run files as the lab tests: tests/lab;
the config rules: tests/unit/study/test_config.py.)"""
import pandas as pd
import pytest
import yaml
from support.repo import copy_workflow, merged_config, run_snakemake

from bpmcal.io.h5 import read_inputs

ARGS = ("--configfile", "config/examples/lac_du_bonnet_fj.yaml",
        "config/examples/lac_du_bonnet_fj_smoke.yaml")
CFG = ("config.yaml", "examples/lac_du_bonnet_fj.yaml", "examples/lac_du_bonnet_fj_smoke.yaml")


@pytest.fixture(scope="module")
def fj_study(tmp_path_factory):
    wf = copy_workflow(tmp_path_factory.mktemp("fj"))
    out = merged_config(*CFG)["outdir"]
    targets = [f"{out}/tables/table5_verification.csv", f"{out}/tables/fresh_seeds.csv",
               f"{out}/tables/table3_importance.csv"]
    r = run_snakemake(wf, *targets, "--cores", "2", *ARGS)
    assert r.returncode == 0, r.stderr[-3000:]
    return wf / out, r


@pytest.mark.slow
def test_the_flat_joint_study_runs_on_the_flat_joints_names(fj_study):
    out, r = fj_study
    assert "contact_model flatjoint: 9 parallel-bond key(s) of the base config left out" in r.stderr
    ds = pd.read_csv(out / "dataset.csv")
    assert not [c for c in ds.columns if c.startswith("pb_") or c == "fric"]
    assert {"fj_emod_GPa", "fj_kratio", "fj_ten_MPa", "fj_coh_MPa", "fj_nal"} <= set(ds.columns)
    assert (ds["status"] == "ok").sum() >= 8 and "dtt_status" in ds.columns
    # every sample job ran a flat-jointed card
    s0 = ds["sample_id"].iloc[0]
    assert read_inputs(out / "ucs" / f"{s0}.h5")["contact_model"] == "flatjoint"
    t3 = pd.read_csv(out / "tables" / "table3_importance.csv", index_col=0)
    assert list(t3.index) == ["fj_emod_GPa", "fj_kratio", "fj_ten_MPa", "fj_coh_MPa"]
    assert "dtt_MPa" in t3.columns


@pytest.mark.slow
def test_the_flat_joint_card_is_calibrated_and_verified(fj_study):
    out, _ = fj_study
    card = yaml.safe_load((out / "calibration" / "LdB.yaml").read_text())
    p = card["parameters"]
    assert set(p) == {"rmin_mm", "porosity", "fj_emod_GPa", "fj_kratio", "fj_ten_MPa",
                      "fj_coh_MPa", "fj_fa_deg", "fj_fric"}
    assert card["roles"]["fj_ten_MPa"] == "free"  # the lab's sigma_t sets the ratio
    assert card["strength_ratio"]["set_by"] == "dtt_MPa target"
    assert card["strength_ratio"]["value"] == pytest.approx(p["fj_ten_MPa"] / p["fj_coh_MPa"])
    ver = yaml.safe_load((out / "verification" / "LdB" / "card.yaml").read_text())["verification"]
    assert set(ver["parameters"]) == set(p) and ver["runs"] >= 3
    assert set(ver["closed_loop"]["errors_pct"]) == {"ucs_MPa", "E_GPa", "nu", "dtt_MPa"}
    fresh = pd.read_csv(out / "tables" / "fresh_seeds.csv")
    assert set(fresh["response"]) == {"ucs_MPa", "E_GPa", "nu", "dtt_MPa"}
    assert (fresh["n"] + fresh["n_failed"] >= 2).all()
