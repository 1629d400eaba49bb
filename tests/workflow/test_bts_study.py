"""The Brazilian test of every design sample in the study: the gathered dataset's sigma_t
columns (a failed Brazilian test recorded with its reason, the sample's UCS responses
kept), and sigma_t in the screening (Table 3) and the stepwise regression (models.json,
Table 4, the equations) without changing the UCS analyses; datasets without the Brazilian
columns still work."""
import json

import numpy as np
import pandas as pd
import pytest
from support.paper import A1

from bpmcal import params as P
from bpmcal.cli import main
from bpmcal.io import h5
from bpmcal.stages.dataset import gather
from bpmcal.stages.regression import RegressionSettings, regress
from bpmcal.stages.screening import ScreeningSettings, screen


def _design(tmp_path, rows) -> str:
    d = pd.DataFrame([{"sample_id": f"s{i:03d}", **r, "seed": 7 + i} for i, r in enumerate(rows)])
    f = tmp_path / "design.csv"
    d.to_csv(f, index=False)
    return str(f)


def _row(i, card=A1) -> dict:
    """The inputs a run file of design row ``i`` of :func:`_design` records (gather checks
    them against the row)."""
    return {**card, "seed": 7 + i}


def _ucs_ok(path, ucs, i=0, card=A1):
    h5.write_run(path,
                 h5.RunRecord(test="ucs",
                           inputs=_row(i, card),
                           summary={"ucs_MPa": ucs, "E_GPa": 12.0, "nu": 0.21, "wall_s": 3.0,
                          "stop_reason": "post_peak_drop"}))


def test_a_failed_brazilian_test_is_recorded_and_the_sample_keeps_its_ucs(tmp_path, capsys,
                                                                          packing_cache):
    # s001 cannot be built (pb_kratio 1e-5: the timestep 100 x shorter, the bpmcal genesis
    # does not settle within 1,000 steps):
    # `bpmcal bts --failed-ok`, as the study's sample job runs it, writes a failure record
    # and exits 0
    design = _design(tmp_path, [A1, {**A1, "pb_kratio": 1e-5}, A1])
    bts = tmp_path / "bts"
    rc = main(["bts", "--design", design, "--sample", "s001", "--out", str(bts / "s001.h5"),
               "--scale", "0.4", "--threads", "1", "--genesis-max-steps", "1000",
               "--genesis", "bpmcal",
               "--specimen-cache", str(packing_cache), "--failed-ok", "--quiet"])
    assert rc == 0
    assert "bpmcal bts: FAILED: " in capsys.readouterr().err
    rec = h5.read_summary(bts / "s001.h5")
    assert rec["status"] == "failed" and "GenesisError" in rec["error"]
    h5.write_run(bts / "s000.h5",
                 h5.RunRecord(test="bts",
                           inputs=_row(0),
                           summary={"bts_MPa": 6.5, "wall_s": 2.5}))
    # s002 has no Brazilian run file (missing); every sample's UCS run is ok
    ucs = [tmp_path / "ucs" / f"s00{i}.h5" for i in range(3)]
    for i, f in enumerate(ucs):
        _ucs_ok(f, 40.0 + i, i, {**A1, "pb_kratio": 1e-5} if i == 1 else A1)
    df, report = gather(design, ucs, tmp_path / "dataset.csv",
                        bts_runs=[bts / "s000.h5", bts / "s001.h5", bts / "s002.h5"])
    ds = pd.read_csv(tmp_path / "dataset.csv").set_index("sample_id")
    assert list(ds["status"]) == ["ok", "ok", "ok"]  # the UCS outcome, untouched
    assert list(ds["ucs_MPa"]) == [40.0, 41.0, 42.0]
    assert list(ds["bts_status"]) == ["ok", "failed", "missing"]
    assert ds.loc["s000", "bts_MPa"] == 6.5 and ds.loc["s000", "bts_wall_s"] == 2.5
    assert np.isnan(ds.loc["s001", "bts_MPa"]) and np.isnan(ds.loc["s002", "bts_MPa"])
    assert ds.loc["s001", "bts_error"] == rec["error"]
    assert ds.loc["s002", "bts_error"] == "no run file for s002"
    assert "Brazilian tests: 1 failed, 1 missing, 1 ok" in report
    assert f"s001: bts failed: {rec['error']}" in report


def test_a_failure_records_value_is_never_taken_as_sigma_t(tmp_path):
    design = _design(tmp_path, [A1])
    _ucs_ok(tmp_path / "u" / "s000.h5", 40.0)
    h5.write_run(tmp_path / "b" / "s000.h5",
                 h5.RunRecord(test="bts",
                           inputs=_row(0),
                           status="failed",
                           error="ServoError: the disc did not seat",
                           summary={"bts_MPa": 3.0}))
    df, _ = gather(design, [tmp_path / "u" / "s000.h5"], tmp_path / "d.csv",
                   bts_runs=[tmp_path / "b" / "s000.h5"])
    r = df.iloc[0]
    assert r["bts_status"] == "failed" and np.isnan(r["bts_MPa"])
    assert r["bts_error"] == "ServoError: the disc did not seat"


def test_an_invalid_brazilian_test_gives_no_sigma_t_and_says_why(tmp_path):
    """A run file that finished but failed the ISRM check: the dataset carries it as
    'invalid' with the reason, no sigma_t, the peak stress for inspection."""
    design = _design(tmp_path, [A1, A1])
    for i in (0, 1):
        _ucs_ok(tmp_path / "u" / f"s00{i}.h5", 40.0, i)
    h5.write_run(tmp_path / "b" / "s000.h5",
                 h5.RunRecord(test="bts",
                           inputs=_row(0),
                           summary={"bts_MPa": 6.5, "bts_peak_MPa": 6.5, "bts_valid": True,
                          "balls_across": 13.0, "wall_s": 2.5}))
    reason = "fracture initiated next to the top platen: the first 5 cracks ..."
    h5.write_run(tmp_path / "b" / "s001.h5",
                 h5.RunRecord(test="bts",
                           inputs=_row(1),
                           summary={"bts_MPa": float("nan"), "bts_peak_MPa": 0.78, "bts_valid": False,
                          "bts_invalid_reason": reason, "balls_across": 13.0,
                          "wall_s": 2.5}))
    df, report = gather(design, [tmp_path / "u" / f"s00{i}.h5" for i in (0, 1)],
                        tmp_path / "d.csv",
                        bts_runs=[tmp_path / "b" / f"s00{i}.h5" for i in (0, 1)])
    ds = pd.read_csv(tmp_path / "d.csv").set_index("sample_id")
    assert list(ds["bts_status"]) == ["ok", "invalid"]
    assert ds.loc["s001", "bts_error"] == reason and np.isnan(ds.loc["s001", "bts_MPa"])
    assert ds.loc["s001", "bts_peak_MPa"] == 0.78 and not ds.loc["s001", "bts_valid"]
    assert ds.loc["s000", "bts_valid"] and ds.loc["s000", "bts_balls_across"] == 13.0
    assert "Brazilian tests: 1 invalid, 1 ok (invalid: the fracture did not start" in report
    assert f"s001: bts invalid: {reason}" in report


def test_gather_counts_the_discs_discarded_before_a_valid_one(tmp_path):
    """A sample whose first disc was invalid and whose second was valid (bts.retests): its
    sigma_t is the valid disc's, the dataset says it took two discs, and the report says
    how many first discs were valid."""
    design = _design(tmp_path, [A1, A1])
    for i in (0, 1):
        _ucs_ok(tmp_path / "u" / f"s00{i}.h5", 40.0, i)
    for i, discs in ((0, 1), (1, 2)):
        h5.write_run(tmp_path / "b" / f"s00{i}.h5",
                     h5.RunRecord(test="bts",
                               inputs=_row(i),
                               summary={"bts_MPa": 6.5 + i, "bts_peak_MPa": 6.5 + i, "bts_valid": True,
                              "balls_across": 13.0, "wall_s": 2.5 * discs, "discs": discs,
                              "discarded": "" if discs == 1 else "seed 8: planted"}))
    df, report = gather(design, [tmp_path / "u" / f"s00{i}.h5" for i in (0, 1)],
                        tmp_path / "d.csv",
                        bts_runs=[tmp_path / "b" / f"s00{i}.h5" for i in (0, 1)])
    assert list(df["bts_discs"]) == [1, 2] and list(df["bts_status"]) == ["ok", "ok"]
    assert df["bts_MPa"].tolist() == [6.5, 7.5]
    assert ("1 samples had an invalid first disc and tested another (1 discs discarded, "
            "their reasons in the run files); first discs valid: 1 of 2") in report


def test_gather_without_brazilian_runs_has_no_brazilian_columns(tmp_path):
    design = _design(tmp_path, [A1])
    _ucs_ok(tmp_path / "u" / "s000.h5", 40.0)
    df, report = gather(design, [tmp_path / "u" / "s000.h5"], tmp_path / "d.csv")
    assert not any(c.startswith("bts") for c in df.columns)
    assert "Brazilian" not in report


# ---------------------------------------------------------------- sigma_t in the analyses
def _dataset(n=48, seed=3) -> pd.DataFrame:
    """Planted responses: sigma_t depends on the bond tensile strength and Rmin only."""
    rng = np.random.default_rng(seed)
    cols = {p: rng.uniform(P.PARAMS[p].lo, P.PARAMS[p].hi, n) for p in P.PARAMS}
    df = pd.DataFrame(cols)
    df.insert(0, "sample_id", [f"s{i:03d}" for i in range(n)])
    df["seed"] = np.arange(n)
    e = rng.normal(0, 1, (4, n))
    df["ucs_MPa"] = 10 + 1.2 * df["pb_ten_MPa"] + 0.6 * df["pb_coh_MPa"] + 0.5 * e[0]
    df["E_GPa"] = 2 + 0.3 * df["pb_emod_GPa"] - 0.8 * df["pb_kratio"] + 0.1 * e[1]
    df["nu"] = 0.1 + 0.04 * df["pb_kratio"] + 0.002 * e[2]
    df["status"], df["error"] = "ok", ""
    df.loc[5, ["ucs_MPa", "E_GPa", "nu"]] = np.nan  # a failed UCS run ...
    df.loc[5, ["status", "error"]] = ["failed", "NumericalInstability: planted"]
    df["bts_MPa"] = 20 + 0.25 * df["pb_ten_MPa"] - 20 * df["rmin_mm"] + 0.05 * e[3]
    df["bts_wall_s"] = 2.0
    df["bts_status"], df["bts_error"] = "ok", ""
    for i in (7, 8, 9):  # ... and failed Brazilian tests of samples whose UCS run is ok
        df.loc[i, ["bts_MPa", "bts_wall_s"]] = np.nan
        df.loc[i, ["bts_status", "bts_error"]] = ["failed", "ServoError: planted"]
    for i in (10, 11):  # invalid tests (a seating event read as the peak): no sigma_t - and
        # a value the analyses must not take even though it is there
        df.loc[i, "bts_MPa"] = 0.78
        df.loc[i, ["bts_status", "bts_error"]] = [
            "invalid", "fracture initiated next to the bottom platen: planted"]
    return df


def _analyse(df, folder):
    folder.mkdir()
    f = folder / "dataset.csv"
    df.to_csv(f, index=False)
    o = {k: folder / n for k, n in [
        ("selected", "selected.json"), ("table3", "table3.csv"), ("fig", "imp.png"),
        ("imp", "imp.csv"), ("cv", "cv.csv"), ("shadow", "shadow.csv"), ("sum", "sum.txt"),
        ("models", "models.json"), ("eq", "equations.md"), ("summ", "summ.txt"),
        ("coef", "coef.csv"), ("cand", "cand.csv"), ("table4", "table4.csv"),
        ("fit", "fit.csv"), ("regfig", "reg.png")]}
    s = screen(f, selected=o["selected"], table3_csv=o["table3"], figure=o["fig"],
               importance_table=o["imp"], cv_table=o["cv"], shadow_table=o["shadow"],
               summary=o["sum"], settings=ScreeningSettings(n_splits=4, n_repeats=2))
    r = regress(f, o["selected"], models=o["models"], equations=o["eq"], summaries=o["summ"],
                coefficients=o["coef"], candidates=o["cand"], table4=o["table4"],
                fit_table=o["fit"], figure=o["regfig"],
                settings=RegressionSettings(cv_folds=4, cv_repeats=2))
    return o, s, r


@pytest.fixture(scope="module")
def analysed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bts_analyses")
    df = _dataset()
    with_bts = _analyse(df, tmp / "with")
    without = _analyse(df.drop(columns=[c for c in df.columns if c.startswith("bts")]),
                       tmp / "without")
    return with_bts, without


@pytest.mark.slow
def test_table3_and_the_selection_have_sigma_t(analysed):
    (o, s, _), _ = analysed
    t3 = pd.read_csv(o["table3"], index_col=0)
    assert list(t3.columns) == [*P.TARGETS, "bts_MPa"]
    assert t3["bts_MPa"].sum() == pytest.approx(100.0)
    # the planted sigma_t depends on the bond tensile strength and Rmin only
    assert set(t3["bts_MPa"].nlargest(2).index) == {"pb_ten_MPa", "rmin_mm"}
    assert set(s["selected"]["bts_MPa"]) >= {"pb_ten_MPa", "rmin_mm"}
    # sigma_t's candidates are every parameter (the stepwise regression chooses), the
    # paper's responses keep the paper's 10 % rule; selected.json says which rule
    sel = json.loads(o["selected"].read_text())
    assert sel["rule"] == {**{r: "threshold" for r in P.TARGETS}, "bts_MPa": "all"}
    assert set(s["selected"]["bts_MPa"]) == set(P.PARAMS)
    assert "pb_fa_deg" not in s["selected"]["nu"]
    assert "σt (%)" in (o["table3"].with_suffix(".md")).read_text()
    # sigma_t was screened on the 43 samples with a valid Brazilian result (s005's UCS failed,
    # its Brazilian test did not; s007-s009 failed, s010-s011 are invalid), the UCS
    # responses on the 47 with a UCS result
    summary = o["sum"].read_text()
    assert "47 rows used" in summary
    assert "bts_MPa: screened on its own rows: 43 used, 5 dropped (5 not ok" in summary
    assert ("sigma_t: 43 of 48 Brazilian tests used (5 left out: 3 failed: s007, s008, s009; "
            "2 invalid: s010, s011)") in s["note"]


@pytest.mark.slow
def test_the_regression_has_a_sigma_t_model_fitted_on_the_brazilian_rows(analysed):
    (o, _, r), _ = analysed
    m = json.loads(o["models"].read_text())
    assert set(m["models"]) == {*P.TARGETS, "bts_MPa"}
    final = list(m["models"]["bts_MPa"].values())[-1]
    assert final["n_obs"] == 43  # the invalid tests' 0.78 MPa never enters the fit
    assert m["response_rows"]["bts_MPa"]["n_used"] == 43 and m["rows"]["n_used"] == 47
    assert final["adj_r2"] > 0.99
    first = list(m["models"]["bts_MPa"].values())[0]  # the main effects: the planted slopes
    coef = {t["name"]: t["coef"] for t in first["terms"]}
    assert coef["pb_ten_MPa"] == pytest.approx(0.25, rel=0.02)
    assert coef["rmin_mm"] == pytest.approx(-20.0, rel=0.02)
    assert "bts_MPa" in o["eq"].read_text()
    t4 = pd.read_csv(o["table4"], index_col=0)
    assert "bts_MPa" in t4.index
    fit = pd.read_csv(o["fit"])
    assert "bts_MPa" in set(fit["response"])
    # what the calibration reads: a model of every response, sigma_t's among them
    from bpmcal.stages.inputs import read_models
    assert set(read_models(o["models"])) == {*P.TARGETS, "bts_MPa"}


@pytest.mark.slow
def test_sigma_t_leaves_the_ucs_analyses_unchanged_and_old_datasets_work(analysed):
    (o, _, _), (w, _, _) = analysed
    t3, t3w = pd.read_csv(o["table3"], index_col=0), pd.read_csv(w["table3"], index_col=0)
    assert list(t3w.columns) == list(P.TARGETS)
    pd.testing.assert_frame_equal(t3[list(P.TARGETS)], t3w)
    m, mw = json.loads(o["models"].read_text()), json.loads(w["models"].read_text())
    assert set(mw["models"]) == set(P.TARGETS) and "response_rows" not in mw
    def fitted(models, r):  # every number of the model (the statsmodels text has a clock)
        return {st: {k: v for k, v in d.items() if k != "summary"}
                for st, d in models["models"][r].items()}

    for r in P.TARGETS:
        assert fitted(m, r) == fitted(mw, r), r
    assert "bts_MPa" not in w["eq"].read_text()
