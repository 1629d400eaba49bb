"""Strength envelopes from triaxial points (sigma3, sigma1): Mohr-Coulomb and Hoek-Brown.

Pure functions on numbers (compression positive, any consistent stress unit; the study
uses MPa); no files.

**Mohr-Coulomb** (``fit_mohr_coulomb``): the linear envelope in principal stresses,

    sigma1 = sigma_c + q sigma3,   q = (1 + sin phi) / (1 - sin phi),

fitted by ordinary least squares; phi = asin((q - 1) / (q + 1)) and the cohesion
c = sigma_c (1 - sin phi) / (2 cos phi) = sigma_c / (2 sqrt(q)). Standard errors of
sigma_c and q come from the OLS covariance (n - 2 degrees of freedom, so they need at
least 3 points); those of phi and c follow by the delta method.

**Hoek-Brown, intact rock** (``fit_hoek_brown``, s = 1, a = 1/2):

    sigma1 = sigma3 + sigma_ci sqrt(m_i sigma3 / sigma_ci + 1),

i.e. (sigma1 - sigma3)^2 = sigma_ci^2 + m_i sigma_ci sigma3. With sigma_ci given (the
UCS), m_i follows from a one-parameter least-squares fit of that squared form through the
fixed intercept sigma_ci^2; without it, sigma_ci^2 and m_i sigma_ci are the intercept and
slope of a linear fit of y = (sigma1 - sigma3)^2 on sigma3 (Hoek & Brown 1980, 1997; the
standard procedure, e.g. RocLab). Standard errors from the same linear fits (delta method
for sigma_ci and m_i); ``r2`` is the coefficient of determination of the squared form.
Both fits also report the RMS residual in sigma1.

Errors (``EnvelopeError``, a ``ValueError``): fewer points than the fit needs, non-finite
values, all sigma3 equal (no slope), sigma1 <= sigma3, a negative sigma3, or a fit
outside the model's domain (q <= 1, i.e. phi <= 0; sigma_ci or m_i <= 0).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np


class EnvelopeError(ValueError):
    """The points cannot define the requested envelope."""


def _points(sigma3, sigma1, need: int) -> tuple[np.ndarray, np.ndarray]:
    s3 = np.asarray(sigma3, float).reshape(-1)
    s1 = np.asarray(sigma1, float).reshape(-1)
    if s3.shape != s1.shape:
        raise EnvelopeError(f"sigma3 and sigma1 differ in length ({s3.size} vs {s1.size})")
    if s3.size < need:
        raise EnvelopeError(f"{s3.size} point(s): the fit needs at least {need} "
                            "(sigma3, sigma1) points")
    if not (np.all(np.isfinite(s3)) and np.all(np.isfinite(s1))):
        raise EnvelopeError("sigma3/sigma1: expected finite numbers")
    if np.any(s3 < 0):
        raise EnvelopeError(f"sigma3 = {s3.min():g} < 0: expected confining stresses >= 0 "
                            "(compression positive)")
    if np.any(s1 <= s3):
        k = int(np.flatnonzero(s1 <= s3)[0])
        raise EnvelopeError(f"point {k}: sigma1 = {s1[k]:g} <= sigma3 = {s3[k]:g}; expected "
                            "sigma1 > sigma3 at failure")
    if np.ptp(s3) == 0:
        raise EnvelopeError(f"all sigma3 are equal ({s3[0]:g}): at least two confining "
                            "stresses are needed for an envelope")
    return s3, s1


def _ols(x, y):
    """Intercept, slope, their covariance matrix (n - 2 dof; NaN if n = 2), and R^2."""
    n = x.size
    X = np.column_stack([np.ones(n), x])
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - X @ beta
    ss = float(res @ res)
    dof = n - 2
    cov = np.linalg.inv(X.T @ X) * (ss / dof) if dof > 0 else np.full((2, 2), np.nan)
    tot = float(((y - y.mean()) ** 2).sum())
    r2 = 1.0 - ss / tot if tot > 0 else math.nan
    return float(beta[0]), float(beta[1]), cov, r2


@dataclass(frozen=True)
class MohrCoulomb:
    """Mohr-Coulomb envelope: cohesion c, friction angle phi [deg], and the principal-stress
    form sigma1 = sigma_c + q sigma3 (standard errors ``*_se``, NaN with 2 points)."""

    c: float
    phi_deg: float
    sigma_c: float
    q: float
    c_se: float
    phi_se_deg: float
    sigma_c_se: float
    q_se: float
    r2: float
    rms: float
    n: int

    def sigma1(self, sigma3):
        return self.sigma_c + self.q * np.asarray(sigma3, float)

    def to_dict(self) -> dict:
        return asdict(self)


def fit_mohr_coulomb(sigma3, sigma1) -> MohrCoulomb:
    """Least-squares Mohr-Coulomb envelope through (sigma3, sigma1) points (>= 2 distinct
    sigma3; standard errors need >= 3 points)."""
    s3, s1 = _points(sigma3, sigma1, 2)
    a, q, cov, r2 = _ols(s3, s1)
    if not q > 1.0:
        raise EnvelopeError(f"fitted slope q = {q:.4g} <= 1: sigma1 does not rise faster than "
                            "sigma3, so the friction angle would be <= 0")
    if not a > 0:
        raise EnvelopeError(f"fitted sigma_c = {a:.4g} <= 0: no positive cohesion")
    sin_phi = (q - 1.0) / (q + 1.0)
    phi = math.asin(sin_phi)
    c = a / (2.0 * math.sqrt(q))
    # delta method: dphi/dq = 1 / ((q + 1) sqrt(q)); dc/da = 1 / (2 sqrt q),
    # dc/dq = -a / (4 q^1.5)
    g_phi = np.array([0.0, 1.0 / ((q + 1.0) * math.sqrt(q))])
    g_c = np.array([1.0 / (2.0 * math.sqrt(q)), -a / (4.0 * q ** 1.5)])
    res = s1 - (a + q * s3)
    return MohrCoulomb(c=c, phi_deg=math.degrees(phi), sigma_c=a, q=q,
                       c_se=float(math.sqrt(g_c @ cov @ g_c)),
                       phi_se_deg=float(math.degrees(math.sqrt(g_phi @ cov @ g_phi))),
                       sigma_c_se=float(math.sqrt(cov[0, 0])),
                       q_se=float(math.sqrt(cov[1, 1])), r2=r2,
                       rms=float(math.sqrt((res ** 2).mean())), n=int(s3.size))


def mohr_coulomb_q(phi_deg: float) -> float:
    """q = (1 + sin phi) / (1 - sin phi)."""
    s = math.sin(math.radians(phi_deg))
    return (1.0 + s) / (1.0 - s)


def mohr_coulomb_sigma_c(c: float, phi_deg: float) -> float:
    """Uniaxial strength of the envelope, 2 c cos phi / (1 - sin phi)."""
    p = math.radians(phi_deg)
    return 2.0 * c * math.cos(p) / (1.0 - math.sin(p))


@dataclass(frozen=True)
class HoekBrown:
    """Intact-rock Hoek-Brown envelope (s = 1, a = 0.5): sigma_ci, m_i and their standard
    errors (``sigma_ci_se`` is 0 when sigma_ci was given)."""

    mi: float
    sigma_ci: float
    mi_se: float
    sigma_ci_se: float
    sigma_ci_fixed: bool
    r2: float
    rms: float
    n: int

    def sigma1(self, sigma3):
        s3 = np.asarray(sigma3, float)
        return s3 + self.sigma_ci * np.sqrt(self.mi * s3 / self.sigma_ci + 1.0)

    def to_dict(self) -> dict:
        return asdict(self)


def hoek_brown_sigma1(sigma3, sigma_ci: float, mi: float):
    """sigma1 = sigma3 + sigma_ci sqrt(mi sigma3 / sigma_ci + 1)."""
    s3 = np.asarray(sigma3, float)
    return s3 + sigma_ci * np.sqrt(mi * s3 / sigma_ci + 1.0)


def fit_hoek_brown(sigma3, sigma1, sigma_ci: float | None = None) -> HoekBrown:
    """Intact-rock Hoek-Brown m_i (and sigma_ci unless given) from (sigma3, sigma1) points.

    With ``sigma_ci`` given (e.g. the UCS), one parameter is fitted: at least one point with
    sigma3 > 0 is needed (a standard error needs two). Without it, two: at least two
    distinct sigma3 (a standard error needs three points)."""
    s3 = np.asarray(sigma3, float).reshape(-1)
    s1 = np.asarray(sigma1, float).reshape(-1)
    if sigma_ci is not None:
        sci = float(sigma_ci)
        if not (sci > 0 and math.isfinite(sci)):
            raise EnvelopeError(f"sigma_ci={sigma_ci!r}: expected a positive uniaxial "
                                "strength")
        if s3.size < 1:
            raise EnvelopeError("0 points: the fit needs at least 1 (sigma3, sigma1) point "
                                "with sigma3 > 0")
        if s3.shape != s1.shape or not (np.all(np.isfinite(s3)) and np.all(np.isfinite(s1))):
            raise EnvelopeError("sigma3/sigma1: expected finite numbers of equal length")
        if np.any(s3 < 0) or np.any(s1 <= s3):
            raise EnvelopeError("expected sigma3 >= 0 and sigma1 > sigma3 at every point")
        x = s3
        if not np.any(x > 0):
            raise EnvelopeError("all sigma3 are 0: m_i needs at least one confined point "
                                "(sigma3 > 0)")
        y = (s1 - s3) ** 2 - sci ** 2
        # y = b x through the origin, b = m_i sigma_ci
        sxx = float(x @ x)
        b = float(x @ y) / sxx
        res = y - b * x
        dof = x.size - 1
        b_se = math.sqrt(float(res @ res) / dof / sxx) if dof > 0 else math.nan
        mi = b / sci
        mi_se = b_se / sci
        sci_se = 0.0
        yy = (s1 - s3) ** 2
        fit = sci ** 2 + b * x
        fixed = True
    else:
        s3, s1 = _points(s3, s1, 2)
        yy = (s1 - s3) ** 2
        a, b, cov, _ = _ols(s3, yy)
        if not a > 0:
            raise EnvelopeError(f"fitted sigma_ci^2 = {a:.4g} <= 0: the points do not define "
                                "a Hoek-Brown envelope")
        sci = math.sqrt(a)
        mi = b / sci
        # delta method: sigma_ci = sqrt(a), m_i = b / sqrt(a)
        g_s = np.array([0.5 / sci, 0.0])
        g_m = np.array([-0.5 * b / a ** 1.5, 1.0 / sci])
        sci_se = float(math.sqrt(g_s @ cov @ g_s))
        mi_se = float(math.sqrt(g_m @ cov @ g_m))
        fit = a + b * s3
        fixed = False
    if not mi > 0:
        raise EnvelopeError(f"fitted m_i = {mi:.4g} <= 0: sigma1 - sigma3 does not grow with "
                            "sigma3")
    tot = float(((yy - yy.mean()) ** 2).sum())
    r2 = 1.0 - float(((yy - fit) ** 2).sum()) / tot if tot > 0 else math.nan
    res1 = s1 - hoek_brown_sigma1(s3, sci, mi)
    return HoekBrown(mi=float(mi), sigma_ci=float(sci), mi_se=float(mi_se),
                     sigma_ci_se=float(sci_se), sigma_ci_fixed=fixed, r2=float(r2),
                     rms=float(math.sqrt((res1 ** 2).mean())), n=int(s3.size))
