# Helpers shared by the rules: config validation, paths, sample ids, CLI options.
#
# Shell safety: every value that comes from the config or from a file name reaches a shell
# command only through Snakemake's quoting ({x:q}; a list is quoted element by element),
# never spliced as text. outdir, lab.csv and specimen names are also checked against safe
# patterns at validation (bpmcal.io.paths).
import json
import os

from bpmcal.study.config import ConfigError, load_lab, validate_config
from bpmcal.study.sweep import ratio_grid, ratio_id

try:
    validate_config(config, workflow.source_path("../schemas/config.schema.yaml"))
    _lab = load_lab(config["lab"]["csv"])
except ConfigError as e:
    raise WorkflowError(str(e)) from None

OUT = config["outdir"]
N = int(config["study"]["n_samples"])
SAMPLES = [f"s{i:0{max(3, len(str(N)))}d}" for i in range(N)]
DESIGN = f"{OUT}/design/samples.csv"
DATASET = f"{OUT}/dataset.csv"
PACKINGS = f"{OUT}/cache/packings"
LOGS = f"{OUT}/logs"
SWEEP = f"{OUT}/ratio_sweep"
SWEEP_PLAN = f"{SWEEP}/plan.csv"
SWEEP_CHOSEN = f"{SWEEP}/chosen.json"
IMPACT = f"{OUT}/impact"

SPECIMENS = list(_lab["specimen"])


def _vtag(v):
    """6.0 -> "6", 2.5 -> "2.5" (file names of the impact runs)."""
    return f"{float(v):g}"


SWEEP_SPEC = SPECIMENS[0]
IMPACT_SPEC = SPECIMENS[0]
SWEEP_IDS = [ratio_id(a) for a in ratio_grid(*config["ratio_sweep"]["ratios"])]
IMPACT_V0 = _vtag(config["impact"]["velocity"])
IMPACT_VS = sorted({_vtag(v) for v in [config["impact"]["velocity"],
                                       *config["impact"]["sweep_velocities"]]}, key=float)


def specimen_args(cfg=config, scale=None):
    """bpmcal ucs/impact options of the specimen, loading and resources sections, as a list
    of arguments (for {params.opts:q}: each one is shell-quoted)."""
    sp, u, r = cfg["specimen"], cfg["ucs"], cfg["resources"]
    scale = sp["scale"] if scale is None else scale
    opts = {"--scale": scale, "--diameter": sp["diameter_mm"], "--height": sp["height_mm"],
            "--sigma0": sp["sigma0_MPa"], "--genesis": sp["genesis"],
            "--relax-ratio": sp["relax_ratio"], "--platen-velocity": u["platen_velocity"],
            "--damping": u["damping"], "--stop-drop": u["stop_drop"],
            "--max-strain": u["max_strain"], "--platen-fric": u["platen_fric"],
            "--record-strain": u["record_strain"], "--specimen-cache": PACKINGS,
            "--max-balls": r["max_balls"], "--mem-budget-mb": r["ucs_mem_mb"],
            "--genesis-max-steps": r["genesis_max_steps"]}
    if sp["install_gap_mm"] is not None:  # null: the genesis's own gap
        opts["--install-gap"] = sp["install_gap_mm"]
    return [str(x) for k, v in opts.items() for x in (k, v)]


def parent_of(key, up=1, io="output"):
    """A params function: the folder ``up`` levels above a rule's output (or input) ``key``
    (a name or an index; the first file of a list), so shell commands get folders that
    follow the declared files instead of hard-coded prefixes."""

    def f(wildcards, input, output):
        files = output if io == "output" else input
        v = files[key] if isinstance(key, int) else getattr(files, key)
        path = v if isinstance(v, str) else v[0]
        for _ in range(up):
            path = os.path.dirname(path)
        return path

    return f
