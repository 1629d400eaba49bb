"""A triaxial strength at the study's design confinement (``tri_MPa``, σ1 at failure at
``triaxial.design_sigma3_MPa``) as a fifth target: validated in the lab CSV and the config,
gathered from the samples' triaxial run files, inverted with one more free parameter, and
verified by the closed loop and the fresh-seed check with a triaxial test per seed. No
DEM: the synthetic models of tests/support/synthetic.py plus a triaxial model, and a synthetic
'DEM' in place of the run functions."""

import numpy as np
import pandas as pd
import pytest
import yaml
from support.repo import REPO, SCHEMA, merged_config
from support.synthetic import FIXED, RANGES, TRUTH, calibrate_b1, dem_response, models, predict, write_models

from bpmcal.analysis.calibration import LoopSettings
from bpmcal.analysis.stepwise import RegressionModel
from bpmcal.cli import main
from bpmcal.io.checks import BadInput
from bpmcal.io.h5 import RunRecord, write_run
from bpmcal.lab.runner import Geometry
from bpmcal.lab.triaxial import TriaxialSettings
from bpmcal.lab.ucs import UCSSettings
from bpmcal.params import BTS, TRI
from bpmcal.stages import fresh_seeds as F
from bpmcal.stages import measure as M
from bpmcal.stages import verification as V
from bpmcal.stages.runs import RunOutcome
from bpmcal.study.config import ConfigError, validate_config
from bpmcal.study.gather import gather

R = RANGES
HEAD = "specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3,bts_MPa,tri_MPa\n"
S3 = 10.0  # MPa, the design confinement
#: the friction angle is free: σ1 at the design σ3 depends on it, σc, E, ν and σt do not
FIXED_TRI = {k: v for k, v in FIXED.items() if k != "pb_fa_deg"}
FREE = "pb_emod_GPa,pb_kratio,pb_coh_MPa,pb_fa_deg"


def tri_models():
    """The synthetic models plus σ1 at the design σ3: σc's terms and a friction-angle term
    (the envelope's slope), so that σ1 - σc measures φp."""
    ms = models()
    u = ms["ucs_MPa"]
    ms[TRI] = RegressionModel(TRI, [*u.terms, ("pb_fa_deg",)], [*u.coef, 2.0],
                              u.intercept + S3)
    return ms


PLANTED = {**FIXED_TRI, **TRUTH, "pb_fa_deg": 38.0, "pb_ten_MPa": 1.5 * TRUTH["pb_coh_MPa"]}
T = predict(tri_models(), PLANTED)


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    d = tmp_path_factory.mktemp("tri_inputs")
    rng = np.random.default_rng(2)
    rows = []
    for i in range(40):
        p = {k: lo + (hi - lo) * rng.random() for k, (lo, hi) in R.items()}
        rows.append({"sample_id": f"s{i:03d}", **p, **predict(tri_models(), p), "seed": i,
                     "status": "ok", "error": "", "bts_status": "ok", "bts_error": "",
                     "tri_status": "ok", "tri_error": ""})
    pd.DataFrame(rows).to_csv(d / "dataset.csv", index=False)
    ms = tri_models()
    write_models(d / "models.json", ms)
    write_models(d / "models_no_tri.json", {r: m for r, m in ms.items() if r != TRI})
    (d / "lab.csv").write_text(HEAD + f"B1,{T['ucs_MPa']!r},{T['E_GPa']!r},{T['nu']!r},,"
                               f"{T[BTS]!r},{T[TRI]!r}\n")
    return d


def calibrate(d, o, models="models.json"):
    return calibrate_b1(d, o, models=models, fixed=FIXED_TRI, options=("--free", FREE))


@pytest.fixture(scope="module")
def card(d, tmp_path_factory):
    o = tmp_path_factory.mktemp("cards")
    assert calibrate(d, o) == 0
    return o / "B1.yaml"


def test_the_triaxial_strength_is_a_target_and_recovers_the_planted_card(card):
    c = yaml.safe_load(card.read_text())
    assert c["status"] == "ok", c["message"]
    assert c["targets"][TRI] == pytest.approx(T[TRI]) and BTS in c["targets"]
    for k in ("pb_emod_GPa", "pb_kratio", "pb_coh_MPa", "pb_fa_deg", "pb_ten_MPa"):
        assert c["parameters"][k] == pytest.approx(PLANTED[k], rel=1e-3), k
    assert c["roles"]["pb_fa_deg"] == "free"


def test_a_triaxial_target_without_its_model_is_one_line_exit_2(d, tmp_path, capsys):
    rc = calibrate(d, tmp_path / "o", models="models_no_tri.json")
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert "a triaxial strength (tri_MPa)" in err[0] and "no model of tri_MPa" in err[0]
    assert not (tmp_path / "o" / "B1.yaml").exists()


class FakeDEM:
    """UCS, Brazilian and triaxial 'runs': the models' responses off by a few %."""

    def __init__(self):
        self.calls = []
        self.sigma3 = []

    def ucs(self, out, params, seed, geometry, settings, **kw):
        self.calls.append(("ucs", seed))
        y = dem_response(predict(tri_models(), params))
        s = {k: y[k] for k in ("ucs_MPa", "E_GPa", "nu")} | {
            "u_pre_MJm3": 0.1, "peak_strain": 0.01, "cracks_tension": 1, "cracks_shear": 1}
        write_run(out, RunRecord(test="ucs", inputs={"seed": seed}, summary=s))
        return RunOutcome(status="ok", summary=s, path=out)

    def bts(self, out, params, seed, geometry, settings, **kw):
        self.calls.append(("bts", seed))
        v = dem_response(predict(tri_models(), params))[BTS]
        s = {BTS: v, "bts_valid": True, "bts_peak_MPa": v}
        write_run(out, RunRecord(test="bts", inputs={"seed": seed}, summary=s))
        return RunOutcome(status="ok", summary=s, path=out)

    def tri(self, out, params, seed, geometry, settings, **kw):
        self.calls.append(("tri", seed))
        self.sigma3.append(settings.sigma3)
        v = predict(tri_models(), params)[TRI] * 0.95
        s = {"sigma1_MPa": v, "sigma3_MPa": settings.sigma3 / 1e6}
        write_run(out, RunRecord(test="triaxial", inputs={"seed": seed}, summary=s))
        return RunOutcome(status="ok", summary=s, path=out)

    def install(self, monkeypatch):
        monkeypatch.setitem(M.RUNNERS, "ucs", self.ucs)
        monkeypatch.setitem(M.RUNNERS, "bts", self.bts)
        monkeypatch.setitem(M.RUNNERS, "tri", self.tri)


#: the tests of a seed: the cylinder at scale 0.4, the triaxial test at the design S3
TESTS = M.SeedTests(Geometry(scale=0.4), UCSSettings(),
                    tri_settings=TriaxialSettings(sigma3=S3 * 1e6))


def _verify(card, d, tmp_path, name):
    """The closed loop of ``card`` on seeds 7 and 8 with the design confinement S3."""
    return V.verify(card, d / "models.json", out_card=tmp_path / f"{name}.yaml",
                    rounds=tmp_path / f"{name}.csv", run=tmp_path / f"{name}.h5",
                    tests=TESTS, loop=LoopSettings(seed=7, seeds_per_round=2, max_seeds=2,
                                                   rtol=0.01, max_rounds=8,
                                                   tensile_specimens=1))  # one disc per seed


def test_verify_runs_the_triaxial_test_every_seed_and_steers_sigma1(card, d, tmp_path,
                                                                      monkeypatch):
    dem = FakeDEM()
    dem.install(monkeypatch)
    v = _verify(card, d, tmp_path, "B1")["verification"]
    # each test of a seed a job of its own, the round's UCS tests first (seed_parts)
    assert dem.calls[:6] == [("ucs", 7), ("ucs", 8), ("bts", 7), ("tri", 7), ("bts", 8),
                             ("tri", 8)]
    assert set(dem.sigma3) == {S3 * 1e6}
    # round 1 is off by the 'DEM's -5 % on σ1; the loop steers it within the tolerance
    assert v["single_pass"]["errors_pct"][TRI] == pytest.approx(-5.0, abs=0.5)
    assert v["status"] == "converged", v["message"]
    assert abs(v["closed_loop"]["errors_pct"][TRI]) <= 1.0
    assert v["tri_sigma3_MPa"] == S3
    assert f"err_{TRI}" in pd.read_csv(tmp_path / "B1.csv").columns


def test_verify_runs_the_triaxial_test_on_the_first_seeds_only(card, d, tmp_path, monkeypatch):
    """verification.triaxial_seeds = 2 of 3 seeds: every round runs the triaxial test on
    seeds 7 and 8, never 9; the loop still steers σ1 (on those two), the rounds table
    counts them and the card records the cap."""
    dem = FakeDEM()
    dem.install(monkeypatch)
    v = V.verify(card, d / "models.json", out_card=tmp_path / "C.yaml",
                 rounds=tmp_path / "C.csv", run=tmp_path / "C.h5",
                 tests=TESTS, loop=LoopSettings(seed=7, seeds_per_round=3, max_seeds=3,
                                                rtol=0.01, max_rounds=8,
                                                triaxial_seeds=2))["verification"]
    tri = [s for t, s in dem.calls if t == "tri"]
    ucs = [s for t, s in dem.calls if t == "ucs"]
    assert set(tri) == {7, 8} and set(ucs) == {7, 8, 9}
    assert len(tri) == 2 * v["rounds"] and len(ucs) == 3 * v["rounds"]
    assert v["status"] == "converged", v["message"]
    assert abs(v["closed_loop"]["errors_pct"][TRI]) <= 1.0
    assert v["triaxial_seeds"] == 2
    assert v["closed_loop"]["n_measured"] == {TRI: 2} and v["closed_loop"]["n_seeds"] == 3
    rounds = pd.read_csv(tmp_path / "C.csv")
    assert (rounds[f"n_{TRI}"] == 2).all() and (rounds["n_seeds"] == 3).all()


@pytest.mark.parametrize("bad", ["1", "2.5", "x"])
def test_a_bad_triaxial_seed_count_is_one_line_exit_2(card, d, tmp_path, capsys, bad):
    rc = main(["verify", "--card", str(card), "--models", str(d / "models.json"),
               "--out-card", str(tmp_path / "v.yaml"), "--rounds", str(tmp_path / "r.csv"),
               "--run", str(tmp_path / "r.h5"), "--triaxial-seeds", bad, "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "triaxial-seeds" in err[0] and bad in err[0]
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("n", [1, 0, 2.0, True, 201])
def test_the_settings_refuse_a_bad_triaxial_seed_count(n):
    with pytest.raises(BadInput, match=r"triaxial_seeds=.*expected an integer in 2 \.\. 200"):
        LoopSettings(triaxial_seeds=n)


def test_verify_of_a_triaxial_target_needs_the_design_confinement(card, d, tmp_path, capsys):
    rc = main(["verify", "--card", str(card), "--models", str(d / "models.json"),
               "--out-card", str(tmp_path / "v.yaml"), "--rounds", str(tmp_path / "r.csv"),
               "--run", str(tmp_path / "r.h5"), "--scale", "0.4", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert "tri_MPa" in err[0] and "--design-sigma3" in err[0]
    assert not any(tmp_path.iterdir())


def test_fresh_seeds_run_the_triaxial_test_of_a_triaxial_target(card, d, tmp_path, monkeypatch):
    dem = FakeDEM()
    dem.install(monkeypatch)
    v = _verify(card, d, tmp_path, "V")
    assert v["verification"]["status"] == "converged"
    dem.calls.clear()
    seeds = [101, 102]
    runs = [tmp_path / f"f{s}.h5" for s in seeds]
    bts = [tmp_path / f"f{s}.bts.h5" for s in seeds]
    tri = [tmp_path / f"f{s}.tri.h5" for s in seeds]
    with pytest.raises(Exception, match="--tri-runs"):
        F.fresh_seeds(tmp_path / "V.yaml", seeds=seeds, runs=runs, bts_runs=bts,
                      seed_runs=tmp_path / "fs.csv", tests=TESTS)
    df = F.fresh_seeds(tmp_path / "V.yaml", seeds=seeds, runs=runs, bts_runs=bts,
                       tri_runs=tri, seed_runs=tmp_path / "fs.csv", tests=TESTS)
    assert [c for c in dem.calls if c[0] == "tri"] == [("tri", 101), ("tri", 102)]
    assert (df["status"] == "ok").all() and df[TRI].notna().all()
    table = F.fresh_seeds_table([tmp_path / "V.yaml"], [tmp_path / "fs.csv"],
                                table=tmp_path / "t.csv")
    assert TRI in set(table["response"])


# ------------------------------------------------------------ the sample jobs and the dataset
def test_gather_reads_the_triaxial_run_files(tmp_path):
    design = pd.DataFrame([{"sample_id": f"s{i:03d}", **{k: v[0] for k, v in R.items()},
                            "seed": i} for i in range(3)])
    ucs, tri = {}, {}
    rows = design.to_dict("records")
    for i, sid in enumerate(design["sample_id"]):
        ucs[sid] = tmp_path / f"{sid}.h5"
        inputs = {k: v for k, v in rows[i].items() if k != "sample_id"}  # its design row
        write_run(ucs[sid],
                  RunRecord(test="ucs",
                            inputs=inputs,
                            summary={"ucs_MPa": 100.0 + i, "stop_reason": "post_peak_drop"}))
        tri[sid] = tmp_path / f"{sid}.tri.h5"
    write_run(tri["s000"],
              RunRecord(test="triaxial",
                        inputs={**rows[0], "sample_id": None},
                        summary={"sigma1_MPa": 150.0, "sigma3_MPa": S3, "wall_s": 2.0}))
    write_run(tri["s001"],
              RunRecord(test="triaxial",
                        inputs={**rows[1], "sample_id": None},
                        status="failed",
                        error="ServoError: planted",
                        summary={"wall_s": 1.0}))
    df = gather(design, ucs, tri_files=tri)  # s002: no triaxial run file
    assert df["tri_MPa"].iloc[0] == 150.0 and df["tri_sigma3_MPa"].iloc[0] == S3
    assert list(df["tri_status"]) == ["ok", "failed", "missing"]
    assert np.isnan(df["tri_MPa"].iloc[1]) and "planted" in df["tri_error"].iloc[1]
    assert (df["status"] == "ok").all()  # the UCS tests keep their own status


def test_the_sample_job_refuses_a_triaxial_output_without_its_confinement(tmp_path, capsys):
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump({**FIXED, **TRUTH, "pb_ten_MPa": 30.0}))
    rc = main(["sample", "--params", str(p), "--out", str(tmp_path / "u.h5"),
               "--tri-out", str(tmp_path / "t.h5"), "--scale", "0.2", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--design-sigma3" in err[0], err
    assert not (tmp_path / "u.h5").exists() and not (tmp_path / "t.h5").exists()


@pytest.mark.parametrize("s3, tri, needle", [
    (None, "300", "set triaxial.design_sigma3_MPa"),
    (10.0, "8", "is not above triaxial.design_sigma3_MPa = 10 MPa"),
    (10.0, "strong", "tri_MPa='strong': expected a positive number (or empty)"),
])
def test_a_lab_triaxial_strength_needs_its_confinement(tmp_path, s3, tri, needle):
    lab = tmp_path / "lab.csv"
    lab.write_text("specimen,ucs_MPa,E_GPa,nu,tri_MPa\nR1,150,50,0.25," + tri + "\n")
    cfg = merged_config("config.yaml", "examples/lac_du_bonnet.yaml")
    cfg["lab"]["csv"] = str(lab)
    cfg["triaxial"]["lab_csv"] = None
    cfg["triaxial"]["design_sigma3_MPa"] = s3
    with pytest.raises(ConfigError, match="tri_MPa") as e:
        validate_config(cfg, SCHEMA, base_dir=REPO)
    assert needle in str(e.value)
    cfg["triaxial"]["design_sigma3_MPa"] = 10.0
    if tri == "300":
        validate_config(cfg, SCHEMA, base_dir=REPO)  # with its confinement: accepted


@pytest.mark.parametrize("s3", [0.0, -5.0, "ten"])
def test_the_design_confinement_is_a_positive_stress(s3):
    cfg = merged_config("config.yaml")
    cfg["triaxial"]["design_sigma3_MPa"] = s3
    with pytest.raises(ConfigError, match="design_sigma3_MPa"):
        validate_config(cfg, SCHEMA, base_dir=REPO)


def test_the_sample_job_runs_the_triaxial_test_on_the_dem(tmp_path):
    """``bpmcal sample --tri-out --design-sigma3`` on a real (tiny) specimen: the triaxial run
    file holds σ1 at the confinement asked, above the same packing's σc, and the dataset
    reads it."""
    from bpmcal.io.h5 import read_inputs, read_summary

    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump({**FIXED, **TRUTH, "pb_ten_MPa": 30.0}))
    u, t = tmp_path / "s000.h5", tmp_path / "tri" / "s000.h5"
    t.parent.mkdir()
    assert main(["sample", "--params", str(p), "--out", str(u), "--tri-out", str(t),
                 "--design-sigma3", "5", "--scale", "0.2", "--platen-velocity", "0.2",
                 "--threads", "1", "--quiet"]) == 0
    su, st = read_summary(u), read_summary(t)
    assert st["status"] == "ok" and st["sigma3_MPa"] == 5.0
    assert st["sigma1_MPa"] > su["ucs_MPa"] + 5.0
    assert read_inputs(t)["seed"] == read_inputs(u)["seed"]  # the same packing seed
    design = pd.DataFrame([{"sample_id": "s000", **{**FIXED, **TRUTH, "pb_ten_MPa": 30.0},
                            "seed": 1}])
    df = gather(design, {"s000": u}, tri_files={"s000": t})
    assert df.loc[0, "tri_MPa"] == pytest.approx(st["sigma1_MPa"])


def test_the_design_triaxial_test_stops_at_its_own_drop(capsys):
    """Only its peak is used: it stops at --design-stop-drop (default 0.9 of the peak),
    while the UCS test of the same job keeps --stop-drop."""
    from bpmcal.cli import build_parser
    from bpmcal.cli.options import DESIGN_STOP_DROP, run_settings, tri_settings_of

    base = ["sample", "--params", "p.yaml", "--out", "u.h5", "--stop-drop", "0.7"]
    a = build_parser().parse_args([*base, "--design-sigma3", "10"])
    st = tri_settings_of(a)
    assert st.stop_drop == DESIGN_STOP_DROP == 0.9 and st.sigma3 == 10e6
    assert run_settings(a).stop_drop == 0.7
    assert tri_settings_of(build_parser().parse_args(
        [*base, "--design-sigma3", "10", "--design-stop-drop", "0.8"])).stop_drop == 0.8
    assert tri_settings_of(build_parser().parse_args(base)) is None
    with pytest.raises(SystemExit) as e:
        build_parser().parse_args([*base, "--design-stop-drop", "1.0"])
    assert e.value.code == 2 and "design-stop-drop" in capsys.readouterr().err
