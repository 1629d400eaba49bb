"""Genesis share of the study's sample job, phase by phase, in CPU seconds.

    python benchmarks/genesis_share.py --design DESIGN.csv \
        --samples s000 s017 s050 s096 s110 [--src new=src old=/path/to/other/src] \
        [--repeat 1] [--json out.json]

The sample job is what the workflow's rule ``sample`` runs for one design row: ``bpmcal
sample --design ... --sample sNNN --out U.h5 --bts-out B.h5`` with the default study's options
(``study_args()``: the workflow's command of config/config.yaml, built by the parent with
``bpmcal.cli.jobs.job_argv``: scale 0.4, pfc genesis, one thread, the bts section): a
UCS test on a 20 x 40 mm cylinder and a Brazilian test on a 20 x 10 mm disc, each with
its own genesis. Every job runs in a fresh process (numba's kernels come from its on-disk
cache, as in a study) with a fresh, empty specimen cache, so each genesis packs and
relaxes its balls as it does in a study.

In the child process the phases are timed by wrapping the functions that run them
(``time.process_time``, CPU seconds of the process). Each timed call is a node of a path,
``ucs/genesis/packing/relax/steps``; the table lists the seconds of each path without its
timed children:

- per test (``ucs``, ``bts``): ``genesis`` (``runner.make_specimen``) and inside it
  ``packing`` (``get_packing``: ``distribute``, ``steps`` = the speed-capped steps,
  ``relax`` = the ``_solve`` to the relax ratio, ``floaters``) and ``build``
  (``build_specimen``: the material, ``settle_vessel``, bonding, ``count_touching``,
  ``settle_free``); ``test`` (``run_ucs`` / ``run_bts``); ``write`` (the run file);
- ``numba_load`` / ``numba_init``: numba's start-up, the loading of each kernel from the
  on-disk cache at its first call and, inside the first one, the one-time set-up of
  numba's compiler context; whatever calls a kernel first pays it (the UCS genesis);
- ``other``: the job's CPU seconds (the child's rusage, measured by the parent) minus
  the two tests: interpreter start-up, imports, input checks, the run files.

The genesis share is (genesis of both tests) / (the whole job's CPU seconds, start-up
included); it is also given without numba's start-up (in the genesis and in the job).
Medians over samples (and repeats) are printed per source tree. With several ``--src``
trees each sample runs with each tree in turn (the order alternates), and the run files of
the trees are compared: every dataset and every attribute except the timings (``*_s``)
must be bitwise the same for a job to count as identical.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: the sample job's options that name its files, which the child sets itself
FILE_OPTIONS = ("--design", "--sample", "--out", "--bts-out", "--specimen-cache")


def study_args(config=None) -> list[str]:
    """The default study's options of the sample job (the workflow's command:
    ``bpmcal.cli.jobs.job_argv`` of config/config.yaml, or ``config``) without the
    subcommand and the options naming files, which the child sets per job."""
    from _study import CONFIG, study_config, study_targets

    from bpmcal.cli.jobs import job_argv

    cfg = study_config(config or CONFIG)
    argv = job_argv(cfg, "sample", input={"design": "D"}, wildcards={"sample": "S"},
                    output={"ucs": "U", "bts": "B"}, threads=cfg["resources"]["dem_threads"],
                    targets=study_targets(cfg))
    out, skip = [], False
    for a in argv[1:]:
        if skip:
            skip = False
        elif a in FILE_OPTIONS:
            skip = True
        else:
            out.append(a)
    return out


#: the summary values compared and printed
RESULTS = {"ucs": ("ucs_MPa", "E_GPa", "nu"), "bts": ("bts_MPa",)}


# ------------------------------------------------------------------ child: one timed job
class Timer:
    """CPU and wall seconds of nested phases: each wrapped call is a node of a path
    (``ucs/genesis/packing/relax/steps``); ``excl`` holds the seconds of a path without
    its timed children, ``incl`` with them."""

    def __init__(self):
        self.incl = {}
        self.excl = {}
        self.stack = []  # [path, cpu at entry, cpu of the timed children]

    def wrap(self, owner, name, label):
        f = getattr(owner, name, None)
        if f is None:
            return
        timer = self

        def wrapped(*a, **k):
            lab = label
            if label == "solve":  # the settling phases of _solve
                lab = {"relax packing": "relax", "settle in vessel": "settle_vessel",
                       "settle bonded": "settle_free"}.get(k.get("phase", ""), "solve")
            path = f"{timer.stack[-1][0]}/{lab}" if timer.stack else lab
            timer.stack.append([path, time.process_time(), 0.0])
            try:
                return f(*a, **k)
            finally:
                p, c0, kids = timer.stack.pop()
                dt = time.process_time() - c0
                timer.incl[p] = timer.incl.get(p, 0.0) + dt
                timer.excl[p] = timer.excl.get(p, 0.0) + dt - kids
                if timer.stack:
                    timer.stack[-1][2] += dt

        setattr(owner, name, wrapped)


def digest(path) -> dict:
    """The results of a run file and a hash of everything in it but the timings."""
    import h5py
    import numpy as np

    h = hashlib.sha256()
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                h.update(name.encode())
                h.update(np.ascontiguousarray(obj[()]).tobytes())
        f.visititems(visit)
        for grp in ("summary", "genesis"):
            if grp in f:
                for k in sorted(f[grp].attrs):
                    if not k.endswith("_s"):
                        h.update(f"{grp}.{k}={f[grp].attrs[k]!r}".encode())
        s = f["summary"].attrs
        g = f["genesis"].attrs if "genesis" in f else {}
        out = {k: float(s[k]) for k in ("ucs_MPa", "E_GPa", "nu", "bts_MPa") if k in s}
        out.update({k: int(g[k]) for k in ("n_balls", "relax_steps", "settle_walls_steps",
                                           "settle_free_steps") if k in g})
        out["test_steps"] = int(s["steps"]) if "steps" in s else -1
        out["status"] = str(f.attrs.get("status"))
    out["sha256"] = h.hexdigest()[:16]
    return out


def child(a) -> int:
    c_start = time.process_time()
    from bpmcal import cli
    from bpmcal.lab import runner, specimen
    from bpmcal.stages import runs

    tm = Timer()
    # the tests: per test before the lab-test driver and registry (one lab_test, one
    # run_test since), as a --src of either kind has them
    tests = ({"ucs_test": "ucs", "bts_test": "bts"} if hasattr(runs, "ucs_test")
             else {"lab_test": "ucs+bts"})
    driver = ({"run_ucs": "test", "run_bts": "test"} if hasattr(runner, "run_ucs")
              else {"run_test": "test"})
    for owner, names in ((runs, {**tests, "write_lab_run": "write"}),
                         (runner, {"make_specimen": "genesis", "get_packing": "packing",
                                   "build_specimen": "build", **driver}),
                         # cycle: the genesis's steps (its calls of stepping.cycle)
                         (specimen, {"distribute": "distribute", "_solve": "solve",
                                     "_settle_force_free": "settle_free",
                                     "_fix_floaters": "floaters",
                                     "_count_touching": "count_touching", "cycle": "steps"})):
        for name, label in names.items():
            tm.wrap(owner, name, label)
    # numba's start-up: the one-time set-up of its compiler context (the registries of
    # its numpy implementations, scipy.linalg for BLAS), paid by the first kernel call
    # of the process, and loading each kernel from the on-disk cache at its first call;
    # whatever runs first pays them (here: the UCS genesis)
    from numba.core.cpu import CPUContext
    from numba.core.dispatcher import Dispatcher
    tm.wrap(CPUContext, "load_additional_registries", "numba_init")
    tm.wrap(Dispatcher, "_compile_for_args", "numba_load")
    out = Path(a.out)
    # the sample job's command: ``sample``; a --src older than its rename calls it ``ucs``
    cmd = "sample" if "sample" in cli.COMMANDS else "ucs"
    argv = [cmd, "--design", a.design, "--sample", a.sample, "--out", str(out / "ucs.h5"),
            "--bts-out", str(out / "bts.h5"), "--specimen-cache", str(out / "cache"),
            *json.loads(a.study_args)]
    c0, t0 = time.process_time(), time.perf_counter()
    rc = cli.main(argv)
    res = {"rc": rc, "job_cpu": time.process_time() - c0, "imports_cpu": c0 - c_start,
           "job_wall": time.perf_counter() - t0, "excl": tm.excl, "incl": tm.incl}
    print("GENESIS_SHARE " + json.dumps(res))
    return 0


# ------------------------------------------------------------------ parent
def run_job(src, design, sample) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(Path(src).resolve())
    env.pop("BPMCAL_SPECIMEN_CACHE", None)
    with tempfile.TemporaryDirectory() as tmp:
        env["BPMCAL_SPECIMEN_CACHE"] = str(Path(tmp) / "cache")
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        p = subprocess.run([sys.executable, __file__, "--child", "--design", design,
                            "--sample", sample, "--out", tmp,
                            "--study-args", json.dumps(study_args())], env=env,
                           capture_output=True, text=True)
        wall = time.perf_counter() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        line = [x for x in p.stdout.splitlines() if x.startswith("GENESIS_SHARE ")]
        if p.returncode != 0 or not line:
            raise RuntimeError(f"job {sample} with {src} failed:\n{p.stdout}\n{p.stderr}")
        res = json.loads(line[-1].split(" ", 1)[1])
        res["files"] = {t: digest(Path(tmp) / f"{t}.h5") for t in ("ucs", "bts")}
    total = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    res["total_cpu"] = total
    res["total_wall"] = wall
    return res


def breakdown(res) -> dict:
    """CPU seconds of one job: ``total`` (the process), ``other`` (outside both tests:
    interpreter, imports, input checks), every timed path (exclusive seconds), and the
    summary lines ``genesis`` (both tests' genesis, inclusive), ``numba_startup`` (all
    of the job, and the part of it in the genesis), the genesis share with and without
    numba's start-up."""
    ex, inc = res["excl"], res["incl"]
    d = {"total": res["total_cpu"],
         "other": res["total_cpu"] - inc.get("ucs", 0.0) - inc.get("bts", 0.0)}
    d.update({f"  {p}": v for p, v in sorted(ex.items())})
    d["genesis"] = inc.get("ucs/genesis", 0.0) + inc.get("bts/genesis", 0.0)
    # numba's start-up (the outermost numba_load of each path; numba_init is inside one)
    top = {p: v for p, v in inc.items() if p.endswith("numba_load")
           and p.count("numba_load") == 1}
    d["numba_startup"] = sum(top.values())
    d["genesis_numba_startup"] = sum(v for p, v in top.items() if "/genesis/" in p)
    d["tests"] = inc.get("ucs/test", 0.0) + inc.get("bts/test", 0.0)
    d["share"] = d["genesis"] / d["total"]
    d["share_without_numba_startup"] = ((d["genesis"] - d["genesis_numba_startup"])
                                        / (d["total"] - d["numba_startup"]))
    return d


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--design", required=False, default=None)
    ap.add_argument("--samples", nargs="*", default=["s000", "s017", "s050", "s096", "s110"])
    ap.add_argument("--src", nargs="*", default=None,
                    help="NAME=PATH of source trees (default: this tree's src)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--json", default=None)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--sample", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    ap.add_argument("--study-args", help=argparse.SUPPRESS)  # the parent's study_args()
    a = ap.parse_args(argv)
    if a.child:
        return child(a)
    if a.design is None:
        ap.error("--design is required (e.g. a study's results/design/samples.csv)")
    here = Path(__file__).resolve().parent.parent / "src"
    srcs = dict(s.split("=", 1) for s in a.src) if a.src else {"this": str(here)}
    names = list(srcs)
    for name in names:  # numba: compile or load the kernels of every tree once, untimed
        run_job(srcs[name], a.design, a.samples[0])
    runs = []
    k = 0
    for rep in range(a.repeat):
        for sample in a.samples:
            order = names if k % 2 == 0 else names[::-1]
            k += 1
            for name in order:
                res = run_job(srcs[name], a.design, sample)
                b = breakdown(res)
                runs.append({"repeat": rep, "sample": sample, "src": name, "breakdown": b,
                             "files": res["files"], "raw": res})
                f = res["files"]
                inc = res["incl"]
                print(f"{sample} {name:>8s}: job {b['total']:6.2f} s cpu, genesis "
                      f"{b['genesis']:5.2f} s ({100 * b['share']:4.1f} %, without numba's "
                      f"start-up {100 * b['share_without_numba_startup']:4.1f} %; ucs "
                      f"{inc.get('ucs/genesis', 0):.2f}, bts {inc.get('bts/genesis', 0):.2f}"
                      f"), tests {inc.get('ucs/test', 0):.2f} + {inc.get('bts/test', 0):.2f}, "
                      f"other {b['other']:.2f}; sigma_c {f['ucs'].get('ucs_MPa', float('nan')):.4f} "
                      f"MPa, E {f['ucs'].get('E_GPa', float('nan')):.4f} GPa, nu "
                      f"{f['ucs'].get('nu', float('nan')):.4f}, sigma_t "
                      f"{f['bts'].get('bts_MPa', float('nan')):.4f} MPa "
                      f"[{f['ucs']['sha256']} {f['bts']['sha256']}]", flush=True)
    print("\nCPU seconds, median over samples and repeats:")
    keys = list(dict.fromkeys(k for r in runs for k in r["breakdown"]))
    print(f"{'phase (exclusive, indented; inclusive, flush)':44s}"
          + "".join(f"{n:>10s}" for n in names))
    med = {}
    for n in names:
        rs = [r["breakdown"] for r in runs if r["src"] == n]
        med[n] = {key: statistics.median([x.get(key, 0.0) for x in rs]) for key in keys}
    for key in keys:
        print(f"{key:44s}" + "".join(f"{med[n][key]:10.3f}" for n in names))
    if len(names) > 1:
        same = {}
        for r in runs:
            same.setdefault((r["repeat"], r["sample"]), {})[r["src"]] = r["files"]
        ident = [len({json.dumps(v[n]["ucs"]["sha256"]) + v[n]["bts"]["sha256"]
                      for n in names}) == 1 for v in same.values()]
        print(f"run files bitwise identical across trees: {sum(ident)} of {len(ident)} jobs")
    if a.json:
        Path(a.json).write_text(json.dumps({"args": vars(a), "runs": runs, "median": med},
                                           indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
