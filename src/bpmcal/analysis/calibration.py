"""Calibration of the meso-parameters from laboratory targets (paper section 4.2):
inversion of the regression models, bootstrap uncertainty and a closed-loop corrector.

Parametrisation (shared by everything here)
    The parameters of a calibration are split into *fixed* ones (paper: ``porosity`` 0.34,
    ``rmin_mm`` 0.8, ``pb_fa_deg`` and ``fric`` at configured values), *free* ones (default
    ``pb_emod_GPa``, ``pb_kratio``, ``pb_coh_MPa``) and, with a bond-strength ratio
    ``a = σcp/τcp`` (``ratio``, default 1.4 as in the paper; ``None`` = both strengths
    free), the *derived* ``pb_ten_MPa = ratio × pb_coh_MPa``. Free parameters are bounded
    by ``ranges``, the design space the dataset was sampled over (the study config's
    ``ranges``; a regression is not valid outside it, so there are no default bounds),
    optionally narrowed by ``bounds`` (bounds wider than ``ranges`` are an error, as is a
    fixed value outside its range). With the ratio the bounds of ``pb_coh_MPa`` are
    intersected with those of ``pb_ten_MPa`` divided by the ratio (for the paper's Table 2
    ranges and a = 1.4: 10-35.71 MPa), so the derived value stays in its range too. Every
    effective bound remembers the configured key it comes from, so a message can say
    "pb_coh_MPa at the upper bound 35.7 (= upper bound 50 of ranges.pb_ten_MPa / ratio 1.4)".
    Internally the free parameters are mapped to the unit cube ``u = (x - lo) / (hi - lo)``.

Inversion (:func:`invert`)
    Minimise Σ_k r_k² with relative residuals ``r_k = (model_k(x) - target_k) / |target_k|``
    over the bounded free parameters (``scipy.optimize.least_squares``, method ``trf``,
    analytic Jacobian from the models' partial derivatives), from a seeded Latin-hypercube
    set of starting points (plus any given ``x0``). Outcomes (``status``):

    ``"ok"``           max |r_k| <= ``tol`` (default 1e-3) and a single solution;
    ``"non-unique"``   several solutions, more than ``distinct`` (default 2 %) of a range apart
                       in some free parameter, fit within ``tol`` (all listed in
                       ``alternatives``; with more free parameters than targets there is a
                       continuum and the list samples it);
    ``"unreachable"``  the best fit has residuals above ``tol`` with a parameter on a bound:
                       the targets lie outside what the sampled ranges can reach. The
                       returned point is the closest one inside the bounds and is *not* a
                       calibration (``ok`` is False, ``message`` says which bound of which
                       configured range stops it);
    ``"no-exact-fit"`` residuals above ``tol`` at an interior optimum (the models cannot meet
                       all targets at once, e.g. more targets than free parameters).

    What to widen: for the last two outcomes the regression is extrapolated into a box 2,
    then 5, then 20 range widths wider on each side (inside each parameter's physical
    domain) until some point meets the targets; among the
    points that meet the targets there, the one least outside the configured limits names
    every configured key to widen (``ranges.<p>`` or ``calibration.bounds.<p>``) and the value
    it must reach (``widen``, ``advice``). If even the extrapolated models cannot meet every
    target, their best compromise is used instead: the keys to widen to reach it, and what it
    still misses (which may need another free parameter or other fixed values); if that
    compromise lies inside the configured limits, an ``unreachable`` card names the limits
    that stop the fit without a value and a ``no-exact-fit`` card says that with these models
    widening does not help. All these values are indicative: the regression is not validated
    outside the sampled space.

    Multi-start finds separate solutions only if some start lies in each basin; 24 starts
    are ample for the low-order polynomials of the stepwise models.

Tensile strength (σt, ``bts_MPa``)
    A Brazilian tensile strength among the targets (a ``bts_MPa`` model must exist) is
    matched like any other target. :func:`bts_strengths` frees the bond-strength ratio for
    it: ``pb_ten_MPa`` becomes a free parameter beside ``pb_coh_MPa`` (``ratio`` None), so
    σt, not a configured ratio or the crack-share criterion of the ratio sweep, sets
    ``a = pb_ten / pb_coh``. The parallel-bond model reaches only a limited σc/σt (about
    4-8 in Potyondy & Cundall 2004, where rocks show 10-20), so a target set may be out of
    reach even though every target alone is not. When the fit misses (some |r_k| > tol)
    and the targets *without* σt are met together by parameter sets inside the bounds,
    the status is ``"no-exact-fit"`` (never ``"unreachable"``: the card is still a
    calibration, of the best compromise) and ``reach`` gives the σt interval, and the
    σc/σt interval, that the models span while they meet the other targets exactly
    (:func:`_bts_reach`: the smallest and largest σt over that solution set, SLSQP with the
    other targets as equality constraints, multi-start). The compromise is the minimum of
    the objective every inversion minimises, Σ_k r_k² with equal weights on the relative
    residuals (the closed loop's Gauss-Newton step minimises the same sum), so the miss is
    shared between σt and the targets that pull against it; ``missed`` lists every target
    with |r_k| > tol, its value, the predicted value and the error in %. No target is
    dropped: every target stays in the sum and in ``missed``.

Bootstrap (:func:`bootstrap_intervals`)
    Case resampling of the usable dataset rows (n rows drawn with replacement, ``n_boot``
    times, seeded). In each resample every model is refitted by least squares *with the
    terms selected on the full data* (model-selection uncertainty is then not included;
    pass ``reselect=StepwiseRegression(...)`` and ``candidates`` to re-run the selection in
    each resample instead), and the targets are inverted again, warm-started from the
    full-data solution (so a resample follows the same branch when the inversion is
    non-unique). Percentile intervals (default 2.5-97.5 %) are reported for every
    calibrated (free and derived) parameter over the resamples whose inversion reached the
    targets, and for every response the model predicts at the full-data solution (the
    regression uncertainty of the predicted responses).

Closed loop (:class:`ClosedLoop`)
    The regression models only approximate the DEM, so their solution is corrected with the
    DEM itself. A DEM response also scatters with the packing seed (a CV of 1.5-3 % for σc
    at the default specimen size), so every round runs the candidate on the same ``k``
    packing seeds (``seeds_per_round``, default 3; ``seeds``, default 1..k) and steers the
    *mean*. Each round: ``simulate(params, seed=s)`` for every seed → the mean ``ȳ_k`` and
    its relative errors ``e_k = (ȳ_k - t_k) / |t_k|`` → stop if every
    ``|e_k| <= max(rtol_k, z · SE_k)`` (the *convergence rule*; ``rtol`` default 0.01,
    ``z`` default 2), where ``SE_k = CV_k / sqrt(k)`` is the relative standard error of the
    mean and ``CV_k`` the seed coefficient of variation pooled over all rounds so far
    (``sqrt(Σ (k-1) cv²_round / Σ (k-1))``; the scatter hardly changes between nearby
    parameter sets, and three seeds alone give a poor estimate): a mean within ``z``
    standard errors of the target cannot be told apart from it, and chasing it further
    would fit the packings, not the rock. Otherwise a damped Newton step in the unit-cube
    coordinates, ``Δu = -damping · J⁺ e`` (``J⁺`` the pseudo-inverse; damping default 0.8),
    shortened so that no parameter moves by more than ``max_step`` (default 0.25) of its
    range, then projected onto the bounds (the ratio constraint holds by construction).
    The initial Jacobian ``J`` of the relative errors is the regression models' analytic
    Jacobian at the starting point; after each new round it is corrected by Broyden's
    ("good") secant update ``J += (Δe - J s) sᵀ / (sᵀ s)`` with the step ``s`` actually
    taken. The same seeds in every round (common random numbers) keep the packing scatter
    out of the differences between rounds, which the secant update needs. The responses
    are known to different precision (σt of a Brazilian disc scatters ~8 % between
    packings, E ~1 %): the step weighs each relative error by 1/tolerance, and a step that
    would leave the cap is a Levenberg-Marquardt step (the weighted residuals set its
    direction) rather than a shortened Gauss-Newton step, so a poorly conditioned pair of
    parameters (the two bond strengths, against σc and σt) is not swung across its range to
    chase a response known only to its scatter. A trust region keeps the steps honest: the
    merit of a round is ``Σ (e_k / tol_k)²``; a round worse than the best so far is not
    stepped from - the next step starts again from the best round, capped at half the
    rejected step (``accepted`` false, ``step_cap``) - so a Jacobian that points the wrong
    way shrinks its steps instead of swinging the parameters between the bounds. A parameter at a
    bound whose step points out of the box is held there and the step is solved again for
    the others (an active-set Gauss-Newton step), so the other parameters do not chase a
    move that cannot happen; a step cut at the bounds is recorded (``clipped``). A
    parameter held at a bound for two rounds while the loop misses is probed: the next step
    moves it half the cap into the box (``probed``), because Broyden learns the Jacobian
    only along the steps taken, and a column never stepped along keeps the regression's
    sign (which is what held it there).

    The mean of a fixed set of k seeds is itself off the rock's (population) mean by about
    ``CV / sqrt(k)``: a loop that steers three packings fits those three, and fresh packings
    of the final card scatter around a point up to ~2 CV/sqrt(3) from the target. So the
    seed set can grow (``max_seeds``, default k: no growth): when every mean is within
    tolerance but a standard error is still too large to state the target to ``rtol``
    (``z · SE_k > rtol_k``), the round's point is also run on new seeds (the next integers
    after the largest seed) up to ``max_seeds``, and the rule is judged again on the mean
    of all of them; if it no longer holds, the loop steps on, every later round running the
    grown set. The grown round keeps its row, with its ``n_seeds`` and ``grown`` (seeds
    added). Every round (parameters, mean responses, seed CV, standard error, tolerance
    used, k, errors, step) and every single run (``samples``) is recorded. A simulator ``simulate(params)``
    without a ``seed`` argument is a single-seed simulator: k = 1, SE = 0, and the rule is
    ``|e_k| <= rtol_k`` (the loop before seed averaging). :func:`seed_scatter` judges
    whether a tolerance is meaningful given the packing-seed scatter of the DEM responses.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares
from scipy.stats import qmc

from bpmcal.params import PARAMS, TARGETS, TENSILE_TESTS, ParameterError, validate_params

from ._common import check_params, check_responses, seed_from, usable_rows
from .stepwise import RegressionModel, StepwiseRegression

PAPER_RATIO = 1.4
PAPER_FIXED: dict[str, float] = {"porosity": 0.34, "rmin_mm": 0.8}
DEFAULT_FREE: tuple[str, ...] = ("pb_emod_GPa", "pb_kratio", "pb_coh_MPa")
_TEN, _COH = "pb_ten_MPa", "pb_coh_MPa"
BTS = "bts_MPa"  # the Brazilian tensile strength response
#: the tensile strengths a card can be calibrated against (Brazilian, direct tension)
TENSILE = tuple(TENSILE_TESTS)


def tensile_target(targets) -> str | None:
    """The tensile strength among ``targets`` (the first of :data:`TENSILE`), or None."""
    return next((r for r in TENSILE if r in targets), None)
_EDGE = 1e-6  # |u| or |1 - u| below this counts as "on the bound"
_EXTEND = (2.0, 5.0, 20.0)  # range widths added on each side, in turn, for the "what to widen" search


# -- parametrisation ------------------------------------------------------------------------
def _default_free(free: Sequence[str] | None, ratio: float | None) -> tuple[str, ...]:
    if free is not None:
        return tuple(free)
    return DEFAULT_FREE if ratio is not None else DEFAULT_FREE + (_TEN,)


def bts_strengths(targets: Mapping[str, float], free: Sequence[str] | None, fixed: Mapping[str, float],
                  ratio: float | None) -> tuple[tuple[str, ...] | None, float | None, str]:
    """The free parameters and ratio of a calibration against ``targets``: with a tensile
    strength target (``bts_MPa`` or ``dtt_MPa``) σt sets the bond-strength ratio, so
    ``pb_ten_MPa`` is freed beside ``pb_coh_MPa`` and the ratio is None; without it
    ``free`` and ``ratio`` are returned unchanged. The third value says where the ratio
    comes from: the tensile response, or ``"ratio"`` (the given one: configured, or the
    ratio sweep's choice). ``pb_ten_MPa`` fixed by the user keeps σt a plain target
    (``"ratio"``)."""
    tr = tensile_target(targets)
    if tr is None or _TEN in fixed:
        return (tuple(free) if free is not None else None), ratio, "ratio"
    base = tuple(free) if free is not None else DEFAULT_FREE
    if _TEN not in base:
        base = base + (_TEN,)
    return base, None, tr


class _Space:
    """Free parameters <-> unit cube, with fixed values and the strength-ratio constraint.

    ``ranges``: the design space (the sampled ranges, paper units) of every free parameter,
    of ``pb_ten_MPa`` when it is derived, and of any fixed parameter that should be checked;
    ``bounds``: optional narrower limits of free (or derived) parameters. Every effective
    bound remembers which configured range it comes from (:meth:`edge_text`).
    """

    def __init__(self, free, fixed: Mapping[str, float], ratio: float | None,
                 ranges: Mapping[str, Sequence[float]], bounds: Mapping[str, Sequence[float]] | None):
        if ratio is not None:
            ratio = float(ratio)
            if not (math.isfinite(ratio) and ratio > 0):
                raise ParameterError(f"ratio={ratio!r}: expected a positive number σcp/τcp (or None)")
        self.ratio = ratio
        self.free = check_params(_default_free(free, ratio), "free parameter")
        if not self.free:
            raise ParameterError("no free parameter: expected at least one name in free")
        self.fixed = validate_params(dict(fixed), require_all=False)
        both = sorted(set(self.free) & set(self.fixed))
        if both:
            raise ParameterError(f"parameter(s) {both} are both free and fixed")
        if ratio is not None:
            if _TEN in self.free or _TEN in self.fixed:
                raise ParameterError(f"{_TEN} is derived as ratio × {_COH} (ratio={ratio:g}); remove it from "
                                     "free/fixed or pass ratio=None")
            if _COH not in self.free and _COH not in self.fixed:
                raise ParameterError(f"the strength ratio needs {_COH} to be free or fixed")
        self.ranges = _check_ranges(ranges)
        needed = list(self.free) + ([_TEN] if ratio is not None else [])
        missing = [p for p in needed if p not in self.ranges]
        if missing:
            raise ParameterError(f"ranges lacks {missing}: the sampled range (design space) of every free "
                                 "parameter" + (f" and of the derived {_TEN}" if ratio is not None else "")
                                 + " is needed; the regression is valid only there")
        for p in needed:
            lo, hi = self.ranges[p]
            if not lo < hi:
                raise ParameterError(f"ranges.{p}=[{lo:g}, {hi:g}] has no width: {p} was not sampled, so it "
                                     "cannot be calibrated (fix it instead)")
        for p, v in self.fixed.items():
            if p in self.ranges and not _inside(v, *self.ranges[p]):
                lo, hi = self.ranges[p]
                raise ParameterError(f"fixed {p}={v:g} is outside ranges.{p}=[{lo:g}, {hi:g}], the sampled "
                                     "space (the regression is not valid there): fix a value inside it, or "
                                     f"widen ranges.{p} and rerun the design")
        # box: the configured limits of every calibrated parameter; origin: where each side comes from
        box = {p: self.ranges[p] for p in needed}
        origin = {p: {s: (f"ranges.{p}", None) for s in ("lower", "upper")} for p in needed}
        for name, b in (bounds or {}).items():
            check_params([name], "bounded parameter")
            try:
                lo, hi = (float(v) for v in b)
            except (TypeError, ValueError):
                raise ParameterError(f"calibration.bounds.{name}={b!r}: expected [lo, hi]") from None
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ParameterError(f"calibration.bounds.{name}={list(b)!r}: expected finite [lo, hi] "
                                     "with lo < hi")
            if name not in needed:
                derived = f", derived: {_TEN}" if ratio is not None else ""
                raise ParameterError(f"calibration.bounds.{name}: {name} is not calibrated (free: "
                                     f"{list(self.free)}{derived}); bounds apply to calibrated "
                                     "parameters only")
            rlo, rhi = self.ranges[name]
            if not (_inside(lo, rlo, rhi) and _inside(hi, rlo, rhi)):
                raise ParameterError(f"calibration.bounds.{name}=[{lo:g}, {hi:g}] reaches beyond "
                                     f"ranges.{name}=[{rlo:g}, {rhi:g}], the sampled space (the regression "
                                     "is not valid outside it): narrow the bounds, or widen "
                                     f"ranges.{name} and rerun the design")
            box[name] = (max(lo, rlo), min(hi, rhi))
            if lo > rlo:
                origin[name]["lower"] = (f"calibration.bounds.{name}", None)
            if hi < rhi:
                origin[name]["upper"] = (f"calibration.bounds.{name}", None)
        self.box = box
        lo = np.array([box[p][0] for p in self.free])
        hi = np.array([box[p][1] for p in self.free])
        self.origin = {p: dict(origin[p]) for p in self.free}
        if ratio is not None and _COH in self.free:
            j = self.free.index(_COH)
            if box[_TEN][0] / ratio > lo[j]:
                lo[j] = box[_TEN][0] / ratio
                self.origin[_COH]["lower"] = (origin[_TEN]["lower"][0], box[_TEN][0])
            if box[_TEN][1] / ratio < hi[j]:
                hi[j] = box[_TEN][1] / ratio
                self.origin[_COH]["upper"] = (origin[_TEN]["upper"][0], box[_TEN][1])
            if not lo[j] < hi[j]:
                raise ParameterError(f"no {_COH} in {list(box[_COH])} gives {_TEN} = {ratio:g} × {_COH} "
                                     f"inside {list(box[_TEN])} (ranges.{_COH} and ranges.{_TEN} do not "
                                     "overlap at this ratio): widen one of them and rerun the design")
        if ratio is not None and _COH in self.fixed:
            ten = ratio * self.fixed[_COH]
            if not _inside(ten, *box[_TEN]):
                raise ParameterError(f"{_TEN} = {ratio:g} × {self.fixed[_COH]:g} = {ten:g} is outside "
                                     f"{origin[_TEN]['lower'][0]}={list(box[_TEN])}")
        self.lo, self.hi = lo, hi
        self.width = hi - lo

    @property
    def derived(self) -> tuple[str, ...]:
        return (_TEN,) if self.ratio is not None else ()

    @property
    def calibrated(self) -> tuple[str, ...]:
        """Free and derived parameters (what a calibration determines)."""
        return self.free + self.derived

    def bounds(self) -> dict[str, tuple[float, float]]:
        """Effective bounds of the free parameters and of the derived ``pb_ten_MPa``."""
        out = {p: (float(a), float(b)) for p, a, b in zip(self.free, self.lo, self.hi)}
        if self.ratio is not None and _COH in out:
            out[_TEN] = (self.ratio * out[_COH][0], self.ratio * out[_COH][1])
        return out

    def bound_origins(self) -> dict[str, dict[str, str]]:
        """For every effective bound: the configured key it comes from, e.g.
        ``{"pb_coh_MPa": {"lower": "ranges.pb_coh_MPa", "upper": "ranges.pb_ten_MPa / ratio 1.4"}}``."""
        out = {}
        for p in self.free:
            out[p] = {s: key + (f" / ratio {self.ratio:g}" if via is not None else "")
                      for s, (key, via) in self.origin[p].items()}
        if self.ratio is not None and _COH in self.free:
            out[_TEN] = {s: key + (f" × ratio {self.ratio:g}" if via is None else "")
                         for s, (key, via) in self.origin[_COH].items()}
        return out

    def edge_text(self, p: str, side: str, value: float, margin: float = 0.0) -> str:
        """``pb_coh_MPa at the upper bound 35.7 (= upper bound 50 of ranges.pb_ten_MPa / ratio 1.4)``;
        with the closed loop's ``margin`` (:meth:`loop_box`) past a design range, which says so."""
        key, via = self.origin[p][side]
        j = self.free.index(p)
        edge = self.lo[j] if side == "lower" else self.hi[j]
        if margin > 0 and key.startswith("ranges.") and not math.isclose(value, edge):
            return (f"{p} at the {side} bound {value:g} of the closed loop ({key} widened by "
                    f"the margin {margin:g} of its width, inside {p}'s physical domain)")
        if via is None:
            return f"{p} at the {side} bound {value:g} of {key}"
        return (f"{p} at the {side} bound {value:g} (= {side} bound {via:g} of {key} / ratio {self.ratio:g}; "
                f"{_TEN} = {via:g})")

    def x(self, u: np.ndarray) -> np.ndarray:
        return self.lo + np.asarray(u, float) * self.width

    def u(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, float) - self.lo) / self.width

    def full(self, x: np.ndarray) -> dict[str, float]:
        out = dict(self.fixed)
        out.update(zip(self.free, (float(v) for v in x)))
        if self.ratio is not None:
            out[_TEN] = self.ratio * out[_COH]
        return out

    def free_values(self, params: Mapping[str, float]) -> np.ndarray:
        missing = [p for p in self.free if p not in params]
        if missing:
            raise ParameterError(f"missing free parameter(s) {missing}")
        return np.array([float(params[p]) for p in self.free])

    def check_models(self, models: Mapping[str, RegressionModel], responses: Sequence[str]) -> None:
        known = set(self.fixed) | set(self.free) | set(self.derived)
        for r in responses:
            missing = [p for p in models[r].params if p not in known]
            if missing:
                raise ParameterError(f"the {r} model needs {missing}: give them in fixed or free")

    def jacobian(self, models: Mapping[str, RegressionModel], responses: Sequence[str], x) -> np.ndarray:
        """∂model_k/∂x_j (physical units), chain rule through the ratio constraint."""
        point = self.full(x)
        J = np.zeros((len(responses), len(self.free)))
        for k, r in enumerate(responses):
            grad = models[r].gradient(point)
            for j, p in enumerate(self.free):
                J[k, j] = grad.get(p, 0.0)
                if p == _COH and self.ratio is not None:
                    J[k, j] += self.ratio * grad.get(_TEN, 0.0)
        return J

    def at_bound(self, u: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> list[tuple[str, str, float]]:
        """(parameter, side, value) of every free parameter on an edge of the box (in unit
        coordinates ``box = (ulo, uhi)``, default the bounds [0, 1])."""
        ulo, uhi = box if box is not None else (np.zeros(len(self.free)), np.ones(len(self.free)))
        xlo, xhi = self.limits((ulo, uhi))
        out = []
        for j, p in enumerate(self.free):
            if u[j] <= ulo[j] + _EDGE:
                out.append((p, "lower", float(xlo[j])))
            elif u[j] >= uhi[j] - _EDGE:
                out.append((p, "upper", float(xhi[j])))
        return out

    def limits(self, box: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The box ``(ulo, uhi)`` (unit coordinates) in physical units; an edge the loop did
        not widen is the bound itself, to the bit (not lo + 1 x width)."""
        ulo, uhi = box
        return (np.where(ulo == 0.0, self.lo, self.lo + ulo * self.width),
                np.where(uhi == 1.0, self.hi, self.lo + uhi * self.width))

    def loop_box(self, margin: float) -> tuple[np.ndarray, np.ndarray]:
        """The closed loop's box in unit coordinates: [0, 1], widened by ``margin`` range
        widths on every side whose bound is a design range (``ranges``; never past a
        ``bounds`` narrowing), kept inside the parameter's physical domain."""
        ulo, uhi = np.zeros(len(self.free)), np.ones(len(self.free))
        if margin <= 0:
            return ulo, uhi
        elo, ehi = self.extended(margin)
        for j, p in enumerate(self.free):
            if self.origin[p]["lower"][0].startswith("ranges."):
                ulo[j] = min(0.0, (elo[j] - self.lo[j]) / self.width[j])
            if self.origin[p]["upper"][0].startswith("ranges."):
                uhi[j] = max(1.0, (ehi[j] - self.lo[j]) / self.width[j])
        return ulo, uhi

    def extended(self, factor: float) -> tuple[np.ndarray, np.ndarray]:
        """The free-parameter box widened by ``factor`` range widths on each side, kept inside
        each parameter's physical domain (for the extrapolated "what to widen" search)."""
        lo, hi = self.lo - factor * self.width, self.hi + factor * self.width
        for j, p in enumerate(self.free):
            d = PARAMS[p]
            lo[j] = max(lo[j], d.phys_lo + (1e-3 * self.width[j] if d.lo_open else 0.0))
            hi[j] = min(hi[j], d.phys_hi)
        return lo, hi


def check_calibration_space(free, fixed: Mapping[str, float], ratio: float | None,
                            ranges: Mapping[str, Sequence[float]],
                            bounds: Mapping[str, Sequence[float]] | None = None) -> None:
    """Raise :class:`ParameterError` if free/fixed/ratio/ranges/bounds do not define a valid
    calibration space (the checks :func:`invert` makes first), so a caller can reject bad
    input before it writes anything."""
    _Space(free, fixed, ratio, ranges, bounds)

def _check_ranges(ranges) -> dict[str, tuple[float, float]]:
    if ranges is None:
        raise ParameterError("ranges is required: the sampled range (design space) of the parameters, "
                             "e.g. the study config's ranges")
    out = {}
    for name, r in dict(ranges).items():
        check_params([name], "ranged parameter")
        try:
            lo, hi = (float(v) for v in r)
        except (TypeError, ValueError):
            raise ParameterError(f"ranges.{name}={r!r}: expected [low, high]") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ParameterError(f"ranges.{name}={list(r)!r}: expected finite [low, high] with low <= high")
        out[name] = (lo, hi)
    return out


def _inside(v: float, lo: float, hi: float) -> bool:
    tol = 1e-9 * max(abs(lo), abs(hi), hi - lo, 1e-300)
    return lo - tol <= v <= hi + tol


def _check_targets(targets: Mapping[str, float], models: Mapping[str, RegressionModel] | None
                   ) -> tuple[tuple[str, ...], np.ndarray]:
    responses = check_responses(targets)
    if not responses:
        raise ValueError("targets is empty: expected e.g. {'ucs_MPa': ..., 'E_GPa': ..., 'nu': ...}")
    t = np.array([float(targets[r]) for r in responses])
    bad = [f"{r}={targets[r]!r}" for r, v in zip(responses, t) if not (math.isfinite(v) and v != 0)]
    if bad:
        raise ValueError(f"target(s) {bad}: expected finite non-zero values (errors are relative)")
    if models is not None:
        missing = [r for r in responses if r not in models]
        if missing:
            raise ValueError(f"no regression model for target(s) {missing}; models given: {list(models)}")
    return responses, t


def _fmt_pct(responses, r) -> str:
    return ", ".join(f"{name} {100 * v:+.2f} %" for name, v in zip(responses, r))


# -- inversion ------------------------------------------------------------------------------
@dataclass
class InversionResult:
    """Outcome of :func:`invert` (see the module docstring for ``status``).

    ``solution`` holds every parameter (fixed, free, derived) of the best fit;
    ``alternatives`` one row per distinct solution that fits equally well (best first);
    ``starts`` the end point of every start. ``bounds`` are the effective bounds of the
    calibrated parameters and ``bound_origins`` the configured key each side comes from
    (``ranges.<p>``, ``calibration.bounds.<p>``, or ``ranges.pb_ten_MPa / ratio a``);
    ``ranges`` the design space. When the targets are not met, ``widen`` lists each
    configured limit to move (parameter, side, key, bound, needed value, and whether the
    extrapolated models meet every target there, ``reaches_targets``; ``needed`` is None when
    they cannot tell how far) and ``advice`` says it in words (empty when the diagnosis was
    not run).
    """

    status: str
    message: str
    solution: dict[str, float]
    free: tuple[str, ...]
    derived: tuple[str, ...]
    targets: dict[str, float]
    predicted: dict[str, float]
    residuals: dict[str, float]  # relative
    bounds: dict[str, tuple[float, float]]
    at_bound: list[tuple[str, str, float]]
    alternatives: pd.DataFrame
    starts: pd.DataFrame
    tol: float
    bound_origins: dict[str, dict[str, str]] = field(default_factory=dict)
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    widen: list[dict] = field(default_factory=list)
    advice: str = ""
    reach: dict = field(default_factory=dict)  # σt / σc/σt spans when σt misses (see the module doc)

    @property
    def missed(self) -> list[dict]:
        """Every target the solution misses by more than ``tol``: target, value, predicted,
        error_pct (100 × relative residual), in the order of the targets."""
        return [{"target": r, "value": self.targets[r], "predicted": self.predicted[r],
                 "error_pct": 100 * v} for r, v in self.residuals.items() if abs(v) > self.tol]

    @property
    def ok(self) -> bool:
        """True when the targets are met within ``tol`` by a single parameter set."""
        return self.status == "ok"

    @property
    def reachable(self) -> bool:
        return self.status in ("ok", "non-unique")

    @property
    def unique(self) -> bool:
        return len(self.alternatives) <= 1

    @property
    def max_abs_residual(self) -> float:
        return max(abs(v) for v in self.residuals.values())

    def to_frame(self) -> pd.DataFrame:
        """One row per parameter: value, role (fixed/free/derived), lower and upper bound."""
        recs = []
        for p, v in self.solution.items():
            role = "free" if p in self.free else ("derived" if p in self.derived else "fixed")
            lo, hi = self.bounds.get(p, (np.nan, np.nan))
            recs.append({"parameter": p, "value": v, "role": role, "lower": lo, "upper": hi})
        return pd.DataFrame.from_records(recs).set_index("parameter")

    def responses_frame(self) -> pd.DataFrame:
        """One row per target: target, predicted, relative residual."""
        return pd.DataFrame({"target": self.targets, "predicted": self.predicted,
                             "rel_residual": self.residuals})

    def summary(self) -> str:
        return "\n".join([f"Inversion: {self.status} - {self.message}", "", self.to_frame().to_string(), "",
                          self.responses_frame().to_string(), "",
                          f"{len(self.alternatives)} distinct solution(s):", self.alternatives.to_string()])


def _lhs(n: int, d: int, seed: int) -> np.ndarray:
    return qmc.LatinHypercube(d=d, seed=np.random.default_rng(seed)).random(n) if n > 0 else np.empty((0, d))


def _fit(space: _Space, models, responses, t, lo, hi, x_starts, n_starts: int, seed: int) -> list[tuple]:
    """Multi-start bounded least squares of the relative residuals in the box [lo, hi] of the
    free parameters; one (sum of squares, max |r|, x, r) per start, best first."""
    width = hi - lo
    scale = np.abs(t)

    def resid_x(x):
        point = space.full(x)
        return (np.array([models[r].predict(point) for r in responses]) - t) / scale

    def resid(u):
        return resid_x(lo + u * width)

    def jac(u):
        return space.jacobian(models, responses, lo + u * width) * width / scale[:, None]

    starts = [np.clip((np.asarray(x, float) - lo) / width, 0.0, 1.0) for x in x_starts]
    starts += list(_lhs(int(n_starts), len(space.free), seed))
    if not starts:
        raise ValueError("no starting point: expected n_starts > 0 or x0")
    fits = []
    for u0 in starts:
        sol = least_squares(resid, u0, jac=jac, bounds=(0.0, 1.0), method="trf", xtol=1e-12, ftol=1e-12,
                            gtol=1e-12)
        u = np.clip(sol.x, 0.0, 1.0)
        r = resid(u)
        fits.append((float(r @ r), float(np.max(np.abs(r))), lo + u * width, r))
    fits.sort(key=lambda f: f[0])
    return fits


def _what_to_widen(space: _Space, models, responses, t, x_best, tol: float, n_starts: int, seed: int
                   ) -> tuple[list[dict], str]:
    """Which configured limit keeps the targets out of reach, and how far it must move.

    The regression is extrapolated into a box 2, then 5, then 20 range widths wider on each
    side (:data:`_EXTEND`, within each parameter's physical domain) until some point meets
    the targets; among the points that meet the targets there,
    the one least outside the configured limits is taken, and every calibrated parameter
    (free or derived) outside its configured range or bound is reported with the configured
    key to widen and the value it must reach. Indicative only: outside the sampled ranges
    the regression is not validated.
    """
    for factor in _EXTEND:
        elo, ehi = space.extended(factor)
        fits = _fit(space, models, responses, t, elo, ehi, [x_best], n_starts, seed)
        reach = [f for f in fits if f[1] <= tol]
        if reach:
            break
    box = space.box

    def needs(x):
        point = space.full(x)
        out = []
        for p in space.calibrated:
            lo, hi = box[p]
            w = hi - lo
            v = point[p]
            for side, beyond in (("lower", v < lo - 1e-9 * w), ("upper", v > hi + 1e-9 * w)):
                if not beyond:
                    continue
                key = (f"calibration.bounds.{p}" if (side == "lower" and lo > space.ranges[p][0])
                       or (side == "upper" and hi < space.ranges[p][1]) else f"ranges.{p}")
                rlo, rhi = space.ranges[p]
                out.append({"parameter": p, "side": side, "key": key,
                            "bound": lo if side == "lower" else hi, "needed": float(v),
                            "beyond_ranges": bool(v < rlo or v > rhi)})
        return out

    def distance(x):
        point = space.full(x)
        return sum(max(0.0, box[p][0] - point[p], point[p] - box[p][1]) / (box[p][1] - box[p][0])
                   for p in space.calibrated)

    if not reach:
        best = fits[0]
        point = space.full(best[2])
        missed = ", ".join(f"{r} {100 * v:+.2f} %" for r, v in zip(responses, best[3]) if abs(v) > tol)
        models_say = (f"The fitted models, extrapolated up to {_EXTEND[-1]:g} range widths beyond the "
                      f"sampled space, cannot meet all targets either (best relative residuals "
                      f"{_fmt_pct(responses, best[3])})")
        items = needs(best[2])
        if items:
            for it in items:
                it["reaches_targets"] = False
            where = ", ".join(f"{p} = {point[p]:.4g}" for p in space.calibrated)
            parts = [f"{it['key']} {'below' if it['side'] == 'lower' else 'above'} {it['needed']:.4g} "
                     f"(its {it['side']} bound is now {it['bound']:.4g})" for it in items]
            return items, (f"{models_say}. Their best compromise lies at {where}: widen {'; '.join(parts)} "
                           "and rerun the design so that a new regression covers it. What it still misses "
                           f"({missed}) may need another free parameter (calibration.free) or other fixed "
                           "values (calibration.fixed). Indicative only: the regression is not validated "
                           "outside the sampled space.")
        u_best = space.u(x_best)
        for p, side, v in space.at_bound(u_best):
            key, via = space.origin[p][side]
            name = key.split(".", 1)[1] if key.startswith("ranges.") else key.rsplit(".", 1)[1]
            items.append({"parameter": name, "side": side, "key": key,
                          "bound": float(via) if via is not None else float(v), "needed": None,
                          "beyond_ranges": key.startswith("ranges."), "reaches_targets": False})
        if items:
            keys = ", ".join(f"{it['key']} ({it['side']} bound {it['bound']:.4g})" for it in items)
            return items, (f"{models_say}, and their best compromise lies inside the configured limits, "
                           f"so they cannot tell how far to widen. The limits that stop the fit are {keys}: "
                           "widen them and rerun the design so that a new regression covers the targets, "
                           "or free another parameter (calibration.free) or change a fixed value "
                           "(calibration.fixed).")
        return [], (f"{models_say}, and no configured bound is active: with these models widening the "
                    "ranges does not help; free another parameter (calibration.free) or change a fixed "
                    "value (calibration.fixed), then rerun.")
    x = min(reach, key=lambda f: (distance(f[2]), f[0]))[2]
    items = needs(x)
    for it in items:
        it["reaches_targets"] = True
    if not items:  # a point inside the limits meets the targets: the multi-start missed it
        return [], ("A point inside the configured limits meets the targets when started from the "
                    "extrapolated search; the multi-start missed it (increase n_starts).")
    parts = []
    for it in items:
        word = "below" if it["side"] == "lower" else "above"
        parts.append(f"{it['key']} {word} {it['needed']:.4g} "
                     f"(its {it['side']} bound is now {it['bound']:.4g})")
        if it["key"].startswith("calibration.bounds") and it["beyond_ranges"]:
            parts.append(f"ranges.{it['parameter']} {word} {it['needed']:.4g}")
    rerun = any(it["key"].startswith("ranges") or it["beyond_ranges"] for it in items)
    point = space.full(x)
    where = ", ".join(f"{p} = {point[p]:.4g}" for p in space.calibrated)
    advice = (f"To reach the targets widen {'; '.join(parts)}"
              + (" and rerun the design (new samples, screening, regression)" if rerun else "")
              + f". The regression extrapolated beyond the sampled space meets the targets at {where}: "
              "indicative only (the regression is not validated there), so leave a margin.")
    return items, advice


def invert(models: Mapping[str, RegressionModel], targets: Mapping[str, float], fixed: Mapping[str, float],
           free: Sequence[str] | None = None, bounds: Mapping[str, Sequence[float]] | None = None,
           ratio: float | None = PAPER_RATIO, *, ranges: Mapping[str, Sequence[float]], n_starts: int = 24,
           seed: int = 0, tol: float = 1e-3, distinct: float = 0.02, x0: Sequence[Mapping[str, float]] = (),
           diagnose: bool = True) -> InversionResult:
    """Solve the regression models for the free parameters that reproduce ``targets``.

    Parameters
    ----------
    models:
        response -> :class:`RegressionModel` (e.g. ``StepwiseResults.final_models``).
    targets:
        response -> laboratory value, e.g. ``{"ucs_MPa": 62.1, "E_GPa": 14.07, "nu": 0.267}``.
    fixed:
        parameter -> value for the parameters held fixed (paper: :data:`PAPER_FIXED` plus
        ``pb_fa_deg`` and ``fric``). A fixed value outside its range in ``ranges`` is an error.
    free:
        parameters to solve for (default :data:`DEFAULT_FREE`, plus ``pb_ten_MPa`` when
        ``ratio`` is None).
    bounds:
        parameter -> (lo, hi) narrowing ``ranges`` for a free (or the derived) parameter;
        bounds reaching beyond ``ranges`` are an error (the regression is not valid there).
    ratio:
        ``pb_ten_MPa / pb_coh_MPa`` (default 1.4), or None for independent strengths.
    ranges:
        The design space: parameter -> (lo, hi) the dataset was sampled over (the study
        config's ``ranges``, paper units); required for every free parameter and for
        ``pb_ten_MPa`` with a ratio. The free parameters are confined to it.
    n_starts, seed:
        Latin-hypercube starting points in the free-parameter box (seeded).
    tol:
        Largest relative residual that counts as meeting the targets.
    distinct:
        Solutions further apart than this fraction of a range (in some free parameter)
        are distinct.
    x0:
        Extra starting points (mappings holding the free parameters), tried first.
    diagnose:
        For ``unreachable`` and ``no-exact-fit``, search the extrapolated regression for
        which configured limit to widen and how far (``widen``, ``advice``; costs one more
        multi-start), and with a σt target the spans the models reach (``reach``).
    """
    space = _Space(free, fixed, ratio, ranges, bounds)
    responses, t = _check_targets(targets, models)
    space.check_models(models, responses)
    if not tol > 0 or not distinct > 0:
        raise ValueError(f"tol={tol!r}, distinct={distinct!r}: expected positive numbers")
    fits = _fit(space, models, responses, t, space.lo, space.hi, [space.free_values(p) for p in x0],
                n_starts, seed)
    fits = [(c, m, space.u(x), r) for c, m, x, r in fits]
    best_cost, best_max, best_u, best_r = fits[0]
    reachable = best_max <= tol
    good = [f for f in fits if (f[1] <= tol if reachable else f[0] <= best_cost * (1 + 1e-6) + 1e-14)]
    kept: list[tuple] = []
    for f in good:
        if all(np.max(np.abs(f[2] - k[2])) > distinct for k in kept):
            kept.append(f)

    def row(f):
        point = space.full(space.x(f[2]))
        rec = {p: point[p] for p in space.calibrated}
        rec.update({r: float(models[r].predict(point)) for r in responses})
        rec.update(max_abs_residual=f[1], sum_sq=f[0])
        return rec

    alternatives = pd.DataFrame.from_records([row(f) for f in kept])
    start_frame = pd.DataFrame.from_records([row(f) for f in fits])
    solution = space.full(space.x(best_u))
    edges = space.at_bound(best_u)
    widen, advice = [], ""
    if not reachable and diagnose:
        widen, advice = _what_to_widen(space, models, responses, t, space.x(best_u), tol, n_starts,
                                       seed + 1)
    reach: dict = {}
    joint = ""  # the σt target set is out of reach although the other targets are not
    tr = tensile_target(responses)
    if not reachable and tr is not None and len(responses) > 1:
        others = [r for r in responses if r != tr]
        t_other = np.array([t[responses.index(r)] for r in others])
        sub = _fit(space, models, others, t_other, space.lo, space.hi, [space.x(best_u)], n_starts,
                   seed + 2)
        if sub[0][1] <= tol:
            reach = _bts_reach(space, models, others, t_other, tol,
                               [f[2] for f in sub if f[1] <= tol], seed + 3,
                               response=tr) if diagnose else {}
            t_bts = float(t[responses.index(tr)])
            span = (f"while meeting {', '.join(others)} the models give σt in "
                    f"[{reach[tr][0]:.4g}, {reach[tr][1]:.4g}] MPa"
                    + (f" (σc/σt in [{reach['ucs_over_bts'][0]:.3g}, {reach['ucs_over_bts'][1]:.3g}])"
                       if "ucs_over_bts" in reach else "")
                    if reach else f"{', '.join(others)} are met together inside the bounds")
            target_ratio = (f", σc/σt = {targets['ucs_MPa'] / t_bts:.3g}" if "ucs_MPa" in responses
                            else "")
            joint = (f"the target set cannot be met at once: σt = {t_bts:g} MPa{target_ratio} is "
                     f"outside what the parallel-bond models reach ({span})")
    missed = "; ".join(f"{r} {100 * v:+.2f} %" for r, v in zip(responses, best_r) if abs(v) > tol)
    if reachable and len(kept) == 1:
        status, message = "ok", f"targets met within {tol:g} (relative): {_fmt_pct(responses, best_r)}"
    elif reachable:
        extra = (f"; {len(space.free)} free parameters for {len(responses)} targets: a continuum of solutions"
                 if len(space.free) > len(responses) else "")
        status = "non-unique"
        message = (f"{len(kept)} distinct parameter sets meet the targets within {tol:g}{extra}; "
                   "see alternatives (the best-fitting one is returned)")
    elif joint:
        where = ", ".join(space.edge_text(p, side, v) for p, side, v in edges)
        status = "no-exact-fit"
        message = (f"{joint}. The card keeps the best compromise (least squares of the relative "
                   f"residuals, equal weights){' with ' + where if where else ''}; targets missed: "
                   f"{missed} (relative residuals {_fmt_pct(responses, best_r)}, tol {tol:g})."
                   + (f" {advice}" if advice else ""))
    elif edges:
        where = ", ".join(space.edge_text(p, side, v) for p, side, v in edges)
        status = "unreachable"
        message = (f"targets lie outside what the sampled ranges can reach: the closest point inside the "
                   f"bounds has {where}, relative residuals {_fmt_pct(responses, best_r)}; "
                   "this point is not a calibration." + (f" {advice}" if advice else ""))
    else:
        status = "no-exact-fit"
        message = (f"the models cannot meet all targets at once: the best compromise is an interior optimum "
                   f"(no bound of the configured ranges is active), relative residuals "
                   f"{_fmt_pct(responses, best_r)} exceed {tol:g}." + (f" {advice}" if advice else ""))
    return InversionResult(
        status=status, message=message, solution=solution, free=space.free, derived=space.derived,
        targets=dict(zip(responses, t.tolist())),
        predicted={r: float(models[r].predict(solution)) for r in responses},
        residuals=dict(zip(responses, best_r.tolist())),
        bounds=space.bounds(),
        at_bound=edges, alternatives=alternatives, starts=start_frame, tol=tol,
        bound_origins=space.bound_origins(), ranges=dict(space.ranges), widen=widen, advice=advice,
        reach=reach)


def _bts_reach(space: _Space, models, others: Sequence[str], t_other: np.ndarray, tol: float,
               x_starts: Sequence[np.ndarray], seed: int, n_starts: int = 8,
               response: str = BTS) -> dict:
    """The smallest and largest σt (``response``: the tensile strength; and σc/σt) the
    models give over the parameter sets inside the bounds that meet the ``others``
    targets (relative residuals <= ``tol``): SLSQP in the unit cube with those residuals
    as equality constraints, from the given solutions and ``n_starts`` Latin-hypercube
    points. ``{}`` if no start converges."""
    from scipy.optimize import minimize

    lo, width = space.lo, space.width
    scale = np.abs(t_other)
    m_bts = models[response]

    def point(u):
        return space.full(lo + np.clip(u, 0.0, 1.0) * width)

    def cons(u):
        p = point(u)
        return np.array([models[r].predict(p) for r in others]) - t_other

    def cons_jac(u):
        return space.jacobian(models, others, lo + np.clip(u, 0.0, 1.0) * width) * width

    def bts(u):
        return float(m_bts.predict(point(u)))

    def bts_grad(u):
        return space.jacobian(models, [response], lo + np.clip(u, 0.0, 1.0) * width)[0] * width

    starts = [space.u(x) for x in x_starts] + list(_lhs(n_starts, len(space.free), seed))
    found = []
    for sign in (1.0, -1.0):
        for u0 in starts:
            sol = minimize(lambda u: sign * bts(u), np.clip(u0, 0, 1), jac=lambda u: sign * bts_grad(u),
                           method="SLSQP", bounds=[(0.0, 1.0)] * len(space.free),
                           constraints=[{"type": "eq", "fun": cons, "jac": cons_jac}],
                           options={"maxiter": 300, "ftol": 1e-12})
            u = np.clip(sol.x, 0.0, 1.0)
            if np.max(np.abs(cons(u)) / scale) <= tol:
                p = point(u)
                found.append((bts(u), float(models["ucs_MPa"].predict(p)) if "ucs_MPa" in models
                              and "ucs_MPa" in others else math.nan))
    if not found:
        return {}
    v = np.array(found)
    out = {response: [float(v[:, 0].min()), float(v[:, 0].max())],
           "met": list(others)}
    if np.all(np.isfinite(v[:, 1])) and np.all(v[:, 0] > 0):
        q = v[:, 1] / v[:, 0]
        out["ucs_over_bts"] = [float(q.min()), float(q.max())]
    return out


# -- bootstrap ------------------------------------------------------------------------------
@dataclass
class BootstrapResults:
    """Outcome of :func:`bootstrap_intervals`.

    ``intervals``: one row per calibrated parameter (kind ``parameter``) and per response
    predicted at the full-data solution (kind ``response``): full-data estimate, bootstrap
    median, std, lower and upper percentile bound, number of resamples used. ``draws``: one
    row per resample. ``base``: the full-data :class:`InversionResult`.
    """

    base: InversionResult
    intervals: pd.DataFrame
    draws: pd.DataFrame
    level: float
    scheme: str
    rows: dict[str, int]

    @property
    def n_unreachable(self) -> int:
        return int((~self.draws["reachable"]).sum())

    def to_frame(self) -> pd.DataFrame:
        return self.intervals

    def summary(self) -> str:
        return "\n".join([
            f"Bootstrap ({self.scheme}): {len(self.draws)} resamples of {self.rows['n_used']} rows "
            f"({self.rows['n_dropped']} dropped), {100 * self.level:g} % percentile intervals; "
            f"{self.n_unreachable} resample(s) did not reach the targets and are excluded",
            f"full-data inversion: {self.base.status} - {self.base.message}", "", self.intervals.to_string()])


def bootstrap_intervals(df: pd.DataFrame, models: Mapping[str, RegressionModel], targets: Mapping[str, float],
                        fixed: Mapping[str, float], free: Sequence[str] | None = None,
                        bounds: Mapping[str, Sequence[float]] | None = None,
                        ratio: float | None = PAPER_RATIO, *, ranges: Mapping[str, Sequence[float]],
                        n_boot: int = 1000, level: float = 0.95, seed: int = 0,
                        reselect: StepwiseRegression | None = None,
                        candidates: Mapping[str, Sequence[str]] | None = None, n_starts: int = 0,
                        tol: float = 1e-3) -> BootstrapResults:
    """Case-resampling bootstrap of the calibration (see the module docstring).

    ``models`` are the full-data models whose terms are refitted in every resample (or,
    with ``reselect``, re-selected from ``candidates``; use ``cv_folds=0`` there for
    speed). Each resample's inversion starts from the full-data solution plus ``n_starts``
    Latin-hypercube points. ``ranges`` and ``bounds`` confine every inversion as in
    :func:`invert` (the design space, optionally narrowed).
    """
    if not isinstance(n_boot, (int, np.integer)) or n_boot < 2:
        raise ValueError(f"n_boot={n_boot!r}: expected an integer >= 2")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level={level!r}: expected a probability in (0, 1), e.g. 0.95")
    if reselect is not None and not candidates:
        raise ValueError("reselect needs candidates (response -> screened parameters)")
    responses, _ = _check_targets(targets, models)
    needed = list(dict.fromkeys([p for r in responses for p in models[r].params] + list(responses)
                                + [p for c in (candidates or {}).values() for p in c]))
    rows = usable_rows(df, needed)
    data = rows.data
    rng = np.random.default_rng(seed)
    base = invert(models, targets, fixed, free, bounds, ratio, ranges=ranges, seed=seed_from(rng), tol=tol)
    designs = {r: (models[r].design(data), data[r].to_numpy(float)) for r in responses}
    start = [{p: base.solution[p] for p in base.free}]
    recs = []
    for b in range(int(n_boot)):
        idx = rng.integers(0, len(data), len(data))
        if reselect is None:
            boot = {}
            for r in responses:
                X, y = designs[r]
                A = np.column_stack([np.ones(len(idx)), X[idx]])
                beta = np.linalg.lstsq(A, y[idx], rcond=None)[0]
                boot[r] = models[r].with_coefficients(beta[0], beta[1:])
        else:
            boot = reselect.fit(data.iloc[idx], {r: candidates[r] for r in responses}).final_models
        inv = invert(boot, targets, fixed, free, bounds, ratio, ranges=ranges, n_starts=n_starts,
                     seed=seed_from(rng), tol=tol, x0=start, diagnose=False)
        rec = {"resample": b, "status": inv.status, "reachable": inv.reachable}
        rec.update({p: inv.solution[p] for p in inv.free + inv.derived})
        rec.update({f"{r}@estimate": float(boot[r].predict(base.solution)) for r in responses})
        recs.append(rec)
    draws = pd.DataFrame.from_records(recs)
    q = [(1 - level) / 2, 1 - (1 - level) / 2]
    out = []
    quantities = [(p, "parameter", base.solution[p], p) for p in base.free + base.derived]
    quantities += [(r, "response", base.predicted[r], f"{r}@estimate") for r in responses]
    if base.status == "no-exact-fit":
        # the targets cannot all be met: the calibrated set is the least-squares compromise,
        # and so is every resample's (an interior optimum, well defined): use those
        used = draws[draws["status"].isin(["ok", "non-unique", "no-exact-fit"])]
    else:
        used = draws[draws["reachable"]]
    for name, kind, est, col in quantities:
        v = (used if kind == "parameter" else draws)[col].to_numpy(float)
        lo, hi = np.quantile(v, q) if len(v) else (np.nan, np.nan)
        out.append({"quantity": name, "kind": kind, "estimate": est,
                    "median": np.median(v) if len(v) else np.nan,
                    "std": np.std(v, ddof=1) if len(v) > 1 else np.nan,
                    "lower": lo, "upper": hi, "n": len(v)})
    scheme = ("case resampling, selection re-run in every resample" if reselect is not None
              else "case resampling, terms fixed at the full-data selection")
    return BootstrapResults(base=base, intervals=pd.DataFrame.from_records(out).set_index("quantity"),
                            draws=draws, level=float(level), scheme=scheme, rows=rows.describe())


# -- closed loop ----------------------------------------------------------------------------
@dataclass
class ClosedLoopResult:
    """Outcome of :meth:`ClosedLoop.run`.

    ``status``: ``"converged"``, ``"max_rounds"``, ``"stalled"`` (the step was blocked by
    the bounds) or ``"failed"`` (a simulation returned no finite value). ``params`` and
    ``responses`` (the seed means) are those of the best round ``best_round``: the
    converged one, else the one with the smallest max |error| of the mean; ``seed_cv``
    holds that round's seed coefficient of variation per response (NaN with one seed),
    ``n_seeds`` its k and ``seeds`` its seeds. ``loop_bounds`` are the bounds the loop
    searched (the design ranges, widened by ``margin``), ``outside`` the calibrated
    parameters of ``params`` that lie outside their design range (value and range): the
    regression never saw them, the simulator did.
    ``history`` has one row per round: the parameters, the mean of every response, its
    seed CV ``cv_<r>`` in that round, the pooled relative standard error ``se_<r>``, the
    tolerance used ``tol_<r>`` = max(rtol, z · se), the relative error ``err_<r>`` of the
    mean, ``n_seeds`` and the step; ``samples`` one row per simulation (round, seed,
    responses). ``jacobian`` is the final Broyden estimate of ∂response/∂parameter in
    physical units.
    """

    status: str
    message: str
    history: pd.DataFrame
    params: dict[str, float]
    responses: dict[str, float]
    jacobian: pd.DataFrame
    samples: pd.DataFrame = field(default_factory=pd.DataFrame)
    seed_cv: dict[str, float] = field(default_factory=dict)
    n_seeds: int = 1
    seeds: tuple = ()
    best_round: int = 0
    outside: dict = field(default_factory=dict)
    loop_bounds: dict = field(default_factory=dict)

    @property
    def converged(self) -> bool:
        return self.status == "converged"

    @property
    def n_rounds(self) -> int:
        return len(self.history)

    @property
    def n_simulations(self) -> int:
        return len(self.samples)

    def to_frame(self) -> pd.DataFrame:
        return self.history

    def summary(self) -> str:
        head = (f"Closed loop: {self.status} after {self.n_rounds} round(s) of {self.n_seeds} "
                f"seed(s) - {self.message}")
        return "\n".join([head, "", self.history.to_string(index=False)])


class ClosedLoop:
    """Newton-Broyden closed-loop correction of a calibration with the simulator itself.

    Parameters
    ----------
    simulate:
        ``simulate(params, seed=s) -> {response: value, ...}`` for a full parameter dict
        (paper units) and a packing seed, e.g. one DEM UCS test; must return every target
        response. A callable without a ``seed`` parameter, ``simulate(params)``, is a
        single-seed simulator (one run per round).
    targets:
        response -> laboratory value.
    free, ratio, ranges, bounds:
        As for :func:`invert` (``ranges`` the design space, required; ``bounds`` optional
        narrower limits); every other parameter of the initial set stays fixed.
    models:
        Regression models whose analytic Jacobian at the initial point starts the Broyden
        updates (alternatively ``jacobian``: DataFrame responses × free parameters,
        ∂response/∂parameter in physical units).
    rtol:
        Relative tolerance, one number or response -> number (default 0.01); the loop
        stops when every mean is within max(rtol, z · SE) of its target (module docstring).
    max_rounds:
        Maximum number of rounds (default 6, room for a polishing round), each of
        ``seeds_per_round`` simulations.
    seeds_per_round, seeds:
        The packing seeds every round runs (the same in every round): ``seeds`` (distinct
        integers), else 1..``seeds_per_round``; default 3 seeds for a simulator with a
        ``seed`` parameter, 1 (and no seed) for ``simulate(params)``, which cannot take
        more.
    max_seeds:
        The seed set may grow to this many seeds (the next integers after the largest of
        ``seeds``) once the means are within tolerance but a standard error is too large
        to state them to ``rtol`` (module docstring); default (or at most the seeds of a
        round): no growth.
    z:
        Standard errors of the mean within which a target counts as met (default 2).
    damping, max_step:
        Newton step factor (default 0.8) and cap on the move of any parameter per round
        as a fraction of its range (default 0.25); after a round that is worse than the
        best so far the cap becomes half that round's step (the trust region, module
        docstring).
    broyden:
        Update the Jacobian by Broyden's secant rule (default True).
    margin:
        How far the loop may leave the design space: every bound that is a design range
        (``ranges``) moves out by ``margin`` times the range's width, never past the
        parameter's physical domain nor a ``bounds`` narrowing (default 0: the loop stays
        inside the ranges). The regression only starts the loop (its Jacobian); every
        round measures the simulator itself, so the loop can follow a target just outside
        the sampled space, e.g. a stiffness ratio that a smaller verification specimen
        needs for the rock's ν. :attr:`ClosedLoopResult.outside` lists what ended outside.
    polish:
        When a seed-averaged loop (k > 1 seeds) converges with some mean more than one
        standard error from its target, and a round is left, take one more full Newton
        step (damping 1) towards the targets on the same seeds (default True). The
        tolerance accepts a card anywhere within ``rtol``; the polished round aims at the
        targets themselves. It becomes the card's if it is within tolerance too, else the
        converged round stays the card's (``history``: ``polish`` marks the step).
        Single-seed loops are not polished: with no standard error there is no telling
        a real miss from that packing's scatter.
    """

    def __init__(self, simulate: Callable[[dict], Mapping[str, float]], targets: Mapping[str, float], *,
                 free: Sequence[str] | None = None, ratio: float | None = PAPER_RATIO,
                 ranges: Mapping[str, Sequence[float]],
                 bounds: Mapping[str, Sequence[float]] | None = None,
                 models: Mapping[str, RegressionModel] | None = None, jacobian: pd.DataFrame | None = None,
                 rtol: float | Mapping[str, float] = 0.01, max_rounds: int = 6, damping: float = 0.8,
                 max_step: float = 0.25, broyden: bool = True, seeds_per_round: int | None = None,
                 seeds: Sequence[int] | None = None, z: float = 2.0, max_seeds: int | None = None,
                 margin: float = 0.0, polish: bool = True):
        if not callable(simulate):
            raise TypeError(f"simulate={simulate!r}: expected a callable (params, seed) -> responses")
        self.seeds = _round_seeds(simulate, seeds_per_round, seeds)
        whole = isinstance(max_seeds, (int, np.integer)) and not isinstance(max_seeds, bool)
        if max_seeds is not None and not (whole and max_seeds >= 1):
            raise ValueError(f"max_seeds={max_seeds!r}: expected an integer >= 1")
        n_more = 0 if max_seeds is None else max(0, int(max_seeds) - len(self.seeds))
        if n_more and self.seeds == (None,):
            raise ValueError("simulate(params) takes no seed argument, so the seed set cannot grow: "
                             "give it a 'seed' parameter, or leave max_seeds unset")
        top = max(self.seeds) if self.seeds != (None,) else 0
        self.growth_seeds = tuple(range(top + 1, top + 1 + n_more))
        if not (math.isfinite(float(z)) and float(z) >= 0):
            raise ValueError(f"z={z!r}: expected a number of standard errors >= 0")
        self.z = float(z)
        self.responses, self.t = _check_targets(targets, models)
        if (models is None) == (jacobian is None):
            raise ValueError("give exactly one of models (analytic Jacobian) or jacobian")
        rt = {r: float(rtol[r] if isinstance(rtol, Mapping) else rtol) for r in self.responses}
        if not all(v > 0 for v in rt.values()):
            raise ValueError(f"rtol={rtol!r}: expected positive relative tolerance(s)")
        if not isinstance(max_rounds, (int, np.integer)) or max_rounds < 1:
            raise ValueError(f"max_rounds={max_rounds!r}: expected an integer >= 1")
        if not 0 < damping <= 1:
            raise ValueError(f"damping={damping!r}: expected a factor in (0, 1]")
        if not 0 < max_step <= 1:
            raise ValueError(f"max_step={max_step!r}: expected a fraction of the range in (0, 1]")
        self.simulate = simulate
        self.free, self.ratio, self.ranges, self.bounds = free, ratio, _check_ranges(ranges), bounds
        self.models, self.jacobian = models, jacobian
        self.rtol = np.array([rt[r] for r in self.responses])
        self.max_rounds, self.damping, self.max_step = int(max_rounds), float(damping), float(max_step)
        self.broyden = bool(broyden)
        if isinstance(margin, bool) or not isinstance(margin, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(float(margin)) and 0 <= float(margin) <= 1):
            raise ValueError(f"margin={margin!r}: expected a fraction of the range width in [0, 1]")
        self.margin = float(margin)
        if not isinstance(polish, (bool, np.bool_)):
            raise ValueError(f"polish={polish!r}: expected True or False")
        self.polish = bool(polish)

    def _space(self, initial: Mapping[str, float]) -> _Space:
        free = _default_free(self.free, self.ratio)
        derived = (_TEN,) if self.ratio is not None else ()
        fixed = {k: v for k, v in initial.items() if k not in free and k not in derived}
        space = _Space(free, fixed, self.ratio, self.ranges, self.bounds)
        if self.ratio is not None and _TEN in initial and _COH in initial:
            if not math.isclose(float(initial[_TEN]), self.ratio * float(initial[_COH]), rel_tol=1e-9):
                raise ParameterError(f"initial {_TEN}={initial[_TEN]!r} differs from ratio × {_COH} = "
                                     f"{self.ratio:g} × {initial[_COH]!r}")
        return space

    def _initial_jacobian(self, space: _Space, x: np.ndarray) -> np.ndarray:
        if self.models is not None:
            space.check_models(self.models, self.responses)
            Jx = space.jacobian(self.models, self.responses, x)
        else:
            jac = pd.DataFrame(self.jacobian)
            missing = [r for r in self.responses if r not in jac.index] + [p for p in space.free
                                                                          if p not in jac.columns]
            if missing:
                raise ValueError(f"jacobian lacks {missing}: expected rows {list(self.responses)} and "
                                 f"columns {list(space.free)}")
            Jx = jac.loc[list(self.responses), list(space.free)].to_numpy(float)
        return Jx * space.width / np.abs(self.t)[:, None]

    @property
    def seeds_per_round(self) -> int:
        return len(self.seeds)

    def _simulate(self, params: dict[str, float], seed: int | None) -> np.ndarray:
        out = self.simulate(dict(params)) if seed is None else self.simulate(dict(params), seed=seed)
        return np.array([float(out.get(r, np.nan)) if out is not None else np.nan for r in self.responses])

    def _step(self, J: np.ndarray, e: np.ndarray, u: np.ndarray,
              box: tuple[np.ndarray, np.ndarray], damping: float | None = None,
              cap: float | None = None, weights: np.ndarray | None = None,
              probe: Sequence[int] = ()) -> tuple[np.ndarray, list[int]]:
        """The damped Gauss-Newton step from ``u`` with the parameters at a bound whose step
        points out of the box held there (solved again without them until none is left),
        kept within ``cap`` (default ``max_step``); returns the step and the held
        parameters' indices. With ``weights`` (one per response, 1/tolerance) a step that
        would leave the cap is a Levenberg-Marquardt step instead of a shortened
        Gauss-Newton one: the weighted residuals decide its direction, so a poorly
        conditioned pair of parameters is not swung across its range to chase a response
        known only to its scatter."""
        held: list[int] = []
        du = np.zeros_like(u)
        damp = self.damping if damping is None else damping
        cap = self.max_step if cap is None else cap
        w = np.ones(len(e)) if weights is None else np.asarray(weights, float)
        # a probed parameter moves half the cap into the box; the others answer that move
        fixed_du = {j: 0.5 * cap * (1.0 if u[j] <= 0.5 * (box[0][j] + box[1][j]) else -1.0)
                    for j in probe}
        while True:
            act = [j for j in range(len(u)) if j not in held and j not in fixed_du]
            du[:] = 0.0
            for j, v in fixed_du.items():
                du[j] = v
            r = e + J @ du
            if act:
                du[act] = _lm_step(w[:, None] * J[:, act], w * r, cap / damp) * damp
            out = [j for j in act if (u[j] <= box[0][j] + _EDGE and du[j] < 0)
                   or (u[j] >= box[1][j] - _EDGE and du[j] > 0)]
            if not out:
                break
            held += out
        biggest = float(np.max(np.abs(du))) if len(du) else 0.0
        if biggest > cap:
            du *= cap / biggest
        return du, sorted(held)

    def run(self, initial: Mapping[str, float]) -> ClosedLoopResult:
        """Iterate from ``initial`` (a full parameter set, e.g. ``invert(...).solution``)."""
        space = self._space(initial)
        box = space.loop_box(self.margin)
        u = space.u(space.free_values(initial))
        xlo, xhi = space.limits(box)
        inside = (u >= box[0] - 1e-12) & (u <= box[1] + 1e-12)
        if not np.all(inside):
            bad = [f"{p}={space.x(u)[j]:g} outside [{xlo[j]:g}, {xhi[j]:g}] "
                   f"({space.bound_origins()[p]['lower']} .. "
                   f"{space.bound_origins()[p]['upper']}"
                   + (f", widened by the margin {self.margin:g}" if self.margin else "") + ")"
                   for j, p in enumerate(space.free) if not inside[j]]
            raise ParameterError(f"initial value(s) outside the bounds: {'; '.join(bad)} - the loop "
                                 "starts inside the ranges widened by its margin (the "
                                 f"verification's range margin; now {self.margin:g})")
        u = np.clip(u, *box)
        J = self._initial_jacobian(space, space.x(u))
        scale = np.abs(self.t)
        seeds = list(self.seeds)
        spare = list(self.growth_seeds)
        history, samples, prev = [], [], None
        polished_from, best_idx = None, None  # the converged round a polishing step left; the card's round
        cap = self.max_step  # the trust region: the step cap, halved after a worse round
        held_rounds = [0] * len(space.free)  # rounds each parameter has been held at a bound
        base = None  # (u, e, merit) of the best round so far: the point the next step starts from
        pooled, dof = np.zeros(len(self.responses)), 0  # Σ (k-1) cv², Σ (k-1)
        status, message = "max_rounds", f"tolerance not met within {self.max_rounds} rounds"

        def run_seeds(rnd, params, which) -> np.ndarray:
            ys = np.empty((len(which), len(self.responses)))
            for i, sd in enumerate(which):
                ys[i] = self._simulate(params, sd)
                samples.append({"round": rnd, "seed": sd, **dict(zip(self.responses, ys[i]))})
            return ys

        def failed(ys) -> list:
            """(seed, responses) of every run of the round with a non-finite response."""
            return [(sd, dict(zip(self.responses, row))) for sd, row in zip(seeds, ys)
                    if not np.all(np.isfinite(row))]

        def judge(ys):
            """mean, seed CV, SE (pooled with the earlier rounds), tolerance, error."""
            k = len(ys)
            y = ys.mean(axis=0)
            cv = ys.std(axis=0, ddof=1) / np.abs(y) if k > 1 else np.full(len(y), np.nan)
            se = (np.sqrt((pooled + (k - 1) * cv ** 2) / (dof + k - 1)) / math.sqrt(k)
                  if k > 1 else np.zeros(len(y)))
            return y, cv, se, np.maximum(self.rtol, self.z * se), (y - self.t) / scale

        for rnd in range(self.max_rounds):
            params = space.full(space.x(u))
            ys = run_seeds(rnd, params, seeds)
            rec = {"round": rnd, **{p: params[p] for p in space.calibrated}}
            grown = 0
            bad = failed(ys)
            if not bad:
                y, cv, se, tol, e = judge(ys)
                if np.all(np.abs(e) <= tol) and spare and np.any(self.z * se > self.rtol):
                    grown, seeds, spare = len(spare), seeds + spare, []
                    ys = np.vstack([ys, run_seeds(rnd, params, seeds[-grown:])])
                    bad = failed(ys)
                    if not bad:
                        y, cv, se, tol, e = judge(ys)
            k = len(ys)
            rec.update({**dict(zip(self.responses, ys.mean(axis=0))), "n_seeds": k, "grown": grown})
            if bad:
                history.append(rec)
                status = "failed"
                txt = "; ".join(f"seed {sd}: {v}" if sd is not None else str(v) for sd, v in bad)
                message = f"round {rnd} returned non-finite responses ({txt})"
                if polished_from is not None:  # the converged round before it stands
                    status, best_idx = "converged", polished_from
                    message = (f"converged after {polished_from + 1} round(s); the polishing "
                               f"round {rnd + 1} failed ({txt}), so round {polished_from + 1} "
                               "stays the card's")
                break
            if k > 1:
                pooled += (k - 1) * cv ** 2
                dof += k - 1
            rec.update({f"cv_{r}": v for r, v in zip(self.responses, cv)})
            rec.update({f"se_{r}": v for r, v in zip(self.responses, se)})
            rec.update({f"tol_{r}": v for r, v in zip(self.responses, tol)})
            rec.update({f"err_{r}": v for r, v in zip(self.responses, e)})
            rec["max_abs_err"] = float(np.max(np.abs(e)))
            updated = False
            if prev is not None and self.broyden and prev[2] == k:  # the same seeds: a secant
                s, de = u - prev[0], e - prev[1]
                if s @ s > 1e-16:
                    J = J + np.outer(de - J @ s, s) / (s @ s)
                    updated = True
            rec["broyden_update"] = updated
            within = bool(np.all(np.abs(e) <= tol))
            met = (f"every mean of {k} seeds within max(rtol, {self.z:g} standard errors) of its "
                   "target" if k > 1 else "all relative errors within tolerance")
            if polished_from is not None:  # the polishing round: it, or the round before, is the card's
                history.append(rec)
                status = "converged"
                if within:
                    best_idx = rnd
                    message = (f"{met} after {rnd + 1} round(s), the last a polishing step towards "
                               "the targets")
                else:
                    best_idx = polished_from
                    miss = ", ".join(r for r, x, t in zip(self.responses, e, tol) if not abs(x) <= t)
                    message = (f"{met} after {polished_from + 1} round(s); the polishing step "
                               f"(round {rnd + 1}) left the tolerance in {miss}, so round "
                               f"{polished_from + 1} stays the card's")
                break
            polishing = (within and self.polish and k > 1 and rnd < self.max_rounds - 1
                         and bool(np.any(np.abs(e) > se)))
            if within and not polishing:
                history.append(rec)
                status = "converged"
                message = (f"{met} after {rnd + 1} round(s)" if k > 1
                           else f"{met} after {rnd + 1} simulation(s)")
                break
            if rnd == self.max_rounds - 1:
                history.append(rec)
                break
            # the trust region: step from the best round so far; a worse round halves the cap
            merit = float(np.sum((e / tol) ** 2))
            # a grown seed set measures on other packings with a smaller SE (a tighter
            # tolerance): its rounds are not compared with the earlier ones
            accepted = base is None or polishing or base[3] != k or merit <= base[2]
            if accepted:
                base = (u.copy(), e.copy(), merit, k)
            else:  # half the step that led here (the cap may not have bound it)
                cap = 0.5 * float(np.max(np.abs(u - base[0])))
            rec["accepted"], rec["step_cap"] = accepted, cap
            u_from, e_from = base[0], base[1]
            # a parameter held at a bound two rounds running while the loop misses: its
            # column of J was never measured (Broyden learns along the steps taken), so the
            # step probes it - half the cap into the box - instead of trusting the sign
            probe = [j for j in range(len(u)) if held_rounds[j] >= 2] if not polishing else []
            du, held = self._step(J, e_from, u_from, box, 1.0 if polishing else None,
                                  None if polishing else cap, weights=1.0 / tol, probe=probe)
            for j in range(len(u)):
                held_rounds[j] = 0 if j in probe else (held_rounds[j] + 1 if j in held else 0)
            rec["probed"] = ",".join(space.free[j] for j in probe)
            u_new = np.clip(u_from + du, *box)
            rec.update({f"step_{p}": v for p, v in zip(space.free, (u_new - u) * space.width)})
            cut = [j for j in range(len(u)) if j in held or u_new[j] != u_from[j] + du[j]]
            rec["clipped"] = ",".join(space.free[j] for j in cut)
            rec["polish"] = polishing
            history.append(rec)
            if np.max(np.abs(u_new - u_from)) < 1e-9:
                if polishing:  # nothing left to move: this round is the card's
                    status, message = "converged", f"{met} after {rnd + 1} round(s)"
                    break
                edges = ", ".join(space.edge_text(p, side, v, self.margin)
                                  for p, side, v in space.at_bound(u_from, box))
                status = "stalled"
                message = (f"the Newton step points out of the bounds ({edges}); the targets appear "
                           "unreachable within the parameter ranges")
                break
            if polishing:
                polished_from = rnd
            prev, u = (u, e, k), u_new
        hist = pd.DataFrame.from_records(history)
        if status == "max_rounds" and len(hist) > 1 and hist["clipped"].iloc[-2]:
            message += (f"; the last step was cut at the bounds of {hist['clipped'].iloc[-2]}: the targets "
                        "may lie outside what the parameter ranges can reach")
        finite = hist.dropna(subset=["max_abs_err"]) if "max_abs_err" in hist else hist.iloc[:0]
        if status == "converged":
            best = hist.iloc[-1 if best_idx is None else best_idx]
        else:
            best = hist.loc[finite["max_abs_err"].idxmin()] if len(finite) else hist.iloc[-1]
        x_best = np.array([best[p] for p in space.free])
        J_phys = J * scale[:, None] / space.width
        return ClosedLoopResult(
            status=status, message=message, history=hist, params=space.full(x_best),
            responses={r: float(best[r]) for r in self.responses},
            jacobian=pd.DataFrame(J_phys, index=list(self.responses), columns=list(space.free)),
            samples=pd.DataFrame.from_records(samples),
            seed_cv={r: float(best.get(f"cv_{r}", np.nan)) for r in self.responses},
            n_seeds=int(best["n_seeds"]), seeds=tuple(seeds[:int(best["n_seeds"])]),
            best_round=int(best["round"]), outside=_outside(space, space.full(x_best)),
            loop_bounds={p: (float(a), float(b)) for p, a, b in zip(space.free, xlo, xhi)})


def _lm_step(A: np.ndarray, b: np.ndarray, cap: float) -> np.ndarray:
    """The step ``x`` minimising ``|A x + b|²`` (Gauss-Newton) when it lies within ``cap``
    in the max norm, else the Levenberg-Marquardt step ``-(AᵀA + λI)⁻¹ Aᵀ b`` with the
    λ that brings it onto the cap (bisection on log λ; the step shrinks monotonically
    with λ and turns from the Gauss-Newton towards the steepest-descent direction)."""
    x = -np.linalg.lstsq(A, b, rcond=None)[0]
    if not np.all(np.isfinite(x)) or float(np.max(np.abs(x))) <= cap:
        return x
    AtA, Atb = A.T @ A, A.T @ b
    n = AtA.shape[0]
    scale = float(np.trace(AtA)) / n or 1.0

    def step(lam):
        return -np.linalg.solve(AtA + lam * scale * np.eye(n), Atb)

    lo, hi = -12.0, 12.0  # log10 of λ / mean diagonal
    if float(np.max(np.abs(step(10.0 ** hi)))) > cap:  # not even the gradient step fits
        return step(10.0 ** hi)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if float(np.max(np.abs(step(10.0 ** mid)))) > cap:
            lo = mid
        else:
            hi = mid
    return step(10.0 ** hi)


def _outside(space: _Space, params: Mapping[str, float]) -> dict[str, dict]:
    """The calibrated parameters of ``params`` outside their design range: value and range."""
    out = {}
    for p in space.calibrated:
        lo, hi = space.ranges[p]
        v = float(params[p])
        if not _inside(v, lo, hi):
            out[p] = {"value": v, "range": [float(lo), float(hi)]}
    return out


def _takes_seed(simulate: Callable) -> bool:
    """Whether ``simulate`` accepts a keyword ``seed`` (a parameter of that name or
    ``**kwargs``)."""
    import inspect

    try:
        sig = inspect.signature(simulate)
    except (TypeError, ValueError):
        return False
    return any(p.name == "seed" and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
               or p.kind == p.VAR_KEYWORD for p in sig.parameters.values())


def _round_seeds(simulate: Callable, seeds_per_round: int | None, seeds: Sequence[int] | None) -> tuple:
    """The packing seeds of every closed-loop round (``(None,)``: a single-seed simulator)."""
    if seeds_per_round is not None and (isinstance(seeds_per_round, bool)
                                        or not isinstance(seeds_per_round, (int, np.integer))
                                        or seeds_per_round < 1):
        raise ValueError(f"seeds_per_round={seeds_per_round!r}: expected an integer >= 1")
    if not _takes_seed(simulate):
        if (seeds_per_round or 1) > 1 or seeds is not None:
            raise ValueError("simulate(params) takes no seed argument, so it cannot run several packing "
                             "seeds per round: give it a 'seed' parameter, or use seeds_per_round=1")
        return (None,)
    if seeds is None:
        return tuple(range(1, (3 if seeds_per_round is None else int(seeds_per_round)) + 1))
    out = []
    for sd in seeds:
        if isinstance(sd, bool) or not isinstance(sd, (int, np.integer)) or sd < 0:
            raise ValueError(f"seeds: {sd!r} is not a packing seed (an integer >= 0)")
        out.append(int(sd))
    if not out or len(set(out)) != len(out):
        raise ValueError(f"seeds={list(seeds)!r}: expected distinct packing seeds, at least one")
    if seeds_per_round is not None and seeds_per_round != len(out):
        raise ValueError(f"seeds_per_round={seeds_per_round} but {len(out)} seeds given")
    return tuple(out)


def seed_scatter(sims: pd.DataFrame | Sequence[Mapping[str, float]], rtol: float | Mapping[str, float] = 0.01,
                 responses: Sequence[str] = TARGETS, n_per_round: int = 1) -> pd.DataFrame:
    """Judge a closed-loop tolerance against the packing-seed scatter of the simulator.

    ``sims`` holds the responses of ONE parameter set simulated with several packing seeds
    (one row per seed). Per response: n, mean, sample std (ddof=1), coefficient of variation
    ``cv = std / |mean|`` (the relative scatter of a single run), the relative standard
    error of one closed-loop evaluation ``se = cv / sqrt(n_per_round)`` (``n_per_round``
    seeds averaged per round), the noise floor ``2 se`` and ``noise_limited = rtol < 2 se``:
    such a tolerance is below the noise - a parameter set that is exactly right would fail
    it in more than ~5 % of evaluations and the loop would chase noise.
    """
    frame = pd.DataFrame(sims) if not isinstance(sims, pd.DataFrame) else sims
    responses = check_responses(responses)
    if not isinstance(n_per_round, (int, np.integer)) or n_per_round < 1:
        raise ValueError(f"n_per_round={n_per_round!r}: expected an integer >= 1")
    recs = []
    for r in responses:
        if r not in frame:
            raise ValueError(f"sims lacks response {r!r}; it has {list(frame.columns)}")
        v = pd.to_numeric(frame[r], errors="coerce").to_numpy(float)
        v = v[np.isfinite(v)]
        if len(v) < 2:
            raise ValueError(f"{r}: {len(v)} finite value(s); need at least 2 seeds to estimate the scatter")
        tol = float(rtol[r] if isinstance(rtol, Mapping) else rtol)
        mean, std = float(v.mean()), float(v.std(ddof=1))
        cv = std / abs(mean) if mean != 0 else math.inf
        se = cv / math.sqrt(n_per_round)
        recs.append({"response": r, "n": len(v), "mean": mean, "std": std, "cv": cv, "se": se,
                     "noise_floor": 2 * se, "rtol": tol, "noise_limited": tol < 2 * se})
    return pd.DataFrame.from_records(recs).set_index("response")


__all__ = ["PAPER_RATIO", "PAPER_FIXED", "DEFAULT_FREE", "BTS", "bts_strengths", "InversionResult", "invert",
           "BootstrapResults", "bootstrap_intervals", "ClosedLoop", "ClosedLoopResult", "seed_scatter"]
