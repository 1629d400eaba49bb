"""LoopSettings (bpmcal.analysis.calibration.loop_settings): every option of a closed loop as
one value, checked once where it is built, with one set of limits that ClosedLoop's
keywords, the ``bpmcal verify`` options and the workflow's command line share. (The
config schema against the fields: tests/workflow/test_defaults.py.)"""
import argparse
import dataclasses
import math

import pytest

from bpmcal.analysis.calibration import ClosedLoop, LoopSeeds, LoopSteps, SearchSpace
from bpmcal.analysis.calibration.loop_settings import LIMITS, Limit, LoopSettings, check_loop_value
from bpmcal.cli import build_parser
from bpmcal.cli.options import loop_argv, loop_settings_of
from bpmcal.io.checks import BadInput


def test_the_defaults_are_the_default_studys_and_the_seeds_follow_the_first():
    s = LoopSettings()
    assert (s.seed, s.seeds_per_round, s.max_seeds, s.rtol, s.max_rounds) == (1, 3, 10, 0.01, "auto")
    assert s.seeds == [1, 2, 3]
    assert LoopSettings(seed=7, seeds_per_round=2).seeds == [7, 8]
    assert s.most_tensile_specimens == 3  # none: the fixed count
    assert LoopSettings(tensile_specimens=3, max_tensile_specimens=8).most_tensile_specimens == 8
    assert LoopSettings(tensile_specimens=5, max_tensile_specimens=2).most_tensile_specimens == 5


@pytest.mark.parametrize("field, bad, expected", [
    ("seed", -1, r"an integer in 0 \.\. 4294967295"),
    ("seeds_per_round", 51, r"an integer in 1 \.\. 50"),
    ("max_seeds", 0, r"an integer in 1 \.\. 200"),
    ("grow_within", math.nan, r"a number in \[1, inf\)"),
    ("rtol", 0.0, r"a number in \(0, 1\]"),
    ("rtol", 1.5, r"a number in \(0, 1\]"),
    ("max_rounds", "Auto", r"an integer in 1 \.\. 50, or 'auto'"),
    ("range_margin", -0.1, r"a number in \[0, 1\]"),
    ("polish", "yes", r"true or false"),
    ("jacobian_update", "newton", r"one of broyden, history"),
    ("tensile_specimens", 2.0, r"an integer in 1 \.\. 50"),
    ("tensile_seed_cv", 1.0, r"a number in \(0, 1\), or none"),
    ("max_tensile_specimens", True, r"an integer in 1 \.\. 50, or none"),
    ("triaxial_seeds", 1, r"an integer in 2 \.\. 200, or none"),
    ("from_unreachable", 1, r"true or false"),
])
def test_a_bad_setting_is_refused_naming_it_and_what_it_takes(field, bad, expected):
    with pytest.raises(BadInput, match=f"{field}={bad!r}: expected {expected}"):
        LoopSettings(**{field: bad})


def test_values_are_normalised_and_the_settings_frozen():
    import numpy as np

    s = LoopSettings(seed=np.int64(4), grow_within=2, rtol=np.float64(0.02))
    assert type(s.seed) is int and type(s.grow_within) is float and type(s.rtol) is float
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.rtol = 0.5
    with pytest.raises(BadInput, match="max_seeds=0"):
        dataclasses.replace(s, max_seeds=0)  # a changed copy is checked again


def test_closed_loop_keywords_are_checked_by_the_same_limits():
    """ClosedLoop's keywords that are LoopSettings fields take exactly what the fields
    take (its own names in the message: margin, update)."""
    for name, field, bad in (("margin", "range_margin", 1.5), ("update", "jacobian_update", "x"),
                             ("max_rounds", "max_rounds", 51), ("rtol", "rtol", 2.0),
                             ("grow_within", "grow_within", 0.5)):
        where = ({"seeding": LoopSeeds(grow_within=bad)} if name == "grow_within"
                 else {"steps": LoopSteps(**{name: bad})})
        with pytest.raises(ValueError, match=f"{name}={bad!r}: expected") as e:
            ClosedLoop(lambda p, seed: {}, {"ucs_MPa": 1.0},
                       space=SearchSpace(ranges={"pb_coh_MPa": [1, 2]}), jacobian=object(),
                       **where)
        assert str(e.value).endswith(LIMITS[field].expected())
    assert check_loop_value("range_margin", 0.5, "margin") == 0.5


def test_a_limit_accepts_exactly_its_range():
    lim = Limit("float", 0.0, 1.0, lo_open=True, hi_open=True, null=True)
    assert [lim.accepts(v) for v in (None, 0.0, 1e-9, 0.5, 1.0, math.inf, True, "0.5")] == [
        True, False, True, True, False, False, False, False]
    whole = Limit("int", 1, 50, words=("auto",))
    assert [whole.accepts(v) for v in (1, 50, 51, 0, "auto", "Auto", 2.5, None)] == [
        True, True, False, False, True, False, False, False]
    assert whole.parse("auto", "max-rounds") == "auto" and whole.parse("7", "max-rounds") == 7
    with pytest.raises(BadInput, match="max-rounds='0': expected an integer in 1 .. 50, or 'auto'"):
        whole.parse("0", "max-rounds")


def _verify_args(*extra):
    return build_parser(only="verify").parse_args(
        ["verify", "--card", "c.yaml", "--models", "m.json", "--out-card", "o.yaml",
         "--rounds", "r.csv", "--run", "r.h5", *extra])


def test_the_command_reads_back_the_settings_it_was_given():
    assert loop_settings_of(_verify_args()) == LoopSettings()
    a = _verify_args("--seed", "4", "--max-rounds", "12", "--no-polish", "--grow-within", "1.5",
                     "--jacobian-update", "history", "--tensile-seed-cv", "0.05",
                     "--triaxial-seeds", "5", "--from-unreachable")
    assert loop_settings_of(a) == LoopSettings(seed=4, max_rounds=12, polish=False,
                                               grow_within=1.5, jacobian_update="history",
                                               tensile_seed_cv=0.05, triaxial_seeds=5,
                                               from_unreachable=True)


@pytest.mark.parametrize("option, value", [("--max-rounds", "51"), ("--seeds-per-round", "0"),
                                           ("--rtol", "nan"), ("--tensile-seed-cv", "1")])
def test_the_command_refuses_what_the_settings_refuse(option, value, capsys):
    with pytest.raises(SystemExit) as e:
        _verify_args(option, value)
    err = capsys.readouterr().err
    assert e.value.code == 2 and f"{option[2:]}={value!r}: expected" in err


def test_the_workflows_command_line_is_the_sections_settings():
    """loop_argv: every setting of a config's verification section as the option the
    command reads back into the same LoopSettings; the adaptive tensile count only with a
    σt target (and its cap only with the count), the triaxial seed cap only with a σ1 one."""
    section = {**dataclasses.asdict(LoopSettings()), "max_rounds": 9, "polish": False,
               "grow_within": 1.37, "tensile_seed_cv": 0.05, "max_tensile_specimens": 8,
               "triaxial_seeds": 4, "scatter_seeds": [1, 2], "fresh_seeds": []}
    both = loop_argv(section, tensile=True, triaxial=True)
    want = LoopSettings(**{k: section[k] for k in LIMITS})
    assert loop_settings_of(_verify_args(*both)) == want
    assert "--no-polish" in both and "--no-from-unreachable" in both
    plain = loop_argv(section)
    assert not {"--tensile-seed-cv", "--max-tensile-specimens", "--triaxial-seeds"} & set(plain)
    no_cv = loop_argv({**section, "tensile_seed_cv": None}, tensile=True)
    assert "--max-tensile-specimens" not in no_cv  # a cap without the count acts on nothing
    with pytest.raises(BadInput, match="max_rounds=51"):
        loop_argv({**section, "max_rounds": 51})
    assert isinstance(build_parser(only="verify"), argparse.ArgumentParser)
