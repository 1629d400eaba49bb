"""How hostile and unlucky inputs end (issue 55): every case of ``tests/support/hostile.py``
run as a user runs it (a fresh ``bpmcal`` process), judged and counted by class.

    python benchmarks/hostile_inputs.py [--src CHECKOUT/src] [--slow] [--json out.json]

    python benchmarks/hostile_inputs.py --record BEFORE.json AFTER.json  # the tables

``--src`` is the bpmcal under test (its ``src`` folder, put first on PYTHONPATH: e.g. a
``git worktree`` of an older commit), whose config files and schema the config cases
validate against; the cases, their inputs and the judge are this checkout's. Each case
prints one line: ``clean`` or what was wrong (a traceback, a hang, the wrong exit code,
files left, ...), with its wall time; a case that does not end in
``support.hostile.timeout_of`` seconds is a hang (a process without a DEM run is limited
to 4 GB of address space, so reading /dev/zero cannot take the machine). The full-disk
case mounts a 64 kB tmpfs and needs root (skipped otherwise); ``--slow`` adds the cases
the fast test tier leaves out (minutes: a triaxial test, a damaged numba cache compiled
again; seconds: three more small DEM runs).
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


def scrub(rows: list, tmp: str, src: str, label: str) -> list:
    """``rows`` with the run's temporary folder and the checkout's path replaced by
    ``<tmp>`` and ``label`` (a record names no path outside the repository)."""
    text = json.dumps(rows).replace(tmp, "<tmp>").replace(src, label)
    return json.loads(text)


def _kind(row: dict) -> str:
    """One word for how a case ended: clean, or its worst problem: a hang, a crash (a
    signal), a traceback, accepted (exit 0 where a refusal or a failed measurement was
    due), the wrong exit code, unclear (the right code, but not one line naming the value)
    or wrong output (an escape printed raw, a value gathered, files left)."""
    if "skipped" in row:
        return "skipped"
    if not row["problems"]:
        return "clean"
    first = row["problems"][0]
    for word in ("hang", "crash", "traceback"):
        if any(p.startswith(word) for p in row["problems"]):
            return word
    if first.startswith("exit 0"):
        return "accepted"
    if first.startswith("exit"):
        return "wrong exit"
    return "unclear" if "stderr does not say" in first or "line" in first else "wrong output"


def markdown(before: dict, after: dict) -> str:
    """The record's tables: cases by class, clean before and after, and every case."""
    b = {r["case"]: r for r in before["cases"]}
    a = {r["case"]: r for r in after["cases"]}
    out = ["| class | what | cases | clean before | clean after |", "|---|---|---|---|---|"]
    for cls, what in CLASSES.items():
        ids = [c.id for c in CASES if c.cls == cls and c.id in a and c.id in b]
        out.append(f"| {cls} | {what} | {len(ids)} | "
                   f"{sum(_kind(b[i]) == 'clean' for i in ids)} | "
                   f"{sum(_kind(a[i]) == 'clean' for i in ids)} |")
    both = [c.id for c in CASES if c.id in a and c.id in b]
    out.append(f"| all | | {len(both)} | {sum(_kind(b[i]) == 'clean' for i in both)} | "
               f"{sum(_kind(a[i]) == 'clean' for i in both)} |")
    kinds = ("clean", "accepted", "traceback", "crash", "hang", "wrong exit", "unclear",
             "wrong output", "skipped")
    out += ["", "| ending | before | after |", "|---|---|---|"]
    out += [f"| {k} | {sum(_kind(b[i]) == k for i in both)} | "
            f"{sum(_kind(a[i]) == k for i in both)} |" for k in kinds
            if any(_kind(r[i]) == k for r in (a, b) for i in both)]
    out += ["", "| case | class | before: exit, ending | after: exit, ending |", "|---|---|---|---|"]
    for i in both:
        cells = []
        for r in (b[i], a[i]):
            k = _kind(r)
            why = "" if k in ("clean", "skipped") else f": {r['problems'][0][:70]}"
            cells.append(f"{r.get('exit')}, {k}{why}".replace("|", "/"))
        out.append(f"| `{i}` | {a[i]['class']} | {cells[0]} | {cells[1]} |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", type=Path, default=ROOT / "src",
                    help="the src folder of the bpmcal under test (default this checkout's)")
    ap.add_argument("--slow", action="store_true",
                    help="also the cases the fast test tier leaves out")
    ap.add_argument("--only", default=None, help="run the cases whose id contains this")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--label", default=None,
                    help="how the JSON names the bpmcal under test (default its src path)")
    ap.add_argument("--record", nargs=2, type=Path, metavar=("BEFORE", "AFTER"),
                    help="print the record's tables of two --json results and stop")
    a = ap.parse_args(argv)
    if a.record:
        print(markdown(*(json.loads(f.read_text()) for f in a.record)), end="")
        return 0
    env = {**os.environ, "PYTHONPATH": str(a.src.resolve())}
    repo = a.src.resolve().parent  # the checkout under test: its config files and schema
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
                ending = run(case, d, o, cache, repo=repo, env=env, tiny=tiny)
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
        label = a.label or str(a.src)
        a.json.write_text(json.dumps({"src": label, "cases": scrub(rows, t, str(a.src.resolve()),
                                                                   label)}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
