"""``benchmarks/genesis_share.py`` times the default study's sample job with its options
(``study_args()``, from ``bpmcal.cli.jobs.job_argv``, as the workflow's); a hand-typed
copy once went stale silently (it ran the Brazilian disc at an old size and speed). The
options of the default study's dry run must be the benchmark's."""
import shlex
import sys

import pytest
from support.repo import REPO, copy_workflow, run_snakemake

from bpmcal.cli import build_parser

pytestmark = pytest.mark.slow  # a Snakemake dry run of the default study

#: options that name files, which the benchmark sets itself per job
PER_JOB = {"design", "sample", "out", "bts_out", "specimen_cache", "dtt_out"}


def test_genesis_share_runs_the_sample_job_with_the_default_study_options(tmp_path):
    sys.path.insert(0, str(REPO / "benchmarks"))
    import genesis_share
    wf = copy_workflow(tmp_path / "wf")
    r = run_snakemake(wf, "-n", "-p", timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    line = next(ln for ln in (r.stdout + r.stderr).splitlines()
                if "Shell command: bpmcal sample " in ln)
    argv = shlex.split(line.split("Shell command: ", 1)[1])
    argv = argv[1:argv.index(">")]
    parser = build_parser(only="sample")
    study = vars(parser.parse_args(argv))
    bench = vars(parser.parse_args(["sample", "--design", "d.csv", "--sample", "s000",
                                    "--out", "u.h5", *genesis_share.study_args()]))
    differ = {k: (study[k], bench.get(k)) for k in study
              if k not in PER_JOB and study[k] != bench.get(k)}
    assert not differ, f"genesis_share.study_args() differ from the workflow: {differ}"
