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
        lab_msgs = _check_lab(lab, cfg["lab"]["csv"])
        msgs.extend(lab_msgs)
        if not lab_msgs:
            msgs.extend(_check_reference(cfg, lab))
    if not msgs:
        msgs.extend(_check_calibration_space(cfg))
    return msgs


def _check_calibration_space(cfg: dict) -> list[str]:
    """The calibration works inside the design space: fixed values inside their ranges,
    ``calibration.bounds`` only narrowing the ranges of calibrated parameters, and (with a
    strength ratio) some cohesion whose derived tensile strength lies in its range."""
    msgs = []
    rng, cal = cfg["ranges"], cfg["calibration"]
    ratio = cal.get("ratio")
    free = list(cal.get("free", []))
    derived = ["pb_ten_MPa"] if ratio and "pb_ten_MPa" not in free else []
    for name, v in cal["fixed"].items():
        lo, hi = rng[name]
        if not lo <= v <= hi:
            msgs.append(f"calibration.fixed.{name}: {v:g} is outside ranges.{name} [{lo:g}, {hi:g}], "
                        "the sampled space (the regression is not valid there): fix a value inside "
                        f"it, or widen ranges.{name}")
    box = {k: tuple(rng[k]) for k in rng}
    for name, (lo, hi) in (cal.get("bounds") or {}).items():
        rlo, rhi = rng[name]
        if not lo < hi:
            msgs.append(f"calibration.bounds.{name}: low {lo:g} must be below high {hi:g}")
        elif name not in free + derived:
            msgs.append(f"calibration.bounds.{name}: {name} is not calibrated (calibration.free: "
                        f"{free}" + (", derived: pb_ten_MPa" if derived else "")
                        + "); bounds apply to calibrated parameters only")
        elif lo < rlo or hi > rhi:
            msgs.append(f"calibration.bounds.{name}: [{lo:g}, {hi:g}] reaches beyond ranges.{name} "
                        f"[{rlo:g}, {rhi:g}], the sampled space (the regression is not valid "
                        f"outside it): narrow the bounds, or widen ranges.{name}")
        else:
            box[name] = (lo, hi)
    if not msgs and derived and "pb_coh_MPa" in free:
        (clo, chi), (tlo, thi) = box["pb_coh_MPa"], box["pb_ten_MPa"]
        if not max(clo, tlo / ratio) < min(chi, thi / ratio):
            msgs.append(f"calibration.ratio: {ratio:g} x pb_coh_MPa in [{clo:g}, {chi:g}] never falls "
                        f"inside pb_ten_MPa [{tlo:g}, {thi:g}]: widen ranges.pb_ten_MPa or "
                        "ranges.pb_coh_MPa, or change the ratio")
    return msgs


def _check_reference(cfg: dict, lab: Path) -> list[str]:
    """``study.reference: yu2026`` puts the paper's published values beside the results;
    that only means something for the paper's specimens B1-B3."""
    if cfg["study"].get("reference") != "yu2026":
        return []
    from ..report.paper import LAB

    df = read_lab(lab)
    bad = []
    for rec in df.to_dict("records"):
        pub = LAB.get(str(rec["specimen"]))
        if pub is None or any(abs(float(rec[k]) - pub[k]) > 1e-9 * abs(pub[k])
                              for k in ("ucs_MPa", "E_GPa", "nu")):
            bad.append(str(rec["specimen"]))
    if bad:
        return [f"study.reference: yu2026 compares the results with the paper's green sandstone "
                f"specimens {sorted(LAB)}, but lab.csv {cfg['lab']['csv']!r} holds other data "
                f"(specimen(s) {bad}); set study.reference: none for another rock"]
    return []


LAB_COLUMNS = ("specimen", "ucs_MPa", "E_GPa", "nu")


def _check_lab(path: Path, key: str) -> list[str]:
    import pandas as pd

    try:
        df = read_lab(path)
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
    """The lab specimens table. Lines whose first non-blank character is ``#`` are comments
    (the data's source, units, notes) and are skipped; everything else is plain CSV."""
    import io

    import pandas as pd

    text = Path(path).read_text()
    body = "".join(ln for ln in text.splitlines(keepends=True) if not ln.lstrip().startswith("#"))
    return pd.read_csv(io.StringIO(body))
