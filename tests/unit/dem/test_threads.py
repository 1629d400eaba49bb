"""The default thread count (bpmcal.dem.threads): never more threads than the work pays
for or than the CPUs free for this process; a forced count wins."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from bpmcal.dem import _jit
from bpmcal.dem import threads as T
from bpmcal.dem._jit import numba


@pytest.fixture
def unforced():
    """Models choose their own threads inside the test; the process's state restored."""
    saved, n = _jit._FORCED[0], numba.get_num_threads()
    _jit.unforce_threads()
    yield
    _jit._FORCED[0] = saved
    numba.set_num_threads(n)


# ---- cgroup quota ---------------------------------------------------------------------
def _cgroup(tmp_path, files: dict, self_cgroup="0::/job\n"):
    root = tmp_path / "cg"
    for rel, text in files.items():
        f = root / rel
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(text)
    sc = tmp_path / "self_cgroup"
    sc.write_text(self_cgroup)
    return T.cgroup_cpu_limit(root, sc)


def test_cgroup_v2_quota_at_own_path(tmp_path):
    assert _cgroup(tmp_path, {"job/cpu.max": "150000 100000\n",
                              "cpu.max": "max 100000\n"}) == pytest.approx(1.5)


def test_cgroup_v2_no_quota(tmp_path):
    assert _cgroup(tmp_path, {"job/cpu.max": "max 100000\n"}) is None


def test_cgroup_smallest_of_own_and_root(tmp_path):
    assert _cgroup(tmp_path, {"job/cpu.max": "400000 100000\n",
                              "cpu.max": "100000 100000\n"}) == pytest.approx(1.0)


def test_cgroup_v1(tmp_path):
    files = {"cpu,cpuacct/slurm/cpu.cfs_quota_us": "200000\n",
             "cpu,cpuacct/slurm/cpu.cfs_period_us": "100000\n"}
    assert _cgroup(tmp_path, files, "4:cpu,cpuacct:/slurm\n") == pytest.approx(2.0)
    files["cpu,cpuacct/slurm/cpu.cfs_quota_us"] = "-1\n"
    assert _cgroup(tmp_path, files, "4:cpu,cpuacct:/slurm\n") is None


def test_cgroup_unreadable(tmp_path):
    assert T.cgroup_cpu_limit(tmp_path / "none", tmp_path / "none") is None


# ---- other processes ------------------------------------------------------------------
def _tasks(tmp_path, states):
    d = tmp_path / "task"
    for n, s in enumerate(states):
        (d / str(n)).mkdir(parents=True)
        # a command name with a space and a ")" inside, as /proc allows
        (d / str(n) / "stat").write_bytes(f"{n} (py (x) y) {s} 1 2 3".encode())
    return d


def test_others_running_subtracts_own_threads(tmp_path):
    la = tmp_path / "loadavg"
    la.write_text("0.50 0.40 0.30 4/120 999\n")
    assert T.others_running(la, _tasks(tmp_path, "RSR")) == 2
    la.write_text("0.50 0.40 0.30 2/120 999\n")
    assert T.others_running(la, tmp_path / "task") == 0  # never negative


def test_others_running_unreadable(tmp_path):
    assert T.others_running(tmp_path / "none", tmp_path / "none") == 0


# ---- the rule -------------------------------------------------------------------------
@pytest.mark.parametrize("n_balls, cpus, busy, want", [
    (1500, 2, 0, 1),                                   # too little work for two
    (2 * T.MIN_BALLS_PER_THREAD, 2, 0, 2),
    (2 * T.MIN_BALLS_PER_THREAD, 2, 1, 1),             # another process on one core
    (2 * T.MIN_BALLS_PER_THREAD, 2, 5, 1),             # oversubscribed: still one
    (100 * T.MIN_BALLS_PER_THREAD, 1, 0, 1),           # one CPU allowed
    (3 * T.MIN_BALLS_PER_THREAD, 8, 2, 3),             # the work is the limit
    (100 * T.MIN_BALLS_PER_THREAD, 8, 2, 6),           # the free CPUs are
])
def test_auto_threads(n_balls, cpus, busy, want):
    assert T.auto_threads(n_balls, cpus, busy) == want


def test_available_cpus_follows_affinity():
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("needs 2 CPUs")
    code = ("import os; os.sched_setaffinity(0, {min(os.sched_getaffinity(0))}); "
            "from bpmcal.dem.threads import available_cpus, auto_threads; "
            "print(available_cpus(), auto_threads(10**7, busy=0))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["1", "1"]


def _model(n=27):
    from support.dem_util import material

    from bpmcal.dem import Model
    g = np.arange(3) * 2.0e-3
    pos = np.array([[x, y, z] for x in g for y in g for z in g])[:n]
    return Model(pos, np.full(len(pos), 1.0e-3), 2650.0, material())


def test_small_model_runs_one_thread_unforced(unforced, monkeypatch):
    monkeypatch.setattr(T, "others_running", lambda *a: 0)
    m = _model()
    m.set_timestep(None)
    m.cycle(5)
    assert m.threads_used == [1]
    assert numba.get_num_threads() == 1


def test_forced_count_wins(unforced, monkeypatch):
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    monkeypatch.setattr(T, "MIN_BALLS_PER_THREAD", 1)  # auto would pick 2 ...
    monkeypatch.setattr(T, "others_running", lambda *a: 1)  # ... if not for a busy core
    m = _model()
    m.set_timestep(None)
    m.cycle(2)
    assert m.threads_used == [1]
    m2 = _model()
    m2.set_timestep(None)
    _jit.set_threads(2)
    m2.cycle(2)
    assert m2.threads_used == [2]


def test_rises_only_when_two_checks_agree(unforced, monkeypatch):
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    monkeypatch.setattr(T, "MIN_BALLS_PER_THREAD", 1)
    monkeypatch.setattr(T, "RECHECK_S", 0.0)
    busy = [1]
    monkeypatch.setattr(T, "others_running", lambda *a: busy[0])
    a = T.AutoThreads()
    assert a.apply(100) == 1
    busy[0] = 0
    assert a.apply(100) == 1  # one free reading is not enough
    assert a.apply(100) == 2
    busy[0] = 1
    assert a.apply(100) == 1  # falls at once
