"""Inversion of the regression models for laboratory targets (:func:`invert`).

Multi-start bounded least squares of the relative residuals over the free parameters
of a :class:`~.space.CalibrationSpace`; the outcome is ``ok``, ``non-unique``,
``unreachable`` or ``no-exact-fit`` (:class:`InversionResult`), with the configured
limits to widen (:mod:`.widen`) when the targets are out of reach, and, with a tensile
strength among the targets, the σt and σc/σt spans the models reach while meeting the
other targets (:func:`_bts_reach`).

The method: ``docs/methods/calibration.md`` (sections "Inversion" and "Tensile strength").
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from bpmcal.params import BTS

from ..stepwise import RegressionModel
from .fit import _fit, _fmt_pct, _lhs
from .reach import reach_text, reach_within_error
from .space import CalibrationSpace, SearchSpace, _check_targets, tensile_target
from .widen import _what_to_widen


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
    reach_test: dict = field(default_factory=dict)  # the miss against the models' error (.reach)

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
        """Met exactly by the models (``ok``, ``non-unique``); a ``within-error`` miss is
        not, though it is within their own error."""
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



@dataclass(frozen=True)
class Multistart:
    """How :func:`invert` searches: ``n_starts`` Latin-hypercube starting points in the
    free-parameter box (``seed``); ``tol``, the largest relative residual that counts as
    meeting the targets; ``distinct``, solutions further apart than this fraction of a
    range are distinct; ``diagnose``, say what to widen when the targets are missed."""

    n_starts: int = 24
    seed: int = 0
    tol: float = 1e-3
    distinct: float = 0.02
    diagnose: bool = True

    def __post_init__(self):
        if not self.tol > 0 or not self.distinct > 0:
            raise ValueError(f"tol={self.tol!r}, distinct={self.distinct!r}: expected positive "
                             "numbers")


def invert(models: Mapping[str, RegressionModel], targets: Mapping[str, float],
           fixed: Mapping[str, float], space: SearchSpace, *, search: Multistart = Multistart(),
           x0: Sequence[Mapping[str, float]] = (), errors: Mapping | None = None,
           target_se: Mapping[str, float] | None = None) -> InversionResult:
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
    space:
        The :class:`~.space.SearchSpace`: ``ranges``, the design space (parameter -> (lo,
        hi) the dataset was sampled over, the study config's ``ranges``, paper units;
        required for every free parameter and for the tensile strength with a ratio: the
        free parameters are confined to it); ``free``, the parameters to solve for
        (default :data:`DEFAULT_FREE`, plus ``pb_ten_MPa`` when ``ratio`` is None);
        ``ratio``, ``pb_ten_MPa / pb_coh_MPa`` (default 1.4; None: independent
        strengths); ``bounds``, parameter -> (lo, hi) narrowing ``ranges`` for a free (or
        the derived) parameter (bounds reaching beyond ``ranges`` are an error: the
        regression is not valid there).
    search:
        :class:`Multistart`: the starting points and their seed, the residual that counts
        as met (``tol``), when two solutions are distinct, and ``diagnose``: for
        ``unreachable`` and ``no-exact-fit``, search the extrapolated regression for
        which configured limit to widen and how far (``widen``, ``advice``; costs one more
        multi-start), and with a σt target the spans the models reach (``reach``).
    x0:
        Extra starting points (mappings holding the free parameters), tried first.
    errors, target_se:
        The models' prediction errors (:func:`~.reach.prediction_errors`) and the lab
        values' standard errors: when the targets are not met exactly, whether the miss
        is within the models' own error (:func:`~.reach.reach_within_error`,
        ``reach_test``). Within it the status is ``within-error`` (no advice to widen or to
        change the model: the regression cannot tell); beyond it ``no-exact-fit`` or
        ``unreachable`` with the probability stated. Without ``errors`` the models are
        taken as exact (the bootstrap's resamples).
    """
    tol = search.tol
    space = CalibrationSpace(space.free, fixed, space.ratio, space.ranges, space.bounds)
    responses, t = _check_targets(targets, models)
    space.check_models(models, responses)
    fits = _fit(space, models, responses, t, space.lo, space.hi, [space.free_values(p) for p in x0],
                search.n_starts, search.seed)
    fits = [(c, m, space.u(x), r) for c, m, x, r in fits]
    best_cost, best_max, best_u, best_r = fits[0]
    reachable = best_max <= tol
    kept = _distinct(fits, reachable, tol, search.distinct)
    alternatives = _fits_frame(space, models, responses, kept)
    start_frame = _fits_frame(space, models, responses, fits)
    solution = space.full(space.x(best_u))
    edges = space.at_bound(best_u)
    v = _verdict(space, models, targets, responses, t, (best_u, best_r), reachable, len(kept),
                 edges, search=search, errors=errors, target_se=target_se)
    status, message, widen, advice, reach, test = v
    return InversionResult(
        status=status, message=message, solution=solution, free=space.free, derived=space.derived,
        targets=dict(zip(responses, t.tolist())),
        predicted={r: float(models[r].predict(solution)) for r in responses},
        residuals=dict(zip(responses, best_r.tolist())),
        bounds=space.bounds(),
        at_bound=edges, alternatives=alternatives, starts=start_frame, tol=tol,
        bound_origins=space.bound_origins(), ranges=dict(space.ranges), widen=widen, advice=advice,
        reach=reach, reach_test=test)


def _verdict(space: CalibrationSpace, models, targets, responses, t, best: tuple, reachable: bool,
             n_kept: int, edges, *, search: Multistart, errors, target_se) -> tuple:
    """The status and message of an inversion, with what to widen (``widen``, ``advice``),
    the σt spans (``reach``) and the test of the miss against the models' own error
    (``test``; :mod:`.reach`): a miss within that error is ``within-error`` and gets no
    advice to widen or to change the model. ``best``: the best fit's unit point and
    residuals."""
    best_u, best_r = best
    tol, n_starts, seed, diagnose = search.tol, search.n_starts, search.seed, search.diagnose
    x_best = space.x(best_u)
    test = {}
    if not reachable and errors:
        test = reach_within_error(space, models, errors, dict(zip(responses, t.tolist())),
                                  target_se, [x_best], seed=seed + 5)
    within = bool(test) and test["reachable"]
    widen, advice = [], ""
    if not reachable and diagnose and not within:
        widen, advice = _what_to_widen(space, models, responses, t, x_best, tol, n_starts, seed + 1)
    reach, joint = {}, ""
    if not reachable and not within:
        reach, joint = _joint_bts_diagnosis(space, models, targets, responses, t, x_best, tol,
                                            n_starts, seed, diagnose)
    status, message = _classify(space, responses, best_r, n_kept, reachable, joint, edges, advice, tol)
    if within:
        status = "within-error"
        message = (f"the models do not meet the targets exactly (relative residuals "
                   f"{_fmt_pct(responses, best_r)}), but {reach_text(test)}.")
    elif test:
        message = f"{message} Counting their error, {reach_text(test)}."
    return status, message, widen, advice, reach, test


def _distinct(fits: list[tuple], reachable: bool, tol: float, distinct: float) -> list[tuple]:
    """The distinct solutions among the fits (unit coordinates, best first): those that
    meet the targets (or, when none does, that fit as well as the best), each more than
    ``distinct`` of a range away from every one kept before it."""
    best_cost = fits[0][0]
    good = [f for f in fits if (f[1] <= tol if reachable else f[0] <= best_cost * (1 + 1e-6) + 1e-14)]
    kept: list[tuple] = []
    for f in good:
        if all(np.max(np.abs(f[2] - k[2])) > distinct for k in kept):
            kept.append(f)
    return kept


def _fits_frame(space: CalibrationSpace, models, responses, fits: list[tuple]) -> pd.DataFrame:
    """One row per fit: the calibrated parameters, the predicted responses, the largest
    relative residual and the sum of squares."""
    def row(f):
        point = space.full(space.x(f[2]))
        rec = {p: point[p] for p in space.calibrated}
        rec.update({r: float(models[r].predict(point)) for r in responses})
        rec.update(max_abs_residual=f[1], sum_sq=f[0])
        return rec

    return pd.DataFrame.from_records([row(f) for f in fits])


def _joint_bts_diagnosis(space: CalibrationSpace, models, targets: Mapping[str, float], responses, t,
                         x_best, tol: float, n_starts: int, seed: int, diagnose: bool) -> tuple[dict, str]:
    """A missed fit with a tensile-strength target among others: when the other targets are
    met together inside the bounds, the σt (and σc/σt) spans the models reach while meeting
    them (``reach``; only with ``diagnose``) and the sentence that the target set cannot be
    met at once (``joint``); else ``({}, "")``."""
    reach: dict = {}
    joint = ""  # the σt target set is out of reach although the other targets are not
    tr = tensile_target(responses)
    if tr is not None and len(responses) > 1:
        others = [r for r in responses if r != tr]
        t_other = np.array([t[responses.index(r)] for r in others])
        sub = _fit(space, models, others, t_other, space.lo, space.hi, [x_best], n_starts, seed + 2)
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
                     f"outside what the {space.model.title} models reach ({span})"
                     + _ratio_advice(space, targets, t_bts, reach))
    return reach, joint


def _ratio_advice(space: CalibrationSpace, targets: Mapping[str, float], t_bts: float,
                  reach: dict) -> str:
    """The registry's advice (:attr:`ContactModel.ratio_advice`) when the target σc/σt
    lies above or below the σc/σt span the models reach; else ``""``."""
    advice = space.model.ratio_advice or {}
    if "ucs_over_bts" not in reach or "ucs_MPa" not in targets:
        return ""
    q = targets["ucs_MPa"] / t_bts
    lo, hi = reach["ucs_over_bts"]
    side = "above" if q > hi else "below" if q < lo else None
    return f"; {advice[side]}" if side in advice else ""


def _classify(space: CalibrationSpace, responses, best_r: np.ndarray, n_kept: int, reachable: bool,
              joint: str, edges: list, advice: str, tol: float) -> tuple[str, str]:
    """The status and message of an inversion (module docs, "Inversion"): ``ok``,
    ``non-unique`` (``n_kept`` distinct solutions), ``no-exact-fit`` (the σt target set
    ``joint`` out of reach, or an interior optimum) or ``unreachable`` (a bound active)."""
    missed = "; ".join(f"{r} {100 * v:+.2f} %" for r, v in zip(responses, best_r) if abs(v) > tol)
    if reachable and n_kept == 1:
        return "ok", f"targets met within {tol:g} (relative): {_fmt_pct(responses, best_r)}"
    if reachable:
        extra = (f"; {len(space.free)} free parameters for {len(responses)} targets: a continuum of solutions"
                 if len(space.free) > len(responses) else "")
        return "non-unique", (f"{n_kept} distinct parameter sets meet the targets within {tol:g}{extra}; "
                              "see alternatives (the best-fitting one is returned)")
    tail = f" {advice}" if advice else ""
    if joint:
        where = ", ".join(space.edge_text(p, side, v) for p, side, v in edges)
        return "no-exact-fit", (f"{joint}. The card keeps the best compromise (least squares of the "
                                f"relative residuals, equal weights){' with ' + where if where else ''}; "
                                f"targets missed: {missed} (relative residuals "
                                f"{_fmt_pct(responses, best_r)}, tol {tol:g})." + tail)
    if edges:
        where = ", ".join(space.edge_text(p, side, v) for p, side, v in edges)
        return "unreachable", (f"targets lie outside what the sampled ranges can reach: the closest point "
                               f"inside the bounds has {where}, relative residuals "
                               f"{_fmt_pct(responses, best_r)}; this point is not a calibration." + tail)
    return "no-exact-fit", (f"the models cannot meet all targets at once: the best compromise is an "
                            f"interior optimum (no bound of the configured ranges is active), relative "
                            f"residuals {_fmt_pct(responses, best_r)} exceed {tol:g}." + tail)


def _bts_reach(space: CalibrationSpace, models, others: Sequence[str], t_other: np.ndarray, tol: float,
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

