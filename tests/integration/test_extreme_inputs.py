"""Extreme inputs end at once: a card or loading that cannot finish is refused before the
specimen is built, with one line naming the cause and exit code 2 (bad input, nothing
written); a design row is recorded as failed instead, so the study goes on."""
import subprocess
import sys
import time

import pandas as pd
import pytest
import yaml
from support.paper import A1

from bpmcal.cli import main
from bpmcal.io import h5


def _params(tmp_path, **kw):
    f = tmp_path / "p.yaml"
    f.write_text(yaml.safe_dump({**A1, **kw}))
    return str(f)


@pytest.mark.parametrize("sets, extra, names", [
    (["--set", "pb_kratio=1e-9"], ["--scale", "0.2"], "pb_kratio = 1e-09"),
    (["--set", "rmin_mm=0.01"], ["--scale", "0.4"], "rmin_mm=0.01"),
    ([], ["--scale", "0.4", "--platen-velocity", "1e-6"], "platen_velocity gives 1e-06 m/s"),
], ids=["pb_kratio", "rmin_mm", "platen_velocity"])
def test_an_extreme_input_ends_within_10_s_with_one_line_and_exit_2(tmp_path, sets, extra,
                                                                   names):
    """The issue's three cases, as a user runs them (a fresh process, no packing cache)."""
    out = tmp_path / "run" / "x.h5"
    cmd = [sys.executable, "-m", "bpmcal.cli", "ucs", "--params", _params(tmp_path), *sets,
           *extra, "--out", str(out), "--specimen-cache", str(tmp_path / "cache")]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    wall = time.perf_counter() - t0
    assert p.returncode == 2, p.stderr
    assert wall < 10.0
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bpmcal ucs: error: "), p.stderr
    assert names in lines[0]
    assert not out.exists()


def test_a_normal_card_is_not_refused(tmp_path, packing_cache):
    out = tmp_path / "a1.h5"
    assert main(["ucs", "--params", _params(tmp_path), "--out", str(out), "--scale", "0.24",
                 "--platen-velocity", "0.1", "--record-strain", "4e-5", "--threads", "1",
                 "--specimen-cache", str(packing_cache), "--quiet"]) == 0
    assert h5.read_summary(out)["status"] == "ok"


def test_a_hopeless_design_row_is_recorded_as_failed(tmp_path, capsys):
    """In a design (the study's sample jobs) the refusal is the sample's failure record,
    written before anything is built, and --failed-ok lets the study go on."""
    design = tmp_path / "design.csv"
    pd.DataFrame([{"sample_id": "s000", **A1, "seed": 1}]).to_csv(design, index=False)
    out = tmp_path / "s000.h5"
    t0 = time.perf_counter()
    rc = main(["ucs", "--design", str(design), "--sample", "s000", "--out", str(out),
               "--scale", "0.4", "--platen-velocity", "1e-6", "--quiet", "--failed-ok"])
    assert rc == 0 and time.perf_counter() - t0 < 10.0
    s = h5.read_summary(out)
    assert s["status"] == "failed"
    assert "cannot reach the card's failure" in s["error"] and "platen_velocity" in s["error"]
    assert "FAILED" in capsys.readouterr().err
