"""Where the bytes go: bytes each pass of a step reads and writes, per particle-step.

    python benchmarks/bytes_per_step.py --n 10000 [--markdown]

An accounting model, not a hardware counter: for the dem_throughput.py case (N balls,
every contact bonded, one thread, no dashpots, no gravity, not a recording step) it lists
every array each pass of a step touches, the bytes per element, and how many elements
per ball the live model has (bonds, neighbour-list pairs, wall slots, force-buffer rows
of the partitions that touch a ball), and prints bytes read and written per particle
step. Unique bytes are counted once per pass (a ball's position read by several of its
bonds in the same pass counts once: it is in cache by then), whole 64-byte lines for the
force-buffer rows. ``benchmarks/README.md`` has the table with the measured throughputs.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def accounting(m) -> list[tuple]:
    """Rows (pass, data, bytes read per ball-step, bytes written per ball-step)."""
    from bpmcal.dem import bondblock as bb
    n = m.n
    nb = m.n_bonds
    npairs = int(m.iprm[1])
    nverlet = npairs - nb
    nslots = m.n_wall_slots
    npart = m.B.fbuf.shape[0]
    rows_touched = float(sum(bin(int(x)).count("1") for x in m.B.pmask)) / n
    b = nb / n  # bonds per ball
    v = nverlet / n  # unbonded neighbour-list pairs per ball
    s = nslots / n  # wall slots per ball
    line = 64.0
    rd_rows = 14  # bond-state rows read per step (bondblock: FN..BZ, LX..LZ, RG, FLAGS, SF)
    wr_rows = 13  # rows written (all: RG too, for re-contact at first touch)
    assert bb.NSF == 17
    out = [
        ("integrate", "force buffers (rows of the partitions touching the ball)",
         rows_touched * line, rows_touched * line),
        ("integrate", "pos, vel, angvel (3 x 24 B)", 72.0, 72.0),
        ("integrate", "mass, inertia, fixity, partition mask, CSR pointer", 8 + 8 + 1 + 8 + 8, 0.0),
        ("integrate", "local-damping energy accumulator", 8.0, 8.0),
        ("integrate", f"wall-slot forces and moments ({s:.2f} slots/ball x 48 B)", s * 48, 0.0),
        ("bond pairs", f"bond state ({b:.2f} bonds/ball x {rd_rows} rows read, "
                       f"{wr_rows} written, 8 B)", b * rd_rows * 8, b * wr_rows * 8),
        ("bond pairs", "pair indices i, j (2 x 4 B per bond)", b * 8, 0.0),
        ("bond pairs", "ball data gathered: pos, vel, angvel, radius (80 B per ball)", 80.0,
         0.0),
        ("bond pairs", "force buffers, read-modify-write (rows touched)", rows_touched * line,
         rows_touched * line),
        ("neighbour pairs", f"unbonded pairs ({v:.2f}/ball): i, j, in-contact flag (9 B)",
         v * 9, 0.0),
        ("wall slots", f"slot state ({s:.2f}/ball): indices, reference gap, shear force, "
                       "slip energy; force, moment, radial force written",
         s * (8 + 8 + 24 + 8), s * (24 + 24 + 24 + 8 + 8)),
    ]
    return out, {"n": n, "bonds_per_ball": b, "unbonded_pairs_per_ball": v,
                 "slots_per_ball": s, "force_rows_per_ball": rows_touched,
                 "partitions": npart}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10000)
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args(argv)
    from dem_throughput import bench_model
    m, _ = bench_model(a.n)
    m.cycle(200)
    rows, info = accounting(m)
    tr = sum(r[2] for r in rows)
    tw = sum(r[3] for r in rows)
    print(f"N = {info['n']:,}: {info['bonds_per_ball']:.2f} bonds, "
          f"{info['unbonded_pairs_per_ball']:.2f} unbonded neighbour pairs, "
          f"{info['slots_per_ball']:.2f} wall slots and {info['force_rows_per_ball']:.2f} "
          f"force-buffer rows (of {info['partitions']} partitions) per ball")
    if a.markdown:
        print("| pass | data | read B | written B |")
        print("|---|---|---|---|")
        for p, d, r, w in rows:
            print(f"| {p} | {d} | {r:.0f} | {w:.0f} |")
        print(f"| **total** | per particle-step | **{tr:.0f}** | **{tw:.0f}** |")
    else:
        for p, d, r, w in rows:
            print(f"{p:16s} {r:7.0f} {w:7.0f}  {d}")
        print(f"{'total':16s} {tr:7.0f} {tw:7.0f}  bytes per particle-step (read, written)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
