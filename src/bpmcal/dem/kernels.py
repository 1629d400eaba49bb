"""The stepping kernels: contact laws (``laws.py``) mapped over ball-ball pairs and
ball-wall slots, the law of motion (``motion.py``) mapped over balls, wall motion, and the
chunk runner that numba executes between two Python calls.

One step (``run_steps``; PFC cycle order, positions x_n, velocities at half steps):

1. ``integrate``      (parallel over balls): gather the forces of step n from the
   partition buffers and the ball's wall slots in a fixed order, add gravity and local
   damping, update v_{n+1/2} and x_{n+1} (``motion.ball_update``).
2. ``advance_walls``  (serial): rigid-body walls get their new velocity, boundary work is
   booked, walls move.
3. Verlet criterion; when some ball may have moved more than half the skin, the
   neighbour lists are rebuilt (``neighbors.py``).
4. ``pair_forces``    (parallel over fixed partitions of the ball-ball pairs): linear
   contact + parallel bond of every pair (bonds in vectorised blocks, ``bondblock.py``),
   scattered into one force buffer per partition in increasing pair order.
5. ``wall_forces``    (parallel over ball-wall slots): linear contact with each wall;
   ``wall_resultants`` (serial) sums the force on each wall.

Per-partition buffers + a fixed-order gather mean no atomics and results that are
bitwise identical for any number of threads.

Energy bookkeeping is consistent with the leapfrog scheme: kinetic energy at step n is
``1/2 m v_{n-1/2} . v_{n+1/2}``, strain energies are evaluated from the forces at step n,
and every incremental term (damping, gravity, boundary work, slip, dashpots, breakage)
is accumulated with the weights the integrator implies. For linear springs the balance
then closes to round-off; what remains is the (small) error of contact creation and loss
inside a step. The measurements that read these terms are in ``diagnostics.py``.
"""
from __future__ import annotations

import math

import numpy as np

from ._jit import jit, jit_parallel, prange
from .bondblock import bond_range
from .bondblock import scratch as bond_scratch
from .flatjoint import fj_range
from .laws import (
    dashpot,
    kinematics,
    linear_shear,
    linear_stiffness,
    rotate_shear,
    wall_contact_geometry,
)
from .motion import ball_state, ball_update, constraint_power, gather, wall_power
from .neighbors import max_displacement, rebuild_lists
from .slots import (
    I_BAD,
    I_FORCES,
    I_NB,
    I_NBROKEN,
    I_NSLOTS,
    I_REBUILD,
    I_STEP,
    P_ALPHA,
    P_DBOUND,
    P_DP_N,
    P_DP_S,
    P_DT,
    P_EMOD,
    P_FRIC,
    P_GX,
    P_GY,
    P_GZ,
    P_KRATIO,
    P_MAXSPEED,
    P_MODEL,
    P_NOSPIN,
    P_PB_COH,
    P_PB_EMOD,
    P_PB_KRATIO,
    P_PB_MCF,
    P_PB_RMUL,
    P_PB_TANFA,
    P_PB_TEN,
    P_SKIN,
    P_TIME,
    P_VCAP,
)


# ---------------------------------------------------------------------------------------
# 1. ball-ball pairs
# ---------------------------------------------------------------------------------------
@jit
def pair_partition(p, pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, pslip, pdash,
                   pestr, blk, bstate, bstep, bpos, bnrm, be, bestr, bsig, part, fbuf, prm, step,
                   nb, record, idt, Fj):
    """Force-displacement for the pairs of partition ``p``, scattered into ``fbuf[p]``.

    Pairs are split into fixed index ranges ``part`` (one per partition); partition p adds
    the forces and moments of its pairs to ``fbuf[p]`` (ball-major, 6 components), in
    increasing pair order. The partitions, not the threads, fix the summation order, so
    the result does not depend on the number of threads. Bond pairs (k < nb) keep their
    state in the blocked array ``blk`` (bondblock.py); the unbonded pairs use ``pfs``,
    ``pdf`` and ``pact`` (whether the pair carried force last step). With flat joints
    (``prm[P_MODEL]`` = 1) the installed pairs are flat joints (``flatjoint.fj_range``,
    state in ``Fj``) instead. Returns bonds (flat-joint elements) broken.
    """
    dt = idt
    emod = prm[P_EMOD]
    ikr = 1.0 / prm[P_KRATIO]
    fric = prm[P_FRIC]
    pb_emod = prm[P_PB_EMOD]
    pb_ikr = 1.0 / prm[P_PB_KRATIO]
    pb_ten = prm[P_PB_TEN]
    pb_coh = prm[P_PB_COH]
    tanfa = prm[P_PB_TANFA]
    rmul = prm[P_PB_RMUL]
    mcf = prm[P_PB_MCF]
    betan = prm[P_DP_N]
    betas = prm[P_DP_S]
    nbroken = 0
    T = bond_scratch()
    k0 = part[p]
    k1 = part[p + 1]
    kb = min(k1, nb)
    if kb > k0 and prm[P_MODEL] > 0.0:  # flat-jointed pairs
        nbroken += fj_range(pos, vel, angvel, radius, pi, pj, pslip, pestr, bstate, bstep, be,
                            bestr, fbuf[p], k0, kb, dt, Fj, Fj.prm, step, record,
                            np.empty(8), np.empty((Fj.geo.shape[0], 8)))
    elif kb > k0:  # bond pairs: vectorised blocks
        nbroken += bond_range(pos, vel, angvel, radius, mass, pi, pj, blk, pslip, pdash,
                              pestr, bstate, bstep, bpos, bnrm, be, bestr, bsig, fbuf[p],
                              k0, kb, T, dt, emod, ikr, fric, pb_emod, pb_ikr, pb_ten,
                              pb_coh, tanfa, rmul, mcf, betan, betas, step, record)
    if fric == 0.0 and betan == 0.0 and betas == 0.0:
        _pair_range_frictionless(pos, vel, angvel, radius, pi, pj, pfs, pact, pestr, fbuf[p],
                                 max(k0, nb), k1, dt, emod, ikr, record,
                                 prm[P_NOSPIN] == 0.0)
    else:
        _pair_range(pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, pslip, pdash,
                    pestr, fbuf[p], max(k0, nb), k1, dt, emod, ikr, fric, betan, betas,
                    record)
    return nbroken


@jit_parallel
def pair_forces(pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, pslip, pdash, pestr,
                blk, bstate, bstep, bpos, bnrm, be, bestr, bsig, part, fbuf, prm, step, nb,
                record, idt, Fj):
    """``pair_partition`` for every partition, in parallel. Returns bonds broken."""
    nbroken = 0
    for p in prange(part.shape[0] - 1):
        nbroken += pair_partition(p, pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact,
                                  pslip, pdash, pestr, blk, bstate, bstep, bpos, bnrm, be,
                                  bestr, bsig, part, fbuf, prm, step, nb, record, idt, Fj)
    return nbroken


@jit
def _pair_range(pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, pslip, pdash, pestr, fb,
                k0, k1, dt, emod, ikr, fric, betan, betas, record):
    """Unbonded (Verlet) pairs k0..k1: the linear contact law (+ dashpots), scattered into
    the partition buffer ``fb`` in increasing pair order."""
    dp = betan > 0.0 or betas > 0.0
    for k in range(k0, k1):
        i = pi[k]
        j = pj[k]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        ri = radius[i]
        rj = radius[j]
        sr = ri + rj
        if dx * dx + dy * dy + dz * dz >= sr * sr and pact[k] == 0:
            # stays out of contact: no force
            if record:
                pestr[k] = 0.0
            continue
        (nx, ny, nz, gap, inv_l, ai, aj, vrx, vry, vrz, vn, dun, dusx, dusy, dusz,
         dphi) = kinematics(dx, dy, dz, vel[j, 0] - vel[i, 0], vel[j, 1] - vel[i, 1],
                            vel[j, 2] - vel[i, 2], angvel[i, 0], angvel[i, 1], angvel[i, 2],
                            angvel[j, 0], angvel[j, 1], angvel[j, 2], ri, rj, dt)
        kn, ks = linear_stiffness(ri, rj, inv_l, emod, ikr)
        iks = 1.0 / ks
        sx, sy, sz = rotate_shear(pfs[k, 0], pfs[k, 1], pfs[k, 2], nx, ny, nz, dphi)
        if gap < 0.0:
            fn = -kn * gap
            ux, uy, uz, tx, ty, tz, eslip = linear_shear(sx, sy, sz, dusx, dusy, dusz, ks, iks,
                                                         fric * fn)
            pfs[k, 0] = ux
            pfs[k, 1] = uy
            pfs[k, 2] = uz
            fx = fn * nx + ux
            fy = fn * ny + uy
            fz = fn * nz + uz
            if record:
                pestr[k] = 0.5 * fn * fn / kn + 0.5 * (ux * ux + uy * uy + uz * uz) * iks
            if dp:
                gx, gy, gz = dashpot(vrx, vry, vrz, vn, nx, ny, nz,
                                     mass[i] * mass[j] / (mass[i] + mass[j]), kn, ks, betan,
                                     betas)
                fx += gx
                fy += gy
                fz += gz
                # the dashpot force of step n acts over half of the interval before and
                # half of the interval after it: book this force's first half and the
                # previous force's second half on this interval's displacement
                pdash[k] -= 0.5 * ((gx + pdf[k, 0]) * vrx + (gy + pdf[k, 1]) * vry
                                   + (gz + pdf[k, 2]) * vrz) * dt
                pdf[k, 0] = gx
                pdf[k, 1] = gy
                pdf[k, 2] = gz
            pact[k] = 1
        else:
            # contact lost this step: the shear spring lets go of its energy (booked as
            # slip, in the step-consistent form 1/2 s_old . s_trial / ks); the last
            # dashpot force's second half-step is booked
            eslip = 0.5 * (sx * (sx - ks * dusx) + sy * (sy - ks * dusy)
                           + sz * (sz - ks * dusz)) * iks
            if dp:
                pdash[k] -= 0.5 * (pdf[k, 0] * vrx + pdf[k, 1] * vry + pdf[k, 2] * vrz) * dt
                pdf[k, 0] = 0.0
                pdf[k, 1] = 0.0
                pdf[k, 2] = 0.0
            pfs[k, 0] = 0.0
            pfs[k, 1] = 0.0
            pfs[k, 2] = 0.0
            pact[k] = 0
            if record:
                pestr[k] = 0.0
            fx = 0.0
            fy = 0.0
            fz = 0.0
        if eslip != 0.0:
            pslip[k] += eslip
        # force on j (-F on i) and moments M_j = aj n x F, M_i = -ai n x F
        cx = ny * fz - nz * fy
        cy = nz * fx - nx * fz
        cz = nx * fy - ny * fx
        fb[i, 0] -= fx
        fb[i, 1] -= fy
        fb[i, 2] -= fz
        fb[i, 3] -= ai * cx
        fb[i, 4] -= ai * cy
        fb[i, 5] -= ai * cz
        fb[j, 0] += fx
        fb[j, 1] += fy
        fb[j, 2] += fz
        fb[j, 3] += aj * cx
        fb[j, 4] += aj * cy
        fb[j, 5] += aj * cz


@jit
def _pair_range_frictionless(pos, vel, angvel, radius, pi, pj, pfs, pact, pestr, fb, k0, k1,
                             dt, emod, ikr, record, spin):
    """``_pair_range`` for friction 0 and no dashpots (the genesis relaxation), with the
    same results bit for bit: with a zero slip limit the stored shear force is always a
    signed zero, so the shear spring, the slip energy and the stored force reduce to
    zeros. The additions of those zeros are kept (``+ 0.0``; not optimised away without
    fast-math), so the force expressions round exactly as in the general kernel.

    Without ``spin`` (translation only, ``Model.set_spin``) no moments are scattered: the
    force is central, so its moment n x F is round-off, and nothing in a frictionless
    pack without bonds turns spins back into forces."""
    for k in range(k0, k1):
        i = pi[k]
        j = pj[k]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        ri = radius[i]
        rj = radius[j]
        sr = ri + rj
        if dx * dx + dy * dy + dz * dz >= sr * sr and pact[k] == 0:
            if record:
                pestr[k] = 0.0
            continue
        (nx, ny, nz, gap, inv_l, ai, aj, vrx, vry, vrz, vn, dun, dusx, dusy, dusz,
         dphi) = kinematics(dx, dy, dz, vel[j, 0] - vel[i, 0], vel[j, 1] - vel[i, 1],
                            vel[j, 2] - vel[i, 2], angvel[i, 0], angvel[i, 1], angvel[i, 2],
                            angvel[j, 0], angvel[j, 1], angvel[j, 2], ri, rj, dt)
        pfs[k, 0] = 0.0
        pfs[k, 1] = 0.0
        pfs[k, 2] = 0.0
        if gap < 0.0:
            kn, ks = linear_stiffness(ri, rj, inv_l, emod, ikr)
            fn = -kn * gap
            fx = fn * nx + 0.0
            fy = fn * ny + 0.0
            fz = fn * nz + 0.0
            if record:
                pestr[k] = 0.5 * fn * fn / kn + 0.5 * (0.0 * 0.0 + 0.0 * 0.0 + 0.0 * 0.0) / ks
            pact[k] = 1
        else:
            # contact lost this step: nothing to scatter (adding zeros leaves the
            # buffers, which never hold -0.0, unchanged)
            pact[k] = 0
            if record:
                pestr[k] = 0.0
            continue
        fb[i, 0] -= fx
        fb[i, 1] -= fy
        fb[i, 2] -= fz
        fb[j, 0] += fx
        fb[j, 1] += fy
        fb[j, 2] += fz
        if spin:
            cx = ny * fz - nz * fy
            cy = nz * fx - nx * fz
            cz = nx * fy - ny * fx
            fb[i, 3] -= ai * cx
            fb[i, 4] -= ai * cy
            fb[i, 5] -= ai * cz
            fb[j, 3] += aj * cx
            fb[j, 4] += aj * cy
            fb[j, 5] += aj * cz


# ---------------------------------------------------------------------------------------
# 2. ball-wall slots (geometry of one ball-wall contact: laws.wall_contact_geometry)
# ---------------------------------------------------------------------------------------
@jit
def wall_range(s0, s1, pos, vel, angvel, radius, mass, sb, sw, sfs, sdf, srg, sf, sm, srad,
               sslip, sdash, sestr, wtype, wpos, wnrm, wrad, wdisk, wvel, wradv, wfric, prm,
               record, idt):
    """Linear contact (+ dashpots) of ball-wall slots s0..s1 with their walls."""
    dt = idt
    emod = prm[P_EMOD]
    ikr = 1.0 / prm[P_KRATIO]
    betan = prm[P_DP_N]
    betas = prm[P_DP_S]
    for s in range(s0, s1):
        b = sb[s]
        w = sw[s]
        r = radius[b]
        gap, nx, ny, nz, ex, ey, ez, inside = wall_contact_geometry(
            pos[b, 0], pos[b, 1], pos[b, 2], r, w, wtype, wpos, wnrm, wrad, wdisk)
        gap -= srg[s]  # surface gap relative to the contact's reference gap
        if gap >= 0.0 or not inside:
            if sfs[s, 0] != 0.0 or sfs[s, 1] != 0.0 or sfs[s, 2] != 0.0:
                # contact lost: the shear spring's energy, booked as slip (see pairs)
                kn = math.pi * r * emod
                ks = kn * ikr
                vx = vel[b, 0] - wvel[w, 0] - wradv[w] * ex
                vy = vel[b, 1] - wvel[w, 1] - wradv[w] * ey
                vz = vel[b, 2] - wvel[w, 2] - wradv[w] * ez
                vnn = vx * nx + vy * ny + vz * nz
                sx, sy, sz = rotate_shear(sfs[s, 0], sfs[s, 1], sfs[s, 2], nx, ny, nz, 0.0)
                sslip[s] += 0.5 * (sx * (sx - ks * (vx - vnn * nx) * dt)
                                   + sy * (sy - ks * (vy - vnn * ny) * dt)
                                   + sz * (sz - ks * (vz - vnn * nz) * dt)) / ks
            if sdf[s, 0] != 0.0 or sdf[s, 1] != 0.0 or sdf[s, 2] != 0.0:
                vx = vel[b, 0] - wvel[w, 0] - wradv[w] * ex
                vy = vel[b, 1] - wvel[w, 1] - wradv[w] * ey
                vz = vel[b, 2] - wvel[w, 2] - wradv[w] * ez
                sdash[s] -= 0.5 * (sdf[s, 0] * vx + sdf[s, 1] * vy + sdf[s, 2] * vz) * dt
                sdf[s, 0] = 0.0
                sdf[s, 1] = 0.0
                sdf[s, 2] = 0.0
            for c in range(3):
                sfs[s, c] = 0.0
                sf[s, c] = 0.0
                sm[s, c] = 0.0
            srad[s] = 0.0
            if record:
                sestr[s] = 0.0
            continue
        a = -(r + 0.5 * (gap + srg[s]))  # contact point = x_b + a n
        wx = angvel[b, 0]
        wy = angvel[b, 1]
        wz = angvel[b, 2]
        wr = wradv[w]
        vrx = vel[b, 0] + a * (wy * nz - wz * ny) - wvel[w, 0] - wr * ex
        vry = vel[b, 1] + a * (wz * nx - wx * nz) - wvel[w, 1] - wr * ey
        vrz = vel[b, 2] + a * (wx * ny - wy * nx) - wvel[w, 2] - wr * ez
        vn = vrx * nx + vry * ny + vrz * nz
        vsx = vrx - vn * nx
        vsy = vry - vn * ny
        vsz = vrz - vn * nz
        kn = math.pi * r * emod  # pi R^2 E*/L with L = R
        ks = kn * ikr
        fn = -kn * gap
        dphi = (wx * nx + wy * ny + wz * nz) * dt * 0.5
        sx, sy, sz = rotate_shear(sfs[s, 0], sfs[s, 1], sfs[s, 2], nx, ny, nz, dphi)
        tx, ty, tz, _, _, _, eslip = linear_shear(sx, sy, sz, vsx * dt, vsy * dt, vsz * dt,
                                                  ks, 1.0 / ks, wfric[w] * fn)
        sfs[s, 0] = tx
        sfs[s, 1] = ty
        sfs[s, 2] = tz
        sslip[s] += eslip
        fx = fn * nx + tx
        fy = fn * ny + ty
        fz = fn * nz + tz
        if betan > 0.0 or betas > 0.0:
            cn = 2.0 * betan * math.sqrt(mass[b] * kn)
            cs = 2.0 * betas * math.sqrt(mass[b] * ks)
            gx = -(cn * vn * nx + cs * vsx)
            gy = -(cn * vn * ny + cs * vsy)
            gz = -(cn * vn * nz + cs * vsz)
            fx += gx
            fy += gy
            fz += gz
            sdash[s] -= 0.5 * ((gx + sdf[s, 0]) * vrx + (gy + sdf[s, 1]) * vry
                               + (gz + sdf[s, 2]) * vrz) * dt
            sdf[s, 0] = gx
            sdf[s, 1] = gy
            sdf[s, 2] = gz
        if record:
            sestr[s] = 0.5 * fn * fn / kn + 0.5 * (tx * tx + ty * ty + tz * tz) / ks
        sf[s, 0] = fx
        sf[s, 1] = fy
        sf[s, 2] = fz
        sm[s, 0] = a * (ny * fz - nz * fy)
        sm[s, 1] = a * (nz * fx - nx * fz)
        sm[s, 2] = a * (nx * fy - ny * fx)
        srad[s] = fx * ex + fy * ey + fz * ez


#: wall slots per chunk of the parallel wall loop
SLOT_CHUNK = 256


@jit_parallel
def wall_forces(pos, vel, angvel, radius, mass, sb, sw, sfs, sdf, srg, sf, sm, srad, sslip,
                sdash, sestr, wtype, wpos, wnrm, wrad, wdisk, wvel, wradv, wfric, prm, nslots,
                record, idt):
    """``wall_range`` over all slots, in parallel chunks (slots are independent)."""
    nc = (nslots + SLOT_CHUNK - 1) // SLOT_CHUNK
    for c in prange(nc):
        wall_range(c * SLOT_CHUNK, min(nslots, (c + 1) * SLOT_CHUNK), pos, vel, angvel,
                   radius, mass, sb, sw, sfs, sdf, srg, sf, sm, srad, sslip, sdash, sestr,
                   wtype, wpos, wnrm, wrad, wdisk, wvel, wradv, wfric, prm, record, idt)


# ---------------------------------------------------------------------------------------
# 3. wall resultants, rigid-body walls, wall motion and boundary work
# ---------------------------------------------------------------------------------------
@jit
def wall_resultants(sw, sf, srad, nslots, wforce, wradsum):
    """Force the balls exert on each wall (``wforce``) and the radial sum F.e_rho of the
    forces on the balls (cylinders; for the work of a moving radius)."""
    nw = wforce.shape[0]
    for w in range(nw):
        wforce[w, 0] = 0.0
        wforce[w, 1] = 0.0
        wforce[w, 2] = 0.0
        wradsum[w] = 0.0
    for s in range(nslots):
        w = sw[s]
        wforce[w, 0] -= sf[s, 0]
        wforce[w, 1] -= sf[s, 1]
        wforce[w, 2] -= sf[s, 2]
        wradsum[w] += srad[s]


@jit
def advance_walls(wpos, wrad, wvel, wradv, wmass, wforce, wradsum, wwork, wgrav, wdisp, prm):
    """Step n of the walls: rigid bodies get v_{n+1/2} = v_{n-1/2} + (F_n/M + g) dt; the
    boundary work of step n, F_n . (v_{n-1/2} + v_{n+1/2})/2 dt, is added; walls move.
    Returns the largest wall displacement since the last rebuild."""
    nw = wpos.shape[0]
    dt = prm[P_DT]
    g0 = prm[P_GX]
    g1 = prm[P_GY]
    g2 = prm[P_GZ]
    mx = 0.0
    for w in range(nw):
        a0 = wvel[w, 0]
        a1 = wvel[w, 1]
        a2 = wvel[w, 2]
        if wmass[w] > 0.0:
            m = wmass[w]
            wvel[w, 0] = a0 + (wforce[w, 0] / m + g0) * dt
            wvel[w, 1] = a1 + (wforce[w, 1] / m + g1) * dt
            wvel[w, 2] = a2 + (wforce[w, 2] / m + g2) * dt
            wgrav[w] += 0.5 * m * (g0 * (a0 + wvel[w, 0]) + g1 * (a1 + wvel[w, 1])
                                   + g2 * (a2 + wvel[w, 2])) * dt
        rv = wradv[w]
        p = wall_power(wforce, wradsum, w, a0, a1, a2, rv) + wall_power(
            wforce, wradsum, w, wvel[w, 0], wvel[w, 1], wvel[w, 2], rv)
        wwork[w] += 0.5 * p * dt
        d = 0.0
        for c in range(3):
            wpos[w, c] += wvel[w, c] * dt
            d += wvel[w, c] * wvel[w, c]
        wrad[w] += rv * dt
        wdisp[w] += (math.sqrt(d) + abs(rv)) * dt
        if wdisp[w] > mx:
            mx = wdisp[w]
    return mx


# ---------------------------------------------------------------------------------------
# 4. gather + integrate
# ---------------------------------------------------------------------------------------
@jit
def integrate_range(i0, i1, pos, vel, angvel, mass, inertia, fix, fbuf, pmask, sptr, sf, sm,
                    edamp, egrav, efix, prm):
    """Step n for balls i0..i1: gather F_n, add gravity and local damping, v_{n+1/2}, x_{n+1}.

    Per-ball accumulators get the damping dissipation, gravity work and work of velocity
    constraints of step n, each as F . (v_{n-1/2} + v_{n+1/2})/2 dt. Returns (largest
    squared speed, 1 + index of a ball whose velocity is not finite or above the speed
    guard, or 0). The largest speed bounds the displacements for the Verlet criterion, so
    the step does not read the reference positions.
    """
    dt = prm[P_DT]
    alpha = prm[P_ALPHA]
    vmax2 = prm[P_MAXSPEED] * prm[P_MAXSPEED]
    gx = prm[P_GX]
    gy = prm[P_GY]
    gz = prm[P_GZ]
    grav = gx != 0.0 or gy != 0.0 or gz != 0.0
    vcap = prm[P_VCAP]
    spin = prm[P_NOSPIN] == 0.0
    maxv2 = 0.0
    bad = 0
    for i in range(i0, i1):
        f0, f1, f2, m0, m1, m2 = gather(i, fbuf, pmask, sptr, sf, sm, True)
        mi = mass[i]
        f0 += mi * gx
        f1 += mi * gy
        f2 += mi * gz
        fl, im, ii, u0, u1, u2, w0, w1, w2 = ball_state(i, mi, inertia, fix, vel, angvel)
        n0, n1, n2, r0, r1, r2, d0, d1, d2, e0, e1, e2 = ball_update(
            u0, u1, u2, w0, w1, w2, f0, f1, f2, m0, m1, m2, im, ii, alpha, dt, fl, spin)
        s0 = 0.5 * (u0 + n0) * dt
        s1 = 0.5 * (u1 + n1) * dt
        s2 = 0.5 * (u2 + n2) * dt
        q0 = 0.5 * (w0 + r0) * dt
        q1 = 0.5 * (w1 + r1) * dt
        q2 = 0.5 * (w2 + r2) * dt
        if alpha > 0.0:
            edamp[i] -= d0 * s0 + d1 * s1 + d2 * s2 + e0 * q0 + e1 * q1 + e2 * q2
        if grav:
            egrav[i] += mi * (gx * s0 + gy * s1 + gz * s2)
        if fl:
            efix[i] -= constraint_power(fl, f0, f1, f2, m0, m1, m2, s0, s1, s2, q0, q1, q2)
        if vcap > 0.0:
            # genesis only: clip the speed (removes energy that is not booked)
            sp2 = n0 * n0 + n1 * n1 + n2 * n2
            if sp2 > vcap * vcap:
                sc = vcap / math.sqrt(sp2)
                n0 *= sc
                n1 *= sc
                n2 *= sc
        vel[i, 0] = n0
        vel[i, 1] = n1
        vel[i, 2] = n2
        angvel[i, 0] = r0
        angvel[i, 1] = r1
        angvel[i, 2] = r2
        pos[i, 0] += n0 * dt
        pos[i, 1] += n1 * dt
        pos[i, 2] += n2 * dt
        v2 = n0 * n0 + n1 * n1 + n2 * n2
        maxv2 = max(maxv2, v2)
        if not (v2 <= vmax2) or not (abs(r0) + abs(r1) + abs(r2) < 1e300):
            bad = max(bad, i + 1)
    return maxv2, bad


#: balls per chunk of the parallel integration loop
BALL_CHUNK = 1024


@jit_parallel
def integrate(pos, vel, angvel, mass, inertia, fix, fbuf, pmask, sptr, sf, sm, edamp, egrav,
              efix, prm):
    """``integrate_range`` over all balls, in parallel chunks. Returns (largest squared
    speed, 1 + largest index of a ball that blew up, or 0), as integrate_range."""
    n = pos.shape[0]
    nc = (n + BALL_CHUNK - 1) // BALL_CHUNK
    maxv2 = 0.0
    bad = 0
    for c in prange(nc):
        v2, b = integrate_range(c * BALL_CHUNK, min(n, (c + 1) * BALL_CHUNK), pos, vel, angvel,
                                mass, inertia, fix, fbuf, pmask, sptr, sf, sm, edamp, egrav,
                                efix, prm)
        maxv2 = max(maxv2, v2)
        bad = max(bad, b)
    return maxv2, bad


# ---------------------------------------------------------------------------------------
# 5. the chunk runner: numba runs the steps, Python runs chunks
# ---------------------------------------------------------------------------------------
@jit
def _forces(B, P, Bd, S, W, Fj, prm, iprm, record, idt, serial):
    """Force-displacement at the current positions; increments use velocity x ``idt``.
    ``serial``: call the kernels directly (one thread: no parallel-region overhead)."""
    if serial:
        nbk = 0
        for p in range(P.part.shape[0] - 1):
            nbk += pair_partition(p, B.pos, B.vel, B.angvel, B.radius, B.mass, P.pi, P.pj,
                                  P.fs, P.df, P.act, P.slip, P.dash, P.estr, Bd.blk, Bd.state,
                                  Bd.step, Bd.pos, Bd.nrm, Bd.energy, Bd.estr, Bd.sig, P.part,
                                  B.fbuf, prm, iprm[I_STEP], iprm[I_NB], record, idt, Fj)
        wall_range(0, iprm[I_NSLOTS], B.pos, B.vel, B.angvel, B.radius, B.mass, S.b, S.w,
                   S.fs, S.df, S.rg, S.f, S.m, S.rad, S.slip, S.dash, S.estr, W.type, W.pos,
                   W.nrm, W.rad, W.disk, W.vel, W.radv, W.fric, prm, record, idt)
    else:
        nbk = pair_forces(B.pos, B.vel, B.angvel, B.radius, B.mass, P.pi, P.pj, P.fs, P.df,
                          P.act, P.slip, P.dash, P.estr, Bd.blk, Bd.state, Bd.step, Bd.pos,
                          Bd.nrm, Bd.energy, Bd.estr, Bd.sig, P.part, B.fbuf, prm,
                          iprm[I_STEP], iprm[I_NB], record, idt, Fj)
        wall_forces(B.pos, B.vel, B.angvel, B.radius, B.mass, S.b, S.w, S.fs, S.df, S.rg, S.f,
                    S.m, S.rad, S.slip, S.dash, S.estr, W.type, W.pos, W.nrm, W.rad, W.disk,
                    W.vel, W.radv, W.fric, prm, iprm[I_NSLOTS], record, idt)
    iprm[I_NBROKEN] += nbk
    wall_resultants(S.w, S.f, S.rad, iprm[I_NSLOTS], W.force, W.radsum)


@jit
def run_steps(B, P, Bd, S, W, Fj, prm, iprm, eacc, nsteps, record_last, serial):
    """Advance ``nsteps`` steps (PFC cycle order: law of motion, then force-displacement).
    Returns (status, steps_done).

    status 0: done; 1: a capacity overflowed during a rebuild (grow and call again);
    2: a ball blew up (index + 1 in iprm[I_BAD]).
    iprm[I_FORCES]: 0 forces are current; 1 recompute them without increments (after a
    change made from Python); 2 the last step's force-displacement is still due.
    B, P, Bd, S, W, Fj: namedtuples of ball, pair, bond, slot, wall and flat-joint arrays
    (model_arrays.py).
    ``serial``: one thread; the kernels are called directly instead of through numba's
    parallel regions (same arithmetic, so the same results).
    """
    dt = prm[P_DT]
    skin = prm[P_SKIN]
    if iprm[I_FORCES] != 0:
        if iprm[I_FORCES] == 1:
            B.fbuf[:] = 0.0  # forces of the last evaluation are replaced, not added to
        if iprm[I_REBUILD]:
            if rebuild_lists(B, P, Bd, S, W, prm, iprm, eacc) != 0:
                return 1, 0
        _forces(B, P, Bd, S, W, Fj, prm, iprm, record_last and nsteps == 0,
                dt if iprm[I_FORCES] == 2 else 0.0, serial)
        iprm[I_FORCES] = 0
    for s in range(nsteps):
        if serial:
            maxv2, bad = integrate_range(0, B.pos.shape[0], B.pos, B.vel, B.angvel, B.mass,
                                         B.inertia, B.fix, B.fbuf, B.pmask, S.ptr, S.f, S.m,
                                         B.edamp, B.egrav, B.efix, prm)
        else:
            maxv2, bad = integrate(B.pos, B.vel, B.angvel, B.mass, B.inertia, B.fix, B.fbuf,
                                   B.pmask, S.ptr, S.f, S.m, B.edamp, B.egrav, B.efix, prm)
        wmax = advance_walls(W.pos, W.rad, W.vel, W.radv, W.mass, W.force, W.radsum, W.work,
                             W.grav, W.disp, prm)
        iprm[I_STEP] += 1
        prm[P_TIME] += dt
        if bad != 0:
            iprm[I_BAD] = bad
            iprm[I_FORCES] = 2
            return 2, s + 1
        # Verlet criterion: a cheap upper bound (sum of the largest speed x dt) first, the
        # exact displacement only when the bound says a rebuild may be needed
        prm[P_DBOUND] += math.sqrt(maxv2) * dt
        if 2.0 * prm[P_DBOUND] > skin or prm[P_DBOUND] + wmax > skin:
            maxd = max_displacement(B.pos, B.pos_ref)
            prm[P_DBOUND] = maxd
            if 2.0 * maxd > skin or maxd + wmax > skin:
                iprm[I_REBUILD] = 1
        if iprm[I_REBUILD]:
            if rebuild_lists(B, P, Bd, S, W, prm, iprm, eacc) != 0:
                iprm[I_FORCES] = 2
                return 1, s + 1
        _forces(B, P, Bd, S, W, Fj, prm, iprm, record_last and s == nsteps - 1, dt, serial)
    return 0, nsteps
