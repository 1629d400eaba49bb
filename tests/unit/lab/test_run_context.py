"""RunContext (bpmcal.lab.run_context): how a DEM job runs - the packing cache, threads,
the budgets and the progress sink - as one value, checked once where it is built and
passed whole from the command to where the lab runner takes its values."""
import dataclasses
import math

import pytest

from bpmcal.cli import build_parser
from bpmcal.cli.options import run_context
from bpmcal.io.checks import BadInput
from bpmcal.lab.budget import GENESIS_MAX_STEPS, MAX_BALLS, BudgetError
from bpmcal.lab.run_context import RunContext
from bpmcal.lab.runner import Geometry

A1 = {"rmin_mm": 0.8, "porosity": 0.34, "pb_emod_GPa": 20.0, "pb_kratio": 2.0,
      "pb_ten_MPa": 30.0, "pb_coh_MPa": 30.0, "pb_fa_deg": 35.0, "fric": 0.35}


def test_the_defaults_are_the_commands():
    c = RunContext()
    assert (c.cache, c.threads, c.max_balls, c.mem_budget_mb, c.genesis_max_steps,
            c.progress) == (None, None, MAX_BALLS, None, GENESIS_MAX_STEPS, None)
    a = build_parser(only="ucs").parse_args(["ucs", "--params", "p.yaml", "--out", "o.h5"])
    assert run_context(a) == c


@pytest.mark.parametrize("field, bad", [
    ("cache", 3), ("cache", True), ("threads", 0), ("threads", 4097), ("threads", 2.0),
    ("threads", True), ("max_balls", 0), ("max_balls", 1.5), ("mem_budget_mb", 0),
    ("mem_budget_mb", math.inf), ("mem_budget_mb", True), ("genesis_max_steps", 999),
    ("genesis_max_steps", 5e4), ("progress", "stderr")])
def test_a_bad_value_is_refused_naming_it(field, bad):
    with pytest.raises(BadInput, match=f"^{field}={bad!r}: expected "):
        RunContext(**{field: bad})


def test_the_lab_runner_gets_its_values_and_a_pool_run_its_own_threads():
    seen = []
    c = RunContext(cache="/tmp/x", threads=4, genesis_max_steps=2000, progress=seen.append)
    assert c.lab_kw() == {"cache": "/tmp/x", "threads": 4, "progress": seen.append,
                          "genesis_max_steps": 2000}
    run = c.with_run(1, None)
    assert (run.threads, run.progress, run.cache, run.genesis_max_steps) == (1, None, "/tmp/x", 2000)
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.threads = 2


def test_the_budget_is_checked_for_every_specimen_and_not_without_one():
    big = Geometry(scale=10.0)
    RunContext().check_budget(A1, Geometry(scale=0.3))
    with pytest.raises(BudgetError, match="more than the budget of 1,000"):
        RunContext(max_balls=1000).check_budget(A1, Geometry(scale=0.3), big)
    with pytest.raises(BudgetError, match="MB of memory"):
        RunContext(mem_budget_mb=1.0).check_budget(A1, Geometry(scale=0.3))
    RunContext(max_balls=None, mem_budget_mb=1.0).check_budget(A1, big)  # no budget check
