"""No function in src/bpmcal is longer than :data:`MAX_LINES` lines (from its first
decorator to its last line, docstring included, as a reader scrolls it) unless a comment
``# long: <reason>`` stands on the line above it (above its first decorator), or it is in
:data:`ALLOWED` with its reason. A long function that is neither fails this test: split
it along its steps, or say beside it why it stays whole."""
from pathlib import Path

import pytest
from support.source import functions

SRC = Path(__file__).resolve().parents[2] / "src" / "bpmcal"
MAX_LINES = 80

#: "path:qualified name" -> why it stays long (functions outside the refactor of issue 25;
#: each entry is a candidate for a later split)
ALLOWED = {
    "dem/bondblock.py:_compute": "the njit parallel-bond law of one block, written branch-free for "
                                 "the vectoriser; a call per step inside it would cost the SIMD loop",
    "dem/bondblock.py:bond_range": "njit driver of the bond blocks (gather, _compute, scatter); its "
                                   "40 array arguments are the engine's state, split only with it",
    "dem/kernels.py:_pair_range": "njit linear contact law over the unbonded pairs, one fused pass",
    "dem/kernels.py:wall_range": "njit linear contact law over the ball-wall slots, one fused pass",
    "dem/neighbors.py:rebuild": "njit Verlet rebuild with the contact-history carry-over, one pass "
                                "over the cells; review §2: to be split with the engine",
    "lab/impact.py:run_impact": "the impact test's loop: dynamic, ended on time, not driven by "
                                "lab/driver.py (its docstring says why)",
    "lab/specimen.py:build_specimen": "specimen genesis step by step (pack, relax, install, bond); "
                                      "review §2: a candidate for a split by step",
    "plots/fracture.py:fig_impact": "one figure of two panels and their annotations",
    "stages/fresh_seeds.py:fresh_seeds": "the fresh-seed stage: checks, runs and table in one job; "
                                         "outside the split of stages/analysis.py",
    "stages/triaxial.py:envelopes": "the envelope stage: tables, lab points and figure in one job",
}


def long_functions(text: str, max_lines: int = MAX_LINES) -> list[tuple[str, int, bool]]:
    """(qualified name, lines, has a ``# long:`` comment above it) of every function in
    ``text`` longer than ``max_lines``, nested ones included."""
    lines = text.splitlines()
    out = []
    for name, fn in functions(text):
        first = min([fn.lineno] + [d.lineno for d in fn.decorator_list])
        n = fn.end_lineno - first + 1
        above = lines[first - 2].strip() if first >= 2 else ""
        if n > max_lines:
            out.append((name, n, above.startswith("# long:") and len(above) > 10))
    return out


SOURCES = sorted(SRC.rglob("*.py"))


@pytest.mark.parametrize("path", SOURCES, ids=[str(f.relative_to(SRC)) for f in SOURCES])
def test_no_long_function_without_a_reason(path):
    rel = path.relative_to(SRC).as_posix()
    bad = [f"{name} ({n} lines)" for name, n, reason in long_functions(path.read_text())
           if not reason and f"{rel}:{name}" not in ALLOWED]
    assert not bad, (f"{rel}: functions over {MAX_LINES} lines without '# long: <reason>' above "
                     f"them: {', '.join(bad)}")


def test_every_allowed_function_exists_and_is_still_long():
    """An entry of ALLOWED whose function was split (or renamed) goes."""
    for key in ALLOWED:
        rel, name = key.split(":")
        found = {f for f, _, _ in long_functions((SRC / rel).read_text())}
        assert name in found, f"ALLOWED[{key!r}]: no such function over {MAX_LINES} lines any more"


def test_the_check_can_fail():
    def body(indent):
        return "".join(f"{indent}x{i} = {i}\n" for i in range(85))

    text = (f"class C:\n    def run(self):\n{body(' ' * 8)}\n\n"
            f"# long: a planted reason\ndef g():\n{body(' ' * 4)}")
    assert long_functions(text) == [("C.run", 86, False), ("g", 86, True)]
    short = "def f():\n    return 1\n"
    assert long_functions(short) == []
