"""Sampling a posterior over a box with emcee until it has converged (:func:`sample`).

emcee's ensemble sampler (Goodman & Weare 2010; Foreman-Mackey et al. 2013; moves:
:func:`moves`) is used because a calibration posterior is low-dimensional (3-6 free parameters)
and often a narrow curved ridge (two bond strengths that trade off): an affine-invariant
move follows a linear ridge at any orientation and scale without tuning a proposal, and
the whole ensemble is evaluated at once (the surrogate predicts every walker in one
call). The prior is uniform on the box; the log-density is -inf outside it.

Convergence is judged on the second half of the chains (the first half is warm-up) and
the sampler runs on in chunks until, for every parameter, the rank-normalised split
R-hat (Vehtari et al. 2021, arviz; each walker a chain) is at most ``rhat_max`` and the
bulk and tail effective sample sizes are at least ``ess_min``, and the kept half is at
least 50 integrated autocorrelation times long (emcee's own rule). A run that reaches
``max_steps`` first returns what it has with ``converged`` False. The walkers start in a
small ball around the given point (the card, or the best fit), the random stream is
seeded: the chains are a function of the inputs and the seed.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

RHAT_MAX = 1.01


def moves():
    """emcee's moves: differential evolution (ter Braak 2006), with a fifth of stretch
    moves. Differential evolution follows a correlated ridge faster than the stretch move
    alone; emcee's snooker move, the other half of the mix its documentation suggests,
    shrank the variances of a known Gaussian by 5-20 % here and is not used."""
    import emcee

    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.StretchMove(), 0.2)]


ESS_MIN = 400
TAU_FACTOR = 50


@dataclass
class Chains:
    """The kept (post-warm-up) chains: ``chain`` (walkers, draws, d) and their
    log-densities ``log_prob`` (walkers, draws); the convergence figures per parameter
    (``rhat``, ``ess_bulk``, ``ess_tail``, ``tau``), the steps run, the acceptance
    fraction and whether every criterion was met."""

    chain: np.ndarray
    log_prob: np.ndarray
    rhat: np.ndarray
    ess_bulk: np.ndarray
    ess_tail: np.ndarray
    tau: np.ndarray
    steps: int
    acceptance: float
    converged: bool
    thin: int = 1

    @property
    def flat(self) -> np.ndarray:
        """Every kept draw, (walkers * draws, d)."""
        return self.chain.reshape(-1, self.chain.shape[-1])


def diagnostics(chain: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """R-hat, bulk and tail ESS per parameter of ``chain`` (walkers, draws, d), with
    arviz (rank-normalised split R-hat; each walker a chain)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import arviz as az

        ds = az.convert_to_dataset({"x": chain})
        rhat = np.atleast_1d(az.rhat(ds)["x"].to_numpy())
        bulk = np.atleast_1d(az.ess(ds, method="bulk")["x"].to_numpy())
        tail = np.atleast_1d(az.ess(ds, method="tail")["x"].to_numpy())
    return rhat, bulk, tail


def _tau(chain: np.ndarray) -> np.ndarray:
    """emcee's integrated autocorrelation time per parameter (steps x walkers x d input
    order of emcee; ``chain`` here is walkers x draws x d), without its length check."""
    import logging

    import emcee

    logging.disable(logging.WARNING)  # its "chain is shorter than 50 tau" note: judged here
    try:
        return np.atleast_1d(emcee.autocorr.integrated_time(np.swapaxes(chain, 0, 1),
                                                            quiet=True))
    finally:
        logging.disable(logging.NOTSET)


def sample(log_prob, lo, hi, x0, *, seed: int = 0, walkers: int | None = None,
           chunk: int = 1000, max_steps: int = 40000, rhat_max: float = RHAT_MAX,
           ess_min: int = ESS_MIN, ball: float = 1e-2, keep: int = 4000) -> Chains:
    """Sample ``log_prob`` (vectorised: (m, d) -> (m,), -inf for impossible points) over the
    box [``lo``, ``hi``] from ``x0`` (module docstring). ``walkers`` defaults to
    max(32, 8 d); ``ball`` is the starting spread as a fraction of the box; ``keep``
    bounds the draws returned (the kept half is thinned to about that many)."""
    import emcee

    lo, hi, x0 = (np.asarray(v, float) for v in (lo, hi, x0))
    d = len(lo)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
        raise ValueError(f"the prior box [{lo}, {hi}] is empty or not finite")
    if not np.all((x0 >= lo) & (x0 <= hi)):
        raise ValueError(f"the start {x0} is outside the prior box [{lo}, {hi}]")
    nw = int(walkers or max(32, 8 * d))
    rng = np.random.default_rng(seed)
    width = hi - lo
    p0 = x0 + ball * width * rng.standard_normal((nw, d))
    p0 = np.clip(p0, lo + 1e-9 * width, hi - 1e-9 * width)

    def lp(x):
        x = np.atleast_2d(x)
        out = np.full(len(x), -np.inf)
        inside = np.all((x >= lo) & (x <= hi), axis=1)
        if inside.any():
            out[inside] = log_prob(x[inside])
        return np.where(np.isfinite(out), out, -np.inf)

    if not np.isfinite(lp(p0)).all():
        p0 = np.repeat(x0[None, :], nw, axis=0) + 1e-6 * width * rng.standard_normal((nw, d))
        p0 = np.clip(p0, lo, hi)
    sampler = emcee.EnsembleSampler(nw, d, lp, vectorize=True, moves=moves())
    sampler.random_state = np.random.RandomState(seed % 2 ** 32).get_state()
    state, steps = p0, 0
    while True:
        state = sampler.run_mcmc(state, chunk, progress=False)
        steps += chunk
        chain = np.swapaxes(sampler.get_chain(), 0, 1)  # walkers, steps, d
        half = chain[:, steps // 2:, :]
        rhat, bulk, tail = diagnostics(half)
        tau = _tau(half)
        done = (np.all(rhat <= rhat_max) and np.all(bulk >= ess_min)
                and np.all(tail >= ess_min) and half.shape[1] >= TAU_FACTOR * np.max(tau))
        if done or steps >= max_steps:
            break
    lps = np.swapaxes(sampler.get_log_prob(), 0, 1)[:, steps // 2:]
    thin = max(1, int(math.ceil(half.shape[0] * half.shape[1] / keep)))
    return Chains(half[:, ::thin], lps[:, ::thin], rhat, bulk, tail, tau, steps,
                  float(np.mean(sampler.acceptance_fraction)), bool(done), thin)
