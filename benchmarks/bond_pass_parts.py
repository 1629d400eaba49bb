"""Where the bond pass spends its time, per bond: gather, the law over the state, scatter.

    python benchmarks/bond_pass_parts.py --n 10000 30000 60000 [--reps 40] [--json out.json]
    PYTHONPATH=/tmp/base/src python benchmarks/bond_pass_parts.py ...   # another tree

On the ``dem_throughput.py`` case (N balls, every contact bonded, one thread), after 200
steps, each part of ``bondblock.bond_range`` is run alone over all bonds, in the blocks
of the bond state of the bpmcal that is imported (``bondblock.BLK`` lanes):

- ``gather``: the per-pair inputs copied from the ball arrays into the scratch block
  (random access to ball j);
- ``law``: ``bondblock._compute`` over every block of the state in turn (it reads ~14
  and writes ~13 fields of every bond: the state streams through the caches);
- ``law, one block``: the same number of ``_compute`` calls on one block of the state
  that stays in L1/L2: the arithmetic alone;
- ``scatter``: forces and moments added to a ball-major buffer (random access to j).

``law`` minus ``law, one block`` is the time the law waits for the state. Figures are
nanoseconds per bond, the best (and the median) of ``--reps`` repetitions. Hardware
counters are not needed (the KVM guest this was written on exposes none).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def _kernels():
    from numba import njit

    from bpmcal.dem.bondblock import (
        BLK,
        BLOCK_SIZE,
        F_DX,
        F_DY,
        F_DZ,
        F_RI,
        F_RJ,
        F_VX,
        F_VY,
        F_VZ,
        F_WIX,
        F_WIY,
        F_WIZ,
        F_WJX,
        F_WJY,
        F_WJZ,
        O_FX,
        O_FY,
        O_FZ,
        O_MIX,
        O_MIY,
        O_MIZ,
        O_MJX,
        O_MJY,
        O_MJZ,
        STR,
        _compute,
    )
    jit = njit(nogil=True, error_model="numpy", fastmath={"contract"})  # as bpmcal's, uncached

    @jit
    def gather(pos, vel, angvel, radius, pi, pj, T, nb):
        acc = 0.0
        for b0 in range(0, nb, BLK):
            for ll in range(min(BLK, nb - b0)):
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
            acc += T[F_DX * STR]
        return acc

    @jit
    def scatter(pi, pj, fb, T, nb):
        for b0 in range(0, nb, BLK):
            for ll in range(min(BLK, nb - b0)):
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

    @jit
    def law(blk, T, nb, one_block, dt, emod, ikr, fric, pb_emod, pb_ikr, pb_ten, pb_coh,
            tanfa, rmul, mcf):
        for b0 in range(0, nb, BLK):
            nl = min(BLK, nb - b0)
            base = 0 if one_block else (b0 // BLK) * BLOCK_SIZE
            _compute(T, blk[base:base + BLOCK_SIZE], nl, dt, emod, ikr, fric, pb_emod,
                     pb_ikr, pb_ten, pb_coh, tanfa, rmul, mcf, 0.0, 0.0, False, False)

    return gather, scatter, law


def measure(n: int, reps: int) -> dict:
    import dem_throughput as dtp

    from bpmcal.dem import bondblock as bb
    from bpmcal.dem import slots as sl
    from bpmcal.dem._jit import set_threads
    set_threads(1)
    gather, scatter, law = _kernels()
    m, nb = dtp.bench_model(n, 1, 1)
    m.cycle(200)
    B, P, prm = m.B, m.P, m.prm
    T = np.zeros(bb.NF * bb.STR)
    fb = np.zeros((n, 8))
    blk = m.Bd.blk.copy()  # the law updates the state: work on a copy
    consts = (m.dt, prm[sl.P_EMOD], 1.0 / prm[sl.P_KRATIO], prm[sl.P_FRIC],
              prm[sl.P_PB_EMOD], 1.0 / prm[sl.P_PB_KRATIO], prm[sl.P_PB_TEN],
              prm[sl.P_PB_COH], prm[sl.P_PB_TANFA], prm[sl.P_PB_RMUL], prm[sl.P_PB_MCF])
    gather(B.pos, B.vel, B.angvel, B.radius, P.pi, P.pj, T, min(nb, bb.BLK))  # real inputs
    parts = {
        "gather": lambda: gather(B.pos, B.vel, B.angvel, B.radius, P.pi, P.pj, T, nb),
        "law": lambda: law(blk, T, nb, False, *consts),
        "law_one_block": lambda: law(blk, T, nb, True, *consts),
        "scatter": lambda: scatter(P.pi, P.pj, fb, T, nb),
    }
    out = {"n": n, "bonds": int(nb), "blk": bb.BLK, "state_MB": blk.nbytes / 2 ** 20,
           "load1_before": round(os.getloadavg()[0], 2)}
    for name, f in parts.items():
        f()
        ts = []
        for _ in range(reps):
            t = time.perf_counter()
            f()
            ts.append(time.perf_counter() - t)
        out[name] = {"best_ns": min(ts) / nb * 1e9, "median_ns": float(np.median(ts)) / nb * 1e9}
    out["law_waits_ns"] = out["law"]["median_ns"] - out["law_one_block"]["median_ns"]
    out["load1_after"] = round(os.getloadavg()[0], 2)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[10000, 30000, 60000])
    ap.add_argument("--reps", type=int, default=40)
    ap.add_argument("--json", default=None, help="also write the results to this file")
    a = ap.parse_args(argv)
    import bpmcal
    rows = [measure(n, a.reps) for n in a.n]
    print(f"bpmcal from {Path(bpmcal.__file__).parent}; ns per bond, median (best) of "
          f"{a.reps}")
    print("| balls | bonds | BLK | state MB | gather | law | law, one block | scatter | "
          "law waits |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        c = " | ".join(f"{r[k]['median_ns']:.1f} ({r[k]['best_ns']:.1f})"
                       for k in ("gather", "law", "law_one_block", "scatter"))
        print(f"| {r['n']:,} | {r['bonds']:,} | {r['blk']} | {r['state_MB']:.1f} | {c} | "
              f"{r['law_waits_ns']:.1f} |")
    if a.json:
        Path(a.json).write_text(json.dumps({"date": time.strftime("%Y-%m-%dT%H:%M:%S"),
                                            "src": str(Path(bpmcal.__file__).parent),
                                            "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
