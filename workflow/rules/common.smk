# Helpers shared by the rules: config validation, the study's files and ids, CLI options.
#
# Every file name comes from bpmcal.io.study_files (StudyFiles: the study's file contract; the stages
# use the same module). Rules declare every file their command reads (in input) and writes
# (in output) and pass each one on the command line; a table's Markdown and a figure's PDF
# are written beside the CSV/PNG (companions) and declared too.
#
# Shell safety: every value that comes from the config or from a file name reaches a shell
# command only through Snakemake's quoting ({x:q}; a list is quoted element by element),
# never spliced as text. outdir, lab.csv and specimen names are also checked against safe
# patterns at validation (bpmcal.io.safe_names).
import json
import os

from bpmcal.cli import BTS_OPTIONS, DTT_OPTIONS
from bpmcal.cli.options import loop_argv
from bpmcal.io import study_files as L
from bpmcal.study.config import (
    ConfigError,
    load_lab,
    loop_rounds_bound,
    transfer_seed,
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
# a lab sigma_t target: the fresh-seed check runs each card's Brazilian test too
LAB_BTS = "bts_MPa" in _lab.columns and bool(_lab["bts_MPa"].notna().any())
# a lab direct-tension strength: the closed loops and fresh seeds run that test
LAB_DTT = "dtt_MPa" in _lab.columns and bool(_lab["dtt_MPa"].notna().any())
REFERENCE = config["study"].get("reference") == "yu2026"
TRIAX_ON = bool(config["triaxial"]["enabled"])
TRIAX_KINDS = list(config["triaxial"]["cards"])
TRIAX_S3 = [float(x) for x in config["triaxial"]["sigma3_MPa"]]
TRIAX_TAGS = [L.sigma3_tag(x) for x in TRIAX_S3]
TRIAX_LAB = config["triaxial"]["lab_csv"]  # None: no lab triaxial points
# a triaxial test of every design sample at this confinement (None: none)
TRI_ON = config["triaxial"]["design_sigma3_MPa"] is not None
# a lab triaxial strength at that confinement: the closed loops and fresh seeds run it
LAB_TRI = "tri_MPa" in _lab.columns and bool(_lab["tri_MPa"].notna().any())
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


def specimen_args(cfg=config, scale=None, loading=True, ucs=True):
    """bpmcal sample/ucs/impact options of the specimen, loading (the compression section;
    ``loading`` False for a job that does not load a cylinder axially: the impact; ``ucs``
    False for one that runs no UCS test, without the UCS test's approach: the triaxial
    tests) and resources sections, as a list of arguments (for {params.opts:q}: each one
    is shell-quoted).
    A job's params hold only what it reads, so that a changed key reruns exactly those
    jobs (tests/workflow/test_smoke.py, the rerun map)."""
    sp, u, r = cfg["specimen"], cfg["compression"], cfg["resources"]
    scale = sp["scale"] if scale is None else scale
    opts = {
        "--scale": scale,
        "--diameter": sp["diameter_mm"],
        "--height": sp["height_mm"],
        "--sigma0": sp["sigma0_MPa"],
        "--genesis": sp["genesis"],
        "--relax-ratio": sp["relax_ratio"],
    }
    if loading:
        opts.update(
            {
                "--platen-velocity": u["platen_velocity"],
                "--damping": u["damping"],
                "--stop-drop": u["stop_drop"],
                "--max-strain": u["max_strain"],
                "--platen-fric": u["platen_fric"],
                "--record-strain": u["record_strain"],
                "--end-cap": u["end_cap"],
                "--end-cap-factor": u["end_cap_factor"],
            }
        )
    if loading and ucs:
        opts["--approach-velocity"] = u["approach_velocity"]
        opts["--approach-ramp"] = u["approach_ramp"]
    opts.update(
        {
            "--specimen-cache": FILES.packings,
            "--max-balls": r["max_balls"],
            "--mem-budget-mb": r["dem_mem_mb"],
            "--genesis-max-steps": r["genesis_max_steps"],
        }
    )
    if sp["install_gap_mm"] is not None:  # null: the genesis's own gap
        opts["--install-gap"] = sp["install_gap_mm"]
    return [str(x) for k, v in opts.items() for x in (k, v)]


def bts_args(cfg=config):
    """The --bts-* options of bpmcal sample/verify/transfer from the bts section: every
    Brazilian test of the study (the samples' and, for a card with a tensile strength
    target, the closed loops') runs with the same disc and loading."""
    b = cfg["bts"]
    opts = {"--bts-diameter": b["diameter_mm"], "--bts-thickness": b["thickness_mm"]}
    if b["scale"] is not None:  # null: the disc at the cylinder's scale
        opts["--bts-scale"] = b["scale"]
    # the BTSSettings fields that are options (bpmcal.cli.options), each its config key
    for f in BTS_OPTIONS:
        opts[f"--bts-{f.replace('_', '-')}"] = b[f]
    return [str(x) for k, v in opts.items() for x in (k, v)]


def tri_args(cfg=config):
    """The --tri-* options of bpmcal sample/verify/transfer/fresh-seeds: the triaxial test at
    the design confinement (triaxial.design_sigma3_MPa) on the UCS cylinder and loading.
    """
    t = cfg["triaxial"]
    return [
        "--design-sigma3",
        str(t["design_sigma3_MPa"]),
        "--tri-servo-alpha",
        str(t["servo_alpha"]),
        "--design-stop-drop",
        str(t["design_stop_drop"]),
    ]


def dtt_args(cfg=config):
    """The --dtt-* options of bpmcal sample/verify/transfer/fresh-seeds from the dtt section: the
    direct-tension test of every sample and, for a card with a dtt_MPa target, of the
    closed loops (the UCS cylinder at dtt.scale)."""
    d = cfg["dtt"]
    opts = {}
    if d["scale"] is not None:  # null: the cylinder's scale
        opts["--dtt-scale"] = d["scale"]
    # the DTTSettings fields that are options (bpmcal.cli.options), each its config key
    for f in DTT_OPTIONS:
        opts[f"--dtt-{f.replace('_', '-')}"] = d[f]
    return [str(x) for k, v in opts.items() for x in (k, v)]


def loop_args(cfg=config):
    """The closed loop's options of bpmcal verify from the verification section: one per
    LoopSettings field (bpmcal.cli.options.loop_argv: names, checks and switches from the
    fields); the tensile-specimen count's adaptation only for a sigma_t target, the
    triaxial seed cap only for a sigma_1 one, so that those keys rerun nothing else."""
    return loop_argv(cfg["verification"], tensile=LAB_BTS or LAB_DTT, triaxial=LAB_TRI)


# ---- the posterior predictive (workflow/rules/posterior.smk)
_PRED = config["posterior"]["predictive"]
_PRED_S3 = [float(x) for x in (_PRED["sigma3_MPa"] or config["triaxial"]["sigma3_MPa"])]
_PRED_N = int(_PRED["draws"])
_PRED_IMPACT = bool(_PRED["impact"])
_PRED_ENV = TRIAX_ON and "verified" in TRIAX_KINDS  # the card's own envelope


# the predictive's run files, with the {spec} wildcard
_PRED_TRI, _PRED_IMP = FILES.predictive_runs("{spec}", _PRED_N, _PRED_S3, _PRED_IMPACT)
