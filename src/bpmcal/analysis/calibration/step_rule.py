"""The closed loop's step rule (:class:`StepRule`): where the next round goes.

The Jacobian starts from the regression models (:func:`initial_jacobian`; a strength's
slope against a bond strength held at >= 0 by :func:`hold_signs`) and is corrected by the
measured rounds: Broyden's secant update between consecutive rounds, each row shrunk by its
signal-to-noise ratio (:meth:`StepRule.broyden`), or a fit to every judged round at once
(:meth:`StepRule.history_jacobian`). The step is a damped, weighted Gauss-Newton step in the
unit cube, a Levenberg-Marquardt one (:func:`lm_step`) where it would leave the cap, with
the parameters held at a bound probed (:meth:`StepRule.step`), from the best round so far
(the trust region, :class:`TrustRegion`, :meth:`StepRule.next_point`).

The driver, :class:`~bpmcal.analysis.calibration.closed_loop.ClosedLoop`, checks the
settings and runs the rounds; the seed sets the rounds run on are
:mod:`~bpmcal.analysis.calibration.seed_policy`'s. The method:
``docs/methods/calibration.md`` (section "Closed loop").
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from bpmcal.params import STRENGTH_RESPONSES

from ..stepwise import RegressionModel
from .space import _EDGE, CalibrationSpace

if TYPE_CHECKING:
    from .seed_policy import Round

#: the trust region's smallest cap with update="history", as a fraction of max_step
HISTORY_MIN_STEP = 0.125


def initial_jacobian(space: CalibrationSpace, x: np.ndarray, responses, t: np.ndarray,
                     models: Mapping[str, RegressionModel] | None,
                     jacobian: pd.DataFrame | None) -> tuple[np.ndarray, list[dict]]:
    """The starting Jacobian in unit coordinates and relative errors (``t``: the
    targets): the regression models' at ``x`` (held to :func:`hold_signs`), or the
    ``jacobian`` given; and the entries held (:func:`hold_signs`; none for a given one)."""
    held: list[dict] = []
    if models is not None:
        space.check_models(models, responses)
        Jx, held = hold_signs(space, space.jacobian(models, responses, x), responses)
    else:
        jac = pd.DataFrame(jacobian)
        missing = [r for r in responses if r not in jac.index] + [p for p in space.free
                                                                  if p not in jac.columns]
        if missing:
            raise ValueError(f"jacobian lacks {missing}: expected rows {list(responses)} and "
                             f"columns {list(space.free)}")
        Jx = jac.loc[list(responses), list(space.free)].to_numpy(float)
    return Jx * space.width / np.abs(t)[:, None], held


def hold_signs(space: CalibrationSpace, Jx: np.ndarray, responses) -> tuple[np.ndarray, list[dict]]:
    """The regression's Jacobian ``Jx`` (physical units) with every strength's slope
    against a bond strength of the model's strength pair that is negative set to 0
    (``params.STRENGTH_RESPONSES``): a stronger bond never makes a weaker specimen. A
    quadratic model of a strength that saturates (a shear-strong card, whose bonds
    break in tension whatever their cohesion) turns over inside the design range, and
    past its vertex it would send the loop's first step the wrong way at the full cap;
    0 says the slope is not known to be other than flat there, and the measured rounds
    correct it (Broyden). Returns ``Jx`` and each entry set (response, parameter, the
    regression's slope): the loop's ``sign_held``."""
    held = []
    pair = set(space.model.strength or ())
    for k, r in enumerate(responses):
        for j, p in enumerate(space.free):
            if r in STRENGTH_RESPONSES and p in pair and Jx[k, j] < 0:
                held.append({"response": r, "parameter": p, "regression": float(Jx[k, j])})
                Jx[k, j] = 0.0
    return Jx, held


class TrustRegion:
    """The step cap (halved after a worse round), the best round so far ``base`` =
    (u, e, merit, k) the next step starts from, and the rounds each parameter has been
    held at a bound."""

    def __init__(self, cap: float, n: int):
        self.cap = cap
        self.base = None
        self.held_rounds = [0] * n


@dataclass(frozen=True, eq=False)
class StepRule:
    """The step rule of a closed loop, with its checked settings (``ClosedLoop``'s
    parameters of the same names): ``responses`` and their targets ``t``, the tolerances
    ``rtol`` and ``z`` (the history fit's weight of a round without a standard error),
    ``damping``, ``max_step`` and ``min_step`` (the trust region), ``broyden`` (correct
    the Jacobian at all) and ``update`` (how: one of :data:`UPDATES`)."""

    responses: tuple
    t: np.ndarray
    rtol: np.ndarray
    z: float
    damping: float
    max_step: float
    min_step: float
    broyden: bool
    update: str

    def broyden_update(self, J: np.ndarray, prev, u: np.ndarray, e: np.ndarray,
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

    def history_jacobian(self, J0: np.ndarray, memory: list) -> tuple[tuple, list[str]]:
        """The Jacobian from every judged round at once (``update="history"``), in the
        loop's unit coordinates and relative errors; returns the fit ``(u_b, a, J)`` (the
        next step starts from the fitted errors ``a + J (u - u_b)``) and the responses whose
        row moved from the starting estimate ``J0`` by more than half that row's norm.
        ``memory``: (u, judged :class:`~.seed_policy.Round`) of every judged round.

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

    def step(self, J: np.ndarray, e: np.ndarray, u: np.ndarray,
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
                du[act] = lm_step(w[:, None] * J[:, act], w * r, cap / damp) * damp
            out = [j for j in act if (u[j] <= box[0][j] + _EDGE and du[j] < 0)
                   or (u[j] >= box[1][j] - _EDGE and du[j] > 0)]
            if not out:
                break
            held += out
        biggest = float(np.max(np.abs(du))) if len(du) else 0.0
        if biggest > cap:
            du *= cap / biggest
        return du, sorted(held)

    def next_point(self, space: CalibrationSpace, box, J: np.ndarray, u: np.ndarray, rd: Round,
                   polishing: bool, trust: TrustRegion, rec: dict,
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
        du, held = self.step(J, e_from, u_from, box, 1.0 if polishing else None,
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


def lm_step(A: np.ndarray, b: np.ndarray, cap: float) -> np.ndarray:
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
