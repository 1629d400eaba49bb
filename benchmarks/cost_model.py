"""The cost model of a finished study: CPU seconds and particle-steps per rule and per
phase, from the jobs' logs and the run files.

    python benchmarks/cost_model.py --study CLONE/results [--snakemake-log study.log] \\
        [--bench-n 10000] [--label LABEL] --out benchmarks/results/results_cost_model_DATE_NAME.json \\
        --markdown docs/measurements/DATE-cost-model-NAME.md
    python benchmarks/cost_model.py --render benchmarks/results/results_cost_model_DATE_NAME.json \\
        --markdown docs/measurements/DATE-cost-model-NAME.md

What it reads (``bpmcal.cost`` books it; the workflow sets ``BPMCAL_COST``):

- every job's log (``<study>/logs/<rule>[/<id>].log``): the job's cost line, ``bpmcal
  <command>: cost {...}``, written when the job ends: the CPU seconds of its process
  (``cpu_s``) and of its finished child processes (``children_cpu_s``: the workers of
  a seed pool, git), CPU seconds and the engine's ball-steps by phase path, and those
  its pool workers reported;
- the run files (``<study>/ucs/<id>.h5``, ``bts/<id>.h5``, ...): each one's ``/cost``
  group, the share of its process it stands for (what the process spent since the run
  file before it), and its summary (balls, steps, discs);
- with ``--snakemake-log``: each rule's job time (wall, from Snakemake's stamps) and how
  busy its jobs kept the cores they held (CPU seconds over wall x threads: a seed pool
  waiting for its last seed, or a loaded host, shows as less than 100 %).

A phase path's category (``category``): ``start`` (the interpreter and imports up to the
command's start), ``imports`` (the run machinery imported later), ``inputs`` (reading
and checking the inputs), ``kernels: numba's set-up`` and ``kernels: loading`` (numba
setting up its compiler context once, loading each kernel at its first call),
``genesis: packing``/``genesis: build`` (each split into the engine's steps and the rest:
distributing, the cache, bonding), ``test: engine`` and ``test: records`` (the test's
steps: a Brazilian disc's seating and loading, a cylinder's loading, a triaxial test's
consolidation and loading; the work between them: records, servo, checks, progress),
``results`` (the failure morphology), ``write`` (the run files), ``retests`` (the
Brazilian discs after the first, all their phases), ``other`` (what no phase holds).

The engine's rate inside the jobs (ball-steps of the engine over the engine's CPU
seconds) and the sample jobs' particle-steps per CPU-second (the two tests' steps
x balls over the whole job's CPU seconds, start-up and genesis included) are set
beside the engine's own benchmark (``dem_throughput.py``, ``--bench-n`` balls, one
thread, run in the same invocation: its particle-steps per CPU-second).

Bookkeeping: a job's phases sum to its process's CPU seconds by construction (``other``
is the rest); how much ``other`` holds, and how the jobs' CPU compares with an outside
measure of the process (``tests/unit/test_cost.py``), say whether the phases
account for the job.
"""
from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
from pathlib import Path

from _study import record_header, write_record

HERE = Path(__file__).resolve().parent

#: the order of the categories in the tables
CATEGORIES = ("start", "imports", "inputs", "kernels: numba's set-up", "kernels: loading",
              "genesis: packing (engine)",
              "genesis: packing (rest)", "genesis: build (engine)", "genesis: build (rest)",
              "test: engine", "test: records", "results", "write", "retests",
              "engine (elsewhere)", "other", "work (no DEM)")
#: the rule of the sample jobs: ``sample``; studies finished before its rename call it
#: ``ucs`` (their logs are in ``logs/ucs/``, their records name rule ``ucs``), so both are
#: read as the sample jobs
SAMPLE_RULES = ("sample", "ucs")
#: the cost line in a job's log
_LINE = re.compile(r"^bpmcal (\S+): cost (\{.*\})\s*$", re.M)


def category(path: str) -> str:
    """The category of a phase path (module doc)."""
    if path in ("start", "imports", "inputs", "write", "other"):
        return path
    if path == "kernels":
        return "kernels: loading"
    if path == "kernels_setup":
        return "kernels: numba's set-up"
    parts = path.split("/")
    if parts[0].endswith("_retest"):
        return "retests"
    engine = parts[-1] == "engine"
    rest = parts[1:]
    if "genesis" in rest:
        i = rest.index("genesis")
        sub = rest[i + 1] if len(rest) > i + 1 and rest[i + 1] != "engine" else "build"
        return f"genesis: {sub} ({'engine' if engine else 'rest'})"
    if "test" in rest:
        return "test: engine" if engine else "test: records"
    if "results" in rest:
        return "results"
    if "write" in rest:
        return "write"
    return "engine (elsewhere)" if engine else "other"


def test_steps(path: str) -> bool:
    """Whether a phase path's ball-steps are a test's own steps (not genesis, not a
    discarded disc)."""
    parts = path.split("/")
    return (not parts[0].endswith("_retest") and "test" in parts[1:]
            and "genesis" not in parts)


_STAMP = r"\[(\w{3} \w{3} +\d+ \d\d:\d\d:\d\d \d{4})\]\n"


def snakemake_jobs(log: Path) -> dict:
    """Each job of Snakemake's log (its stderr) by its log file (``logs/...``, the part
    of the path from ``logs/`` on): its rule and its wall seconds, from its start stamp
    to its ``Finished jobid`` stamp."""
    import datetime as dt

    text = Path(log).read_text(errors="replace")

    def when(stamp):
        return dt.datetime.strptime(" ".join(stamp.split()), "%a %b %d %H:%M:%S %Y")

    start = {}
    for m in re.finditer(_STAMP + r"(?:local)?rule (\S+):\n((?:    .*\n)*)", text):
        block = m.group(3)
        jid = re.search(r"    jobid: (\d+)", block)
        lg = re.search(r"    log: (\S+)", block)
        th = re.search(r"    threads: (\d+)", block)
        if jid and lg:
            key = lg.group(1)[lg.group(1).find("logs/"):]
            start[jid.group(1)] = (key, m.group(2), when(m.group(1)),
                                   int(th.group(1)) if th else 1)
    out = {}
    for m in re.finditer(_STAMP + r"Finished jobid: (\d+)", text):
        if m.group(2) in start:
            key, rule, t0, threads = start[m.group(2)]
            out[key] = {"rule": rule, "wall_s": (when(m.group(1)) - t0).total_seconds(),
                        "threads": threads}
    return out


def read_jobs(study: Path, sm: dict | None = None) -> list[dict]:
    """One record per job log with a cost line: rule (Snakemake's, from its log ``sm``;
    else the log's folder), job id, wall seconds (from ``sm``), the cost line."""
    jobs = []
    logs = study / "logs"
    for f in sorted(logs.rglob("*.log")):
        rel = f.relative_to(logs)
        m = list(_LINE.finditer(f.read_text(errors="replace")))
        if not m:
            continue
        d = json.loads(m[-1].group(2))
        info = (sm or {}).get(f"logs/{rel.as_posix()}", {})
        rule = info.get("rule") or (rel.parts[0] if len(rel.parts) > 1 else rel.stem)
        jobs.append({"rule": rule, "job": rel.with_suffix("").as_posix(),
                     "command": m[-1].group(1), "wall_s": info.get("wall_s"),
                     "threads": info.get("threads", 1), **d})
    return jobs


def job_phases(job: dict) -> dict:
    """CPU seconds by phase path of a job, its pool workers' included."""
    out = dict(job["phases"])
    for k, v in job.get("worker_phases", {}).items():
        out[k] = out.get(k, 0.0) + v
    return out


def job_steps(job: dict) -> dict:
    out = dict(job["ball_steps"])
    for k, v in job.get("worker_ball_steps", {}).items():
        out[k] = out.get(k, 0) + v
    return out


def geneses(job: dict) -> tuple[int, int]:
    """(specimens built, packings relaxed: not read from the specimen cache) of a job."""
    calls = dict(job.get("calls", {}))
    for k, v in job.get("worker_calls", {}).items():
        calls[k] = calls.get(k, 0) + v
    built = sum(v for k, v in calls.items() if k.split("/")[-1] == "genesis")
    relaxed = sum(v for k, v in calls.items() if k.endswith("genesis/packing/relax"))
    return built, relaxed


def job_cpu(job: dict) -> float:
    """The job's CPU seconds: its process and its finished children."""
    return job["cpu_s"] + job["children_cpu_s"]


def run_file_costs(study: Path) -> list[dict]:
    """The ``/cost`` group and a few summary values of every run file of the study."""
    import h5py

    rows = []
    for f in sorted(study.rglob("*.h5")):
        try:
            with h5py.File(f, "r") as h:
                if "cost" not in h:
                    continue
                c = dict(h["cost"].attrs)
                s = dict(h["summary"].attrs) if "summary" in h else {}
                rows.append({"file": f.relative_to(study).as_posix(),
                             "test": str(h.attrs.get("test", "")),
                             "status": str(h.attrs.get("status", "")),
                             "cpu_s": float(c["cpu_s"]), "pid": int(c["pid"]),
                             "process_cpu_s": float(c["process_cpu_s"]),
                             "phases": json.loads(c["phases"]),
                             "ball_steps": json.loads(c["ball_steps"]),
                             "n_balls": int(s.get("n_balls", 0)),
                             "bonds_per_ball": float(s.get("bonds_per_ball", 0.0)),
                             "steps": int(s.get("steps", 0)),
                             "seat_steps": int(s.get("seat_steps", 0)),
                             "discs": int(s.get("discs", 1) or 1)})
        except OSError:
            continue
    return rows


def by_category(phases: dict, steps: dict | None = None) -> dict:
    """CPU seconds (and ball-steps) by category."""
    cpu, bs = {}, {}
    for k, v in phases.items():
        c = category(k)
        cpu[c] = cpu.get(c, 0.0) + v
    for k, v in (steps or {}).items():
        c = category(k)
        bs[c] = bs.get(c, 0) + v
    return {"cpu_s": cpu, "ball_steps": bs}


def _engine(phases: dict, steps: dict) -> tuple[float, int]:
    """The engine's CPU seconds and ball-steps."""
    cpu = sum(v for k, v in phases.items() if k.split("/")[-1] == "engine")
    return cpu, sum(steps.values())


def per_rule(jobs: list[dict]) -> list[dict]:
    rules = {}
    for j in jobs:
        r = rules.setdefault(j["rule"], {"rule": j["rule"], "jobs": 0, "cpu_s": 0.0,
                                         "ball_steps": 0, "test_ball_steps": 0,
                                         "engine_cpu_s": 0.0, "geneses": 0, "relaxed": 0})
        st, ph = job_steps(j), job_phases(j)
        r["jobs"] += 1
        built, relaxed = geneses(j)
        r["geneses"] += built
        r["relaxed"] += relaxed
        if j.get("wall_s") is not None:
            r["job_wall_s"] = r.get("job_wall_s", 0.0) + j["wall_s"]
            r["core_s"] = r.get("core_s", 0.0) + j["wall_s"] * j["threads"]
        r["cpu_s"] += job_cpu(j)
        r["ball_steps"] += sum(st.values())
        r["test_ball_steps"] += sum(v for k, v in st.items() if test_steps(k))
        r["engine_cpu_s"] += _engine(ph, st)[0]
    total = sum(r["cpu_s"] for r in rules.values()) or 1.0
    out = []
    for r in sorted(rules.values(), key=lambda r: -r["cpu_s"]):
        r["share"] = r["cpu_s"] / total
        r["ps_per_cpu_s"] = r["ball_steps"] / r["cpu_s"] if r["cpu_s"] else 0.0
        r["engine_ps_per_cpu_s"] = (r["ball_steps"] / r["engine_cpu_s"]
                                    if r["engine_cpu_s"] else 0.0)
        if r.get("core_s"):  # CPU seconds over the cores the jobs held (wall x threads)
            r["busy"] = r["cpu_s"] / r["core_s"]
        out.append(r)
    return out


def per_phase(jobs: list[dict], rules=None) -> dict:
    """CPU seconds, share and ball-steps by category over the jobs (of ``rules``)."""
    cpu, bs, n = {}, {}, 0
    for j in jobs:
        if rules and j["rule"] not in rules:
            continue
        n += 1
        c = by_category(job_phases(j), job_steps(j))
        if not sum(job_steps(j).values()):  # a job without DEM: its work is no phase's
            c["cpu_s"]["work (no DEM)"] = c["cpu_s"].pop("other", 0.0)
        for k, v in c["cpu_s"].items():
            cpu[k] = cpu.get(k, 0.0) + v
        for k, v in c["ball_steps"].items():
            bs[k] = bs.get(k, 0) + v
        # what the cost line's phases do not hold: the workers' CPU they did not report
        # (their start and end), measured as the children's CPU
        gap = j["children_cpu_s"] - sum(j.get("worker_phases", {}).values())
        if gap > 0:
            cpu["other"] = cpu.get("other", 0.0) + gap
    total = sum(cpu.values()) or 1.0
    return {"jobs": n, "total_cpu_s": total,
            "rows": [{"category": k, "cpu_s": cpu.get(k, 0.0), "share": cpu.get(k, 0.0) / total,
                      "ball_steps": bs.get(k, 0)} for k in CATEGORIES if k in cpu or k in bs]}


def sample_jobs(jobs: list[dict], runs: list[dict]) -> dict:
    """The sample jobs (rule ``sample``, or ``ucs`` in an older study: ``SAMPLE_RULES``):
    particle-steps per CPU-second, by job."""
    rows = []
    for j in jobs:
        if j["rule"] not in SAMPLE_RULES:
            continue
        ph, st = job_phases(j), job_steps(j)
        cpu = job_cpu(j)
        eng_cpu, eng_steps = _engine(ph, st)
        tsteps = sum(v for k, v in st.items() if test_steps(k))
        cat = by_category(ph)["cpu_s"]
        genesis = sum(v for k, v in cat.items() if k.startswith("genesis"))
        rows.append({"job": j["job"], "cpu_s": cpu, "test_ball_steps": tsteps,
                     "ball_steps": eng_steps, "engine_cpu_s": eng_cpu,
                     "ps_per_cpu_s": tsteps / cpu if cpu else 0.0,
                     "all_ps_per_cpu_s": eng_steps / cpu if cpu else 0.0,
                     "engine_ps_per_cpu_s": eng_steps / eng_cpu if eng_cpu else 0.0,
                     "genesis_share": genesis / cpu if cpu else 0.0,
                     "startup_share": (cat.get("start", 0.0) + cat.get("imports", 0.0)
                                       + cat.get("kernels: loading", 0.0)
                                       + cat.get("kernels: numba's set-up", 0.0)) / cpu
                     if cpu else 0.0,
                     "other_share": cat.get("other", 0.0) / cpu if cpu else 0.0})
    if not rows:
        return {"jobs": 0}
    tot = {k: sum(r[k] for r in rows) for k in ("cpu_s", "test_ball_steps", "ball_steps",
                                                "engine_cpu_s")}
    med = {k: statistics.median(r[k] for r in rows) for k in rows[0] if k != "job"}
    # the loading's bond-steps (balls x steps x bonds per ball / 2) over the engine's CPU
    # seconds of the loading, from the run files: the engine's speed per bond
    bond_steps, load_cpu = 0.0, 0.0
    for r in runs:
        for k, v in r["ball_steps"].items():
            if test_steps(k) and k.split("/")[0] in ("ucs", "bts"):
                bond_steps += v * r["bonds_per_ball"] / 2.0
                load_cpu += r["phases"].get(k, 0.0)
    ucs_runs = [r for r in runs if r["file"].startswith("ucs/") and r["status"] == "ok"]
    # the step count of the ledger against the run's own: balls x steps of the UCS test
    counted = [(sum(v for k, v in r["ball_steps"].items() if k == "ucs/test/engine"),
                r["n_balls"] * r["steps"]) for r in ucs_runs]
    return {"jobs": len(rows), "total": tot, "median": med,
            "ps_per_cpu_s": tot["test_ball_steps"] / tot["cpu_s"],
            "all_ps_per_cpu_s": tot["ball_steps"] / tot["cpu_s"],
            "engine_ps_per_cpu_s": tot["ball_steps"] / tot["engine_cpu_s"]
            if tot["engine_cpu_s"] else 0.0,
            "ucs_steps_match": sum(a == b for a, b in counted), "ucs_runs": len(counted),
            "loading_bond_steps_per_cpu_s": bond_steps / load_cpu if load_cpu else 0.0,
            "rows": rows}


def bench(n: int, steps: int) -> dict:
    """``dem_throughput.py`` at ``n`` balls, one thread, in its own process."""
    p = subprocess.run([sys.executable, str(HERE / "dem_throughput.py"), "--n", str(n),
                        "--threads", "1", "--steps", str(steps), "--json"],
                       capture_output=True, text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def _head() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE,
                              capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "not recorded"


def record(study: Path, label: str, snakemake_log, bench_n, bench_steps, argv,
           commit=None) -> dict:
    sm = snakemake_jobs(Path(snakemake_log)) if snakemake_log else None
    jobs = read_jobs(study, sm)
    runs = run_file_costs(study)
    rec = {**record_header("cost_model.py", argv), "study": label,
           "commit": commit or _head(),
           "jobs": len(jobs), "rules": per_rule(jobs),
           "phases_all": per_phase(jobs),
           "phases_dem": per_phase(jobs, {j["rule"] for j in jobs
                                          if sum(job_steps(j).values())}),
           "phases_samples": per_phase(jobs, set(SAMPLE_RULES)),
           "samples": sample_jobs(jobs, runs),
           "run_files": len(runs)}
    if bench_n:
        b = bench(bench_n, bench_steps)
        rec["bench"] = b
        s = rec["samples"]
        if s.get("jobs"):
            rec["samples"]["vs_bench"] = s["ps_per_cpu_s"] / b["particle_steps_per_cpu_s"]
            rec["samples"]["engine_vs_bench"] = (s["engine_ps_per_cpu_s"]
                                                 / b["particle_steps_per_cpu_s"])
            bench_bonds = b["particle_steps_per_cpu_s"] * b["bonds_per_ball"] / 2.0
            rec["samples"]["bond_steps_vs_bench"] = (s["loading_bond_steps_per_cpu_s"]
                                                     / bench_bonds)
    return rec


def _m(x: float) -> str:
    return f"{x / 1e6:.2f}"


def markdown(rec: dict) -> str:
    L = [f"# The cost model of a study: {rec['date']}", "",
         f"Host: {rec['cpu_model']} ({rec['cpus']} CPUs); load average when recorded "
         f"{', '.join(f'{x:.2f}' for x in rec['load_average'])}. Commit: {rec['commit']}. "
         f"Study: {rec['study']}.", "",
         f"Command: `{rec['command']}`", "",
         f"{rec['jobs']} jobs with a cost line, {rec['run_files']} run files with a cost "
         "record.", "", "## By rule", "",
         "| rule | jobs | CPU s | share | M ball-steps | of them the tests' | M ball-steps per CPU s "
         "(job) | M ball-steps per CPU s (engine) | specimens built (packings relaxed) |"
         + (" job time (wall) s | busy |" if any("job_wall_s" in r for r in rec["rules"])
            else ""),
         "|---|---|---|---|---|---|---|---|---|" + ("---|---|" if any("job_wall_s" in r for r in
                                                                     rec["rules"]) else "")]
    wall = any("job_wall_s" in r for r in rec["rules"])
    for r in rec["rules"]:
        built = f"{r['geneses']} ({r['relaxed']})" if r.get("geneses") else "–"
        line = (f"| {r['rule']} | {r['jobs']} | {r['cpu_s']:.1f} | {100 * r['share']:.1f} % | "
                f"{_m(r['ball_steps'])} | {_m(r['test_ball_steps'])} | "
                f"{_m(r['ps_per_cpu_s'])} | {_m(r['engine_ps_per_cpu_s'])} | {built} |")
        if wall:
            busy = f"{100 * r['busy']:.0f} %" if "busy" in r else "–"
            line += f" {r.get('job_wall_s', float('nan')):.1f} | {busy} |"
        L.append(line)
    # the sample jobs' rule as the record names it (``ucs`` in a record made before the
    # rename: its page renders as it was written)
    rule = next((r["rule"] for r in rec["rules"] if r["rule"] in SAMPLE_RULES), "sample")
    for key, title in (("phases_samples", f"The sample jobs (rule `{rule}`) by phase"),
                       ("phases_dem", "Every DEM job by phase"),
                       ("phases_all", "Every job by phase")):
        p = rec[key]
        if not p["jobs"]:
            continue
        L += ["", f"## {title}", "", f"{p['jobs']} jobs, {p['total_cpu_s']:.1f} CPU s.", "",
              "| phase | CPU s | share | M ball-steps |", "|---|---|---|---|"]
        for r in p["rows"]:
            L.append(f"| {r['category']} | {r['cpu_s']:.2f} | {100 * r['share']:.1f} % | "
                     f"{_m(r['ball_steps']) if r['ball_steps'] else '–'} |")
    s = rec["samples"]
    if s.get("jobs"):
        med = s["median"]
        L += ["", "## The sample jobs' throughput", "",
              f"{s['jobs']} jobs, {s['total']['cpu_s']:.1f} CPU s; the tests' ball-steps "
              f"{s['total']['test_ball_steps'] / 1e9:.3f} G, all engine ball-steps "
              f"{s['total']['ball_steps'] / 1e9:.3f} G.", "",
              "| | all jobs | median job |", "|---|---|---|",
              f"| the tests' particle-steps per job CPU-second (M) | {_m(s['ps_per_cpu_s'])} | "
              f"{_m(med['ps_per_cpu_s'])} |",
              f"| engine particle-steps per job CPU-second (M) | {_m(s['all_ps_per_cpu_s'])} | "
              f"{_m(med['all_ps_per_cpu_s'])} |",
              f"| engine particle-steps per engine CPU-second (M) | "
              f"{_m(s['engine_ps_per_cpu_s'])} | {_m(med['engine_ps_per_cpu_s'])} |",
              f"| genesis share of the job | – | {100 * med['genesis_share']:.1f} % |",
              f"| start-up share (start, imports, kernels) | – | "
              f"{100 * med['startup_share']:.1f} % |",
              f"| unbooked (other) share | – | {100 * med['other_share']:.1f} % |",
              f"| job CPU s | {s['total']['cpu_s']:.1f} | {med['cpu_s']:.2f} |"]
        L += ["", f"The ledger's UCS test ball-steps equal the run file's balls x steps in "
              f"{s['ucs_steps_match']} of {s['ucs_runs']} UCS run files."]
        if "bench" in rec:
            b = rec["bench"]
            L += ["", f"The engine's benchmark in the same invocation (`dem_throughput.py "
                  f"--n {b['n']} --threads 1 --steps {b['steps']}`): "
                  f"{_m(b['particle_steps_per_cpu_s'])} M particle-steps per CPU-second. "
                  f"The sample jobs' test particle-steps per CPU-second are "
                  f"{s['vs_bench']:.2f} x that; the engine inside them runs at "
                  f"{s['engine_vs_bench']:.2f} x per particle-step. Per bond (the "
                  f"benchmark's pack has {b['bonds_per_ball']:.2f} bonds per ball; the "
                  f"tests' bond-steps, balls x steps x bonds per ball at the test's start / 2 of each run "
                  f"file, over the tests' engine CPU seconds: "
                  f"{_m(s['loading_bond_steps_per_cpu_s'])} M per CPU-second) the engine "
                  f"inside the jobs runs at {s['bond_steps_vs_bench']:.2f} x the "
                  f"benchmark's."]
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--study", help="the study's outdir (results)")
    ap.add_argument("--render", default=None,
                    help="a JSON record of this script: write its Markdown (--markdown) again")
    ap.add_argument("--label", default="", help="what the study was (for the record)")
    ap.add_argument("--commit", default=None,
                    help="the commit the study ran (default: this checkout's HEAD)")
    ap.add_argument("--snakemake-log", default=None,
                    help="Snakemake's log of the run (job times by rule)")
    ap.add_argument("--bench-n", type=int, default=0,
                    help="balls of the engine benchmark run beside (0: none)")
    ap.add_argument("--bench-steps", type=int, default=2000)
    ap.add_argument("--out", default=None, help="JSON record")
    ap.add_argument("--markdown", default=None, help="Markdown record")
    a = ap.parse_args(argv)
    if a.render:
        write_record(json.loads(Path(a.render).read_text()), None, a.markdown, markdown)
        return 0
    if not a.study:
        ap.error("--study is required (a study's outdir), or --render RECORD.json")
    rec = record(Path(a.study), a.label or a.study, a.snakemake_log, a.bench_n, a.bench_steps,
                 sys.argv[1:] if argv is None else argv, a.commit)
    write_record(rec, a.out, a.markdown, markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
