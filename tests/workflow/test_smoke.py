"""The smoke study end to end through Snakemake, re-runs, the file contract, and config
errors.

The smoke study runs with an output folder that holds a space and a title full of shell
syntax (quotes, ``$( )``, backticks, ``;``): every command must quote them, and nothing
may run. One sample's run file is corrupted (truncated) before the dataset is gathered:
the study must carry it as "unreadable" to the report, which lists it. Every ``bpmcal``
process of the study records the files it reads (``audit/sitecustomize.py``): each must be
a file the rule graph declares as an input of that job."""
import csv
import json
import os
import shlex
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from support.repo import REPO, copy_workflow, run_snakemake, scheduled_jobs

pytestmark = pytest.mark.slow  # the smoke study and further Snakemake runs: minutes

AUDIT = Path(__file__).resolve().parent / "audit"
AUDIT_LOGS = ".audit"  # in the smoke study's folder: the files each bpmcal process read


def snakemake(cwd, *args, timeout=1200, audit=None):
    """Run Snakemake in ``cwd``; with ``audit`` (a folder), every bpmcal process records the
    files it reads there."""
    if audit is None:
        return run_snakemake(cwd, *args, timeout=timeout)
    return run_snakemake(cwd, *args, timeout=timeout, env={"BPMCAL_AUDIT_DIR": str(audit)},
                         pythonpath=[AUDIT])


#: the smoke study's output folder (a space) and title (shell syntax), see the module doc
OUTDIR = "results/smoke run"
TITLE = "O'Brien sandstone; $(touch PWNED) `touch PWNED` \" '; touch PWNED; echo '"
SMOKE = ["--configfile", "config/smoke.yaml", "config/hostile_names.yaml"]
#: the sample whose run file is corrupted before the gather
PLANTED = "s003"
#: the sample whose Brazilian run is made invalid before the gather (as a run whose
#: fracture started at a platen is recorded)
PLANTED_INVALID = "s004"
INVALID_REASON = "fracture initiated next to the top platen: planted by the smoke test"


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    wf = copy_workflow(tmp_path_factory.mktemp("smoke"))
    audit = wf / AUDIT_LOGS
    audit.mkdir()
    (wf / "config" / "hostile_names.yaml").write_text(
        yaml.safe_dump({"outdir": OUTDIR, "study": {"name": TITLE}}))
    n = yaml.safe_load((wf / "config" / "smoke.yaml").read_text())["study"]["n_samples"]
    runs = [f"{OUTDIR}/ucs/s{i:03d}.h5" for i in range(n)]
    r = snakemake(wf, *runs, "--cores", "2", *SMOKE, audit=audit)  # the samples ...
    assert r.returncode == 0, r.stderr[-3000:]
    f = wf / OUTDIR / "ucs" / f"{PLANTED}.h5"  # ... one of them damaged (a half copy) ...
    raw = f.read_bytes()
    f.write_bytes(raw[: len(raw) // 2])
    import h5py

    with h5py.File(wf / OUTDIR / "bts" / f"{PLANTED_INVALID}.h5", "r+") as h:  # ... another's
        a = h["summary"].attrs  # Brazilian test made an invalid one ...
        a["bts_valid"], a["bts_invalid_reason"] = False, INVALID_REASON
        a["bts_MPa"] = float("nan")
    r = snakemake(wf, "--cores", "2", *SMOKE, audit=audit)  # ... and the rest of the study
    assert r.returncode == 0, r.stderr[-3000:]
    return wf


def test_no_shell_text_from_the_config_ran(smoke):
    assert not [p for p in smoke.rglob("PWNED*")]
    index = (smoke / OUTDIR / "report" / "index.md").read_text()
    assert index.startswith(f"# {TITLE}: the paper, regenerated")
    cfg = json.loads((smoke / OUTDIR / "report" / "config.json").read_text())
    assert cfg["study"]["name"] == TITLE and cfg["outdir"] == OUTDIR


def test_smoke_study_gathers_every_sample(smoke):
    cfg = yaml.safe_load((smoke / "config" / "smoke.yaml").read_text())
    out = smoke / OUTDIR
    ds = pd.read_csv(out / "dataset.csv")
    n = cfg["study"]["n_samples"]
    assert len(ds) == n and ds["sample_id"].is_unique
    planted = ds.set_index("sample_id").loc[PLANTED]
    assert planted["status"] == "unreadable"
    assert f"{PLANTED}.h5: not a readable HDF5 file" in planted["error"]
    rest = ds[ds["sample_id"] != PLANTED]
    assert set(rest["status"]) <= {"ok", "failed"}
    ok = ds[ds["status"] == "ok"]
    assert len(ok) >= n - 2
    assert (ok["ucs_MPa"] > 0).all() and (ok["E_GPa"] > 0).all()
    design = pd.read_csv(out / "design" / "samples.csv")
    for c in ("rmin_mm", "porosity", "pb_emod_GPa", "seed"):
        assert (ds[c].to_numpy() == design[c].to_numpy()).all()
    for sid in ds["sample_id"]:
        log = (out / "logs" / "sample" / f"{sid}.log").read_text()  # the sample job: both tests
        assert f"ucs/{sid}.h5" in log and f"bts/{sid}.h5" in log, log[-2000:]


def test_every_sample_has_a_brazilian_test_in_the_dataset_and_the_analyses(smoke):
    """bts.enabled (the default): sigma_t of every sample, its own status; the planted
    sample's UCS file is unreadable, its Brazilian test is not; Table 3 and the regression
    have sigma_t."""
    out = smoke / OUTDIR
    ds = pd.read_csv(out / "dataset.csv").set_index("sample_id")
    assert set(ds["bts_status"]) <= {"ok", "failed", "invalid"}
    okb = ds[ds["bts_status"] == "ok"]
    assert len(okb) >= len(ds) - 4
    # the planted invalid test: no sigma_t, its reason, its peak kept; left out of the fit
    r = ds.loc[PLANTED_INVALID]
    assert r["bts_status"] == "invalid" and r["bts_error"] == INVALID_REASON
    assert np.isnan(r["bts_MPa"]) and r["bts_peak_MPa"] > 0 and r["status"] == "ok"
    assert (ds["bts_status"] == "invalid").eq(ds["bts_valid"] == False).all()  # noqa: E712
    assert (okb["bts_MPa"] > 0).all() and (okb["bts_MPa"] < 100).all()
    assert ds[ds["bts_status"] != "ok"]["bts_MPa"].isna().all()
    assert ds.loc[PLANTED, "status"] == "unreadable"
    assert ds.loc[PLANTED, "bts_status"] == "ok" and ds.loc[PLANTED, "bts_MPa"] > 0
    # the disc is weaker in tension than the cylinder in compression, sample by sample
    both = ds[(ds["status"] == "ok") & (ds["bts_status"] == "ok")]
    assert (both["bts_MPa"] < both["ucs_MPa"]).all()
    t3 = pd.read_csv(out / "tables" / "table3_importance.csv", index_col=0)
    assert "bts_MPa" in t3.columns and t3["bts_MPa"].sum() == pytest.approx(100.0)
    models = json.loads((out / "regression" / "models.json").read_text())
    assert "bts_MPa" in models["models"]
    assert models["response_rows"]["bts_MPa"]["n_used"] == len(okb)  # valid tests only
    assert "bts_MPa" in (out / "regression" / "equations.md").read_text()
    index = (out / "report" / "index.md").read_text()
    assert f"- Brazilian tests: {len(okb)} of {len(ds)} valid and ok" in index
    assert f"  - {PLANTED_INVALID}: Brazilian invalid: {INVALID_REASON}" in index
    assert "σt" in index


def test_the_report_lists_the_failed_sample(smoke):
    index = (smoke / OUTDIR / "report" / "index.md").read_text()
    assert "- Failed samples (left out of the analysis):" in index
    line = next(ln for ln in index.splitlines() if ln.strip().startswith(f"- {PLANTED}:"))
    assert "unreadable" in line and "not a readable HDF5 file" in line
    ok = (pd.read_csv(smoke / OUTDIR / "dataset.csv")["status"] == "ok").sum()
    assert f"- Dataset: {ok} of 16 samples ok" in index


def test_rerun_redoes_nothing(smoke):
    r = snakemake(smoke, "-n", *SMOKE)
    assert r.returncode == 0
    assert "Nothing to be done" in r.stdout + r.stderr


def test_interrupted_study_resumes_without_redoing_samples(tmp_path):
    wf = copy_workflow(tmp_path / "wf")
    (wf / "config" / "resume.yaml").write_text(yaml.safe_dump(
        {"outdir": "results/resume", "study": {"name": "resume", "n_samples": 4, "lhs_seed": 3}}))
    cfg = ["--configfile", "config/smoke.yaml", "config/resume.yaml"]
    done = [f"results/resume/ucs/s00{i}.h5" for i in (0, 1)]
    r = snakemake(wf, *done, "--cores", "2", *cfg)  # "interrupted" after two samples
    assert r.returncode == 0, r.stderr[-2000:]
    mtimes = {f: (wf / f).stat().st_mtime_ns for f in done}
    r = snakemake(wf, "results/resume/dataset.csv", "--cores", "2", *cfg)
    assert r.returncode == 0, r.stderr[-2000:]
    assert {f: (wf / f).stat().st_mtime_ns for f in done} == mtimes
    assert len(pd.read_csv(wf / "results/resume/dataset.csv")) == 4


def test_same_seed_reproduces_design_and_results(tmp_path, smoke):
    cfg = yaml.safe_load((smoke / "config" / "smoke.yaml").read_text())
    out = smoke / OUTDIR
    design = out / "design" / "samples.csv"
    d2 = tmp_path / "d2.csv"
    subprocess.run(["bpmcal", "design", "--ranges", __import__("json").dumps(
        yaml.safe_load((REPO / "config/config.yaml").read_text())["ranges"]),
        "--n", str(cfg["study"]["n_samples"]), "--seed", str(cfg["study"]["lhs_seed"]),
        "--out", str(d2)], check=True, capture_output=True)
    assert design.read_bytes() == d2.read_bytes()
    from bpmcal.io.h5 import read_series, read_summary
    h = out / "ucs" / "s001.h5"
    again = tmp_path / "again.h5"
    r = subprocess.run(["bpmcal", "ucs", "--design", str(design), "--sample", "s001", "--out",
                        str(again), "--scale", str(cfg["specimen"]["scale"]),
                        "--platen-velocity", str(cfg["compression"]["platen_velocity"]),
                        "--record-strain", str(cfg["compression"]["record_strain"]), "--threads", "1",
                        "--quiet"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    a, b = read_summary(h), read_summary(again)
    for k in ("ucs_MPa", "E_GPa", "nu", "steps", "cracks_tension", "cracks_shear", "n_balls"):
        assert a[k] == b[k], k
    assert read_series(h).equals(read_series(again))


@pytest.mark.parametrize("patch, needle", [
    ({"study": {"n_samples": "many"}}, "study.n_samples: 'many' is not of type 'integer'"),
    ({"ranges": {"porosity": [0.2, 0.95]}}, "ranges.porosity[1]: 0.95 is greater than"),
    ({"compression": {"platen_velocty": 0.1}}, "compression: unknown key(s) ['platen_velocty']"),
    ({"lab": {"csv": "config/lab/missing.csv"}}, "lab.csv: file 'config/lab/missing.csv'"),
    ({"ranges": {"pb_ten_MPa": [50, 10]}}, "ranges.pb_ten_MPa: low 50 exceeds high 10"),
    ({"specimen": {"scale": 0.05}}, "specimen.scale: 0.05 gives"),
    ({"outdir": "results/a;touch PWNED;b"}, "outdir: 'results/a;touch PWNED;b': character(s) ';'"),
    ({"lab": {"csv": "config/lab/evil.csv"}}, "specimen '../../evil_card'"),
])
def test_config_errors_stop_before_any_job_naming_the_key(tmp_path, patch, needle):
    wf = copy_workflow(tmp_path / "wf")
    (wf / "config" / "lab" / "evil.csv").write_text(
        "specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3\n../../evil_card,60,13,0.25,\n")
    bad = wf / "config" / "bad.yaml"
    bad.write_text(yaml.safe_dump(patch))
    r = snakemake(wf, "--cores", "1", "--configfile", "config/bad.yaml")
    assert r.returncode != 0
    assert needle in r.stdout + r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    assert not (wf / "results").exists()
    assert not list(tmp_path.rglob("PWNED*")) and not list(tmp_path.rglob("evil_card*"))


# ---------------------------------------------------------------------------- the report
def _published_values():
    """Every number the paper publishes that the report compares against."""
    from bpmcal.study import paper

    vals = [v for d in paper.TABLE3.values() for v in d.values()]
    vals += [v for d in paper.ADJ_R2.values() for v in d.values()]
    vals += [v for d in paper.CALIBRATED.values() for v in d.values()]
    for d in paper.VERIFIED.values():
        vals += [d[k] for k in ("ucs_MPa", "E_GPa", "nu")] + list(d["err_pct"].values())
    vals += [v for d in paper.PREPEAK.values() for v in (d["sim"], d["err_pct"])]
    vals += [paper.RATIO, paper.IMPACT["W_in_J"], paper.IMPACT["eta_f"]]
    return vals


def test_report_holds_every_table_and_figure(smoke):
    from bpmcal.io.study_files import TRIAXIAL_LAB
    from bpmcal.report.build import FIGURES, TABLES

    rep = smoke / OUTDIR / "report"
    for stem in TABLES:
        if stem == TRIAXIAL_LAB:  # only with lab triaxial points (the paper has none)
            assert not (rep / "tables" / f"{stem}.csv").exists()
            continue
        for ext in (".csv", ".md"):
            f = rep / "tables" / f"{stem}{ext}"
            assert f.exists() and f.stat().st_size > 0, f
        assert len(pd.read_csv(rep / "tables" / f"{stem}.csv")) > 0, stem
    for stem in FIGURES:
        for ext in (".png", ".pdf"):
            f = rep / "figures" / f"{stem}{ext}"
            assert f.exists() and f.stat().st_size > 1000, f
    index = (rep / "index.md").read_text()
    for stem in FIGURES:
        assert f"figures/{stem}.png" in index, stem
    assert "Figures not produced" not in index
    assert "samples ok" in index and "Specimen scale 0.3" in index


def test_smoke_study_fits_an_envelope_for_every_verified_card(smoke):
    """Every verified card ran at every configured sigma3; each run is a row of the points
    table (ok or failed, never dropped); each card has its envelope row, with c, phi and
    mi where its runs allow a fit (else the reason); the report shows them and says what
    the paper does not publish."""
    cfg = yaml.safe_load((smoke / "config" / "smoke.yaml").read_text())
    s3 = cfg["triaxial"]["sigma3_MPa"]
    out = smoke / OUTDIR
    pts = pd.read_csv(out / "tables" / "triaxial_points.csv", dtype={"specimen": str})
    env = pd.read_csv(out / "tables" / "triaxial_envelopes.csv", dtype={"specimen": str})
    specs = ["B1", "B2", "B3"]
    assert sorted(pts["specimen"].unique()) == specs and len(pts) == len(specs) * len(s3)
    assert set(pts["card"]) == {"verified"} and sorted(set(pts["sigma3_MPa"])) == s3
    assert set(pts["status"]) <= {"ok", "failed"}
    assert sorted(env["specimen"]) == specs and set(env["card"]) == {"verified"}
    for r in env.itertuples():
        mine = pts[pts["specimen"] == r.specimen]
        ok = mine[mine["status"] == "ok"].sort_values("sigma3_MPa")
        assert r.runs_ok == len(ok) and r.runs == len(s3)
        if len(ok) == len(s3):
            # two exact points: the Mohr-Coulomb line passes through both
            assert r.mc_sigma_c_MPa == pytest.approx(ok["sigma1_MPa"].iloc[0], rel=1e-9)
            assert r.c_MPa > 0 and 0 < r.phi_deg < 90 and r.mi > 0
            assert ok["sigma1_MPa"].iloc[1] > ok["sigma1_MPa"].iloc[0]  # confinement helps
        else:
            assert "left out" in r.note, r.note
        for _, p in mine[mine["status"] != "ok"].iterrows():
            assert isinstance(p["error"], str) and p["error"]
    fig = out / "figures" / "triaxial_envelopes.png"
    assert fig.stat().st_size > 1000 and fig.with_suffix(".pdf").is_file()
    index = (out / "report" / "index.md").read_text()
    assert "## Tension and confinement" in index
    assert "no Brazilian tensile strength and no triaxial tests" in index
    assert "figures/triaxial_envelopes.png" in index


def _no_ratio_chosen(smoke) -> bool:
    """Whether the ratio sweep chose no ratio. With the planted sample left out, the
    refitted sigma_c model of the 15 others may no longer depend on the bond strengths (it
    did here: porosity only), the issue's case: every ratio is then unreachable."""
    ch = json.loads((smoke / OUTDIR / "ratio_sweep" / "chosen.json").read_text())
    return ch["chosen_ratio"] is None


def test_report_index_names_every_published_value(smoke):
    from bpmcal.study import paper

    rep = smoke / OUTDIR / "report"
    index = (rep / "index.md").read_text()
    comp = pd.read_csv(rep / "tables" / "comparison.csv")
    for v in _published_values():
        rows = comp[(comp["paper"] - v).abs() <= 1e-9 * max(1.0, abs(v))]
        assert len(rows), f"published value {v} missing from comparison.csv"
        shown = {f"{v:.1f}", f"{v:.2f}", f"{v:.3f}", f"{100 * v:.1f}", f"{v:g}"}
        assert any(s in index for s in shown), f"published value {v} not in index.md"
        if v == paper.RATIO and _no_ratio_chosen(smoke):
            assert "No ratio chosen: no ratio of the sweep gave a usable run" in index
            continue
        # each comparison carries our value next to it and the difference
        assert rows["ours"].notna().any(), rows


def test_unreachable_ratios_run_through_the_dag(smoke):
    """Unreachable ratios are failure records in the DAG, listed by the report; the
    calibration then used the configured ratio."""
    from bpmcal.io.h5 import read_summary

    out = smoke / OUTDIR
    plan = pd.read_csv(out / "ratio_sweep" / "plan.csv")
    for r in plan.itertuples():
        s = read_summary(out / "ratio_sweep" / "runs" / f"{r.sample_id}.h5")
        if r.status == "unreachable":
            assert s["status"] == "failed" and s["error"].startswith("not run: unreachable")
        else:
            assert r.status == "planned"
    if _no_ratio_chosen(smoke):
        index = (out / "report" / "index.md").read_text()
        assert all(f"({sid}): unreachable" in index for sid in plan["sample_id"])
        card = yaml.safe_load((out / "calibration" / "B1.yaml").read_text())
        assert card["ratio_ten_coh"] == 1.4  # calibration.strength_ratio


def test_snakemake_html_report_has_every_caption(smoke):
    r = snakemake(smoke, *SMOKE, "--report", f"{OUTDIR}/report.html")
    assert r.returncode == 0, r.stderr[-3000:]
    html = (smoke / OUTDIR / "report.html").read_text(errors="replace")
    for cap in sorted((REPO / "workflow" / "report").glob("fig*.rst")) + [
            REPO / "workflow" / "report" / f"{n}.rst"
            for n in ("regression", "screening", "t10", "envelopes")]:
        # the captions sit in the page's JSON (non-ASCII escaped): compare an ASCII prefix
        text = " ".join(cap.read_text().split())
        cut = next((i for i, c in enumerate(text) if ord(c) > 127 or c in "'*"), len(text))
        first = text[:min(cut, 60)]
        assert len(first) >= 15, cap.name
        assert first in html, f"caption of {cap.name} missing"
    assert "XGBoost screening (Table 3) selects" in html  # the workflow description


# ---------------------------------------------------------------------------- the file contract
def declared_jobs(wf, *args) -> dict:
    """The rule graph's jobs, by command line (the arguments after ``bpmcal``, up to the log
    redirection): rule, declared inputs and outputs (absolute), from
    ``snakemake --detailed-summary``."""
    r = snakemake(wf, "--detailed-summary", *args)
    assert r.returncode == 0, r.stderr[-3000:]
    jobs: dict[tuple, dict] = {}
    rows = csv.DictReader(r.stdout.splitlines(), delimiter="\t")
    for row in rows:
        argv = shlex.split(row["shellcmd"])
        if not argv or argv[0] != "bpmcal":
            continue
        key = tuple(argv[1:argv.index(">")])
        j = jobs.setdefault(key, {"rule": row["rule"], "inputs": set(), "outputs": set()})
        j["inputs"] |= {str((wf / f).resolve()) for f in row["input-file(s)"].split(",") if f}
        j["outputs"].add(str((wf / row["output_file"]).resolve()))
    return jobs


def audited(folder) -> list[dict]:
    """Every audited bpmcal process: its arguments and the files it read."""
    procs = []
    for f in sorted(Path(folder).glob("*.jsonl")):
        lines = [json.loads(x) for x in f.read_text().splitlines()]
        procs.append({"argv": tuple(lines[0]["argv"][1:]),
                      "reads": {x["read"] for x in lines[1:]}})
    return procs


def undeclared_reads(procs, jobs, root, ignore=()) -> list[str]:
    """Files under ``root`` that a process read but its job does not declare (as an input,
    or as an output it checks before replacing), and processes that match no job."""
    root = str(Path(root).resolve()) + os.sep
    ignore = tuple(str(Path(i).resolve()) + os.sep for i in ignore)
    bad = []
    for p in procs:
        job = jobs.get(p["argv"])
        if job is None:
            bad.append(f"a bpmcal process that is no job of the rule graph: {p['argv'][:3]}")
            continue
        for f in sorted(p["reads"]):
            if f.startswith(root) and not f.startswith(ignore) and \
                    f not in job["inputs"] | job["outputs"]:
                bad.append(f"rule {job['rule']} read {os.path.relpath(f, root)}, not declared")
    return bad


def test_every_file_a_stage_reads_is_declared_by_the_rule_graph(smoke):
    procs = audited(smoke / AUDIT_LOGS)
    jobs = declared_jobs(smoke, *SMOKE)
    bad = undeclared_reads(procs, jobs, smoke,
                           ignore=[smoke / AUDIT_LOGS, smoke / ".snakemake",
                                   smoke / OUTDIR / "cache"])  # the packing cache
    assert not bad, "\n".join(bad)
    # the audit saw every rule's command, and what the rules read
    assert {j["rule"] for j in jobs.values()} == {jobs[p["argv"]]["rule"] for p in procs}
    reads = {f for p in procs for f in p["reads"]}
    for f in ("tables/regression_fit.csv", "tables/jk_fit.json", "regression/equations.md",
              "verification/B1/best_round.h5", "ucs/s000.h5", "bts/s000.h5"):
        assert str((smoke / OUTDIR / f).resolve()) in reads, f


def test_the_contract_check_can_fail(tmp_path):
    """A stage that reads a file its rule does not declare, and a process that is no job."""
    jobs = {("report", "--x"): {"rule": "report", "inputs": {str(tmp_path / "a.csv")},
                                "outputs": {str(tmp_path / "index.md")}}}
    procs = [{"argv": ("report", "--x"),
              "reads": {str(tmp_path / "a.csv"), str(tmp_path / "index.md"),
                        str(tmp_path / "tables" / "jk_fit.json"), "/usr/lib/x.py"}},
             {"argv": ("screen",), "reads": set()}]
    bad = undeclared_reads(procs, jobs, tmp_path)
    assert bad == ["rule report read tables/jk_fit.json, not declared",
                   "a bpmcal process that is no job of the rule graph: ('screen',)"]


def test_verify_averages_seeds_and_the_transfer_runs_at_its_scale(smoke):
    """The smoke config runs verification.seeds_per_round = 2 seeds per round (a seed set
    that may grow to max_seeds = 3) and the full-size transfer at transfer.scale 0.35
    (specimens at 0.3) on the first seed no loop may use: every verified card records the
    seed mean, CV and n_seeds; every transferred card carries calibrated_at_scale; the
    impact runs the transferred card."""
    from bpmcal.io.h5 import read_inputs
    from bpmcal.io.study_files import TABLE5, TRANSFER, StudyFiles, velocity_tag

    cfg = yaml.safe_load((smoke / "config" / "smoke.yaml").read_text())
    k, scale = cfg["verification"]["seeds_per_round"], cfg["transfer"]["scale"]
    kmax = cfg["verification"]["max_seeds"]
    assert kmax > k
    lay = StudyFiles(str(smoke / OUTDIR))
    t5 = pd.read_csv(lay.table(TABLE5), index_col=0)
    for spec in ("B1", "B2", "B3"):
        v = yaml.safe_load(Path(lay.verified_card(spec)).read_text())["verification"]
        assert v["status"] != "not-run"
        assert v["n_seeds"] in (k, kmax) and v["seeds"] == list(range(1, v["n_seeds"] + 1))
        assert v["seeds_per_round"] == k and v["max_seeds"] == kmax
        rounds = pd.read_csv(lay.verification_rounds(spec))
        assert set(rounds["n_seeds"]) <= {k, kmax} and len(rounds) == v["rounds"]
        assert rounds["n_seeds"].is_monotonic_increasing  # a seed set only grows
        assert (rounds["grown"] > 0).sum() <= 1 and v["runs"] == rounds["n_seeds"].sum()
        for r in ("ucs_MPa", "E_GPa", "nu"):
            cv = v["closed_loop"]["seed_cv"][r]
            assert 0 < cv < 0.5, (spec, r, cv)  # two packings never agree to the last bit
            assert t5.loc[spec, f"closed_loop_{r}_cv_pct"] == pytest.approx(100 * cv)
        assert t5.loc[spec, "n_seeds"] == v["n_seeds"]
        assert read_inputs(lay.verification_run(spec))["seed"] == 1
        t = yaml.safe_load(Path(lay.transferred_card(spec)).read_text())
        assert t["transfer"]["scale"] == scale and t["transfer"]["seed"] == 1 + kmax
        assert 1 <= t["transfer"]["rounds"] <= 1 + cfg["transfer"]["max_rounds"]
        if t["transfer"]["status"] != "failed":
            assert t["calibrated_at_scale"] == scale
        inputs = read_inputs(lay.transfer_run(spec))
        assert inputs["scale"] == pytest.approx(scale) and inputs["seed"] == 1 + kmax
    table = pd.read_csv(lay.table(TRANSFER))
    assert len(table) == 9 and set(table["scale"]) == {scale}
    v0 = yaml.safe_load((smoke / "config" / "config.yaml").read_text())["impact"]["velocity"]
    imp = read_inputs(lay.impact_run(velocity_tag(cfg["impact"].get("velocity", v0))))
    card = yaml.safe_load(Path(lay.transferred_card("B1")).read_text())
    if card["transfer"]["parameters"]:  # the impact runs the transferred card
        assert imp["pb_emod_GPa"] == pytest.approx(card["transfer"]["parameters"]["pb_emod_GPa"])


def test_the_verified_cards_are_checked_on_fresh_seeds(smoke):
    """verification.fresh_seeds (11, 12 in the smoke config): every verified card is re-run
    on those packing seeds, none of its closed loop's, with its closed-loop parameters, and
    the fresh-seed table's statistics are those of the seed tables."""
    from bpmcal.io.h5 import read_inputs
    from bpmcal.io.study_files import FRESH_SEEDS, StudyFiles

    cfg = yaml.safe_load((smoke / "config" / "smoke.yaml").read_text())
    seeds = cfg["verification"]["fresh_seeds"]
    lay = StudyFiles(str(smoke / OUTDIR))
    table = pd.read_csv(lay.table(FRESH_SEEDS))
    # three targets and sigma_t's prediction (its Brazilian test on the same fresh seeds)
    assert len(table) == 3 * 4 and set(table["seeds"]) == {",".join(map(str, seeds))}
    pred = table[table["role"] == "prediction"]
    assert set(pred["response"]) == {"bts_MPa"} and pred["lab"].isna().all()
    for spec in ("B1", "B2", "B3"):
        card = yaml.safe_load(Path(lay.verified_card(spec)).read_text())
        assert not set(seeds) & set(card["verification"]["seeds"])
        runs = pd.read_csv(lay.fresh_seed_runs(spec))
        assert list(runs["seed"]) == seeds
        for s in seeds:
            inputs = read_inputs(lay.fresh_seed_run(spec, s))
            assert inputs["seed"] == s
            assert inputs["pb_emod_GPa"] == pytest.approx(
                card["verification"]["parameters"]["pb_emod_GPa"])
        ok = runs[runs["status"] == "ok"]
        for _, r in table[table["specimen"] == spec].iterrows():
            assert r["n_failed"] == len(runs) - len(ok)
            vals = ok[r["response"]].dropna()  # sigma_t: the valid discs only
            assert r["n"] == len(vals)
            if len(vals):
                assert r["mean"] == pytest.approx(vals.mean(), rel=1e-12)
            if r["role"] == "target":  # the same cylinder as the loop's: its mean the reference
                loop = card["verification"]["closed_loop"]
                assert r["judged_by"] == "closed loop" and runs["loop_reference"].all()
                assert r["loop_mean"] == pytest.approx(loop[r["response"]], rel=1e-12)
                assert r["loop_n"] == loop["n_seeds"]
    index = (smoke / OUTDIR / "report" / "index.md").read_text()
    assert "The verified cards on fresh packing seeds" in index
    assert "**The check**: do the fresh seeds read as the card's closed loop" in index
    assert "The tensile strengths each card has no lab value for, on the same fresh seeds" in index
    loops = [yaml.safe_load(Path(lay.verified_card(sp)).read_text())["verification"]
             .get("n_seeds") for sp in ("B1", "B2", "B3")]
    # the false-alarm rate of a card fitted to its loop's seeds, when they were several
    assert ("fitted exactly to the mean of its closed loop's" in index) == any(
        isinstance(k, int) and k > 1 for k in loops)


# -- a changed config key reruns exactly the jobs that read it -------------------------------
#: DEM rules and the config sections they read (their params: specimen_args, --bts-*)
_DEM = {"sample", "sweep_ucs", "verify", "transfer", "seed_scatter", "fresh_seeds", "impact",
        "triaxial"}
_AXIAL = _DEM - {"impact"}  # the compression section: the rules that load a cylinder axially
_CAL = {"calibrate_initial", "calibrate"}
_VERIFY = {"verify"}
#: config key -> (a changed value, the rules whose jobs read it). A dry run after the change
#: must schedule exactly their jobs and those downstream of them (the rule graph), the
#: report (it renders the whole config) and `all`; a value written as {rule: n} lists the
#: jobs a structural change adds instead (new velocities, seeds, cards). The smoke study's
#: lab has no sigma_t target, so the closed loops read no bts key (they run no disc).
RERUN = {
    "study.name": ("another title", set()),
    "study.n_samples": (17, {"design"}),
    "study.lhs_seed": (8, {"design"}),
    "study.lhs_optimization": ("lloyd", {"design"}),
    "study.reference": ("none", set()),
    "ranges.rmin_mm": ([0.61, 1.0], {"design"}),
    "ranges.porosity": ([0.21, 0.36], {"design"}),
    "ranges.pb_emod_GPa": ([11.0, 50.0], {"design"}),
    "ranges.pb_kratio": ([1.1, 5.0], {"design"}),
    "ranges.pb_ten_MPa": ([11.0, 50.0], {"design"}),
    "ranges.pb_coh_MPa": ([11.0, 50.0], {"design"}),
    "ranges.pb_fa_deg": ([16.0, 55.0], {"design"}),
    "ranges.fric": ([0.16, 0.55], {"design"}),
    "specimen.scale": (0.31, _AXIAL - {"transfer"}),
    "specimen.diameter_mm": (51.0, _DEM),
    "specimen.height_mm": (101.0, _DEM),
    "specimen.sigma0_MPa": (0.11, _DEM),
    "specimen.install_gap_mm": (0.05, _DEM),
    "specimen.relax_ratio": (0.011, _DEM),
    "specimen.genesis": ("bpmcal", _DEM),
    **{f"compression.{k}": (v, _AXIAL) for k, v in {
        "platen_velocity": 0.21, "damping": 0.71, "stop_drop": 0.71, "max_strain": 0.031,
        "platen_fric": 0.01, "record_strain": 2.1e-5, "end_cap": 0.5,
        "end_cap_factor": 999.0}.items()},
    # the UCS test's approach: the jobs that run a UCS test (not the triaxial ones)
    "compression.approach_velocity": (0.09, _AXIAL - {"triaxial"}),
    "compression.approach_ramp": (4.0, _AXIAL - {"triaxial"}),
    "compression.density_scaling": (0.3, _AXIAL),
    **{f"bts.{k}": (v, {"sample", "fresh_seeds"}) for k, v in {  # fresh_seeds: every card's σt
        "enabled": False, "scale": 0.43, "diameter_mm": 51.0, "thickness_mm": 26.0,
        "loading": "jaws", "jaw_ratio": 1.4, "contact_cap": 1.4,
        "contact_cap_factor": 999.0, "central_zone": 0.45, "retests": 1, "platen_velocity": 0.051,
        "approach_velocity": 0.11, "approach_damage": 0.007, "platen_fric": 0.31,
        "damping": 0.71, "stop_drop": 0.21,
        "max_strain": 0.051, "record_strain": 1.1e-5, "post_peak_strain": 0.00031,
        "min_balls_across": 14.0, "density_scaling": 0.3}.items()},
    # the sample jobs gain the test, the fresh seeds measure each card's σt,d
    "dtt.enabled": (True, {"sample", "fresh_seeds"}),
    **{f"dtt.{k}": (v, set()) for k, v in {  # off in the smoke study: nothing reads them
        "scale": 0.31, "grip_velocity": 0.011, "grip_length": 0.21, "grip_clearance": 1.1,
        "damping": 0.71, "stop_drop": 0.21, "post_peak_strain": 0.00011, "max_strain": 0.021,
        "record_strain": 2.1e-6, "density_scaling": 0.3}.items()},
    "lab.csv": ("config/lab/green_sandstone_copy.csv",
                {"calibrate_initial", "calibrate", "verification_tables",
                 "triaxial_envelopes"}),
    "resources.dem_threads": (2, set()),  # a job's threads and Slurm time: no rerun
    "resources.loop_threads": (3, set()),
    "resources.dem_runtime_min": (31, set()),
    "resources.dem_mem_mb": (2100, _DEM),  # the jobs' memory budget (--mem-budget-mb)
    "resources.max_balls": (1_999_999, _DEM),
    "resources.genesis_max_steps": (49_999, _DEM),
    "screening.threshold_pct": (9.0, {"screen"}),
    "screening.importance": ("total_gain", {"screen"}),
    "screening.n_splits": (4, {"screen"}),
    "screening.n_repeats": (3, {"screen"}),
    "screening.seed": (12, {"screen"}),
    "screening.rule": ("above_noise", {"screen"}),
    "screening.tensile_rule": ("threshold", {"screen"}),
    "regression.alpha_in": (0.04, {"regress"}),
    "regression.alpha_out": (0.06, {"regress"}),
    "regression.vif_max": (11.0, {"regress"}),
    "regression.hierarchy": ("weak", {"regress"}),
    "regression.cv_folds": (4, {"regress"}),
    "regression.cv_repeats": (3, {"regress"}),
    "regression.seed": (13, {"regress"}),
    "calibration.fixed.porosity": (0.33, _CAL),
    "calibration.fixed.rmin_mm": (0.81, _CAL),
    "calibration.fixed.pb_fa_deg": (36.0, _CAL),
    "calibration.fixed.fric": (0.36, _CAL),
    "calibration.free": (["pb_kratio", "pb_emod_GPa", "pb_coh_MPa"], _CAL),
    "calibration.strength_ratio": (1.5, _CAL),
    "calibration.bounds.pb_emod_GPa": ([11.0, 49.0], _CAL),
    "calibration.n_boot": (21, {"calibrate"}),  # the initial calibration bootstraps nothing
    "calibration.seed": (14, _CAL),
    "verification.rtol": (0.011, {"verify", "transfer", "seed_scatter", "fresh_seeds_table"}),
    "verification.max_rounds": (3, _VERIFY),
    "verification.seed": (2, _VERIFY | {"transfer"}),
    "verification.seeds_per_round": (3, _VERIFY | {"transfer"}),
    "verification.max_seeds": (4, _VERIFY | {"transfer"}),
    "verification.polish": (False, _VERIFY),
    "verification.grow_within": (1.5, _VERIFY),
    "verification.tensile_specimens": (2, _VERIFY),  # transfer, fresh seeds: from the card
    # no σt target in the smoke study: the loops get no seed-CV options, so nothing reruns
    # (they reach a loop with a σt target: test_config_reaches_jobs.py)
    "verification.tensile_seed_cv": (0.04, set()),
    "verification.max_tensile_specimens": (5, set()),
    "verification.triaxial_seeds": (3, set()),  # no triaxial target in the smoke study
    "verification.jacobian_update": ("history", _VERIFY | {"transfer"}),
    "verification.range_margin": (0.2, _VERIFY | {"transfer"}),
    "verification.from_unreachable": (False, _VERIFY),
    "verification.scatter_seeds": ([1, 2, 3], {"seed_scatter"}),
    "verification.fresh_seeds": ([11, 12, 13], {"fresh_seeds": 3}),
    # the impact takes the verified card instead; the first card's predictive check then
    # reads that card's own reference impact (a new input)
    "transfer.enabled": (False, {"impact": 2, "posterior_predictive": 1}),
    "transfer.scale": (0.36, {"transfer"}),
    "transfer.max_rounds": (2, {"transfer"}),
    "ratio_sweep.enabled": (False, {"calibrate"}),
    "ratio_sweep.ratios": ([1.0, 1.6, 0.2], {"sweep_plan"}),
    "ratio_sweep.criterion": ("crack_count", {"sweep_analyse"}),
    "ratio_sweep.target": (0.55, {"sweep_analyse"}),
    "ratio_sweep.seed": (2, {"sweep_plan"}),
    **{f"impact.{k}": (v, {"impact", "posterior_predictive"}) for k, v in {  # draws' impacts
        "scale": 0.26, "hammer_mass_kg": 4.4, "dp_ratio": 0.11, "anvil_fric": 0.31,
        "duration_ms": 2.1, "record_us": 21.0, "seed": 2}.items()},
    "impact.velocity": (7.0, {"impact": 1, "posterior_predictive": 1}),  # 10 m/s stays
    "impact.sweep_velocities": ([10.0, 12.0], {"impact": 1}),
    "triaxial.enabled": (False, {"posterior_predictive"}),  # its own envelope is gone
    "triaxial.cards": (["verified", "calibrated"], {"triaxial": 6}),
    # the predictive check's stresses default to the triaxial section's
    "triaxial.sigma3_MPa": ([0.0, 10.0, 20.0], {"triaxial": 3, "posterior_predictive": 1}),
    "triaxial.servo_alpha": (0.7, {"triaxial", "posterior_predictive"}),
    "triaxial.seed": (2, {"triaxial", "posterior_predictive"}),
    "triaxial.lab_csv": ("config/lab/gs_triaxial.csv", {"triaxial_envelopes"}),
    "triaxial.design_sigma3_MPa": (10.0, {"sample"}),  # the sample jobs gain the test
    "triaxial.design_stop_drop": (0.85, set()),  # no design triaxial test in the smoke study
    "posterior.enabled": (False, set()),  # its jobs leave the DAG: the report only
    **{f"posterior.{k}": (v, {"posterior"}) for k, v in {
        "surrogate": "stepwise", "seed": 1, "hdi_prob": 0.8, "rhat_max": 1.02, "ess_min": 300,
        "max_steps": 30000, "refine.max_runs": 1, "refine.ratio": 0.6, "refine.seeds": 1,
        "refine.seed": 202, "predictive.draws": 3}.items()},
    "posterior.learning_curve": (False, set()),  # fewer outputs: nothing to redo
    "posterior.predictive.specimens": (2, {"posterior_predictive": 1}),
    "posterior.predictive.sigma3_MPa": ([0.0, 5.0], {"posterior_predictive": 1}),
    "posterior.predictive.impact": (False, {"posterior_predictive"}),
    # the smoke study's lab gives no disc size: no bts_size job, so nothing reruns
    **{f"bts_size.{k}": (v, set()) for k, v in {
        "seeds": 4, "max_seeds": 9, "target_se": 0.03, "first_seed": 302,
        "middle": False}.items()},
}
#: keys the map leaves out, and why
NOT_MAPPED = {"outdir": "moves every file: everything reruns, by construction",
              "contact_model": "another model needs its own ranges and fixed values: a new "
                               "study from the design on (tests/workflow/test_flatjoint_study.py)"}


def _downstream(wf) -> dict:
    """rule -> the rules that depend on it, directly or not (``snakemake --rulegraph``)."""
    import re

    r = snakemake(wf, "--rulegraph", *SMOKE)
    assert r.returncode == 0, r.stderr[-2000:]
    names = dict(re.findall(r'^\s*(\d+)\[label = "([^"]+)"', r.stdout, re.M))
    edges = re.findall(r"^\s*(\d+) -> (\d+)", r.stdout, re.M)
    child = {}
    for a, b in edges:
        child.setdefault(names[a], set()).add(names[b])
    out = {}
    for n in names.values():
        seen, todo = set(), [n]
        while todo:
            for c in child.get(todo.pop(), ()):
                if c not in seen:
                    seen.add(c)
                    todo.append(c)
        out[n] = seen
    return out


def _nested(key: str, value) -> dict:
    d = value
    for part in reversed(key.split(".")):
        d = {part: d}
    return d


def test_the_rerun_map_covers_every_config_key():
    from bpmcal.study.config import load_schema

    schema = load_schema(REPO / "workflow" / "schemas" / "config.schema.yaml")
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())

    def leaves(node, prefix=""):
        for k, sub in node.get("properties", {}).items():
            key = f"{prefix}{k}"
            if sub.get("type") == "object" and sub.get("properties"):
                yield from leaves(sub, key + ".")
            else:
                yield key
    keys = set(leaves(schema))
    # calibration.fixed / bounds: the map changes the keys the study sets (others stay unset)
    unset = {k for k in keys if k.startswith(("calibration.fixed.", "calibration.bounds."))
             and k.split(".")[-1] not in cfg["calibration"][k.split(".")[1]]}
    # ranges of the other contact model's parameters: a parallel-bond study sets none
    unset |= {k for k in keys if k.startswith("ranges.") and k.split(".")[1] not in cfg["ranges"]}
    missing = keys - set(RERUN) - set(NOT_MAPPED) - unset - {"calibration.bounds.pb_emod_GPa"}
    assert not missing, f"config keys without an entry in the rerun map: {sorted(missing)}"


def test_a_changed_config_key_reruns_exactly_the_jobs_that_read_it(smoke):
    """Each key of the config in turn, changed over the finished smoke study: the dry run
    schedules the jobs that read it and everything downstream, nothing else. (A rule whose
    params miss a key it passes - or hold a whole section - fails here: the Brazilian
    settings once reached the sample jobs through a callable, which Snakemake's params
    trigger does not compare, so a bts change left the dataset's sigma_t stale.)"""
    from concurrent.futures import ThreadPoolExecutor

    shutil.copy(smoke / "config" / "lab" / "green_sandstone.csv",
                smoke / "config" / "lab" / "green_sandstone_copy.csv")
    (smoke / "config" / "lab" / "gs_triaxial.csv").write_text(
        "specimen,sigma3_MPa,sigma1_MPa\nB1,0,60\nB1,10,95\n")
    base = scheduled_jobs((r := snakemake(smoke, "-n", *SMOKE)).stdout + r.stderr)
    assert base == {}, f"the finished study is not up to date: {base}"
    down = _downstream(smoke)

    def dry(item):
        i, (key, (value, _)) = item
        f = smoke / "config" / f"rerun_{i}.yaml"
        f.write_text(yaml.safe_dump(_nested(key, value)))
        r = snakemake(smoke, "-n", "--nolock", *SMOKE, f"config/rerun_{i}.yaml")
        return key, r

    with ThreadPoolExecutor(max_workers=2) as pool:
        results = dict(pool.map(dry, enumerate(RERUN.items())))
    wrong = []
    for key, (value, readers) in RERUN.items():
        r = results[key]
        if r.returncode != 0:
            wrong.append(f"{key}={value!r}: the dry run failed: {r.stderr[-400:]}")
            continue
        got = scheduled_jobs(r.stdout + r.stderr)
        if isinstance(readers, dict):  # a structural change: these new jobs
            want = {**readers}
            for rule in readers:
                want.update({d: None for d in down[rule]})
            ok = set(got) == set(want) and all(got.get(k) == n for k, n in readers.items())
        else:
            want = set(readers).union(*(down[rr] for rr in readers)) if readers else set()
            want |= {"report", "all"}
            ok = set(got) == want
        if not ok:
            wrong.append(f"{key}={value!r}: scheduled {got}, expected "
                         f"{sorted(want) if not isinstance(want, dict) else want}")
    assert not wrong, "\n".join(wrong)


def test_the_posterior_record_reads_every_card_of_the_study(smoke):
    """benchmarks/posterior_study.py on the smoke study: every lab specimen's posterior is
    read (its parameters' HDIs hold their means; the learning curve's runs grow), the
    predictive draws of the first specimen are summarised, and the record renders."""
    import sys

    sys.path.insert(0, str(REPO / "benchmarks"))
    import posterior_study

    res = smoke / OUTDIR
    specs = list(pd.read_csv(smoke / "config" / "lab" / "green_sandstone.csv")["specimen"])
    rec = posterior_study.record(res, specs, None, "test", "", [])
    assert [c["specimen"] for c in rec["cards"]] == specs
    for c in rec["cards"]:
        assert c["parameters"] and c["identifiability"]
        for p, d in c["parameters"].items():
            lo, hi = d["hdi"]
            assert lo <= d["mean"] <= hi, (c["specimen"], p)
        runs = [p["dem_runs"] for p in c["learning_curve"]]
        assert runs == sorted(runs) and len(runs) >= 2
    first = rec["cards"][0]["predictive"]
    assert first["mi"]["draws"] >= 1 and first["mi"]["low"] <= first["mi"]["mean"] <= first["mi"]["high"]
    text = posterior_study.markdown(rec)
    assert all(f"## {s}:" in text for s in specs)
