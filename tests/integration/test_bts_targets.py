"""The lab's tensile strength as a calibration target, through the stages and the CLI
(issue 13 item 5): the optional ``bts_MPa`` column is validated, sets the bond-strength
ratio of its specimen, is verified by the closed loop (a Brazilian test per round, with the
round's packing seed, the disc at the study scale), and a σc/σt the models cannot reach
gives a no-exact-fit card that names the missed target. No DEM: synthetic regression
models, and the verify test replaces the two run functions by a synthetic 'DEM'."""
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from support.synthetic import FIXED, RANGES, TRUTH, dem_response, models, predict, write_models

from bpmcal.analysis.calibration import LoopSettings, Multistart, SearchSpace, invert
from bpmcal.cli import main
from bpmcal.io.h5 import RunRecord, check_run_file, write_run
from bpmcal.lab.runner import Geometry
from bpmcal.lab.ucs import UCSSettings
from bpmcal.params import BTS, PARAMS
from bpmcal.stages import measure as M
from bpmcal.stages import verification as V
from bpmcal.stages import verification_tables as VT
from bpmcal.stages.runs import RunOutcome

R = RANGES
HEAD = "specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3"


def at(params):
    return predict(models(), params)


def models_json(path, with_bts=True):
    return write_models(path, {r: m for r, m in models().items() if with_bts or r != BTS})


PLANTED = {**FIXED, **TRUTH, "pb_ten_MPa": 1.6 * TRUTH["pb_coh_MPa"]}  # ratio 1.6, not 1.4
T = at(PLANTED)
FAR = at({**FIXED, **TRUTH, "pb_ten_MPa": 35.0})  # its σt replaced by σc / 15 below


def lab_row(name, t, bts=""):
    return f"{name},{t['ucs_MPa']!r},{t['E_GPa']!r},{t['nu']!r},,{bts}\n"


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    d = tmp_path_factory.mktemp("bts_inputs")
    rng = np.random.default_rng(1)
    rows = []
    for i in range(30):  # the dataset is read (and only used by the bootstrap)
        p = {k: lo + (hi - lo) * rng.random() for k, (lo, hi) in R.items()}
        rows.append({"sample_id": f"s{i:03d}", **p, **at(p), "seed": i, "status": "ok", "error": ""})
    pd.DataFrame(rows).to_csv(d / "dataset.csv", index=False)
    models_json(d / "models.json")
    models_json(d / "models_nobts.json", with_bts=False)
    (d / "lab.csv").write_text(HEAD + ",bts_MPa\n" + lab_row("B1", T, repr(T[BTS]))
                               + lab_row("B2", FAR, repr(FAR["ucs_MPa"] / 15)) + lab_row("B3", T))
    (d / "lab_plain.csv").write_text(HEAD + "\n" + lab_row("B3", T)[:-2] + "\n")
    (d / "lab_blank.csv").write_text(HEAD + ",bts_MPa\n" + lab_row("B3", T))
    for name, bad in (("neg", "-1"), ("zero", "0"), ("text", "abc"), ("nan", "nan")):
        (d / f"lab_{name}.csv").write_text(HEAD + ",bts_MPa\n" + lab_row("B1", T, bad))
    (d / "lab_b1.csv").write_text(HEAD + ",bts_MPa\n" + lab_row("B1", T, repr(T[BTS])))
    # the lab's disc diameter (issue 56): > 0, numeric, with its row's bts_MPa
    for name, bad in (("dneg", "-50"), ("dzero", "0"), ("dtext", "fifty")):
        (d / f"lab_{name}.csv").write_text(HEAD + ",bts_MPa,bts_diameter_mm\n"
                                           + lab_row("B1", T, f"{T[BTS]!r},{bad}"))
    (d / "lab_dalone.csv").write_text(HEAD + ",bts_MPa,bts_diameter_mm\n"
                                      + lab_row("B1", T, ",50"))
    (d / "lab_diam.csv").write_text(HEAD + ",bts_MPa,bts_diameter_mm\n"
                                    + lab_row("B1", T, f"{T[BTS]!r},50"))
    return d


def calibrate(d, o, lab="lab.csv", specs=("B1", "B2", "B3"), models="models.json", n_boot=0):
    argv = ["calibrate", "--dataset", str(d / "dataset.csv"), "--models", str(d / models),
            "--lab", str(d / lab), "--cards", *[str(o / f"{s}.yaml") for s in specs],
            "--ranges", json.dumps(R), "--fixed", json.dumps(FIXED), "--ratio", "1.4",
            "--n-boot", str(n_boot), "--seed", "0"]
    return main(argv)


@pytest.fixture(scope="module")
def cards(d, tmp_path_factory):
    o = tmp_path_factory.mktemp("cards")
    assert calibrate(d, o) == 0
    return {s: yaml.safe_load((o / f"{s}.yaml").read_text()) for s in ("B1", "B2", "B3")} | {"dir": o}


def test_sigma_t_sets_the_ratio_of_its_specimen(cards):
    c = cards["B1"]
    assert c["status"] == "ok" and c["missed"] == []
    assert c["targets"][BTS] == pytest.approx(T[BTS])
    assert c["ratio_ten_coh"] is None and c["roles"]["pb_ten_MPa"] == "free"
    assert c["strength_ratio"]["set_by"] == "bts_MPa target"
    assert c["strength_ratio"]["value"] == pytest.approx(1.6, rel=1e-5)  # the planted ratio
    assert c["parameters"]["pb_ten_MPa"] == pytest.approx(PLANTED["pb_ten_MPa"], rel=1e-5)


def test_unreachable_ucs_over_bts_card_is_no_exact_fit_and_names_the_miss(cards):
    c = cards["B2"]
    assert c["status"] == "no-exact-fit"
    missed = {m["target"]: m for m in c["missed"]}
    assert BTS in missed and missed[BTS]["error_pct"] > 1.0
    assert missed[BTS]["error_pct"] == pytest.approx(c["residuals_pct"][BTS])
    assert set(c["targets"]) == {"ucs_MPa", "E_GPa", "nu", BTS}  # nothing dropped
    assert c["reach"]["ucs_over_bts"][1] < 15 and "σc/σt = 15" in c["message"]
    assert f"bts_MPa {missed[BTS]['error_pct']:+.2f} %" in c["message"]


def test_a_blank_sigma_t_is_not_a_target(cards):
    c = cards["B3"]
    assert set(c["targets"]) == {"ucs_MPa", "E_GPa", "nu"}
    assert c["ratio_ten_coh"] == 1.4 and c["roles"]["pb_ten_MPa"] == "derived"
    assert c["strength_ratio"] == {"value": pytest.approx(1.4), "set_by": "config calibration.ratio"}


def test_a_lab_csv_without_bts_is_calibrated_as_before(d, tmp_path):
    """Without the column (or with it empty) the card is the plain UCS inversion at the
    configured ratio: the same solution as invert() with the three targets."""
    cards = {}
    for lab in ("lab_plain.csv", "lab_blank.csv"):
        o = tmp_path / lab
        assert calibrate(d, o, lab=lab, specs=("B3",), models="models_nobts.json", n_boot=5) == 0
        cards[lab] = yaml.safe_load((o / "B3.yaml").read_text())
    a, b = cards["lab_plain.csv"], cards["lab_blank.csv"]
    for k in set(a) | set(b):
        if k not in ("provenance", "lab"):
            assert a[k] == b[k], k
    targets = {k: T[k] for k in ("ucs_MPa", "E_GPa", "nu")}
    ref = invert(models(), targets, FIXED, SearchSpace(ranges=R, ratio=1.4), search=Multistart(seed=0))
    assert a["targets"] == pytest.approx(targets)
    assert a["status"] == ref.status and a["missed"] == []
    for k in PARAMS:
        assert a["parameters"][k] == pytest.approx(ref.solution[k], rel=1e-9), k
    assert a["roles"]["pb_ten_MPa"] == "derived" and a["ratio_ten_coh"] == 1.4


def test_the_bootstrap_refits_the_sigma_t_model(d, tmp_path):
    assert calibrate(d, tmp_path, lab="lab_b1.csv", specs=("B1",), n_boot=5) == 0
    c = yaml.safe_load((tmp_path / "B1.yaml").read_text())
    q = {i["quantity"]: i for i in c["bootstrap"]["intervals"]}
    assert {"pb_ten_MPa", BTS} <= set(q) and q["pb_ten_MPa"]["n"] == 5


@pytest.mark.parametrize("lab, needle", [
    ("lab_neg.csv", "bts_MPa='-1': expected a positive number (or empty)"),
    ("lab_zero.csv", "bts_MPa='0': expected a positive number (or empty)"),
    ("lab_text.csv", "bts_MPa='abc': expected a positive number (or empty)"),
    ("lab_nan.csv", "bts_MPa='nan': expected a positive number (or empty)"),
    ("lab_dneg.csv", "bts_diameter_mm='-50': expected a positive number (or empty)"),
    ("lab_dzero.csv", "bts_diameter_mm='0': expected a positive number (or empty)"),
    ("lab_dtext.csv", "bts_diameter_mm='fifty': expected a positive number (or empty)"),
    ("lab_dalone.csv", "gives bts_diameter_mm without bts_MPa"),
])
def test_bad_sigma_t_is_one_line_exit_2_nothing_written(d, tmp_path, capsys, lab, needle):
    o = tmp_path / "out"
    rc = calibrate(d, o, lab=lab, specs=("B1",))
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1, err
    assert lines[0].startswith("bpmcal calibrate: error: ") and needle in lines[0], err
    assert "specimen B1" in lines[0] and "Traceback" not in err
    assert not o.exists() or not any(o.rglob("*"))


def test_the_lab_disc_diameter_is_read_and_is_no_target(d, tmp_path):
    """``bts_diameter_mm`` says where the lab measured σt; it is not a target itself."""
    assert calibrate(d, tmp_path, lab="lab_diam.csv", specs=("B1",)) == 0
    c = yaml.safe_load((tmp_path / "B1.yaml").read_text())
    assert set(c["targets"]) == {"ucs_MPa", "E_GPa", "nu", BTS}


def test_sigma_t_without_a_sigma_t_model_is_one_line_exit_2(d, tmp_path, capsys):
    o = tmp_path / "out"
    rc = calibrate(d, o, lab="lab_b1.csv", specs=("B1",), models="models_nobts.json")
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1, err
    assert "has no model of bts_MPa" in lines[0] and "['B1']" in lines[0]
    assert not o.exists() or not any(o.rglob("*"))


# ------------------------------------------------------------------------ verify
class FakeDEM:
    """A synthetic 'DEM' in place of run_ucs_file / run_bts_file: the regression's
    responses off by a few % (σt by more), and a record of every call."""

    def __init__(self):
        self.calls = []

    def _resp(self, params):
        return dem_response(at(params))

    def ucs(self, out, params, seed, geometry, settings, **kw):
        self.calls.append(("ucs", seed, geometry))
        y = self._resp(params)
        s = {k: y[k] for k in ("ucs_MPa", "E_GPa", "nu")} | {"u_pre_MJm3": 0.1, "peak_strain": 0.01,
                                                              "cracks_tension": 1, "cracks_shear": 1}
        write_run(out, RunRecord(test="ucs", inputs={"seed": seed}, summary=s))
        return RunOutcome(status="ok", summary=s, path=out)

    def bts(self, out, params, seed, geometry, settings, **kw):
        self.calls.append(("bts", seed, geometry))
        s = {BTS: self._resp(params)[BTS]}
        write_run(out, RunRecord(test="bts", inputs={"seed": seed}, summary=s))
        return RunOutcome(status="ok", summary=s, path=out)


@pytest.fixture()
def dem(monkeypatch):
    f = FakeDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", f.ucs)
    monkeypatch.setitem(M.RUNNERS, "bts", f.bts)
    return f


def _verify(cards, d, spec, o, max_rounds=8, seeds_per_round=1):
    return V.verify(cards["dir"] / f"{spec}.yaml", d / "models.json", out_card=o / f"{spec}.yaml",
                    rounds=o / f"{spec}.csv", run=o / f"{spec}.h5", bts_run=o / f"{spec}.bts.h5",
                    tests=M.SeedTests(Geometry(scale=0.4), UCSSettings()),
                    loop=LoopSettings(seed=7, rtol=0.01, max_rounds=max_rounds,
                                      seeds_per_round=seeds_per_round,
                                      tensile_specimens=1))  # one disc per seed: its
    # order of runs is what these tests read (several: tests/integration/test_dtt_targets.py)


def test_every_seed_of_a_round_gets_its_brazilian_test(cards, d, tmp_path, dem):
    """Seed-averaged loop: each packing seed of a round runs UCS and Brazilian with that
    seed (each a job of its own, the round's UCS tests first: verification.seed_parts),
    and the card records σt's seed mean and n_seeds."""
    v = _verify(cards, d, "B1", tmp_path, max_rounds=2, seeds_per_round=2)["verification"]
    assert [(c[0], c[1]) for c in dem.calls[:4]] == [("ucs", 7), ("ucs", 8), ("bts", 7),
                                                      ("bts", 8)]
    assert v["n_seeds"] == 2 and v["closed_loop"]["n_seeds"] == 2
    assert "bts_MPa" in v["closed_loop"]["seed_sd"]


def test_verify_runs_a_brazilian_test_per_round_and_steers_sigma_t(cards, d, tmp_path, dem):
    v = _verify(cards, d, "B1", tmp_path)["verification"]
    kinds = [c[0] for c in dem.calls]
    assert kinds == ["ucs", "bts"] * (len(kinds) // 2) and v["rounds"] == len(kinds) // 2
    assert {c[1] for c in dem.calls} == {7}  # the same packing seed for both tests
    disc = [c[2] for c in dem.calls if c[0] == "bts"][0]
    assert (disc.scale, disc.diameter_mm, disc.height_mm) == (0.4, 50.0, 25.0)
    assert v["bts_geometry"]["diameter_mm"] == pytest.approx(20.0)
    # round 1 (the regression's answer) misses σt by the 'DEM's 6 %; the loop fixes it
    assert v["single_pass"]["errors_pct"][BTS] == pytest.approx(6.0, abs=0.5)
    assert v["status"] == "converged" and v["missed"] == []
    assert abs(v["closed_loop"]["errors_pct"][BTS]) <= 1.0
    rounds = pd.read_csv(tmp_path / "B1.csv")
    assert f"err_{BTS}" in rounds.columns
    assert check_run_file(tmp_path / "B1.bts.h5")["test"] == "bts"


def test_verify_of_a_no_exact_fit_card_records_the_missed_target(cards, d, tmp_path, dem):
    v = _verify(cards, d, "B2", tmp_path, max_rounds=3)["verification"]
    assert v["status"] != "converged"
    missed = {m["target"]: m for m in v["missed"]}
    assert BTS in missed and missed[BTS]["error_pct"] > 1.0
    assert missed[BTS]["dem"] == pytest.approx(v["closed_loop"][BTS])
    t5 = tmp_path / "t5.csv"
    VT.verification_tables([tmp_path / "B2.yaml"], [tmp_path / "B2.h5"], d / "lab.csv",
                          table5=t5, table6=tmp_path / "t6.csv", figure=tmp_path / "f6.png")
    row = pd.read_csv(t5, index_col=0).loc["B2"]
    assert math.isclose(row[f"closed_loop_{BTS}_err_pct"], missed[BTS]["error_pct"])
    assert f"bts_MPa {missed[BTS]['error_pct']:+.2f} %" in row["missed"]


def test_verify_without_sigma_t_runs_no_brazilian_test(cards, d, tmp_path, dem):
    v = _verify(cards, d, "B3", tmp_path, max_rounds=2)["verification"]
    assert {c[0] for c in dem.calls} == {"ucs"} and BTS not in v["closed_loop"]
    rec = check_run_file(Path(tmp_path / "B3.bts.h5"))
    assert rec["status"] == "failed" and "no tensile-strength target" in rec["error"]


def test_the_report_names_the_missed_target_and_the_ratio_set_by_sigma_t(cards, d, tmp_path, dem):
    import shutil

    from bpmcal.io import study_files as L
    from bpmcal.report.build import _calibration
    from bpmcal.report.verification import section

    lay = L.StudyFiles(tmp_path / "study")
    for s in ("B1", "B2"):
        Path(lay.card(s)).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(cards["dir"] / f"{s}.yaml", lay.card(s))
    Path(lay.table(L.CALIBRATION)).parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame({"specimen": ["B1", "B2"]}).to_csv(lay.table(L.CALIBRATION), index=False)
    cfg = {"calibration": {"strength_ratio": 1.4}, "ratio_sweep": {"enabled": False}}
    text = _calibration(lay, cfg, [])
    b2 = cards["B2"]
    miss = next(m for m in b2["missed"] if m["target"] == BTS)
    assert "B2: target bts_MPa missed by the calibration" in text
    assert f"({miss['error_pct']:+.2f} %)" in text
    assert "B1: the lab tensile strength" in text and f"{cards['B1']['strength_ratio']['value']:.3f}" in text
    v = tmp_path / "v"
    v.mkdir()
    _verify(cards, d, "B2", v, max_rounds=2)
    VT.verification_tables([v / "B2.yaml"], [v / "B2.h5"], d / "lab.csv", table5=lay.table(L.TABLE5),
                          table6=lay.table(L.TABLE6), figure=tmp_path / "f6.png")
    text = section(lay, [])
    assert "| B2 | sigma_t |" in text and "B2: target(s) missed by the closed loop" in text


def test_a_disc_too_small_for_the_balls_is_refused_before_any_run(cards, d, tmp_path, dem):
    """At scale 0.3 the ISRM disc is 15 x 7.5 mm, less than 3 diameters of Rmax = 1.66 x
    0.8 mm: refused before the first round (not after its UCS run)."""
    from bpmcal.io.checks import BadInput

    o = tmp_path / "o"
    with pytest.raises(BadInput, match=r"Brazilian disc at scale 0.3 \(15 x 7.5 mm\)"):
        V.verify(cards["dir"] / "B1.yaml", d / "models.json", out_card=o / "B1.yaml",
                 rounds=o / "B1.csv", run=o / "B1.h5",
                 tests=M.SeedTests(Geometry(scale=0.3), UCSSettings()),
                 loop=LoopSettings(seed=7, seeds_per_round=1))
    assert dem.calls == [] and not o.exists()


@pytest.mark.parametrize("scale, ok", [(0.25, False), (0.4, True)])
def test_the_study_config_refuses_a_disc_too_small_for_a_lab_sigma_t(tmp_path, scale, ok):
    """Rmax = 1.66 x 0.8 mm (the default calibration.fixed.rmin_mm, the cards' Rmin): the
    25 mm-thick disc needs bts.scale >= 0.319; checked with the config, before any job; a
    lab CSV without σt is not concerned."""
    from bpmcal.study.config import ConfigError, validate_config

    repo = Path(__file__).resolve().parents[2]
    schema = repo / "workflow" / "schemas" / "config.schema.yaml"
    cfg = yaml.safe_load((repo / "config" / "config.yaml").read_text())
    cfg["study"]["reference"] = "none"
    cfg["bts"]["scale"] = scale
    cfg["bts"]["enabled"] = True
    cfg["ranges"]["rmin_mm"] = [0.6, 0.8]  # the samples' discs fit at 0.4 too
    lab = tmp_path / "lab.csv"
    lab.write_text(HEAD + ",bts_MPa\n" + lab_row("B1", T, "8.0"))
    cfg["lab"]["csv"] = str(lab)
    if ok:
        validate_config(cfg, schema, base_dir=repo)
        return
    with pytest.raises(ConfigError) as e:
        validate_config(cfg, schema, base_dir=repo)
    assert "specimen(s) ['B1'] give bts_MPa" in str(e.value)
    assert "bts.scale 0.25: 12.5 x 6.25 mm" in str(e.value)
    assert "raise bts.scale to at least 0.319" in str(e.value)
    assert "calibration.fixed.rmin_mm 0.8 mm" in str(e.value)
    lab.write_text(HEAD + ",bts_MPa\n" + lab_row("B1", T, ""))  # no σt: no disc, no problem
    try:
        validate_config(cfg, schema, base_dir=repo)
    except ConfigError as e2:
        assert "bts_MPa" not in str(e2)
