"""The stages that measure a card on the DEM (the closed loop, the transfer, the seed
scatter, the fresh-seed check, the posterior's refinement) run every test through
``stages.measure.RUNNERS``, looked up at the call: tests replace the DEM there. A module
of those stages that calls or imports a runner of ``stages.runs`` itself would run the
real DEM in a test that replaced it (or fail only with the DEM's cost), so this scan of
their sources fails on any use of a runner's name outside ``RUNNERS``' definition."""
import ast
from pathlib import Path

import pytest

from bpmcal.stages import measure

STAGES = Path(__file__).resolve().parents[2] / "src" / "bpmcal" / "stages"

#: the modules whose DEM runs go through RUNNERS
MEASURING = ["measure.py", "loop_runs.py", "verification.py", "transfer.py",
             "seed_scatter.py", "fresh_seeds.py", "posterior.py"]

#: the runners of stages.runs that RUNNERS holds
RUNNER_NAMES = {"run_ucs_file", "run_bts_file", "run_dtt_file", "run_triaxial_file"}


def runner_uses(text: str, imports: bool = True) -> list[str]:
    """``line N: name`` for every use of a runner's name in ``text`` (a name or an
    attribute; with ``imports``, an imported name too) but inside the assignment of
    ``RUNNERS``, in the order of the lines."""
    tree = ast.parse(text)
    inside = {id(n) for node in tree.body if isinstance(node, ast.Assign)
              and any(getattr(t, "id", None) == "RUNNERS" for t in node.targets)
              for n in ast.walk(node)}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and imports:
            out += [(node.lineno, f"import {a.name}") for a in node.names
                    if a.name in RUNNER_NAMES]
        name = (node.id if isinstance(node, ast.Name) else
                node.attr if isinstance(node, ast.Attribute) else None)
        if name in RUNNER_NAMES and id(node) not in inside:
            out.append((node.lineno, name))
    return [f"line {n}: {what}" for n, what in sorted(out)]


def test_runners_hold_every_test_the_stages_run():
    from bpmcal.stages import runs

    assert measure.RUNNERS == {"ucs": runs.run_ucs_file, "bts": runs.run_bts_file,
                               "dtt": runs.run_dtt_file, "tri": runs.run_triaxial_file}


def test_the_scan_finds_a_direct_call_and_an_import():
    text = ("from .runs import run_bts_file, write_failure\n"
            "RUNNERS = {'bts': run_bts_file}\n"
            "def f():\n    return run_ucs_file(1) + runs.run_dtt_file(2)\n")
    assert runner_uses(text) == ["line 1: import run_bts_file", "line 4: run_dtt_file",
                                 "line 4: run_ucs_file"]
    assert runner_uses(text, imports=False) == ["line 4: run_dtt_file", "line 4: run_ucs_file"]


@pytest.mark.parametrize("name", MEASURING)
def test_a_measuring_stage_runs_the_dem_through_runners_only(name):
    """measure.py imports the runners to fill RUNNERS; no other use anywhere."""
    bad = runner_uses((STAGES / name).read_text(), imports=name != "measure.py")
    assert not bad, (f"stages/{name} uses a DEM runner outside measure.RUNNERS: "
                     f"{', '.join(bad)}; call RUNNERS[test] instead")
