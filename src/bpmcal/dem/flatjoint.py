"""The flat-joint contact model (PFC ``flatjoint``) for ONE contact and over the
flat-jointed pairs, as numba kernels. Specification: ``docs/flatjoint-spec.md``; the choices made
where PFC's documentation is silent are listed in ``docs/contact_laws.md``.

A flat joint replaces the point contact of two balls by a disk interface of radius
``R = fj_rmul * min(R1, R2)`` centred on the contact point and normal to the line of
centres, cut into ``fj_nr`` rings x ``fj_nal`` sectors (elements). Each element is bonded
(elastic in tension and compression; breaks in tension or Mohr-Coulomb shear at its
centroid stresses) or unbonded (compression only, Coulomb friction). Conventions as in
``laws.py``: the normal ``n`` points from ball i (piece 1) to ball j (piece 2); forces
and moments are those acting on piece 2; the element normal force ``fn`` is tension
positive.

Kinematic state of a contact, in its local frame (s, t, n) carried with the pair:
the surface gap ``g_s = gap - g_ref`` (absolute, so it cannot drift), the relative bend
rotation ``theta_b`` (2 components in (s, t)), and per element the shear force (2
components). The gap field over the interface is ``g(p) = g_s + w . p`` with
``w = n x theta_b = (-theta_bt, theta_bs)``.

Element normal force and first moment (``Q = integral sigma p dA`` about the interface
centre): closed forms for a bonded element or an unbonded one closed everywhere; for an
unbonded element cut by the neutral line, the compressed part is integrated in closed
form over pieces of the angle range on which the integrand's form does not change
(``partial_element``).

Element table (``element_table``): per element, normalised by the interface radius R:
area A/R^2, centroid x/R (2), second moments of area about the interface centre
I/R^4 (ss, tt, st), inner and outer radius a/R, b/R and the sector's angles.
"""
from __future__ import annotations

import math

import numpy as np

from ._jit import jit, numba
from .laws import kinematics, linear_shear, linear_stiffness, rotate_shear

_inl = numba.njit(cache=True, inline="always")

# ---- element table columns ------------------------------------------------------------
G_A, G_XS, G_XT, G_ISS, G_ITT, G_IST, G_RA, G_RB, G_P0, G_P1 = range(10)
G_C0, G_S0, G_C1, G_S1 = range(10, 14)  # cos, sin of the sector's bounding angles
NG = 14

# ---- per-contact float fields: Fj.c[k, ...] -------------------------------------------
C_SX, C_SY, C_SZ = 0, 1, 2  # unit vector s of the local frame (t = n x s)
C_TBS, C_TBT = 3, 4  # relative bend rotation theta_b in (s, t) [rad]
C_GREF = 5  # reference gap: g_s = gap - g_ref [m]
C_G0 = 6  # initial surface gap g_0 (gapped contacts) [m]
C_SF = 7  # strength factor (x fj_ten, fj_coh) [-]
C_LX, C_LY, C_LZ = 8, 9, 10  # linear shear force once the flat joint is deleted [N]
C_FX, C_FY, C_FZ = 11, 12, 13  # force on j of the last recording step (diagnostics) [N]
C_TEN, C_COH = 14, 15  # the joint's own fj_ten, fj_coh [Pa] (PFC: contact properties, shared
#                        by its elements): the material's at installation, or drawn per
#                        joint (Model.set_bond_strengths); x C_SF at the failure checks
NC = 16

# ---- per-contact flags: Fj.flag[k, ...] ------------------------------------------------
K_TYPE = 0  # microstructural type at installation (MT_*)
K_LIVE = 1  # 1: flat joint; 0: deleted (the pair is a linear contact from then on)
NK = 2

MT_BONDED = 0
MT_GAPPED = 1
MT_SLIT = 2
MT_NAMES = ("bonded", "gapped", "slit")

# ---- element states: Fj.es[k, e] ------------------------------------------------------
E_UNBONDED = 0  # unbonded from installation (gapped or slit contact)
E_TENSION = 1  # broken in tension
E_SHEAR = 2  # broken in shear
E_BONDED = 3

#: a flat joint whose elements are all unbonded is deleted (becomes a linear contact)
#: once its interface is open everywhere by more than its initial gap plus this many
#: interface radii: 2, its diameter (Potyondy 2015: a fully broken contact persists as a
#: frictional, moment-resisting face until the relative displacement exceeds the
#: flat-joint diameter; docs/contact_laws.md)
DELETE_GAP = 2.0

TWO_PI = 2.0 * math.pi


def element_table(nr: int, nal: int) -> np.ndarray:
    """Geometry of the ``nr`` x ``nal`` elements of a unit-radius interface (docs/flatjoint-spec.md §1):
    rings of equal radial width, sectors of equal angle measured from s towards t."""
    nr = int(nr)
    nal = int(nal)
    tab = np.zeros((nr * nal, NG))
    da = TWO_PI / nal
    for i in range(nr):
        a = i / nr
        b = (i + 1) / nr
        for j in range(nal):
            e = i * nal + j
            area = 0.5 * da * (b * b - a * a)
            if nal == 1:
                rho = 0.0
            else:
                rho = (2.0 / 3.0) * (b ** 3 - a ** 3) / (b * b - a * a) * \
                    math.sin(0.5 * da) / (0.5 * da)
            psi = (j + 0.5) * da
            r4 = 0.25 * (b ** 4 - a ** 4)
            iuu = r4 * (0.5 * da + 0.5 * math.sin(da))
            ivv = r4 * (0.5 * da - 0.5 * math.sin(da))
            c, s = math.cos(psi), math.sin(psi)
            p0, p1 = j * da, (j + 1) * da
            tab[e] = (area, rho * c, rho * s, iuu * c * c + ivv * s * s,
                      iuu * s * s + ivv * c * c, (iuu - ivv) * s * c, a, b, p0, p1,
                      math.cos(p0), math.sin(p0), math.cos(p1), math.sin(p1))
    return tab


def twist_factor(tab: np.ndarray) -> float:
    """Sum A_e rho_e^2 of a unit interface: twist stiffness = k_s R^4 x this."""
    return float((tab[:, G_A] * (tab[:, G_XS] ** 2 + tab[:, G_XT] ** 2)).sum())


# ---------------------------------------------------------------------------------------
# one element
# ---------------------------------------------------------------------------------------
@_inl
def closed_element(kn, area, xs, xt, iss, itt, ist, gs, ws, wt):
    """(F_n, Q_s, Q_t, 2 E/k_n) of an element stressed everywhere (bonded, or unbonded and
    closed everywhere): sigma = k_n g(p) over the element; tension positive."""
    fn = kn * area * (gs + ws * xs + wt * xt)
    qs = kn * (gs * area * xs + iss * ws + ist * wt)
    qt = kn * (gs * area * xt + ist * ws + itt * wt)
    e2 = (area * gs * gs + 2.0 * gs * area * (xs * ws + xt * wt) + ws * ws * iss
          + 2.0 * ws * wt * ist + wt * wt * itt)
    return fn, qs, qt, e2


@_inl
def _const_r(rr, gs, ws, wt, p0, p1):
    """Integrals over phi in [p0, p1] of the radial antiderivatives at a constant radius
    ``rr``: F = gs r^2/2 + c r^3/3, (G_s, G_t) = (gs r^3/3 + c r^4/4)(cos, sin),
    E = gs^2 r^2/2 + 2 gs c r^3/3 + c^2 r^4/4, c = ws cos phi + wt sin phi (exact)."""
    d = p1 - p0
    s0 = math.sin(p0)
    s1 = math.sin(p1)
    c0 = math.cos(p0)
    c1 = math.cos(p1)
    icos = s1 - s0
    isin = c0 - c1
    q = 0.25 * (math.sin(2.0 * p1) - math.sin(2.0 * p0))
    icc = 0.5 * d + q
    iss = 0.5 * d - q
    isc = 0.5 * (s1 * s1 - s0 * s0)
    ic = ws * icos + wt * isin
    r2 = rr * rr
    r3 = r2 * rr
    r4 = r2 * r2
    f = gs * r2 / 2.0 * d + r3 / 3.0 * ic
    gs_ = gs * r3 / 3.0 * icos + r4 / 4.0 * (ws * icc + wt * isc)
    gt_ = gs * r3 / 3.0 * isin + r4 / 4.0 * (ws * isc + wt * iss)
    e = (gs * gs * r2 / 2.0 * d + 2.0 * gs * r3 / 3.0 * ic
         + r4 / 4.0 * (ws * ws * icc + 2.0 * ws * wt * isc + wt * wt * iss))
    return f, gs_, gt_, e


@_inl
def _neutral_r(gs, wm, pw, p0, p1):
    """The same integrals at the neutral radius r = -gs/c(phi), c = wm cos(phi - pw):
    F = gs^3/(6 c^2), G = -gs^4/(12 c^3) (cos, sin), E = gs^4/(12 c^2), integrated in
    closed form (int sec^2 = tan, int sin/cos^3 = 1/(2 cos^2)); the piece must not
    contain a zero of c."""
    a0 = p0 - pw
    a1 = p1 - pw
    ca0 = math.cos(a0)
    ca1 = math.cos(a1)
    tt = math.tan(a1) - math.tan(a0)
    ss = 0.5 / (ca1 * ca1) - 0.5 / (ca0 * ca0)
    g2 = gs * gs
    w2 = wm * wm
    cw = math.cos(pw)
    sw = math.sin(pw)
    f = g2 * gs / 6.0 * tt / w2
    k = -g2 * g2 / 12.0 / (w2 * wm)
    return f, k * (cw * tt - sw * ss), k * (sw * tt + cw * ss), g2 * g2 / 12.0 * tt / w2


@_inl
def _piece(gs, ws, wt, wm, pw, a, b, p0, p1):
    """Integral over phi in [p0, p1] (one piece: which bound limits the compressed
    interval r in [a, b] does not change inside it) of the compressed part
    (g = gs + r c < 0): returns (int g dA, int g s dA, int g t dA, int g^2 dA)."""
    pm = 0.5 * (p0 + p1)
    c = ws * math.cos(pm) + wt * math.sin(pm)
    # compressed interval at the middle of the piece, and which bound is the neutral line
    if c > 0.0:
        h = -gs / c
        if h <= a:
            return 0.0, 0.0, 0.0, 0.0
        lo_n = False
        hi_n = h < b
    elif c < 0.0:
        h = -gs / c
        if h >= b:
            return 0.0, 0.0, 0.0, 0.0
        lo_n = h > a
        hi_n = False
    else:
        if gs >= 0.0:
            return 0.0, 0.0, 0.0, 0.0
        lo_n = False
        hi_n = False
    if hi_n:
        f1, q1, t1, e1 = _neutral_r(gs, wm, pw, p0, p1)
    else:
        f1, q1, t1, e1 = _const_r(b, gs, ws, wt, p0, p1)
    if lo_n:
        f0, q0, t0, e0 = _neutral_r(gs, wm, pw, p0, p1)
    elif a > 0.0:
        f0, q0, t0, e0 = _const_r(a, gs, ws, wt, p0, p1)
    else:
        f0, q0, t0, e0 = 0.0, 0.0, 0.0, 0.0
    return f1 - f0, q1 - q0, t1 - t0, e1 - e0


@jit
def partial_element(kn, gs, ws, wt, a, b, p0, p1, brk):
    """(F_n, Q_s, Q_t, 2 E/k_n) of the compressed part of an unbonded element (annular
    sector a <= r <= b, p0 <= phi <= p1) whose gap field g = gs + r (ws cos phi + wt sin
    phi) changes sign over it. The angle range is split where the neutral line crosses
    r = a or r = b and where c(phi) = 0; on each piece the integral is in closed form
    (``_piece``), so the result is exact to round-off. ``brk``: scratch array of at least
    8 floats."""
    wm = math.sqrt(ws * ws + wt * wt)
    nbk = 0
    brk[0] = p0
    nbk = 1
    if wm > 0.0:
        pw = math.atan2(wt, ws)
        for cand in range(6):
            if cand < 2:
                ang = pw + (0.5 * math.pi if cand == 0 else -0.5 * math.pi)
            else:
                rr = a if cand < 4 else b
                if rr <= 0.0:
                    continue
                arg = -gs / (rr * wm)
                if arg < -1.0 or arg > 1.0:
                    continue
                d = math.acos(arg)
                ang = pw + (d if cand % 2 == 0 else -d)
            ang = p0 + ((ang - p0) % TWO_PI)
            if ang > p0 and ang < p1:
                brk[nbk] = ang
                nbk += 1
    brk[nbk] = p1
    nbk += 1
    # insertion sort of the interior points
    for u in range(2, nbk - 1):
        v = brk[u]
        w = u - 1
        while w >= 1 and brk[w] > v:
            brk[w + 1] = brk[w]
            w -= 1
        brk[w + 1] = v
    f = 0.0
    qs = 0.0
    qt = 0.0
    e = 0.0
    pw = math.atan2(wt, ws)
    for u in range(nbk - 1):
        if brk[u + 1] > brk[u]:
            df, dqs, dqt, de = _piece(gs, ws, wt, wm, pw, a, b, brk[u], brk[u + 1])
            f += df
            qs += dqs
            qt += dqt
            e += de
    return kn * f, kn * qs, kn * qt, e


@_inl
def gap_range(gs, ws, wt, a, b, p0, p1, c0, s0, c1, s1):
    """Smallest and largest gap over an annular sector: at its four corners and at the
    outer arc's extreme points (the directions +-w) when they lie in the sector (the
    inner arc has none that beat the outer one). No trigonometry: the corners' cos/sin
    come from the element table, and a direction is tested against the sector's bounding
    rays by cross products."""
    gmin = math.inf
    gmax = -math.inf
    for q in range(4):
        r = a if q < 2 else b
        cq = c0 if q % 2 == 0 else c1
        sq = s0 if q % 2 == 0 else s1
        g = gs + r * (ws * cq + wt * sq)
        gmin = min(gmin, g)
        gmax = max(gmax, g)
    wm = math.sqrt(ws * ws + wt * wt)
    if wm > 0.0:
        span = p1 - p0
        for sgn in (1.0, -1.0):
            ux = sgn * ws
            uy = sgn * wt
            if span >= TWO_PI * (1.0 - 1e-12):
                inside = True
            elif span <= math.pi:
                inside = c0 * uy - s0 * ux >= 0.0 and ux * s1 - uy * c1 >= 0.0
            else:  # wider than a half plane: not inside the complementary sector
                inside = not (c1 * uy - s1 * ux > 0.0 and ux * s0 - uy * c0 > 0.0)
            if inside:
                g = gs + sgn * b * wm
                gmin = min(gmin, g)
                gmax = max(gmax, g)
    return gmin, gmax


@jit
def unbonded_element(kn, area, xs, xt, iss, itt, ist, gs, ws, wt, a, b, p0, p1, c0, s0, c1,
                     s1, brk):
    """(F_n, Q_s, Q_t, 2 E/k_n) of an unbonded element: compression only."""
    gmin, gmax = gap_range(gs, ws, wt, a, b, p0, p1, c0, s0, c1, s1)
    if gmin >= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    if gmax <= 0.0:
        return closed_element(kn, area, xs, xt, iss, itt, ist, gs, ws, wt)
    return partial_element(kn, gs, ws, wt, a, b, p0, p1, brk)


@_inl
def _unbonded_at(kn, area, xs, xt, iss, itt, ist, gs, ws, wt, geo, e, rad, brk):
    """``unbonded_element`` of element ``e`` of the table ``geo`` at interface radius
    ``rad``."""
    return unbonded_element(kn, area, xs, xt, iss, itt, ist, gs, ws, wt, geo[e, G_RA] * rad,
                            geo[e, G_RB] * rad, geo[e, G_P0], geo[e, G_P1], geo[e, G_C0],
                            geo[e, G_S0], geo[e, G_C1], geo[e, G_S1], brk)


# ---------------------------------------------------------------------------------------
# the flat-jointed pairs
# ---------------------------------------------------------------------------------------
@_inl
def _deleted_contact(ri, rj, inv_l, gap, nx, ny, nz, dphi, dusx, dusy, dusz, lx, ly, lz,
                     emod, ikr, mu):
    """A deleted flat joint: a linear contact (reference gap 0), as the pairs found later.
    ``l`` = its stored shear force. Returns the force on j (3), the new shear force (3), the
    slip energy and the strain energy."""
    kn, ks = linear_stiffness(ri, rj, inv_l, emod, ikr)
    sx, sy, sz = rotate_shear(lx, ly, lz, nx, ny, nz, dphi)
    eslip = 0.0
    elin = 0.0
    if gap < 0.0:
        fn = -kn * gap
        ux, uy, uz, tx, ty, tz, esl_ = linear_shear(sx, sy, sz, dusx, dusy, dusz, ks,
                                                    1.0 / ks, mu * fn)
        eslip = esl_
        elin = 0.5 * fn * fn / kn + 0.5 * (ux * ux + uy * uy + uz * uz) / ks
    else:
        if sx != 0.0 or sy != 0.0 or sz != 0.0:
            eslip = 0.5 * (sx * (sx - ks * dusx) + sy * (sy - ks * dusy)
                           + sz * (sz - ks * dusz)) / ks
        fn = 0.0
        ux = 0.0
        uy = 0.0
        uz = 0.0
    return fn * nx + ux, fn * ny + uy, fn * nz + uz, ux, uy, uz, eslip, elin


# The law of one contact is written out inside the loop over the pairs, not called: as a
# function inlined by numba its array arguments cost a reference-count increment and
# decrement each per pair, and as a plain call more still (the record
# docs/measurements/2026-11-27-flatjoint-speed.md gives the throughput before and after).
# long: the hot loop, one contact's law written out inside it
@jit
def fj_range(pos, vel, angvel, radius, pi, pj, pslip, pestr, bstate, bstep, be, bestr, fb,
             k0, k1, dt, Fj, prm_fj, step, record, brk, crk):
    """Force-displacement of the flat-jointed pairs k0..k1 for one step, scattered into the
    partition buffer ``fb`` in increasing pair order; element breaks recorded in ``Fj``.
    Returns the number of elements broken.

    ``prm_fj`` = (E*, 1/kappa*, sigma_b, c_b, tan phi_b, mu, lambda, E* lin, 1/kappa* lin,
    mu lin). Per pair: the force and couple on j, the slip energy (``pslip``), the strain
    energy of the interface (``bestr``) or of a deleted (linear) contact (``pestr``) on
    recording steps, and per element broken (listed in the scratch ``crk[q]`` = (element,
    mode, crack position relative to ball i (3), sigma, tau, released energy)) its step,
    position, normal, stresses and released energy. ``brk``: scratch of 8 floats."""
    c = Fj.c
    flag = Fj.flag
    es = Fj.es
    ef = Fj.ef
    esl = Fj.eslip
    geo = Fj.geo
    estep = Fj.estep
    epos = Fj.epos
    enrm = Fj.enrm
    esig = Fj.esig
    een = Fj.een
    emod = prm_fj[0]
    ikr = prm_fj[1]
    tanfa = prm_fj[4]  # (prm_fj[2], prm_fj[3], the material's means: each joint has its own)
    mu = prm_fj[5]
    rmul = prm_fj[6]
    ne = geo.shape[0]
    nbroken = 0
    for k in range(k0, k1):
        i = pi[k]
        j = pj[k]
        ri = radius[i]
        rj = radius[j]
        wix = angvel[i, 0]
        wiy = angvel[i, 1]
        wiz = angvel[i, 2]
        wjx = angvel[j, 0]
        wjy = angvel[j, 1]
        wjz = angvel[j, 2]
        (nx, ny, nz, gap, inv_l, ai, aj, vrx, vry, vrz, vn, dun, dusx, dusy, dusz,
         dphi) = kinematics(pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1],
                            pos[j, 2] - pos[i, 2], vel[j, 0] - vel[i, 0],
                            vel[j, 1] - vel[i, 1], vel[j, 2] - vel[i, 2], wix, wiy, wiz,
                            wjx, wjy, wjz, ri, rj, dt)
        nbrk = 0
        if flag[k, K_LIVE] == 0:
            fx, fy, fz, lx, ly, lz, eslip, elin = _deleted_contact(
                ri, rj, inv_l, gap, nx, ny, nz, dphi, dusx, dusy, dusz, c[k, C_LX],
                c[k, C_LY], c[k, C_LZ], prm_fj[7], prm_fj[8], prm_fj[9])
            c[k, C_LX] = lx
            c[k, C_LY] = ly
            c[k, C_LZ] = lz
            mx = 0.0
            my = 0.0
            mz = 0.0
            ebond = 0.0
        else:
            rad = rmul * min(ri, rj)
            r2 = rad * rad
            r4 = r2 * r2
            kn = emod * inv_l
            ks = kn * ikr
            sf = c[k, C_SF]
            ten = c[k, C_TEN] * sf
            coh = c[k, C_COH] * sf
            # ---- carry the frame: drop the component along the new normal, turn by the spin
            sx, sy, sz = rotate_shear(c[k, C_SX], c[k, C_SY], c[k, C_SZ], nx, ny, nz, dphi)
            sm = sx * sx + sy * sy + sz * sz
            if sm < 1e-12:  # degenerate (never after installation): any perpendicular
                if abs(nx) < 0.9:
                    sx, sy, sz = 0.0, -nz, ny
                else:
                    sx, sy, sz = nz, 0.0, -nx
                sm = sx * sx + sy * sy + sz * sz
            sm = 1.0 / math.sqrt(sm)
            sx *= sm
            sy *= sm
            sz *= sm
            tx = ny * sz - nz * sy
            ty = nz * sx - nx * sz
            tz = nx * sy - ny * sx
            c[k, C_SX] = sx
            c[k, C_SY] = sy
            c[k, C_SZ] = sz
            # ---- increments in the local frame
            dwx = (wjx - wix) * dt
            dwy = (wjy - wiy) * dt
            dwz = (wjz - wiz) * dt
            dtbs = dwx * sx + dwy * sy + dwz * sz
            dtbt = dwx * tx + dwy * ty + dwz * tz
            dtht = dwx * nx + dwy * ny + dwz * nz
            dds = dusx * sx + dusy * sy + dusz * sz
            ddt = dusx * tx + dusy * ty + dusz * tz
            tbs = c[k, C_TBS] + dtbs
            tbt = c[k, C_TBT] + dtbt
            c[k, C_TBS] = tbs
            c[k, C_TBT] = tbt
            gs = gap - c[k, C_GREF]
            ws = -tbt
            wt = tbs
            gs0 = gs - dun  # the state before this step (for the released energy)
            ws0 = ws + dtbt
            wt0 = wt - dtbs
            fnt = 0.0
            qst = 0.0
            qtt = 0.0
            fst = 0.0
            ftt = 0.0
            mnt = 0.0
            e2n = 0.0
            esh = 0.0
            eslip = 0.0
            nbrk = 0
            nbonded = 0
            for e in range(ne):
                area = geo[e, G_A] * r2
                xs = geo[e, G_XS] * rad
                xt = geo[e, G_XT] * rad
                iss = geo[e, G_ISS] * r4
                itt = geo[e, G_ITT] * r4
                ist = geo[e, G_IST] * r4
                st = es[k, e]
                if st == E_BONDED:
                    # force and first moment only: the energy is computed where it is used
                    fn = kn * area * (gs + ws * xs + wt * xt)
                    qs = kn * (gs * area * xs + iss * ws + ist * wt)
                    qt = kn * (gs * area * xt + ist * ws + itt * wt)
                    e2 = 0.0
                else:
                    fn, qs, qt, e2 = _unbonded_at(kn, area, xs, xt, iss, itt, ist, gs, ws, wt,
                                                  geo, e, rad, brk)
                # ---- incremental shear at the centroid (interface shear + twist x arm)
                ka = ks * area
                f0s = ef[k, e, 0]
                f0t = ef[k, e, 1]
                us = f0s - ka * (dds - dtht * xt)
                ut = f0t - ka * (ddt + dtht * xs)
                if st == E_BONDED:
                    # sigma = F_n/A >= sigma_b, else tau = |F_s|/A >= c_b - sigma tan(phi_b):
                    # multiplied through by A and squared (no division, no square root)
                    mode = 0
                    if fn >= ten * area:
                        mode = E_TENSION
                    else:
                        lim = coh * area - fn * tanfa
                        if lim <= 0.0 or us * us + ut * ut >= lim * lim:
                            mode = E_SHEAR
                    if mode != 0:
                        sig = fn / area
                        tau = math.sqrt(us * us + ut * ut) / area
                        # released: the element's strain energy, in the step-consistent form
                        # 1/2 k g_old g_trial (normal) + 1/2 F_old . F_trial / k (shear);
                        _, _, _, e2x = closed_element(kn, area, xs, xt, iss, itt, ist,
                                                      0.5 * (gs + gs0), 0.5 * (ws + ws0),
                                                      0.5 * (wt + wt0))
                        _, _, _, e2a = closed_element(kn, area, xs, xt, iss, itt, ist,
                                                      0.5 * (gs - gs0), 0.5 * (ws - ws0),
                                                      0.5 * (wt - wt0))
                        # only the stretched part is released: an element compressed everywhere
                        # keeps its normal strain energy as an unbonded one (same law there);
                        # in between, the share of the energy held by the opening part
                        _, _, _, e2 = closed_element(kn, area, xs, xt, iss, itt, ist, gs, ws, wt)
                        _, _, _, e2u = _unbonded_at(kn, area, xs, xt, iss, itt, ist, gs, ws, wt,
                                                    geo, e, rad, brk)
                        share = 1.0 - e2u / e2 if e2 > 0.0 else 1.0
                        erel = (share * 0.5 * kn * (e2x - e2a)
                                + 0.5 * (f0s * us + f0t * ut) / ka)
                        crk[nbrk, 0] = e
                        crk[nbrk, 1] = mode
                        crk[nbrk, 2] = xs * sx + xt * tx
                        crk[nbrk, 3] = xs * sy + xt * ty
                        crk[nbrk, 4] = xs * sz + xt * tz
                        crk[nbrk, 5] = sig
                        crk[nbrk, 6] = tau
                        crk[nbrk, 7] = erel
                        nbrk += 1
                        es[k, e] = mode
                        st = mode
                        fn, qs, qt, e2 = _unbonded_at(kn, area, xs, xt, iss, itt, ist, gs, ws, wt,
                                                      geo, e, rad, brk)
                        us = 0.0  # residual mode 0: the shear force is removed at breakage
                        ut = 0.0
                        f0s = 0.0
                        f0t = 0.0
                    else:
                        nbonded += 1
                if st != E_BONDED:
                    lim = mu * max(0.0, -fn)
                    uu = us * us + ut * ut
                    if uu > lim * lim:
                        sc = lim / math.sqrt(uu)
                        vs = us * sc
                        vt = ut * sc
                        # dissipated: -1/2 (F_old + F_new) . (slip displacement)
                        eslip += 0.5 * ((f0s + vs) * (us - vs) + (f0t + vt) * (ut - vt)) / ka
                        us = vs
                        ut = vt
                        esl[k, e] = 1
                    else:
                        esl[k, e] = 0
                ef[k, e, 0] = us
                ef[k, e, 1] = ut
                fnt += fn
                qst += qs
                qtt += qt
                fst += us
                ftt += ut
                mnt += xs * ut - xt * us
                if record:
                    if st == E_BONDED:
                        _, _, _, e2 = closed_element(kn, area, xs, xt, iss, itt, ist, gs, ws, wt)
                    e2n += e2
                    esh += 0.5 * (us * us + ut * ut) / ka
            # ---- resultants on piece 2
            fx = -fnt * nx + fst * sx + ftt * tx
            fy = -fnt * ny + fst * sy + ftt * ty
            fz = -fnt * nz + fst * sz + ftt * tz
            mx = -qtt * sx + qst * tx + mnt * nx
            my = -qtt * sy + qst * ty + mnt * ny
            mz = -qtt * sz + qst * tz + mnt * nz
            # crack positions: contact point + element centroid offset (global)
            for q in range(nbrk):
                crk[q, 2] += ai * nx
                crk[q, 3] += ai * ny
                crk[q, 4] += ai * nz
            # ---- deletion: every element unbonded and the interface open everywhere
            if nbonded == 0:
                wm = math.sqrt(ws * ws + wt * wt)
                if gs - wm * rad > c[k, C_G0] + DELETE_GAP * rad:
                    flag[k, K_LIVE] = 0
                    for e in range(ne):
                        ef[k, e, 0] = 0.0
                        ef[k, e, 1] = 0.0
                    c[k, C_LX] = 0.0
                    c[k, C_LY] = 0.0
                    c[k, C_LZ] = 0.0
            ebond = 0.5 * kn * e2n + esh
            elin = 0.0
        if record:
            c[k, C_FX] = fx
            c[k, C_FY] = fy
            c[k, C_FZ] = fz
        cx = ny * fz - nz * fy
        cy = nz * fx - nx * fz
        cz = nx * fy - ny * fx
        fb[i, 0] -= fx
        fb[i, 1] -= fy
        fb[i, 2] -= fz
        fb[i, 3] -= ai * cx + mx
        fb[i, 4] -= ai * cy + my
        fb[i, 5] -= ai * cz + mz
        fb[j, 0] += fx
        fb[j, 1] += fy
        fb[j, 2] += fz
        fb[j, 3] += aj * cx + mx
        fb[j, 4] += aj * cy + my
        fb[j, 5] += aj * cz + mz
        if eslip != 0.0:
            pslip[k] += eslip
        if record:
            bestr[k] = ebond
            pestr[k] = elin
        for q in range(nbrk):
            e = int(crk[q, 0])
            estep[k, e] = step
            for d in range(3):
                epos[k, e, d] = pos[i, d] + crk[q, 2 + d]
            enrm[k, e, 0] = nx
            enrm[k, e, 1] = ny
            enrm[k, e, 2] = nz
            esig[k, e, 0] = crk[q, 5]
            esig[k, e, 1] = crk[q, 6]
            een[k, e] = crk[q, 7]
            be[k] += crk[q, 7]
        if nbrk > 0:
            anyb = False
            for e in range(ne):
                if es[k, e] == E_BONDED:
                    anyb = True
            if not anyb and bstate[k] == 0:
                bstate[k] = int(crk[nbrk - 1, 1])
                bstep[k] = step
        nbroken += nbrk
    return nbroken
