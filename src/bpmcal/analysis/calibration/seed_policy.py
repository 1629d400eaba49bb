"""The closed loop's seed-set policy (:class:`SeedPolicy`): which packing seeds a round
runs, how its mean is judged, and when the set grows.

Every round runs the candidate on the same packing seeds (:func:`round_seeds`); a
response may be measured on the first few of them only (its seed cap,
:func:`check_seed_caps`). A round's mean is judged against its target within max(rtol,
z standard errors), the seed CV pooled over the rounds so far (:class:`SeedStats`), the
lab value's own standard error added where it is given (:func:`relative_target_se`). The
seed set grows once, by the spare seeds after the largest one (:func:`growth_seeds`),
when every mean is within ``grow_within`` tolerances while a standard error is too large
to state a target to ``rtol`` (:meth:`SeedPolicy.run_round`).

The driver, :class:`~bpmcal.analysis.calibration.closed_loop.ClosedLoop`, runs the
simulations; the step between rounds is
:mod:`~bpmcal.analysis.calibration.step_rule`'s. The method:
``docs/methods/calibration.md`` (section "Closed loop").
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .loop_settings import check_loop_value


def takes_seed(simulate: Callable) -> bool:
    """Whether ``simulate`` accepts a keyword ``seed`` (a parameter of that name or
    ``**kwargs``)."""
    import inspect

    try:
        sig = inspect.signature(simulate)
    except (TypeError, ValueError):
        return False
    return any(p.name == "seed" and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
               or p.kind == p.VAR_KEYWORD for p in sig.parameters.values())


def round_seeds(simulate: Callable, seeds_per_round: int | None, seeds: Sequence[int] | None) -> tuple:
    """The packing seeds of every closed-loop round (``(None,)``: a single-seed simulator)."""
    if seeds_per_round is not None:  # as LoopSettings checks it
        seeds_per_round = check_loop_value("seeds_per_round", seeds_per_round)
    if not takes_seed(simulate):
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


def growth_seeds(seeds: tuple, max_seeds: int | None) -> tuple:
    """The spare seeds a round's set ``seeds`` (:func:`round_seeds`) may grow by: the
    next integers after the largest, up to ``max_seeds`` seeds in all (none without it)."""
    if max_seeds is not None:  # as LoopSettings checks it
        max_seeds = check_loop_value("max_seeds", max_seeds)
    n_more = 0 if max_seeds is None else max(0, int(max_seeds) - len(seeds))
    if n_more and seeds == (None,):
        raise ValueError("simulate(params) takes no seed argument, so the seed set cannot grow: "
                         "give it a 'seed' parameter, or leave max_seeds unset")
    top = max(seeds) if seeds != (None,) else 0
    return tuple(range(top + 1, top + 1 + n_more))


def check_seed_caps(caps, responses) -> dict:
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


def relative_target_se(target_se, responses, t: np.ndarray) -> np.ndarray | None:
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


class SeedStats:
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
            y = response_means(ys, ks)
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


def response_means(ys: np.ndarray, ks: np.ndarray) -> np.ndarray:
    """Each response's mean over the seeds measuring it (the first ``ks[i]`` rows)."""
    if np.all(ks == len(ys)):
        return ys.mean(axis=0)
    return np.array([ys[:kr, i].mean() for i, kr in enumerate(ks)])


@dataclass
class Round:
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


class SeedPolicy:
    """The seed-set policy of a closed loop, with its checked settings (``ClosedLoop``'s
    parameters of the same names): ``responses`` and their targets ``t``, the tolerances
    ``rtol`` and ``z``, the targets' relative standard errors ``target_se``
    (:func:`relative_target_se`), the seed caps ``seed_caps`` (:func:`check_seed_caps`)
    and ``grow_within``."""

    def __init__(self, responses, t: np.ndarray, rtol: np.ndarray, z: float,
                 target_se: np.ndarray | None, seed_caps: dict, grow_within: float):
        self.responses, self.t, self.rtol, self.z = responses, t, rtol, z
        self.target_se, self.grow_within = target_se, grow_within
        # each response's seed cap (inf: every seed)
        self.caps = np.array([seed_caps.get(r, np.inf) for r in responses], float)

    def counts(self, k: int) -> np.ndarray:
        """How many of a round's first ``k`` seeds measure each response."""
        return np.minimum(k, self.caps).astype(int)

    def measured(self, k: int) -> np.ndarray:
        """seeds x responses: does the i-th of a round's ``k`` seeds measure the response?"""
        return np.arange(k)[:, None] < self.counts(k)[None, :]

    def run_round(self, rnd: int, params: dict, seeds: list, spare: list, stats: SeedStats,
                  samples: list, run: Callable[[dict, list], list]) -> Round:
        """Run ``params`` on every seed of the round (``run(params, seeds)``: one array of
        the responses per seed) and judge the mean; when it is within ``grow_within``
        tolerances but a standard error is too large to state it to ``rtol``, grow the
        seed set by the ``spare`` seeds and judge again (module docs, "Closed loop").
        Every run is appended to ``samples``."""
        def run_seeds(which, first: int = 0) -> np.ndarray:
            """The runs of the seeds ``which``, the first of them the round's ``first``-th
            seed: a response past its seed cap is NaN (not measured)."""
            ys = np.empty((len(which), len(self.responses)))
            ys[:] = run(params, which)
            ys[~self.measured(first + len(which))[first:]] = np.nan
            for i, sd in enumerate(which):
                samples.append({"round": rnd, "seed": sd, **dict(zip(self.responses, ys[i]))})
            return ys

        def failed(ys) -> list:
            """(seed, responses) of every run of the round with a non-finite response."""
            measured = self.measured(len(ys))
            return [(sd, dict(zip(self.responses, row))) for sd, row, m in zip(seeds, ys, measured)
                    if not np.all(np.isfinite(row[m]))]

        ys = run_seeds(seeds)
        grown = 0
        judged = None
        bad = failed(ys)
        if not bad:
            judged = stats.judge(ys, self.counts(len(ys)), self.rtol, self.z, self.t,
                                 self.target_se)
            se, tol, e = judged[2], judged[3], judged[4]
            can_grow = self.caps > len(seeds)  # a response a grown set measures on more seeds
            if (np.all(np.abs(e) <= self.grow_within * tol) and spare
                    and np.any((self.z * se > self.rtol) & can_grow)):
                grown, seeds, spare = len(spare), seeds + spare, []
                ys = np.vstack([ys, run_seeds(seeds[-grown:], len(ys))])
                bad = failed(ys)
                if not bad:
                    judged = stats.judge(ys, self.counts(len(ys)), self.rtol, self.z, self.t,
                                         self.target_se)
        return Round(ys, seeds, spare, grown, bad,
                     *(judged if judged is not None else (None,) * 5), counts=self.counts(len(ys)))
