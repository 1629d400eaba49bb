"""Renamed subcommands keep their old names as argparse aliases (``bpmcal.cli.ALIASES``):
a script that calls the old name runs the same command, while the help lists the new
names only (the new name's own help says what it was called before)."""
import re

import pytest

from bpmcal.cli import ALIASES, COMMANDS, build_parser, main


def test_every_alias_names_a_command_and_shadows_none():
    assert ALIASES and set(ALIASES.values()) <= set(COMMANDS)
    assert not set(ALIASES) & set(COMMANDS)


@pytest.mark.parametrize("old", sorted(ALIASES))
def test_an_old_name_parses_as_the_new_command(old):
    new = ALIASES[old]
    argv = {"fresh-seeds": ["--card", "c.yaml", "--seeds", "101,102", "--runs", "1.h5", "2.h5",
                            "--seed-runs", "s.csv"],
            "fresh-seeds-table": ["--cards", "c.yaml", "--seed-runs", "s.csv",
                                  "--table", "t.csv"]}[new]
    a = build_parser(only=new).parse_args([old, *argv])
    b = build_parser(only=new).parse_args([new, *argv])
    assert a.func is b.func
    assert {k: v for k, v in vars(a).items() if k != "cmd"} == \
        {k: v for k, v in vars(b).items() if k != "cmd"}


@pytest.mark.parametrize("old", sorted(ALIASES))
def test_main_runs_an_old_name(old, tmp_path, capsys):
    """Through ``main`` (which builds only the command's parser): the command's own
    checks run, here refusing a card that does not exist."""
    argv = {"fresh-seeds": ["--card", str(tmp_path / "none.yaml"), "--seeds", "101,102",
                            "--runs", str(tmp_path / "o" / "1.h5"), str(tmp_path / "o" / "2.h5"),
                            "--seed-runs", str(tmp_path / "o" / "s.csv")],
            "fresh-seeds-table": ["--cards", str(tmp_path / "none.yaml"), "--seed-runs",
                                  str(tmp_path / "s.csv"), "--table",
                                  str(tmp_path / "o" / "t.csv")]}[ALIASES[old]]
    assert main([old, *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"bpmcal {old}: error:") and "none.yaml" in err[0]
    assert not (tmp_path / "o").exists()


def test_the_help_lists_the_new_names_only():
    """Each old name appears once in ``bpmcal --help``: in "formerly <old>" of its new
    name's line (not in the usage, the list of choices or beside the new name)."""
    text = build_parser(only="ucs").format_help()
    usage = text.split("\n\n")[0]
    words = " ".join(text.split())
    for old, new in ALIASES.items():
        assert new in usage and old not in usage
        whole = re.findall(rf"(?<![\w-])(\w+ )?{re.escape(old)}(?![\w-])", words)
        assert whole == ["formerly "], (old, whole)
