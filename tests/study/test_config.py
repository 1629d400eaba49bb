"""The shipped configs validate, and the overlays change what they say they change."""
import copy
from pathlib import Path

import pytest
import yaml

from bpmcal.study.config import ConfigError, validate_config

REPO = Path(__file__).resolve().parents[2]
SCHEMA = REPO / "workflow" / "schemas" / "config.schema.yaml"


def merged(*names):
    """Snakemake's --configfile semantics: later files update nested keys of earlier ones."""
    def update(a, b):
        for k, v in b.items():
            if isinstance(v, dict) and isinstance(a.get(k), dict):
                update(a[k], v)
            else:
                a[k] = copy.deepcopy(v)
    cfg = {}
    for n in names:
        update(cfg, yaml.safe_load((REPO / "config" / n).read_text()))
    return cfg


@pytest.mark.parametrize("overlay", [None, "smoke.yaml", "paper.yaml"])
def test_shipped_configs_validate(overlay):
    cfg = merged("config.yaml", *([overlay] if overlay else []))
    validate_config(cfg, SCHEMA, base_dir=REPO)
    assert cfg["study"]["n_samples"] >= 4


def test_paper_config_is_the_full_size_study():
    cfg = validate_config(merged("config.yaml", "paper.yaml"), SCHEMA, base_dir=REPO)
    assert cfg["specimen"]["scale"] == 1.0 and cfg["impact"]["scale"] == 1.0
    assert cfg["study"]["n_samples"] == 150
    assert cfg["outdir"] != "results"  # never overwrites the default study


def test_a_typo_in_an_overlay_is_named():
    cfg = merged("config.yaml")
    cfg["impact"]["velocty"] = 6.0
    with pytest.raises(ConfigError, match="velocty"):
        validate_config(cfg, SCHEMA, base_dir=REPO)
