"""Contact laws for ONE contact, as small inlined numba functions (PFC3D semantics).

These functions are the physics; ``kernels.py`` maps them over pairs and wall slots.
Conventions (see ../shared/PBM.md and the Itasca linearpbond documentation):

- unit normal ``n`` points from piece 1 to piece 2 (ball i to ball j; wall to ball);
  relative displacement increments are those of piece 2 with respect to piece 1 at
  the contact point: ``dun`` (positive = opening) and ``dus`` (tangential vector);
- the *linear* component: ``Fn = kn * (g_r - g)`` while the surface gap ``g - g_r`` is
  negative (no tension; absolute normal-force update, PFC ``lin_mode = 0``), shear force
  incremental ``Fs <- Fs - ks dus`` with Coulomb slip at ``mu Fn``; the stored shear force
  is rotated into the current contact plane (normal change + mean spin about the normal);
- the *parallel bond*: ``Fn_bar`` tension-positive, ``Fn_bar += kn_bar A dun``,
  ``Fs_bar -= ks_bar A dus``, ``Mt -= ks_bar J dtheta_t``, ``Mb -= kn_bar I dtheta_b``;
  peak stresses ``sigma = Fn_bar/A + beta |Mb| R/I`` and ``tau = |Fs_bar|/A + beta |Mt| R/J``;
  tensile failure if ``sigma >= sigma_c``, else shear failure if ``tau >= c - (Fn_bar/A) tan phi``
  (tension lowers, compression raises the shear strength; no cap, as in PFC 5-9);
- forces returned are those acting on piece 2; piece 1 gets the opposite force.

Energy is kept in a form consistent with the leapfrog integrator: the energy a breaking
bond releases is ``1/2 F_old . F_trial / k`` per component (the strain energy evaluated
half-way through the step), so that the energy balance closes to round-off for linear
springs (see ``kernels.py``).
"""
from __future__ import annotations

import math

from ._jit import numba

_inl = numba.njit(cache=True, inline="always")


@_inl
def rotate_shear(sx, sy, sz, nx, ny, nz, dphi):
    """Carry a stored tangential vector into the current contact plane.

    Removes the component along the new normal (first-order rotation for the change of
    the normal) and turns it by the mean spin ``dphi`` about the normal.
    """
    d = sx * nx + sy * ny + sz * nz
    sx -= d * nx
    sy -= d * ny
    sz -= d * nz
    # s + dphi * (n x s)
    cx = ny * sz - nz * sy
    cy = nz * sx - nx * sz
    cz = nx * sy - ny * sx
    return sx + dphi * cx, sy + dphi * cy, sz + dphi * cz


@_inl
def linear_stiffness(r1, r2, inv_l, emod, inv_kratio):
    """PFC deformability method: kn = pi r^2 E*/L, r = min(R1,R2), L = R1+R2; ks = kn/kappa*.

    ``inv_l`` = 1/L and ``inv_kratio`` = 1/kappa* are passed in (no divisions here)."""
    r = min(r1, r2)
    kn = math.pi * r * r * emod * inv_l
    return kn, kn * inv_kratio


@_inl
def linear_shear(sx, sy, sz, dusx, dusy, dusz, ks, fslip):
    """Incremental shear force with Coulomb slip.

    ``s`` is the stored (already rotated) shear force, ``dus`` the shear displacement
    increment, ``fslip = mu Fn`` the slip limit. Returns the new shear force and the
    energy dissipated by slip in this increment (>= 0).
    """
    tx = sx - ks * dusx
    ty = sy - ks * dusy
    tz = sz - ks * dusz
    tt = tx * tx + ty * ty + tz * tz
    e = 0.0
    if tt > fslip * fslip:
        if tt > 0.0:
            sc = fslip / math.sqrt(tt)
        else:
            sc = 0.0
        tx *= sc
        ty *= sc
        tz *= sc
        # elastic part of the increment: (s - t)/ks; slip part: dus - elastic part
        ex = dusx - (sx - tx) / ks
        ey = dusy - (sy - ty) / ks
        ez = dusz - (sz - tz) / ks
        e = -0.5 * ((sx + tx) * ex + (sy + ty) * ey + (sz + tz) * ez)
    return tx, ty, tz, e


@_inl
def bond_geometry(r1, r2, inv_l, pb_emod, pb_inv_kratio, rmul):
    """Parallel-bond radius R = lambda min(R1,R2), area A = pi R^2 and the four stiffnesses
    kn_bar A, ks_bar A, ks_bar J, kn_bar I with kn_bar = E_bar/L, ks_bar = kn_bar/kappa_bar,
    I = pi R^4/4, J = 2 I. ``inv_l`` = 1/L, ``pb_inv_kratio`` = 1/kappa_bar."""
    rb = rmul * min(r1, r2)
    area = math.pi * rb * rb
    inertia = 0.25 * area * rb * rb
    knb = pb_emod * inv_l
    ksb = knb * pb_inv_kratio
    return rb, area, knb * area, ksb * area, ksb * 2.0 * inertia, knb * inertia


@_inl
def bond_failure(fn, smag, mt, mbmag, rb, area, ten, coh, tanfa, mcf):
    """Failure mode of a parallel bond: 0 intact, 1 tension, 2 shear.

    sigma = Fn/A + beta |Mb| R/I >= sigma_c  -> tension (checked first);
    tau = |Fs|/A + beta |Mt| R/J >= c - (Fn/A) tan(phi)  -> shear.
    Evaluated multiplied through by A R (A R/I = 4/R, A R/J = 2/R): no divisions.
    """
    if fn * rb + 4.0 * mcf * mbmag >= ten * area * rb:
        return 1
    if smag * rb + 2.0 * mcf * abs(mt) >= (coh * area - fn * tanfa) * rb:
        return 2
    return 0


@_inl
def bond_strength_stresses(fn, smag, mt, mbmag, rb, mcf):
    """(sigma, tau, sigma_n) peak bond stresses [Pa], tension positive (for reporting)."""
    area = math.pi * rb * rb
    inertia = 0.25 * math.pi * rb ** 4
    sig = fn / area + mcf * mbmag * rb / inertia
    tau = smag / area + mcf * abs(mt) * rb / (2.0 * inertia)
    return sig, tau, fn / area
