"""How many numba threads a run uses when nobody says: a default that is never a trap.

Two runs that each take both cores of a 2-core machine are not twice as slow but 25x: the
OpenMP threads of one run spin at every barrier of a step while the thread they wait for
is descheduled in favour of the other run's. ``--threads N`` (``threads=N`` in the API)
forces N, as before. Without it a model chooses, at its start and again between chunks
of steps (:class:`AutoThreads`), the number of threads from

- the work: one thread below :data:`MIN_BALLS_PER_THREAD` balls per thread (a second
  thread's share of a step must outweigh what a parallel region costs to start and end);
- the CPUs this process may use: its affinity mask and its cgroup's CPU quota (a Slurm
  job's allocation, a container's limit), never more than numba's own limit;
- the CPUs other processes are using now: the runnable threads of the whole machine
  (``/proc/loadavg``, the instantaneous count) minus this process's own.

The choice changes how fast a run goes, never its result: the forces are summed in fixed
partitions, not per thread (``kernels.pair_partition``).
"""
from __future__ import annotations

import math
import os
import time
from pathlib import Path

from ._jit import forced_threads, numba

#: fewest balls per thread for another thread to pay: on a 2-core AMD EPYC two threads
#: ran a bonded pack 1.06x faster than one at 2,000 balls, 1.54x at 4,000 and 1.97x at
#: 16,000 (docs/measurements/2026-11-27-threads.md)
MIN_BALLS_PER_THREAD = 2000
#: seconds between two re-evaluations of the thread count of a running model
RECHECK_S = 0.5


def cgroup_cpu_limit(root: str | os.PathLike = "/sys/fs/cgroup",
                     self_cgroup: str | os.PathLike = "/proc/self/cgroup") -> float | None:
    """The CPU quota of this process's cgroup in CPUs (``quota / period``), or None when
    there is none or it cannot be read. cgroup v2 (``cpu.max``: ``"max 100000"`` or
    ``"200000 100000"``) and v1 (``cpu.cfs_quota_us`` = -1 for none, ``cpu.cfs_period_us``),
    at the process's own cgroup path and at the root of the hierarchy."""
    root = Path(root)
    rel = []
    try:
        for line in Path(self_cgroup).read_text().splitlines():
            parts = line.split(":", 2)
            if len(parts) == 3 and (parts[0] == "0" or "cpu" in parts[1].split(",")):
                rel.append(parts[2].lstrip("/"))
    except OSError:
        pass
    limits = []
    for sub in [*rel, ""]:
        for base in (root / sub, root / "cpu" / sub, root / "cpu,cpuacct" / sub):
            v = _read_limit(base)
            if v is not None:
                limits.append(v)
    return min(limits) if limits else None


def _read_limit(base: Path) -> float | None:
    try:
        q = (base / "cpu.max").read_text().split()
        if q and q[0] != "max":
            return float(q[0]) / float(q[1])
        return None
    except (OSError, ValueError, IndexError, ZeroDivisionError):
        pass
    try:
        quota = float((base / "cpu.cfs_quota_us").read_text())
        period = float((base / "cpu.cfs_period_us").read_text())
        return quota / period if quota > 0 and period > 0 else None
    except (OSError, ValueError):
        return None


def available_cpus() -> int:
    """CPUs this process may use: its affinity mask, the cgroup quota (rounded up; at
    least 1) and numba's thread limit, whichever is smallest."""
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    q = cgroup_cpu_limit()
    if q is not None:
        n = min(n, max(1, math.ceil(q - 1e-9)))
    return max(1, min(n, numba.config.NUMBA_NUM_THREADS))


def _running_self(task_dir: str | os.PathLike = "/proc/self/task") -> int:
    """Threads of this process in state R (running or runnable) now."""
    n = 0
    try:
        for t in os.scandir(task_dir):
            try:
                with open(os.path.join(t.path, "stat"), "rb") as f:
                    s = f.read()
            except OSError:
                continue
            # state is the field after the ")" closing the command name
            if s[s.rfind(b")") + 2:s.rfind(b")") + 3] == b"R":
                n += 1
    except OSError:
        return 1
    return max(n, 1)


def others_running(loadavg: str | os.PathLike = "/proc/loadavg",
                   task_dir: str | os.PathLike = "/proc/self/task") -> int:
    """Runnable threads of other processes now: the machine's instantaneous count
    (4th field of ``/proc/loadavg``, ``running/total``) minus this process's own; 0 where
    it cannot be read."""
    try:
        running = int(Path(loadavg).read_text().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return 0
    return max(0, running - _running_self(task_dir))


def auto_threads(n_balls: int, cpus: int | None = None, busy: int | None = None) -> int:
    """Threads for a model of ``n_balls`` balls: as many as the work pays for
    (:data:`MIN_BALLS_PER_THREAD` per thread) and as there are CPUs free for this process
    (``cpus`` available, ``busy`` of them taken by other processes; read from the machine
    when None); at least 1."""
    cpus = available_cpus() if cpus is None else int(cpus)
    busy = others_running() if busy is None else int(busy)
    by_work = max(1, int(n_balls) // MIN_BALLS_PER_THREAD)
    return max(1, min(by_work, cpus - busy, cpus))


class AutoThreads:
    """The thread count of one model that was not given one: chosen at the first chunk of
    steps and re-evaluated between chunks at most every :data:`RECHECK_S` seconds, so that
    a run started beside it (or ended) moves it within a second. Falls to fewer threads at
    once; rises only when two evaluations in a row agree (a process that sleeps for a
    moment is not a free CPU)."""

    def __init__(self):
        self.last = -math.inf
        self.current = None
        self.pending_up = None
        self.used = set()

    def apply(self, n_balls: int) -> int:
        """Set numba's thread count for the next chunk of steps of a model of ``n_balls``
        balls (a count forced by ``set_threads`` wins); returns it."""
        f = forced_threads()
        if f is not None:
            n = numba.get_num_threads()
            self.used.add(n)
            return n
        now = time.monotonic()
        if self.current is None or now - self.last >= RECHECK_S:
            self.last = now
            want = auto_threads(n_balls)
            if self.current is None or want <= self.current:
                self.current = want
                self.pending_up = None
            elif self.pending_up == want:
                self.current = want
                self.pending_up = None
            else:
                self.pending_up = want
        if numba.get_num_threads() != self.current:
            numba.set_num_threads(self.current)
        self.used.add(self.current)
        return self.current
