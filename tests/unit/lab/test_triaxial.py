"""Triaxial test on small specimens: the unconfined limit, the confinement effect, the servo."""
import json
import time
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest
from support.lab_util import A1, FAST, SMALL

from bpmcal.cli import main
from bpmcal.dem.errors import InputError
from bpmcal.io import h5
from bpmcal.io.vtk import export_run
from bpmcal.lab.runner import make_specimen
from bpmcal.lab.servo import ServoError
from bpmcal.lab.triaxial import TriaxialSettings, run_triaxial
from bpmcal.lab.ucs import run_ucs
from bpmcal.stages.runs import run_triaxial_file

SEED = 3
TX = dict(platen_velocity=FAST.platen_velocity, record_strain=FAST.record_strain)


def triaxial(cache, sigma3_MPa, seed=SEED, **kw):
    sp = make_specimen(A1, seed, SMALL, cache=cache, boundary="vessel")
    return run_triaxial(sp, TriaxialSettings(sigma3=sigma3_MPa * 1e6, **TX, **kw))


def params_file(d):
    pf = d / "a1.yaml"
    pf.write_text("\n".join(f"{k}: {v}" for k, v in A1.items()))
    return pf


@pytest.fixture(scope="module")
def runs(cache, tmp_path_factory):
    out = {s3: triaxial(cache, s3) for s3 in (0.0, 5.0)}
    # the third point through the command line: parameter file -> one HDF5 run file
    d = tmp_path_factory.mktemp("triaxial")
    f = d / "tx10.h5"
    assert main(["triaxial", "--params", str(params_file(d)), "--sigma3", "10", "--out",
                 str(f), "--scale", str(SMALL.scale), "--seed", str(SEED),
                 "--platen-velocity", str(FAST.platen_velocity), "--record-strain",
                 str(FAST.record_strain), "--specimen-cache", str(cache), "--quiet"]) == 0
    ser = h5.read_series(f)
    out[10.0] = SimpleNamespace(summary=h5.read_summary(f), path=f,
                                series={k: ser[k].to_numpy() for k in ser})
    return out


def test_unconfined_triaxial_reproduces_the_ucs_test(runs, cache):
    """sigma3 = 0 (servo-controlled cylinder, consolidation to zero stress) against the UCS
    test (no cylinder) on the same packing: well inside the packing scatter (3.3 % CV of
    sigma_c, 0.9 % of E, 1.2 % of nu: docs/measurements/2026-11-23-brazilian-and-triaxial-a1.md)."""
    u = run_ucs(make_specimen(A1, SEED, SMALL, cache=cache), FAST).summary
    t = runs[0.0].summary
    assert t["sigma1_MPa"] == pytest.approx(u["ucs_MPa"], rel=0.03)
    assert t["E_GPa"] == pytest.approx(u["E_GPa"], rel=0.01)
    assert abs(t["nu"] - u["nu"]) < 0.01
    # the wall retreats from the bulging surface: the lateral stress stays negligible
    assert t["sigma3_maxdev_MPa"] < 0.005 * t["sigma1_MPa"]


def test_peak_axial_stress_rises_with_confinement(runs):
    s1 = [runs[s3].summary["sigma1_MPa"] for s3 in (0.0, 5.0, 10.0)]
    assert s1[0] < s1[1] < s1[2], s1
    # a frictional material: sigma1 grows faster than sigma3 (q > 1)
    assert (s1[2] - s1[0]) / 10.0 > 1.5
    for s3 in (0.0, 5.0, 10.0):
        s = runs[s3].summary
        assert s["stop_reason"] == "post_peak_drop"
        assert s["sigma1_MPa"] == pytest.approx(s3 + s["deviator_MPa"])


@pytest.mark.parametrize("s3", [5.0, 10.0])
def test_servo_holds_sigma3_within_one_percent_up_to_the_peak(runs, s3):
    r = runs[s3]
    ser = r.series
    ip = int(np.argmax(ser["deviator"]))
    dev = np.abs(ser["confining_stress"][: ip + 1] / (s3 * 1e6) - 1.0)
    assert ip > 20 and dev.max() < 0.01, dev.max()
    assert r.summary["sigma3_maxdev_rel"] == pytest.approx(dev.max())
    # the lateral stress is the radial wall force over the current wall area
    assert ser["wall_radius"][ip] > ser["wall_radius"][0]  # the specimen dilates
    # consolidation reached sigma3 on all walls before loading
    assert abs(ser["confining_stress"][0] / (s3 * 1e6) - 1) < 0.005
    assert abs(ser["axial_stress"][0] / (s3 * 1e6) - 1) < 0.005


def test_confined_moduli_and_strain_definitions(runs):
    """E from the deviator is nearly independent of sigma3 for bonded particles (the bonds
    carry tension and compression alike); nu from the surface balls agrees with the wall's
    radius change under confinement, where the rigid wall holds the surface."""
    e0 = runs[0.0].summary["E_GPa"]
    for s3 in (5.0, 10.0):
        s = runs[s3].summary
        assert s["E_GPa"] == pytest.approx(e0, rel=0.05)
        assert abs(s["nu"] - s["nu_wall"]) < 0.02
        ser = runs[s3].series
        assert np.allclose(ser["volumetric_strain"],
                           ser["axial_strain"] + 2 * ser["lateral_strain"])


def test_triaxial_settings_refuse_bad_values():
    for kw, needle in [(dict(sigma3=-1e6), "sigma3=-1000000.0"),
                       (dict(sigma3=float("nan")), "sigma3=nan"),
                       (dict(servo_alpha=1.5), "servo_alpha=1.5"),
                       (dict(servo_interval=0), "servo_interval=0")]:
        with pytest.raises(InputError, match=needle):
            TriaxialSettings(**kw)


def test_run_file_summary_json_and_vtk(runs, tmp_path, capsys):
    r = runs[10.0]
    assert r.summary["test"] == "triaxial" and r.summary["status"] == "ok"
    inp = h5.read_inputs(r.path)
    assert inp["sigma3_MPa"] == 10.0 and inp["seed"] == SEED and inp["scale"] == SMALL.scale
    assert main(["summary", str(r.path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    for k in ("sigma1_MPa", "sigma3_MPa", "E_GPa", "nu"):
        assert isinstance(d[k], float), k
    assert d["sigma3_MPa"] == 10.0 and d["sigma1_MPa"] > 10.0
    files = {f.name for f in export_run(r.path, tmp_path / "vtk")}
    assert {"particles_initial.vtp", "particles_final.vtp", "cracks.vtp", "run.pvd"} <= files
    cr = ET.parse(tmp_path / "vtk" / "cracks.vtp").getroot().find("PolyData/Piece")
    assert int(cr.get("NumberOfPoints")) == d["cracks_tension"] + d["cracks_shear"]


def test_a_consolidation_that_does_not_converge_gives_a_failure_record(tmp_path, cache,
                                                                        monkeypatch):
    def stuck(*a, **k):
        raise ServoError("consolidation to sigma3 = 10 MPa did not converge: ...")
    monkeypatch.setattr("bpmcal.lab.triaxial.consolidate", stuck)
    out = tmp_path / "f.h5"
    res = run_triaxial_file(out, A1, SEED, SMALL, TriaxialSettings(sigma3=10e6), cache=cache)
    assert res.status == "failed" and "did not converge" in res.error
    s = h5.read_summary(out)
    assert s["status"] == "failed" and s["test"] == "triaxial"
    assert h5.read_inputs(out)["sigma3_MPa"] == 10.0


@pytest.mark.parametrize("args, needle", [
    (["--sigma3", "-5"], "sigma3='-5'"),
    (["--sigma3", "abc"], "sigma3='abc'"),
    (["--sigma3", "nan"], "sigma3='nan'"),
    (["--sigma3", "inf"], "sigma3='inf'"),
    (["--sigma3", "5", "--servo-alpha", "2"], "servo-alpha='2'"),
    (["--sigma3", "5", "--servo-gain", "2"], "--servo-gain"),  # the pre-release spelling: unknown
    (["--sigma3", "5", "--servo-interval", "0"], "servo-interval='0'"),
    (["--sigma3", "5", "--set", "pb_ten_MPa=abc"], "pb_ten_MPa"),
])
def test_cli_rejects_bad_input_with_one_line_and_no_file(tmp_path, capsys, args, needle):
    out = tmp_path / "o.h5"
    t0 = time.perf_counter()
    assert main(["triaxial", "--params", str(params_file(tmp_path)), "--out", str(out),
                 *args]) == 2
    assert time.perf_counter() - t0 < 5  # before any work
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and "error" in err[0], err
    assert not out.exists()


def test_same_seed_and_inputs_give_the_same_run(runs, cache):
    """Deterministic: the servo runs in Python on the engine's state, nothing random."""
    again = triaxial(cache, 5.0)
    for k, v in runs[5.0].series.items():
        assert np.array_equal(again.series[k], v), k
