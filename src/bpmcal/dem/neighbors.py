"""Neighbour search: the Verlet list of unbonded ball-ball pairs and the ball-wall slots.

Bond pairs are permanent (the first ``nb`` entries of the pair arrays) and are never
searched. The other pairs come from a uniform cell grid with a Verlet skin: every pair
whose surfaces are closer than the skin is listed, and the lists are rebuilt only when
some ball may have moved more than half the skin since the last build (``kernels.run_steps``
checks this with ``max_displacement``). Contact history (shear force, dashpot force,
ball-wall reference gaps) is carried over to the new lists. Pairs of a row are sorted
by partner index, so the lists and every result built on them are deterministic.
"""
from __future__ import annotations

import math

import numpy as np

from ._jit import jit
from .laws import wall_contact_geometry
from .slots import (
    E_DASH,
    E_SLIP,
    E_WDASH,
    E_WSLIP,
    I_NB,
    I_NEED_C,
    I_NEED_P,
    I_NEED_W,
    I_NPAIRS,
    I_NREBUILDS,
    I_NSLOTS,
    I_REBUILD,
    P_DBOUND,
    P_SKIN,
)


@jit
def _cell_grid(pos, radius, skin, ncap):
    """Bin balls into a uniform grid of cells at least 2 Rmax + skin wide. Returns the cell
    of every ball, the CSR start of every cell, the balls in cell order (increasing ball
    index within a cell), their positions and radii in that order, and the grid size."""
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
    cnt = np.zeros(ncell + 1, np.int64)
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
        cnt[ic + 1] += 1
    # unsigned CSR and ball indices, and the coordinates in four flat arrays: the search
    # loop then indexes without sign fix-ups or stride multiplications
    start = np.empty(ncell + 1, np.uint64)
    acc = 0
    for c in range(ncell + 1):
        acc += cnt[c]
        start[c] = acc
    fill = cnt[:-1].copy()
    for c in range(ncell):
        fill[c] = start[c]
    order = np.empty(n, np.uint32)
    cp = np.empty((4, n))  # x, y, z, radius in cell order: the search reads them in sequence
    for i in range(n):
        e = fill[cell[i]]
        order[e] = i
        cp[0, e] = pos[i, 0]
        cp[1, e] = pos[i, 1]
        cp[2, e] = pos[i, 2]
        cp[3, e] = radius[i]
        fill[cell[i]] += 1
    return cell, start, order, cp, dims


#: partition boundaries inside the bond pairs are multiples of this (bondblock.BLK need not
#: be one: a partition may start inside a block of the bond state); it fixes the
#: summation order of the forces, so it must not change
PART_ALIGN = 64

#: cost of an unbonded (Verlet) pair relative to a bond pair, for balancing partitions
VERLET_COST = 0.15


@jit
def set_partitions(part, npairs, nb):
    """Split pairs 0..npairs into len(part)-1 contiguous ranges of about equal work (a
    Verlet pair costs ``VERLET_COST`` of a bond pair); boundaries inside the bond pairs
    fall on multiples of ``PART_ALIGN``."""
    npart = part.shape[0] - 1
    work = nb + VERLET_COST * (npairs - nb)
    part[0] = 0
    part[npart] = npairs
    for p in range(1, npart):
        target = work * p / npart
        if target <= nb:
            b = int(target)
            b = (b // PART_ALIGN) * PART_ALIGN
        else:
            b = nb + int((target - nb) / VERLET_COST)
        part[p] = min(max(b, part[p - 1]), npairs)


@jit
def partition_masks(pmask, part, pi, pj):
    """Bit p of ``pmask[i]`` is set when partition p has a pair with ball i (the
    integrator reads only those partitions' force buffers)."""
    for i in range(pmask.shape[0]):
        pmask[i] = 0
    for p in range(part.shape[0] - 1):
        bit = 1 << p
        for k in range(part[p], part[p + 1]):
            pmask[pi[k]] |= bit
            pmask[pj[k]] |= bit


@jit
def _bonded(i, j, bptr, bpart):
    for e in range(bptr[i], bptr[i + 1]):
        if bpart[e] == j:
            return True
    return False


@jit
def rebuild(pos, radius, pos_ref, pmask, pi, pj, pfs, pdf, pact, pslip, pdash, vptr, bptr,
            bpart, pi2, pj2, pfs2, vptr2, cand, part, sb, sw, sfs, sdf, srg, sslip, sdash,
            sptr, sb2, sw2, sfs2, sptr2, wtype, wpos, wnrm, wrad, wdisk, wdisp, prm, iprm,
            eacc):
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
    cell, start, order, cp, dims = _cell_grid(pos, radius, skin, 4 * n + 64)
    d0 = dims[0]
    d1 = dims[1]
    d2 = dims[2]
    ccap = cand.shape[0]
    # 1. candidate pairs, each found once: a ball's own cell (later entries) and the 13
    #    "forward" neighbour cells (half shell); found pairs go to pi2/pj2 (as lo < hi)
    #    and are counted per row lo in vptr2
    for i in range(n + 1):
        vptr2[i] = 0
    room = cap - nb
    found = 0
    cx_ = cp[0]
    cy_ = cp[1]
    cz_ = cp[2]
    cr_ = cp[3]
    one = np.uint64(1)
    for c in range(d0 * d1 * d2):
        s0 = start[c]
        s1 = start[c + 1]
        if s0 == s1:
            continue
        cz = c % d2
        cy = (c // d2) % d1
        cx = c // (d1 * d2)
        # cell pairs (c, q), then ball pairs: the stencil arithmetic and the bounds of q
        # are worked out once per cell, not once per ball (the order in which pairs are
        # found does not matter: step 2 sorts them)
        for h in range(14):  # 0: own cell; 1..13: forward cells
            if h == 0:
                q0 = s0
                q1 = s1
            else:
                k = h + 13  # offsets 14..26 of the 3x3x3 stencil (x fastest)
                qx = cx + k // 9 - 1
                qy = cy + (k // 3) % 3 - 1
                qz = cz + k % 3 - 1
                if qx >= d0 or qy < 0 or qy >= d1 or qz < 0 or qz >= d2:
                    continue
                q = (qx * d1 + qy) * d2 + qz
                q0 = start[q]
                q1 = start[q + 1]
                if q0 == q1:
                    continue
            for e in range(s0, s1):
                a = order[e]
                xa = cx_[e]
                ya = cy_[e]
                za = cz_[e]
                ra = cr_[e]
                e0 = e + one if h == 0 else q0
                for e2 in range(e0, q1):
                    b = order[e2]
                    # the same test, bit for bit, as from the row ball lo = min(a, b):
                    # IEEE subtraction is antisymmetric (squares equal) and addition
                    # commutative, so the order of a and b does not matter
                    dx = cx_[e2] - xa
                    dy = cy_[e2] - ya
                    dz = cz_[e2] - za
                    lim = ra + cr_[e2] + skin
                    if dx * dx + dy * dy + dz * dz < lim * lim:
                        lo = min(a, b)
                        hi = max(a, b)
                        if not _bonded(lo, hi, bptr, bpart):
                            if found < room:
                                pi2[nb + found] = lo
                                pj2[nb + found] = hi
                            found += 1
                            vptr2[lo] += 1
    cnt = nb + found
    cmax = found
    if found > room or found > ccap:
        iprm[I_NEED_P] = cnt
        iprm[I_NEED_W] = sb.shape[0]
        iprm[I_NEED_C] = cmax
        return 1
    # 2. rows in increasing i, each sorted by j (deterministic order): counting sort into
    #    cand, then insertion sort per row
    acc = 0
    for i in range(n):
        k = vptr2[i]
        vptr2[i] = acc
        acc += k
    vptr2[n] = acc
    fillp = vptr2[:n].copy()
    for t in range(found):
        lo = pi2[nb + t]
        cand[fillp[lo]] = pj2[nb + t]
        fillp[lo] += 1
    cnt = nb
    for i in range(n):
        r0 = vptr2[i]
        r1 = vptr2[i + 1]
        for a in range(r0 + 1, r1):
            v = cand[a]
            b = a - 1
            while b >= r0 and cand[b] > v:
                cand[b + 1] = cand[b]
                b -= 1
            cand[b + 1] = v
        vptr2[i] = cnt
        # history: the old row is sorted by j too, so one pass over both finds every match
        e = vptr[i]
        e1 = vptr[i + 1]
        for a in range(r0, r1):
            j = cand[a]
            while e < e1 and pj[e] < j:
                e += 1
            pi2[cnt] = i
            pj2[cnt] = j
            if e < e1 and pj[e] == j:
                for c in range(3):
                    pfs2[cnt, c] = pfs[e, c]
                    pfs2[cnt, 3 + c] = pdf[e, c]
            else:
                for c in range(6):
                    pfs2[cnt, c] = 0.0
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
    partition_masks(pmask, part, pi, pj)
    for i in range(n):
        for c in range(3):
            pos_ref[i, c] = pos[i, c]
    for w in range(nw):
        wdisp[w] = 0.0
    prm[P_DBOUND] = 0.0
    iprm[I_REBUILD] = 0
    iprm[I_NREBUILDS] += 1
    return 0


@jit
def rebuild_lists(B, P, Bd, S, W, prm, iprm, eacc):
    """``rebuild`` on the model's namedtuples of arrays (model.py)."""
    return rebuild(B.pos, B.radius, B.pos_ref, B.pmask, P.pi, P.pj, P.fs, P.df, P.act, P.slip, P.dash,
                   P.vptr, Bd.ptr, Bd.part, P.pi2, P.pj2, P.fs2, P.vptr2, P.cand, P.part,
                   S.b, S.w, S.fs, S.df, S.rg, S.slip, S.dash, S.ptr, S.b2, S.w2, S.fs2,
                   S.ptr2, W.type,
                   W.pos, W.nrm, W.rad, W.disk, W.disp, prm, iprm, eacc)


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


