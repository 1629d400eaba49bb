"""Runs side by side: what the default thread count costs when two bpmcal runs (or a run
and another busy process) share the machine.

    python benchmarks/concurrent_runs.py [--scale 0.4] [--repeat 3] [--skip-forced]
        [--json benchmarks/results/results_concurrent_runs_DATE.json]

Each scenario starts ``bpmcal ucs`` processes at the same moment (the paper's A1 card,
``tests/support/paper.py``, at ``--scale``; cached packings, warmed first) and takes each
process's wall time and CPU time (``os.wait4``) and the thread count its run file records
(``threads``):

- ``alone``: one run; ``pair``: two runs at once; ``busy``: one run beside a process that
  keeps one core busy (a Python loop);
- the thread setting of every run in the scenario: ``default`` (no ``--threads``: the
  run chooses, ``bpmcal.dem.threads``), ``t1`` (``--threads 1``), ``t2`` (``--threads 2``,
  numba's default before that rule: every CPU). ``--skip-forced`` leaves out ``pair t2``
  and ``busy t2`` (the slow ones: minutes each); ``--only`` names the scenarios to run
  (``alone t1`` is always run: the reference); ``--env`` sets a variable for every run
  (e.g. ``GOMP_SPINCOUNT=0``, OpenMP's spin before a waiting thread sleeps).

The table gives the median wall time per run of each scenario and its ratio to ``alone
t1`` of the same invocation.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

from peers import host_info  # noqa: E402

BUSY = "import time\nt = time.time() + {s}\nwhile time.time() < t:\n    pass\n"


def _card(tmp: Path) -> Path:
    import yaml

    from bpmcal.study.paper import A1  # the paper's card
    p = tmp / "a1.yaml"
    p.write_text(yaml.safe_dump({k: float(v) for k, v in A1.items()}))
    return p


def _cmd(card, scale, out, threads, cache):
    c = [sys.executable, "-m", "bpmcal.cli", "ucs", "--params", str(card), "--scale",
         str(scale), "--seed", "1", "--specimen-cache", str(cache), "--out", str(out)]
    return c + ([] if threads is None else ["--threads", str(threads)])


def scenario(kind, threads, card, scale, tmp, cache, env=None) -> list[dict]:
    """Start the scenario's processes at once; each run's wall, CPU and threads."""
    n = 2 if kind == "pair" else 1
    busy = None
    if kind == "busy":
        busy = subprocess.Popen([sys.executable, "-c", BUSY.format(s=3600)])
        time.sleep(0.5)
    outs = [tmp / f"{kind}_{threads}_{q}.h5" for q in range(n)]
    for o in outs:
        o.unlink(missing_ok=True)
    t0 = time.perf_counter()
    procs = [subprocess.Popen(_cmd(card, scale, o, threads, cache), stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, env={**os.environ, **(env or {})})
             for o in outs]
    res = {}
    while len(res) < n:
        pid, status, ru = os.wait4(-1, 0)
        for q, p in enumerate(procs):
            if p.pid == pid:
                res[q] = {"wall_s": time.perf_counter() - t0, "cpu_s": ru.ru_utime + ru.ru_stime,
                          "rc": os.waitstatus_to_exitcode(status)}
    if busy is not None:
        busy.kill()
        busy.wait()
    from bpmcal.io.h5 import read_summary
    for q, o in enumerate(outs):
        if res[q]["rc"] != 0:
            raise SystemExit(f"{kind} {threads}: run {q} failed: "
                             f"{procs[q].stderr.read().decode()[-500:]}")
        procs[q].stderr.close()
        res[q]["threads"] = int(read_summary(o)["threads"])
    return [res[q] for q in range(n)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=0.4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-forced", action="store_true")
    ap.add_argument("--env", action="append", default=[], metavar="NAME=VALUE",
                    help="an environment variable for every run (e.g. GOMP_SPINCOUNT=0)")
    ap.add_argument("--only", default=None,
                    help="comma-separated scenarios to run, e.g. 'alone t1,pair t2'")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    env = dict(e.split("=", 1) for e in a.env)
    scen = [("alone", 1), ("alone", None), ("alone", 2), ("pair", 1), ("pair", None),
            ("busy", 1), ("busy", None)]
    if not a.skip_forced:
        scen += [("pair", 2), ("busy", 2)]
    if a.only:
        want = [w.split() for w in a.only.split(",")]
        scen = [(k, None if t == "default" else int(t[1:])) for k, t in want]
        if ("alone", 1) not in scen:
            scen.insert(0, ("alone", 1))
    load0 = os.getloadavg()
    runs = []
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        card = _card(tmp)
        cache = tmp / "packings"
        scenario("alone", 1, card, a.scale, tmp, cache, env)  # warm: packing cache, numba cache
        for r in range(a.repeat):
            for kind, th in scen:
                for x in scenario(kind, th, card, a.scale, tmp, cache, env):
                    runs.append({"scenario": kind, "threads_opt": th, "repeat": r, **x})
                    print(f"repeat {r + 1}: {kind:5s} {('default' if th is None else f't{th}'):7s}"
                          f" wall {x['wall_s']:7.2f} s  CPU {x['cpu_s']:7.2f} s  "
                          f"threads {x['threads']}", flush=True)
    rows = []
    base = None
    for kind, th in scen:
        xs = [x for x in runs if x["scenario"] == kind and x["threads_opt"] == th]
        w = statistics.median(x["wall_s"] for x in xs)
        c = statistics.median(x["cpu_s"] for x in xs)
        if (kind, th) == ("alone", 1):
            base = w
        rows.append({"scenario": kind, "threads_opt": th, "wall_s_median": w,
                     "cpu_s_median": c, "threads_seen": sorted({x["threads"] for x in xs}),
                     "n": len(xs)})
    print(f"\n{'scenario':9s} {'--threads':>9s} {'wall/run (s)':>13s} {'CPU/run (s)':>12s} "
          f"{'x alone t1':>10s} {'threads used':>12s}")
    for x in rows:
        x["ratio_to_alone_t1"] = x["wall_s_median"] / base
        th = "default" if x["threads_opt"] is None else str(x["threads_opt"])
        print(f"{x['scenario']:9s} {th:>9s} {x['wall_s_median']:13.2f} {x['cpu_s_median']:12.2f} "
              f"{x['ratio_to_alone_t1']:10.2f} {str(x['threads_seen']):>12s}")
    if a.json:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=REPO).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "src"], capture_output=True,
                               text=True, cwd=REPO).stdout.strip()
        Path(a.json).write_text(json.dumps({
            "date": time.strftime("%Y-%m-%d"), "commit": commit + ("+dirty" if dirty else ""),
            "host": host_info(), "load_start": load0, "load_end": os.getloadavg(),
            "command": "python benchmarks/concurrent_runs.py " + " ".join(argv or sys.argv[1:]),
            "args": vars(a), "rows": rows, "runs": runs}, indent=1))
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
