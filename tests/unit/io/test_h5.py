"""One HDF5 file per run: round trip, atomic writes, failure records, CLI, VTK."""
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from support.paper import A1, FAST, SMALL

from bpmcal.cli import main
from bpmcal.dem.errors import InstabilityError
from bpmcal.io import h5
from bpmcal.io.vtk import export_run
from bpmcal.lab import runner
from bpmcal.stages.runs import run_ucs_file


@pytest.fixture(scope="module")
def run(tmp_path_factory, packing_cache):
    d = tmp_path_factory.mktemp("run")
    out = d / "a1.h5"
    res = run_ucs_file(out, A1, 3, SMALL, FAST, cache=packing_cache)
    return out, res


def test_round_trip_through_the_reader(run):
    path, res = run
    assert res.status == "ok"
    s = h5.read_summary(path)
    for k in ("ucs_MPa", "E_GPa", "nu", "peak_strain", "u_pre_MJm3", "cracks_tension",
              "cracks_shear", "n_balls", "n_bonds", "porosity_achieved", "coordination",
              "steps", "wall_s", "stop_reason"):
        assert s[k] == res.summary[k], k
    assert s["schema_version"] == h5.SCHEMA_VERSION and s["status"] == "ok"
    assert s["git_commit"] and s["bpmcal_version"] and len(s["inputs_hash"]) == 16
    inp = h5.read_inputs(path)
    for k, v in A1.items():
        assert inp[k] == v
    assert inp["seed"] == 3 and inp["scale"] == 0.24
    ser = h5.read_series(path)
    assert len(ser) == s["records"]
    assert ser["axial_stress"].max() / 1e6 == pytest.approx(s["ucs_MPa"])
    cr = h5.read_cracks(path)
    assert len(cr) >= s["cracks_tension"] + s["cracks_shear"]
    assert set(cr["mode"].unique()) <= {1, 2}
    ini = h5.read_particles(path, "initial")
    fin = h5.read_particles(path, "final")
    assert ini["position"].shape == fin["position"].shape == (s["n_balls"], 3)
    b = h5.read_bonds(path)
    assert b["i"].size == s["n_bonds"]
    assert np.count_nonzero(b["state"]) == len(cr)


def test_written_file_has_a_normal_mode_not_the_temporary_0600(tmp_path):
    old = os.umask(0o022)
    try:
        out = h5.write_run(tmp_path / "m.h5", h5.RunRecord(test="ucs", inputs={"a": 1}))
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == 0o644  # readable by the group and others


def test_a_failed_write_leaves_no_file(tmp_path, monkeypatch):
    out = tmp_path / "x.h5"

    def boom(*a, **k):
        raise RuntimeError("disk full")
    monkeypatch.setattr(h5.h5py.Group, "create_dataset", boom)
    with pytest.raises(RuntimeError):
        h5.write_run(out, h5.RunRecord(test="ucs", inputs={"a": 1}, series={"t": np.arange(3)}))
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_a_killed_writer_leaves_no_file(tmp_path):
    """A process killed while writing never leaves a file under the final name."""
    out = tmp_path / "k.h5"
    code = textwrap.dedent(f"""
        import os, time, numpy as np
        from bpmcal.io import atomic, h5
        real = os.replace
        def slow(a, b):
            time.sleep(60)
            real(a, b)
        atomic.os.replace = slow
        h5.write_run({str(out)!r}, h5.RunRecord(test="ucs", inputs={{}},
                                              series={{"t": np.arange(10**6)}}))
    """)
    p = subprocess.Popen([sys.executable, "-c", code])
    t0 = time.time()
    while not any(f.name.endswith(".tmp") for f in tmp_path.iterdir()):
        assert time.time() - t0 < 60 and p.poll() is None
        time.sleep(0.1)
    time.sleep(0.5)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert not out.exists()


def test_unstable_run_gives_a_failure_record(tmp_path, monkeypatch, packing_cache):
    def unstable(*a, **k):
        raise InstabilityError("run blew up at step 12: ball 3 ...", 12, 3)
    monkeypatch.setattr(runner, "run_test", unstable)  # the driver, as the runner calls it
    out = tmp_path / "f.h5"
    res = run_ucs_file(out, A1, 3, SMALL, FAST, cache=packing_cache)
    assert res.status == "failed"
    s = h5.read_summary(out)
    assert s["status"] == "failed" and "step 12" in s["error"]
    assert h5.read_inputs(out)["pb_ten_MPa"] == A1["pb_ten_MPa"]


def test_cli_summary_json_and_vtk(run, tmp_path, capsys):
    path, res = run
    assert main(["summary", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["ucs_MPa"] == pytest.approx(res.summary["ucs_MPa"])
    files = export_run(path, tmp_path / "vtk")
    names = {f.name for f in files}
    assert {"particles_initial.vtp", "particles_final.vtp", "cracks.vtp", "run.pvd"} <= names
    root = ET.parse(tmp_path / "vtk" / "particles_final.vtp").getroot()
    piece = root.find("PolyData/Piece")
    assert int(piece.get("NumberOfPoints")) == res.summary["n_balls"]
    arrays = {a.get("Name") for a in piece.find("PointData")}
    assert {"radius", "displacement", "velocity", "broken_bonds"} <= arrays
    cr = ET.parse(tmp_path / "vtk" / "cracks.vtp").getroot().find("PolyData/Piece")
    assert int(cr.get("NumberOfPoints")) == res.summary["cracks_tension"] + res.summary[
        "cracks_shear"]


@pytest.mark.parametrize("args, needle", [
    (["--set", "porosity=0.95"], "porosity=0.95"),
    (["--set", "pb_kratio=-1"], "pb_kratio=-1"),
    (["--set", "bogus=1"], "bogus"),
    (["--set", "pb_ten_MPa=abc"], "pb_ten_MPa"),
])
def test_cli_rejects_bad_parameters_before_any_work(tmp_path, capsys, args, needle):
    pf = tmp_path / "p.yaml"
    pf.write_text("\n".join(f"{k}: {v}" for k, v in A1.items()))
    out = tmp_path / "o.h5"
    t0 = time.perf_counter()
    assert main(["ucs", "--params", str(pf), "--out", str(out), *args]) == 2
    assert time.perf_counter() - t0 < 5
    err = capsys.readouterr().err
    assert needle in err
    assert not out.exists()


def test_load_params_takes_a_material_card_and_applies_overrides(tmp_path):
    from bpmcal.io.card import write_card
    from bpmcal.stages.runs import load_params

    card = tmp_path / "B1.yaml"
    write_card(card, {"specimen": "B1", "status": "ok", "parameters": dict(A1),
                      "targets": {"ucs_MPa": 60.0}})
    p = load_params(card, ["fric=0.5"])
    assert p == {**A1, "fric": 0.5}


def test_cli_reports_missing_parameters(tmp_path, capsys):
    pf = tmp_path / "p.yaml"
    pf.write_text("rmin_mm: 0.8\nporosity: 0.3\n")
    assert main(["ucs", "--params", str(pf), "--out", str(tmp_path / "o.h5")]) == 2
    assert "missing parameter(s)" in capsys.readouterr().err


def test_cli_help_documents_every_parameter_with_unit_and_range():
    out = subprocess.run([sys.executable, "-m", "bpmcal.cli", "ucs", "--help"],
                         capture_output=True, text=True, env=dict(os.environ, COLUMNS="120"))
    assert out.returncode == 0
    for name, lo_hi in [("rmin_mm", "0.6-1"), ("porosity", "0.2-0.36"),
                        ("pb_emod_GPa", "10-50"), ("pb_kratio", "1-5"),
                        ("pb_ten_MPa", "10-50"), ("pb_coh_MPa", "10-50"),
                        ("pb_fa_deg", "15-55"), ("fric", "0.15-0.55")]:
        line = next(ln for ln in out.stdout.splitlines() if ln.strip().startswith(name))
        assert lo_hi in line
    assert "[mm ]" in out.stdout and "[GPa]" in out.stdout
