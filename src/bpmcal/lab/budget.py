"""Resource guards checked before a specimen is built: ball count, memory, genesis steps.

A tiny ``rmin_mm`` or a large specimen asks for millions of balls; without a guard the
genesis would fill the memory before anything is reported. ``estimate_balls`` predicts
the ball count from the geometry alone (the same volume balance as ``distribute``: the
summed ball volume is (1 - n) V), ``estimate_memory_mb`` the peak memory of a run, and
:func:`check_budget` refuses a run above ``max_balls`` or ``mem_budget_mb`` with a
:class:`BudgetError` (bad input, exit code 2) naming the parameters that drive it.

The genesis step budget (``genesis_max_steps``, total steps of relaxation and settling)
turns a specimen that does not settle (e.g. ``pb_kratio=1e-9``: the timestep collapses)
into a failure record after a bounded time instead of a run of hours.

No numba here: the study's config validation uses it at DAG-parse time.
"""
from __future__ import annotations

import math
import os

from .. import params as P

#: default ceiling on the ball count of one specimen (the paper's full-size specimens
#: hold 12k-70k balls; 2 million balls would take days per UCS test on one core)
MAX_BALLS = 2_000_000
#: default step budget of the settling phases of genesis (``build_specimen``: the
#: material installed, in the vessel, then bonded and free); measured 0-1,000 steps for the
#: smoke study's specimens and 500-1,000 for 24k-ball ones, so 50x headroom. The relaxed
#: packing has its own limit (``SpecimenSpec.max_relax_steps``, 200,000)
GENESIS_MAX_STEPS = 50_000
#: peak memory model of a run [MB] = MEM_BASE_MB + MEM_PER_BALL_KB x balls / 1024. Measured
#: peak RSS (UCS run, 1 thread): 222 MB at 8.6k balls and 266 MB at 23.9k with a warm numba
#: cache (2.9 kB per ball), 364 MB at 1.9k balls when the kernels compiled (cold cache); the
#: model adds headroom on both terms
MEM_BASE_MB = 400.0
MEM_PER_BALL_KB = 4.0


class BudgetError(P.ParameterError):
    """A run would exceed a resource budget (refused before any work)."""


def estimate_balls(rmin_mm: float, porosity: float, *, scale: float = 1.0,
                   diameter_mm: float = 50.0, height_mm: float = 100.0,
                   ratio: float = P.RADIUS_RATIO) -> float:
    """Expected ball count of a cylinder ``scale * diameter_mm`` x ``scale * height_mm``
    with radii uniform in [rmin, ratio rmin] and nominal porosity ``porosity``."""
    r0 = float(rmin_mm)
    r1 = ratio * r0
    mean_r3 = (r1 ** 4 - r0 ** 4) / (4 * (r1 - r0)) if r1 > r0 else r0 ** 3
    mean_v = 4.0 / 3.0 * math.pi * mean_r3
    vol = math.pi * (0.5 * scale * diameter_mm) ** 2 * scale * height_mm
    return (1.0 - float(porosity)) * vol / mean_v


def estimate_memory_mb(n_balls: float) -> float:
    """Expected peak resident memory of one run [MB] (see ``MEM_PER_BALL_KB``)."""
    return MEM_BASE_MB + MEM_PER_BALL_KB * float(n_balls) / 1024.0


def physical_memory_mb() -> float | None:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2 ** 20
    except (ValueError, OSError, AttributeError):
        return None


def default_mem_budget_mb() -> float:
    """80 % of this machine's physical memory (8 GB when it cannot be read)."""
    m = physical_memory_mb()
    return 0.8 * m if m else 8192.0


def budget_problem(rmin_mm, porosity, *, scale=1.0, diameter_mm=50.0, height_mm=100.0,
                   max_balls=MAX_BALLS, mem_budget_mb=None, what="") -> str | None:
    """None if the specimen fits the budgets, else a message naming what drives it."""
    n = estimate_balls(rmin_mm, porosity, scale=scale, diameter_mm=diameter_mm,
                       height_mm=height_mm)
    spec = (f"{what}rmin_mm={float(rmin_mm):g}, porosity={float(porosity):g} on a "
            f"{scale * diameter_mm:g} x {scale * height_mm:g} mm specimen")
    nb = f"{n:,.0f}" if n < 1e12 else f"{n:.3g}"
    if max_balls is not None and n > max_balls:
        return (f"{spec} needs about {nb} balls, more than the budget of {max_balls:,} "
                "(raise --max-balls / resources.max_balls, or a larger rmin_mm / smaller "
                "specimen)")
    if mem_budget_mb is not None:
        mb = estimate_memory_mb(n)
        if mb > mem_budget_mb:
            return (f"{spec} needs about {nb} balls and ~{mb:,.0f} MB of memory, more "
                    f"than the budget of {mem_budget_mb:,.0f} MB (raise --mem-budget-mb / "
                    "resources.dem_mem_mb, or a larger rmin_mm / smaller specimen)")
    return None


def check_budget(params: dict, geometry, *, max_balls=MAX_BALLS, mem_budget_mb=None):
    """Raise :class:`BudgetError` if the specimen of ``params`` (paper units) and
    ``geometry`` (a runner.Geometry) exceeds a budget; ``mem_budget_mb=None`` uses
    :func:`default_mem_budget_mb`."""
    if mem_budget_mb is None:
        mem_budget_mb = default_mem_budget_mb()
    msg = budget_problem(params["rmin_mm"], params["porosity"], scale=geometry.scale,
                         diameter_mm=geometry.diameter_mm, height_mm=geometry.height_mm,
                         max_balls=max_balls, mem_budget_mb=mem_budget_mb)
    if msg:
        raise BudgetError(msg)


# ---- the loading phase of a lab test ---------------------------------------------------
#: a lab test's loading is estimated to run to this many times the card's failure-strain
#: scale (``dem.material.expected_failure_strain``: bond strength over bond modulus), or to
#: the test's ``max_strain`` if that comes first. Generous: a UCS of the paper's cards peaks
#: at about 1-2 times the scale
FAILURE_STRAIN_FACTOR = 10.0


#: a loading that would be cut off by its ``max_steps`` before its estimate is done is
#: refused up front when the steps up to the cut-off take longer than this at this
#: machine's measured speed [s] (shorter ones run: a test may cut a loading short on
#: purpose); ``BPMCAL_LOADING_BUDGET_S`` overrides it
LOADING_BUDGET_S = 600.0
#: ball-steps per second assumed before a run has measured its own speed (``stepping``
#: measures it during genesis): a slow host's single thread
DEFAULT_BALL_STEPS_PER_S = 1.0e6


class StepBudgetError(RuntimeError):
    """A lab test's loading would be cut off by ``max_steps`` long before it is done:
    refused before the loading starts (a run failure: the run file records it with this
    message)."""


def loading_steps(strain_per_step: float, max_strain: float,
                  failure_strain: float | None = None) -> float:
    """Steps a loading needs: to ``FAILURE_STRAIN_FACTOR`` x ``failure_strain`` or to
    ``max_strain``, whichever is smaller, at ``strain_per_step``."""
    target = float(max_strain)
    if failure_strain is not None and failure_strain > 0:
        target = min(target, FAILURE_STRAIN_FACTOR * float(failure_strain))
    return target / float(strain_per_step)


def budget_seconds() -> float:
    """The environment's ``BPMCAL_LOADING_BUDGET_S``, else :data:`LOADING_BUDGET_S`."""
    env = os.environ.get("BPMCAL_LOADING_BUDGET_S")
    if not env:
        return LOADING_BUDGET_S
    try:
        v = float(env)
    except ValueError:
        v = math.nan
    if not v >= 0:
        raise P.ParameterError(f"BPMCAL_LOADING_BUDGET_S={env!r}: expected a number of "
                               "seconds >= 0")
    return v


def check_loading_steps(test: str, *, strain_per_step: float, max_strain: float,
                        max_steps: int, dt: float, loading: str, spring: str, n_balls: int,
                        ball_steps_per_s: float | None,
                        failure_strain: float | None = None) -> int:
    """The loading's estimated steps (:func:`loading_steps`, rounded up). When they exceed
    ``max_steps`` (the loading would be cut off before it is done) and the steps up to the
    cut-off take longer than :func:`budget_seconds` at ``ball_steps_per_s`` (default
    :data:`DEFAULT_BALL_STEPS_PER_S`), a :class:`StepBudgetError` naming the timestep's
    cause (``spring``, the card's property that makes the stiffest spring) and the loading
    (``loading``, e.g. the platen velocity)."""
    est = loading_steps(strain_per_step, max_strain, failure_strain)
    rate = ball_steps_per_s or DEFAULT_BALL_STEPS_PER_S
    cut_s = min(est, max_steps) * max(n_balls, 1) / rate
    if not est <= max_steps and not cut_s <= budget_seconds():
        target = est * strain_per_step
        raise StepBudgetError(
            f"{test}: the loading would need about {est:.3g} steps (strain {target:.3g} at "
            f"{strain_per_step:.3g} per step: {loading}, timestep {dt:.3g} s), more than "
            f"max_steps = {int(max_steps)}, and would be cut off after about "
            f"{cut_s / 60:.0f} min; the timestep is set by {spring}. Refused before "
            "loading: change that property, load faster, or raise max_steps")
    return int(math.ceil(est))
