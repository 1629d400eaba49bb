"""Options renamed to their config keys keep their old spelling for one release
(``bpmcal.cli.args.old_spelling``): the old spelling sets the same value as the new one,
with exactly one line on stderr naming the new spelling, and no help lists it."""
import pytest

from bpmcal.cli import COMMANDS, build_parser, main, run_settings
from bpmcal.cli.args import _OldSpelling
from bpmcal.cli.options import bts_settings_of, dtt_settings_of

#: the options every command requires (values that parse; nothing is run)
REQUIRED = {
    "ucs": ["--out", "o.h5"],
    "bts": ["--out", "o.h5"],
    "dtt": ["--out", "o.h5"],
    "triaxial": ["--out", "o.h5", "--sigma3", "5"],
    "screen": ["--dataset", "d.csv", "--selected", "s.json", "--table3", "t.csv",
               "--figure", "f.png", "--importance-table", "i.csv", "--cv-table", "c.csv",
               "--shadow-table", "h.csv", "--summary", "s.txt"],
    "verify": ["--card", "c.yaml", "--models", "m.json", "--out-card", "v.yaml",
               "--rounds", "r.csv", "--run", "1.h5"],
    "transfer": ["--card", "c.yaml", "--models", "m.json", "--out-card", "v.yaml",
                 "--rounds", "r.csv", "--run", "1.h5"],
    "fresh-seeds": ["--card", "c.yaml", "--seeds", "101,102", "--runs", "1.h5", "2.h5",
                    "--seed-runs", "s.csv"],
    "posterior": ["--card", "c.yaml", "--dataset", "d.csv", "--models", "m.json",
                  "--out-card", "p.yaml", "--table", "t.csv", "--predictions", "p.csv",
                  "--netcdf", "p.nc", "--figure", "f.png"],
    "predictive": ["--draws", "d.csv", "--specimen", "B1", "--table", "t.csv",
                   "--sigma3", "0,10", "--tri-runs", "1.h5", "2.h5"],
}

#: old spelling -> (new spelling, a valid value other than the default)
RENAMED = {
    "--post-peak-min": ("--post-peak-strain", "0.00037"),
    "--bts-post-peak-min": ("--bts-post-peak-strain", "0.00037"),
    "--dtt-post-peak-min": ("--dtt-post-peak-strain", "0.00037"),
    "--servo-gain": ("--servo-alpha", "0.55"),
    "--splits": ("--n-splits", "3"),
    "--repeats": ("--n-repeats", "4"),
}

CASES = [("ucs", "--bts-post-peak-min"), ("ucs", "--dtt-post-peak-min"),
         ("bts", "--post-peak-min"), ("dtt", "--post-peak-min"), ("triaxial", "--servo-gain"),
         ("screen", "--splits"), ("screen", "--repeats"),
         *[(c, o) for c in ("verify", "transfer", "fresh-seeds", "posterior", "predictive")
           for o in ("--bts-post-peak-min", "--dtt-post-peak-min")]]


def _parser(cmd):
    return build_parser(only=cmd)._subparsers._group_actions[0].choices[cmd]


def _line(cmd, old, new):
    return f"bpmcal {cmd}: {old} is deprecated: use {new} (it will be removed in the next release)"


def test_the_cases_are_every_old_spelling_of_every_command():
    parser = build_parser()
    found = {(cmd, a.option_strings[0])
             for cmd, p in parser._subparsers._group_actions[0].choices.items()
             if cmd in COMMANDS  # not the aliases of renamed commands
             for a in p._actions if isinstance(a, _OldSpelling)}
    assert found == set(CASES)
    for cmd, old in CASES:
        a = next(a for a in _parser(cmd)._actions if old in a.option_strings)
        assert a.new == RENAMED[old][0]


@pytest.mark.parametrize("cmd, old", CASES)
def test_an_old_spelling_sets_what_the_new_one_sets_with_one_line(cmd, old, capsys):
    new, value = RENAMED[old]
    p = _parser(cmd)
    want = p.parse_args([*REQUIRED[cmd], new, value])
    assert capsys.readouterr().err == ""
    default = p.parse_args(REQUIRED[cmd])
    got = p.parse_args([*REQUIRED[cmd], old, value])
    assert capsys.readouterr().err == _line(cmd, old, new) + "\n"
    assert vars(got) == vars(want) != vars(default)
    got_eq = p.parse_args([*REQUIRED[cmd], f"{old}={value}"])  # --OPTION=VALUE too
    assert vars(got_eq) == vars(want)
    assert capsys.readouterr().err == _line(cmd, old, new) + "\n"


@pytest.mark.parametrize("cmd, old", [("bts", "--post-peak-min"), ("dtt", "--post-peak-min"),
                                      ("ucs", "--bts-post-peak-min"),
                                      ("ucs", "--dtt-post-peak-min"),
                                      ("triaxial", "--servo-gain")])
def test_an_old_spelling_gives_the_same_settings(cmd, old, capsys):
    """The settings objects the commands build from the two spellings are equal (and not
    the defaults)."""
    new, value = RENAMED[old]
    p = _parser(cmd)
    a, b, d = (p.parse_args([*REQUIRED[cmd], *x]) for x in ([old, value], [new, value], []))
    if cmd == "triaxial":
        from bpmcal.lab.triaxial import TriaxialSettings

        def of(n):
            return run_settings(n, TriaxialSettings, sigma3=n.sigma3 * 1e6,
                                servo_alpha=n.servo_alpha)
    else:
        prefix = "" if cmd != "ucs" else old[2:6].replace("-", "_")
        test = cmd if cmd != "ucs" else prefix[:-1]
        read = bts_settings_of if test == "bts" else dtt_settings_of

        def of(n):
            return read(n, prefix)
    assert of(a) == of(b) != of(d)
    field = new.lstrip("-").replace("-", "_").removeprefix("bts_").removeprefix("dtt_")
    assert getattr(of(a), field) == float(value)


@pytest.mark.parametrize("cmd", sorted({c for c, _ in CASES}))
def test_the_help_lists_the_new_spellings_only(cmd):
    text = " ".join(_parser(cmd).format_help().split())
    for c, old in CASES:
        if c == cmd:
            assert f"{RENAMED[old][0]} " in text and f"{old} " not in text, old


def test_a_bad_value_of_an_old_spelling_names_it_in_one_line(tmp_path, capsys):
    assert main(["screen", *REQUIRED["screen"], "--splits", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "splits='1': expected an integer >= 2" in err[0], err
    assert "n-splits" not in err[0]


def test_an_old_spelling_runs_through_main(tmp_path, capsys):
    """``bpmcal screen --repeats`` on a dataset that does not exist: the deprecation line,
    then the command's own one-line error (the option reached the command)."""
    argv = [a if not a.endswith((".csv", ".json", ".png", ".txt")) else str(tmp_path / a)
            for a in REQUIRED["screen"]]
    assert main(["screen", *argv, "--repeats", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == _line("screen", "--repeats", "--n-repeats")
    assert len(err) == 2 and err[1].startswith("bpmcal screen: error:") and "d.csv" in err[1]
