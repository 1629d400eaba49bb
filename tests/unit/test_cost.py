"""The cost model's bookkeeping (``bpmcal.cost``, ``benchmarks/cost_model.py``): a sample
job run as the workflow runs it (``bpmcal sample --bts-out`` with ``BPMCAL_COST`` set, its
log in a study's ``logs/sample/``) books its CPU seconds to phases that account for the
process as the kernel measures it from outside, counts the engine's ball-steps as the
run counts its steps, and its run files' shares add up to the process."""
import json
import os
import resource
import subprocess
import sys

import pytest
import yaml
from support.paper import A1
from support.repo import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import cost_model  # noqa: E402

#: the paper's A1 set at the smoke study's size (test_sample_job.py)
UCS = ["--scale", "0.3", "--platen-velocity", "0.2", "--record-strain", "2e-5", "--threads", "1"]
DISC = ["--bts-diameter=70", "--bts-thickness=35", "--bts-platen-velocity=0.025",
        "--bts-approach-velocity=0.1", "--bts-stop-drop=0.2", "--bts-post-peak-strain=0.0003"]


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


@pytest.fixture(scope="module")
def study(tmp_path_factory, packing_cache):
    """A one-sample study folder: the sample job's run files, its log, and its CPU
    seconds as the kernel counted them (``getrusage`` of the finished child)."""
    d = tmp_path_factory.mktemp("cost")
    pf = d / "a1.yaml"
    pf.write_text(yaml.safe_dump(A1))
    res = d / "results"
    (res / "logs" / "sample").mkdir(parents=True)
    argv = [sys.executable, "-m", "bpmcal.cli", "sample", "--params", str(pf),
            "--out", str(res / "ucs" / "s000.h5"), "--bts-out", str(res / "bts" / "s000.h5"),
            *UCS, *DISC, "--quiet", "--specimen-cache"]
    env = {**os.environ, "BPMCAL_COST": "1"}
    # once to warm numba's cache, then the measured job, which packs its specimens (an
    # empty specimen cache), as a study's sample job does
    subprocess.run([*argv, str(packing_cache)], env=env, check=True, capture_output=True)
    c0 = _children_cpu()
    with open(res / "logs" / "sample" / "s000.log", "w") as log:
        subprocess.run([*argv, str(d / "packings")], env=env, check=True, stdout=log,
                       stderr=subprocess.STDOUT)
    return res, _children_cpu() - c0


@pytest.mark.slow
def test_the_phases_of_a_sample_job_account_for_its_cpu_time(study):
    res, outside = study
    jobs = cost_model.read_jobs(res)
    assert [j["rule"] for j in jobs] == ["sample"]
    job = jobs[0]
    phases = cost_model.job_phases(job)
    assert sum(phases.values()) == pytest.approx(job["cpu_s"], abs=1e-4)  # rounded
    # the process as the kernel counted it: the ledger misses only the last instants
    assert cost_model.job_cpu(job) == pytest.approx(outside, rel=0.03)
    # ... and names the phase of nearly every second of it
    assert phases["other"] < 0.03 * job["cpu_s"]
    cat = cost_model.by_category(phases)["cpu_s"]
    for c in ("start", "kernels: loading", "kernels: numba's set-up",
              "genesis: packing (engine)", "test: engine", "test: records", "write"):
        assert cat[c] > 0, c
    assert cat["test: engine"] > 0.3 * job["cpu_s"]


@pytest.mark.slow
def test_the_run_files_share_the_process_and_count_its_steps(study):
    res, _ = study
    runs = {r["test"]: r for r in cost_model.run_file_costs(res)}
    assert set(runs) == {"ucs", "bts"}
    job = cost_model.read_jobs(res)[0]
    # each run file holds what the process spent since the one before it: together, the
    # process up to its last run file, which is nearly all of the job
    total = sum(r["cpu_s"] for r in runs.values())
    assert total == pytest.approx(max(r["process_cpu_s"] for r in runs.values()), abs=1e-3)
    assert total == pytest.approx(job["cpu_s"], rel=0.02)
    for r in runs.values():
        assert sum(r["phases"].values()) == pytest.approx(r["cpu_s"], rel=1e-6)
    # the engine's ball-steps of the loading are the run's balls x steps
    u = runs["ucs"]
    assert u["ball_steps"]["ucs/test/engine"] == u["n_balls"] * u["steps"] > 0
    b = runs["bts"]  # the disc's test: its seating, then its loading
    assert b["ball_steps"]["bts/test/engine"] == b["n_balls"] * (b["seat_steps"] + b["steps"])
    assert b["seat_steps"] > 0 and b["steps"] > 0
    # the job's cost line holds the run files' ball-steps, and the genesis's too
    steps = cost_model.job_steps(job)
    assert steps["ucs/test/engine"] == u["ball_steps"]["ucs/test/engine"]
    assert steps["ucs/genesis/packing/relax/engine"] > 0
    assert steps["bts/genesis/build/engine"] > 0
    # two geneses, each packing relaxed (the job's specimen cache was empty)
    assert cost_model.geneses(job) == (2, 2)


def test_phase_paths_fall_into_the_model_categories():
    c = cost_model.category
    assert c("ucs/genesis/packing/engine") == "genesis: packing (engine)"
    assert c("bts/genesis/build") == "genesis: build (rest)"
    assert c("ucs/test/engine") == "test: engine"
    assert c("triaxial/test") == "test: records"
    assert c("bts_retest/test/engine") == "retests"
    assert c("kernels") == "kernels: loading" and c("ucs/results") == "results"
    assert c("ucs/genesis/packing/relax/engine") == "genesis: packing (engine)"
    assert cost_model.test_steps("ucs/test/engine")
    assert not cost_model.test_steps("bts_retest/test/engine")
    assert not cost_model.test_steps("ucs/genesis/packing/engine")


def test_the_sample_jobs_of_a_study_before_the_rules_rename_are_read_too(tmp_path):
    """The rule of the sample jobs is ``sample``; a study finished before its rename has
    their logs in ``logs/ucs/``. Both are the sample jobs; another rule's jobs are not."""
    cost = {"cpu_s": 2.0, "children_cpu_s": 0.0, "phases": {"ucs/test/engine": 1.5,
                                                             "other": 0.5},
            "ball_steps": {"ucs/test/engine": 3000}}
    for rule in ("sample", "ucs", "impact"):
        (tmp_path / "logs" / rule).mkdir(parents=True)
        (tmp_path / "logs" / rule / "s000.log").write_text(
            f"bpmcal {rule}: cost {json.dumps(cost)}\n")
    jobs = cost_model.read_jobs(tmp_path)
    assert sorted(j["rule"] for j in jobs) == ["impact", "sample", "ucs"]
    s = cost_model.sample_jobs(jobs, [])
    assert s["jobs"] == 2 and s["total"]["test_ball_steps"] == 6000
    assert s["ps_per_cpu_s"] == 6000 / 4.0
    assert cost_model.per_phase(jobs, set(cost_model.SAMPLE_RULES))["jobs"] == 2


def test_the_ledger_books_nested_phases_once(monkeypatch):
    from bpmcal import cost

    t = [0.0]
    monkeypatch.setattr(cost, "_clock", lambda: t[0])
    led = cost.Ledger()
    with led.phase("ucs"):
        t[0] += 1.0
        with led.phase("genesis"):
            t[0] += 2.0
            with led.phase("kernels", flat=True):
                t[0] += 0.5
            with led.engine(600):
                t[0] += 2.0
            c0 = led.engine_start()  # the lighter form lab.stepping uses: the same booking
            t[0] += 1.0
            led.engine_end(c0, 400)
        first = led.take("file")  # inside an open phase: its time so far is booked
        t[0] += 4.0
    second = led.take("file")
    assert first["phases"] == {"ucs": 1.0, "ucs/genesis": 2.0, "kernels": 0.5,
                               "ucs/genesis/engine": 3.0, "other": 0.0}
    assert first["cpu_s"] == 6.5 and first["ball_steps"] == {"ucs/genesis/engine": 1000}
    assert first["calls"] == {"kernels": 1, "ucs/genesis": 1}  # the engine's not counted
    assert second == {"cpu_s": 4.0, "phases": {"ucs": 4.0, "other": 0.0}, "ball_steps": {},
                      "calls": {"ucs": 1}}
    json.dumps(first)


def test_a_kernel_compiled_inside_an_engine_call_is_booked_once(monkeypatch):
    """numba compiles (or loads) a kernel at its first call, inside the engine's call of
    lab.stepping: the flat phase ``kernels`` keeps that time, the engine the rest, and
    the phases still sum to the process's time (a cold cache booked it twice)."""
    from bpmcal import cost

    t = [0.0]
    monkeypatch.setattr(cost, "_clock", lambda: t[0])
    led = cost.Ledger()
    with led.phase("test"):
        t[0] += 1.0
        c0 = led.engine_start()
        t[0] += 0.25
        with led.phase("kernels", flat=True):  # the first call compiles
            t[0] += 30.0
        t[0] += 2.0
        led.engine_end(c0, 500)
    c0 = led.engine_start()  # outside any phase: the same
    with led.phase("kernels", flat=True):
        t[0] += 5.0
    t[0] += 1.0
    led.engine_end(c0, 100)
    got = led.take("job")
    assert got["phases"] == {"test": 1.0, "kernels": 35.0, "test/engine": 2.25,
                             "engine": 1.0, "other": 0.0}
    assert got["cpu_s"] == sum(v for k, v in got["phases"].items() if k != "other")
