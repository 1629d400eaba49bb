"""One source for every config section that is a settings object: each key of the section
is a field of its settings class (its name, less a unit suffix, or a stated conversion),
the option the workflow passes it to is the key's name, and key, option and field agree
in default and bounds; every field that is no key is named here with why. (The closed
loop's section, ``verification`` and ``LoopSettings``: test_defaults.py, which also holds
the map of every key's default to its source used here.)"""
import dataclasses
import math

import pytest
from test_defaults import DEFAULTS, SCHEMA, STUDY_ONLY, _limits, cli_default, cli_type, same

from bpmcal.analysis.posterior import PosteriorSettings
from bpmcal.lab.brazilian import BTSSettings
from bpmcal.lab.direct_tension import DTTSettings
from bpmcal.lab.impact import ImpactSettings
from bpmcal.lab.run_context import RunContext
from bpmcal.lab.runner import Geometry
from bpmcal.lab.triaxial import TriaxialSettings
from bpmcal.lab.ucs import UCSSettings
from bpmcal.stages.posterior import RefineSettings

#: config section -> its settings class
SECTIONS = {
    "specimen": Geometry, "compression": UCSSettings, "bts": BTSSettings, "dtt": DTTSettings,
    "triaxial": TriaxialSettings, "impact": ImpactSettings, "posterior": PosteriorSettings,
    "posterior.refine": RefineSettings, "resources": RunContext,
}

#: a key whose field has another name, (field, the field's value per unit of the key's)
CONVERTED = {
    "impact.hammer_mass_kg": ("hammer_mass", 1.0),
    "impact.duration_ms": ("duration", 1e-3),  # the settings in SI units: s
    "impact.record_us": ("record_dt", 1e-6),
}

#: keys of these sections that are no field of the section's class, and why
NOT_FIELDS = {
    # the disc's size (bts_geometry's, the CLI's --diameter/--thickness): a geometry,
    # not a loading setting; its scale a Geometry field (null: the cylinder's)
    "bts.diameter_mm", "bts.thickness_mm", "bts.scale", "dtt.scale",
    "impact.scale",  # the impact specimen's Geometry.scale
    # the triaxial jobs' confinements, seed and cards, and the design test's (the UCS
    # cylinder and loading at design_sigma3_MPa, stopped at design_stop_drop: the CLI's)
    "triaxial.sigma3_MPa", "triaxial.seed", "triaxial.design_sigma3_MPa",
    "triaxial.design_stop_drop",
    "impact.seed", "impact.sweep_velocities",  # the impact jobs' packing seed and runs
    "resources.dem_runtime_min",  # Slurm's time limit of a job
    "resources.dem_threads", "resources.loop_threads",  # a job's threads (Snakemake's)
} | {k for k in STUDY_ONLY if k.count(".") >= 1}  # the DAG's switches and lists

#: fields of these classes that are no config key: the study runs them at the field's
#: default (one place to see which lab settings the study does not expose), and why
LAB_ONLY = {
    # the lab's own controls the study leaves at their defaults: a strain rate instead of
    # a platen speed, the step guard, the fitting windows, the gauges and seating
    "compression": {"strain_rate", "max_steps", "fit_window", "ci_fraction", "lateral_band",
                    "post_peak_strain"},
    "bts": {"max_steps", "central_band", "contact_cap_bridge", "split_drop", "seat_stress",
            "seat_velocity", "seat_tol", "seat_ratio", "max_seat_steps", "servo_alpha"},
    "dtt": {"max_steps", "fit_window"},
    # the triaxial test takes its cylinder's loading from the compression section and its
    # confinement per job (sigma3); the servo's and consolidation's controls are the lab's
    "triaxial": {"sigma3", "platen_velocity", "strain_rate", "damping", "platen_fric",
                 "wall_fric", "servo_vmax", "servo_interval", "servo_feedforward",
                 "gain_update", "seat_stress", "consol_tol", "consol_tol_abs", "consol_ratio",
                 "max_consol_steps", "stop_drop", "max_strain", "max_steps", "record_strain",
                 "fit_window", "lateral_band", "post_peak_strain", "ci_fraction", "end_cap",
                 "end_cap_factor", "density_scaling"},
    "impact": {"gravity", "after_rebound", "gap"},  # the drop's physics and stop
    "posterior": {"chunk", "walkers", "draws"},  # the sampler's ensemble
    # a job's packing cache, threads and progress line: the workflow's per job; its
    # memory budget the study's resources.dem_mem_mb (also Slurm's mem_mb), the library's
    # default 80 % of the machine's
    "resources": {"cache", "threads", "progress", "mem_budget_mb"},
}

#: keys whose schema bounds are stricter than the command's, and why (none may be looser)
STRICTER_SCHEMA = {}


def _props(section: str) -> dict:
    node = SCHEMA
    for part in section.split("."):
        node = node["properties"][part]
    return node["properties"]


def _setting_keys(section: str) -> list:
    return [f"{section}.{k}" for k, v in _props(section).items()
            if f"{section}.{k}" not in NOT_FIELDS and "properties" not in v]


def _field(key: str) -> tuple:
    """(field name, factor) of a key: its stated conversion, or its own name."""
    return CONVERTED.get(key, (key.rsplit(".", 1)[1], 1.0))


ALL_KEYS = [k for s in SECTIONS for k in _setting_keys(s)]


@pytest.mark.parametrize("section", list(SECTIONS))
def test_every_key_is_a_field_and_every_field_a_key_or_a_stated_lab_option(section):
    cls = SECTIONS[section]
    fields = {f.name for f in dataclasses.fields(cls)}
    keys = _setting_keys(section)
    named = {_field(k)[0] for k in keys}
    assert named - fields == set(), f"{section}: keys of no {cls.__name__} field"
    assert fields - named == LAB_ONLY.get(section, set()), (
        f"{section}: {cls.__name__} fields that are neither a config key nor stated in LAB_ONLY",
        fields - named - LAB_ONLY.get(section, set()),
        "stated but a key (or gone)", LAB_ONLY.get(section, set()) - (fields - named))


@pytest.mark.parametrize("key", ALL_KEYS)
def test_key_option_and_field_share_the_default(key):
    """The schema's default is the field's (in the key's units) and the option's; the
    option is the one test_defaults.py maps the key to (its name: the key's)."""
    section = key.rsplit(".", 1)[0]
    field, factor = _field(key)
    value = getattr(SECTIONS[section](), field)
    item = _props(section)[key.rsplit(".", 1)[1]]
    if "default" not in item:  # a key every config sets (specimen.scale)
        return
    schema = item["default"]
    want = value / factor if isinstance(value, float) and factor != 1.0 else value
    assert same(schema, want), f"{key}: schema {schema!r}, {SECTIONS[section].__name__}." \
                               f"{field} {value!r}"
    assert key in DEFAULTS, f"{key}: no option mapped in test_defaults.DEFAULTS"
    cli = DEFAULTS[key][1]
    if cli is not None:
        cmd, dest, conv = cli
        v = cli_default(cmd, dest)
        assert same(conv(v) if conv else v, want), f"{key}: bpmcal {cmd} --{dest} {v!r}"


def _probes(bounds) -> list:
    """Values the bounds (low, low open, high, high open) accept, at and near each end."""
    lo, lo_open, hi, hi_open = bounds
    lo_v = 0.0 if lo is None else lo
    hi_v = (lo_v + 1e3) if hi is None else hi
    span = hi_v - lo_v
    out = [lo_v + span * 1e-6 if lo_open else lo_v, hi_v - span * 1e-6 if hi_open else hi_v,
           lo_v + span / 2]
    return [v for v in out if math.isfinite(v)]


@pytest.mark.parametrize("key", [k for k in ALL_KEYS
                                 if DEFAULTS.get(k, (None, None))[1] is not None])
def test_key_option_and_field_share_the_bounds(key):
    """The schema lets through exactly what the option accepts (a stricter schema only
    where STRICTER_SCHEMA says why), and the settings class takes every value the option
    accepts (a command never fails after its parsing on a value it let through)."""
    section, name = key.rsplit(".", 1)
    item = _props(section)[name]
    item = item.get("items", item)
    cmd, dest, conv = DEFAULTS[key][1]
    bounds = getattr(cli_type(cmd, dest), "bounds", None)
    if bounds is None or conv is not None or item.get("type") not in ("number", "integer"):
        return  # a choice or text: compared by the default (and the option's choices)
    schema = _limits(item)
    if key in STRICTER_SCHEMA:
        assert schema != bounds, f"{key}: now the same; remove it from STRICTER_SCHEMA"
    else:
        assert schema == bounds, f"{key}: the schema allows {schema}, bpmcal {cmd} --" \
                                 f"{dest.replace('_', '-')} {bounds}"
    field, factor = _field(key)
    cls = SECTIONS[section]
    for v in _probes(bounds):
        v = int(v) if item["type"] == "integer" else v
        try:
            cls(**{field: v * factor if factor != 1.0 else v})
        except Exception as e:  # noqa: BLE001 - any refusal is the disagreement
            pytest.fail(f"{key}={v!r}: bpmcal {cmd} accepts it, {cls.__name__} refuses: {e}")


def test_the_section_checks_can_fail(monkeypatch):
    monkeypatch.setitem(LAB_ONLY, "dtt", {"max_steps"})
    with pytest.raises(AssertionError, match="neither a config key nor stated"):
        test_every_key_is_a_field_and_every_field_a_key_or_a_stated_lab_option("dtt")
    monkeypatch.setitem(CONVERTED, "impact.duration_ms", ("duration", 1.0))
    with pytest.raises(AssertionError, match="impact.duration_ms: schema"):
        test_key_option_and_field_share_the_default("impact.duration_ms")
