"""How a DEM job runs, not what it measures: :class:`RunContext`.

A stage that runs the DEM (``bpmcal verify``, ``transfer``, ``fresh-seeds``, ``scatter``,
``posterior``, ``predictive``, the lab commands) takes one ``RunContext``, built once by
the command from its options (``bpmcal.cli.options.run_context``) and passed whole down to
where the lab runner takes its values (:meth:`RunContext.lab_kw`): the packing cache,
the numba threads (a stage that runs several seeds side by side takes them as CPUs:
``bpmcal.stages.pool``), the resource budgets checked before any work
(:meth:`RunContext.check_budget`) and the progress sink. None of them changes a
result: the same inputs give the same run files whatever the context (the genesis step
budget only turns a specimen that does not settle into a failure record sooner).
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, replace

from ..io.checks import BadInput
from .budget import GENESIS_MAX_STEPS, MAX_BALLS, check_budget

#: the most numba threads (or CPUs of a stage) a run may ask for (``bpmcal --threads``)
MAX_THREADS = 4096
#: the smallest genesis step budget (``--genesis-max-steps``): a specimen of the smoke
#: study settles in up to 1,000 steps (``lab.budget.GENESIS_MAX_STEPS``)
MIN_GENESIS_STEPS = 1000


def _whole(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


@dataclass(frozen=True)
class RunContext:
    """How a DEM job runs (module docs). ``cache``: the folder of relaxed packings (None:
    ``~/.cache/bpmcal/packings`` or ``$BPMCAL_SPECIMEN_CACHE``); ``threads``: numba threads
    of a run, or the CPUs of a stage that runs several (None: each run chooses);
    ``max_balls``: refuse a specimen estimated to hold more balls (None: no budget check
    at all); ``mem_budget_mb``: refuse a run estimated to need more memory [MB] (None: 80 %
    of this machine's); ``genesis_max_steps``: a specimen that has not settled after this
    many steps is a failed run (None: no limit); ``progress``: the callable that receives
    a run's progress records and notes (None: none). The defaults are the ``bpmcal``
    command's (and so the study's)."""

    cache: str | os.PathLike | None = None
    threads: int | None = None
    max_balls: int | None = MAX_BALLS
    mem_budget_mb: float | None = None
    genesis_max_steps: int | None = GENESIS_MAX_STEPS
    progress: Callable[[dict], None] | None = None

    def __post_init__(self):
        if self.cache is not None and (isinstance(self.cache, bool)
                                       or not isinstance(self.cache, (str, os.PathLike))):
            raise BadInput(f"cache={self.cache!r}: expected the folder of cached packings "
                           "(a path), or None")
        if self.threads is not None and not (_whole(self.threads)
                                             and 1 <= self.threads <= MAX_THREADS):
            raise BadInput(f"threads={self.threads!r}: expected an integer in 1 .. "
                           f"{MAX_THREADS} (numba threads, or a stage's CPUs), or None")
        if self.max_balls is not None and not (_whole(self.max_balls) and self.max_balls >= 1):
            raise BadInput(f"max_balls={self.max_balls!r}: expected an integer >= 1 (the most "
                           "balls of a specimen), or None (no budget check)")
        mb = self.mem_budget_mb
        if mb is not None and (isinstance(mb, bool) or not isinstance(mb, (int, float))
                               or not (math.isfinite(mb) and mb > 0)):
            raise BadInput(f"mem_budget_mb={mb!r}: expected a number of MB > 0, or None "
                           "(80 % of this machine's memory)")
        steps = self.genesis_max_steps
        if steps is not None and not (_whole(steps) and steps >= MIN_GENESIS_STEPS):
            raise BadInput(f"genesis_max_steps={steps!r}: expected an integer >= "
                           f"{MIN_GENESIS_STEPS} (the genesis's step budget), or None")
        if self.progress is not None and not callable(self.progress):
            raise BadInput(f"progress={self.progress!r}: expected a callable (a record -> "
                           "None), or None")

    def lab_kw(self) -> dict:
        """The lab runner's keywords (``lab.runner.ucs_test`` ..., ``stages.runs.run_*_file``):
        cache, threads, progress and the genesis step budget."""
        return {"cache": self.cache, "threads": self.threads, "progress": self.progress,
                "genesis_max_steps": self.genesis_max_steps}

    def check_budget(self, params: dict, *geometries) -> None:
        """Refuse (``lab.budget.BudgetError``, before any work) a specimen of ``params``
        of any of ``geometries`` over the ball or memory budget; no check with
        ``max_balls`` None."""
        if self.max_balls is None:
            return
        for g in geometries:
            check_budget(params, g, max_balls=self.max_balls, mem_budget_mb=self.mem_budget_mb)

    def with_run(self, threads: int | None, progress) -> "RunContext":
        """This context for one run of a stage's pool: its own threads and progress."""
        return replace(self, threads=threads, progress=progress)
