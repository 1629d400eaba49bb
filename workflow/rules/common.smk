# Helpers shared by the rules: config validation, paths, sample ids, CLI options.
import json
import os

from bpmcal.study.config import ConfigError, validate_config

try:
    validate_config(config, workflow.source_path("../schemas/config.schema.yaml"))
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

from bpmcal.study.config import read_lab

SPECIMENS = [str(s) for s in read_lab(config["lab"]["csv"])["specimen"]]


def _vtag(v):
    """6.0 -> "6", 2.5 -> "2.5" (file names of the impact runs)."""
    return f"{float(v):g}"


SWEEP_SPEC = SPECIMENS[0]
IMPACT_SPEC = SPECIMENS[0]
_r0, _r1, _rs = config["ratio_sweep"]["ratios"]
SWEEP_IDS = [f"a{int(round((_r0 + k * _rs) * 100)):03d}"
             for k in range(int((_r1 - _r0) / _rs + 1e-9) + 1)]
IMPACT_V0 = _vtag(config["impact"]["velocity"])
IMPACT_VS = sorted({_vtag(v) for v in [config["impact"]["velocity"],
                                       *config["impact"]["sweep_velocities"]]}, key=float)


def specimen_args(cfg=config, scale=None):
    """bpmcal ucs options of the specimen and loading sections."""
    sp, u = cfg["specimen"], cfg["ucs"]
    scale = sp["scale"] if scale is None else scale
    return (f"--scale {scale} --diameter {sp['diameter_mm']} --height {sp['height_mm']} "
            f"--sigma0 {sp['sigma0_MPa']} --install-gap {sp['install_gap_mm']} "
            f"--relax-ratio {sp['relax_ratio']} --platen-velocity {u['platen_velocity']} "
            f"--damping {u['damping']} --stop-drop {u['stop_drop']} "
            f"--max-strain {u['max_strain']} --platen-fric {u['platen_fric']} "
            f"--record-strain {u['record_strain']} --specimen-cache {PACKINGS}")


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
