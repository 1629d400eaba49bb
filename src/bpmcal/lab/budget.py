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
from dataclasses import dataclass

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
    if not 1e-30 < r0 < 1e30:  # beyond the powers' range: the same balance in logarithms
        return _estimate_balls_log(r0, float(porosity), scale * diameter_mm,
                                   scale * height_mm, ratio)
    r1 = ratio * r0
    mean_r3 = (r1 ** 4 - r0 ** 4) / (4 * (r1 - r0)) if r1 > r0 else r0 ** 3
    mean_v = 4.0 / 3.0 * math.pi * mean_r3
    vol = math.pi * (0.5 * scale * diameter_mm) ** 2 * scale * height_mm
    return (1.0 - float(porosity)) * vol / mean_v


def _estimate_balls_log(r0: float, porosity: float, d: float, h: float, ratio: float) -> float:
    """:func:`estimate_balls` for an extreme ``r0`` (1e-100 or 1e300 mm): inf or 0 where
    the count leaves the floats, never an overflow or a division by zero."""
    if not (r0 > 0 and d > 0 and h > 0) or not porosity < 1:
        return 0.0 if r0 > 0 else math.inf
    f = (ratio ** 4 - 1.0) / (4.0 * (ratio - 1.0)) if ratio > 1 else 1.0
    ln = (math.log(1.0 - porosity) + 2.0 * math.log(0.5 * d) + math.log(h) - 3.0 * math.log(r0)
          + math.log(0.75 / f))
    return math.inf if ln > 700 else math.exp(ln)


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
    msg = budget_problem(params[P.RMIN], params[P.POROSITY], scale=geometry.scale,
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


#: a loading is hopeless when its cut-off at ``max_steps`` comes before this fraction of
#: the card's failure-strain scale (``dem.material.expected_failure_strain``): no UCS of the
#: default study's 150 cards peaked before 0.55 x its scale, no Brazilian test before
#: 1.27 x (the platens' approach over D), no UCS of a flat-joint study's 40 before 1.86 x
#: and no direct-tension test before 0.52 x its tensile scale; record
#: ``docs/measurements/2026-11-27d-extreme-inputs.md``
REACH_FRACTION = 0.25
#: a hopeless loading is refused when its steps to the cut-off would take longer than this
#: [s] (or ``BPMCAL_LOADING_BUDGET_S`` if that is shorter); shorter ones run, as a test
#: that cuts a loading short on purpose does
HOPELESS_S = 10.0


@dataclass(frozen=True)
class Loading:
    """How a lab test loads its body: each of two ``loaders`` moves at ``velocity`` [m/s]
    along a body of ``length`` [m] (strain per step 2 v dt / L). ``setting`` names the
    setting that gives the velocity and ``default`` that setting's default velocity [m/s]
    (a refusal names the velocity when it, not the timestep, makes the loading long)."""
    test: str
    velocity: float
    length: float
    setting: str
    default: float
    loaders: str = "platens"
    body: str = "specimen"
    tension: bool = False  # pulled apart: the card's tensile failure strain applies

    def describe(self) -> str:
        return (f"{self.loaders} at {self.velocity:g} m/s each on a {self.length * 1e3:.3g} mm "
                f"{self.body}")


def timestep_bound(material, rmin: float, density: float = P.DENSITY,
                   ratio: float = P.RADIUS_RATIO) -> float:
    """An upper bound [s] of the timestep a specimen of ``material`` with radii in
    [``rmin``, ``ratio`` x ``rmin``] [m] gets, known before it is built: sqrt(m/k) of a
    ball of radius ``rmin`` whose only spring is the stiffest single spring of one contact
    with the largest neighbour (k = E pi (lambda rmin)^2 / ((1 + ratio) rmin), E the
    largest of each spring set's E* and E*/kappa*). A packed ball has several contacts,
    each with a linear spring and a bond (or flat joint), and rotation; the timestep is
    0.8 x the smallest ball's: the real one is several times smaller (a test compares
    the two on built specimens)."""
    k_per_m = max(float(getattr(material, e)) * max(1.0, 1.0 / float(getattr(material, k)))
                  * float(lam) ** 2 for e, k, _, lam in material.springs())
    r = float(rmin)
    mass = density * 4.0 / 3.0 * math.pi * r ** 3
    k = k_per_m * math.pi * r * r / ((1.0 + ratio) * r)
    return math.sqrt(mass / k)


def _cause(loading: Loading, est: float, max_steps: int, spring: str) -> str:
    """What makes a loading long: its velocity when the default one would fit
    ``max_steps``, else the spring that sets the timestep."""
    v, d = loading.velocity, loading.default
    if d and v < d and est * v / d <= max_steps:
        return (f"the loading is slow: {loading.setting} gives {v:g} m/s, against the "
                f"default {d:g} m/s (which would need about {est * v / d:.3g} steps); "
                "load faster or raise max_steps")
    return (f"the timestep is set by {spring}; change that property, load faster, or "
            "raise max_steps")


def screen_loading(loading: Loading, material, rmin: float, *, max_strain: float,
                   max_steps: int, n_balls: float, spring: str,
                   failure_strain: float | None, density: float = P.DENSITY) -> None:
    """Refuse, before the specimen is built, a loading that cannot reach the card's
    failure: a :class:`BudgetError` (bad input) when ``max_strain`` comes before
    :data:`REACH_FRACTION` of ``failure_strain`` (the run could only end incomplete), or
    when even at :func:`timestep_bound` the cut-off at ``max_steps`` comes before it and
    the steps to it (``n_balls`` balls at :data:`DEFAULT_BALL_STEPS_PER_S`) would take
    longer than :data:`HOPELESS_S`. The message names the cause: the velocity, or
    ``spring`` (``dem.material.stiffest_spring``: the property that sets the timestep)."""
    if not failure_strain or failure_strain <= 0:
        return
    need = REACH_FRACTION * float(failure_strain)
    if float(max_strain) < need:  # stopped before any test peaks, however fast it runs
        raise BudgetError(
            f"{loading.test}: max_strain = {float(max_strain):g} stops the loading before the "
            f"card can fail: it fails at about {failure_strain:.3g} (its bonds' "
            f"{'tensile ' if loading.tension else ''}strength over modulus) and no test "
            f"peaked before {REACH_FRACTION:g} of that; raise max_strain. Refused before "
            "building the specimen")
    dt = timestep_bound(material, rmin, density)
    per_step = 2.0 * loading.velocity * dt / loading.length
    reach = per_step * max_steps
    cut_s = max_steps * max(float(n_balls), 1.0) / DEFAULT_BALL_STEPS_PER_S
    if reach >= need or cut_s <= min(HOPELESS_S, budget_seconds()):
        return
    est = loading_steps(per_step, max_strain, failure_strain)
    raise BudgetError(
        f"{loading.test}: the loading cannot reach the card's failure: at most "
        f"{reach:.3g} strain within max_steps = {int(max_steps)} ({loading.describe()}, "
        f"timestep at most {dt:.3g} s), where the card fails at about {failure_strain:.3g}"
        f" (its bonds' {'tensile ' if loading.tension else ''}strength over modulus); "
        f"{_cause(loading, est, max_steps, spring)}."
        " Refused before building the specimen")


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


def platen_loading(test: str, settings, length: float, *, field: str = "platen_velocity",
                   loaders: str = "platens", body: str = "specimen",
                   tension: bool = False) -> Loading:
    """The :class:`Loading` of a test whose ``settings`` give each loader's velocity in
    ``field`` (or, if they have one that is set, a ``strain_rate``: each loader then
    moves at rate x ``length`` / 2) on a body of ``length`` [m]."""
    default = type(settings).__dataclass_fields__[field].default
    rate = getattr(settings, "strain_rate", None)
    if rate is not None:
        return Loading(test, 0.5 * float(rate) * length, length,
                       f"strain_rate = {float(rate):g} /s", default, loaders, body, tension)
    return Loading(test, float(getattr(settings, field)), length, field, default, loaders,
                   body, tension)


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"


def check_loading_steps(loading: Loading, *, dt: float, max_strain: float, max_steps: int,
                        spring: str, n_balls: int, ball_steps_per_s: float | None,
                        failure_strain: float | None = None) -> int:
    """The estimated steps of ``loading`` at timestep ``dt`` (:func:`loading_steps`,
    rounded up). When they exceed ``max_steps`` (the loading would be cut off before it is
    done), a :class:`StepBudgetError` if the steps up to the cut-off take longer than
    :func:`budget_seconds` at ``ball_steps_per_s`` (default
    :data:`DEFAULT_BALL_STEPS_PER_S`), or longer than :data:`HOPELESS_S` when the cut-off
    comes before :data:`REACH_FRACTION` of ``failure_strain`` (no peak is possible). The
    message names the cause: the velocity, or ``spring`` (the card's property that makes
    the stiffest spring)."""
    per_step = 2.0 * loading.velocity * dt / loading.length
    est = loading_steps(per_step, max_strain, failure_strain)
    if est <= max_steps:
        return int(math.ceil(est))
    rate = ball_steps_per_s or DEFAULT_BALL_STEPS_PER_S
    cut_s = max_steps * max(n_balls, 1) / rate
    budget = budget_seconds()
    hopeless = bool(failure_strain) and per_step * max_steps < REACH_FRACTION * failure_strain
    if cut_s > budget or (hopeless and cut_s > min(HOPELESS_S, budget)):
        target = est * per_step
        reach = (f"; it would reach {per_step * max_steps:.3g}, before the card fails (about "
                 f"{failure_strain:.3g})" if hopeless else "")
        raise StepBudgetError(
            f"{loading.test}: the loading would need about {est:.3g} steps (strain "
            f"{target:.3g} at {per_step:.3g} per step: {loading.describe()}, timestep "
            f"{dt:.3g} s), more than max_steps = {int(max_steps)}, and would be cut off "
            f"after about {_duration(cut_s)}{reach}; {_cause(loading, est, max_steps, spring)}"
            ". Refused before loading")
    return int(math.ceil(est))
