"""How fast the extreme inputs of issue 28 end: wall time, exit code and the one line.

    python benchmarks/extreme_inputs.py [--repeat 3] [--params CARD.yaml] [--json out.json]

Runs ``bpmcal ucs`` (a fresh process each time, an empty specimen cache) with each of
``CASES`` on the card (default: the paper's A1, ``tests/support/paper.py``) and prints the
median wall time over ``--repeat`` runs, the exit code and the first line of stderr.
Peak memory is the largest child's maximum resident set (``ru_maxrss``).
"""
from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
#: (name, extra arguments of ``bpmcal ucs``)
CASES = (("pb_kratio 1e-9", ["--set", "pb_kratio=1e-9", "--scale", "0.2"]),
         ("rmin_mm 0.01", ["--set", "rmin_mm=0.01", "--scale", "0.4"]),
         ("platen 1e-6 m/s", ["--platen-velocity", "1e-6", "--scale", "0.4"]))


def a1() -> dict:
    from bpmcal.study.paper import A1  # the paper's card

    return dict(A1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--params", type=Path)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    out = {"cases": []}
    with tempfile.TemporaryDirectory() as tmp:
        card = a.params
        if card is None:
            card = Path(tmp) / "a1.yaml"
            card.write_text(yaml.safe_dump(a1()))
        for name, extra in CASES:
            walls, codes, line = [], set(), ""
            for k in range(a.repeat):
                cmd = [sys.executable, "-m", "bpmcal.cli", "ucs", "--params", str(card),
                       *extra, "--out", f"{tmp}/x{k}.h5", "--specimen-cache",
                       f"{tmp}/cache{k}"]
                t0 = time.perf_counter()
                p = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
                walls.append(time.perf_counter() - t0)
                codes.add(p.returncode)
                line = (p.stderr.strip().splitlines() or [""])[0]
            row = {"case": name, "args": extra, "wall_s": walls,
                   "median_wall_s": statistics.median(walls), "exit_codes": sorted(codes),
                   "stderr_lines": len(p.stderr.strip().splitlines()), "line": line}
            out["cases"].append(row)
            print(f"{name}: median {row['median_wall_s']:.2f} s over {a.repeat} "
                  f"(runs {', '.join(f'{w:.2f}' for w in walls)}), exit {sorted(codes)}, "
                  f"{row['stderr_lines']} line(s): {line}")
    out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"peak memory of a child: {out['peak_rss_mb']:.0f} MB")
    if a.json:
        a.json.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
