"""Provenance stamped on every output: package version, git commit and a hash of the
inputs (:func:`provenance`); run files also get the time, host and Slurm job
(``stamp=True``). Material cards, models and selections carry the unstamped form, so the
same inputs give the same file."""
from __future__ import annotations

import datetime as _dt
import functools
import hashlib
import json
import os
import socket
import subprocess
from pathlib import Path

from .. import __version__


@functools.lru_cache(maxsize=1)
def git_commit() -> str:
    """Commit of the source tree the package runs from ("unknown" outside a checkout);
    a "+dirty" suffix marks uncommitted changes."""
    here = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True,
                             text=True, timeout=5)
        if sha.returncode != 0:
            return "unknown"
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=here, capture_output=True, text=True, timeout=5)
        return sha.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def config_hash(d: dict) -> str:
    """Stable short hash of a JSON-able dict (sorted keys)."""
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]


def provenance(inputs: dict, *, stamp: bool = False) -> dict:
    """``bpmcal_version``, ``git_commit`` and ``inputs_hash`` (:func:`config_hash` of
    ``inputs``); with ``stamp`` also ``created_utc``, ``hostname`` and ``slurm_job_id``."""
    d = {"bpmcal_version": __version__, "git_commit": git_commit(),
         "inputs_hash": config_hash(inputs)}
    if stamp:
        d.update({"created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                  "hostname": socket.gethostname(),
                  "slurm_job_id": os.environ.get("SLURM_JOB_ID", "")})
    return d
