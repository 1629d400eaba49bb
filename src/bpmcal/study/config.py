"""Study configuration: schema validation (with defaults) and the checks a schema cannot
express. Every error names the offending key; all errors are reported together, before
any job runs.
"""
from __future__ import annotations

import copy
import math
import sys
from pathlib import Path

import yaml

from .. import params as P
from ..io.safe_names import clip, outdir_problem, path_problem
from ..io.study_files import MAX_SWEEP_RATIOS, ratio_count, ratio_grid
from ..lab.budget import budget_problem
from .config_doc import schema_reference
from .errors import ConfigError
from .lab_data import LAB_COLUMNS as LAB_COLUMNS  # re-exported: the lab table's home is lab_data
from .lab_data import LAB_OPTIONAL as LAB_OPTIONAL
from .lab_data import lab_problems, lab_triaxial_problems, read_lab
from .lab_data import load_lab as load_lab
from .paper import LAB as PAPER_LAB


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
    """The config schema, with every contact model's parameters (the registry,
    :data:`bpmcal.params.MODELS`) in ``ranges``, ``calibration.fixed``, ``calibration.free``
    and ``calibration.bounds``: the YAML writes out the parallel bond's, the flat joint's
    are generated from their declarations so they cannot drift."""
    with open(path) as f:
        schema = yaml.safe_load(f)
    return with_model_parameters(schema)


def _number_schema(p: P.Param) -> dict:
    """A parameter's physical domain as JSON-schema limits."""
    out: dict = {"type": "number"}
    if math.isfinite(p.phys_lo):
        out["exclusiveMinimum" if p.lo_open else "minimum"] = p.phys_lo
    if math.isfinite(p.phys_hi):
        out["exclusiveMaximum" if p.hi_open else "maximum"] = p.phys_hi
    return out


def with_model_parameters(schema: dict) -> dict:
    """``schema`` with every registered model's parameters added where the YAML does not
    write them (see :func:`load_schema`)."""
    props = schema.get("properties", {})
    if "ranges" not in props or "calibration" not in props:
        return schema
    ranges = props["ranges"]["properties"]
    cal = props["calibration"]["properties"]
    for name, p in P.ALL_PARAMS.items():
        unit = f" [{p.unit or '-'}]"
        if name not in ranges:
            ranges[name] = {"type": "array", "minItems": 2, "maxItems": 2,
                            "description": p.description + unit, "items": _number_schema(p)}
        cal["fixed"]["properties"].setdefault(name, _number_schema(p))
        cal["bounds"]["properties"].setdefault(
            name, {"type": "array", "minItems": 2, "maxItems": 2, "items": {"type": "number"}})
        enum = cal["free"]["items"]["enum"]
        if name not in enum:
            enum.append(name)
    return schema


def _stderr_line(line: str) -> None:
    print(line, file=sys.stderr)


def validate_config(config: dict, schema_path, base_dir=".", note=_stderr_line,
                    read_files: bool = True) -> dict:
    """Validate ``config`` in place (unset keys dropped and the contact model's
    parameters applied, with one line each to ``note``; defaults filled in) and return
    it. ``read_files``: also read and check the lab CSVs it names (relative to
    ``base_dir``).

    Raises :class:`ConfigError` listing every problem as ``key: message``.
    """
    import jsonschema

    _drop_unset(config, note)
    _apply_contact_model(config, note)
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
            msgs.append(f"{_path(e)}: {clip(e.message, 300)}")
    if not msgs:
        msgs.extend(_semantic_checks(config, Path(base_dir), read_files))
    if msgs:
        raise ConfigError("invalid configuration:\n  " + "\n  ".join(msgs))
    _density_scaling_note(config, note)
    return config


#: where density scaling's paired effect on the design samples is measured
DENSITY_SCALING_RECORD = "docs/measurements/2026-12-02j-density-scaling.md"


def _density_scaling_note(config: dict, note) -> None:
    """One line to ``note`` when a flat-jointed study scales its balls' densities
    (``compression``, ``bts`` or ``dtt`` ``density_scaling`` set): it was validated on
    parallel-bond cards, and moves a flat-jointed card's responses sample by sample."""
    if config.get("contact_model") != "flatjoint":
        return
    on = [f"{s}.density_scaling" for s in ("compression", "bts", "dtt")
          if (config.get(s) or {}).get("density_scaling") is not None]
    if on:
        note(f"config: contact_model flatjoint with {', '.join(on)} set: density scaling "
             "is validated on parallel-bond cards; on flat-jointed ones it moves σc, E and ν "
             f"by several per cent from sample to sample ({DENSITY_SCALING_RECORD}); set it "
             "null for the true masses")


#: the schema's place in a source checkout (the package is installed from one)
_SCHEMA = Path("workflow") / "schemas" / "config.schema.yaml"


def find_schema() -> Path | None:
    """The config schema of the checkout bpmcal runs from, or of the working folder (a
    study's), or None when neither has one."""
    for root in (Path(__file__).resolve().parents[3], Path.cwd()):
        if (root / _SCHEMA).is_file():
            return root / _SCHEMA
    return None


def check_study_config(cfg: dict, flag: str) -> dict:
    """A whole study config for a command that reads one (``bpmcal report``): validated
    against the schema when it can be found (:func:`find_schema`; defaults filled in),
    else at least every section present. A BadInput-like :class:`ConfigError` names what
    is missing: an overlay alone (config/smoke.yaml) is not a study config."""
    schema = find_schema()
    required = ("outdir", "study", "ranges", "specimen", "compression", "lab", "resources",
                "screening", "regression", "calibration", "verification", "ratio_sweep",
                "impact")
    missing = [k for k in required if k not in cfg]
    if missing:
        raise ConfigError(f"{flag}: not a whole study config (no {', '.join(missing)}): an "
                          "overlay alone? Give the config as the workflow merges it "
                          "(config/config.yaml with the overlay over it; the workflow passes "
                          "it with --config-json)")
    if schema is not None:  # (the lab files are not the report's inputs: not read)
        try:
            validate_config(cfg, schema, note=lambda line: None, read_files=False)
        except ConfigError as e:
            raise ConfigError(f"{flag}: {' '.join(str(e).split())}") from None
    return cfg


def _param_maps(config: dict, keys):
    """``(key, mapping)`` for each dotted ``key`` of ``config`` that holds a mapping (of
    parameter names: ``ranges``, ``calibration.fixed``, ...); absent or other keys are
    left to the schema."""
    for key in keys:
        node = config
        for k in key.split("."):
            node = node.get(k) if isinstance(node, dict) else None
        if isinstance(node, dict):
            yield key, node


#: the mappings of parameter names in which an overlay may unset an inherited entry (null)
UNSETTABLE = ("calibration.fixed", "calibration.bounds")


def _drop_unset(config: dict, note=_stderr_line) -> None:
    """``null`` for a parameter in :data:`UNSETTABLE` removes the entry: the way an overlay
    frees a parameter the base config holds fixed (a config merged over another cannot
    delete its keys; e.g. ``calibration.fixed.fj_fa_deg: null`` beside ``fj_fa_deg`` in
    ``calibration.free``). One line to ``note`` names what was removed."""
    dropped = []
    for key, node in _param_maps(config, UNSETTABLE):
        for k in [k for k, v in node.items() if v is None]:
            del node[k]
            dropped.append(f"{key}.{k}")
    if dropped:
        note(f"config: {', '.join(dropped)} unset (null: the base config's value removed)")


def _apply_contact_model(config: dict, note=_stderr_line) -> None:
    """What depends on the contact model before the schema sees the config: the default
    ``calibration.free`` (the model's modulus, stiffness ratio and cohesion), and, for a
    model other than the parallel bond, the parallel bond's parameters that an overlay
    inherits from config/config.yaml (an overlay cannot delete keys) dropped from
    ``ranges``, ``calibration.fixed`` and ``calibration.bounds``, and a ``calibration.free``
    that is the parallel bond's default replaced by the model's, with one line to
    ``note``. An unknown model is left to the schema; another model's names in a
    parallel-bond config are an error (:func:`_model_problems`)."""
    name = config.get("contact_model", P.DEFAULT_CONTACT_MODEL)
    if name not in P.MODELS:
        return
    model = P.MODELS[name]
    cal = config.get("calibration")
    if name != P.DEFAULT_CONTACT_MODEL:
        base = P.MODELS[P.DEFAULT_CONTACT_MODEL].params
        dropped = []
        for key, node in _param_maps(config, ("ranges", *UNSETTABLE)):
            for k in [k for k in node if k in base and k not in model.params]:
                del node[k]
                dropped.append(f"{key}.{k}")
        if isinstance(cal, dict) and cal.get("free") == list(P.MODELS[P.DEFAULT_CONTACT_MODEL].free):
            del cal["free"]  # config.yaml's parallel-bond default: the model's default instead
            dropped.append("calibration.free")
        if dropped:
            note(f"config: contact_model {name}: {len(dropped)} parallel-bond key(s) of the base "
                 f"config left out ({', '.join(dropped)})")
    if isinstance(cal, dict) and "free" not in cal:
        cal["free"] = list(model.free)


def _model_problems(cfg: dict) -> list[str]:
    """Every parameter name of ``ranges`` and ``calibration`` belongs to the config's
    contact model, and every parameter of the model has a range (its optional keys
    excepted)."""
    model = P.MODELS[cfg["contact_model"]]
    cal = cfg["calibration"]
    other = {k: m for m in P.MODELS.values() for k in m.params if k not in model.params}
    msgs = []
    used = [("ranges", list(cfg["ranges"])), ("calibration.fixed", list(cal["fixed"])),
            ("calibration.free", list(cal.get("free") or [])),
            ("calibration.bounds", list(cal.get("bounds") or {}))]
    for key, names in used:
        bad = [k for k in names if k in other]
        if bad:
            msgs.append(f"{key}: {bad} are {other[bad[0]].name} parameters, but contact_model is "
                        f"{model.name} (its parameters: {list(model.params)}); set "
                        f"contact_model: {other[bad[0]].name} to use them")
    if not msgs:
        missing = [k for k in model.params if k not in cfg["ranges"]
                   and k not in (model.defaults or {})]
        if missing:
            msgs.append(f"ranges: no range for {missing} (contact_model {model.name}); give "
                        "[low, high], or [v, v] to hold one at v")
    return msgs


def _finite_problems(v, key="") -> list[str]:
    """NaN and inf anywhere in the config (YAML ``.nan``/``.inf``), by key."""
    if isinstance(v, dict):
        return [m for k, x in v.items() for m in _finite_problems(x, f"{key}.{k}" if key else k)]
    if isinstance(v, list):
        return [m for i, x in enumerate(v) for m in _finite_problems(x, f"{key}[{i}]")]
    if isinstance(v, float) and not math.isfinite(v):
        return [f"{key}: {v!r} is not a finite number"]
    return []


def _semantic_checks(cfg: dict, base: Path, read_files: bool = True) -> list[str]:
    msgs = _finite_problems(cfg) or _model_problems(cfg)
    if msgs:
        return msgs  # the checks below compare numbers of the model's parameters
    for key in ("outdir",):
        m = path_problem(cfg[key]) or outdir_problem(cfg[key])
        if m:
            msgs.append(f"{key}: {m}")
    m = path_problem(cfg["lab"]["csv"])
    if m:
        msgs.append(f"lab.csv: {m}")
    for name, (lo, hi) in cfg["ranges"].items():
        if lo > hi:
            msgs.append(f"ranges.{name}: low {lo:g} exceeds high {hi:g}")
    sp = cfg["specimen"]
    rmax = P.RADIUS_RATIO * max(cfg["ranges"][P.RMIN])
    d = sp["scale"] * sp.get("diameter_mm", 50.0)
    h = sp["scale"] * sp.get("height_mm", 100.0)
    if d < 6 * rmax or h < 6 * rmax:
        msgs.append(f"specimen.scale: {sp['scale']:g} gives a {d:g} x {h:g} mm specimen, less "
                    f"than 3 ball diameters across for Rmax = {rmax:g} mm "
                    f"(ranges.{P.RMIN} up to {max(cfg['ranges'][P.RMIN]):g} mm)")
    b = cfg.get("bts", {})
    if b.get("enabled"):  # the Brazilian disc of every sample must fit its balls too
        sc, which = disc_scale(cfg)
        bd, bt = sc * b["diameter_mm"], sc * b["thickness_mm"]
        if bd < 6 * rmax or bt < 6 * rmax:
            msgs.append(f"bts: {which} {sc:g} gives a {bd:g} x {bt:g} mm disc, "
                        f"less than 3 ball diameters across for Rmax = {rmax:g} mm "
                        f"(ranges.{P.RMIN} up to {max(cfg['ranges'][P.RMIN]):g} mm); "
                        "raise bts.scale (or bts.diameter_mm and bts.thickness_mm) or set "
                        "bts.enabled: false")
    msgs.extend(_budget_checks(cfg))
    msgs.extend(_design_checks(cfg))
    if not msgs:
        msgs.extend(_loading_checks(cfg))
    msgs.extend(_sweep_checks(cfg))
    msgs.extend(_fresh_seed_checks(cfg))
    if read_files:
        msgs.extend(_lab_file_checks(cfg, base))
    if not msgs:
        msgs.extend(_check_calibration_space(cfg))
    return msgs


def _lab_file_checks(cfg: dict, base: Path) -> list[str]:
    """The checks of the lab CSVs the config names (:func:`_semantic_checks`)."""
    msgs = _check_bts_disc(cfg, base) + _check_tensile_tests(cfg, base)
    if not path_problem(cfg["lab"]["csv"]):
        lab = base / cfg["lab"]["csv"]
        if not lab.is_file():
            msgs.append(f"lab.csv: file {cfg['lab']['csv']!r} not found (relative to {base})")
        else:
            lab_msgs = _check_lab(lab, cfg["lab"]["csv"])
            msgs.extend(lab_msgs)
            if not lab_msgs:
                msgs.extend(_check_reference(cfg, lab))
                msgs.extend(_check_lab_triaxial(cfg, lab, base))
    return msgs


def _check_lab_triaxial(cfg: dict, lab: Path, base: Path) -> list[str]:
    """``triaxial.lab_csv``: a safe path to a lab triaxial CSV whose specimens are those of
    ``lab.csv`` (``bpmcal.study.lab_data``)."""
    key = (cfg.get("triaxial") or {}).get("lab_csv")
    if key is None:
        return []
    m = path_problem(key)
    if m:
        return [f"triaxial.lab_csv: {m}"]
    if not (base / key).is_file():
        return [f"triaxial.lab_csv: file {key!r} not found (relative to {base})"]
    try:
        df = read_lab(base / key)
    except ConfigError as e:
        return [str(e).replace("lab.csv:", "triaxial.lab_csv:", 1)]
    return lab_triaxial_problems(df, key, list(read_lab(lab)["specimen"]))


def _budget_checks(cfg: dict) -> list[str]:
    """The largest specimen the study can build (smallest Rmin and porosity of the ranges
    and of the fixed calibration values, at the UCS, the impact and the disc's scale) must fit
    ``resources.max_balls`` and ``resources.dem_mem_mb``."""
    res = cfg["resources"]
    rg, fx = cfg["ranges"], cfg["calibration"]["fixed"]
    rmin = min([min(rg[P.RMIN])] + ([fx[P.RMIN]] if P.RMIN in fx else []))
    por = min([min(rg[P.POROSITY])] + ([fx[P.POROSITY]] if P.POROSITY in fx else []))
    sp = cfg["specimen"]
    out = []
    shapes = [("specimen.scale", sp["scale"], sp["diameter_mm"], sp["height_mm"]),
              ("impact.scale", cfg["impact"]["scale"], sp["diameter_mm"], sp["height_mm"])]
    b = cfg.get("bts") or {}
    if b.get("enabled") and b.get("scale") is not None:  # a disc sized on its own
        shapes.append(("bts.scale", b["scale"], b["diameter_mm"], b["thickness_mm"]))
    for what, scale, dia, height in shapes:
        m = budget_problem(rmin, por, scale=scale, diameter_mm=dia,
                           height_mm=height, max_balls=res["max_balls"],
                           mem_budget_mb=res["dem_mem_mb"],
                           what=f"{what}={scale:g} with the smallest ")
        if m:
            out.append(f"resources: {m}")
    return out


def _design_checks(cfg: dict) -> list[str]:
    """``study.n_samples`` within what its ``lhs_optimization`` takes in seconds
    (``study.design.design_size_problem``)."""
    from .design import design_size_problem

    st = cfg["study"]
    m = design_size_problem(st["n_samples"], st.get("lhs_optimization"))
    return [f"study.n_samples: {m}"] if m else []


def _loading_checks(cfg: dict) -> list[str]:
    """Every lab test of the study's samples (the compression of the cylinders, and the
    Brazilian and direct-tension tests when on) must be able to reach the failure of some
    card of the design space (``lab.reach.hopeless_everywhere``): a loading that none can
    complete (``max_strain`` far too small, a hopeless step budget) is refused here,
    before the first job, not after every sample failed."""
    from dataclasses import fields, replace

    from ..dem.errors import InputError
    from ..lab.brazilian import BTSSettings
    from ..lab.direct_tension import DTTSettings
    from ..lab.reach import hopeless_everywhere
    from ..lab.runner import Geometry, bts_geometry
    from ..lab.ucs import UCSSettings

    def of(cls, section):
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in section.items() if k in names})

    sp = cfg["specimen"]
    model = P.MODELS[cfg["contact_model"]]
    cyl = {k: sp[k] for k in ("diameter_mm", "height_mm") if k in sp}
    try:
        tests = [("compression", "ucs", Geometry(scale=sp["scale"], **cyl),
                  of(UCSSettings, cfg["compression"]))]
        b, d = cfg.get("bts") or {}, cfg.get("dtt") or {}
        if b.get("enabled"):
            tests.append(("bts", "bts", bts_geometry(disc_scale(cfg)[0], b["diameter_mm"],
                                                     b["thickness_mm"]), of(BTSSettings, b)))
        if d.get("enabled"):
            scale = sp["scale"] if d.get("scale") is None else d["scale"]
            tests.append(("dtt", "dtt", Geometry(scale=scale, **cyl), of(DTTSettings, d)))
    except (InputError, KeyError, TypeError):
        return []  # a combination the settings refuse: their own checks say why
    out = []
    for key, test, geometry, settings in tests:
        m = hopeless_everywhere(test, cfg["ranges"], model, geometry,
                                replace(settings))
        if m:
            where = f"{key}.max_strain" if "max_strain =" in m else key
            out.append(f"{where}: no card of the design space (ranges) can complete this "
                       f"loading: {m}")
    return out


#: the largest packing or analysis seed (numpy's 32-bit seeds; ``bpmcal --seed``'s bound)
MAX_SEED = 2 ** 32 - 1


def loop_seeds(verification: dict) -> list[int]:
    """Every packing seed a closed loop of ``verification`` (the config section) may use:
    ``seed`` ... ``seed + max_seeds - 1`` (the first ``seeds_per_round`` of them, grown)."""
    v = verification
    n = max(v["seeds_per_round"], v.get("max_seeds") or v["seeds_per_round"])
    return list(range(v["seed"], v["seed"] + n))


def loop_rounds_bound(cfg: dict, tensile: bool) -> int:
    """The most rounds a study's closed loop may take (a cluster job's time limit):
    ``verification.max_rounds``, or for ``auto`` two per free parameter
    (:func:`bpmcal.params.auto_rounds`), counting the
    tensile strength a σt target frees (``tensile``) when the config does not fix or
    free it already."""
    m = cfg["verification"]["max_rounds"]
    if m != P.AUTO_ROUNDS:
        return int(m)
    model = P.MODELS[cfg.get("contact_model", P.DEFAULT_CONTACT_MODEL)]
    c = cfg["calibration"]
    free = c.get("free") or None
    if tensile:
        free = model.tensile_free(free, c.get("fixed") or {})
    return P.auto_rounds(len(free or model.free))


def transfer_seed(verification: dict) -> int:
    """The packing seed of the full-size transfer: the first no closed loop used."""
    return loop_seeds(verification)[-1] + 1


def _fresh_seed_checks(cfg: dict) -> list[str]:
    """``verification.fresh_seeds``: none or at least two, all fresh (no seed of the
    closed loop or of the transfer)."""
    v = cfg["verification"]
    last = transfer_seed(v)
    if last > MAX_SEED:  # the packing seeds the loops and the transfer derive from seed
        return [f"verification.seed: {v['seed']} + {last - v['seed']} seeds (the closed "
                f"loop's max_seeds and the transfer's) reach {last}, beyond the largest "
                f"packing seed {MAX_SEED}; expected a smaller seed"]
    seeds = list(v.get("fresh_seeds") or [])
    if not seeds:
        return []
    if len(seeds) < 2:
        return [f"verification.fresh_seeds: {seeds} has one seed; expected [] (no check) or "
                "at least 2 (a standard error needs two)"]
    used = set(loop_seeds(v))
    if (cfg.get("transfer") or {}).get("enabled"):
        used.add(transfer_seed(v))
    seen = sorted(used & set(seeds))
    if seen:
        return [f"verification.fresh_seeds: {seen} also seed(s) the closed loop or the "
                f"transfer (seeds {sorted(used)}); expected fresh packing seeds"]
    return []


def _sweep_checks(cfg: dict) -> list[str]:
    rs = cfg["ratio_sweep"]
    start, stop, step = rs["ratios"]
    if not (start <= stop):
        return [f"ratio_sweep.ratios: start {start:g} exceeds stop {stop:g} (expected "
                "[start, stop, step] with start <= stop)"]
    n = ratio_count(start, stop, step)
    if n > MAX_SWEEP_RATIOS:
        return [f"ratio_sweep.ratios: {rs['ratios']} gives {n:.4g} ratios, more than "
                f"{MAX_SWEEP_RATIOS} (one DEM run each); use a larger step"]
    try:
        ratio_grid(start, stop, step)
    except P.ParameterError as e:
        return [f"ratio_sweep.ratios: {e}"]
    return []


def _check_calibration_space(cfg: dict) -> list[str]:
    """The calibration works inside the design space: fixed values inside their ranges,
    ``calibration.bounds`` only narrowing the ranges of calibrated parameters, and (with a
    strength ratio) some cohesion whose derived tensile strength lies in its range."""
    msgs = []
    rng, cal = cfg["ranges"], cfg["calibration"]
    ratio = cal.get("strength_ratio")
    free = list(cal.get("free", []))
    model = P.MODELS[cfg["contact_model"]]
    ten, coh = model.strength
    derived = [ten] if ratio and ten not in free else []
    for name in [f for f in free if f in cal["fixed"]]:
        msgs.append(f"calibration.free and calibration.fixed both name {name}: a parameter is "
                    f"either free or fixed (an overlay frees one its base config fixes with "
                    f"calibration.fixed.{name}: null)")
    for name, v in cal["fixed"].items():
        if name not in rng:  # an optional key of the model: designed at its default
            d = (model.defaults or {})[name]
            rng = {**rng, name: (d, d)}
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
                        f"{free}" + (f", derived: {ten}" if derived else "")
                        + "); bounds apply to calibrated parameters only")
        elif lo < rlo or hi > rhi:
            msgs.append(f"calibration.bounds.{name}: [{lo:g}, {hi:g}] reaches beyond ranges.{name} "
                        f"[{rlo:g}, {rhi:g}], the sampled space (the regression is not valid "
                        f"outside it): narrow the bounds, or widen ranges.{name}")
        else:
            box[name] = (lo, hi)
    if not msgs and derived and coh in free:
        (clo, chi), (tlo, thi) = box[coh], box[ten]
        if not max(clo, tlo / ratio) < min(chi, thi / ratio):
            msgs.append(f"calibration.strength_ratio: {ratio:g} x {coh} in [{clo:g}, {chi:g}] "
                        f"never falls inside {ten} [{tlo:g}, {thi:g}]: widen ranges.{ten} or "
                        f"ranges.{coh}, or change the ratio")
    return msgs


def _check_reference(cfg: dict, lab: Path) -> list[str]:
    """``study.reference: yu2026`` puts the paper's published values beside the results;
    that only means something for the paper's specimens B1-B3."""
    if cfg["study"].get("reference") != "yu2026":
        return []
    df = read_lab(lab)
    bad = []
    for rec in df.to_dict("records"):
        pub = PAPER_LAB.get(str(rec["specimen"]))
        if pub is None or any(abs(float(rec[k]) - pub[k]) > 1e-9 * abs(pub[k])
                              for k in ("ucs_MPa", "E_GPa", "nu")):
            bad.append(str(rec["specimen"]))
    if bad:
        return [f"study.reference: yu2026 compares the results with the paper's green sandstone "
                f"specimens {sorted(PAPER_LAB)}, but lab.csv {cfg['lab']['csv']!r} holds other data "
                f"(specimen(s) {bad}); set study.reference: none for another rock"]
    return []


def disc_scale(cfg: dict) -> tuple[float, str]:
    """The Brazilian disc's scale factor and the key it comes from: ``bts.scale``, or
    ``specimen.scale`` when that is null (the disc at the cylinder's scale)."""
    b = cfg.get("bts") or {}
    if b.get("scale") is not None:
        return float(b["scale"]), "bts.scale"
    return float(cfg["specimen"]["scale"]), "specimen.scale"


def _check_bts_disc(cfg: dict, base: Path) -> list[str]:
    """A lab tensile strength (``bts_MPa``) is verified with the study's Brazilian disc
    (``bts.diameter_mm`` x ``bts.thickness_mm``, default ISRM 50 x 25 mm) at its scale
    (:func:`disc_scale`; ``stages.verification.verify``): it must hold 3 of the largest balls
    across its thickness, or the closed loop would stop after its first UCS run."""
    import pandas as pd

    lab = base / cfg["lab"]["csv"]
    if path_problem(cfg["lab"]["csv"]) or not lab.is_file():
        return []  # reported by the lab checks
    try:
        df = read_lab(lab)
    except ConfigError:
        return []  # reported by the lab checks
    if "bts_MPa" not in df.columns:
        return []
    given = [str(s) for s, v in zip(df["specimen"], pd.to_numeric(df["bts_MPa"], errors="coerce"))
             if math.isfinite(v)]
    if not given:
        return []
    from ..lab.runner import BTS_DIAMETER_MM, BTS_THICKNESS_MM

    disc = cfg.get("bts") or {}
    dia = float(disc.get("diameter_mm", BTS_DIAMETER_MM))
    thick = float(disc.get("thickness_mm", BTS_THICKNESS_MM))
    scale, which = disc_scale(cfg)
    fixed = (cfg.get("calibration") or {}).get("fixed") or {}
    if P.RMIN in fixed:  # the cards' Rmin (verify's check uses the card's)
        rmin, where = float(fixed[P.RMIN]), f"calibration.fixed.{P.RMIN} {fixed[P.RMIN]:g} mm"
    else:
        rmin = max(cfg["ranges"][P.RMIN])
        where = f"ranges.rmin_mm up to {rmin:g} mm"
    rmax = P.RADIUS_RATIO * rmin
    t = scale * thick
    if t >= 6 * rmax:
        return []
    return [f"lab.csv: specimen(s) {given} give bts_MPa, which the closed loop verifies with a "
            f"Brazilian disc (bts.diameter_mm {dia:g} x bts.thickness_mm {thick:g}) at "
            f"{which} {scale:g}: {scale * dia:g} x {t:g} mm, less than 3 ball diameters "
            f"across for Rmax = {rmax:g} mm ({where}): raise bts.scale to at least "
            f"{6 * rmax / thick:.3g}, or leave bts_MPa empty"]


def _check_tensile_tests(cfg: dict, base: Path) -> list[str]:
    """A lab tensile strength is calibrated against the regression's model of it: the
    study must run that test on every sample (``bts.enabled`` for ``bts_MPa``,
    ``dtt.enabled`` for ``dtt_MPa``)."""
    import pandas as pd

    lab = base / cfg["lab"]["csv"]
    if path_problem(cfg["lab"]["csv"]) or not lab.is_file():
        return []
    try:
        df = read_lab(lab)
    except ConfigError:
        return []
    out = []
    for col, sec, what in (("bts_MPa", "bts", "a Brazilian"),
                           ("dtt_MPa", "dtt", "a direct-tension")):
        if col not in df.columns or (cfg.get(sec) or {}).get("enabled"):
            continue
        given = [str(sp) for sp, v in zip(df["specimen"],
                                          pd.to_numeric(df[col], errors="coerce"))
                 if math.isfinite(v)]
        if given:
            out.append(f"lab.csv: specimen(s) {given} give {col}, a calibration target that "
                       f"needs {what} test of every sample: set {sec}.enabled: true, or "
                       f"leave {col} empty")
    out.extend(_check_triaxial_target(cfg, df))
    return out


def _check_triaxial_target(cfg: dict, df) -> list[str]:
    """A lab triaxial strength (``tri_MPa``) is sigma1 at failure at the study's design
    confinement: ``triaxial.design_sigma3_MPa`` must be set (every sample then runs that
    triaxial test) and the strength must exceed it."""
    import pandas as pd

    if "tri_MPa" not in df.columns:
        return []
    s3 = (cfg.get("triaxial") or {}).get("design_sigma3_MPa")
    vals = [(str(sp), v) for sp, v in zip(df["specimen"],
                                          pd.to_numeric(df["tri_MPa"], errors="coerce"))
            if math.isfinite(v)]
    if vals and s3 is None:
        return [f"lab.csv: specimen(s) {[sp for sp, _ in vals]} give tri_MPa (sigma1 at "
                "failure at the design confinement), a calibration target that needs a "
                "triaxial test of every sample: set triaxial.design_sigma3_MPa to the "
                "confining stress [MPa] of those lab values, or leave tri_MPa empty"]
    low = [f"{sp} ({v:g})" for sp, v in vals if s3 is not None and not v > s3]
    if low:
        return [f"lab.csv: tri_MPa of specimen(s) {low} is not above "
                f"triaxial.design_sigma3_MPa = {s3:g} MPa: expected sigma1 > sigma3 at "
                "failure"]
    return []


def _check_lab(path: Path, key: str) -> list[str]:
    try:
        df = read_lab(path)
    except ConfigError as e:
        return [str(e)]
    return lab_problems(df, key)


if __name__ == "__main__":  # python -m bpmcal.study.config SCHEMA: print the reference
    import sys

    print(schema_reference(load_schema(sys.argv[1])), end="")
