"""The triaxial envelope stage (``bpmcal envelopes``) on synthetic run files: planted
Mohr-Coulomb and Hoek-Brown envelopes are recovered from the runs of a card, failed runs
stay in the tables with their reason (the fit uses the rest and says so), a lab triaxial
CSV is compared point by point, and bad lab triaxial CSVs (missing columns, unknown
specimens, negative or non-numeric sigma3) end with one error line, exit code 2 and no
output file. No DEM run: the run files are written with ``bpmcal.io.h5.write_run``."""
import math
from pathlib import Path

import pandas as pd
import pytest
import yaml
from support.paper import A1
from support.repo import REPO, SCHEMA

from bpmcal.analysis.envelopes import hoek_brown_sigma1, mohr_coulomb_q, mohr_coulomb_sigma_c
from bpmcal.cli import main
from bpmcal.io.card import write_card
from bpmcal.io.h5 import RunRecord, write_run

S3 = [0.0, 5.0, 10.0, 20.0]


def _card(path, spec, params, **extra):
    write_card(path, {"specimen": spec, "status": "ok", "parameters": params, **extra})
    return str(path)


def _run(path, params, s3, s1=None, status="ok", error=""):
    summ = {} if s1 is None else {"sigma1_MPa": s1, "sigma3_MPa": s3, "E_GPa": 11.0,
                                  "nu": 0.22, "sigma3_maxdev_rel": 1e-4,
                                  "cracks_tension": 10, "cracks_shear": 5, "wall_s": 1.0}
    write_run(path,
              RunRecord(test="triaxial",
                        inputs={**params, "sigma3_MPa": s3, "seed": 1},
                        summary=summ,
                        status=status,
                        error=error))
    return str(path)


def _args(cards, runs, out, extra=()):
    return ["envelopes", "--cards", *cards, "--runs", *runs, "--sigma3",
            ",".join(f"{x:g}" for x in S3), "--table", str(out / "env.csv"),
            "--points", str(out / "pts.csv"), "--figure", str(out / "env.png"), *extra]


@pytest.fixture
def mc_and_hb(tmp_path):
    """Two cards: B1 on a planted Mohr-Coulomb line (c 13 MPa, phi 32 deg), B2 on a planted
    Hoek-Brown curve (sigma_ci 45 MPa, mi 7.5), with sigma_t on the verified card."""
    c, phi = 13.0, 32.0
    sc, q = mohr_coulomb_sigma_c(c, phi), mohr_coulomb_q(phi)
    p2 = {**A1, "pb_coh_MPa": 21.0}
    cards = [_card(tmp_path / "B1.yaml", "B1", A1),
             _card(tmp_path / "B2.yaml", "B2", A1, verification={
                 "status": "ok", "parameters": p2,
                 "closed_loop": {"ucs_MPa": 45.3, "bts_MPa": 6.9}})]
    runs = [_run(tmp_path / f"b1_{x:g}.h5", A1, x, sc + q * x) for x in S3]
    runs += [_run(tmp_path / f"b2_{x:g}.h5", p2, x, float(hoek_brown_sigma1(x, 45.0, 7.5)))
             for x in S3]
    return tmp_path, cards, runs, (c, phi, sc)


def test_envelope_stage_recovers_planted_c_phi_and_mi(mc_and_hb, capsys):
    d, cards, runs, (c, phi, sc) = mc_and_hb
    out = d / "out"
    assert main(_args(cards, runs, out)) == 0
    env = pd.read_csv(out / "env.csv").set_index("specimen")
    b1, b2 = env.loc["B1"], env.loc["B2"]
    assert b1["card"] == "calibrated" and b2["card"] == "verified"
    assert b1["c_MPa"] == pytest.approx(c, rel=1e-9)
    assert b1["phi_deg"] == pytest.approx(phi, rel=1e-9)
    assert b1["mc_sigma_c_MPa"] == pytest.approx(sc, rel=1e-9)
    assert b2["mi"] == pytest.approx(7.5, rel=1e-9)
    assert b2["hb_sigma_ci_MPa"] == pytest.approx(45.0, rel=1e-9)
    # a Hoek-Brown curve is not a line: the Mohr-Coulomb fit of B2 is worse than its HB fit
    assert b2["mc_rms_MPa"] > 100 * max(b2["hb_rms_MPa"], 1e-9)
    # sigma_t and sigma_c/sigma_t come from the verified card's closed loop
    assert b2["sigma_t_MPa"] == 6.9 and b2["sigma_t_source"] == "DEM closed loop"
    assert b2["sigma_c_over_sigma_t"] == pytest.approx(45.3 / 6.9)
    assert math.isnan(b1["sigma_t_MPa"])  # the calibrated card holds none
    assert (out / "env.md").is_file() and (out / "env.pdf").is_file()
    assert (out / "env.png").stat().st_size > 1000


def test_failed_runs_are_recorded_and_the_fit_uses_the_rest(mc_and_hb):
    d, cards, runs, (c, phi, _) = mc_and_hb
    _run(runs[3], A1, 20.0, status="failed", error="ServoError: consolidation did not converge")
    Path(runs[1]).unlink()  # B1 at sigma3 = 5: no file
    out = d / "out"
    assert main(_args(cards, runs, out)) == 0
    pts = pd.read_csv(out / "pts.csv")
    assert len(pts) == 8  # nothing dropped
    b1 = pts[pts["specimen"] == "B1"].set_index("sigma3_MPa")
    assert b1.loc[20.0, "status"] == "failed" and "ServoError" in b1.loc[20.0, "error"]
    assert b1.loc[5.0, "status"] == "missing"
    env = pd.read_csv(out / "env.csv").set_index("specimen").loc["B1"]
    assert env["runs_ok"] == 2 and env["status"] == "partial"
    assert "fitted on 2 of 4 runs" in env["note"] and "ServoError" in env["note"]
    assert env["c_MPa"] == pytest.approx(c, rel=1e-9)  # two exact points still define it


def test_lab_points_are_compared_with_each_card(mc_and_hb):
    d, cards, runs, _ = mc_and_hb
    lab = d / "lab_tx.csv"
    lab.write_text("# synthetic\nspecimen,sigma3_MPa,sigma1_MPa\nB2,0,45\nB2,10,"
                   f"{float(hoek_brown_sigma1(10.0, 45.0, 7.5)) * 1.1}\nB1,10,90\n")
    out = d / "out"
    args = _args(cards, runs, out, ["--lab-triaxial", str(lab), "--lab-table",
                                    str(out / "lab.csv")])
    assert main(args) == 0
    comp = pd.read_csv(out / "lab.csv")
    assert len(comp) == 3
    r = comp[(comp["specimen"] == "B2") & (comp["sigma3_MPa"] == 10)].iloc[0]
    assert r["hb_err_pct"] == pytest.approx(100 * (1 / 1.1 - 1), rel=1e-6)
    env = pd.read_csv(out / "env.csv")
    assert set(env["card"]) == {"calibrated", "verified", "lab"}


@pytest.mark.parametrize("text, needle", [
    ("specimen,sigma3_MPa\nB1,5\n", "lacks column(s) ['sigma1_MPa']"),
    ("specimen,sigma3_MPa,sigma1_MPa\nB7,5,80\n", "specimen 'B7' is not in"),
    ("specimen,sigma3_MPa,sigma1_MPa\nB1,-5,80\n", "sigma3_MPa='-5'"),
    ("specimen,sigma3_MPa,sigma1_MPa\nB1,five,80\n", "sigma3_MPa='five'"),
    ("specimen,sigma3_MPa,sigma1_MPa\nB1,10,8\n", "sigma1_MPa=8 <= sigma3_MPa=10"),
])
def test_bad_lab_triaxial_csv_is_one_error_line_and_no_output(mc_and_hb, capsys, text, needle):
    d, cards, runs, _ = mc_and_hb
    lab = d / "bad.csv"
    lab.write_text(text)
    out = d / "out"
    capsys.readouterr()
    code = main(_args(cards, runs, out, ["--lab-triaxial", str(lab), "--lab-table",
                                         str(out / "lab.csv")]))
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bpmcal envelopes: error:"), err
    assert needle in lines[0]
    assert not out.exists() or not any(out.iterdir())


def test_runs_of_another_sigma3_are_bad_input(mc_and_hb, capsys):
    d, cards, runs, _ = mc_and_hb
    runs[0], runs[1] = runs[1], runs[0]
    out = d / "out"
    assert main(_args(cards, runs, out)) == 2
    assert "sigma3 = 5 MPa, expected 0 MPa" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())


def test_bad_lab_triaxial_config_is_refused_before_any_job(tmp_path):
    """The study config: triaxial.lab_csv is checked with the lab CSV's specimens."""
    from bpmcal.study.config import ConfigError, validate_config

    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    bad = tmp_path / "tx.csv"
    bad.write_text("specimen,sigma3_MPa,sigma1_MPa\nB9,-1,80\n")
    cfg["triaxial"] = {"lab_csv": str(bad)}
    with pytest.raises(ConfigError) as e:
        validate_config(cfg, SCHEMA, base_dir=REPO)
    assert "specimen 'B9' is not in lab.csv" in str(e.value) and "sigma3_MPa='-1'" in str(e.value)
