"""The tests mirror the source (issue 54): ``tests/unit/<package path>/test_<name>.py``
tests the module ``src/bpmcal/<package path>/<module>.py`` that ``<name>`` starts with
(``test_<module>.py`` or ``test_<module>_<topic>.py``), or the package as a whole
(``test_<package>.py``); test files live only in the folders the layout names; the
shared helpers live in ``tests/support`` alone."""
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SRC = REPO / "src" / "bpmcal"
TESTS = REPO / "tests"
#: where test files may live (docs/developer/layout.md)
FOLDERS = ("unit", "integration", "workflow", "docs", "architecture")


def _modules(pkg: Path) -> set[str]:
    return {p.stem for p in pkg.glob("*.py") if p.stem != "__init__"} | {
        p.name for p in pkg.iterdir() if (p / "__init__.py").exists()}


def _names_a_module(test: Path) -> bool:
    rel = test.parent.relative_to(TESTS / "unit")
    pkg = SRC / rel
    if not (pkg / "__init__.py").exists():
        return False
    name = test.stem.removeprefix("test_")
    own = pkg.name if rel.parts else "bpmcal"
    return any(name == m or name.startswith(m + "_") for m in _modules(pkg) | {own})


def test_every_unit_test_names_the_module_it_tests():
    bad = [str(t.relative_to(REPO)) for t in sorted((TESTS / "unit").rglob("test_*.py"))
           if not _names_a_module(t)]
    assert not bad, ("unit tests that name no module of src/bpmcal (tests/unit/<package>/"
                     f"test_<module>[_<topic>].py): {bad}")


def test_test_files_live_only_in_the_layouts_folders():
    stray = [str(t.relative_to(REPO)) for t in sorted(TESTS.rglob("test_*.py"))
             if t.relative_to(TESTS).parts[0] not in FOLDERS]
    assert not stray, f"test files outside tests/{{{', '.join(FOLDERS)}}}: {stray}"


def test_shared_helpers_live_in_support():
    helpers = [str(p.relative_to(REPO)) for p in sorted(TESTS.rglob("*.py"))
               if not p.name.startswith("test_") and p.name != "conftest.py"
               and "support" not in p.relative_to(TESTS).parts
               and "audit" not in p.relative_to(TESTS).parts]  # a subprocess's sitecustomize
    assert not helpers, f"test helpers outside tests/support: {helpers}"


def test_the_check_catches_a_misnamed_file(tmp_path):
    """The rule itself: a file naming a module of its package passes, one naming none, or
    sitting under a folder that is no package, fails."""
    assert _names_a_module(TESTS / "unit" / "lab" / "test_brazilian.py")
    assert _names_a_module(TESTS / "unit" / "lab" / "test_specimen_pfc.py")
    assert _names_a_module(TESTS / "unit" / "plots" / "test_plots.py")
    assert not _names_a_module(TESTS / "unit" / "lab" / "test_bts.py")
    assert not _names_a_module(TESTS / "unit" / "nowhere" / "test_x.py")
