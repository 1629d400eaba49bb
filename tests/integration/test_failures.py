"""Failed runs and failed samples: exit codes, FAILED lines, failure records that keep the
study going (gather, the ratio sweep, the calibration), and Ctrl-C."""
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
import yaml
from support.paper import A1

from bpmcal.cli import main
from bpmcal.io import h5
from bpmcal.io.card import write_card
from bpmcal.params import PARAM_NAMES, PARAMS

SMALL = ["--scale", "0.24", "--platen-velocity", "0.1", "--record-strain", "4e-5",
         "--threads", "1"]
TABLE2 = {k: [p.lo, p.hi] for k, p in PARAMS.items()}


@pytest.fixture(scope="module")
def cache(packing_cache):
    return str(packing_cache)


def _params(tmp_path, **kw):
    f = tmp_path / "p.yaml"
    f.write_text(yaml.safe_dump({**A1, **kw}))
    return str(f)


# ------------------------------------------------------------------------ exit codes
@pytest.mark.parametrize("failed_ok, code", [(False, 3), (True, 0)])
def test_a_failed_run_exits_3_or_0_with_failed_ok_and_quiet_shows_it(tmp_path, capsys, cache,
                                                                      failed_ok, code):
    out = tmp_path / "k.h5"
    argv = ["ucs", "--params", _params(tmp_path, pb_kratio=1e-5), "--out", str(out), *SMALL,
            "--genesis-max-steps", "1000", "--specimen-cache", cache, "--quiet"]
    assert main(argv + (["--failed-ok"] if failed_ok else [])) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bpmcal ucs: FAILED: ")
    assert "genesis step budget of 1,000 steps" in err[0] and "failure record written" in err[0]
    s = h5.read_summary(out)
    assert s["status"] == "failed" and "GenesisError" in s["error"]


def test_a_good_output_is_kept_when_the_new_run_fails(tmp_path, capsys, cache):
    out = tmp_path / "a1.h5"
    assert main(["ucs", "--params", _params(tmp_path), "--out", str(out), *SMALL,
                 "--specimen-cache", cache, "--quiet"]) == 0
    good = out.read_bytes()
    rc = main(["ucs", "--params", _params(tmp_path, pb_kratio=1e-5), "--out", str(out),
               *SMALL, "--genesis-max-steps", "1000", "--specimen-cache", cache, "--quiet",
               "--failed-ok"])
    assert rc == 3  # --out was not updated: a failure even with --failed-ok
    err = capsys.readouterr().err
    assert f"the good run in {out} was kept" in err
    assert out.read_bytes() == good
    assert h5.read_summary(tmp_path / "a1.failed.h5")["status"] == "failed"


def test_ctrl_c_stops_a_run_quickly_and_leaves_no_file(tmp_path):
    """SIGINT during a long genesis (pb_kratio = 1e-5: a timestep ~100 x shorter, so the
    bpmcal genesis takes ~100 x its steps): exit 130 within a few seconds (the benchmark
    benchmarks/sigint_latency.py measures the latency), no output file, no temporary
    file. The signal is sent once the run reports its genesis on stderr (not after a fixed
    sleep: on a loaded machine the interpreter may still be importing, before the
    command's handler exists)."""
    import selectors

    out = tmp_path / "run" / "k.h5"
    cmd = [sys.executable, "-m", "bpmcal.cli", "ucs", "--params",
           _params(tmp_path, pb_kratio=1e-5), "--out", str(out), "--scale", "0.4",
           "--threads", "1", "--genesis-max-steps", "10000000", "--genesis", "bpmcal",
           "--specimen-cache", str(tmp_path / "cache")]
    # a user's Ctrl-C reaches a process whose SIGINT is at its default; a test suite run
    # as a background job of a non-interactive shell inherits SIGINT *ignored*, and then
    # Python installs no handler at all: restore the default in the child
    p = subprocess.Popen(cmd, stderr=subprocess.PIPE,
                         env=dict(os.environ, NUMBA_THREADING_LAYER="omp"),
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    sel = selectors.DefaultSelector()
    sel.register(p.stderr, selectors.EVENT_READ)
    seen, deadline = b"", time.monotonic() + 300
    while b"genesis" not in seen and time.monotonic() < deadline and p.poll() is None:
        if sel.select(timeout=1.0):
            seen += os.read(p.stderr.fileno(), 4096)
    assert b"genesis" in seen and p.poll() is None, seen[-2000:]
    t0 = time.perf_counter()
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=30)
    err = (seen + err).decode()
    assert time.perf_counter() - t0 < 5.0
    assert p.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not out.parent.exists() or list(out.parent.iterdir()) == []


# ------------------------------------------------------------------------ gather
def test_gather_records_unreadable_missing_and_failed_samples(tmp_path, capsys):
    design = tmp_path / "design.csv"
    rows = [{"sample_id": f"s00{i}", **A1, "seed": i} for i in range(5)]
    pd.DataFrame(rows).to_csv(design, index=False)
    runs = tmp_path / "runs"
    runs.mkdir()
    h5.write_run(runs / "s000.h5",
                 h5.RunRecord(test="ucs",
                           inputs={**A1, "seed": 0},
                           summary={"ucs_MPa": 50.0, "stop_reason": "post_peak_drop"}))
    h5.write_run(runs / "s001.h5",
                 h5.RunRecord(test="ucs",
                           inputs={**A1, "seed": 1},
                           status="failed",
                           error="InstabilityError: blew up"))
    raw = (runs / "s000.h5").read_bytes()
    (runs / "s002.h5").write_bytes(raw[: len(raw) // 3])  # truncated (a killed copy)
    (runs / "s003.h5").write_text("garbage")  # not HDF5
    out = tmp_path / "dataset.csv"
    files = [str(runs / f"s00{i}.h5") for i in range(5)]  # s004.h5 was never written
    assert main(["gather", "--design", str(design), "--runs", *files, "--out", str(out)]) == 0
    ds = pd.read_csv(out).set_index("sample_id")
    assert list(ds["status"]) == ["ok", "failed", "unreadable", "unreadable", "missing"]
    assert "blew up" in ds.loc["s001", "error"]
    assert "s002.h5: not a readable HDF5 file" in ds.loc["s002", "error"]
    assert "s003.h5" in ds.loc["s003", "error"]
    assert ds.loc["s000", "ucs_MPa"] == 50.0 and np.isnan(ds.loc["s002", "ucs_MPa"])
    report = capsys.readouterr().out
    assert "5 samples: 1 failed, 1 missing, 1 ok, 2 unreadable" in report


# ------------------------------------------------------------------------ the ratio sweep
@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """A dataset with planted linear responses and the regression's models.json (no DEM)."""
    d = tmp_path_factory.mktemp("models")
    rng = np.random.default_rng(4)
    n = 40
    cols = {p: PARAMS[p].lo + (PARAMS[p].hi - PARAMS[p].lo) * rng.random(n) for p in PARAM_NAMES}
    ds = pd.DataFrame(cols)
    ds.insert(0, "sample_id", [f"s{i:03d}" for i in range(n)])
    ds["seed"] = np.arange(n)
    ds["ucs_MPa"] = 0.8 * ds["pb_ten_MPa"] + 1.1 * ds["pb_coh_MPa"] + rng.normal(0, 0.3, n)
    ds["E_GPa"] = 0.35 * ds["pb_emod_GPa"] + rng.normal(0, 0.1, n)
    ds["nu"] = 0.05 * ds["pb_kratio"] + 0.08 + rng.normal(0, 0.002, n)
    ds["status"], ds["error"] = "ok", ""
    ds.to_csv(d / "dataset.csv", index=False)
    (d / "selected.json").write_text(json.dumps({"selected": {
        "ucs_MPa": ["pb_ten_MPa", "pb_coh_MPa"], "E_GPa": ["pb_emod_GPa"], "nu": ["pb_kratio"]}}))
    r, t = d / "regression", d / "tables"
    assert main(["regress", "--dataset", str(d / "dataset.csv"), "--selected",
                 str(d / "selected.json"), "--models", str(r / "models.json"), "--equations",
                 str(r / "equations.md"), "--summaries", str(r / "summaries.txt"),
                 "--coefficients", str(r / "coefficients.csv"), "--candidates",
                 str(r / "candidates.csv"), "--table4", str(t / "table4_terms.csv"),
                 "--fit-table", str(t / "regression_fit.csv"), "--figure",
                 str(d / "figures" / "regression_fit.png"), "--cv-folds", "2",
                 "--cv-repeats", "1"]) == 0
    return d


def test_unreachable_ratios_are_marked_run_as_records_and_the_calibration_goes_on(
        models, tmp_path, capsys):
    """The sweep planner cannot reach the target (a sigma_c far above what any tau_cp up to
    four times the sampled range gives): every ratio is marked unreachable instead of raising; its DEM job
    writes a failure record without running; the analysis chooses no ratio and says why;
    the calibration keeps the configured ratio."""
    card = write_card(tmp_path / "B1.yaml", {
        "specimen": "B1", "parameters": A1, "ranges": TABLE2,
        "targets": {"ucs_MPa": 5000.0, "E_GPa": 8.0, "nu": 0.2}})
    plan = tmp_path / "sweep" / "plan.csv"
    assert main(["sweep-plan", "--card", str(card), "--models",
                 str(models / "regression" / "models.json"), "--ratios", "1.0,1.6,0.3",
                 "--out", str(plan)]) == 0
    p = pd.read_csv(plan)
    assert list(p["status"]) == ["unreachable"] * 3
    assert p["reason"].str.contains(r"no tau_cp in \[[0-9.]+, [0-9.]+\] MPa gives the target").all()
    runs = tmp_path / "sweep" / "runs"
    for sid in p["sample_id"]:
        assert main(["ucs", "--design", str(plan), "--sample", sid, "--out",
                     str(runs / f"{sid}.h5"), "--failed-ok", "--quiet"]) == 0
        s = h5.read_summary(runs / f"{sid}.h5")
        assert s["status"] == "failed" and s["error"].startswith("not run: unreachable ratio")
    chosen = tmp_path / "sweep" / "chosen.json"
    figs = tmp_path / "figures"
    assert main(["sweep-analyse", "--plan", str(plan), "--runs",
                 *(str(runs / f"{sid}.h5") for sid in p["sample_id"]), "--table",
                 str(tmp_path / "tables" / "ratio_sweep.csv"), "--fig4",
                 str(figs / "fig4_ratio_cracks.png"), "--fig5", str(figs / "fig5_failure_patterns.png"),
                 "--vtk", str(tmp_path / "vtk"), "--chosen", str(chosen)]) == 0
    ch = json.loads(chosen.read_text())
    assert ch["chosen_ratio"] is None and "no ratio of the sweep gave a usable run" in ch["reason"]
    t = pd.read_csv(tmp_path / "tables" / "ratio_sweep.csv")
    assert list(t["status"]) == ["unreachable"] * 3
    for fig in ("fig4_ratio_cracks", "fig5_failure_patterns"):
        assert (tmp_path / "figures" / f"{fig}.png").stat().st_size > 1000
    lab = tmp_path / "lab.csv"
    lab.write_text("specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3\nB1,60,8,0.2,\n")
    capsys.readouterr()
    assert main(["calibrate", "--dataset", str(models / "dataset.csv"), "--models",
                 str(models / "regression" / "models.json"), "--lab", str(lab), "--cards",
                 str(tmp_path / "cal" / "B1.yaml"), "--fixed", json.dumps({"rmin_mm": 0.8, "porosity": 0.3,
                                                               "pb_fa_deg": 35, "fric": 0.35}),
                 "--free", "pb_emod_GPa,pb_kratio,pb_coh_MPa", "--ratio", "1.4",
                 "--ranges", json.dumps(TABLE2),
                 "--ratio-from", str(chosen), "--n-boot", "0"]) == 0
    assert "the sweep chose no ratio" in capsys.readouterr().out
    assert yaml.safe_load((tmp_path / "cal" / "B1.yaml").read_text())["ratio_ten_coh"] == 1.4


def test_a_reachable_plan_is_planned(models, tmp_path):
    card = write_card(tmp_path / "B1.yaml", {
        "specimen": "B1", "parameters": A1, "ranges": TABLE2,
        "targets": {"ucs_MPa": 60.0, "E_GPa": 8.0, "nu": 0.2}})
    plan = tmp_path / "plan.csv"
    assert main(["sweep-plan", "--card", str(card), "--models",
                 str(models / "regression" / "models.json"), "--ratios", "1.0,1.6,0.3",
                 "--out", str(plan)]) == 0
    p = pd.read_csv(plan)
    assert list(p["status"]) == ["planned"] * 3
    # the planted sigma_c = 0.8 ten + 1.1 coh: coh = 60 / (0.8 a + 1.1), within the noise
    expect = 60.0 / (0.8 * p["ratio"] + 1.1)
    assert np.allclose(p["pb_coh_MPa"], expect, rtol=0.03)
    assert np.allclose(p["pb_ten_MPa"], p["ratio"] * p["pb_coh_MPa"])


def test_calibrate_writes_exactly_the_cards_it_is_given(models, tmp_path, capsys):
    """The cards' paths are the command line's (one per lab specimen, named after it): a
    specimen name never makes a path, and a card that matches no specimen is refused
    before anything is written."""
    lab = tmp_path / "lab.csv"
    lab.write_text("specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3\nB1,60,8,0.2,\nB2,61,8,0.21,\n")
    argv = ["calibrate", "--dataset", str(models / "dataset.csv"), "--models",
            str(models / "regression" / "models.json"), "--lab", str(lab), "--fixed",
            json.dumps({"rmin_mm": 0.8, "porosity": 0.3, "pb_fa_deg": 35, "fric": 0.35}),
            "--ranges", json.dumps(TABLE2), "--n-boot", "0", "--cards"]
    out = tmp_path / "cards"
    assert main([*argv, str(out / "B1.yaml"), str(out / "evil.yaml")]) == 2
    assert "expected one card per lab specimen" in capsys.readouterr().err
    assert not out.exists()
    assert main([*argv, str(out / "B2.yaml"), str(out / "B1.yaml")]) == 0
    assert sorted(f.name for f in out.iterdir()) == ["B1.yaml", "B2.yaml"]
    assert yaml.safe_load((out / "B2.yaml").read_text())["specimen"] == "B2"


# ------------------------------------------------------------------------ other endings
@pytest.mark.parametrize("exc, code, needle", [
    (RuntimeError("boom"), 1, "internal error (a bug in bpmcal, not in your input)"),
    (OSError(28, "No space left on device", "/full/disk.h5"), 4,
     "bpmcal summary: error: /full/disk.h5: no space left on the device (the disk is full) "
     "(system error); free space there"),
    (KeyboardInterrupt(), 130, "bpmcal summary: interrupted"),
])
def test_bugs_system_errors_and_interrupts_have_their_own_exit_codes(monkeypatch, capsys,
                                                                    exc, code, needle):
    import bpmcal.io.h5 as h5mod

    def fail(path):
        raise exc
    monkeypatch.setattr(h5mod, "read_summary", fail)
    assert main(["summary", "x.h5"]) == code
    err = capsys.readouterr().err
    assert needle in err
    assert ("Traceback" in err) == (code == 1)  # only a bug shows a traceback


def test_usage_errors_are_one_line(capsys):
    assert main([]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bpmcal: error: ")
    assert main(["--version"]) == 0


@pytest.mark.parametrize("n_ok, folds", [(9, 4), (5, 2), (3, None)])
def test_screening_adapts_its_folds_to_the_samples_left(models, tmp_path, capsys, n_ok, folds):
    """Failed samples may leave fewer usable rows than 5-fold CV needs (2 per fold): the
    screening then uses fewer folds and says so; below 4 usable samples it is one clear
    error line (exit 2), never a traceback."""
    ds = pd.read_csv(models / "dataset.csv").head(12)
    ds.loc[n_ok:, "status"] = "failed"
    ds.to_csv(tmp_path / "dataset.csv", index=False)
    out = tmp_path / "screening"
    files = {"--selected": out / "selected.json", "--table3": out / "table3.csv",
             "--figure": out / "importance.png", "--importance-table": out / "imp.csv",
             "--cv-table": out / "cv.csv", "--shadow-table": out / "shadow.csv",
             "--summary": out / "summary.txt"}
    rc = main(["screen", "--dataset", str(tmp_path / "dataset.csv"), "--n-repeats", "1",
               *[str(x) for kv in files.items() for x in kv]])
    cap = capsys.readouterr()
    if folds is None:
        assert rc == 2 and "3 of 12 samples have status ok" in cap.err
        assert len(cap.err.strip().splitlines()) == 1 and not (out / "selected.json").exists()
    else:
        assert rc == 0, cap.err
        note = json.loads((out / "selected.json").read_text())["note"]
        assert f"so {folds}-fold CV was used" in note and f"{n_ok} of 12 samples used" in note
