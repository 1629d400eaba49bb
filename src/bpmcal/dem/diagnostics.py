"""Measurements that are not needed every step: energy terms of the current state, the
critical timestep, the mean contact force (unbalanced-force ratio), coordination numbers.

They read the state the stepping kernels (``kernels.py``) keep and never change the
trajectory: ``measure_balls`` predicts the next half-step velocities with the same law
of motion the integrator uses (``motion.ball_update``).
"""
from __future__ import annotations

import math

import numpy as np

from ._jit import jit
from .bondblock import S_FN, S_LX, S_RG, S_SX, state_index
from .flatjoint import C_FX
from .laws import bond_geometry, linear_stiffness
from .motion import ball_state, ball_update, constraint_power, gather, wall_power
from .slots import (
    BOND_INTACT,
    E_DASH,
    E_SLIP,
    E_WDASH,
    E_WSLIP,
    FIX_ALL,
    P_ALPHA,
    P_DT,
    P_EMOD,
    P_GX,
    P_GY,
    P_GZ,
    P_KRATIO,
    P_NOSPIN,
    P_PB_EMOD,
    P_PB_KRATIO,
    P_PB_RMUL,
)


@jit
def measure_balls(vel, angvel, force, moment, mass, inertia, fix, fbuf, pmask, sptr, sf, sm,
                  prm):
    """Ball energy terms at the current step n (forces F_n, velocities v_{n-1/2}):
    kinetic energy 1/2 m v_{n-1/2}.v_{n+1/2} (v_{n+1/2} predicted exactly as ``integrate``
    will compute it) and the first half of step n of damping dissipation, gravity work
    and constraint work. Also stores the resultant force/moment (unbalanced force).
    Returns (kinetic, damping_half, gravity_half, constraint_half)."""
    n = vel.shape[0]
    dt = prm[P_DT]
    alpha = prm[P_ALPHA]
    gx = prm[P_GX]
    gy = prm[P_GY]
    gz = prm[P_GZ]
    spin = prm[P_NOSPIN] == 0.0
    kin = 0.0
    dmp = 0.0
    grv = 0.0
    cst = 0.0
    for i in range(n):
        f0, f1, f2, m0, m1, m2 = gather(i, fbuf, pmask, sptr, sf, sm, False)
        mi = mass[i]
        f0 += mi * gx
        f1 += mi * gy
        f2 += mi * gz
        force[i, 0] = f0
        force[i, 1] = f1
        force[i, 2] = f2
        moment[i, 0] = m0
        moment[i, 1] = m1
        moment[i, 2] = m2
        fl, im, ii, u0, u1, u2, w0, w1, w2 = ball_state(i, mi, inertia, fix, vel, angvel)
        n0, n1, n2, r0, r1, r2, d0, d1, d2, e0, e1, e2 = ball_update(
            u0, u1, u2, w0, w1, w2, f0, f1, f2, m0, m1, m2, im, ii, alpha, dt, fl, spin)
        kin += 0.5 * mi * (u0 * n0 + u1 * n1 + u2 * n2) + 0.5 * inertia[i] * (
            w0 * r0 + w1 * r1 + w2 * r2)
        h = 0.5 * dt
        dmp -= (d0 * u0 + d1 * u1 + d2 * u2 + e0 * w0 + e1 * w1 + e2 * w2) * h
        grv += mi * (gx * u0 + gy * u1 + gz * u2) * h
        if fl:
            cw = constraint_power(fl, f0, f1, f2, m0, m1, m2, u0, u1, u2, w0, w1, w2)
            cst -= cw * h
    return kin, dmp, grv, cst


@jit
def measure_walls(wvel, wradv, wmass, wforce, wradsum, prm, out):
    """Wall energy terms at the current step n (forces F_n known, velocities v_{n-1/2}):
    kinetic 1/2 M v_{n-1/2}.v_{n+1/2} of rigid walls (v_{n+1/2} predicted), and the first
    half of step n of boundary work and of gravity work on rigid walls, which belong to
    the energy state at step n. out = (kinetic, work, gravity) per wall."""
    nw = wvel.shape[0]
    dt = prm[P_DT]
    g = (prm[P_GX], prm[P_GY], prm[P_GZ])
    for w in range(nw):
        a0 = wvel[w, 0]
        a1 = wvel[w, 1]
        a2 = wvel[w, 2]
        out[w, 0] = 0.0
        out[w, 2] = 0.0
        if wmass[w] > 0.0:
            m = wmass[w]
            b0 = a0 + (wforce[w, 0] / m + g[0]) * dt
            b1 = a1 + (wforce[w, 1] / m + g[1]) * dt
            b2 = a2 + (wforce[w, 2] / m + g[2]) * dt
            out[w, 0] = 0.5 * m * (a0 * b0 + a1 * b1 + a2 * b2)
            out[w, 2] = 0.5 * m * (g[0] * a0 + g[1] * a1 + g[2] * a2) * dt
        out[w, 1] = 0.5 * wall_power(wforce, wradsum, w, a0, a1, a2, wradv[w]) * dt


@jit
def ball_stiffness(radius, pi, pj, npairs, nb, bstate, sb, nslots, prm, fjprm, fjlive,
                   fjtwist):
    """Each ball's translational and rotational stiffness (k_tran, k_rot), PFC's estimate
    for the critical timestep.

    k_tran sums kn + kn_bar A (using max(kn, ks) and max of the bond stiffnesses) over
    every pair in the neighbour list (in contact or within the skin, so contacts about
    to form are counted) and the wall slots; k_rot sums ks a^2 (+ ks_bar A a^2 +
    max(ks_bar J, kn_bar I)). A live flat joint (``fjlive[k]``; ``fjprm`` its law's
    parameters, ``fjtwist`` = sum A_e rho_e^2 of a unit interface) counts instead of the
    linear contact with k_tran = max(kn, ks) A and k_rot = ks A a^2 + max(kn I,
    ks R^4 fjtwist) (docs/flatjoint-spec.md §5).
    """
    n = radius.shape[0]
    kt = np.zeros(n)
    kr = np.zeros(n)
    emod = prm[P_EMOD]
    kratio = prm[P_KRATIO]
    for k in range(npairs):
        i = pi[k]
        j = pj[k]
        inv_l = 1.0 / (radius[i] + radius[j])
        kn, ks = linear_stiffness(radius[i], radius[j], inv_l, emod, 1.0 / kratio)
        ktr = max(kn, ks)
        ksh = ks
        krb = 0.0
        if k < nb and fjlive.shape[0] > 0:
            if fjlive[k] != 0:  # flat joint (deleted ones are linear contacts)
                rad = fjprm[6] * min(radius[i], radius[j])
                area = math.pi * rad * rad
                knf = fjprm[0] * inv_l
                ksf = knf * fjprm[1]
                ktr = max(knf, ksf) * area
                ksh = ksf * area
                krb = max(knf * 0.25 * area * rad * rad, ksf * rad ** 4 * fjtwist)
        elif k < nb and bstate[k] == BOND_INTACT:
            rb, area, kna, ksa, ksj, kni = bond_geometry(radius[i], radius[j], inv_l,
                                                         prm[P_PB_EMOD],
                                                         1.0 / prm[P_PB_KRATIO],
                                                         prm[P_PB_RMUL])
            ktr += max(kna, ksa)
            ksh += ksa
            krb = max(ksj, kni)
        kt[i] += ktr
        kt[j] += ktr
        kr[i] += ksh * radius[i] * radius[i] + krb
        kr[j] += ksh * radius[j] * radius[j] + krb
    for s in range(nslots):
        b = sb[s]
        kn = math.pi * radius[b] * emod
        ks = kn / kratio
        kt[b] += max(kn, ks)
        kr[b] += ks * radius[b] * radius[b]
    return kt, kr


@jit
def stiffness_timestep(radius, mass, inertia, fix, pi, pj, npairs, nb, bstate, sb, nslots,
                       prm, fjprm, fjlive, fjtwist):
    """PFC-style critical timestep: min over balls of sqrt(m/k_tran), sqrt(I/k_rot)
    (:func:`ball_stiffness`). Returns (dt_crit, index of the limiting ball)."""
    n = radius.shape[0]
    kt, kr = ball_stiffness(radius, pi, pj, npairs, nb, bstate, sb, nslots, prm, fjprm,
                            fjlive, fjtwist)
    best = np.inf
    arg = -1
    for i in range(n):
        if fix[i] == FIX_ALL:
            continue
        if kt[i] > 0.0:
            t = math.sqrt(mass[i] / kt[i])
            if t < best:
                best = t
                arg = i
        if kr[i] > 0.0:
            t = math.sqrt(inertia[i] / kr[i])
            if t < best:
                best = t
                arg = i
    return best, arg


@jit
def sum_energies(edamp, egrav, efix, pestr, pslip, pdash, npairs, bestr, be, bstate, nb,
                 sestr, sslip, sdash, nslots, eacc, flat):
    """Totals of the per-ball / per-pair / per-slot energy slots (fixed order).
    ``flat``: the installed pairs are flat joints (strain and released energy of every
    contact count, whatever its state).

    Returns strain_linear (ball-ball + ball-wall), strain_bond, slip, dashpot, damping,
    gravity work on balls, constraint work, released by breakage (accumulated through the
    last completed step; ``measure_balls`` adds the half step that belongs to the state).
    """
    damp = 0.0
    grav = 0.0
    fixw = 0.0
    for i in range(edamp.shape[0]):
        damp += edamp[i]
        grav += egrav[i]
        fixw += efix[i]
    lin = 0.0
    slip = eacc[E_SLIP] + eacc[E_WSLIP]
    dash = eacc[E_DASH] + eacc[E_WDASH]
    for k in range(npairs):
        lin += pestr[k]
        slip += pslip[k]
        dash += pdash[k]
    for s in range(nslots):
        lin += sestr[s]
        slip += sslip[s]
        dash += sdash[s]
    bond = 0.0
    rel = 0.0
    for k in range(nb):
        if flat:
            bond += bestr[k]
            rel += be[k]
        elif bstate[k] == BOND_INTACT:
            bond += bestr[k]
        else:
            rel += be[k]
    return lin, bond, slip, dash, damp, grav, fixw, rel


@jit
def contact_force_mean(pos, radius, pi, pj, pfs, npairs, nb, bstate, blk, prm, fjc):
    """Mean magnitude of the force of active pairs (linear contact or intact bond),
    recomputed from the stored state (dashpot forces excluded). Flat joints (``fjc``
    holds a row per installed pair): the force of their last evaluation, counted when
    not zero."""
    emod = prm[P_EMOD]
    tot = 0.0
    cnt = 0
    k0 = 0
    if fjc.shape[0] > 0:
        k0 = nb
        for k in range(nb):
            f = math.sqrt(fjc[k, C_FX] ** 2 + fjc[k, C_FX + 1] ** 2 + fjc[k, C_FX + 2] ** 2)
            if f > 0.0:
                tot += f
                cnt += 1
    for k in range(k0, npairs):
        i = pi[k]
        j = pj[k]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        if d == 0.0:
            continue
        nx = dx / d
        ny = dy / d
        nz = dz / d
        sr = radius[i] + radius[j]
        gap = d - sr
        rg = 0.0
        bonded = False
        if k < nb:
            rg = blk[state_index(k, S_RG)]
            bonded = bstate[k] == BOND_INTACT
            lx = blk[state_index(k, S_LX)]
            ly = blk[state_index(k, S_LX + 1)]
            lz = blk[state_index(k, S_LX + 2)]
        else:
            lx = pfs[k, 0]
            ly = pfs[k, 1]
            lz = pfs[k, 2]
        fn = 0.0
        if gap < rg:
            r = min(radius[i], radius[j])
            fn = math.pi * r * r * emod / sr * (rg - gap)
        fx = fn * nx + lx
        fy = fn * ny + ly
        fz = fn * nz + lz
        if bonded:
            fnb = blk[state_index(k, S_FN)]
            fx += blk[state_index(k, S_SX)] - fnb * nx
            fy += blk[state_index(k, S_SX + 1)] - fnb * ny
            fz += blk[state_index(k, S_SX + 2)] - fnb * nz
        if bonded or gap < rg:
            tot += math.sqrt(fx * fx + fy * fy + fz * fz)
            cnt += 1
    if cnt == 0:
        return 0.0, 0
    return tot / cnt, cnt


@jit
def coordination(pos, radius, pi, pj, npairs, nb, bstate, blk):
    """Number of contacts (gap below reference gap, or intact bond) of every ball."""
    n = radius.shape[0]
    z = np.zeros(n, np.int64)
    for k in range(npairs):
        i = pi[k]
        j = pj[k]
        rg = 0.0
        bonded = False
        if k < nb:
            rg = blk[state_index(k, S_RG)]
            bonded = bstate[k] == BOND_INTACT
        d = math.sqrt((pos[j, 0] - pos[i, 0]) ** 2 + (pos[j, 1] - pos[i, 1]) ** 2
                      + (pos[j, 2] - pos[i, 2]) ** 2)
        if bonded or d - radius[i] - radius[j] < rg:
            z[i] += 1
            z[j] += 1
    return z


@jit
def wall_contact_balls(sw, sb, sf, ns, w, n):
    """The balls (sorted, unique, int32) with a slot on wall ``w`` among the first ``ns``
    slots whose contact force is not zero; ``n`` balls in the model."""
    on = np.zeros(n, np.bool_)
    cnt = 0
    for k in range(ns):
        if sw[k] != w or on[sb[k]]:
            continue
        for c in range(sf.shape[1]):
            if sf[k, c] != 0.0:
                on[sb[k]] = True
                cnt += 1
                break
    out = np.empty(cnt, np.int32)
    j = 0
    for i in range(n):
        if on[i]:
            out[j] = i
            j += 1
    return out
