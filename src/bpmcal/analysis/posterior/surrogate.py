"""Surrogates of the DEM responses for the posterior (:func:`fit_surrogate`).

A surrogate predicts one response's mean over packings, and its own error, at any
parameter set of a card's design space. Two are fitted to the same runs and the one that
predicts the runs near the card best is kept (:func:`fit_surrogate`):

- ``gp``: the stepwise regression's terms as an explicit basis plus a Gaussian process
  (:class:`~.gp.BasisGP`): interpolates the closed loop's rounds exactly to their noise;
- ``stepwise``: the same basis by weighted least squares, its error the coefficients'
  uncertainty plus the lack of fit (the residual variance beyond the packing scatter
  that replicated runs measure).

The runs (:func:`response_data`): the design samples (one run each) and every run near
the card (closed-loop rounds, fresh seeds, refinement runs), one row per specimen (a
tensile seed's discs are one row each). Runs at the same parameter set are one point,
the mean of its ``k`` specimens; the scatter among them (pooled over every replicated
point) is the packing scatter of one specimen, the analogue of a lab specimen's scatter.

Responses are modelled on a log scale where they are strengths or moduli (positive,
with a scatter proportional to their size: :data:`LOG_RESPONSES`), on their own scale
otherwise (ν, the tensile crack share).

Held-out test (:func:`held_out`): each group of near-card points that share packings (the
closed loop's rounds; the fresh seeds; a refinement step) in turn is left out and
predicted from the rest (the process's hyperparameters kept); without points near the
card, the design samples in five folds. The surrogate with the smaller root-mean-square error is
chosen; if its standardised errors show it is overconfident (mean z² > 1), its error is
scaled up until they do not (``inflation``), so the likelihood never trusts it more than
the runs near the card allow.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from bpmcal.params import STRENGTH_RESPONSES

from .gp import BasisGP, fit_basis_gp, shared_packings

#: responses modelled on the log scale (positive, scatter proportional to size)
LOG_RESPONSES = (*STRENGTH_RESPONSES, "E_GPa")
#: the failure mode of a UCS run: tensile cracks / (tensile + shear cracks)
TENSILE_SHARE = "tensile_share"
SOURCES = ("design", "loop", "fresh", "refine")
SURROGATES = ("auto", "gp", "stepwise")


def to_scale(resp: str, v):
    """A response's values on the surrogate's scale (log for :data:`LOG_RESPONSES`)."""
    v = np.asarray(v, float)
    if resp in LOG_RESPONSES:
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(v > 0, np.log(np.where(v > 0, v, 1.0)), np.nan)
    return v


def from_scale(resp: str, v):
    """Inverse of :func:`to_scale`."""
    v = np.asarray(v, float)
    return np.exp(v) if resp in LOG_RESPONSES else v


def tensile_share(df: pd.DataFrame) -> pd.Series:
    """The tensile crack share of UCS runs (NaN where no crack formed)."""
    nan = pd.Series(np.nan, index=df.index)
    t = pd.to_numeric(df["cracks_tension"], errors="coerce") if "cracks_tension" in df else nan
    s = pd.to_numeric(df["cracks_shear"], errors="coerce") if "cracks_shear" in df else nan
    tot = t + s
    return (t / tot.where(tot > 0)).astype(float)


@dataclass
class ResponseData:
    """The runs of one response as points (:func:`response_data`): ``X`` unit
    coordinates (n, d), ``P`` the parameters (DataFrame, physical units), ``y`` the mean
    on the surrogate's scale of ``k`` specimens, ``source`` each point's origin;
    ``pure_sd``/``pure_dof``: the pooled scatter of one specimen among replicated points
    (NaN, 0 without replicates); ``n_obs`` specimens in all; ``C`` which points share
    packings (a run's ``packing`` label; None when none do)."""

    response: str
    params: tuple[str, ...]
    X: np.ndarray
    P: pd.DataFrame
    y: np.ndarray
    k: np.ndarray
    source: np.ndarray
    pure_sd: float
    pure_dof: int
    n_obs: int
    H_raw: np.ndarray  # the raw basis columns of the points
    C: np.ndarray | None = None  # the shared-packing matrix (gp.shared_packings)

    @property
    def near(self) -> np.ndarray:
        """Points near the card (every source but the design)."""
        return self.source != "design"


def unit(P, params: Sequence[str], ranges) -> np.ndarray:
    """Parameters (physical units: a DataFrame, a mapping of columns, or an array with
    ``params``' columns) -> unit coordinates of the design ranges."""
    if isinstance(P, np.ndarray):
        A = np.asarray(P, float)
    else:
        A = np.column_stack([np.asarray(P[p], float) for p in params])
    lo = np.array([ranges[p][0] for p in params], float)
    hi = np.array([ranges[p][1] for p in params], float)
    return (A - lo) / (hi - lo)


def response_data(runs: pd.DataFrame, resp: str, params: Sequence[str], ranges, basis
                  ) -> ResponseData:
    """The points of ``resp`` from ``runs`` (one row per specimen: the parameters, a
    ``source`` column, the response; rows with a non-finite value are left out), with
    their raw basis columns ``basis(P)``."""
    vals = to_scale(resp, runs[resp])
    ok = np.isfinite(vals) & np.isfinite(runs[list(params)].to_numpy(float)).all(1)
    df = runs.loc[ok, list(params) + ["source"]].copy()
    df["_y"] = vals[ok]
    if df.empty:
        raise ValueError(f"no run with a finite {resp}")
    # a point: one parameter set of one source (the fresh seeds at the card's point are a
    # point of their own beside the loop's best round: other packings, a separate test)
    key = df[list(params)].round(12).astype(str).agg("|".join, axis=1) + "|" + df["source"]
    df["_key"] = key
    df["_packing"] = (runs.loc[ok, "packing"].astype(str) if "packing" in runs.columns
                      else [f"_run{i}" for i in range(len(df))])
    g = df.groupby("_key", sort=False)
    first = g.first()
    y = g["_y"].mean().to_numpy(float)
    k = g["_y"].size().to_numpy(float)
    dev = df["_y"] - g["_y"].transform("mean")
    dof = int((k - 1).sum())
    pure = float(np.sqrt((dev ** 2).sum() / dof)) if dof > 0 else math.nan
    # a point's source: the first run's (a fresh seed at the card's point joins the
    # loop's best round there: "loop")
    P = first[list(params)].reset_index(drop=True)
    H_raw = np.asarray(basis(P), float).reshape(len(y), -1)
    labels = [list(v) for v in g["_packing"].agg(list)]
    return ResponseData(resp, tuple(params), unit(P, params, ranges), P, y, k,
                        first["source"].to_numpy(str), pure, dof, int(len(df)), H_raw,
                        shared_packings(labels))


@dataclass
class ResponseSurrogate:
    """A fitted surrogate of one response (:func:`fit_surrogate`)."""

    response: str
    kind: str
    model: BasisGP
    params: tuple[str, ...]
    ranges: dict
    basis: object  # callable DataFrame -> raw basis columns
    noise_sd: float  # one specimen's packing scatter on the surrogate's scale
    inflation: float = 1.0
    scores: dict = field(default_factory=dict)
    n_points: int = 0
    n_obs: int = 0
    n_near: int = 0

    def predict(self, P: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """The mean over packings and the surrogate's own error (sd), on the surrogate's
        scale, at the parameter sets ``P`` (a DataFrame or a mapping of columns with every
        parameter)."""
        m, s = self.model.predict(unit(P, self.params, self.ranges), self.basis(P))
        return m, self.inflation * s

    def describe(self) -> dict:
        return {"kind": self.kind, "inflation": float(self.inflation),
                "noise_sd": float(self.noise_sd), "packing_share": float(self.model.rho),
                "points": self.n_points,
                "specimens": self.n_obs, "near_points": self.n_near,
                "scale": "log" if self.response in LOG_RESPONSES else "linear",
                "held_out": {k: dict(v) for k, v in self.scores.items()}}


def components(data: ResponseData, idx: np.ndarray) -> list[np.ndarray]:
    """The points ``idx`` grouped by the packings they share (connected components of the
    shared-packing matrix): a closed loop's rounds are one group, the fresh seeds another,
    each refinement step with new seeds another."""
    idx = list(idx)
    parent = {i: i for i in idx}

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    if data.C is not None:
        for a in idx:
            for b in idx:
                if a < b and data.C[a, b] > 0:
                    parent[root(a)] = root(b)
    groups: dict[int, list[int]] = {}
    for i in idx:
        groups.setdefault(root(i), []).append(i)
    return [np.array(g) for g in groups.values()]


def held_out(model: BasisGP, data: ResponseData, kind: str, noise_sd: float, seed: int = 0
             ) -> dict:
    """Held-out prediction of ``data``'s points by ``model`` (module docstring): the
    root-mean-square error (surrogate scale), the mean standardised error squared
    (``mean_z2``) and the errors themselves. Near the card (``on``: "near") a group of
    points that share packings is left out whole (:func:`components`): a round left out
    while its packings stay in the others would be predicted through their offsets, which
    no fresh packing shares. Without points near the card, five folds of the design
    (``on``: "design")."""
    near = np.flatnonzero(data.near)
    if len(near) >= 1:
        folds, on = components(data, near), "near"
    else:
        idx = np.random.default_rng(seed).permutation(len(data.y))
        folds, on = [f for f in np.array_split(idx, 5) if len(f)], "design"
    e, sig2, noise2 = [], [], []
    for f in folds:
        drop = np.zeros(len(data.y), bool)
        drop[f] = True
        if kind == "gp":
            m = model.without(drop)
        else:
            C = None if data.C is None else data.C[np.ix_(~drop, ~drop)]
            m = fit_basis_gp(data.X[~drop], data.H_raw[~drop], data.y[~drop],
                             data.k[~drop], gp=False, noise=noise_sd, C=C, rho=model.rho)
        mu, sd = m.predict(data.X[f], data.H_raw[f])
        e.extend(data.y[f] - mu)
        sig2.extend(sd ** 2)
        noise2.extend(noise_sd ** 2 / data.k[f])
    e, sig2, noise2 = (np.asarray(v, float) for v in (e, sig2, noise2))
    return {"on": on, "points": int(len(e)), "groups": len(folds),
            "rmse": float(np.sqrt(np.mean(e ** 2))),
            "mean_z2": float(np.mean(e ** 2 / (sig2 + noise2))),
            "_e": e, "_sig2": sig2, "_noise2": noise2}


def inflation(e: np.ndarray, sig2: np.ndarray, noise2: np.ndarray) -> float:
    """The factor c >= 1 on the surrogate's error that makes the held-out errors' mean
    standardised square 1 (1 when they are already no larger than predicted)."""
    def excess(c):
        return float(np.mean(e ** 2 / (c * c * sig2 + noise2))) - 1.0

    if excess(1.0) <= 0 or not np.any(sig2 > 0):
        return 1.0
    hi = 2.0
    while excess(hi) > 0 and hi < 1e6:
        hi *= 2.0
    return float(brentq(excess, 1.0, hi)) if excess(hi) <= 0 else hi


def _noise_sd(data: ResponseData, noise, m: BasisGP) -> float:
    """One specimen's packing scatter: measured on replicated runs (two or more degrees of
    freedom), else the larger of a single replicate pair's and the process's estimate (a
    Gaussian process on few points can put all the scatter into its trend)."""
    if noise is not None:
        return float(noise)
    if data.pure_dof == 1 and math.isfinite(data.pure_sd):
        return float(max(data.pure_sd, m.noise))
    return float(m.noise)


def fit_surrogate(runs: pd.DataFrame, resp: str, params: Sequence[str], ranges, basis, *,
                  choice: str = "auto", seed: int = 0) -> ResponseSurrogate:
    """:func:`_fit_surrogate` with one BLAS thread (its matrices are a few hundred rows: a
    thread pool only spins, and on a loaded machine it spins for a long time)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return _fit_surrogate(runs, resp, params, ranges, basis, choice=choice, seed=seed)


def _fit_surrogate(runs: pd.DataFrame, resp: str, params: Sequence[str], ranges, basis, *,
                   choice: str = "auto", seed: int = 0) -> ResponseSurrogate:
    """The surrogate of ``resp`` (module docstring) on ``runs`` (rows: specimens; columns:
    ``params``, ``source``, ``resp``) with the raw basis ``basis(P)`` (DataFrame ->
    columns); ``choice``: "auto" (the better held-out prediction), "gp" or "stepwise"."""
    if choice not in SURROGATES:
        raise ValueError(f"surrogate {choice!r}: expected one of {', '.join(SURROGATES)}")
    flat = [q for q in params if not float(ranges[q][1]) > float(ranges[q][0])]
    if flat:
        raise ValueError(f"the range of {flat} has no width: a surrogate's parameters are "
                         "the ones the design varies")
    data = response_data(runs, resp, params, ranges, basis)
    noise = data.pure_sd if data.pure_dof >= 2 and data.pure_sd > 0 else None
    fitted, scores = {}, {}
    rho = None
    for kind in ("gp", "stepwise"):
        if choice not in ("auto", kind):
            continue
        m = fit_basis_gp(data.X, data.H_raw, data.y, data.k, gp=kind == "gp", seed=seed,
                         noise=noise, C=data.C, rho=None if kind == "gp" else rho)
        rho = m.rho if kind == "gp" else rho
        nsd = _noise_sd(data, noise, m)
        fitted[kind] = m
        scores[kind] = held_out(m, data, kind, nsd, seed)
    kind = min(scores, key=lambda q: scores[q]["rmse"])
    s = scores[kind]
    c = inflation(s["_e"], s["_sig2"], s["_noise2"])
    m = fitted[kind]
    nsd = _noise_sd(data, noise, m)
    clean = {q: {k: v for k, v in d.items() if not k.startswith("_")} for q, d in scores.items()}
    return ResponseSurrogate(resp, kind, m, tuple(params), {p: tuple(ranges[p]) for p in params},
                             basis, float(nsd), c, clean, len(data.y), data.n_obs,
                             int(data.near.sum()))
