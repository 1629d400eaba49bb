"""The repository under test: its root, its configs merged as Snakemake merges them, and
private copies of the workflow to run Snakemake in."""
import copy
import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

#: the repository's root (the folder holding Snakefile, config/, workflow/, src/)
REPO = Path(__file__).resolve().parents[2]
#: the config schema the study validates against
SCHEMA = REPO / "workflow" / "schemas" / "config.schema.yaml"


def update_config(a: dict, b: dict, keep=()) -> dict:
    """Update ``a`` with ``b`` in place as Snakemake's ``--configfile`` does: nested
    mappings are merged key by key, anything else (and any key in ``keep``) is replaced
    by a copy of ``b``'s value. Returns ``a``."""
    for k, v in b.items():
        if isinstance(v, dict) and isinstance(a.get(k), dict) and k not in keep:
            update_config(a[k], v, keep)
        else:
            a[k] = copy.deepcopy(v)
    return a


def merged_config(*names) -> dict:
    """The config files ``config/<name>`` merged in order, as ``--configfile`` merges them
    (later files update nested keys of earlier ones)."""
    cfg = {}
    for n in names:
        update_config(cfg, yaml.safe_load((REPO / "config" / n).read_text()))
    return cfg


def copy_workflow(dst: Path) -> Path:
    """A private copy of the workflow (its own .snakemake metadata and outputs)."""
    dst.mkdir(parents=True, exist_ok=True)
    shutil.copy(REPO / "Snakefile", dst)
    shutil.copytree(REPO / "workflow", dst / "workflow")
    shutil.copytree(REPO / "config", dst / "config")
    return dst


def run_snakemake(cwd, *args, timeout=1200, env=None, pythonpath=()):
    """Run Snakemake in ``cwd`` with this interpreter; ``env`` adds variables, and
    ``pythonpath`` folders go first on PYTHONPATH. The completed process (output captured)."""
    e = dict(os.environ, NUMBA_THREADING_LAYER="omp", **(env or {}))
    if pythonpath:
        e["PYTHONPATH"] = os.pathsep.join([*map(str, pythonpath),
                                           *filter(None, [e.get("PYTHONPATH")])])
    return subprocess.run([sys.executable, "-m", "snakemake", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout, env=e)
