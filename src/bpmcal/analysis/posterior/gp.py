"""A Gaussian process with an explicit basis for one DEM response (:class:`BasisGP`).

The model (Rasmussen & Williams 2006, section 2.7, "explicit basis functions")::

    y_i = h(x_i)' b + f(x_i) + e_i,   f ~ GP(0, a² exp(-½ Σ_j (Δx_j / l_j)²)),
    cov(e_i, e_j) = s² (ρ C_ij + (1 - ρ) δ_ij / k_i)

``x`` are the parameters in unit coordinates (the design ranges mapped to [0, 1]), ``h``
the basis (the intercept and the stepwise regression's terms of that response, columns
standardised), ``y_i`` the mean of ``k_i`` observations at one parameter point (a design
sample: one DEM run; a closed-loop round: its seeds; a tensile seed: its discs), so one
noise variance ``s²`` (the packing scatter of one specimen) serves every point. A share ρ
of that scatter is the packing's own offset, which every run on the same packing seed
shares (the closed loop runs its seeds in every round): ``C_ij`` = Σ_s c_is c_js / (k_i
k_j), with c_is the runs of point i on packing s, so two points on the same packings are
correlated by their common offsets and their means do not average them away. ρ is
fitted where points share packings (else it does not matter and is 0). ``b`` is
estimated by generalised least squares with a vague prior, and the prediction's
variance carries its uncertainty, so the model's error grows where the data thin out
(far from every run it is the basis's extrapolation error, not a constant).

The hyperparameters (``a``, the length scales ``l``, ``s``, ρ) maximise the marginal
likelihood of the ordinary-least-squares residuals (type-II maximum likelihood, analytic
gradients, L-BFGS-B from fixed and seeded starts: deterministic). With ``gp=False`` the
process is off (``a`` = 0) and the model is the weighted least-squares regression on the
same basis: the stepwise surrogate, whose prediction error adds the lack of fit.

Every array is float64; ``fit`` and ``predict`` are pure functions of their inputs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize

#: bounds of the hyperparameters, on the log scale: length scales in unit coordinates,
#: amplitude and noise in standard deviations of the residuals
LOG_LENGTH = (np.log(0.02), np.log(50.0))
LOG_AMP = (np.log(1e-3), np.log(1e2))
LOG_NOISE = (np.log(1e-4), np.log(10.0))
JITTER = 1e-10


def sq_dist_scaled(A: np.ndarray, B: np.ndarray, ls: np.ndarray) -> np.ndarray:
    """Σ_j ((A_ij - B_kj) / ls_j)², the (len(A), len(B)) matrix."""
    a, b = A / ls, B / ls
    d = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(d, 0.0)


@dataclass
class BasisGP:
    """A fitted :class:`BasisGP` (build it with :func:`fit_basis_gp`).

    ``X`` (n, d) the points (unit coordinates), ``H`` (n, p) their standardised basis,
    ``y`` (n,) the responses, ``k`` (n,) their observation counts; ``amp``, ``ls`` (d,),
    ``noise`` the hyperparameters (``amp`` = 0: no process); ``lack_of_fit`` a variance
    added to every prediction (the regression's model error, 0 for the process);
    ``h_mean``, ``h_sd`` the basis standardisation."""

    X: np.ndarray
    H: np.ndarray
    y: np.ndarray
    k: np.ndarray
    amp: float
    ls: np.ndarray
    noise: float
    h_mean: np.ndarray
    h_sd: np.ndarray
    lack_of_fit: float = 0.0
    nll: float = float("nan")
    C: np.ndarray | None = None  # shared-packing matrix (None: no shared packings)
    rho: float = 0.0  # the packing offset's share of a specimen's scatter

    def __post_init__(self):
        self._prepare()

    def noise_matrix(self) -> np.ndarray:
        """The points' noise covariance s² (ρ C + (1 - ρ) diag(1/k))."""
        D = np.diag(1.0 / self.k)
        if self.C is None or self.rho == 0.0:
            return self.noise ** 2 * D
        return self.noise ** 2 * (self.rho * self.C + (1.0 - self.rho) * D)

    def _kernel(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        if self.amp == 0.0:
            return np.zeros((len(A), len(B)))
        return self.amp ** 2 * np.exp(-0.5 * sq_dist_scaled(A, B, self.ls))

    def _prepare(self) -> None:
        K = self._kernel(self.X, self.X) + self.noise_matrix()
        K[np.diag_indices_from(K)] += JITTER
        cf = cho_factor(K, lower=True)
        self._Ki_H = cho_solve(cf, self.H)
        A = self.H.T @ self._Ki_H
        A = A + 1e-12 * np.trace(A) / len(A) * np.eye(len(A))
        self._A_inv = np.linalg.inv(A)
        self._A_inv = 0.5 * (self._A_inv + self._A_inv.T)
        self.beta = self._A_inv @ (self._Ki_H.T @ self.y)
        self._alpha = cho_solve(cf, self.y - self.H @ self.beta)
        self._K_inv = cho_solve(cf, np.eye(len(self.y))) if self.amp else None

    def basis(self, H_raw: np.ndarray) -> np.ndarray:
        return np.column_stack([np.ones(len(H_raw)), (H_raw - self.h_mean) / self.h_sd])

    def predict(self, X: np.ndarray, H_raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The mean and the standard deviation of the latent response (the mean over
        packings, without one specimen's noise) at the points ``X`` (m, d) with raw basis
        columns ``H_raw`` (m, p - 1). Plain matrix products on precomputed inverses (a
        call per sampler step: no factorisation here)."""
        Hs = self.basis(np.asarray(H_raw, float).reshape(len(X), -1))
        if self.amp:
            Ks = self._kernel(np.asarray(X, float), self.X)
            mean = Hs @ self.beta + Ks @ self._alpha
            var = self.amp ** 2 - np.einsum("ij,ij->i", Ks @ self._K_inv, Ks)
            R = Hs - Ks @ self._Ki_H
        else:
            mean = Hs @ self.beta
            var = np.zeros(len(Hs))
            R = Hs
        var = var + np.einsum("ij,ij->i", R @ self._A_inv, R) + self.lack_of_fit
        return mean, np.sqrt(np.maximum(var, 0.0))

    def without(self, drop: np.ndarray) -> BasisGP:
        """The same hyperparameters on the points not in the boolean mask ``drop`` (a
        held-out prediction: :func:`bpmcal.analysis.posterior.surrogate.held_out`)."""
        keep = ~np.asarray(drop, bool)
        C = None if self.C is None else self.C[np.ix_(keep, keep)]
        return BasisGP(self.X[keep], self.H[keep], self.y[keep], self.k[keep], self.amp,
                       self.ls, self.noise, self.h_mean, self.h_sd, self.lack_of_fit,
                       C=C, rho=self.rho)


def standardise(H_raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The basis with an intercept column and the raw columns standardised (constant
    columns dropped to the intercept's care: their sd is set to 1 and they are zeroed)."""
    H_raw = np.asarray(H_raw, float).reshape(len(H_raw), -1)
    mean = H_raw.mean(0) if len(H_raw) else np.zeros(H_raw.shape[1])
    sd = H_raw.std(0) if len(H_raw) else np.ones(H_raw.shape[1])
    const = ~(sd > 1e-12 * np.maximum(1.0, np.abs(mean)))
    sd = np.where(const, np.inf, sd)  # a constant column contributes 0
    H = np.column_stack([np.ones(len(H_raw)), (H_raw - mean) / sd])
    keep = np.concatenate([[True], ~const])
    return H[:, keep], mean[~const], sd[~const]


def shared_packings(seeds: list[list[str]]) -> np.ndarray | None:
    """The shared-packing matrix C of points whose runs ran on the packing ``seeds`` (a
    list of labels per point): C_ij = Σ_s c_is c_js / (k_i k_j); None when no two points
    share a packing (C is then diag(1/k) and ρ does not matter)."""
    index: dict[str, dict[int, int]] = {}
    for i, labels in enumerate(seeds):
        for s in labels:
            index.setdefault(s, {})
            index[s][i] = index[s].get(i, 0) + 1
    k = np.array([len(x) for x in seeds], float)
    n = len(seeds)
    C = np.zeros((n, n))
    cross = False
    for rows in index.values():
        items = list(rows.items())
        for i, ci in items:
            for j, cj in items:
                C[i, j] += ci * cj
        cross = cross or len(items) > 1
    if not cross:
        return None
    return C / np.outer(k, k)


def _nll_and_grad(theta: np.ndarray, X: np.ndarray, r: np.ndarray, inv_k: np.ndarray,
                  C: np.ndarray | None) -> tuple[float, np.ndarray]:
    """Negative log marginal likelihood of residuals ``r`` and its gradient in
    ``theta`` = (log amp, log ls_1..d, log noise, logit rho)."""
    d = X.shape[1]
    amp, ls, noise = np.exp(theta[0]), np.exp(theta[1:1 + d]), np.exp(theta[1 + d])
    rho = 1.0 / (1.0 + np.exp(-theta[2 + d]))
    D = [((X[:, j:j + 1] - X[:, j:j + 1].T) / ls[j]) ** 2 for j in range(d)]
    Kf = amp ** 2 * np.exp(-0.5 * sum(D))
    Dk = np.diag(inv_k)
    shape = Dk if C is None else rho * C + (1.0 - rho) * Dk
    K = Kf + noise ** 2 * shape
    K[np.diag_indices_from(K)] += JITTER
    try:
        cf = cho_factor(K, lower=True)
    except np.linalg.LinAlgError:
        return 1e25, np.zeros_like(theta)
    alpha = cho_solve(cf, r)
    nll = 0.5 * r @ alpha + np.log(np.diag(cf[0])).sum() + 0.5 * len(r) * np.log(2 * np.pi)
    M = np.outer(alpha, alpha) - cho_solve(cf, np.eye(len(r)))
    grad = np.zeros_like(theta)
    grad[0] = -0.5 * np.sum(M * (2.0 * Kf))
    for j in range(d):
        grad[1 + j] = -0.5 * np.sum(M * (Kf * D[j]))
    grad[1 + d] = -0.5 * np.sum(M * (2.0 * noise ** 2 * shape))
    if C is not None:
        grad[2 + d] = -0.5 * np.sum(M * (noise ** 2 * (C - Dk))) * rho * (1.0 - rho)
    return float(nll), grad


#: bounds of the packing offset's share ρ, on the logit scale
LOGIT_RHO = (-7.0, 3.0)


def fit_basis_gp(X, H_raw, y, k=None, *, gp: bool = True, seed: int = 0, restarts: int = 3,
                 noise: float | None = None, C: np.ndarray | None = None,
                 rho: float | None = None) -> BasisGP:
    """Fit :class:`BasisGP` to points ``X`` (n, d; unit coordinates), raw basis columns
    ``H_raw`` (n, p), means ``y`` of ``k`` observations each (default 1).

    ``gp=True``: the hyperparameters by type-II maximum likelihood on the weighted
    least-squares residuals, from the start (amp = residual sd, l = 0.5, noise = half the
    residual sd) and ``restarts`` seeded random starts; the best is kept. A ``noise``
    given (measured on replicated runs) is held at that value: with few points the
    likelihood alone can explain everything by the process and let the noise go to zero.
    ``gp=False``: the
    regression alone, with noise ``noise`` (the packing scatter of one specimen, from
    replicates) if given, its lack of fit the residual variance beyond that noise (all of
    it without ``noise``). ``C``: the shared-packing matrix (:func:`shared_packings`);
    ``rho`` holds the packing offset's share (the regression's: the process's fitted ρ),
    else it is fitted."""
    X = np.asarray(X, float)
    y = np.asarray(y, float)
    k = np.ones(len(y)) if k is None else np.asarray(k, float)
    H, h_mean, h_sd = standardise(H_raw)
    if len(y) <= H.shape[1]:
        raise ValueError(f"{len(y)} points are too few for a basis of {H.shape[1]} columns")
    w = np.sqrt(k)
    beta = np.linalg.lstsq(H * w[:, None], y * w, rcond=None)[0]
    r = y - H @ beta
    dof = max(1, len(y) - H.shape[1])
    s2 = float((k * r * r).sum() / dof)  # residual variance of one observation
    d = X.shape[1]
    if not gp:
        s2_noise = s2 if noise is None else min(float(noise) ** 2, s2)
        lof = max(0.0, s2 - s2_noise) if noise is not None else s2
        return BasisGP(X, H, y, k, 0.0, np.ones(d), float(np.sqrt(max(s2_noise, 1e-300))),
                       h_mean, h_sd, lack_of_fit=lof, C=C, rho=float(rho or 0.0))
    scale = float(np.sqrt(max(s2, 1e-300)))
    rs = r / scale
    rng = np.random.default_rng(seed)
    starts = [np.concatenate([[0.0], np.full(d, np.log(0.5)), [np.log(0.5), 0.0]])]
    for _ in range(restarts):
        starts.append(np.concatenate([[rng.uniform(np.log(0.1), np.log(3.0))],
                                      rng.uniform(np.log(0.1), np.log(3.0), d),
                                      [rng.uniform(np.log(0.05), np.log(1.0))],
                                      [rng.uniform(-2.0, 2.0)]]))
    bounds = [LOG_AMP] + [LOG_LENGTH] * d + [LOG_NOISE, LOGIT_RHO]
    fixed = {}
    if noise is not None and noise > 0:
        fixed[1 + d] = float(np.clip(np.log(float(noise) / scale), *LOG_NOISE))
    if C is None or rho is not None:  # no shared packing: ρ does not matter
        r0 = 0.0 if rho is None else float(rho)
        fixed[2 + d] = float(np.clip(np.log(max(r0, 1e-9) / max(1 - r0, 1e-9)), *LOGIT_RHO))
    for i, v in fixed.items():
        bounds[i] = (v, v)
        for t0 in starts:
            t0[i] = v
    best = None
    for t0 in starts:
        res = minimize(_nll_and_grad, t0, args=(X, rs, 1.0 / k, C), jac=True,
                       method="L-BFGS-B", bounds=bounds, options={"maxiter": 300})
        if best is None or res.fun < best.fun:
            best = res
    t = best.x
    rho_fit = 0.0 if C is None else float(1.0 / (1.0 + np.exp(-t[2 + d])))
    return BasisGP(X, H, y, k, float(np.exp(t[0]) * scale), np.exp(t[1:1 + d]),
                   float(np.exp(t[1 + d]) * scale), h_mean, h_sd, nll=float(best.fun), C=C,
                   rho=rho_fit)
