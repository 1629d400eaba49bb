"""Compare run files bit for bit: every dataset, and every attribute of the summary,
genesis and inputs groups, except the host's timings (``wall_s``, ``test_s``,
``genesis_s``, the triaxial consolidation's ``consol_s``) and the file's provenance
(commit, version, creation time: the file's own attributes, not compared). Prints, per
pair, how many items were compared and which differ.

    python benchmarks/run_diff.py A.h5 B.h5 [C.h5 D.h5 ...]

Used to show that a change leaves runs unchanged (docs/measurements/2026-12-02-strength-
scatter.md: the same UCS and Brazilian runs on the commit before the strength scatter and
on the scatter's commit with sd 0). Exit code 1 if any pair differs.
"""
from __future__ import annotations

import sys

import h5py
import numpy as np

TIMING = {"wall_s", "test_s", "genesis_s", "consol_s"}
GROUPS = ("summary", "genesis", "inputs")


def _datasets(f) -> list[str]:
    out = []
    f.visititems(lambda k, o: out.append(k) if isinstance(o, h5py.Dataset) else None)
    return sorted(out)


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype.kind != b.dtype.kind:
        return False
    return bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))


def compare(path_a, path_b) -> tuple[int, list[str]]:
    """(items compared, the ones that differ) of two run files."""
    with h5py.File(path_a) as fa, h5py.File(path_b) as fb:
        da, db = _datasets(fa), _datasets(fb)
        diffs = [f"only in one file: {k}" for k in sorted(set(da) ^ set(db))]
        both = [k for k in da if k in db]
        diffs += [k for k in both if not _same(fa[k][()], fb[k][()])]
        n = len(both)
        for g in GROUPS:
            A = dict(fa[g].attrs) if g in fa else {}
            B = dict(fb[g].attrs) if g in fb else {}
            for key in sorted((set(A) | set(B)) - TIMING):
                n += 1
                if key not in A or key not in B or not _same(A[key], B[key]):
                    diffs.append(f"{g}.{key}: {A.get(key)!r} != {B.get(key)!r}")
    return n, diffs


def main(argv) -> int:
    if len(argv) < 2 or len(argv) % 2:
        print(__doc__.strip().splitlines()[-5], file=sys.stderr)
        return 2
    bad = 0
    for a, b in zip(argv[0::2], argv[1::2]):
        n, d = compare(a, b)
        bad += bool(d)
        print(f"{a} vs {b}: {n} items compared, {len(d)} differ" + (f": {d[:10]}" if d else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
