"""Workflow-catalog conventions, checked with every test run (so also in CI): the workflow
lints clean (``snakemake --lint``: every rule has a log and a software environment, no
hard-coded prefixes, ...), its Snakemake files are formatted (``snakefmt --check``), and
the catalog's files are there."""
import os
import subprocess
import sys

import pytest
import yaml
from support.repo import REPO

pytestmark = pytest.mark.slow  # snakemake --lint and snakefmt: seconds


def run(*cmd):
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, NUMBA_THREADING_LAYER="omp"))


def test_snakemake_lint_is_clean():
    r = run(sys.executable, "-m", "snakemake", "--lint")
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]
    assert "Congratulations, your workflow is in a good condition!" in r.stdout + r.stderr


def test_snakefmt_check_is_clean():
    r = run(sys.executable, "-m", "snakefmt", "--check", ".")
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]


def test_catalog_files():
    assert "BSD 3-Clause License" in (REPO / "LICENSE").read_text()
    meta = yaml.safe_load((REPO / ".snakemake-workflow-catalog.yml").read_text())
    sd = meta["usage"]["software-stack-deployment"]
    assert set(sd) == {"conda", "apptainer", "apptainer+conda", "report"}
    assert all(isinstance(v, bool) for v in sd.values())
    assert (REPO / "config" / "README.md").exists()
    assert 'min_version("8.0")' in (REPO / "Snakefile").read_text()
    env = yaml.safe_load((REPO / "workflow" / "envs" / "bpmcal.yaml").read_text())
    assert {"pip": ["-e ../.."]} in env["dependencies"]
