"""No module in src/bpmcal is longer than :data:`MAX_LINES` lines (as ``wc -l`` counts them:
docstrings, comments and blank lines included, as a reader scrolls the file). A module
that grows past it holds more than one job: split it along its jobs (e.g.
``analysis/calibration/closed_loop.py`` into the driver, ``step_rule.py`` and
``seed_policy.py``; ``report/build.py`` by section), and update its importers rather than
leave a re-export behind. There is no list of exceptions: a long module is split, not
excused."""
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "bpmcal"
MAX_LINES = 800


def module_lines(text: str) -> int:
    """The lines of a module's text (the last one counts without its newline too)."""
    return len(text.splitlines())


def check_length(path: Path, root: Path = SRC, max_lines: int = MAX_LINES) -> None:
    """An AssertionError naming the module and its length if it is longer than ``max_lines``."""
    n = module_lines(path.read_text())
    rel = path.relative_to(root).as_posix()
    assert n <= max_lines, (f"{rel}: {n} lines, over the limit of {max_lines}: split it along "
                            "its jobs (docs/architecture.md, the module map)")


SOURCES = sorted(SRC.rglob("*.py"))


@pytest.mark.parametrize("path", SOURCES, ids=[str(f.relative_to(SRC)) for f in SOURCES])
def test_no_module_is_longer_than_the_limit(path):
    check_length(path)


def test_every_module_is_checked():
    """The parametrisation sees the package (a wrong SRC would pass on nothing)."""
    names = {f.relative_to(SRC).as_posix() for f in SOURCES}
    assert {"__init__.py", "analysis/calibration/closed_loop.py", "report/build.py",
            "lab/specimen.py"} <= names
    assert len(SOURCES) > 100


def test_the_check_can_fail(tmp_path):
    """A planted module of 801 lines fails, one of 800 passes, whatever its lines hold."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    at_limit, over = pkg / "ok.py", pkg / "long.py"
    at_limit.write_text("x = 1\n" * 799 + '"""no newline at the end"""')
    over.write_text("# a comment\n" * 400 + "\n" * 400 + "y = 2\n")
    assert module_lines(at_limit.read_text()) == 800
    assert module_lines(over.read_text()) == 801
    check_length(at_limit, root=tmp_path)
    with pytest.raises(AssertionError, match=r"pkg/long\.py: 801 lines, over the limit of 800"):
        check_length(over, root=tmp_path)
