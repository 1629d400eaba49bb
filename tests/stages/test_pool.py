"""SeedPool (bpmcal.stages.pool): independent runs side by side on a stage's CPUs. (The
closed loop's use of it: tests/analysis/test_closed_loop.py; the stages with the real DEM
on two CPUs against one: tests/stages/test_pool_dem.py.)"""
import os

import pytest
from _pool_jobs import dies, fails, whoami

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
            pool.map(fails, [{"x": 1}, {"x": 2}])
    with SeedPool(2) as pool:
        with pytest.raises(WorkerLost, match=r"dies \[seed 5\] died"):
            pool.map(dies, [{"x": 5}, {"x": 6}], tags=["seed 5", "seed 6"])


@pytest.mark.parametrize("bad", [0, -1, True])
def test_a_pool_of_no_cpus_is_refused(bad):
    with pytest.raises(ValueError, match=f"threads={bad!r}: expected an integer >= 1"):
        SeedPool(bad)
