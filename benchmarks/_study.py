"""What the cost benchmarks (``bts_study_cost.py``, ``host_independence_cost.py``) read of
the study they measure: its config's design samples, as the workflow draws them (rule
design: ``bpmcal design``), its UCS settings, and the host's CPU model.

bpmcal is imported inside the functions, so a script using them still runs with any
bpmcal version on ``PYTHONPATH``.
"""
from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config" / "config.yaml"


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def study_design(cfg: dict):
    """The study's design (a DataFrame with sample_id, the 8 parameters and seed) from a
    config's ``ranges`` and ``study`` sections; ``lhs_optimization: none`` is no
    optimisation, as ``bpmcal design --optimization none``."""
    from bpmcal.study.design import lhs_design

    st = cfg["study"]
    return lhs_design(cfg["ranges"], st["n_samples"], st["lhs_seed"],
                      optimization=None if st["lhs_optimization"] == "none"
                      else st["lhs_optimization"])


def ucs_settings(cfg: dict):
    """The UCS test settings of a config's ``ucs`` section."""
    from bpmcal.lab.ucs import UCSSettings

    u = cfg["ucs"]
    return UCSSettings(platen_velocity=u["platen_velocity"], damping=u["damping"],
                       stop_drop=u["stop_drop"], max_strain=u["max_strain"],
                       platen_fric=u["platen_fric"], record_strain=u["record_strain"])
