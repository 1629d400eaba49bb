"""The stages' settings values and the config sections they map: every key of the
``screening``, ``regression`` and ``calibration`` sections is a field of the stage's
settings class (its name, less a unit suffix) and every field a key; key, field and the
option of ``bpmcal screen``/``regress``/``calibrate`` share the default and the bounds
(numbers) or the choices (words). The values refuse what the schema refuses, naming the
field, and the command refuses it before any work."""
import math
import subprocess
import sys
from dataclasses import fields

import pytest
import yaml
from support.repo import SCHEMA as SCHEMA_FILE

from bpmcal.cli import build_parser
from bpmcal.io.checks import BadInput
from bpmcal.stages.calibration import CalibrationSettings
from bpmcal.stages.predictive import PredictiveSettings
from bpmcal.stages.regression import RegressionSettings
from bpmcal.stages.screening import ScreeningSettings
from bpmcal.stages.settings import limits

SCHEMA = yaml.safe_load(SCHEMA_FILE.read_text())

#: config section -> (its settings class, the command the workflow passes it to, the
#: fields the class needs to be built)
SECTIONS = {
    "screening": (ScreeningSettings, "screen", {}),
    "regression": (RegressionSettings, "regress", {}),
    "calibration": (CalibrationSettings, "calibrate", {"fixed": {}}),
}
UNIT_SUFFIXES = ("_pct",)
#: a key whose option has another name, and why
OPTIONS = {
    # not renamed yet: bpmcal calibrate --ratio (<= 0 there is the field's None: both
    # strengths free), its --ratio-from and the sweep's ratios
    "calibration.strength_ratio": "ratio",
}
#: keys whose option takes no value of their kind (a JSON text, a comma-separated list):
#: their default is compared with the field's only
TEXT_OPTIONS = {"calibration.fixed", "calibration.free", "calibration.bounds"}


def _field(key: str) -> str:
    name = key.rsplit(".", 1)[1]
    for u in UNIT_SUFFIXES:
        name = name.removesuffix(u)
    return name


def _action(cmd: str, key: str):
    p = build_parser(only=cmd)._subparsers._group_actions[0].choices[cmd]
    dest = OPTIONS.get(key, _field(key))
    return next(a for a in p._actions if a.dest == dest)


def _limits(item: dict) -> tuple:
    """(low, low open, high, high open) of a JSON-schema number."""
    lo, lo_open = item.get("minimum"), False
    if "exclusiveMinimum" in item:
        lo, lo_open = item["exclusiveMinimum"], True
    hi, hi_open = item.get("maximum"), False
    if "exclusiveMaximum" in item:
        hi, hi_open = item["exclusiveMaximum"], True
    return lo, lo_open, hi, hi_open


def _same(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and math.isclose(a, b, rel_tol=1e-12)
    return a == b


KEYS = [f"{s}.{k}" for s in SECTIONS for k in SCHEMA["properties"][s]["properties"]]


@pytest.mark.parametrize("section", list(SECTIONS))
def test_every_key_is_a_field_and_every_field_a_key(section):
    cls = SECTIONS[section][0]
    keys = {_field(f"{section}.{k}") for k in SCHEMA["properties"][section]["properties"]}
    names = {f.name for f in fields(cls)}
    assert keys == names, (f"{section}: keys of no {cls.__name__} field", keys - names,
                           "fields of no key", names - keys)


@pytest.mark.parametrize("key", KEYS)
def test_key_field_and_option_share_default_and_bounds(key):
    section = key.split(".")[0]
    cls, cmd, needed = SECTIONS[section]
    name = _field(key)
    item = SCHEMA["properties"][section]["properties"][key.rsplit(".", 1)[1]]
    value = getattr(cls(**needed), name)
    if "default" in item:
        assert _same(item["default"], value), f"{key}: schema {item['default']!r}, " \
                                               f"{cls.__name__}.{name} {value!r}"
    limit = limits(cls).get(name)
    if limit is None:  # a mapping or a list (fixed, free, bounds): checked when built
        assert key in TEXT_OPTIONS, f"{key}: a setting with no limit"
        return
    a = _action(cmd, key)
    assert _same(a.default, value), f"{key}: bpmcal {cmd} --{a.dest} default {a.default!r}"
    if limit.kind == "choice":
        assert tuple(item["enum"]) == limit.words == tuple(a.choices), key
        return
    assert _limits(item) == limit.bounds, f"{key}: schema {_limits(item)}, field {limit.bounds}"
    if key in OPTIONS:  # --ratio: its low end is the field's None (<= 0), its high the same
        assert a.type.bounds[2:] == limit.bounds[2:] and a.type.bounds[0] is None, key
    else:
        assert a.type.bounds == limit.bounds, f"{key}: bpmcal {cmd} --{a.dest} {a.type.bounds}"


@pytest.mark.parametrize("cls, name, bad", [
    (ScreeningSettings, "n_splits", 21), (ScreeningSettings, "threshold", 100.5),
    (ScreeningSettings, "importance", "weight"), (RegressionSettings, "alpha_in", 0.0),
    (RegressionSettings, "cv_repeats", 101), (RegressionSettings, "seed", -1),
    (CalibrationSettings, "n_boot", 100_001), (CalibrationSettings, "strength_ratio", 0.0),
])
def test_a_value_out_of_bounds_is_refused_naming_the_field(cls, name, bad):
    needed = {"fixed": {}} if cls is CalibrationSettings else {}
    with pytest.raises(BadInput, match=f"^{name}={bad!r}: expected"):
        cls(**needed, **{name: bad})


def test_the_calibration_checks_its_parameters_when_built():
    # (a bad parameter value is a ParameterError, a BadInput a wrong name: both ValueErrors,
    # exit code 2)
    with pytest.raises(ValueError, match=r"--n-boot 1: expected 0 \(no bootstrap\)"):
        CalibrationSettings(fixed={}, n_boot=1)
    with pytest.raises(BadInput, match=r"--free pb_emod_GPa,bogus: unknown parameter\(s\) "
                                       r"\['bogus'\]"):
        CalibrationSettings(fixed={}, free=["pb_emod_GPa", "bogus"])
    with pytest.raises(ValueError, match="--fixed: .*fric"):
        CalibrationSettings(fixed={"fric": True})
    s = CalibrationSettings(fixed={"porosity": 0.34}, free=["pb_emod_GPa"], bounds=None,
                            strength_ratio=None)
    assert s.free == ("pb_emod_GPa",) and s.bounds == {} and s.strength_ratio is None
    assert s.fixed == {"porosity": 0.34} and CalibrationSettings(fixed={}).n_boot == 200


def test_the_predictive_settings_need_an_envelope_and_an_impact_pair():
    with pytest.raises(BadInput, match=r"--sigma3 \[5.0\]: expected at least two"):
        PredictiveSettings(sigma3_MPa=[5])
    from bpmcal.lab.impact import ImpactSettings

    with pytest.raises(BadInput, match="impact_geometry and impact_settings go together"):
        PredictiveSettings(impact_settings=ImpactSettings())
    assert PredictiveSettings(sigma3_MPa=[0, 10]).sigma3_MPa == (0.0, 10.0)


@pytest.mark.parametrize("argv, what", [
    (["screen", "--n-splits", "21"], "n-splits='21'"),
    (["regress", "--cv-folds", "21"], "cv-folds='21'"),
    (["calibrate", "--n-boot", "100001"], "n-boot='100001'"),
    (["calibrate", "--ratio", "20.5"], "ratio='20.5'"),
])
def test_the_command_refuses_what_the_schema_refuses(argv, what):
    """The option stops where the field (and the schema) does: exit 2 and one line
    naming the value, before the files are even asked for."""
    r = subprocess.run([sys.executable, "-m", "bpmcal.cli", *argv], capture_output=True,
                       text=True)
    assert r.returncode == 2 and what in r.stderr, r.stderr


def test_the_check_can_fail(monkeypatch):
    from bpmcal.analysis.calibration.loop_settings import Limit

    lim = dict(limits(ScreeningSettings), n_splits=Limit("int", 2, 100))
    monkeypatch.setattr(sys.modules[__name__], "limits", lambda cls: lim)
    with pytest.raises(AssertionError, match="screening.n_splits: schema"):
        test_key_field_and_option_share_default_and_bounds("screening.n_splits")
