"""Bond pairs in SIMD-friendly blocks: gather -> branch-free compute -> ordered scatter.

The bond pairs (the first ``nb`` pairs, permanent) dominate the work of a bonded
specimen. They are processed in blocks of ``BLK`` pairs:

1. ``_gather``: the inputs of each pair (relative position and velocity, spins, radii,
   masses, bond and contact state) are copied into one flat scratch array ``T``;
2. ``_compute``: the linear contact + parallel-bond law (the same physics as
   ``kernels._pair_range``; see ``laws.py``) is evaluated for every lane without
   branches, reading and writing ``T`` only. Field offsets are compile-time constants
   at least ``BLK`` apart, so LLVM can prove the lanes independent and vectorises the
   loop (no aliasing between arguments to rule out);
3. ``_scatter``: state written back and forces/moments added to the partition buffer in
   increasing pair order (the same order as the scalar path, so results do not depend on
   the block size); the rare events (bond breaks) are recorded here.

Every lane computes in IEEE double precision with the same operations as the scalar
code; vectorisation does not change the results.
"""
from __future__ import annotations

import math

import numpy as np

from ._jit import jit
from .layout import BOND_INTACT

BLK = 64  # lanes per block

# ---- input fields (T[F * BLK + lane]) --------------------------------------------------
_I = iter(range(200))
F_DX, F_DY, F_DZ = next(_I), next(_I), next(_I)
F_VX, F_VY, F_VZ = next(_I), next(_I), next(_I)
F_WIX, F_WIY, F_WIZ = next(_I), next(_I), next(_I)
F_WJX, F_WJY, F_WJZ = next(_I), next(_I), next(_I)
F_RI, F_RJ, F_MI, F_MJ = next(_I), next(_I), next(_I), next(_I)
F_FN, F_SX, F_SY, F_SZ = next(_I), next(_I), next(_I), next(_I)  # bond normal/shear force
F_MT, F_BX, F_BY, F_BZ = next(_I), next(_I), next(_I), next(_I)  # bond twist/bending moment
F_LX, F_LY, F_LZ = next(_I), next(_I), next(_I)  # linear shear force
F_DFX, F_DFY, F_DFZ = next(_I), next(_I), next(_I)  # previous dashpot force
F_RG, F_INTACT, F_WASACT = next(_I), next(_I), next(_I)
# ---- outputs ---------------------------------------------------------------------------
O_FX, O_FY, O_FZ = next(_I), next(_I), next(_I)  # force on j
O_MIX, O_MIY, O_MIZ = next(_I), next(_I), next(_I)
O_MJX, O_MJY, O_MJZ = next(_I), next(_I), next(_I)
O_FN, O_SX, O_SY, O_SZ = next(_I), next(_I), next(_I), next(_I)
O_MT, O_BX, O_BY, O_BZ = next(_I), next(_I), next(_I), next(_I)
O_LX, O_LY, O_LZ = next(_I), next(_I), next(_I)
O_DFX, O_DFY, O_DFZ = next(_I), next(_I), next(_I)
O_ESLIP, O_EDASH, O_ELIN, O_EBOND = next(_I), next(_I), next(_I), next(_I)
O_MODE, O_ACT = next(_I), next(_I)
O_NX, O_NY, O_NZ, O_AI = next(_I), next(_I), next(_I), next(_I)
# the failing trial state (only meaningful where O_MODE > 0)
O_TFN, O_TSX, O_TSY, O_TSZ = next(_I), next(_I), next(_I), next(_I)
O_TMT, O_TBX, O_TBY, O_TBZ = next(_I), next(_I), next(_I), next(_I)
O_R0X, O_R0Y, O_R0Z = next(_I), next(_I), next(_I)  # rotated old bond shear force
O_Q0X, O_Q0Y, O_Q0Z = next(_I), next(_I), next(_I)  # rotated old bending moment
NF = next(_I)
del _I


@jit
def scratch():
    """A scratch block for one partition."""
    return np.empty(NF * BLK)


@jit
def _gather(pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, bfn, bfs, bmt, bmb,
            bstate, brgap, k0, nl, T):
    for ll in range(nl):
        k = k0 + ll
        i = pi[k]
        j = pj[k]
        T[F_DX * BLK + ll] = pos[j, 0] - pos[i, 0]
        T[F_DY * BLK + ll] = pos[j, 1] - pos[i, 1]
        T[F_DZ * BLK + ll] = pos[j, 2] - pos[i, 2]
        T[F_VX * BLK + ll] = vel[j, 0] - vel[i, 0]
        T[F_VY * BLK + ll] = vel[j, 1] - vel[i, 1]
        T[F_VZ * BLK + ll] = vel[j, 2] - vel[i, 2]
        T[F_WIX * BLK + ll] = angvel[i, 0]
        T[F_WIY * BLK + ll] = angvel[i, 1]
        T[F_WIZ * BLK + ll] = angvel[i, 2]
        T[F_WJX * BLK + ll] = angvel[j, 0]
        T[F_WJY * BLK + ll] = angvel[j, 1]
        T[F_WJZ * BLK + ll] = angvel[j, 2]
        T[F_RI * BLK + ll] = radius[i]
        T[F_RJ * BLK + ll] = radius[j]
        T[F_MI * BLK + ll] = mass[i]
        T[F_MJ * BLK + ll] = mass[j]
        T[F_FN * BLK + ll] = bfn[k]
        T[F_SX * BLK + ll] = bfs[k, 0]
        T[F_SY * BLK + ll] = bfs[k, 1]
        T[F_SZ * BLK + ll] = bfs[k, 2]
        T[F_MT * BLK + ll] = bmt[k]
        T[F_BX * BLK + ll] = bmb[k, 0]
        T[F_BY * BLK + ll] = bmb[k, 1]
        T[F_BZ * BLK + ll] = bmb[k, 2]
        T[F_LX * BLK + ll] = pfs[k, 0]
        T[F_LY * BLK + ll] = pfs[k, 1]
        T[F_LZ * BLK + ll] = pfs[k, 2]
        T[F_DFX * BLK + ll] = pdf[k, 0]
        T[F_DFY * BLK + ll] = pdf[k, 1]
        T[F_DFZ * BLK + ll] = pdf[k, 2]
        T[F_RG * BLK + ll] = brgap[k]
        T[F_INTACT * BLK + ll] = 1.0 if bstate[k] == BOND_INTACT else 0.0
        T[F_WASACT * BLK + ll] = 1.0 if pact[k] else 0.0


@jit
def _compute(T, nl, dt, emod, ikr, fric, pb_emod, pb_ikr, pb_ten, pb_coh, tanfa, rmul, mcf,
             betan, betas, dp):
    """Branch-free linear + parallel-bond law for every lane (see laws.py/kernels.py)."""
    for ll in range(nl):
        dx = T[F_DX * BLK + ll]
        dy = T[F_DY * BLK + ll]
        dz = T[F_DZ * BLK + ll]
        ri = T[F_RI * BLK + ll]
        rj = T[F_RJ * BLK + ll]
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
        wix = T[F_WIX * BLK + ll]
        wiy = T[F_WIY * BLK + ll]
        wiz = T[F_WIZ * BLK + ll]
        wjx = T[F_WJX * BLK + ll]
        wjy = T[F_WJY * BLK + ll]
        wjz = T[F_WJZ * BLK + ll]
        vrx = T[F_VX * BLK + ll] + aj * (wjy * nz - wjz * ny) - ai * (wiy * nz - wiz * ny)
        vry = T[F_VY * BLK + ll] + aj * (wjz * nx - wjx * nz) - ai * (wiz * nx - wix * nz)
        vrz = T[F_VZ * BLK + ll] + aj * (wjx * ny - wjy * nx) - ai * (wix * ny - wiy * nx)
        vn = vrx * nx + vry * ny + vrz * nz
        vsx = vrx - vn * nx
        vsy = vry - vn * ny
        vsz = vrz - vn * nz
        dun = vn * dt
        dusx = vsx * dt
        dusy = vsy * dt
        dusz = vsz * dt
        dphi = 0.5 * ((wix + wjx) * nx + (wiy + wjy) * ny + (wiz + wjz) * nz) * dt
        r = min(ri, rj)
        # ---- linear component
        kn = math.pi * r * r * emod * inv_l
        ks = kn * ikr
        rg = T[F_RG * BLK + ll]
        lact = gap < rg
        fn = kn * max(rg - gap, 0.0)
        sx = T[F_LX * BLK + ll]
        sy = T[F_LY * BLK + ll]
        sz = T[F_LZ * BLK + ll]
        d = sx * nx + sy * ny + sz * nz
        sx -= d * nx
        sy -= d * ny
        sz -= d * nz
        cx = ny * sz - nz * sy
        cy = nz * sx - nx * sz
        cz = nx * sy - ny * sx
        sx += dphi * cx
        sy += dphi * cy
        sz += dphi * cz
        tx = sx - ks * dusx
        ty = sy - ks * dusy
        tz = sz - ks * dusz
        tt = tx * tx + ty * ty + tz * tz
        lim = fric * fn
        slip = tt > lim * lim
        sc = lim / math.sqrt(max(tt, 1e-300)) if slip else 1.0
        ux = tx * sc
        uy = ty * sc
        uz = tz * sc
        iks = 1.0 / ks
        # slip energy -1/2 (s + u).(dus - (s - u)/ks); contact lost: 1/2 s.t/ks
        eslip_s = -0.5 * ((sx + ux) * (dusx - (sx - ux) * iks)
                          + (sy + uy) * (dusy - (sy - uy) * iks)
                          + (sz + uz) * (dusz - (sz - uz) * iks))
        elost = 0.5 * (sx * tx + sy * ty + sz * tz) * iks
        wasact = T[F_WASACT * BLK + ll] > 0.0
        eslip = (eslip_s if slip else 0.0) if lact else (elost if wasact else 0.0)
        ux = ux if lact else 0.0
        uy = uy if lact else 0.0
        uz = uz if lact else 0.0
        fx = fn * nx + ux
        fy = fn * ny + uy
        fz = fn * nz + uz
        elin = 0.5 * fn * fn / kn + 0.5 * (ux * ux + uy * uy + uz * uz) * iks
        # ---- dashpots (loop-invariant switch)
        gx = 0.0
        gy = 0.0
        gz = 0.0
        edash = 0.0
        if dp:
            mi = T[F_MI * BLK + ll]
            mj = T[F_MJ * BLK + ll]
            mc = mi * mj / (mi + mj)
            cn = 2.0 * betan * math.sqrt(mc * kn)
            cs = 2.0 * betas * math.sqrt(mc * ks)
            gx = -(cn * vn * nx + cs * vsx) if lact else 0.0
            gy = -(cn * vn * ny + cs * vsy) if lact else 0.0
            gz = -(cn * vn * nz + cs * vsz) if lact else 0.0
            edash = -0.5 * ((gx + T[F_DFX * BLK + ll]) * vrx + (gy + T[F_DFY * BLK + ll]) * vry
                            + (gz + T[F_DFZ * BLK + ll]) * vrz) * dt
            fx += gx
            fy += gy
            fz += gz
        # ---- parallel bond
        rb = rmul * r
        area = math.pi * rb * rb
        inertia = 0.25 * area * rb * rb
        knb = pb_emod * inv_l
        ksb = knb * pb_ikr
        kna = knb * area
        ksa = ksb * area
        ksj = ksb * 2.0 * inertia
        kni = knb * inertia
        fnb = T[F_FN * BLK + ll] + kna * dun
        ax = T[F_SX * BLK + ll]
        ay = T[F_SY * BLK + ll]
        az = T[F_SZ * BLK + ll]
        d = ax * nx + ay * ny + az * nz
        ax -= d * nx
        ay -= d * ny
        az -= d * nz
        cx = ny * az - nz * ay
        cy = nz * ax - nx * az
        cz = nx * ay - ny * ax
        ax += dphi * cx
        ay += dphi * cy
        az += dphi * cz
        sbx = ax - ksa * dusx
        sby = ay - ksa * dusy
        sbz = az - ksa * dusz
        thx = (wjx - wix) * dt
        thy = (wjy - wiy) * dt
        thz = (wjz - wiz) * dt
        tht = thx * nx + thy * ny + thz * nz
        mt = T[F_MT * BLK + ll] - ksj * tht
        bx = T[F_BX * BLK + ll]
        by = T[F_BY * BLK + ll]
        bz = T[F_BZ * BLK + ll]
        d = bx * nx + by * ny + bz * nz
        bx -= d * nx
        by -= d * ny
        bz -= d * nz
        cx = ny * bz - nz * by
        cy = nz * bx - nx * bz
        cz = nx * by - ny * bx
        bx += dphi * cx
        by += dphi * cy
        bz += dphi * cz
        mbx = bx - kni * (thx - tht * nx)
        mby = by - kni * (thy - tht * ny)
        mbz = bz - kni * (thz - tht * nz)
        smag = math.sqrt(sbx * sbx + sby * sby + sbz * sbz)
        mbmag = math.sqrt(mbx * mbx + mby * mby + mbz * mbz)
        intact = T[F_INTACT * BLK + ll] > 0.0
        tens = fnb * rb + 4.0 * mcf * mbmag >= pb_ten * area * rb
        shear = smag * rb + 2.0 * mcf * abs(mt) >= (pb_coh * area - fnb * tanfa) * rb
        mode = (1.0 if tens else (2.0 if shear else 0.0)) if intact else 0.0
        keep = intact and mode == 0.0
        kfn = fnb if keep else 0.0
        ksx = sbx if keep else 0.0
        ksy = sby if keep else 0.0
        ksz = sbz if keep else 0.0
        kmt = mt if keep else 0.0
        kbx = mbx if keep else 0.0
        kby = mby if keep else 0.0
        kbz = mbz if keep else 0.0
        fx += ksx - kfn * nx
        fy += ksy - kfn * ny
        fz += ksz - kfn * nz
        cpx = kmt * nx + kbx
        cpy = kmt * ny + kby
        cpz = kmt * nz + kbz
        ebond = 0.5 * (kfn * kfn / kna + (ksx * ksx + ksy * ksy + ksz * ksz) / ksa
                       + kmt * kmt / ksj + (kbx * kbx + kby * kby + kbz * kbz) / kni)
        # ---- moments: M_j = aj n x F + couple, M_i = -ai n x F - couple
        cx = ny * fz - nz * fy
        cy = nz * fx - nx * fz
        cz = nx * fy - ny * fx
        T[O_FX * BLK + ll] = fx
        T[O_FY * BLK + ll] = fy
        T[O_FZ * BLK + ll] = fz
        T[O_MJX * BLK + ll] = aj * cx + cpx
        T[O_MJY * BLK + ll] = aj * cy + cpy
        T[O_MJZ * BLK + ll] = aj * cz + cpz
        T[O_MIX * BLK + ll] = -ai * cx - cpx
        T[O_MIY * BLK + ll] = -ai * cy - cpy
        T[O_MIZ * BLK + ll] = -ai * cz - cpz
        T[O_FN * BLK + ll] = kfn
        T[O_SX * BLK + ll] = ksx
        T[O_SY * BLK + ll] = ksy
        T[O_SZ * BLK + ll] = ksz
        T[O_MT * BLK + ll] = kmt
        T[O_BX * BLK + ll] = kbx
        T[O_BY * BLK + ll] = kby
        T[O_BZ * BLK + ll] = kbz
        T[O_LX * BLK + ll] = ux
        T[O_LY * BLK + ll] = uy
        T[O_LZ * BLK + ll] = uz
        T[O_DFX * BLK + ll] = gx
        T[O_DFY * BLK + ll] = gy
        T[O_DFZ * BLK + ll] = gz
        T[O_ESLIP * BLK + ll] = eslip
        T[O_EDASH * BLK + ll] = edash
        T[O_ELIN * BLK + ll] = elin if lact else 0.0
        T[O_EBOND * BLK + ll] = ebond
        T[O_MODE * BLK + ll] = mode
        T[O_ACT * BLK + ll] = 1.0 if (lact or intact) else 0.0
        T[O_NX * BLK + ll] = nx
        T[O_NY * BLK + ll] = ny
        T[O_NZ * BLK + ll] = nz
        T[O_AI * BLK + ll] = ai
        T[O_TFN * BLK + ll] = fnb
        T[O_TSX * BLK + ll] = sbx
        T[O_TSY * BLK + ll] = sby
        T[O_TSZ * BLK + ll] = sbz
        T[O_TMT * BLK + ll] = mt
        T[O_TBX * BLK + ll] = mbx
        T[O_TBY * BLK + ll] = mby
        T[O_TBZ * BLK + ll] = mbz
        T[O_R0X * BLK + ll] = ax
        T[O_R0Y * BLK + ll] = ay
        T[O_R0Z * BLK + ll] = az
        T[O_Q0X * BLK + ll] = bx
        T[O_Q0Y * BLK + ll] = by
        T[O_Q0Z * BLK + ll] = bz


@jit
def _scatter(T, k0, nl, pos, radius, pi, pj, pfs, pdf, pact, pslip, pdash, pestr, bfn, bfs,
             bmt, bmb, bstate, bstep, bpos, bnrm, be, bestr, bsig, fb, step, record, dp,
             pb_emod, pb_ikr, rmul, mcf):
    nbroken = 0
    for ll in range(nl):
        k = k0 + ll
        i = pi[k]
        j = pj[k]
        fx = T[O_FX * BLK + ll]
        fy = T[O_FY * BLK + ll]
        fz = T[O_FZ * BLK + ll]
        fb[i, 0] -= fx
        fb[i, 1] -= fy
        fb[i, 2] -= fz
        fb[i, 3] += T[O_MIX * BLK + ll]
        fb[i, 4] += T[O_MIY * BLK + ll]
        fb[i, 5] += T[O_MIZ * BLK + ll]
        fb[j, 0] += fx
        fb[j, 1] += fy
        fb[j, 2] += fz
        fb[j, 3] += T[O_MJX * BLK + ll]
        fb[j, 4] += T[O_MJY * BLK + ll]
        fb[j, 5] += T[O_MJZ * BLK + ll]
        pfs[k, 0] = T[O_LX * BLK + ll]
        pfs[k, 1] = T[O_LY * BLK + ll]
        pfs[k, 2] = T[O_LZ * BLK + ll]
        es = T[O_ESLIP * BLK + ll]
        if es != 0.0:
            pslip[k] += es
        if dp:
            pdash[k] += T[O_EDASH * BLK + ll]
            pdf[k, 0] = T[O_DFX * BLK + ll]
            pdf[k, 1] = T[O_DFY * BLK + ll]
            pdf[k, 2] = T[O_DFZ * BLK + ll]
        pact[k] = 1 if T[O_ACT * BLK + ll] > 0.0 else 0
        if bstate[k] == BOND_INTACT:
            mode = T[O_MODE * BLK + ll]
            bfn[k] = T[O_FN * BLK + ll]
            bfs[k, 0] = T[O_SX * BLK + ll]
            bfs[k, 1] = T[O_SY * BLK + ll]
            bfs[k, 2] = T[O_SZ * BLK + ll]
            bmt[k] = T[O_MT * BLK + ll]
            bmb[k, 0] = T[O_BX * BLK + ll]
            bmb[k, 1] = T[O_BY * BLK + ll]
            bmb[k, 2] = T[O_BZ * BLK + ll]
            if mode > 0.0:
                nbroken += 1
                _record_break(T, ll, k, i, j, pos, radius, bstate, bstep, bpos, bnrm, be,
                              bsig, step, int(mode), pb_emod, pb_ikr, rmul, mcf)
        if record:
            pestr[k] = T[O_ELIN * BLK + ll]
            bestr[k] = T[O_EBOND * BLK + ll]
    return nbroken


@jit
def _record_break(T, ll, k, i, j, pos, radius, bstate, bstep, bpos, bnrm, be, bsig, step,
                  mode, pb_emod, pb_ikr, rmul, mcf):
    """A bond failed in this step: record the event (rare; scalar)."""
    nx = T[O_NX * BLK + ll]
    ny = T[O_NY * BLK + ll]
    nz = T[O_NZ * BLK + ll]
    ai = T[O_AI * BLK + ll]
    ri = radius[i]
    rj = radius[j]
    inv_l = 1.0 / (ri + rj)
    rb = rmul * min(ri, rj)
    area = math.pi * rb * rb
    inertia = 0.25 * area * rb * rb
    knb = pb_emod * inv_l
    ksb = knb * pb_ikr
    kna = knb * area
    ksa = ksb * area
    ksj = ksb * 2.0 * inertia
    kni = knb * inertia
    fnb = T[O_TFN * BLK + ll]
    sbx = T[O_TSX * BLK + ll]
    sby = T[O_TSY * BLK + ll]
    sbz = T[O_TSZ * BLK + ll]
    mt = T[O_TMT * BLK + ll]
    mbx = T[O_TBX * BLK + ll]
    mby = T[O_TBY * BLK + ll]
    mbz = T[O_TBZ * BLK + ll]
    smag = math.sqrt(sbx * sbx + sby * sby + sbz * sbz)
    mbmag = math.sqrt(mbx * mbx + mby * mby + mbz * mbz)
    bstate[k] = mode
    bstep[k] = step
    bpos[k, 0] = pos[i, 0] + ai * nx
    bpos[k, 1] = pos[i, 1] + ai * ny
    bpos[k, 2] = pos[i, 2] + ai * nz
    bnrm[k, 0] = nx
    bnrm[k, 1] = ny
    bnrm[k, 2] = nz
    bsig[k, 0] = fnb / area + 4.0 * mcf * mbmag / (area * rb)
    bsig[k, 1] = smag / area + 2.0 * mcf * abs(mt) / (area * rb)
    bsig[k, 2] = fnb / area
    # released energy in the step-consistent form 1/2 F_old . F_trial / k per component
    be[k] = 0.5 * (T[F_FN * BLK + ll] * fnb / kna
                   + (T[O_R0X * BLK + ll] * sbx + T[O_R0Y * BLK + ll] * sby
                      + T[O_R0Z * BLK + ll] * sbz) / ksa
                   + T[F_MT * BLK + ll] * mt / ksj
                   + (T[O_Q0X * BLK + ll] * mbx + T[O_Q0Y * BLK + ll] * mby
                      + T[O_Q0Z * BLK + ll] * mbz) / kni)


@jit
def bond_range(pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, pslip, pdash, pestr,
               bfn, bfs, bmt, bmb, bstate, brgap, bstep, bpos, bnrm, be, bestr, bsig, fb, k0,
               k1, T, dt, emod, ikr, fric, pb_emod, pb_ikr, pb_ten, pb_coh, tanfa, rmul, mcf,
               betan, betas, step, record):
    """Bond pairs k0..k1 in blocks of BLK. Returns the number of bonds broken."""
    dp = betan > 0.0 or betas > 0.0
    nbroken = 0
    for b0 in range(k0, k1, BLK):
        nl = min(BLK, k1 - b0)
        _gather(pos, vel, angvel, radius, mass, pi, pj, pfs, pdf, pact, bfn, bfs, bmt, bmb,
                bstate, brgap, b0, nl, T)
        _compute(T, nl, dt, emod, ikr, fric, pb_emod, pb_ikr, pb_ten, pb_coh, tanfa, rmul,
                 mcf, betan, betas, dp)
        nbroken += _scatter(T, b0, nl, pos, radius, pi, pj, pfs, pdf, pact, pslip, pdash,
                            pestr, bfn, bfs, bmt, bmb, bstate, bstep, bpos, bnrm, be, bestr,
                            bsig, fb, step, record, dp, pb_emod, pb_ikr, rmul, mcf)
    return nbroken
