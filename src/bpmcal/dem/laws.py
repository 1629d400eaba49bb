"""Contact laws for ONE contact, as small inlined numba functions (PFC3D semantics).

These functions are the physics; ``kernels.py`` maps them over pairs and wall slots
(``wall_contact_geometry``, at the end, is the geometry of one ball-wall contact).
Conventions (see docs/contact_laws.md and Itasca's linearpbond documentation):

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
from .slots import WALL_CYLINDER

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
def kinematics(dx, dy, dz, dvx, dvy, dvz, wix, wiy, wiz, wjx, wjy, wjz, ri, rj, dt):
    """Geometry and relative motion of a ball-ball contact.

    ``d`` = x_j - x_i, ``dv`` = v_j - v_i, spins w_i, w_j. Returns the unit normal n, the
    surface gap, 1/L (L = R_i + R_j), the lever arms ai, aj (contact point = x_i + ai n =
    x_j + aj n, the middle of the overlap), the relative velocity of j w.r.t. i at the
    contact point, its normal component, the displacement increments dun, dus (x dt) and
    the mean spin about the normal times dt (for rotating stored shear quantities).
    Coincident centres give n = 0 (no normal force; only in artificial set-ups).
    """
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    inv = 1.0 / max(dist, 1e-300)
    nx = dx * inv
    ny = dy * inv
    nz = dz * inv
    sr = ri + rj
    inv_l = 1.0 / sr
    gap = dist - sr
    ai = ri + 0.5 * gap
    aj = -(rj + 0.5 * gap)
    vrx = dvx + aj * (wjy * nz - wjz * ny) - ai * (wiy * nz - wiz * ny)
    vry = dvy + aj * (wjz * nx - wjx * nz) - ai * (wiz * nx - wix * nz)
    vrz = dvz + aj * (wjx * ny - wjy * nx) - ai * (wix * ny - wiy * nx)
    vn = vrx * nx + vry * ny + vrz * nz
    dusx = (vrx - vn * nx) * dt
    dusy = (vry - vn * ny) * dt
    dusz = (vrz - vn * nz) * dt
    dphi = 0.5 * ((wix + wjx) * nx + (wiy + wjy) * ny + (wiz + wjz) * nz) * dt
    return (nx, ny, nz, gap, inv_l, ai, aj, vrx, vry, vrz, vn, vn * dt, dusx, dusy, dusz,
            dphi)


@_inl
def dashpot(vrx, vry, vrz, vn, nx, ny, nz, mc, kn, ks, betan, betas):
    """Dashpot force on piece 2: -(2 beta_n sqrt(m kn) vn n + 2 beta_s sqrt(m ks) vs)."""
    cn = 2.0 * betan * math.sqrt(mc * kn)
    cs = 2.0 * betas * math.sqrt(mc * ks)
    return (-(cn * vn * nx + cs * (vrx - vn * nx)), -(cn * vn * ny + cs * (vry - vn * ny)),
            -(cn * vn * nz + cs * (vrz - vn * nz)))


@_inl
def linear_stiffness(r1, r2, inv_l, emod, inv_kratio):
    """PFC deformability method: kn = pi r^2 E*/L, r = min(R1,R2), L = R1+R2; ks = kn/kappa*.

    ``inv_l`` = 1/L and ``inv_kratio`` = 1/kappa* are passed in (no divisions here)."""
    r = min(r1, r2)
    kn = math.pi * r * r * emod * inv_l
    return kn, kn * inv_kratio


@_inl
def linear_shear(sx, sy, sz, dusx, dusy, dusz, ks, iks, fslip):
    """Incremental shear force with Coulomb slip, written without branches (selects) so
    that it vectorises.

    ``s`` is the stored (already rotated) shear force, ``dus`` the shear displacement
    increment, ``ks``/``iks`` the shear stiffness and its inverse, ``fslip = mu Fn`` the
    slip limit. Returns the new shear force, the trial force ``t = s - ks dus`` and the
    energy dissipated by slip in this increment, -1/2 (s + u).(dus - (s - u)/ks) >= 0
    (zero when the contact sticks).
    """
    tx = sx - ks * dusx
    ty = sy - ks * dusy
    tz = sz - ks * dusz
    tt = tx * tx + ty * ty + tz * tz
    slip = tt > fslip * fslip
    sc = fslip / math.sqrt(max(tt, 1e-300)) if slip else 1.0
    ux = tx * sc
    uy = ty * sc
    uz = tz * sc
    e = -0.5 * ((sx + ux) * (dusx - (sx - ux) * iks) + (sy + uy) * (dusy - (sy - uy) * iks)
                + (sz + uz) * (dusz - (sz - uz) * iks))
    return ux, uy, uz, tx, ty, tz, (e if slip else 0.0)


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
def bond_failure(fn, sb2, mt, mb2, rb, area, ten, coh, tanfa, mcf):
    """Failure mode of a parallel bond: 0 intact, 1 tension, 2 shear.

    sigma = Fn/A + beta |Mb| R/I >= sigma_c  -> tension (checked first);
    tau = |Fs|/A + beta |Mt| R/J >= c - (Fn/A) tan(phi)  -> shear.
    Multiplied through by A R (A R/I = 4/R, A R/J = 2/R) and compared on squared
    magnitudes ``sb2`` = |Fs|^2, ``mb2`` = |Mb|^2: no division, no square root.
    """
    rt = (ten * area - fn) * rb  # 4 beta |Mb| must reach this
    tens = rt <= 0.0 or 16.0 * mcf * mcf * mb2 >= rt * rt
    rs = (coh * area - fn * tanfa) * rb - 2.0 * mcf * abs(mt)  # |Fs| rb must reach this
    shear = rs <= 0.0 or sb2 * rb * rb >= rs * rs
    return 1 if tens else (2 if shear else 0)


@_inl
def bond_energy(fn, sb2, mt, mb2, kna, ksa, ksj, kni):
    """Strain energy of a parallel bond: 1/2 [Fn^2/(kn A) + |Fs|^2/(ks A) + Mt^2/(ks J)
    + |Mb|^2/(kn I)]."""
    return 0.5 * (fn * fn / kna + sb2 / ksa + mt * mt / ksj + mb2 / kni)


@_inl
def bond_strength_stresses(fn, smag, mt, mbmag, rb, mcf):
    """(sigma, tau, sigma_n) peak bond stresses [Pa], tension positive (for reporting)."""
    area = math.pi * rb * rb
    inertia = 0.25 * math.pi * rb ** 4
    sig = fn / area + mcf * mbmag * rb / inertia
    tau = smag / area + mcf * abs(mt) * rb / (2.0 * inertia)
    return sig, tau, fn / area


@_inl
def wall_contact_geometry(px, py, pz, r, w, wtype, wpos, wnrm, wrad, wdisk):
    """Gap and unit normal (from wall to ball) of ball (p, r) with wall w.

    Returns (gap, nx, ny, nz, ex, ey, ez, inside): e is the outward radial unit vector for
    a cylinder (zero for planes); ``inside`` is False when the ball is off a finite disk.
    """
    rx = px - wpos[w, 0]
    ry = py - wpos[w, 1]
    rz = pz - wpos[w, 2]
    ax = wnrm[w, 0]
    ay = wnrm[w, 1]
    az = wnrm[w, 2]
    h = rx * ax + ry * ay + rz * az
    qx = rx - h * ax
    qy = ry - h * ay
    qz = rz - h * az
    if wtype[w] == WALL_CYLINDER:
        rho = math.sqrt(qx * qx + qy * qy + qz * qz)
        if rho > 0.0:
            ex = qx / rho
            ey = qy / rho
            ez = qz / rho
        else:
            ex = 1.0
            ey = 0.0
            ez = 0.0
        return wrad[w] - rho - r, -ex, -ey, -ez, ex, ey, ez, True
    inside = True
    if wdisk[w] > 0.0:
        inside = qx * qx + qy * qy + qz * qz <= wdisk[w] * wdisk[w]
    return h - r, ax, ay, az, 0.0, 0.0, 0.0, inside
