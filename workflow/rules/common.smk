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

import pandas as _pd

SPECIMENS = [str(s) for s in _pd.read_csv(config["lab"]["csv"])["specimen"]]


def specimen_args(cfg=config):
    """bpmcal ucs options of the specimen and loading sections."""
    sp, u = cfg["specimen"], cfg["ucs"]
    return (f"--scale {sp['scale']} --diameter {sp['diameter_mm']} --height {sp['height_mm']} "
            f"--sigma0 {sp['sigma0_MPa']} --install-gap {sp['install_gap_mm']} "
            f"--relax-ratio {sp['relax_ratio']} --platen-velocity {u['platen_velocity']} "
            f"--damping {u['damping']} --stop-drop {u['stop_drop']} "
            f"--max-strain {u['max_strain']} --platen-fric {u['platen_fric']} "
            f"--record-strain {u['record_strain']} --specimen-cache {PACKINGS}")
