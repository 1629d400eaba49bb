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

The method: ``docs/methods/calibration.md`` (section "Closed loop").
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from bpmcal.params import AUTO_ROUNDS, ROUNDS_PER_FREE, STRENGTH_RESPONSES, ParameterError, auto_rounds

from ..stepwise import RegressionModel
from .space import (
    _EDGE,
    PAPER_RATIO,
    CalibrationSpace,
    _check_ranges,
    _check_targets,
    _default_free,
    _inside,
    space_model,
)


def check_max_rounds(max_rounds) -> None:
    """A ValueError naming ``max_rounds`` unless it is an integer >= 1 or ``"auto"``."""
    whole = isinstance(max_rounds, (int, np.integer)) and not isinstance(max_rounds, bool)
    if not ((whole and max_rounds >= 1) or max_rounds == AUTO_ROUNDS):
        raise ValueError(f"max_rounds={max_rounds!r}: expected an integer >= 1 or "
                         f"{AUTO_ROUNDS!r} ({ROUNDS_PER_FREE} per free parameter)")


def check_grow_within(grow_within) -> float:
    """``grow_within`` as a float, or a ValueError naming it unless it is a number >= 1."""
    if isinstance(grow_within, (bool, np.bool_)) or not isinstance(
            grow_within, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(float(grow_within)) and float(grow_within) >= 1):
        raise ValueError(f"grow_within={grow_within!r}: expected a factor >= 1 on the tolerance "
                         "(1: the seed set grows once every mean is within its tolerance)")
    return float(grow_within)


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
    regression's slope; :meth:`ClosedLoop._hold_signs`). ``max_rounds``: the round budget
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
        starting Jacobian as its prior (:meth:`_history_jacobian`). Broyden remembers the
        last step exactly and the earlier ones only through its rank-one updates; the
        history fit keeps them all, so a response that depends on several parameters at
        once is resolved once the steps span them. The step then starts from the fitted
        errors at the best round, not from its own: the rounds near it average its scatter.
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
                 free: Sequence[str] | None = None, ratio: float | None = PAPER_RATIO,
                 ranges: Mapping[str, Sequence[float]],
                 bounds: Mapping[str, Sequence[float]] | None = None,
                 models: Mapping[str, RegressionModel] | None = None, jacobian: pd.DataFrame | None = None,
                 rtol: float | Mapping[str, float] = 0.01, max_rounds: int | str = "auto",
                 damping: float = 0.8,
                 max_step: float = 0.25, broyden: bool = True, seeds_per_round: int | None = None,
                 seeds: Sequence[int] | None = None, z: float = 2.0, max_seeds: int | None = None,
                 margin: float = 0.0, polish: bool = True,
                 target_se: Mapping[str, float] | None = None, update: str = "broyden",
                 min_step: float | None = None, report: Callable[[str], None] | None = None,
                 simulate_seeds: Callable[[dict, list], Sequence[Mapping[str, float]]] | None = None,
                 seed_caps: Mapping[str, int] | None = None, grow_within: float = 2.0):
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
        self.target_se = _target_se(target_se, self.responses, self.t)
        self.seed_caps = _seed_caps(seed_caps, self.responses)
        self.grow_within = check_grow_within(grow_within)
        # each response's seed cap (inf: every seed)
        self._caps = np.array([self.seed_caps.get(r, np.inf) for r in self.responses], float)
        if (models is None) == (jacobian is None):
            raise ValueError("give exactly one of models (analytic Jacobian) or jacobian")
        rt = {r: float(rtol[r] if isinstance(rtol, Mapping) else rtol) for r in self.responses}
        if not all(v > 0 for v in rt.values()):
            raise ValueError(f"rtol={rtol!r}: expected positive relative tolerance(s)")
        check_max_rounds(max_rounds)
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
        self.rtol = np.array([rt[r] for r in self.responses])
        self.max_rounds = max_rounds if max_rounds == AUTO_ROUNDS else int(max_rounds)
        self.damping, self.max_step = float(damping), float(max_step)
        self.broyden = bool(broyden)
        if update not in UPDATES:
            raise ValueError(f"update={update!r}: expected one of {list(UPDATES)}")
        self.update = update
        if min_step is None:
            min_step = HISTORY_MIN_STEP * max_step if update == "history" else 0.0
        if not (isinstance(min_step, (int, float, np.integer, np.floating))
                and not isinstance(min_step, bool) and 0 <= min_step <= max_step):
            raise ValueError(f"min_step={min_step!r}: expected a fraction of the range in "
                             f"[0, max_step = {max_step!r}]")
        self.min_step = float(min_step)
        self.report = report
        if isinstance(margin, bool) or not isinstance(margin, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(float(margin)) and 0 <= float(margin) <= 1):
            raise ValueError(f"margin={margin!r}: expected a fraction of the range width in [0, 1]")
        self.margin = float(margin)
        if not isinstance(polish, (bool, np.bool_)):
            raise ValueError(f"polish={polish!r}: expected True or False")
        self.polish = bool(polish)
        self.sign_held: list[dict] = []  # the starting Jacobian's entries held to their sign

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
        """The starting Jacobian in unit coordinates and relative errors: the regression
        models' at ``x`` (held to :meth:`_hold_signs`), or the ``jacobian`` given."""
        self.sign_held = []
        if self.models is not None:
            space.check_models(self.models, self.responses)
            Jx = self._hold_signs(space, space.jacobian(self.models, self.responses, x))
        else:
            jac = pd.DataFrame(self.jacobian)
            missing = [r for r in self.responses if r not in jac.index] + [p for p in space.free
                                                                          if p not in jac.columns]
            if missing:
                raise ValueError(f"jacobian lacks {missing}: expected rows {list(self.responses)} and "
                                 f"columns {list(space.free)}")
            Jx = jac.loc[list(self.responses), list(space.free)].to_numpy(float)
        return Jx * space.width / np.abs(self.t)[:, None]

    def _hold_signs(self, space: CalibrationSpace, Jx: np.ndarray) -> np.ndarray:
        """The regression's Jacobian ``Jx`` (physical units) with every strength's slope
        against a bond strength of the model's strength pair that is negative set to 0
        (``params.STRENGTH_RESPONSES``): a stronger bond never makes a weaker specimen. A
        quadratic model of a strength that saturates (a shear-strong card, whose bonds
        break in tension whatever their cohesion) turns over inside the design range, and
        past its vertex it would send the loop's first step the wrong way at the full cap;
        0 says the slope is not known to be other than flat there, and the measured rounds
        correct it (Broyden). Each entry set is listed in ``sign_held`` (response,
        parameter, the regression's slope)."""
        pair = set(space.model.strength or ())
        for k, r in enumerate(self.responses):
            for j, p in enumerate(space.free):
                if r in STRENGTH_RESPONSES and p in pair and Jx[k, j] < 0:
                    self.sign_held.append({"response": r, "parameter": p,
                                           "regression": float(Jx[k, j])})
                    Jx[k, j] = 0.0
        if self.sign_held and self.report is not None:
            self.report("closed loop: the regression's slope of " + ", ".join(
                f"{h['response']} against {h['parameter']} ({h['regression']:+.3g})"
                for h in self.sign_held) + " is negative at the start, where a stronger bond "
                "never weakens the specimen: taken as 0 (flat), for the rounds to measure")
        return Jx

    @property
    def seeds_per_round(self) -> int:
        return len(self.seeds)

    def _simulate(self, params: dict[str, float], seed: int | None) -> np.ndarray:
        out = self.simulate(dict(params)) if seed is None else self.simulate(dict(params), seed=seed)
        return self._responses(out)

    def _responses(self, out: Mapping[str, float] | None) -> np.ndarray:
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
        # "auto": resolved once the free parameters are known
        n_rounds = (auto_rounds(len(space.free)) if self.max_rounds == AUTO_ROUNDS
                    else self.max_rounds)
        box = space.loop_box(self.margin)
        u = self._start(space, box, initial)
        J = J0 = self._initial_jacobian(space, space.x(u))
        memory: list[tuple[np.ndarray, _Round]] = []  # every judged round (update="history")
        fit = None  # the history fit (u_b, a, J) the next step starts from
        seeds, spare = list(self.seeds), list(self.growth_seeds)
        history, samples, prev = [], [], None
        polished_from = None  # the converged round a polishing step left
        trust = _TrustRegion(self.max_step, len(space.free))
        stats = _SeedStats(len(self.responses))
        out = _Outcome("max_rounds", f"tolerance not met within {n_rounds} rounds")
        for rnd in range(n_rounds):
            params = space.full(space.x(u))
            rd = self._run_round(rnd, params, seeds, spare, stats, samples)
            seeds, spare = rd.seeds, rd.spare
            rec = {"round": rnd, **{p: params[p] for p in space.calibrated}}
            rec.update({**dict(zip(self.responses, _means(rd.ys, rd.ks))), "n_seeds": rd.k,
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
            if self.update == "history":
                memory.append((u.copy(), rd))
                if self.broyden:
                    fit, rows = self._history_jacobian(J0, memory)
                    J = fit[2]
                else:
                    rows = []
            else:
                J, rows = self._broyden(J, prev, u, e, rd.ys, rd.ks)
            rec["broyden_update"], rec["broyden_rows"] = bool(rows), ",".join(rows)
            within = bool(np.all(np.abs(e) <= tol))
            polishing = (polished_from is None and within and self.polish and rd.k > 1
                         and rnd < n_rounds - 1 and bool(np.any(np.abs(e) > rd.se)))
            decided = self._decide(rnd, rd, within, polishing, polished_from)
            if decided is not None or rnd == n_rounds - 1:
                history.append(rec)
                out = decided or out
                break
            u_from, u_new = self._next_point(space, box, J, u, rd, polishing, trust, rec, fit)
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

    def _run_round(self, rnd: int, params: dict, seeds: list, spare: list, stats: _SeedStats,
                   samples: list) -> _Round:
        """Run ``params`` on every seed of the round and judge the mean; when it is within
        tolerance but a standard error is too large to state it to ``rtol``, grow the seed
        set by the ``spare`` seeds and judge again (module docs, "Closed loop")."""
        def run_seeds(which, first: int = 0) -> np.ndarray:
            """The runs of the seeds ``which``, the first of them the round's ``first``-th
            seed: a response past its seed cap is NaN (not measured)."""
            ys = np.empty((len(which), len(self.responses)))
            if self.simulate_seeds is not None and None not in which:  # the seeds at once
                outs = list(self.simulate_seeds(dict(params), list(which)))
                if len(outs) != len(which):
                    raise ValueError(f"simulate_seeds returned {len(outs)} result(s) for "
                                     f"{len(which)} seed(s); expected one per seed")
                ys[:] = [self._responses(o) for o in outs]
            else:
                ys[:] = [self._simulate(params, sd) for sd in which]
            ys[~self._measured(first + len(which))[first:]] = np.nan
            for i, sd in enumerate(which):
                samples.append({"round": rnd, "seed": sd, **dict(zip(self.responses, ys[i]))})
            return ys

        def failed(ys) -> list:
            """(seed, responses) of every run of the round with a non-finite response."""
            measured = self._measured(len(ys))
            return [(sd, dict(zip(self.responses, row))) for sd, row, m in zip(seeds, ys, measured)
                    if not np.all(np.isfinite(row[m]))]

        ys = run_seeds(seeds)
        grown = 0
        judged = None
        bad = failed(ys)
        if not bad:
            judged = stats.judge(ys, self._counts(len(ys)), self.rtol, self.z, self.t,
                                 self.target_se)
            se, tol, e = judged[2], judged[3], judged[4]
            can_grow = self._caps > len(seeds)  # a response a grown set measures on more seeds
            if (np.all(np.abs(e) <= self.grow_within * tol) and spare
                    and np.any((self.z * se > self.rtol) & can_grow)):
                grown, seeds, spare = len(spare), seeds + spare, []
                ys = np.vstack([ys, run_seeds(seeds[-grown:], len(ys))])
                bad = failed(ys)
                if not bad:
                    judged = stats.judge(ys, self._counts(len(ys)), self.rtol, self.z, self.t,
                                         self.target_se)
        return _Round(ys, seeds, spare, grown, bad,
                      *(judged if judged is not None else (None,) * 5), counts=self._counts(len(ys)))

    def _counts(self, k: int) -> np.ndarray:
        """How many of a round's first ``k`` seeds measure each response."""
        return np.minimum(k, self._caps).astype(int)

    def _measured(self, k: int) -> np.ndarray:
        """seeds x responses: does the i-th of a round's ``k`` seeds measure the response?"""
        return np.arange(k)[:, None] < self._counts(k)[None, :]

    def _record(self, rec: dict, rd: _Round) -> None:
        """The round's seed CV, standard error, tolerance and error of every response."""
        rec.update({f"cv_{r}": v for r, v in zip(self.responses, rd.cv)})
        rec.update({f"se_{r}": v for r, v in zip(self.responses, rd.se)})
        rec.update({f"tol_{r}": v for r, v in zip(self.responses, rd.tol)})
        rec.update({f"err_{r}": v for r, v in zip(self.responses, rd.e)})
        rec["max_abs_err"] = float(np.max(np.abs(rd.e)))

    def _broyden(self, J: np.ndarray, prev, u: np.ndarray, e: np.ndarray,
                 ys: np.ndarray, ks: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:
        """Broyden's ("good") secant update of ``J`` from the previous round ``prev`` =
        (u, e, ys), when it ran the same seeds (``ys``: this round's runs, seeds x
        responses); returns J and the responses whose rows moved by more than half the
        full secant update.

        With several seeds, each row's update is shrunk by its signal-to-noise ratio:
        the secant's residual ``r`` (the measured change of that response minus the
        change ``J`` predicted) is applied with the gain r² / (r² + SE²), where SE is the
        paired standard error of the change, from each seed's own change between the two
        rounds (sd of the per-seed differences / sqrt(k)), so the part of the scatter a
        packing keeps from one parameter set to the next cancels. A response whose change
        lies within its noise (a sigma_t over a small step) barely moves its row, and a
        secant through scatter cannot replace the estimate; a change well beyond the
        noise updates it fully. With one seed (no standard error) every row is updated
        fully. ``ks``: the seeds measuring each response (a seed cap), default all."""
        if prev is None or not self.broyden or len(prev[2]) != len(ys):  # other seeds: no secant
            return J, []
        s, de = u - prev[0], e - prev[1]
        if s @ s <= 1e-16:
            return J, []
        resid = de - J @ s
        k = len(ys)
        gain = np.ones(len(resid))
        d = (ys - prev[2]) / np.abs(self.t)
        if ks is not None and np.any(ks != k):  # a capped response: its own seeds' changes
            for i, kr in enumerate(ks):
                if kr > 1:
                    var = d[:kr, i].var(ddof=1) / kr
                    r2 = resid[i] ** 2
                    gain[i] = r2 / max(r2 + var, 1e-300) if r2 + var > 0 else 0.0
        elif k > 1:
            var = d.var(axis=0, ddof=1) / k
            gain = np.where(resid ** 2 + var > 0, resid ** 2 / np.maximum(resid ** 2 + var, 1e-300), 0.0)
        return (J + np.outer(gain * resid, s) / (s @ s),
                [r for r, g in zip(self.responses, gain) if g > 0.5])

    def _history_jacobian(self, J0: np.ndarray, memory: list) -> tuple[tuple, list[str]]:
        """The Jacobian from every judged round at once (``update="history"``), in the
        loop's unit coordinates and relative errors; returns the fit ``(u_b, a, J)`` (the
        next step starts from the fitted errors ``a + J (u - u_b)``) and the responses whose
        row moved from the starting estimate ``J0`` by more than half that row's norm.

        Each response ``i`` gets a local linear model ``e_i(u) = a_i + J_i (u - u_b)``
        about ``u_b``, the best round so far by the trust region's merit (this round
        included), fitted by weighted least squares to the means of all rounds with a
        Gaussian prior ``J_i ~ N(J0_i, |J0_i|² I)`` (the starting estimate, uncertain by
        its own size) and a free intercept ``a_i``. A round's weight is
        1 / (SE² · (1 + (d / cap)²)): its standard error of the mean (relative; the
        tolerance's rtol / z where one seed gives none) and its distance ``d`` from
        ``u_b`` in the max norm against the loop's largest step (the response is only
        locally linear, so far rounds count less). With two rounds on one seed and no
        noise this is Broyden's least-change secant update from ``J0``; with more rounds
        than parameters the data decide every direction they span."""
        us = np.array([m[0] for m in memory])
        es = np.array([m[1].e for m in memory])
        tols = np.array([m[1].tol for m in memory])
        ses = np.array([np.where(m[1].se > 0, m[1].se, self.rtol / max(self.z, 1.0))
                        for m in memory])
        best = int(np.argmin(np.sum((es / tols) ** 2, axis=1)))
        ub = us[best]
        d = np.max(np.abs(us - ub), axis=1)
        dist_w = 1.0 / (1.0 + (d / self.max_step) ** 2)
        X = np.hstack([np.ones((len(us), 1)), us - ub])
        n = us.shape[1]
        J = J0.copy()
        a = es[best].copy()
        moved = []
        for i, r in enumerate(self.responses):
            w = dist_w / np.maximum(ses[:, i], 1e-12) ** 2
            prior_sd = max(float(np.linalg.norm(J0[i])), 1e-6)
            P = np.zeros((n + 1, n + 1))
            P[1:, 1:] = np.eye(n) / prior_sd ** 2
            b = np.zeros(n + 1)
            b[1:] = J0[i] / prior_sd ** 2
            A = X.T @ (w[:, None] * X) + P
            A[0, 0] += 1e-12 * max(float(A[0, 0]), 1.0)  # one round: the intercept alone
            coef = np.linalg.solve(A, X.T @ (w * es[:, i]) + b)
            a[i], J[i] = coef[0], coef[1:]
            if np.linalg.norm(J[i] - J0[i]) > 0.5 * prior_sd:
                moved.append(r)
        return (ub, a, J), moved

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

    def _decide(self, rnd: int, rd: _Round, within: bool, polishing: bool,
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

    def _next_point(self, space: CalibrationSpace, box, J: np.ndarray, u: np.ndarray, rd: _Round,
                    polishing: bool, trust: _TrustRegion, rec: dict,
                    fit: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The step of a round that goes on: from the best round so far (the trust region),
        probing parameters held at a bound, clipped to the box; records it in ``rec``.
        Returns the point stepped from and the new point."""
        e, tol, k = rd.e, rd.tol, rd.k
        # the trust region: step from the best round so far; a worse round halves the cap
        merit = float(np.sum((e / tol) ** 2))
        # a grown seed set measures on other packings with a smaller SE (a tighter
        # tolerance): its rounds are not compared with the earlier ones
        base = trust.base
        accepted = base is None or polishing or base[3] != k or merit <= base[2]
        if accepted:
            # a better round reached by a step the cap cut: the region was too small
            if (base is not None and not polishing and base[3] == k and merit < base[2]
                    and float(np.max(np.abs(u - base[0]))) >= 0.99 * trust.cap):
                trust.cap = min(2.0 * trust.cap, self.max_step)
            trust.base = (u.copy(), e.copy(), merit, k)
        else:  # half the step that led here (the cap may not have bound it)
            trust.cap = max(0.5 * float(np.max(np.abs(u - base[0]))), self.min_step)
        rec["accepted"], rec["step_cap"] = accepted, trust.cap
        u_from, e_from = trust.base[0], trust.base[1]
        if fit is not None and not polishing:
            ub, a, Jf = fit  # the fitted errors at the base: the rounds' scatter averaged
            e_from = a + Jf @ (u_from - ub)
        held_rounds = trust.held_rounds
        # a parameter held at a bound two rounds running while the loop misses: its
        # column of J was never measured (Broyden learns along the steps taken), so the
        # step probes it - half the cap into the box - instead of trusting the sign
        probe = [j for j in range(len(u)) if held_rounds[j] >= 2] if not polishing else []
        du, held = self._step(J, e_from, u_from, box, 1.0 if polishing else None,
                              None if polishing else trust.cap, weights=1.0 / tol, probe=probe)
        for j in range(len(u)):
            held_rounds[j] = 0 if j in probe else (held_rounds[j] + 1 if j in held else 0)
        rec["probed"] = ",".join(space.free[j] for j in probe)
        u_new = np.clip(u_from + du, *box)
        rec.update({f"step_{p}": v for p, v in zip(space.free, (u_new - u) * space.width)})
        cut = [j for j in range(len(u)) if j in held or u_new[j] != u_from[j] + du[j]]
        rec["clipped"] = ",".join(space.free[j] for j in cut)
        rec["polish"] = polishing
        return u_from, u_new

    def _stalled(self, space: CalibrationSpace, box, rnd: int, rd: _Round, polishing: bool,
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


UPDATES = ("broyden", "history")  # how the measured rounds correct the Jacobian
#: the trust region's smallest cap with update="history", as a fraction of max_step
HISTORY_MIN_STEP = 0.125


def _round_line(rnd: int, rd: _Round, responses) -> str:
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


class _SeedStats:
    """The seed CV pooled over the rounds so far: Σ (k-1) cv² and Σ (k-1)."""

    def __init__(self, n: int):
        self.pooled, self.dof = np.zeros(n), np.zeros(n)

    def judge(self, ys: np.ndarray, ks: np.ndarray, rtol: np.ndarray, z: float, t: np.ndarray,
              target_se: np.ndarray | None = None):
        """mean, seed CV, SE (pooled with the earlier rounds), tolerance, error; with
        ``target_se`` (relative standard errors of the targets) the tolerance is
        max(rtol, z · sqrt(SE² + target_se²)): two means, each with its error. ``ks``: how
        many of the seeds (the first ones) measure each response."""
        k = len(ys)
        if np.any(ks != k):  # a seed cap: every response over its own seeds
            y = _means(ys, ks)
            cv = np.array([ys[:kr, i].std(ddof=1) / abs(y[i]) if kr > 1 else np.nan
                           for i, kr in enumerate(ks)])
            se = np.array([math.sqrt((self.pooled[i] + (kr - 1) * cv[i] ** 2)
                                     / (self.dof[i] + kr - 1)) / math.sqrt(kr) if kr > 1 else 0.0
                           for i, kr in enumerate(ks)])
        else:
            y = ys.mean(axis=0)
            cv = ys.std(axis=0, ddof=1) / np.abs(y) if k > 1 else np.full(len(y), np.nan)
            se = (np.sqrt((self.pooled + (k - 1) * cv ** 2) / (self.dof + k - 1)) / math.sqrt(k)
                  if k > 1 else np.zeros(len(y)))
        both = se if target_se is None else np.sqrt(se ** 2 + target_se ** 2)
        return y, cv, se, np.maximum(rtol, z * both), (y - t) / np.abs(t)

    def add(self, ks: np.ndarray, cv: np.ndarray) -> None:
        """Pool a judged round (``ks``: the seeds measuring each response)."""
        many = np.asarray(ks) > 1
        self.pooled[many] += (np.asarray(ks)[many] - 1) * cv[many] ** 2
        self.dof[many] += np.asarray(ks)[many] - 1


def _means(ys: np.ndarray, ks: np.ndarray) -> np.ndarray:
    """Each response's mean over the seeds measuring it (the first ``ks[i]`` rows)."""
    if np.all(ks == len(ys)):
        return ys.mean(axis=0)
    return np.array([ys[:kr, i].mean() for i, kr in enumerate(ks)])


@dataclass
class _Round:
    """One round's runs (``ys``: seeds x responses, NaN past a response's seed cap), its
    seed set afterwards, the spare seeds left, how many it grew by, the failed runs, the
    seeds measuring each response and (when none failed) its judgement."""

    ys: np.ndarray
    seeds: list
    spare: list
    grown: int
    bad: list
    y: np.ndarray | None
    cv: np.ndarray | None
    se: np.ndarray | None
    tol: np.ndarray | None
    e: np.ndarray | None
    counts: np.ndarray | None = None  # the seeds measuring each response (None: every seed)

    @property
    def k(self) -> int:
        return len(self.ys)

    @property
    def ks(self) -> np.ndarray:
        """How many of the round's seeds measure each response (a seed cap: fewer)."""
        return np.full(self.ys.shape[1], self.k) if self.counts is None else self.counts


class _TrustRegion:
    """The step cap (halved after a worse round), the best round so far ``base`` =
    (u, e, merit, k) the next step starts from, and the rounds each parameter has been
    held at a bound."""

    def __init__(self, cap: float, n: int):
        self.cap = cap
        self.base = None
        self.held_rounds = [0] * n


def _seed_caps(caps, responses) -> dict:
    """The seed caps checked: response -> integer >= 1, every response a target."""
    if caps is None:
        return {}
    if not isinstance(caps, Mapping):
        raise ValueError(f"seed_caps={caps!r}: expected a mapping response -> number of seeds")
    out = {}
    for r, n in caps.items():
        if r not in responses:
            raise ValueError(f"seed_caps: {r!r} is not a target; expected one of {list(responses)}")
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"seed_caps[{r!r}]={n!r}: expected an integer >= 1")
        out[r] = int(n)
    return out


def _target_se(target_se, responses, t: np.ndarray) -> np.ndarray | None:
    """The targets' relative standard errors (None: none given); a missing response is 0."""
    if target_se is None:
        return None
    out = np.zeros(len(responses))
    for r, v in dict(target_se).items():
        if r not in responses:
            raise ValueError(f"target_se: {r!r} is not a target (targets: {list(responses)})")
        x = float(v)
        if not (math.isfinite(x) and x >= 0):
            raise ValueError(f"target_se.{r}={v!r}: expected a standard error >= 0")
        out[list(responses).index(r)] = x / abs(t[list(responses).index(r)])
    return out


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


def _outside(space: CalibrationSpace, params: Mapping[str, float]) -> dict[str, dict]:
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

