"""The repository is self-contained: no file in it refers to a file outside it, so a clone
reads and runs alone. Checked in every tracked text file of src/, tests/, docs/, workflow/,
config/, benchmarks/, .ci/ and the top-level files:

- no path to the developers' notes kept beside the repository (``../shared/...``, their
  names ``FJM.md``, ``PBM.md``, ...): what the code needs of a specification is written
  into docs/ (e.g. docs/flatjoint-spec.md);
- no absolute path into a host's own trees (``/work/...``, ``/home/...``, ``/root/...``);
  system and scratch locations (``/tmp``, ``/etc``, ``/run``, ``/usr``) are the operating
  system's, not files the repository needs;
- no relative Markdown link that climbs out of the repository.

The measurement records (docs/measurements/, benchmarks/results/*.json) keep the exact
command that produced them, host paths included: that is their provenance (where the
measured run's files were), not a reference a reader follows, so only the first rule
applies to them."""
import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
FOLDERS = ("src", "tests", "docs", "workflow", "config", "benchmarks", ".ci")
TEXT = {".py", ".md", ".yaml", ".yml", ".smk", ".rst", ".toml", ".cfg", ".txt", ".json",
        ".csv", ".cff", ".sh", ".ini", ""}  # "": Snakefile, .ci/run, ...

#: the developers' notes beside the repository (and the folder that holds them)
NOTES = re.compile(r"(?:\.\./|/)shared/|\b(?:FJM|PBM|DESIGN|SLURM|PERFORMANCE|"
                   r"STRUCTURE-REVIEW)\.md\b")
#: an absolute path into a host's own trees
HOST_PATH = re.compile(r"(?<![\w.~/-])/(?:work|home|root|Users|mnt|srv|scratch)/[\w.-]")
#: a Markdown link target ``](...)``
LINK = re.compile(r"\]\(([^)\s]+)\)")


def is_record(rel: str) -> bool:
    """A dated measurement record or a benchmark's JSON result (see the module docstring)."""
    return rel.startswith("docs/measurements/") or re.fullmatch(
        r"benchmarks/results/[^/]*\.json", rel) is not None


def tracked() -> list[str]:
    out = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True,
                         check=True).stdout.split()
    return sorted(f for f in out if "/" not in f or f.split("/")[0] in FOLDERS)


def outside_references(rel: str, text: str) -> list[str]:
    """What in ``text`` (the file ``rel`` of the repository) refers outside it."""
    found = [f"{m.group(0)!r} (a developers' note)" for m in NOTES.finditer(text)]
    if not is_record(rel):
        found += [f"{text[m.start():m.start() + 40].split()[0]!r} (a host path)"
                  for m in HOST_PATH.finditer(text)]
    if rel.endswith(".md"):
        here = (REPO / rel).parent
        for m in LINK.finditer(text):
            target = m.group(1).split("#")[0]
            if not target or re.match(r"[a-z]+:", target) or target.startswith("/"):
                continue
            resolved = (here / target).resolve()
            if resolved != REPO and REPO not in resolved.parents:
                found.append(f"link {m.group(1)!r} (outside the repository)")
    return found


#: this file, whose examples are what it forbids
SELF = "tests/architecture/test_self_contained.py"


def test_the_files_are_found():
    files = tracked()
    assert "src/bpmcal/dem/flatjoint.py" in files and "docs/contact_laws.md" in files
    assert "README.md" in files and ".ci/run" in files


@pytest.mark.parametrize("rel", [f for f in tracked() if Path(f).suffix in TEXT and f != SELF])
def test_no_reference_outside_the_repository(rel):
    path = REPO / rel
    if not path.is_file():  # deleted in the work tree, not yet in the index
        return
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        return
    found = outside_references(rel, text)
    assert not found, (f"{rel} refers to files outside the repository: " + "; ".join(found)
                       + " (write what is needed into docs/ and refer to that)")


@pytest.mark.parametrize("rel, text, n", [
    ("src/bpmcal/x.py", "Specification: ``../shared/FJM.md``", 2),
    ("docs/x.md", "see /work/shared/STRUCTURE-REVIEW.md", 3),
    ("tests/x.py", "DATA = '/home/me/data.csv'", 1),
    ("docs/x.md", "[notes](../../elsewhere/notes.md)", 1),
    ("docs/measurements/x.md", "Command: `python b.py --out /work/main/x.json`", 0),
    ("docs/measurements/x.md", "spec: ../shared/FJM.md", 2),
    ("benchmarks/results/results_x.json", '{"cmd": "--runs /work/run/a.h5"}', 0),
    ("docs/x.md", "[spec](flatjoint-spec.md), [readme](../README.md), /tmp/old, "
                  "~/.cache/bpmcal, [site](https://example.org/a/../b)", 0),
])
def test_the_check_finds_outside_references(rel, text, n):
    assert len(outside_references(rel, text)) == n, outside_references(rel, text)
