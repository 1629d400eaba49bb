"""Every benchmark script is listed where the docs say every script is: the table of
docs/developer/benchmarks.md and the index of benchmarks/README.md (a script added without
its line fails here)."""
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SCRIPTS = sorted(p.name for p in (REPO / "benchmarks").glob("*.py") if not p.name.startswith("_"))


def _named(page: Path) -> set[str]:
    """The script names a page's table rows name in backquotes."""
    rows = [ln for ln in page.read_text().splitlines() if ln.startswith("| `")]
    return {n for ln in rows for n in re.findall(r"`([\w.]+\.py)`", ln.split(" | ")[0])}


@pytest.mark.parametrize("page", ["docs/developer/benchmarks.md", "benchmarks/README.md"])
def test_every_benchmark_script_is_listed(page):
    named = _named(REPO / page)
    assert set(SCRIPTS) - named == set(), f"{page} leaves out these scripts"
    assert named - set(SCRIPTS) == set(), f"{page} lists scripts that do not exist"


def test_the_scripts_are_found():
    assert "dem_throughput.py" in SCRIPTS and "figures.py" in SCRIPTS and len(SCRIPTS) > 20
