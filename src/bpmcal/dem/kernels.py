"""The stepping kernels: contact laws mapped over pairs and wall slots, force gathering,
central-difference integration with local damping, wall motion, energy bookkeeping.

One step, in order (positions x_n, velocities at half steps v_{n-1/2}):

1. ``pair_forces``  (parallel over ball-ball pairs): linear contact + parallel bond for
   each pair; writes the force on ball j and the moments on i and j into per-pair slots.
2. ``wall_forces``  (parallel over ball-wall slots): linear contact with each wall.
3. ``wall_sums``    (serial): resultant force of each wall, boundary work, rigid-body
   wall velocity update.
4. ``integrate``    (parallel over balls): gather the per-pair/per-slot forces in a fixed
   order (CSR), add gravity and local damping, update v_{n+1/2}, x_{n+1}.
5. walls move; the Verlet criterion is checked.

Per-pair slots + a fixed-order gather mean no atomics and results that are bitwise
identical for any number of threads.

Energy bookkeeping is consistent with the leapfrog scheme: kinetic energy at step n is
``1/2 m v_{n-1/2} . v_{n+1/2}``, strain energies are evaluated from the forces at step n,
and every incremental term (damping, gravity, boundary work, slip, dashpots, breakage)
is accumulated with the weights the integrator implies. For linear springs the balance
then closes to round-off; what remains is the (small) error of contact creation and loss
inside a step.
"""
from __future__ import annotations

import math

import numpy as np

from ._jit import jit, jit_parallel, prange
from .bondblock import (
    BLK,
    S_FN,
    S_LX,
    S_RG,
    S_SX,
    bond_range,
    state_index,
)
from .bondblock import scratch as bond_scratch
from .laws import (
    bond_geometry,
    dashpot,
    kinematics,
    linear_shear,
    linear_stiffness,
    rotate_shear,
)
from .layout import (
    BOND_INTACT,
    E_DASH,
    E_SLIP,
    E_WDASH,
    E_WSLIP,
    I_BAD,
    I_FORCES,
    I_NB,
    I_NBROKEN,
    I_NEED_C,
    I_NEED_P,
    I_NEED_W,
    I_NPAIRS,
    I_NREBUILDS,
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
    WALL_CYLINDER,
)


# ---------------------------------------------------------------------------------------
# 1. ball-ball pairs
# ---------------------------------------------------------------------------------------
@jit_parallel
def pair_forces(pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, pslip, pdash, pestr,
                blk, bstate, bstep, bpos, bnrm, be, bestr, bsig, part, fbuf, prm, step, nb,
                record, idt):
    """Force-displacement for every ball-ball pair; scatter into per-partition buffers.

    Pairs are split into fixed index ranges ``part`` (one per partition); partition p adds
    the forces and moments of its pairs to ``fbuf[p]`` (ball-major, 6 components), in
    increasing pair order. The partitions, not the threads, fix the summation order, so
    the result does not depend on the number of threads. Bond pairs (k < nb) keep their
    state in the blocked array ``blk`` (bondblock.py); the unbonded pairs use ``pfs``,
    ``pdf`` and ``pact`` (whether the pair carried force last step). Returns bonds broken.
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
    for p in prange(part.shape[0] - 1):
        T = bond_scratch()
        k0 = part[p]
        k1 = part[p + 1]
        kb = min(k1, nb)
        if kb > k0:  # bond pairs: vectorised blocks
            nbroken += bond_range(pos, vel, angvel, radius, mass, pi, pj, blk, pslip, pdash,
                                  pestr, bstate, bstep, bpos, bnrm, be, bestr, bsig, fbuf[p],
                                  k0, kb, T, dt, emod, ikr, fric, pb_emod, pb_ikr, pb_ten,
                                  pb_coh, tanfa, rmul, mcf, betan, betas, step, record)
        _pair_range(pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, pslip, pdash,
                    pestr, fbuf[p], max(k0, nb), k1, dt, emod, ikr, fric, betan, betas, record)
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


# ---------------------------------------------------------------------------------------
# 2. ball-wall slots
# ---------------------------------------------------------------------------------------
@jit
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


@jit_parallel
def wall_forces(pos, vel, angvel, radius, mass, sb, sw, sfs, sdf, srg, sf, sm, srad, sslip, sdash,
                sestr, wtype, wpos, wnrm, wrad, wdisk, wvel, wradv, wfric, prm, nslots,
                record, idt):
    dt = idt
    emod = prm[P_EMOD]
    ikr = 1.0 / prm[P_KRATIO]
    betan = prm[P_DP_N]
    betas = prm[P_DP_S]
    for s in prange(nslots):
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
def _wall_power(wforce, wradsum, w, v0, v1, v2, rv):
    """Power the wall delivers to the balls at wall velocity v (and radial velocity rv)."""
    return -(wforce[w, 0] * v0 + wforce[w, 1] * v1 + wforce[w, 2] * v2) + wradsum[w] * rv


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
        p = _wall_power(wforce, wradsum, w, a0, a1, a2, rv) + _wall_power(
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
        out[w, 1] = 0.5 * _wall_power(wforce, wradsum, w, a0, a1, a2, wradv[w]) * dt


# ---------------------------------------------------------------------------------------
# 4. gather + integrate
# ---------------------------------------------------------------------------------------
@jit
def _gather(i, fbuf, sptr, sf, sm, clear):
    """Resultant contact force and moment on ball i: the partition buffers in partition
    order, then the ball's wall slots. ``clear`` zeroes the buffers for the next step."""
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    m0 = 0.0
    m1 = 0.0
    m2 = 0.0
    for p in range(fbuf.shape[0]):
        f0 += fbuf[p, i, 0]
        f1 += fbuf[p, i, 1]
        f2 += fbuf[p, i, 2]
        m0 += fbuf[p, i, 3]
        m1 += fbuf[p, i, 4]
        m2 += fbuf[p, i, 5]
        if clear:
            for c in range(6):
                fbuf[p, i, c] = 0.0
    for s in range(sptr[i], sptr[i + 1]):
        f0 += sf[s, 0]
        f1 += sf[s, 1]
        f2 += sf[s, 2]
        m0 += sm[s, 0]
        m1 += sm[s, 1]
        m2 += sm[s, 2]
    return f0, f1, f2, m0, m1, m2


@jit
def _local_damping(f, v, alpha):
    """PFC local damping force of one degree of freedom: -alpha |F| sign(v), sign(0) = 0.
    Written with selects: the sign of a velocity is a coin toss for the branch predictor."""
    sgn = (1.0 if v > 0.0 else 0.0) - (1.0 if v < 0.0 else 0.0)
    return -alpha * abs(f) * sgn


@jit
def _dof(v, f, im, alpha, dt, fixed):
    """New half-step velocity of one degree of freedom and its damping force."""
    if fixed:
        return v, 0.0
    fd = _local_damping(f, v, alpha)
    return v + (f + fd) * im * dt, fd


@jit_parallel
def integrate(pos, vel, angvel, mass, inertia, fix, fbuf, sptr, sf, sm, edamp, egrav, efix,
              prm):
    """Step n for the balls: gather F_n, add gravity and local damping, v_{n+1/2}, x_{n+1}.

    Per-ball accumulators get the damping dissipation, gravity work and work of velocity
    constraints of step n, each as F . (v_{n-1/2} + v_{n+1/2})/2 dt. Returns (largest
    squared speed, 1 + index of a ball whose velocity is not finite or above the speed
    guard, or 0). The largest speed bounds the displacements for the Verlet criterion, so
    the step does not read the reference positions.
    """
    n = pos.shape[0]
    dt = prm[P_DT]
    alpha = prm[P_ALPHA]
    vmax2 = prm[P_MAXSPEED] * prm[P_MAXSPEED]
    gx = prm[P_GX]
    gy = prm[P_GY]
    gz = prm[P_GZ]
    grav = gx != 0.0 or gy != 0.0 or gz != 0.0
    vcap = prm[P_VCAP]
    maxv2 = 0.0
    bad = 0
    for i in prange(n):
        f0, f1, f2, m0, m1, m2 = _gather(i, fbuf, sptr, sf, sm, True)
        mi = mass[i]
        f0 += mi * gx
        f1 += mi * gy
        f2 += mi * gz
        fl = fix[i]
        im = 1.0 / mi
        ii = 1.0 / inertia[i]
        u0 = vel[i, 0]
        u1 = vel[i, 1]
        u2 = vel[i, 2]
        w0 = angvel[i, 0]
        w1 = angvel[i, 1]
        w2 = angvel[i, 2]
        n0, d0 = _dof(u0, f0, im, alpha, dt, fl & 1)
        n1, d1 = _dof(u1, f1, im, alpha, dt, fl & 2)
        n2, d2 = _dof(u2, f2, im, alpha, dt, fl & 4)
        r0, e0 = _dof(w0, m0, ii, alpha, dt, fl & 8)
        r1, e1 = _dof(w1, m1, ii, alpha, dt, fl & 16)
        r2, e2 = _dof(w2, m2, ii, alpha, dt, fl & 32)
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
            cw = 0.0
            if fl & 1:
                cw += f0 * s0
            if fl & 2:
                cw += f1 * s1
            if fl & 4:
                cw += f2 * s2
            if fl & 8:
                cw += m0 * q0
            if fl & 16:
                cw += m1 * q1
            if fl & 32:
                cw += m2 * q2
            efix[i] -= cw
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


@jit
def max_displacement(pos, pos_ref):
    """Largest ball displacement since the last rebuild [m]."""
    m = 0.0
    for i in range(pos.shape[0]):
        d = 0.0
        for c in range(3):
            x = pos[i, c] - pos_ref[i, c]
            d += x * x
        m = max(m, d)
    return math.sqrt(m)


@jit
def measure_balls(vel, angvel, force, moment, mass, inertia, fix, fbuf, sptr, sf, sm, prm):
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
    kin = 0.0
    dmp = 0.0
    grv = 0.0
    cst = 0.0
    for i in range(n):
        f0, f1, f2, m0, m1, m2 = _gather(i, fbuf, sptr, sf, sm, False)
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
        fl = fix[i]
        im = 1.0 / mi
        ii = 1.0 / inertia[i]
        u0 = vel[i, 0]
        u1 = vel[i, 1]
        u2 = vel[i, 2]
        w0 = angvel[i, 0]
        w1 = angvel[i, 1]
        w2 = angvel[i, 2]
        n0, d0 = _dof(u0, f0, im, alpha, dt, fl & 1)
        n1, d1 = _dof(u1, f1, im, alpha, dt, fl & 2)
        n2, d2 = _dof(u2, f2, im, alpha, dt, fl & 4)
        r0, e0 = _dof(w0, m0, ii, alpha, dt, fl & 8)
        r1, e1 = _dof(w1, m1, ii, alpha, dt, fl & 16)
        r2, e2 = _dof(w2, m2, ii, alpha, dt, fl & 32)
        kin += 0.5 * mi * (u0 * n0 + u1 * n1 + u2 * n2) + 0.5 * inertia[i] * (
            w0 * r0 + w1 * r1 + w2 * r2)
        h = 0.5 * dt
        dmp -= (d0 * u0 + d1 * u1 + d2 * u2 + e0 * w0 + e1 * w1 + e2 * w2) * h
        grv += mi * (gx * u0 + gy * u1 + gz * u2) * h
        if fl:
            cw = 0.0
            if fl & 1:
                cw += f0 * u0
            if fl & 2:
                cw += f1 * u1
            if fl & 4:
                cw += f2 * u2
            if fl & 8:
                cw += m0 * w0
            if fl & 16:
                cw += m1 * w1
            if fl & 32:
                cw += m2 * w2
            cst -= cw * h
    return kin, dmp, grv, cst


# ---------------------------------------------------------------------------------------
# 5. neighbour lists (cell grid + Verlet skin) with history carried across rebuilds
# ---------------------------------------------------------------------------------------
@jit
def _cell_grid(pos, radius, skin, ncap):
    """Bin balls into a uniform grid of cells at least 2 Rmax + skin wide."""
    n = pos.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for c in range(3):
        lo[c] = pos[0, c]
        hi[c] = pos[0, c]
    rmax = 0.0
    for i in range(n):
        for c in range(3):
            x = pos[i, c]
            if x < lo[c]:
                lo[c] = x
            if x > hi[c]:
                hi[c] = x
        if radius[i] > rmax:
            rmax = radius[i]
    cs = 2.0 * rmax + skin
    dims = np.empty(3, np.int64)
    while True:
        tot = 1
        for c in range(3):
            dims[c] = int((hi[c] - lo[c]) / cs) + 1
            tot *= dims[c]
        if tot <= ncap:
            break
        cs *= 1.25
    ncell = dims[0] * dims[1] * dims[2]
    cell = np.empty(n, np.int64)
    start = np.zeros(ncell + 1, np.int64)
    for i in range(n):
        ic = 0
        for c in range(3):
            q = int((pos[i, c] - lo[c]) / cs)
            if q >= dims[c]:
                q = dims[c] - 1
            if q < 0:
                q = 0
            ic = ic * dims[c] + q
        cell[i] = ic
        start[ic + 1] += 1
    for c in range(ncell):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return cell, start, order, dims


#: cost of an unbonded (Verlet) pair relative to a bond pair, for balancing partitions
VERLET_COST = 0.15


@jit
def set_partitions(part, npairs, nb):
    """Split pairs 0..npairs into len(part)-1 contiguous ranges of about equal work (a
    Verlet pair costs ``VERLET_COST`` of a bond pair); boundaries inside the bond pairs
    fall on block boundaries (bondblock.BLK)."""
    npart = part.shape[0] - 1
    work = nb + VERLET_COST * (npairs - nb)
    part[0] = 0
    part[npart] = npairs
    for p in range(1, npart):
        target = work * p / npart
        if target <= nb:
            b = int(target)
            b = (b // BLK) * BLK
        else:
            b = nb + int((target - nb) / VERLET_COST)
        part[p] = min(max(b, part[p - 1]), npairs)


@jit
def _bonded(i, j, bptr, bpart):
    for e in range(bptr[i], bptr[i + 1]):
        if bpart[e] == j:
            return True
    return False


@jit
def rebuild(pos, radius, pos_ref, pi, pj, pfs, pdf, pact, pslip, pdash, vptr, bptr, bpart,
            pi2, pj2, pfs2, vptr2, cand, part, sb, sw, sfs, sdf, srg, sslip, sdash, sptr, sb2,
            sw2, sfs2, sptr2, wtype, wpos, wnrm, wrad, wdisk, wdisp, prm, iprm, eacc):
    """Rebuild the Verlet pair list and the ball-wall slots; carry contact history over.

    Bond pairs (the first nb entries) are permanent and not searched. A new Verlet pair
    (i, j) inherits the shear force of the same pair in the previous list. Returns 0, or
    1 when a capacity is exceeded (nothing is modified then; the needed sizes are in
    iprm[I_NEED_P], iprm[I_NEED_W], iprm[I_NEED_C]).
    """
    n = pos.shape[0]
    skin = prm[P_SKIN]
    nb = iprm[I_NB]
    npo = iprm[I_NPAIRS]
    cap = pi.shape[0]
    cell, start, order, dims = _cell_grid(pos, radius, skin, 4 * n + 64)
    d0 = dims[0]
    d1 = dims[1]
    d2 = dims[2]
    cnt = nb
    ccap = cand.shape[0]
    cmax = 0
    for i in range(n):
        ic = cell[i]
        cz = ic % d2
        cy = (ic // d2) % d1
        cx = ic // (d1 * d2)
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        ri = radius[i]
        nc = 0
        for ox in range(-1, 2):
            qx = cx + ox
            if qx < 0 or qx >= d0:
                continue
            for oy in range(-1, 2):
                qy = cy + oy
                if qy < 0 or qy >= d1:
                    continue
                for oz in range(-1, 2):
                    qz = cz + oz
                    if qz < 0 or qz >= d2:
                        continue
                    q = (qx * d1 + qy) * d2 + qz
                    for e in range(start[q], start[q + 1]):
                        j = order[e]
                        if j <= i:
                            continue
                        dx = pos[j, 0] - xi
                        dy = pos[j, 1] - yi
                        dz = pos[j, 2] - zi
                        lim = ri + radius[j] + skin
                        if dx * dx + dy * dy + dz * dz < lim * lim:
                            if not _bonded(i, j, bptr, bpart):
                                if nc < ccap:
                                    cand[nc] = j
                                nc += 1
        if nc > cmax:
            cmax = nc
        if nc > ccap:
            continue
        # insertion sort: pairs of a row in increasing j (deterministic order)
        for a in range(1, nc):
            v = cand[a]
            b = a - 1
            while b >= 0 and cand[b] > v:
                cand[b + 1] = cand[b]
                b -= 1
            cand[b + 1] = v
        vptr2[i] = cnt
        for a in range(nc):
            j = cand[a]
            if cnt < cap:
                pi2[cnt] = i
                pj2[cnt] = j
                for c in range(6):
                    pfs2[cnt, c] = 0.0
                for e in range(vptr[i], vptr[i + 1]):
                    if pj[e] == j:
                        for c in range(3):
                            pfs2[cnt, c] = pfs[e, c]
                            pfs2[cnt, 3 + c] = pdf[e, c]
                        break
            cnt += 1
    vptr2[n] = cnt
    # ball-wall slots
    nw = wtype.shape[0]
    wcap = sb.shape[0]
    ns = 0
    for i in range(n):
        sptr2[i] = ns
        for w in range(nw):
            gap, nx, ny, nz, ex, ey, ez, inside = wall_contact_geometry(
                pos[i, 0], pos[i, 1], pos[i, 2], radius[i], w, wtype, wpos, wnrm, wrad,
                wdisk)
            if gap < skin:
                if ns < wcap:
                    sb2[ns] = i
                    sw2[ns] = w
                    for c in range(7):
                        sfs2[ns, c] = 0.0
                    for e in range(sptr[i], sptr[i + 1]):
                        if sw[e] == w:
                            for c in range(3):
                                sfs2[ns, c] = sfs[e, c]
                                sfs2[ns, 3 + c] = sdf[e, c]
                            sfs2[ns, 6] = srg[e]
                            break
                ns += 1
    sptr2[n] = ns
    if cnt > cap or ns > wcap or cmax > ccap:
        iprm[I_NEED_P] = cnt
        iprm[I_NEED_W] = ns
        iprm[I_NEED_C] = cmax
        return 1
    # commit: fold the energy of the old Verlet pairs/slots, install the new lists
    for k in range(nb, npo):
        eacc[E_SLIP] += pslip[k]
        eacc[E_DASH] += pdash[k]
    for s in range(iprm[I_NSLOTS]):
        eacc[E_WSLIP] += sslip[s]
        eacc[E_WDASH] += sdash[s]
    for k in range(nb, cnt):
        pi[k] = pi2[k]
        pj[k] = pj2[k]
        for c in range(3):
            pfs[k, c] = pfs2[k, c]
            pdf[k, c] = pfs2[k, 3 + c]
        pact[k] = 1
        pslip[k] = 0.0
        pdash[k] = 0.0
    for i in range(n + 1):
        vptr[i] = vptr2[i]
        sptr[i] = sptr2[i]
    for s in range(ns):
        sb[s] = sb2[s]
        sw[s] = sw2[s]
        for c in range(3):
            sfs[s, c] = sfs2[s, c]
            sdf[s, c] = sfs2[s, 3 + c]
        srg[s] = sfs2[s, 6]
        sslip[s] = 0.0
        sdash[s] = 0.0
    iprm[I_NPAIRS] = cnt
    iprm[I_NSLOTS] = ns
    set_partitions(part, cnt, nb)
    for i in range(n):
        for c in range(3):
            pos_ref[i, c] = pos[i, c]
    for w in range(nw):
        wdisp[w] = 0.0
    prm[P_DBOUND] = 0.0
    iprm[I_REBUILD] = 0
    iprm[I_NREBUILDS] += 1
    return 0


# ---------------------------------------------------------------------------------------
# 6. the chunk runner: numba runs the steps, Python runs chunks
# ---------------------------------------------------------------------------------------
@jit
def _rebuild(B, P, Bd, S, W, prm, iprm, eacc):
    return rebuild(B.pos, B.radius, B.pos_ref, P.pi, P.pj, P.fs, P.df, P.act, P.slip, P.dash,
                   P.vptr, Bd.ptr, Bd.part, P.pi2, P.pj2, P.fs2, P.vptr2, P.cand, P.part,
                   S.b, S.w, S.fs, S.df, S.rg, S.slip, S.dash, S.ptr, S.b2, S.w2, S.fs2,
                   S.ptr2, W.type,
                   W.pos, W.nrm, W.rad, W.disk, W.disp, prm, iprm, eacc)


@jit
def _forces(B, P, Bd, S, W, prm, iprm, record, idt):
    """Force-displacement at the current positions; increments use velocity x ``idt``."""
    nbk = pair_forces(B.pos, B.vel, B.angvel, B.radius, B.mass, P.pi, P.pj, P.fs, P.df, P.act,
                      P.slip, P.dash, P.estr, Bd.blk, Bd.state, Bd.step, Bd.pos, Bd.nrm,
                      Bd.energy, Bd.estr, Bd.sig, P.part, B.fbuf, prm, iprm[I_STEP],
                      iprm[I_NB], record, idt)
    iprm[I_NBROKEN] += nbk
    wall_forces(B.pos, B.vel, B.angvel, B.radius, B.mass, S.b, S.w, S.fs, S.df, S.rg, S.f, S.m,
                S.rad,
                S.slip, S.dash, S.estr, W.type, W.pos, W.nrm, W.rad, W.disk, W.vel, W.radv,
                W.fric, prm, iprm[I_NSLOTS], record, idt)
    wall_resultants(S.w, S.f, S.rad, iprm[I_NSLOTS], W.force, W.radsum)


@jit
def run_steps(B, P, Bd, S, W, prm, iprm, eacc, nsteps, record_last):
    """Advance ``nsteps`` steps (PFC cycle order: law of motion, then force-displacement).
    Returns (status, steps_done).

    status 0: done; 1: a capacity overflowed during a rebuild (grow and call again);
    2: a ball blew up (index + 1 in iprm[I_BAD]).
    iprm[I_FORCES]: 0 forces are current; 1 recompute them without increments (after a
    change made from Python); 2 the last step's force-displacement is still due.
    B, P, Bd, S, W: namedtuples of ball, pair, bond, slot and wall arrays (model.py).
    """
    dt = prm[P_DT]
    skin = prm[P_SKIN]
    if iprm[I_FORCES] != 0:
        if iprm[I_FORCES] == 1:
            B.fbuf[:] = 0.0  # forces of the last evaluation are replaced, not added to
        if iprm[I_REBUILD]:
            if _rebuild(B, P, Bd, S, W, prm, iprm, eacc) != 0:
                return 1, 0
        _forces(B, P, Bd, S, W, prm, iprm, record_last and nsteps == 0,
                dt if iprm[I_FORCES] == 2 else 0.0)
        iprm[I_FORCES] = 0
    for s in range(nsteps):
        maxv2, bad = integrate(B.pos, B.vel, B.angvel, B.mass, B.inertia, B.fix, B.fbuf,
                               S.ptr, S.f, S.m, B.edamp, B.egrav, B.efix, prm)
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
            if _rebuild(B, P, Bd, S, W, prm, iprm, eacc) != 0:
                iprm[I_FORCES] = 2
                return 1, s + 1
        _forces(B, P, Bd, S, W, prm, iprm, record_last and s == nsteps - 1, dt)
    return 0, nsteps


# ---------------------------------------------------------------------------------------
# 7. measurements that are not needed every step
# ---------------------------------------------------------------------------------------
@jit
def stiffness_timestep(radius, mass, inertia, fix, pi, pj, npairs, nb, bstate, sb, nslots,
                       prm):
    """PFC-style critical timestep: min over balls of sqrt(m/k_tran), sqrt(I/k_rot).

    k_tran sums kn + kn_bar A (using max(kn, ks) and max of the bond stiffnesses) over
    every pair in the neighbour list (in contact or within the skin, so contacts about
    to form are counted) and the wall slots; k_rot sums ks a^2 (+ ks_bar A a^2 +
    max(ks_bar J, kn_bar I)). Returns (dt_crit, index of the limiting ball).
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
        if k < nb and bstate[k] == BOND_INTACT:
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
    best = np.inf
    arg = -1
    for i in range(n):
        if fix[i] == 63:
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
                 sestr, sslip, sdash, nslots, eacc):
    """Totals of the per-ball / per-pair / per-slot energy slots (fixed order).

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
        if bstate[k] == BOND_INTACT:
            bond += bestr[k]
        else:
            rel += be[k]
    return lin, bond, slip, dash, damp, grav, fixw, rel


@jit
def contact_force_mean(pos, radius, pi, pj, pfs, npairs, nb, bstate, blk, prm):
    """Mean magnitude of the force of active pairs (linear contact or intact bond),
    recomputed from the stored state (dashpot forces excluded)."""
    emod = prm[P_EMOD]
    tot = 0.0
    cnt = 0
    for k in range(npairs):
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
