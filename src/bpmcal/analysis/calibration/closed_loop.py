"""The closed loop: correct a calibration with the simulator itself (:class:`ClosedLoop`).

Every round runs the candidate on the same packing seeds and steers their mean: stop
when every mean is within max(rtol, z standard errors) of its target, else take a
damped, weighted Gauss-Newton (or Levenberg-Marquardt) step in the unit cube from the
best round so far (a trust region that shrinks after a worse round and grows again
after a better one its cap cut), with the Jacobian started from the regression models
(a strength's slope against a bond strength held at >= 0: a stronger bond never makes
a weaker specimen) and corrected by Broyden's secant update, each row shrunk by its
signal-to-noise ratio (a change within the seeds' scatter barely moves it). Parameters
held at a bound are
probed; the seed set can grow once the means are near their targets (``grow_within``
tolerances) while a standard error is too large to state a target to ``rtol``; a
converged seed-averaged loop may take one polishing step.

This module is the driver: it checks the settings, runs the rounds, decides when the
loop ends and which round is the card's. Where the next round goes (the Jacobian, its
updates, the step and the trust region) is :mod:`.step_rule`'s; which seeds a round runs,
how its mean is judged and when the seed set grows is :mod:`.seed_policy`'s.

The method: ``docs/methods/calibration.md`` (section "Closed loop").
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from bpmcal.params import AUTO_ROUNDS, ParameterError, auto_rounds

from ..stepwise import RegressionModel
from .loop_settings import check_loop_value
from .seed_policy import (
    Round,
    SeedPolicy,
    SeedStats,
    check_seed_caps,
    growth_seeds,
    relative_target_se,
    response_means,
    round_seeds,
)
from .space import (
    CalibrationSpace,
    SearchSpace,
    _check_ranges,
    _check_targets,
    _default_free,
    _inside,
    space_model,
)
from .step_rule import HISTORY_MIN_STEP, StepRule, TrustRegion, initial_jacobian


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
    mean, ``n_seeds``, the Jacobian rows the round's secant updated (``broyden_rows``)
    and the step; ``samples`` one row per simulation (round, seed,
    responses). ``jacobian`` is the final Broyden estimate of ∂response/∂parameter in
    physical units. ``sign_held``: the starting Jacobian's entries set to 0 because the
    regression gave a strength that falls with a bond strength (response, parameter, the
    regression's slope; :func:`step_rule.hold_signs`). ``max_rounds``: the round budget
    the loop had (``"auto"`` resolved by :func:`auto_rounds`).
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
    sign_held: list = field(default_factory=list)
    max_rounds: int = 0

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


def _loop_options(responses, rtol, max_rounds, margin, polish, update, grow_within) -> tuple:
    """:class:`ClosedLoop`'s keywords that are :class:`LoopSettings` fields, checked as it
    checks them (``check_loop_value``: one set of limits; a ValueError naming the keyword):
    (rtol per response, max_rounds, margin, polish, update, grow_within). A mapping
    ``rtol`` (a tolerance of each target, e.g. the transfer's, derived from the seed
    scatter) needs positive values only."""
    if isinstance(rtol, Mapping):
        rt = {r: float(rtol[r]) for r in responses}
        if not all(v > 0 for v in rt.values()):
            raise ValueError(f"rtol={rtol!r}: expected positive relative tolerance(s)")
    else:
        rt = dict.fromkeys(responses, check_loop_value("rtol", rtol))
    return (rt, check_loop_value("max_rounds", max_rounds),
            check_loop_value("range_margin", margin, "margin"),
            check_loop_value("polish", polish),
            check_loop_value("jacobian_update", update, "update"),
            check_loop_value("grow_within", grow_within))


@dataclass(frozen=True)
class LoopSteps:
    """How a :class:`ClosedLoop` judges and takes its rounds: ``rtol``, ``max_rounds``,
    ``margin``, ``polish``, ``update``, ``damping``, ``max_step``, ``min_step``,
    ``broyden`` and ``z`` (each as :class:`ClosedLoop`'s docstring gives it; those that
    are :class:`LoopSettings` fields checked with its limits when the loop starts)."""

    rtol: float | Mapping[str, float] = 0.01
    max_rounds: int | str = "auto"
    margin: float = 0.0
    polish: bool = True
    update: str = "broyden"
    damping: float = 0.8
    max_step: float = 0.25
    min_step: float | None = None
    broyden: bool = True
    z: float = 2.0


@dataclass(frozen=True)
class LoopSeeds:
    """Which packing seeds a :class:`ClosedLoop`'s rounds run and how the set grows:
    ``seeds_per_round``, ``seeds``, ``max_seeds``, ``grow_within`` and ``seed_caps``
    (as :class:`ClosedLoop`'s docstring gives them)."""

    seeds_per_round: int | None = None
    seeds: Sequence[int] | None = None
    max_seeds: int | None = None
    grow_within: float = 2.0
    seed_caps: Mapping[str, int] | None = None


class ClosedLoop:
    """Newton-Broyden closed-loop correction of a calibration with the simulator itself.

    Its options come in three values: ``space`` (:class:`~.space.SearchSpace`: ``free``, ``ratio``,
    ``ranges``, ``bounds``), ``steps`` (:class:`LoopSteps`: ``rtol``, ``max_rounds``,
    ``margin``, ``polish``, ``update``, ``damping``, ``max_step``, ``min_step``,
    ``broyden``, ``z``) and ``seeding`` (:class:`LoopSeeds`: ``seeds_per_round``,
    ``seeds``, ``max_seeds``, ``grow_within``, ``seed_caps``).

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
        Maximum number of rounds, each of ``seeds_per_round`` simulations: an integer,
        or ``"auto"`` (the default): :func:`auto_rounds`, two rounds per free parameter
        (6 for the paper's three).
    seeds_per_round, seeds:
        The packing seeds every round runs (the same in every round): ``seeds`` (distinct
        integers), else 1..``seeds_per_round``; default 3 seeds for a simulator with a
        ``seed`` parameter, 1 (and no seed) for ``simulate(params)``, which cannot take
        more.
    max_seeds:
        The seed set may grow to this many seeds (the next integers after the largest of
        ``seeds``) once the means are within ``grow_within`` tolerances but a standard
        error is too large to state them to ``rtol`` (module docstring); default (or at
        most the seeds of a round): no growth.
    grow_within:
        The seed set grows once every mean is within ``grow_within`` times its tolerance
        (default 2; 1: only once within tolerance), when a standard error is too large to
        state a target to ``rtol``. The tolerance is judged on the few seeds' own spread,
        and three seeds' standard deviation falls below half the true one in about one
        draw in five (chi-square, 2 degrees of freedom; the rounds reuse those seeds, so
        pooling them does not add independent packings): a loop that fits those seeds
        to within such a tolerance fits their offset. Within a few tolerances the
        remaining error is of that size, so the last rounds steer the grown set instead.
    seed_caps:
        Response -> the number of a round's seeds that measure it (the first ones of the
        seed set; default: every seed measures every response). A costly test is judged
        on fewer packings than the cheap ones: with ``max_seeds`` 20 and
        ``{"tri_MPa": 10}`` the triaxial strength is measured on the first 10 seeds and
        every other response on all 20. Whatever the simulator returns for a response on a
        seed past its cap is ignored (it need not run that test there); the response's
        mean, seed CV, standard error and secant use its own seeds only, and the seed set
        grows only for a response whose cap lets it take more.
    z:
        Standard errors of the mean within which a target counts as met (default 2).
    damping, max_step:
        Newton step factor (default 0.8) and cap on the move of any parameter per round
        as a fraction of its range (default 0.25); after a round that is worse than the
        best so far the cap becomes half that round's step, after a better round that a
        step at the cap reached it doubles, up to ``max_step`` (the trust region, module
        docstring).
    broyden:
        Correct the Jacobian with the measured rounds (default True); False keeps the
        starting estimate throughout.
    update:
        How the measured rounds correct it: ``"broyden"`` (default), Broyden's secant
        rule between consecutive rounds on the same seeds, each row shrunk by its
        signal-to-noise ratio; ``"history"``, every judged round at once: each row is the
        posterior mean of a local linear model fitted to all rounds' means (each weighted
        by its standard error and by its distance from the best round so far), with the
        starting Jacobian as its prior (:meth:`StepRule.history_jacobian`). Broyden
        remembers the last step exactly and the earlier ones only through its rank-one
        updates; the history fit keeps them all, so a response that depends on several
        parameters at once is resolved once the steps span them. The step then starts
        from the fitted errors at the best round, not from its own: the rounds near it
        average its scatter.
    simulate_seeds:
        Optional ``simulate_seeds(params, seeds)`` -> one responses mapping per seed, in
        the order of ``seeds``: runs a round's seeds (and a grown set's new seeds) at
        once, e.g. side by side on several CPUs (``stages.pool.SeedPool``); ``simulate``
        is then used only where a single run is asked for. Its results must be those
        ``simulate(params, seed=s)`` gives for each seed: the loop's path does not depend
        on it.
    report:
        Called after every judged round with a one-line summary (the round, its seeds,
        each response's error and tolerance in %): the progress of a loop whose rounds
        take minutes each.
    min_step:
        The trust region's smallest cap (fraction of a range; default 0 with
        ``"broyden"``, ``max_step`` / 8 with ``"history"``). A round is judged worse than
        the best on a merit that carries the seeds' scatter: several worse rounds in a row
        (one real overshoot, then noise) would otherwise halve the cap each time until the
        loop can no longer move.
    margin:
        How far the loop may leave the design space: every bound that is a design range
        (``ranges``) moves out by ``margin`` times the range's width, never past the
        parameter's physical domain nor a ``bounds`` narrowing (default 0: the loop stays
        inside the ranges). The regression only starts the loop (its Jacobian); every
        round measures the simulator itself, so the loop can follow a target just outside
        the sampled space, e.g. a stiffness ratio that a smaller verification specimen
        needs for the rock's ν. :attr:`ClosedLoopResult.outside` lists what ended outside.
    target_se:
        Standard errors of the lab values, response -> value in the target's unit (e.g.
        the lab's standard deviation over its n specimens / sqrt(n); default none: the
        targets are exact). A target known only to its standard error is met when the
        mean is within max(rtol, z · sqrt(SE² + SE_lab²)) of it: the comparison of two
        means, each with its error. Without it, a lab mean that is itself off the rock's
        by a few standard errors asks the loop to fit that error.
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
                 space: SearchSpace, models: Mapping[str, RegressionModel] | None = None,
                 jacobian: pd.DataFrame | None = None, steps: LoopSteps = LoopSteps(),
                 seeding: LoopSeeds = LoopSeeds(), target_se: Mapping[str, float] | None = None,
                 report: Callable[[str], None] | None = None,
                 simulate_seeds: Callable[[dict, list], Sequence[Mapping[str, float]]] | None = None):
        free, ratio, ranges, bounds = space.free, space.ratio, space.ranges, space.bounds
        rtol, max_rounds, margin, polish = steps.rtol, steps.max_rounds, steps.margin, steps.polish
        update, damping, max_step, min_step = steps.update, steps.damping, steps.max_step, steps.min_step
        broyden, z = steps.broyden, steps.z
        seeds_per_round, seeds, max_seeds = seeding.seeds_per_round, seeding.seeds, seeding.max_seeds
        seed_caps, grow_within = seeding.seed_caps, seeding.grow_within
        if not callable(simulate):
            raise TypeError(f"simulate={simulate!r}: expected a callable (params, seed) -> responses")
        self.seeds = round_seeds(simulate, seeds_per_round, seeds)
        self.growth_seeds = growth_seeds(self.seeds, max_seeds)
        if not (math.isfinite(float(z)) and float(z) >= 0):
            raise ValueError(f"z={z!r}: expected a number of standard errors >= 0")
        self.z = float(z)
        self.responses, self.t = _check_targets(targets, models)
        self.target_se = relative_target_se(target_se, self.responses, self.t)
        self.seed_caps = check_seed_caps(seed_caps, self.responses)
        if (models is None) == (jacobian is None):
            raise ValueError("give exactly one of models (analytic Jacobian) or jacobian")
        # the loop's settings, checked as LoopSettings checks them (one set of limits)
        rt, self.max_rounds, self.margin, self.polish, update, grow_within = _loop_options(
            self.responses, rtol, max_rounds, margin, polish, update, grow_within)
        if not 0 < damping <= 1:
            raise ValueError(f"damping={damping!r}: expected a factor in (0, 1]")
        if not 0 < max_step <= 1:
            raise ValueError(f"max_step={max_step!r}: expected a fraction of the range in (0, 1]")
        if simulate_seeds is not None and not callable(simulate_seeds):
            raise TypeError(f"simulate_seeds={simulate_seeds!r}: expected a callable "
                            "(params, seeds) -> one responses mapping per seed")
        self.simulate, self.simulate_seeds = simulate, simulate_seeds
        self.free, self.ratio, self.ranges, self.bounds = free, ratio, _check_ranges(ranges), bounds
        self.models, self.jacobian = models, jacobian
        rtol = np.array([rt[r] for r in self.responses])
        if min_step is None:
            min_step = HISTORY_MIN_STEP * max_step if update == "history" else 0.0
        if not (isinstance(min_step, (int, float, np.integer, np.floating))
                and not isinstance(min_step, bool) and 0 <= min_step <= max_step):
            raise ValueError(f"min_step={min_step!r}: expected a fraction of the range in "
                             f"[0, max_step = {max_step!r}]")
        self.report = report
        self.sign_held: list[dict] = []  # the starting Jacobian's entries held to their sign
        #: where the next round goes, and which seeds it runs on
        self.step_rule = StepRule(self.responses, self.t, rtol, self.z, float(damping),
                                  float(max_step), float(min_step), bool(broyden), update)
        self.seed_policy = SeedPolicy(self.responses, self.t, rtol, self.z, self.target_se,
                                      self.seed_caps, grow_within)

    def _space(self, initial: Mapping[str, float]) -> CalibrationSpace:
        model = space_model(self.free, initial, self.ranges)
        ten, coh = model.strength
        free = _default_free(self.free, self.ratio, model)
        derived = (ten,) if self.ratio is not None else ()
        fixed = {k: v for k, v in initial.items()
                 if k not in free and k not in derived and k != "contact_model"}
        space = CalibrationSpace(free, fixed, self.ratio, self.ranges, self.bounds)
        if self.ratio is not None and ten in initial and coh in initial:
            if not math.isclose(float(initial[ten]), self.ratio * float(initial[coh]), rel_tol=1e-9):
                raise ParameterError(f"initial {ten}={initial[ten]!r} differs from ratio × {coh} = "
                                     f"{self.ratio:g} × {initial[coh]!r}")
        return space

    def _initial_jacobian(self, space: CalibrationSpace, x: np.ndarray) -> np.ndarray:
        """The starting Jacobian (:func:`.step_rule.initial_jacobian`); the entries it held
        to their sign (:func:`.step_rule.hold_signs`) go to ``sign_held`` and are reported."""
        self.sign_held = []
        J, self.sign_held = initial_jacobian(space, x, self.responses, self.t, self.models,
                                             self.jacobian)
        if self.sign_held and self.report is not None:
            self.report("closed loop: the regression's slope of " + ", ".join(
                f"{h['response']} against {h['parameter']} ({h['regression']:+.3g})"
                for h in self.sign_held) + " is negative at the start, where a stronger bond "
                "never weakens the specimen: taken as 0 (flat), for the rounds to measure")
        return J

    @property
    def seeds_per_round(self) -> int:
        return len(self.seeds)

    def _simulate(self, params: dict[str, float], seed: int | None) -> np.ndarray:
        out = self.simulate(dict(params)) if seed is None else self.simulate(dict(params), seed=seed)
        return self._responses(out)

    def _responses(self, out: Mapping[str, float] | None) -> np.ndarray:
        return np.array([float(out.get(r, np.nan)) if out is not None else np.nan for r in self.responses])

    def run(self, initial: Mapping[str, float]) -> ClosedLoopResult:
        """Iterate from ``initial`` (a full parameter set, e.g. ``invert(...).solution``)."""
        space = self._space(initial)
        # "auto": resolved once the free parameters are known
        n_rounds = (auto_rounds(len(space.free)) if self.max_rounds == AUTO_ROUNDS
                    else self.max_rounds)
        box = space.loop_box(self.margin)
        u = self._start(space, box, initial)
        J = J0 = self._initial_jacobian(space, space.x(u))
        memory: list[tuple[np.ndarray, Round]] = []  # every judged round (update="history")
        fit = None  # the history fit (u_b, a, J) the next step starts from
        seeds, spare = list(self.seeds), list(self.growth_seeds)
        history, samples, prev = [], [], None
        polished_from = None  # the converged round a polishing step left
        rule = self.step_rule
        trust = TrustRegion(rule.max_step, len(space.free))
        stats = SeedStats(len(self.responses))
        out = _Outcome("max_rounds", f"tolerance not met within {n_rounds} rounds")
        for rnd in range(n_rounds):
            params = space.full(space.x(u))
            rd = self.seed_policy.run_round(rnd, params, seeds, spare, stats, samples,
                                            self._run_seeds)
            seeds, spare = rd.seeds, rd.spare
            rec = {"round": rnd, **{p: params[p] for p in space.calibrated}}
            rec.update({**dict(zip(self.responses, response_means(rd.ys, rd.ks))), "n_seeds": rd.k,
                        "grown": rd.grown})
            rec.update({f"n_{r}": int(rd.ks[i]) for i, r in enumerate(self.responses)
                        if r in self.seed_caps})
            if rd.bad:
                history.append(rec)
                out = self._failed(rnd, rd.bad, polished_from)
                break
            stats.add(rd.ks, rd.cv)
            e, tol = rd.e, rd.tol
            self._record(rec, rd)
            if self.report is not None:
                self.report(_round_line(rnd, rd, self.responses))
            if rule.update == "history":
                memory.append((u.copy(), rd))
                if rule.broyden:
                    fit, rows = rule.history_jacobian(J0, memory)
                    J = fit[2]
                else:
                    rows = []
            else:
                J, rows = rule.broyden_update(J, prev, u, e, rd.ys, rd.ks)
            rec["broyden_update"], rec["broyden_rows"] = bool(rows), ",".join(rows)
            within = bool(np.all(np.abs(e) <= tol))
            polishing = (polished_from is None and within and self.polish and rd.k > 1
                         and rnd < n_rounds - 1 and bool(np.any(np.abs(e) > rd.se)))
            decided = self._decide(rnd, rd, within, polishing, polished_from)
            if decided is not None or rnd == n_rounds - 1:
                history.append(rec)
                out = decided or out
                break
            u_from, u_new = rule.next_point(space, box, J, u, rd, polishing, trust, rec, fit)
            history.append(rec)
            if np.max(np.abs(u_new - u_from)) < 1e-9:
                out = self._stalled(space, box, rnd, rd, polishing, u_from)
                break
            if polishing:
                polished_from = rnd
            prev, u = (u, e, rd.ys), u_new
        return self._result(space, box, history, samples, J, seeds, out, n_rounds)

    def _start(self, space: CalibrationSpace, box, initial: Mapping[str, float]) -> np.ndarray:
        """The starting point in unit coordinates; an error if it lies outside the loop's box."""
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
        return np.clip(u, *box)

    def _run_seeds(self, params: dict, which: list) -> list:
        """The responses of ``params`` on each of the seeds ``which``: at once with
        ``simulate_seeds``, else one ``simulate`` run per seed."""
        if self.simulate_seeds is not None and None not in which:  # the seeds at once
            outs = list(self.simulate_seeds(dict(params), list(which)))
            if len(outs) != len(which):
                raise ValueError(f"simulate_seeds returned {len(outs)} result(s) for "
                                 f"{len(which)} seed(s); expected one per seed")
            return [self._responses(o) for o in outs]
        return [self._simulate(params, sd) for sd in which]

    def _record(self, rec: dict, rd: Round) -> None:
        """The round's seed CV, standard error, tolerance and error of every response."""
        rec.update({f"cv_{r}": v for r, v in zip(self.responses, rd.cv)})
        rec.update({f"se_{r}": v for r, v in zip(self.responses, rd.se)})
        rec.update({f"tol_{r}": v for r, v in zip(self.responses, rd.tol)})
        rec.update({f"err_{r}": v for r, v in zip(self.responses, rd.e)})
        rec["max_abs_err"] = float(np.max(np.abs(rd.e)))

    def _met(self, k: int) -> str:
        lab = " (with the lab value's)" if self.target_se is not None and k > 1 else ""
        return (f"every mean of {k} seeds within max(rtol, {self.z:g} standard errors{lab}) of "
                "its target" if k > 1 else "all relative errors within tolerance")

    def _failed(self, rnd: int, bad: list, polished_from: int | None) -> _Outcome:
        """A round with a non-finite response ends the loop: failed, unless it was the
        polishing round (then the converged round before it stands)."""
        txt = "; ".join(f"seed {sd}: {v}" if sd is not None else str(v) for sd, v in bad)
        if polished_from is not None:  # the converged round before it stands
            return _Outcome("converged",
                            f"converged after {polished_from + 1} round(s); the polishing "
                            f"round {rnd + 1} failed ({txt}), so round {polished_from + 1} "
                            "stays the card's", polished_from)
        return _Outcome("failed", f"round {rnd} returned non-finite responses ({txt})")

    def _decide(self, rnd: int, rd: Round, within: bool, polishing: bool,
                polished_from: int | None) -> _Outcome | None:
        """The outcome of a judged round that ends the loop (the polishing round, or a
        converged round that is not polished), else None."""
        met = self._met(rd.k)
        if polished_from is not None:  # the polishing round: it, or the round before, is the card's
            if within:
                return _Outcome("converged", f"{met} after {rnd + 1} round(s), the last a polishing step "
                                "towards the targets", rnd)
            miss = ", ".join(r for r, x, t in zip(self.responses, rd.e, rd.tol) if not abs(x) <= t)
            return _Outcome("converged", f"{met} after {polished_from + 1} round(s); the polishing step "
                            f"(round {rnd + 1}) left the tolerance in {miss}, so round "
                            f"{polished_from + 1} stays the card's", polished_from)
        if within and not polishing:
            return _Outcome("converged", f"{met} after {rnd + 1} round(s)" if rd.k > 1
                            else f"{met} after {rnd + 1} simulation(s)")
        return None

    def _stalled(self, space: CalibrationSpace, box, rnd: int, rd: Round, polishing: bool,
                 u_from: np.ndarray) -> _Outcome:
        """The step does not move: a polishing round is the card's, else the loop stalled."""
        if polishing:  # nothing left to move: this round is the card's
            return _Outcome("converged", f"{self._met(rd.k)} after {rnd + 1} round(s)")
        edges = ", ".join(space.edge_text(p, side, v, self.margin)
                          for p, side, v in space.at_bound(u_from, box))
        return _Outcome("stalled", f"the Newton step points out of the bounds ({edges}); the targets appear "
                        "unreachable within the parameter ranges")

    def _result(self, space: CalibrationSpace, box, history: list, samples: list, J: np.ndarray,
                seeds: list, out: _Outcome, max_rounds: int) -> ClosedLoopResult:
        """The result: the history, and the parameters and responses of the best round."""
        hist = pd.DataFrame.from_records(history)
        message = out.message
        if out.status == "max_rounds" and len(hist) > 1 and hist["clipped"].iloc[-2]:
            message += (f"; the last step was cut at the bounds of {hist['clipped'].iloc[-2]}: the targets "
                        "may lie outside what the parameter ranges can reach")
        best = _best_round(hist, out)
        x_best = np.array([best[p] for p in space.free])
        J_phys = J * np.abs(self.t)[:, None] / space.width
        xlo, xhi = space.limits(box)
        return ClosedLoopResult(
            status=out.status, message=message, history=hist, params=space.full(x_best),
            responses={r: float(best[r]) for r in self.responses},
            jacobian=pd.DataFrame(J_phys, index=list(self.responses), columns=list(space.free)),
            samples=pd.DataFrame.from_records(samples),
            seed_cv={r: float(best.get(f"cv_{r}", np.nan)) for r in self.responses},
            n_seeds=int(best["n_seeds"]), seeds=tuple(seeds[:int(best["n_seeds"])]),
            best_round=int(best["round"]), outside=_outside(space, space.full(x_best)),
            loop_bounds={p: (float(a), float(b)) for p, a, b in zip(space.free, xlo, xhi)},
            sign_held=list(self.sign_held), max_rounds=max_rounds)


@dataclass
class _Outcome:
    """How a closed loop ended: status, message and the card's round (None: the last
    round when converged, else the one with the smallest max |error|)."""

    status: str
    message: str
    best_idx: int | None = None


def _round_line(rnd: int, rd: Round, responses) -> str:
    """``round 3 (3 seeds): ucs_MPa +5.3 % (tol 6.7 %), ...; N within tolerance``."""
    parts = ", ".join(f"{r} {100 * x:+.1f} % (tol {100 * t:.1f} %)"
                      for r, x, t in zip(responses, rd.e, rd.tol))
    n_in = int(np.sum(np.abs(rd.e) <= rd.tol))
    fewer = "".join(f"; {r} on {kr}" for r, kr in zip(responses, rd.ks) if kr != rd.k)
    return (f"closed loop round {rnd + 1} ({rd.k} seed{'s' * (rd.k != 1)}{fewer}): {parts}; "
            f"{n_in} of {len(rd.e)} within tolerance")


def _best_round(hist: pd.DataFrame, out: _Outcome) -> pd.Series:
    """The card's round: the converged one (``out.best_idx``, default the last), else the
    one with the smallest max |error| of the mean (the last when none is finite)."""
    finite = hist.dropna(subset=["max_abs_err"]) if "max_abs_err" in hist else hist.iloc[:0]
    if out.status == "converged":
        return hist.iloc[-1 if out.best_idx is None else out.best_idx]
    return hist.loc[finite["max_abs_err"].idxmin()] if len(finite) else hist.iloc[-1]


def _outside(space: CalibrationSpace, params: Mapping[str, float]) -> dict[str, dict]:
    """The calibrated parameters of ``params`` outside their design range: value and range."""
    out = {}
    for p in space.calibrated:
        lo, hi = space.ranges[p]
        v = float(params[p])
        if not _inside(v, lo, hi):
            out[p] = {"value": v, "range": [float(lo), float(hi)]}
    return out
