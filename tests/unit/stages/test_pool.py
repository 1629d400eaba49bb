"""SeedPool (bpmcal.stages.pool): independent runs side by side on a stage's CPUs. (The
closed loop's use of it: tests/unit/analysis/calibration/test_closed_loop.py; the stages with the real DEM
on two CPUs against one: tests/unit/stages/test_pool_dem.py.)"""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support import pool_jobs as _pool_jobs
from support.pool_jobs import dies, whoami

from bpmcal.stages.pool import SeedPool, WorkerLost
from bpmcal.stages.progress import Progress


def test_jobs_run_in_other_processes_in_order_with_the_cpus_shared():
    jobs = [{"x": x} for x in range(5)]
    with SeedPool(2, Progress("verify B1", enabled=False)) as pool:
        out = pool.map(whoami, jobs, tags=[f"seed {x}" for x in range(5)])
        assert [o["x2"] for o in out] == [x * x for x in range(5)]  # the jobs' order
        assert all(o["pid"] != os.getpid() for o in out)  # really in worker processes
        assert len({o["pid"] for o in out}) <= 2
        assert all(o["threads"] == 1 for o in out)  # 2 CPUs, 2 runs at once: 1 thread each
        assert [o["label"] for o in out] == [f"verify B1 [seed {x}]" for x in range(5)]
        one = pool.map(whoami, [{"x": 7}])  # fewer runs than CPUs: in process, all threads
        assert one[0]["pid"] == os.getpid() and one[0]["threads"] == 2


def test_without_cpus_to_share_the_runs_stay_in_this_process():
    for threads in (None, 1):
        with SeedPool(threads) as pool:
            out = pool.map(whoami, [{"x": 2}, {"x": 3}])
        assert [o["x2"] for o in out] == [4, 9]
        assert {o["pid"] for o in out} == {os.getpid()}
        assert {o["threads"] for o in out} == {threads}


def test_a_run_that_raises_raises_here_and_a_dead_worker_is_named():
    with SeedPool(2) as pool:
        with pytest.raises(ValueError, match="planted failure of job 1"):
            pool.map(_pick, [{"fn": "fails", "x": 1}, {"fn": "whoami", "x": 2}])
    with SeedPool(2) as pool:
        with pytest.raises(WorkerLost, match=r"dies \[seed 5\] died"):
            pool.map(dies, [{"x": 5}, {"x": 6}], tags=["seed 5", "seed 6"])


def test_a_pool_of_a_context_passes_each_run_its_context():
    """SeedPool.of(ctx): every run gets ``ctx=``, the stage's context with the run's own
    threads and progress (in a worker: its share of the CPUs, its labelled progress)."""
    from bpmcal.lab.run_context import RunContext

    ctx = RunContext(cache="/tmp/packings", threads=2, genesis_max_steps=3000,
                     progress=Progress("fresh-seeds B1", enabled=False))
    with SeedPool.of(ctx) as pool:
        out = pool.map(_pool_jobs.context, [{"x": x} for x in range(3)],
                       tags=[f"seed {x}" for x in range(3)])
        one = pool.map(_pool_jobs.context, [{"x": 9}])
    assert [o["x"] for o in out] == [0, 1, 2] and all(o["pid"] != os.getpid() for o in out)
    assert all(o["threads"] == 1 and o["cache"] == "/tmp/packings" and o["steps"] == 3000
               for o in out)
    assert [o["label"] for o in out] == [f"fresh-seeds B1 [seed {x}]" for x in range(3)]
    assert one[0]["pid"] == os.getpid() and one[0]["threads"] == 2
    assert one[0]["label"] == "fresh-seeds B1"  # in this process: the stage's own


@pytest.mark.parametrize("bad", [0, -1, True])
def test_a_pool_of_no_cpus_is_refused(bad):
    with pytest.raises(ValueError, match=f"threads={bad!r}: expected an integer >= 1"):
        SeedPool(bad)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = open(f"/proc/{pid}/stat").read()  # a zombie (dead, not yet reaped) is gone too
    return stat[stat.rfind(")") + 2] != "Z"


def _gone_within(pids, seconds) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not any(_alive(p) for p in pids):
            return True
        time.sleep(0.1)
    return False


def _pick(*, fn, **kw):
    """A job naming its function: the pool runs one function for all its jobs."""
    return getattr(_pool_jobs, fn)(**kw)


def test_a_failed_run_stops_the_others_at_once(tmp_path):
    jobs = [{"x": 1, "marker": str(tmp_path / "a")}, {"x": 120, "marker": str(tmp_path / "b")}]
    t0 = time.monotonic()
    with SeedPool(2) as pool:
        with pytest.raises(ValueError, match="planted failure"):
            pool.map(_pick, [dict(j, fn=f) for j, f in zip(jobs, ("fails_soon", "sleepy"))])
    assert time.monotonic() - t0 < 30  # not the 120 s of the other run
    assert _gone_within([int((tmp_path / "b").read_text())], 5)


SCRIPT = """
import signal, sys
# {ignore_int}: started as `cmd &` by a shell without job control (SIGINT ignored); else
# as from a terminal, whose Ctrl-C reaches a process with Python's own SIGINT handler, even
# when this test suite itself runs as such a background job (and its children would
# inherit SIGINT ignored)
signal.signal(signal.SIGINT, signal.SIG_IGN if {ignore_int} else signal.default_int_handler)
sys.path.insert(0, {tests!r})
from support.pool_jobs import sleepy
from bpmcal.stages.pool import SeedPool
with SeedPool(2) as pool:
    pool.map(sleepy, [dict(x=120, marker={d!r} + f"/w{{i}}") for i in range(4)])
"""


@pytest.mark.parametrize("how", ["ctrl-c", "sigkill", "sigterm, SIGINT ignored"])
def test_an_interrupted_or_killed_stage_leaves_no_worker_running(tmp_path, how):
    tests = str(Path(__file__).resolve().parents[2])
    script = SCRIPT.format(tests=tests, d=str(tmp_path), ignore_int="ignored" in how)
    p = subprocess.Popen([sys.executable, "-c", script],
                         start_new_session=True, stderr=subprocess.PIPE)
    end = time.monotonic() + 60
    while len(list(tmp_path.glob("w*"))) < 2 and time.monotonic() < end:
        time.sleep(0.1)
    pids = [int(f.read_text()) for f in tmp_path.glob("w*")]
    assert len(pids) == 2  # two runs started side by side
    t0 = time.monotonic()
    if how == "ctrl-c":  # the terminal's SIGINT reaches the whole process group
        os.killpg(p.pid, signal.SIGINT)
    elif how == "sigkill":  # the stage's own process killed: nothing of it can react
        os.kill(p.pid, signal.SIGKILL)
    else:  # `kill PID` of the stage only (its default action ends it at once)
        os.kill(p.pid, signal.SIGTERM)
    p.wait(timeout=30)
    assert _gone_within(pids, 10), "a worker ran on after its stage ended"
    assert time.monotonic() - t0 < 15  # not the 120 s of the runs
    assert len(list(tmp_path.glob("w*"))) == 2  # no queued run started after the stop


def test_the_workers_report_what_they_spent_to_the_cost_ledger():
    """Each worker returns its share of the stage's cost with its run (bpmcal.cost): the
    stage's cost line holds its workers' phases."""
    from support.pool_jobs import burns

    from bpmcal.cost import LEDGER

    before = LEDGER.workers.get("burn", 0.0)
    with SeedPool(2) as pool:
        assert pool.map(burns, [{"x": 0.2}, {"x": 0.3}]) == [0.2, 0.3]
    assert LEDGER.workers.get("burn", 0.0) - before == pytest.approx(0.5, abs=0.05)
    assert LEDGER.worker_calls.get("burn", 0) >= 2
    assert LEDGER.workers.get("start", 0.0) > 0  # each worker's start-up, booked once
