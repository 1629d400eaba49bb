"""The posterior over a card's free parameters given its lab targets (:func:`fit_posterior`).

Model (``docs/methods/posterior.md``)::

    prior       θ ~ uniform on the closed loop's box (the design ranges widened by the
                loop's margin), the card's other parameters fixed, a derived bond
                strength following its ratio
    likelihood  T(lab_r) ~ N(μ_r(θ), s_r² + c_r² σ_r(θ)²)   for every target r

``T`` is the surrogate's scale (log for strengths and moduli), ``μ_r`` and ``σ_r`` the
surrogate's prediction of the DEM's mean over packings and its own error
(:mod:`.surrogate`; ``c_r`` its held-out inflation), ``s_r`` the lab side: the lab's
standard error where the lab table gives one (a mean over its specimens), else the
packing scatter of one DEM specimen (the lab value is one specimen, and one specimen of
the rock scatters about its mean as a packing does). The posterior is sampled with emcee
to convergence (:mod:`.sampler`); what the targets pin and leave free comes from
:mod:`.identify`.

**Reach.** Whether a card inside the box can meet the targets at all: the smallest
χ²(θ) = Σ_r (T(lab_r) - μ_r)² / (s_r² + c_r² σ_r²) over the box, against the χ²
distribution with one degree of freedom per target. If some θ in the box produced the
targets, χ² there would follow that distribution and the minimum can only be smaller, so
``p_reach`` = P(χ² ≥ min) is the probability that targets this far off arise from a
card inside the box; below :data:`REACH_ALPHA` the targets are out of reach.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import minimize
from scipy.stats import chi2

from .._common import symbol
from .identify import FREE, best_test, identifiability
from .sampler import ESS_MIN, RHAT_MAX, Chains, sample
from .surrogate import (
    LOG_RESPONSES,
    TENSILE_SHARE,
    ResponseSurrogate,
    from_scale,
    to_scale,
)

REACH_ALPHA = 0.05
#: an HDI end within this share of the prior box's width from the box's bound is cut by
#: the prior (:func:`hdi_at_bound`)
AT_BOUND = 0.01
#: a prediction that moves by more than this across the posterior's 90 % interval (in
#: its own unit; the tensile crack share: 10 points) is called moved by the free direction
FAILURE_MODE_SPAN = 0.10


@dataclass(frozen=True)
class PosteriorSettings:
    """How a posterior is fitted: ``surrogate`` ("auto", "gp", "stepwise"), the random
    ``seed``, the interval probability ``hdi_prob``, the sampler's convergence targets
    (:func:`~.sampler.sample`) and how many ``draws`` it keeps (thinned evenly)."""

    surrogate: str = "auto"
    seed: int = 0
    hdi_prob: float = 0.9
    rhat_max: float = RHAT_MAX
    ess_min: int = ESS_MIN
    max_steps: int = 40000
    chunk: int = 1000
    walkers: int | None = None
    draws: int = 4000

    def __post_init__(self):
        if self.surrogate not in ("auto", "gp", "stepwise"):
            raise ValueError(f"surrogate={self.surrogate!r}: expected auto, gp or stepwise")
        if not 0 < self.hdi_prob < 1:
            raise ValueError(f"hdi_prob={self.hdi_prob!r}: expected a probability in (0, 1)")
        if not self.rhat_max > 1:
            raise ValueError(f"rhat_max={self.rhat_max!r}: expected a number > 1")
        for name in ("ess_min", "max_steps", "chunk", "draws"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name}={v!r}: expected an integer >= 1")


@dataclass
class Problem:
    """The parameter side of a posterior: ``free`` parameters with their prior box
    (``lo``, ``hi``, physical units), ``fixed`` values, an optional ``ratio`` deriving
    ``derived`` = ratio x ``coh``; ``ranges`` the design ranges (range-normalised
    coordinates)."""

    free: tuple[str, ...]
    lo: np.ndarray
    hi: np.ndarray
    fixed: dict
    ranges: dict
    ratio: float | None = None
    derived: str | None = None
    coh: str | None = None

    def columns(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Full parameter sets of the free values ``X`` (m, d), as columns (the sampler's
        hot path: no DataFrame)."""
        X = np.atleast_2d(np.asarray(X, float))
        cols = {p: np.full(len(X), float(v)) for p, v in self.fixed.items()}
        cols.update({p: X[:, j] for j, p in enumerate(self.free)})
        if self.ratio is not None and self.derived:
            cols[self.derived] = self.ratio * cols[self.coh]
        return cols

    def frame(self, X: np.ndarray) -> pd.DataFrame:
        """Full parameter sets (DataFrame) of the free values ``X`` (m, d)."""
        return pd.DataFrame(self.columns(X))

    def unit(self, X: np.ndarray) -> np.ndarray:
        """Free values -> range-normalised coordinates (the design ranges)."""
        lo = np.array([self.ranges[p][0] for p in self.free], float)
        w = np.array([self.ranges[p][1] - self.ranges[p][0] for p in self.free], float)
        return (np.atleast_2d(X) - lo) / w

    def from_unit(self, U: np.ndarray) -> np.ndarray:
        lo = np.array([self.ranges[p][0] for p in self.free], float)
        w = np.array([self.ranges[p][1] - self.ranges[p][0] for p in self.free], float)
        return lo + np.atleast_2d(U) * w


@dataclass
class PosteriorResults:
    """Outcome of :func:`fit_posterior` (module docstring). ``draws``: the kept draws of
    every calibrated parameter (free and derived); ``summary`` one row per parameter;
    ``predictions`` one row per response (targets and untargeted); ``reach`` the χ² test;
    ``identifiability`` and ``suggestions`` what the targets pin and what would pin the
    rest."""

    problem: Problem
    draws: pd.DataFrame
    chains: Chains
    targets: dict
    lab_sd: dict
    lab_sd_source: dict
    surrogates: dict
    card: dict
    summary: pd.DataFrame
    predictions: pd.DataFrame
    reach: dict
    identifiability: dict
    suggestions: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    settings: PosteriorSettings = field(default_factory=PosteriorSettings)

    @property
    def converged(self) -> bool:
        return self.chains.converged

    def to_frame(self) -> pd.DataFrame:
        return self.summary

    def text(self) -> str:
        """Plain-text report: the table, the predictions, reach and identifiability."""
        c = self.chains
        head = (f"Posterior over {', '.join(self.problem.free)}: {len(self.draws)} draws, "
                f"{c.steps} steps x {c.chain.shape[0]} walkers, max R-hat "
                f"{np.max(c.rhat):.4f}, min ESS {np.min(np.minimum(c.ess_bulk, c.ess_tail)):.0f}"
                f" ({'converged' if self.converged else 'NOT converged'})")
        return "\n".join([head, "", self.summary.to_string(), "", self.predictions.to_string(),
                          "", self.reach["text"], "", self.identifiability["sentence"],
                          *self.notes])

    def to_inference_data(self):
        """An arviz InferenceData: ``posterior`` (chain = walker, draw), ``sample_stats``
        (``lp``), ``posterior_predictive`` (each target's surrogate mean on the draws, the
        target's unit) and ``observed_data`` (the lab targets)."""
        import arviz as az

        ch = self.chains.chain
        post = {p: ch[:, :, j] for j, p in enumerate(self.problem.free)}
        if self.problem.derived:
            post[self.problem.derived] = self.problem.ratio * post[self.problem.coh]
        pp = {}
        flat = self.problem.frame(self.chains.flat)
        for r, s in self.surrogates.items():
            if r in self.targets:
                m, _ = s.predict(flat)
                pp[r] = from_scale(r, m).reshape(ch.shape[:2])
        attrs = {"free": ",".join(self.problem.free), "hdi_prob": self.settings.hdi_prob,
                 "surrogates": ",".join(f"{r}:{s.kind}" for r, s in self.surrogates.items()),
                 "p_reach": float(self.reach["p_reach"]), "converged": int(self.converged),
                 "steps": int(self.chains.steps), "thin": int(self.chains.thin)}
        return az.from_dict(posterior=post, sample_stats={"lp": self.chains.log_prob},
                            posterior_predictive=pp,
                            observed_data={r: np.array([v]) for r, v in self.targets.items()},
                            attrs=attrs)


def _lab_sd(targets: Mapping[str, float], target_se: Mapping[str, float] | None,
            surrogates: Mapping[str, ResponseSurrogate]) -> tuple[dict, dict]:
    """The lab side's sd of every target on the surrogate's scale, and where it comes
    from (module docstring)."""
    sd, src = {}, {}
    se = dict(target_se or {})
    for r, v in targets.items():
        if r in se and se[r] is not None and float(se[r]) > 0:
            sd[r] = float(se[r]) / abs(float(v)) if r in LOG_RESPONSES else float(se[r])
            src[r] = "lab standard error"
        else:
            sd[r] = surrogates[r].noise_sd
            src[r] = "one specimen's packing scatter"
    return sd, src


def log_likelihood(problem: Problem, surrogates, targets, lab_sd) -> Callable:
    """The vectorised log-likelihood of free values (m, d) (module docstring)."""
    y = {r: float(to_scale(r, v)) for r, v in targets.items()}

    def ll(X):
        P = problem.columns(X)
        out = np.zeros(len(X))
        for r in targets:
            m, s = surrogates[r].predict(P)
            var = lab_sd[r] ** 2 + s ** 2
            out -= 0.5 * ((y[r] - m) ** 2 / var + np.log(2 * np.pi * var))
        return out

    return ll


def chi2_terms(problem: Problem, surrogates, targets, lab_sd, X) -> np.ndarray:
    """χ² (module docstring) of every row of free values ``X``."""
    P = problem.columns(X)
    out = np.zeros(len(np.atleast_2d(X)))
    for r, v in targets.items():
        m, s = surrogates[r].predict(P)
        out += (float(to_scale(r, v)) - m) ** 2 / (lab_sd[r] ** 2 + s ** 2)
    return out


def reach_test(problem: Problem, surrogates, targets, lab_sd, starts: np.ndarray) -> dict:
    """The smallest χ² over the box from ``starts`` and the probability of reach."""
    lo, hi = problem.lo, problem.hi

    def f(x):
        return float(chi2_terms(problem, surrogates, targets, lab_sd, x[None, :])[0])

    best = None
    for x0 in np.atleast_2d(starts):
        res = minimize(f, np.clip(x0, lo, hi), method="L-BFGS-B", bounds=list(zip(lo, hi)))
        if best is None or res.fun < best.fun:
            best = res
    k = len(targets)
    p = float(chi2.sf(best.fun, k))
    point = {q: float(v) for q, v in zip(problem.free, best.x)}
    names = ", ".join(symbol(r) for r in targets)
    if p >= REACH_ALPHA:
        text = (f"Within reach: the best card inside the box meets {names} to χ² = "
                f"{best.fun:.2f} on {k} targets (p = {p:.2f} with the surrogate's own error "
                "and the lab side's scatter).")
    else:
        text = (f"Out of reach: no card inside the box meets {names}; the best reaches χ² = "
                f"{best.fun:.1f} on {k} targets, p = {p:.2g} that a card inside the box "
                "misses this far (counting the surrogate's own error).")
    return {"chi2_min": float(best.fun), "dof": k, "p_reach": p, "reachable": p >= REACH_ALPHA,
            "best": point, "text": text}


def _hdi(x: np.ndarray, prob: float) -> tuple[float, float]:
    """The highest-density interval of the draws ``x`` (the shortest interval holding
    ``prob`` of them)."""
    s = np.sort(np.asarray(x, float))
    n = len(s)
    m = max(1, int(math.ceil(prob * n)))
    if m >= n:
        return float(s[0]), float(s[-1])
    widths = s[m - 1:] - s[:n - m + 1]
    i = int(np.argmin(widths))
    return float(s[i]), float(s[i + m - 1])


def hdi_at_bound(lo: float, hi: float, box_lo: float, box_hi: float,
                 tol: float = AT_BOUND) -> str:
    """Which end of the interval [``lo``, ``hi``] the prior box [``box_lo``, ``box_hi``]
    cuts: "low", "high", "both" or "" (an end within ``tol`` of the box's width from its
    bound). An HDI that ends at a bound of the box ends there because the prior does, not
    the lab data: the density is still high at the bound, and cards beyond it would meet
    the targets as well."""
    w = box_hi - box_lo
    if not (math.isfinite(lo) and math.isfinite(hi)) or not w > 0:
        return ""
    low = lo - box_lo <= tol * w
    high = box_hi - hi <= tol * w
    return "both" if low and high else "low" if low else "high" if high else ""


def _summary(problem: Problem, draws: pd.DataFrame, card: dict, prob: float, chains: Chains
             ) -> pd.DataFrame:
    rows = []
    names = list(problem.free) + ([problem.derived] if problem.derived else [])
    for j, p in enumerate(names):
        x = draws[p].to_numpy(float)
        lo, hi = _hdi(x, prob)
        rlo, rhi = problem.ranges[p]
        cut = (hdi_at_bound(lo, hi, float(problem.lo[j]), float(problem.hi[j]))
               if p in problem.free else "")
        cv = float(card.get(p, math.nan))
        rows.append({"parameter": p, "symbol": symbol(p), "card": cv, "mean": float(x.mean()),
                     "sd": float(x.std(ddof=1)), "hdi_low": lo, "hdi_high": hi,
                     "hdi_width_pct_of_range": 100 * (hi - lo) / (rhi - rlo),
                     "card_quantile": float(np.mean(x < cv)) if math.isfinite(cv) else math.nan,
                     "card_in_hdi": bool(lo <= cv <= hi) if math.isfinite(cv) else False,
                     "rhat": float(chains.rhat[j]) if j < len(chains.rhat) else math.nan,
                     "ess_bulk": float(chains.ess_bulk[j]) if j < len(chains.rhat) else math.nan,
                     "ess_tail": float(chains.ess_tail[j]) if j < len(chains.rhat) else math.nan,
                     "role": "free" if p in problem.free else "derived",
                     "hdi_cut_by_prior": cut})
    return pd.DataFrame(rows).set_index("parameter")


def prior_cut_note(problem: Problem, summary: pd.DataFrame, prob: float) -> str:
    """One sentence per parameter whose HDI the prior box cuts (:func:`hdi_at_bound`):
    its interval shows the box's limit there, not the lab data's, and which range to
    widen to see how far the data allow ("" when none is cut)."""
    out = []
    for j, p in enumerate(problem.free):
        cut = summary.loc[p, "hdi_cut_by_prior"] if "hdi_cut_by_prior" in summary else ""
        if not cut:
            continue
        ends = {"low": [("lower", problem.lo[j])], "high": [("upper", problem.hi[j])],
                "both": [("lower", problem.lo[j]), ("upper", problem.hi[j])]}[cut]
        where = " and ".join(f"its {side} bound {v:.4g}" for side, v in ends)
        out.append(f"The {100 * prob:.0f} % HDI of {symbol(p)} ends at {where}: the prior cuts "
                   "it there, not the lab data (cards beyond it would meet the targets as "
                   f"well); widen ranges.{p} (the prior is the closed loop's box: the "
                   "design range and its margin) to see how far the data allow.")
    return " ".join(out)


def _predictions(problem: Problem, surrogates, targets, draws_free: np.ndarray, card: dict,
                 prob: float) -> pd.DataFrame:
    """Each surrogate's prediction (the target's unit) at the card and across the draws:
    mean and the central ``prob`` interval (the DEM mean's spread among the cards the
    posterior holds)."""
    P = problem.frame(draws_free)
    cardP = problem.frame(np.array([[card[p] for p in problem.free]]))
    rows = []
    q = (1 - prob) / 2
    for r, s in surrogates.items():
        m, _ = s.predict(P)
        v = from_scale(r, m)
        c = float(from_scale(r, s.predict(cardP)[0])[0])
        rows.append({"response": r, "symbol": symbol(r) if r != TENSILE_SHARE else "tensile share",
                     "targeted": r in targets, "lab": targets.get(r, math.nan),
                     "card": c, "mean": float(v.mean()), "low": float(np.quantile(v, q)),
                     "high": float(np.quantile(v, 1 - q)), "surrogate": s.kind})
    return pd.DataFrame(rows).set_index("response")


def fit_posterior(surrogates: Mapping[str, ResponseSurrogate], problem: Problem,
                  targets: Mapping[str, float], card: Mapping[str, float], *,
                  target_se: Mapping[str, float] | None = None,
                  settings: PosteriorSettings = PosteriorSettings(),
                  tests: Mapping[str, dict] | None = None) -> PosteriorResults:
    """:func:`_fit_posterior` (its docstring) with one BLAS thread (small matrices)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return _fit_posterior(surrogates, problem, targets, card, target_se=target_se,
                              settings=settings, tests=tests)


# long: the assembly of the posterior (likelihood, sampling, the summary tables, reach,
# identifiability and its notes) in the order the module docstring gives it
def _fit_posterior(surrogates: Mapping[str, ResponseSurrogate], problem: Problem,
                   targets: Mapping[str, float], card: Mapping[str, float], *,
                   target_se: Mapping[str, float] | None = None,
                   settings: PosteriorSettings = PosteriorSettings(),
                   tests: Mapping[str, dict] | None = None) -> PosteriorResults:
    """The posterior (module docstring) of ``problem``'s free parameters given ``targets``
    (response -> lab value; each needs a surrogate; ``target_se`` their lab standard
    errors) starting from the ``card`` (its free values must lie in the box).
    ``surrogates`` may hold untargeted responses too: their spread over the posterior is
    reported (``predictions``). ``tests``: label -> {"response", "n", "what"}, the tests
    the study can run, for :func:`best_test`."""
    missing = [r for r in targets if r not in surrogates]
    if missing:
        raise ValueError(f"no surrogate of the target(s) {missing}")
    x0 = np.array([float(card[p]) for p in problem.free])
    outside = [p for p, v, a, b in zip(problem.free, x0, problem.lo, problem.hi)
               if not a - 1e-9 * (b - a) <= v <= b + 1e-9 * (b - a)]
    if outside:
        raise ValueError("the card lies outside its prior box: " + "; ".join(
            f"{p} = {card[p]:g} outside [{a:g}, {b:g}]" for p, a, b in
            zip(problem.free, problem.lo, problem.hi) if p in outside))
    x0 = np.clip(x0, problem.lo, problem.hi)
    targets = {r: float(v) for r, v in targets.items()}
    lab_sd, lab_src = _lab_sd(targets, target_se, surrogates)
    ll = log_likelihood(problem, surrogates, targets, lab_sd)
    chains = sample(ll, problem.lo, problem.hi, x0, seed=settings.seed, walkers=settings.walkers,
                    chunk=settings.chunk, max_steps=settings.max_steps,
                    rhat_max=settings.rhat_max, ess_min=settings.ess_min, keep=settings.draws)
    flat = chains.flat
    draws = problem.frame(flat)[list(problem.free) + ([problem.derived] if problem.derived
                                                      else [])]
    summary = _summary(problem, draws, dict(card), settings.hdi_prob, chains)
    preds = _predictions(problem, surrogates, targets, flat, dict(card), settings.hdi_prob)
    best_draw = flat[int(np.argmax(chains.log_prob.reshape(-1)))]
    reach = reach_test(problem, surrogates, targets, lab_sd, np.vstack([best_draw, x0]))
    U = problem.unit(flat)
    ident = identifiability(U, problem.free, *problem.unit(np.vstack([problem.lo, problem.hi])))
    notes, sugg = [], []
    freest = ident["directions"][-1]
    if tests:
        m_u = U.mean(0)
        cands = {}
        for label, t in tests.items():
            r = t["response"]
            if r not in surrogates:
                continue
            s = surrogates[r]
            noise = lab_sd[r] if r in targets else s.noise_sd
            sur = float(s.predict(problem.columns(problem.from_unit(m_u[None, :])))[1][0])
            cands[label] = {"predict": (lambda Uq, s=s: s.predict(problem.columns(
                problem.from_unit(Uq)))[0]), "noise": noise, "n": int(t.get("n", 1)),
                "sur": sur, "what": t.get("what", label)}
        sugg = best_test(freest, problem.free, m_u, cands) if cands else []
    if TENSILE_SHARE in preds.index:
        row = preds.loc[TENSILE_SHARE]
        if row["high"] - row["low"] > FAILURE_MODE_SPAN:
            notes.append(f"The posterior leaves the failure mode free: the tensile crack share "
                         f"of a UCS run spans {100 * row['low']:.0f}-{100 * row['high']:.0f} % "
                         f"({100 * settings.hdi_prob:.0f} % of the cards that meet the targets;"
                         f" this card {100 * row['card']:.0f} %).")
    cut = prior_cut_note(problem, summary, settings.hdi_prob)
    if cut:
        notes.append(cut)
    if freest["class"] != "pinned" and sugg and freest["ratio"] >= FREE:
        b = sugg[0]
        notes.append(f"{b['what']} would narrow the freest direction ({freest['text']}) "
                     f"{b['narrows_by']:.1f}-fold, to {100 * b['ratio']:.0f} % of the prior's "
                     "spread.")
    return PosteriorResults(problem, draws, chains, targets, lab_sd, lab_src, dict(surrogates),
                            dict(card), summary, preds, reach, ident, sugg, notes, settings)
