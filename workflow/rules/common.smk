# Helpers shared by the rules: config validation, the study's files and ids, and each job's
# command (bpmcal.cli.jobs: built from the config by the package, for the rules and the
# benchmarks alike; each rule names its files and passes the command, params.argv, quoted).
#
# Every file name comes from bpmcal.io.study_files (StudyFiles: the study's file contract; the stages
# use the same module). Rules declare every file their command reads (in input) and writes
# (in output) and pass each one on the command line; a table's Markdown and a figure's PDF
# are written beside the CSV/PNG (companions) and declared too.
#
# Shell safety: every value that comes from the config or from a file name reaches a shell
# command only through Snakemake's quoting ({params.argv:q}: element by element), never
# spliced as text. outdir, lab.csv and specimen names are also checked against safe
# patterns at validation (bpmcal.io.safe_names).
import os

from bpmcal.cli.jobs import job_argv, job_options, lab_targets, predictive_sigma3
from bpmcal.io import study_files as L
from bpmcal.study.config import (
    ConfigError,
    load_lab,
    loop_rounds_bound,
    validate_config,
)

try:
    validate_config(config, workflow.source_path("../schemas/config.schema.yaml"))
    _lab = load_lab(config["lab"]["csv"])
except ConfigError as e:
    raise WorkflowError(str(e)) from None

FILES = L.StudyFiles(config["outdir"])
# every bpmcal job ends its log with its cost line: CPU seconds and the engine's
# ball-steps by phase (bpmcal.cost; read by benchmarks/cost_model.py)
os.environ.setdefault("BPMCAL_COST", "1")
SAMPLES = L.sample_ids(config["study"]["n_samples"])
# which ready job Snakemake starts first (a job's priority, higher first; no rule waits
# for a lower one): the longest jobs, so that short ones fill the cores at the end instead
# of a long one running alone - the posterior predictive (every draw's triaxial tests and
# impact), the closed loops and transfers, the posteriors, the fresh seeds and the σt size
# curves, the impacts, the seed scatter, then the one-test jobs; the analysis jobs
# (seconds) last
PRIORITY = {
    "posterior_predictive": 60,
    "verify": 50,
    "transfer": 50,
    "posterior": 45,
    "fresh_seeds": 40,
    "bts_size": 40,
    "impact": 30,
    "seed_scatter": 25,
    "sample": 20,
    "triaxial": 20,
    "sweep_ucs": 10,
}
SPECIMENS = list(_lab["specimen"])
SWEEP_ON = bool(config["ratio_sweep"]["enabled"])
BTS_ON = bool(config["bts"]["enabled"])  # a Brazilian test of every design sample
DTT_ON = bool(config["dtt"]["enabled"])  # a direct-tension test of every design sample
SWEEP_SPEC = SPECIMENS[0]  # the sweep starts from the first specimen's initial card
IMPACT_SPEC = SPECIMENS[0]  # the impact uses the first specimen's verified card
TRANSFER_ON = bool(config["transfer"]["enabled"])
# the card the impact runs: the full-size transfer's when it runs, else the verified one
IMPACT_CARD = (
    FILES.transferred_card(IMPACT_SPEC)
    if TRANSFER_ON
    else FILES.verified_card(IMPACT_SPEC)
)
SWEEP_IDS = L.sweep_ids(config["ratio_sweep"]["ratios"])
IMPACT_V0 = L.velocity_tag(config["impact"]["velocity"])
IMPACT_VS = L.impact_tags(
    config["impact"]["velocity"], config["impact"]["sweep_velocities"]
)
SCATTER_SEEDS = config["verification"]["scatter_seeds"]
FRESH_SEEDS = list(config["verification"]["fresh_seeds"])
FRESH_SEEDS_ON = bool(FRESH_SEEDS)  # the verified cards on fresh packing seeds
# the lab's targets that add a test to a card's runs (bpmcal.cli.jobs.lab_targets)
LAB_TARGETS = lab_targets(config, _lab)
# a lab sigma_t target: the fresh-seed check runs each card's Brazilian test too
LAB_BTS = "bts" in LAB_TARGETS
# a lab direct-tension strength: the closed loops and fresh seeds run that test
LAB_DTT = "dtt" in LAB_TARGETS
REFERENCE = config["study"].get("reference") == "yu2026"
TRIAX_ON = bool(config["triaxial"]["enabled"])
TRIAX_KINDS = list(config["triaxial"]["cards"])
TRIAX_S3 = [float(x) for x in config["triaxial"]["sigma3_MPa"]]
TRIAX_TAGS = [L.sigma3_tag(x) for x in TRIAX_S3]
TRIAX_LAB = config["triaxial"]["lab_csv"]  # None: no lab triaxial points
# a triaxial test of every design sample at this confinement (None: none)
TRI_ON = config["triaxial"]["design_sigma3_MPa"] is not None
# a lab triaxial strength at that confinement: the closed loops and fresh seeds run it
LAB_TRI = "tri" in LAB_TARGETS
POSTERIOR_ON = bool(config["posterior"]["enabled"])  # every verified card's posterior
POSTERIOR_CURVE = bool(config["posterior"]["learning_curve"])
# the posterior predictive in DEM: the first N specimens' cards, when draws are asked for
PREDICTIVE_SPECS = (
    SPECIMENS[: config["posterior"]["predictive"]["specimens"]]
    if POSTERIOR_ON and config["posterior"]["predictive"]["draws"]
    else []
)


def beside(*files):
    """The files written beside ``files`` (a table's .md, a figure's .pdf), to declare."""
    return [c for f in files for c in L.companions(f)[1:]]


def settings(job):
    """The config's settings of ``job``'s command (bpmcal.cli.jobs.job_options): a plain
    value of the rule's params, so that changing a key the job reads reruns it, and a key
    it does not read reruns nothing (tests/workflow/test_smoke.py, the rerun map)."""
    return job_options(config, job, LAB_TARGETS)


def argv(job):
    """The job's whole ``bpmcal`` command (bpmcal.cli.jobs.job_argv: the config's settings,
    the job's files, wildcards and threads, each after its option), for {params.argv:q}:
    every argument shell-quoted. Derived from the job's files, so Snakemake does not
    compare it (``settings`` is compared)."""

    def of(wildcards, input, output, threads):
        return job_argv(
            config,
            job,
            input=input,
            output=output,
            wildcards=wildcards,
            threads=threads,
            targets=LAB_TARGETS,
        )

    return of


# ---- the posterior predictive (workflow/rules/posterior.smk)
_PRED = config["posterior"]["predictive"]
_PRED_S3 = predictive_sigma3(config)
_PRED_N = int(_PRED["draws"])
_PRED_IMPACT = bool(_PRED["impact"])
_PRED_ENV = TRIAX_ON and "verified" in TRIAX_KINDS  # the card's own envelope


# the predictive's run files, with the {spec} wildcard
_PRED_TRI, _PRED_IMP = FILES.predictive_runs("{spec}", _PRED_N, _PRED_S3, _PRED_IMPACT)
