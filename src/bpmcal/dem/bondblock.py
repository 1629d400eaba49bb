"""Bond pairs in SIMD-friendly blocks with their state kept in a blocked layout.

The bond pairs (the first ``nb`` pairs, permanent) dominate the work of a bonded
specimen. Their state lives permanently in one flat array ``blk`` in blocks of ``BLK``
bonds: field ``f`` of bond ``k`` is ``blk[(k // BLK) * NSF * STR + f * STR + k % BLK]``
(structure of arrays within a block). Per block and step:

1. gather: the per-step inputs of each pair (relative position and velocity, spins,
   radii) are copied into a flat scratch array ``T``;
2. ``_compute``: the linear contact + parallel-bond law (``laws.py``) is evaluated for
   every lane without branches, reading ``T`` and updating the block's state in place.
   All field offsets are compile-time constants at least ``BLK`` apart, so LLVM can prove
   the lanes independent and vectorises the loop;
3. scatter: forces and moments are added to the partition buffer in increasing pair
   order (results do not depend on the block size); rare events (bond breaks) are
   handled in a separate scalar pass.

A partition of the pairs may begin inside a block (its boundaries are multiples of
``neighbors.PART_ALIGN``, finer than ``BLK``): ``bond_range`` then runs chunks that start
at any lane and never cross a block, each with the same affine field offsets.

A failing bond's lane is left holding its *trial* state; the break pass records the
event (recomputing the state before the step from the increments) and zeroes it.
"""
from __future__ import annotations

import math

import numpy as np

from ._jit import jit
from .laws import (
    bond_energy,
    bond_failure,
    bond_geometry,
    dashpot,
    kinematics,
    linear_shear,
    linear_stiffness,
    rotate_shear,
)

#: lanes per block. Within a block each field is a row of BLK values, so one pass over the
#: bonds reads ~14 interleaved streams of BLK * 8 bytes each. With 64 lanes (512-byte rows)
#: the hardware prefetcher could not follow them once the state no longer fit in cache:
#: from 10k to 30k balls the law's pass over the state went from ~15 to ~25-30 ns per
#: bond while the gathers and scatters stayed flat. 512 lanes (4 KiB rows) stream; the
#: per-step scratch (NF rows) stays below 128 KiB. docs/measurements/2026-11-27-cache-fix.md
BLK = 512
#: row stride: not a power of two, so that rows do not fall on the same 4 KiB offsets
STR = BLK + 4

# ---- persistent state fields (blk) ----------------------------------------------------
_S = iter(range(100))
S_FN, S_SX, S_SY, S_SZ = next(_S), next(_S), next(_S), next(_S)  # bond normal/shear force
S_MT, S_BX, S_BY, S_BZ = next(_S), next(_S), next(_S), next(_S)  # bond twist/bending moment
S_LX, S_LY, S_LZ = next(_S), next(_S), next(_S)  # shear force of the linear component
S_RG = next(_S)  # reference gap of the linear component [m]; max(rg, 0) once a broken
#                  pair's surfaces are apart (re-contact starts at first touch)
S_FLAGS = next(_S)  # 3.0 intact; broken: 1.0 if the linear part carried force last step, else 0
S_TEN, S_COH = next(_S), next(_S)  # the strengths the bond fails at [Pa]: its own tensile
#                  strength and cohesion (S_TEN0, S_COH0) x its strength factor (S_SF), the
#                  product taken when either is set (Model.set_bond_strengths,
#                  set_bond_strength_factors), so the law reads two rows, not three
S_DFX, S_DFY, S_DFZ = next(_S), next(_S), next(_S)  # dashpot force of the last step (after
#                     the rows read every step: untouched without dashpots)
S_SF = next(_S)  # strength factor of the bond (1 unless set: end caps, contact caps)
S_TEN0, S_COH0 = next(_S), next(_S)  # the bond's own tensile strength and cohesion [Pa] (PFC's
#                  per-contact pb_ten / pb_coh): the material's means at installation, or
#                  drawn per bond (strength scatter). S_SF, S_TEN0, S_COH0 are kept for the
#                  Python side; no kernel reads them
#: S_FLAGS values (one field for two flags: one load and one store less per bond and step)
FLAG_INTACT = 3.0
FLAG_ACTIVE = 1.0
NSF = next(_S)
del _S

# ---- per-step scratch fields (T) ------------------------------------------------------
_I = iter(range(100))
F_DX, F_DY, F_DZ = next(_I), next(_I), next(_I)
F_VX, F_VY, F_VZ = next(_I), next(_I), next(_I)
F_WIX, F_WIY, F_WIZ = next(_I), next(_I), next(_I)
F_WJX, F_WJY, F_WJZ = next(_I), next(_I), next(_I)
F_RI, F_RJ, F_MI, F_MJ = next(_I), next(_I), next(_I), next(_I)
O_FX, O_FY, O_FZ = next(_I), next(_I), next(_I)  # force on j
O_MIX, O_MIY, O_MIZ = next(_I), next(_I), next(_I)
O_MJX, O_MJY, O_MJZ = next(_I), next(_I), next(_I)
O_ESLIP, O_EDASH, O_ELIN, O_EBOND = next(_I), next(_I), next(_I), next(_I)
O_MODE = next(_I)
NF = next(_I)
del _I

BLOCK_SIZE = NSF * STR  # floats per block of state


def n_blocks(nb: int) -> int:
    return max(1, -(-int(nb) // BLK))


def new_state(nb: int, ten: float = 0.0, coh: float = 0.0) -> np.ndarray:
    """Zeroed state for ``nb`` bonds, all intact, strength factor 1, tensile strength
    ``ten`` and cohesion ``coh`` [Pa]."""
    blk = np.zeros(n_blocks(nb) * BLOCK_SIZE)
    set_field(blk, S_FLAGS, nb, FLAG_INTACT)
    set_field(blk, S_SF, nb, 1.0)
    set_field(blk, S_TEN0, nb, ten)
    set_field(blk, S_COH0, nb, coh)
    set_strengths(blk, nb)
    return blk


def set_strengths(blk, nb):
    """The strengths bonds 0..nb-1 fail at (``S_TEN``, ``S_COH``): their own x their
    strength factor (Python side; after either changes)."""
    sf = get_field(blk, S_SF, nb)
    set_field(blk, S_TEN, nb, get_field(blk, S_TEN0, nb) * sf)
    set_field(blk, S_COH, nb, get_field(blk, S_COH0, nb) * sf)


def field_index(f: int, nb: int) -> np.ndarray:
    """Positions of field ``f`` of bonds 0..nb-1 in the blocked state array."""
    k = np.arange(int(nb))
    return (k // BLK) * BLOCK_SIZE + f * STR + k % BLK


def get_field(blk, f, nb) -> np.ndarray:
    """Copy of state field ``f`` of bonds 0..nb-1 (Python side, not for hot loops)."""
    return blk[field_index(f, nb)]


def set_field(blk, f, nb, values):
    blk[field_index(f, nb)] = values


@jit
def scratch():
    """A scratch block for one partition."""
    return np.empty(NF * STR)


@jit
def state_index(k, f):
    """Position of field ``f`` of bond ``k`` in the blocked state array."""
    return (k // BLK) * BLOCK_SIZE + f * STR + k % BLK


@jit
def _compute(T, sb, nl, dt, emod, ikr, fric, pb_emod, pb_ikr, tanfa, rmul, mcf, betan,
             betas, dp, record):
    """Linear + parallel-bond law for every lane of a block, without branches (the laws.py
    helpers are select-based): reads ``T``, updates the block's state ``sb`` (a view of
    one block of ``blk``: indices stay non-negative and affine, which the vectoriser
    needs) in place, writes forces, moments and energies to ``T``. LLVM vectorises this loop. Energy
    terms only needed on record steps are computed only then."""
    for ll in range(nl):
        ri = T[F_RI * STR + ll]
        rj = T[F_RJ * STR + ll]
        wix = T[F_WIX * STR + ll]
        wiy = T[F_WIY * STR + ll]
        wiz = T[F_WIZ * STR + ll]
        wjx = T[F_WJX * STR + ll]
        wjy = T[F_WJY * STR + ll]
        wjz = T[F_WJZ * STR + ll]
        (nx, ny, nz, gap, inv_l, ai, aj, vrx, vry, vrz, vn, dun, dusx, dusy, dusz,
         dphi) = kinematics(T[F_DX * STR + ll], T[F_DY * STR + ll], T[F_DZ * STR + ll],
                            T[F_VX * STR + ll], T[F_VY * STR + ll], T[F_VZ * STR + ll],
                            wix, wiy, wiz, wjx, wjy, wjz, ri, rj, dt)
        # ---- linear component (reference gap rg: active while gap < rg)
        kn, ks = linear_stiffness(ri, rj, inv_l, emod, ikr)
        iks = 1.0 / ks
        rg = sb[S_RG * STR + ll]
        lact = gap < rg
        fn = kn * max(rg - gap, 0.0)
        sx, sy, sz = rotate_shear(sb[S_LX * STR + ll], sb[S_LY * STR + ll],
                                  sb[S_LZ * STR + ll], nx, ny, nz, dphi)
        ux, uy, uz, tx, ty, tz, eslip = linear_shear(sx, sy, sz, dusx, dusy, dusz, ks, iks,
                                                     fric * fn)
        # contact lost this step: the shear spring's energy, as in kernels._pair_range
        elost = 0.5 * (sx * tx + sy * ty + sz * tz) * iks
        flags = sb[S_FLAGS * STR + ll]
        wasact = flags > 0.0  # intact bonds always count as active
        eslip = eslip if lact else (elost if wasact else 0.0)
        ux = ux if lact else 0.0
        uy = uy if lact else 0.0
        uz = uz if lact else 0.0
        fx = fn * nx + ux
        fy = fn * ny + uy
        fz = fn * nz + uz
        if dp:
            mi = T[F_MI * STR + ll]
            mj = T[F_MJ * STR + ll]
            gx, gy, gz = dashpot(vrx, vry, vrz, vn, nx, ny, nz, mi * mj / (mi + mj), kn, ks,
                                 betan, betas)
            gx = gx if lact else 0.0
            gy = gy if lact else 0.0
            gz = gz if lact else 0.0
            T[O_EDASH * STR + ll] = -0.5 * ((gx + sb[S_DFX * STR + ll]) * vrx
                                            + (gy + sb[S_DFY * STR + ll]) * vry
                                            + (gz + sb[S_DFZ * STR + ll]) * vrz) * dt
            sb[S_DFX * STR + ll] = gx
            sb[S_DFY * STR + ll] = gy
            sb[S_DFZ * STR + ll] = gz
            fx += gx
            fy += gy
            fz += gz
        # ---- parallel bond
        rb, area, kna, ksa, ksj, kni = bond_geometry(ri, rj, inv_l, pb_emod, pb_ikr, rmul)
        intact = flags > 2.0
        fnb = sb[S_FN * STR + ll] + kna * dun
        ax, ay, az = rotate_shear(sb[S_SX * STR + ll], sb[S_SY * STR + ll],
                                  sb[S_SZ * STR + ll], nx, ny, nz, dphi)
        sbx = ax - ksa * dusx
        sby = ay - ksa * dusy
        sbz = az - ksa * dusz
        thx = (wjx - wix) * dt
        thy = (wjy - wiy) * dt
        thz = (wjz - wiz) * dt
        tht = thx * nx + thy * ny + thz * nz
        mt = sb[S_MT * STR + ll] - ksj * tht
        bx, by, bz = rotate_shear(sb[S_BX * STR + ll], sb[S_BY * STR + ll],
                                  sb[S_BZ * STR + ll], nx, ny, nz, dphi)
        mbx = bx - kni * (thx - tht * nx)
        mby = by - kni * (thy - tht * ny)
        mbz = bz - kni * (thz - tht * nz)
        sb2 = sbx * sbx + sby * sby + sbz * sbz
        mb2 = mbx * mbx + mby * mby + mbz * mbz
        # the bond's own strengths x its strength factor (S_TEN, S_COH: taken at set time;
        # x 1.0 is exact, so a bond at the material's means fails where it always did)
        fm = bond_failure(fnb, sb2, mt, mb2, rb, area, sb[S_TEN * STR + ll],
                          sb[S_COH * STR + ll], tanfa, mcf)
        keep = intact and fm == 0
        # state: the new (or, for a failing bond, the trial) state; zero once broken
        sb[S_FN * STR + ll] = fnb if intact else 0.0
        sb[S_SX * STR + ll] = sbx if intact else 0.0
        sb[S_SY * STR + ll] = sby if intact else 0.0
        sb[S_SZ * STR + ll] = sbz if intact else 0.0
        sb[S_MT * STR + ll] = mt if intact else 0.0
        sb[S_BX * STR + ll] = mbx if intact else 0.0
        sb[S_BY * STR + ll] = mby if intact else 0.0
        sb[S_BZ * STR + ll] = mbz if intact else 0.0
        sb[S_LX * STR + ll] = ux
        sb[S_LY * STR + ll] = uy
        sb[S_LZ * STR + ll] = uz
        sb[S_FLAGS * STR + ll] = FLAG_INTACT if intact else (FLAG_ACTIVE if lact else 0.0)
        # re-contact at first touch (PFC): once the surfaces of a broken pair are apart,
        # a negative reference gap (locked-in stress relief) no longer applies
        sb[S_RG * STR + ll] = rg if (intact or gap < 0.0) else max(rg, 0.0)
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
        # ---- moments: M_j = aj n x F + couple, M_i = -ai n x F - couple
        cx = ny * fz - nz * fy
        cy = nz * fx - nx * fz
        cz = nx * fy - ny * fx
        T[O_FX * STR + ll] = fx
        T[O_FY * STR + ll] = fy
        T[O_FZ * STR + ll] = fz
        T[O_MJX * STR + ll] = aj * cx + cpx
        T[O_MJY * STR + ll] = aj * cy + cpy
        T[O_MJZ * STR + ll] = aj * cz + cpz
        T[O_MIX * STR + ll] = -ai * cx - cpx
        T[O_MIY * STR + ll] = -ai * cy - cpy
        T[O_MIZ * STR + ll] = -ai * cz - cpz
        T[O_ESLIP * STR + ll] = eslip
        T[O_MODE * STR + ll] = float(fm) if intact else 0.0
        if record:
            T[O_ELIN * STR + ll] = (0.5 * fn * fn / kn + 0.5 * (ux * ux + uy * uy + uz * uz) * iks
                                    if lact else 0.0)
            T[O_EBOND * STR + ll] = bond_energy(kfn, ksx * ksx + ksy * ksy + ksz * ksz, kmt,
                                                kbx * kbx + kby * kby + kbz * kbz, kna, ksa,
                                                ksj, kni)


@jit
def _record_break(T, blk, base, ll, k, i, pos, bstate, bstep, bpos, bnrm, be, bsig, step,
                  mode, dt, pb_emod, pb_ikr, rmul, mcf):
    """A bond failed in this step: record the event (rare; scalar) and zero its state.

    The block holds the failing *trial* state; the state before the step is the trial
    minus this step's increments (recomputed from the inputs still in ``T``)."""
    ri = T[F_RI * STR + ll]
    rj = T[F_RJ * STR + ll]
    wix = T[F_WIX * STR + ll]
    wiy = T[F_WIY * STR + ll]
    wiz = T[F_WIZ * STR + ll]
    wjx = T[F_WJX * STR + ll]
    wjy = T[F_WJY * STR + ll]
    wjz = T[F_WJZ * STR + ll]
    (nx, ny, nz, gap, inv_l, ai, aj, vrx, vry, vrz, vn, dun, dusx, dusy, dusz,
     dphi) = kinematics(T[F_DX * STR + ll], T[F_DY * STR + ll], T[F_DZ * STR + ll],
                        T[F_VX * STR + ll], T[F_VY * STR + ll], T[F_VZ * STR + ll],
                        wix, wiy, wiz, wjx, wjy, wjz, ri, rj, dt)
    rb, area, kna, ksa, ksj, kni = bond_geometry(ri, rj, inv_l, pb_emod, pb_ikr, rmul)
    fnb = blk[base + S_FN * STR + ll]
    sbx = blk[base + S_SX * STR + ll]
    sby = blk[base + S_SY * STR + ll]
    sbz = blk[base + S_SZ * STR + ll]
    mt = blk[base + S_MT * STR + ll]
    mbx = blk[base + S_BX * STR + ll]
    mby = blk[base + S_BY * STR + ll]
    mbz = blk[base + S_BZ * STR + ll]
    tht = ((wjx - wix) * nx + (wjy - wiy) * ny + (wjz - wiz) * nz) * dt
    # state before the step (rotated into the current plane)
    fn0 = fnb - kna * dun
    ax = sbx + ksa * dusx
    ay = sby + ksa * dusy
    az = sbz + ksa * dusz
    mt0 = mt + ksj * tht
    bx = mbx + kni * ((wjx - wix) * dt - tht * nx)
    by = mby + kni * ((wjy - wiy) * dt - tht * ny)
    bz = mbz + kni * ((wjz - wiz) * dt - tht * nz)
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
    # peak stresses of the failing state: sigma (with bending), tau (with twisting), and
    # the normal stress Fn/A (tension positive)
    bsig[k, 0] = fnb / area + 4.0 * mcf * mbmag / (area * rb)
    bsig[k, 1] = smag / area + 2.0 * mcf * abs(mt) / (area * rb)
    bsig[k, 2] = fnb / area
    # released energy in the step-consistent form 1/2 F_old . F_trial / k per component
    be[k] = 0.5 * (fn0 * fnb / kna + (ax * sbx + ay * sby + az * sbz) / ksa + mt0 * mt / ksj
                   + (bx * mbx + by * mby + bz * mbz) / kni)
    for f in (S_FN, S_SX, S_SY, S_SZ, S_MT, S_BX, S_BY, S_BZ):
        blk[base + f * STR + ll] = 0.0
    blk[base + S_FLAGS * STR + ll] = FLAG_ACTIVE  # broken; its linear part was active


@jit
def bond_range(pos, vel, angvel, radius, mass, pi, pj, blk, pslip, pdash, pestr, bstate,
               bstep, bpos, bnrm, be, bestr, bsig, fb, k0, k1, T, dt, emod, ikr, fric,
               pb_emod, pb_ikr, pb_ten, pb_coh, tanfa, rmul, mcf, betan, betas, step, record):
    """Bond pairs k0..k1 in chunks of at most BLK lanes that never cross a block of the
    state (a partition may start inside a block: ``neighbors.PART_ALIGN`` is finer than
    BLK). Returns the bonds broken. ``pb_ten``, ``pb_coh`` (the material's means) are not
    read: each bond fails at its own strengths, kept in its state (``S_TEN``, ``S_COH``).

    Gather and scatter are written out here rather than called: a call that passes ~30
    arrays costs more than a block."""
    dp = betan > 0.0 or betas > 0.0
    nbroken = 0
    brk = np.empty(BLK, np.int64)
    b0 = k0
    while b0 < k1:
        l0 = b0 % BLK  # first lane of the chunk in its block
        nl = min(BLK - l0, k1 - b0)
        # the chunk's view starts at its first lane: field f of lane ll is
        # blk[base + f * STR + ll], the same affine form as for a whole block
        base = (b0 // BLK) * BLOCK_SIZE + l0
        # ---- gather
        for ll in range(nl):
            k = b0 + ll
            i = pi[k]
            j = pj[k]
            T[F_DX * STR + ll] = pos[j, 0] - pos[i, 0]
            T[F_DY * STR + ll] = pos[j, 1] - pos[i, 1]
            T[F_DZ * STR + ll] = pos[j, 2] - pos[i, 2]
            T[F_VX * STR + ll] = vel[j, 0] - vel[i, 0]
            T[F_VY * STR + ll] = vel[j, 1] - vel[i, 1]
            T[F_VZ * STR + ll] = vel[j, 2] - vel[i, 2]
            T[F_WIX * STR + ll] = angvel[i, 0]
            T[F_WIY * STR + ll] = angvel[i, 1]
            T[F_WIZ * STR + ll] = angvel[i, 2]
            T[F_WJX * STR + ll] = angvel[j, 0]
            T[F_WJY * STR + ll] = angvel[j, 1]
            T[F_WJZ * STR + ll] = angvel[j, 2]
            T[F_RI * STR + ll] = radius[i]
            T[F_RJ * STR + ll] = radius[j]
        if dp:  # dashpot inputs only when dashpots are on
            for ll in range(nl):
                T[F_MI * STR + ll] = mass[pi[b0 + ll]]
                T[F_MJ * STR + ll] = mass[pj[b0 + ll]]
        # ---- compute (vectorised)
        _compute(T, blk[base:base + BLOCK_SIZE - l0], nl, dt, emod, ikr, fric, pb_emod,
                 pb_ikr, tanfa, rmul, mcf, betan, betas, dp, record)
        # ---- scatter, in increasing pair order
        nbrk = 0
        for ll in range(nl):
            k = b0 + ll
            i = pi[k]
            j = pj[k]
            fx = T[O_FX * STR + ll]
            fy = T[O_FY * STR + ll]
            fz = T[O_FZ * STR + ll]
            fb[i, 0] -= fx
            fb[i, 1] -= fy
            fb[i, 2] -= fz
            fb[i, 3] += T[O_MIX * STR + ll]
            fb[i, 4] += T[O_MIY * STR + ll]
            fb[i, 5] += T[O_MIZ * STR + ll]
            fb[j, 0] += fx
            fb[j, 1] += fy
            fb[j, 2] += fz
            fb[j, 3] += T[O_MJX * STR + ll]
            fb[j, 4] += T[O_MJY * STR + ll]
            fb[j, 5] += T[O_MJZ * STR + ll]
            es = T[O_ESLIP * STR + ll]
            if es != 0.0:
                pslip[k] += es
            if T[O_MODE * STR + ll] > 0.0:
                brk[nbrk] = ll
                nbrk += 1
        if dp:
            for ll in range(nl):
                pdash[b0 + ll] += T[O_EDASH * STR + ll]
        if record:
            for ll in range(nl):
                pestr[b0 + ll] = T[O_ELIN * STR + ll]
                bestr[b0 + ll] = T[O_EBOND * STR + ll]
        for q in range(nbrk):
            ll = brk[q]
            k = b0 + ll
            _record_break(T, blk, base, ll, k, pi[k], pos, bstate, bstep, bpos, bnrm, be,
                          bsig, step, int(T[O_MODE * STR + ll]), dt, pb_emod, pb_ikr, rmul,
                          mcf)
            if record:
                bestr[k] = 0.0
        nbroken += nbrk
        b0 += nl
    return nbroken
