"""Study configuration: schema validation (with defaults) and the checks a schema cannot
express. Every error names the offending key; all errors are reported together, before
any job runs.
"""
from __future__ import annotations

import copy
from pathlib import Path

import yaml

from .. import params as P


class ConfigError(ValueError):
    """The study configuration is invalid; the message lists every problem by key."""


def _path(err) -> str:
    parts = []
    for p in err.absolute_path:
        parts.append(f"[{p}]" if isinstance(p, int) else (("." if parts else "") + str(p)))
    return "".join(parts) or "(top level)"


def _fill_defaults(validator_cls):
    """A validator that also writes schema defaults into the instance."""
    import jsonschema

    validate_props = validator_cls.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, schema):
        if isinstance(instance, dict):
            for prop, sub in properties.items():
                if "default" in sub and prop not in instance:
                    instance[prop] = copy.deepcopy(sub["default"])
        yield from validate_props(validator, properties, instance, schema)

    return jsonschema.validators.extend(validator_cls, {"properties": set_defaults})


def load_schema(path) -> dict:
    with open(path) as f:
        return yaml.safe_load(f)


def validate_config(config: dict, schema_path, base_dir=".") -> dict:
    """Validate ``config`` in place (defaults filled in) and return it.

    Raises :class:`ConfigError` listing every problem as ``key: message``.
    """
    import jsonschema

    schema = load_schema(schema_path)
    Validator = _fill_defaults(jsonschema.Draft7Validator)
    errors = sorted(Validator(schema).iter_errors(config), key=lambda e: list(e.absolute_path))
    msgs = []
    for e in errors:
        if e.validator == "additionalProperties":
            extra = sorted(set(e.instance) - set(e.schema.get("properties", {})))
            msgs.append(f"{_path(e)}: unknown key(s) {extra}; allowed: "
                        f"{sorted(e.schema.get('properties', {}))}")
        else:
            msgs.append(f"{_path(e)}: {e.message}")
    if not msgs:
        msgs.extend(_semantic_checks(config, Path(base_dir)))
    if msgs:
        raise ConfigError("invalid configuration:\n  " + "\n  ".join(msgs))
    return config


def _semantic_checks(cfg: dict, base: Path) -> list[str]:
    msgs = []
    for name, (lo, hi) in cfg["ranges"].items():
        if lo > hi:
            msgs.append(f"ranges.{name}: low {lo:g} exceeds high {hi:g}")
    sp = cfg["specimen"]
    rmax = P.RADIUS_RATIO * max(cfg["ranges"]["rmin_mm"])
    d = sp["scale"] * sp.get("diameter_mm", 50.0)
    h = sp["scale"] * sp.get("height_mm", 100.0)
    if d < 6 * rmax or h < 6 * rmax:
        msgs.append(f"specimen.scale: {sp['scale']:g} gives a {d:g} x {h:g} mm specimen, less "
                    f"than 3 ball diameters across for Rmax = {rmax:g} mm "
                    f"(ranges.rmin_mm up to {max(cfg['ranges']['rmin_mm']):g} mm)")
    lab = base / cfg["lab"]["csv"]
    if not lab.exists():
        msgs.append(f"lab.csv: file {cfg['lab']['csv']!r} not found (relative to {base})")
    else:
        msgs.extend(_check_lab(lab, cfg["lab"]["csv"]))
    return msgs


LAB_COLUMNS = ("specimen", "ucs_MPa", "E_GPa", "nu")


def _check_lab(path: Path, key: str) -> list[str]:
    import pandas as pd

    try:
        df = pd.read_csv(path)
    except Exception as e:  # noqa: BLE001 - any parse error is reported by key
        return [f"lab.csv: cannot read {key!r}: {e}"]
    missing = [c for c in LAB_COLUMNS if c not in df.columns]
    if missing:
        return [f"lab.csv: {key!r} lacks column(s) {missing}; expected {list(LAB_COLUMNS)} "
                "(+ optional u_pre_MJm3)"]
    msgs = []
    if df["specimen"].duplicated().any():
        msgs.append(f"lab.csv: {key!r} has duplicate specimen names")
    for c in ("ucs_MPa", "E_GPa", "nu"):
        v = pd.to_numeric(df[c], errors="coerce")
        if v.isna().any() or (v <= 0).any():
            msgs.append(f"lab.csv: {key!r} column {c} must hold positive numbers")
    nu = pd.to_numeric(df["nu"], errors="coerce")
    if (nu >= 0.5).any():
        msgs.append(f"lab.csv: {key!r} column nu must be below 0.5")
    return msgs


def read_lab(path):
    """The lab specimens table (validated columns)."""
    import pandas as pd

    return pd.read_csv(path)
