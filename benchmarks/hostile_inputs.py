"""How hostile and unlucky inputs end (issue 55): every case of ``tests/support/hostile.py``
run as a user runs it (a fresh ``bpmcal`` process), judged and counted by class.

    python benchmarks/hostile_inputs.py [--src CHECKOUT/src] [--slow] [--json out.json]

``--src`` is the bpmcal under test (its ``src`` folder, put first on PYTHONPATH: e.g. a
``git worktree`` of an older commit); the cases, their inputs and the judge are this
checkout's. Each case prints one line: ``clean`` or what was wrong (a traceback, a hang,
the wrong exit code, files left, ...), with its wall time. The full-disk case mounts a
64 kB tmpfs and needs root (skipped otherwise); ``--slow`` adds the cases of minutes
(a triaxial test, a damaged numba cache that is compiled again).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from support.hostile import (  # noqa: E402
    CASES,
    CLASSES,
    SETUPS,
    files_beside,
    judge,
    make_inputs,
    run,
)


def _tiny(tmp: Path) -> Path | None:
    m = tmp / "tiny"
    m.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return None
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(m)],
                       capture_output=True)
    return m if r.returncode == 0 else None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", type=Path, default=ROOT / "src",
                    help="the src folder of the bpmcal under test (default this checkout's)")
    ap.add_argument("--slow", action="store_true", help="also the cases of minutes")
    ap.add_argument("--only", default=None, help="run the cases whose id contains this")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    env = {**os.environ, "PYTHONPATH": str(a.src.resolve())}
    rows = []
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        d = make_inputs(tmp / "in")
        cache = tmp / "cache"
        cache.mkdir()
        tiny = _tiny(tmp)
        try:
            for k, case in enumerate(CASES):
                if (case.slow and not a.slow) or (a.only and a.only not in case.id):
                    continue
                if case.root and tiny is None:
                    rows.append({"case": case.id, "class": case.cls, "skipped": "needs root"})
                    continue
                o = tmp / f"out{k}"
                try:
                    if case.setup:
                        SETUPS[case.setup](o, env)
                except Exception as e:  # noqa: BLE001 - reported as the case's result
                    rows.append({"case": case.id, "class": case.cls,
                                 "skipped": f"setup failed: {e}"})
                    continue
                before = files_beside(d)
                ending = run(case, d, o, cache, repo=ROOT, env=env, tiny=tiny,
                             timeout=max(120.0, 3 * case.max_s))
                problems = judge(case, ending, o, before, files_beside(d))
                if tiny is not None and case.root:
                    left = [p.name for p in tiny.iterdir()]
                    problems += [f"left on the full disk: {left}"] if left else []
                    for p in tiny.iterdir():
                        p.unlink()
                row = {"case": case.id, "class": case.cls, "exit": ending.code,
                       "wall_s": round(ending.wall_s, 2), "problems": problems,
                       "stderr_tail": ending.stderr.strip().splitlines()[-1:]}
                rows.append(row)
                print(f"{case.cls:13s} {case.id:32s} {ending.wall_s:7.1f} s  exit "
                      f"{ending.code}  " + ("clean" if not problems else "; ".join(problems)),
                      flush=True)
        finally:
            if tiny is not None:
                subprocess.run(["umount", str(tiny)], capture_output=True)
    ran = [r for r in rows if "skipped" not in r]
    print("\nby class (clean / run):")
    total = Counter()
    for cls in CLASSES:
        n = [r for r in ran if r["class"] == cls]
        ok = sum(not r["problems"] for r in n)
        total.update(clean=ok, run=len(n))
        kinds = Counter(p.split(":")[0].split(" ")[0] for r in n for p in r["problems"][:1])
        print(f"  {cls:13s} {ok:3d} / {len(n):3d}   " + ", ".join(f"{v} {k}" for k, v in
                                                             sorted(kinds.items())))
    print(f"  {'all':13s} {total['clean']:3d} / {total['run']:3d}")
    for r in rows:
        if "skipped" in r:
            print(f"  skipped {r['case']}: {r['skipped']}")
    if a.json:
        a.json.write_text(json.dumps({"src": str(a.src), "cases": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
