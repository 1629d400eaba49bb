"""What a card's lab targets pin and what they leave free (:func:`identifiability`).

The posterior's covariance in range-normalised parameters (each parameter divided by the
width of its design range) is split into its eigen-directions. Along each, the
posterior's standard deviation is compared with the prior's (the uniform box's, along the
same direction): the ratio is 1 where the targets tell nothing and near 0 where they fix
the combination. A direction is

- **pinned** when the ratio is below :data:`PINNED` (the targets narrow it at least
  fourfold),
- **free** when it is :data:`FREE` or more (they narrow it less than by a factor 1.7),
- **partly pinned** in between.

A direction is named by the parameters that carry it (weights of at least
:data:`WEIGHT` of the largest): one parameter alone; two with the same sign, their common
level; two with opposite signs, their balance (raising one while lowering the other keeps
the targets); more, the signed combination. :func:`best_test` says which test the study
can run would narrow the freest direction most (linearised: n specimens of a response
with slope g along the direction, scatter s per specimen and a surrogate error e add
g² / (s² / n + e²) to its precision: a test the surrogate cannot predict tells little).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from .._common import symbol

PINNED = 0.25
FREE = 0.6
WEIGHT = 0.3


def direction_text(v: np.ndarray, names: Sequence[str]) -> str:
    """The combination the unit vector ``v`` stands for (module docstring), in symbols."""
    v = np.asarray(v, float)
    v = v * np.sign(v[np.argmax(np.abs(v))])
    big = [j for j in np.argsort(-np.abs(v)) if abs(v[j]) >= WEIGHT * np.max(np.abs(v))]
    sym = [symbol(names[j]) for j in big]
    if len(big) == 1:
        return sym[0]
    if len(big) == 2:
        a, b = big
        if np.sign(v[a]) == np.sign(v[b]):
            return f"{sym[0]} and {sym[1]} together (their common level)"
        return f"the balance of {sym[0]} against {sym[1]} (raising one, lowering the other)"
    return " ".join(f"{'+' if v[j] >= 0 else '−'}{abs(v[j]):.2f}·{symbol(names[j])}"
                    for j in big).lstrip("+")


def identifiability(samples_u: np.ndarray, names: Sequence[str], prior_lo, prior_hi) -> dict:
    """The eigen-directions of the posterior (``samples_u``: draws in range-normalised
    coordinates) against the uniform prior on [``prior_lo``, ``prior_hi``] (same
    coordinates): per direction, its weights, posterior and prior sd, their ratio, its
    class and text (module docstring); per parameter, the ratio of its marginal sd to the
    prior's; and ``sentence``, what the targets pin and what they leave free."""
    X = np.asarray(samples_u, float)
    d = X.shape[1]
    C = np.atleast_2d(np.cov(X.T)) if len(X) > 1 else np.zeros((d, d))
    lam, V = np.linalg.eigh(C)
    prior_var = (np.asarray(prior_hi, float) - np.asarray(prior_lo, float)) ** 2 / 12.0
    dirs = []
    for i in np.argsort(lam):
        v = V[:, i] * np.sign(V[np.argmax(np.abs(V[:, i])), i])
        sd = math.sqrt(max(lam[i], 0.0))
        psd = math.sqrt(float(np.sum(v * v * prior_var)))
        ratio = sd / psd if psd > 0 else math.nan
        cls = "pinned" if ratio < PINNED else "free" if ratio >= FREE else "partly pinned"
        dirs.append({"weights": {n: round(float(w), 4) for n, w in zip(names, v)},
                     "posterior_sd": sd, "prior_sd": psd, "ratio": ratio, "class": cls,
                     "text": direction_text(v, names)})
    marg = {n: float(np.sqrt(C[j, j] / prior_var[j])) for j, n in enumerate(names)}
    return {"directions": dirs, "marginal_ratio": marg, "sentence": sentence(dirs)}


def sentence(dirs: list[dict]) -> str:
    """One or two sentences a user can act on: what is pinned and what is free."""
    pinned = [d for d in dirs if d["class"] == "pinned"]
    part = [d for d in dirs if d["class"] == "partly pinned"]
    free = [d for d in dirs if d["class"] == "free"]

    def pct(d):
        if d["ratio"] >= 0.9:  # along a ridge the box can allow more than its projection
            return "as wide as the prior allows"
        return f"{100 * d['ratio']:.0f} % of the prior's spread"

    out = []
    if pinned:
        out.append("The lab targets pin " + "; ".join(f"{d['text']} ({pct(d)})" for d in pinned))
    if part:
        out.append(("They only partly pin " if pinned else "The lab targets only partly pin ")
                   + "; ".join(f"{d['text']} ({pct(d)})" for d in part))
    if free:
        out.append(("They leave free " if (pinned or part) else "The lab targets leave free ")
                   + "; ".join(f"{d['text']} ({pct(d)})" for d in free)
                   + ": cards along it meet the targets alike")
    return ". ".join(out) + "."


def slope(predict, m_u: np.ndarray, v: np.ndarray, h: float = 0.02) -> float:
    """d prediction / d s along the unit direction ``v`` at ``m_u`` (central difference,
    step ``h`` in range-normalised units; ``predict`` maps (k, d) unit points to means)."""
    x = np.vstack([m_u + h * v, m_u - h * v])
    y = np.asarray(predict(x), float)
    return float((y[0] - y[1]) / (2 * h))


def best_test(direction: dict, names: Sequence[str], m_u: np.ndarray,
              candidates: Mapping[str, dict]) -> list[dict]:
    """How far each candidate test would narrow ``direction`` (:func:`identifiability`'s):
    ``candidates`` maps a label to ``{"predict": unit points -> means (surrogate scale),
    "noise": one specimen's sd (same scale), "n": specimens, "sur": the surrogate's own
    error there (same scale; default 0), "what": text}``; returns one
    row per candidate, the best (smallest new sd) first: label, what, slope, the new
    posterior sd along the direction and its ratio to the prior's."""
    v = np.array([direction["weights"][n] for n in names], float)
    sd0, psd = direction["posterior_sd"], direction["prior_sd"]
    rows = []
    for label, c in candidates.items():
        g = slope(c["predict"], m_u, v)
        var = c["noise"] ** 2 / c["n"] + float(c.get("sur", 0.0)) ** 2
        prec = (1.0 / sd0 ** 2 if sd0 > 0 else math.inf) + (g * g / var if var > 0 else math.inf)
        new = 1.0 / math.sqrt(prec) if prec > 0 else math.inf
        rows.append({"test": label, "what": c["what"], "slope": g, "posterior_sd": new,
                     "ratio": new / psd if psd > 0 else math.nan,
                     "narrows_by": (sd0 / new) if new > 0 else math.inf})
    return sorted(rows, key=lambda r: r["posterior_sd"])
