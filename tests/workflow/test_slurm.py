"""The Slurm workflow profile against a real (private, single-node) Slurm cluster.

Runs the bpmcal smoke study (4 samples) with
``snakemake --executor slurm --workflow-profile workflow/profiles/slurm`` and checks that
the ``sample`` jobs really went through sbatch (the job id is in each run file's provenance),
grouped, that the cheap rules ran locally, and that the cluster is gone afterwards.
"""

import os
import re
import time

import pytest
import yaml
from support import slurm_cluster as sc
from support.repo import REPO, copy_workflow

PROFILE = REPO / "workflow" / "profiles" / "slurm"
N_SAMPLES = 4


def test_profile_keys_are_valid_snakemake_options():
    """Every key of the profile is a Snakemake (or Slurm plugin) command-line option."""
    from snakemake.cli import get_argument_parser

    profile = yaml.safe_load((PROFILE / "config.yaml").read_text())
    parser = get_argument_parser()
    known = {opt.lstrip("-") for action in parser._actions for opt in action.option_strings}
    known |= {  # plugin options are registered only when the plugin is loaded
        "slurm-status-command",
        "slurm-init-seconds-before-status-checks",
        "slurm-status-attempts",
    }
    assert not set(profile) - known, f"unknown profile keys: {set(profile) - known}"
    assert profile["executor"] == "slurm"
    assert profile["slurm-status-command"] == "squeue"
    assert profile["groups"] == {"sample": "sample_batch"}  # a sample job: UCS and Brazilian test
    assert profile["group-components"]["sample_batch"] > 1
    assert "slurm_partition" not in profile["default-resources"]  # left to the user
    assert "slurm_account" not in profile["default-resources"]


def test_skips_cleanly_when_not_root(monkeypatch, tmp_path):
    monkeypatch.setenv(sc.ASK, "1")
    monkeypatch.setattr(os, "geteuid", lambda: 1000)
    assert sc.unavailable_reason() == "Slurm test needs root and apt-get (not root)"
    etc_before = sc.ETC_SLURM_CONF.exists() or sc.ETC_SLURM_CONF.is_symlink()
    with pytest.raises(sc.SlurmUnavailable, match=r"needs root and apt-get \(not root\)"):
        with sc.local_slurm_cluster(tmp_path):
            pass
    with pytest.raises(pytest.skip.Exception, match=r"needs root and apt-get \(not root\)"):
        with sc.cluster_or_skip(tmp_path):
            pass
    # nothing was touched
    assert (sc.ETC_SLURM_CONF.exists() or sc.ETC_SLURM_CONF.is_symlink()) == etc_before
    assert not (tmp_path / sc.MARKER).exists()


@pytest.mark.parametrize("value", [None, "", "0"])
def test_skips_and_changes_nothing_unless_asked(monkeypatch, tmp_path, value):
    """Without BPMCAL_TEST_SLURM=1 the cluster is not brought up, even as root with
    apt-get at hand: no package is installed, no daemon started, /etc is untouched."""
    if value is None:
        monkeypatch.delenv(sc.ASK, raising=False)
    else:
        monkeypatch.setenv(sc.ASK, value)
    monkeypatch.setattr(os, "geteuid", lambda: 0)  # root, where the test would install
    calls = []
    monkeypatch.setattr(sc, "ensure_installed", lambda *a, **k: calls.append(a) or 0.0)
    monkeypatch.setattr(sc.subprocess, "Popen", lambda *a, **k: calls.append(a))
    assert sc.unavailable_reason().startswith("Slurm test not asked for: set BPMCAL_TEST_SLURM=1")
    etc_before = sc.ETC_SLURM_CONF.exists() or sc.ETC_SLURM_CONF.is_symlink()
    with pytest.raises(pytest.skip.Exception, match="not asked for"):
        with sc.cluster_or_skip(tmp_path):
            pass
    with pytest.raises(sc.SlurmUnavailable, match="not asked for"):
        with sc.local_slurm_cluster(tmp_path):
            pass
    assert calls == []
    assert (sc.ETC_SLURM_CONF.exists() or sc.ETC_SLURM_CONF.is_symlink()) == etc_before
    assert not (tmp_path / sc.MARKER).exists()


@pytest.mark.slow
@pytest.mark.slurm
def test_smoke_study_runs_through_sbatch(local_slurm, tmp_path):
    cluster = local_slurm
    print(
        f"\nSlurm bring-up: {cluster.bringup_seconds:.1f} s (apt-get {cluster.install_seconds:.1f} s;",
        f"{cluster.cpus} CPUs, {cluster.real_memory_mb} MB)",
    )
    wf = copy_workflow(tmp_path / "wf")
    (wf / "config" / "slurm_test.yaml").write_text(yaml.safe_dump(
        {"outdir": "results", "study": {"name": "slurm", "n_samples": N_SAMPLES, "lhs_seed": 5},
         "resources": {"dem_runtime_min": 5},
         "bts": {"enabled": False}}))  # UCS only: shorter sample jobs, same batches

    run = sc.run_snakemake_on_slurm(
        wf,
        PROFILE,
        [
            "results/dataset.csv",  # the sample stage: the part that goes to the cluster
            "--jobs", "4",
            # two batches of two sample jobs: several submissions, each holding several jobs
            "--group-components", "sample_batch=2",
            # first status check after 2 s instead of the profile's 5 s
            "--slurm-init-seconds-before-status-checks", "2",
            "--seconds-between-status-checks", "2",
            "--slurm-keep-successful-logs",
            "--configfile", "config/smoke.yaml", "config/slurm_test.yaml",
        ],
        timeout_s=600,
        env=cluster.env,
    )  # fmt: skip
    diagnostics = f"\n--- snakemake output ({run.log}) ---\n{run.output[-6000:]}\n{cluster.log_tails(20)}"
    assert not run.timed_out, "snakemake timed out" + diagnostics
    assert run.returncode == 0, f"snakemake failed ({run.returncode})" + diagnostics

    # every ucs run file was written inside a Slurm job (its provenance has the job id)
    from bpmcal.io.h5 import read_summary

    ids_in_outputs = {}
    for i in range(N_SAMPLES):
        s = read_summary(wf / "results" / "ucs" / f"s{i:03d}.h5")
        jobid = s["slurm_job_id"]
        assert re.fullmatch(r"\d+", jobid), f"no SLURM_JOB_ID in s{i:03d}: {jobid!r}" + diagnostics
        assert s["hostname"] == cluster.node
        ids_in_outputs[i] = jobid
    import pandas as pd

    assert len(pd.read_csv(wf / "results" / "dataset.csv")) == N_SAMPLES

    # ... and those jobs are the ones Snakemake submitted with sbatch
    submitted = run.slurm_job_ids
    assert submitted, "no 'has been submitted with SLURM jobid' lines" + diagnostics
    assert set(ids_in_outputs.values()) == set(submitted), diagnostics
    # grouping: fewer submissions than sample jobs (2 batches of 2 here)
    assert len(submitted) < N_SAMPLES, diagnostics
    assert len(set(submitted)) == len(submitted) == 2, diagnostics
    # each batch was sized for serial execution inside its allocation (profile `cores: 1`):
    # 1 CPU and -t = 2 jobs x 5 min (dem_runtime_min; finished jobs stay visible for
    # MinJobAge = 300 s)
    for jobid in submitted:
        info = cluster.run("scontrol", "show", "job", "-o", jobid).stdout
        assert "NumCPUs=1 " in info and "TimeLimit=00:10:00 " in info, info

    # only the sample batches went to Slurm (gather is a local rule)
    slurm_logs = wf / ".snakemake" / "slurm_logs"
    log_dirs = [p.name for p in slurm_logs.iterdir()]  # group_<group>_<rules>
    assert log_dirs and all(name.startswith("group_sample_batch") for name in log_dirs), diagnostics

    # the cluster goes away completely
    pids = dict(cluster.pids)
    t1 = time.monotonic()
    cluster.stop()
    stop_seconds = time.monotonic() - t1
    assert not cluster.daemons_alive(), f"daemons still alive after stop: {cluster.daemons_alive()}"
    leftovers = [p for p in sc.slurm_processes() if p[0] in pids.values() or sc.MARKER in p[2]]
    assert not leftovers, f"processes left behind: {leftovers}"
    etc = sc.ETC_SLURM_CONF
    assert not (etc.is_symlink() and sc.MARKER in os.readlink(etc)), "/etc/slurm/slurm.conf not restored"
    print(
        f"Slurm part: bring-up {cluster.bringup_seconds:.1f} s + snakemake {run.seconds:.1f} s"
        f" + tear-down {stop_seconds:.1f} s = {cluster.bringup_seconds + run.seconds + stop_seconds:.1f} s;"
        f" {len(submitted)} submissions for {N_SAMPLES} sample jobs"
    )
