"""Independent DEM runs side by side: the runs of a closed-loop round's seeds and of the
fresh seeds (each seed's UCS test and each of its tensile specimens a job of its own:
``verification.seed_parts``), the seed-scatter seeds, the posterior predictive's runs.

A stage given ``threads`` = N CPUs runs its independent runs on up to N worker
processes at once, each run with N // (runs at once) numba threads (one, when there are
at least N runs): on two cores a ten-seed round takes about half the time of the same
round run seed after seed with one thread each, where two threads inside one run of a
few thousand balls gain far less (``dem.threads.MIN_BALLS_PER_THREAD``). Without
``threads`` (None: each run chooses its own thread count) or with one, the runs go one
after the other in this process, as before.

The results do not depend on it: every run is deterministic in its seed and inputs,
and neither the thread count nor the process a run ran in changes its numbers
(``dem.threads``); results come back in the order of the jobs. Workers are started
with ``spawn`` (a fork of a process whose numba threads already ran is not safe), once
per pool, and import the run function by name: it must be a module-level function, its
arguments picklable. An exception raised by a run is raised here, as in a serial run; a
worker that dies (killed, out of memory) is a :class:`WorkerLost` naming the run. When a
run fails or this process is interrupted, the other runs are stopped at once (not run
to their end), each discarding the file it was writing, as a run stopped by Ctrl-C does.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import signal
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Callable, Sequence

from ..cost import LEDGER
from .progress import Progress


class WorkerLost(RuntimeError):
    """A worker process of a :class:`SeedPool` died during a run."""


def _progress_spec(progress) -> tuple | None:
    """What a worker needs to report progress as ``progress`` does: a :class:`Progress`
    is rebuilt in the worker (label, interval, on/off); any other callable cannot cross a
    process boundary, so the worker reports nothing."""
    if isinstance(progress, Progress):
        return (progress.label, progress.every, progress.enabled)
    return None


#: seconds a stopped pool's workers get to end their runs (an interrupted run discards
#: the file it was writing) before they are terminated
STOP_GRACE_S = 10.0


def _interrupt(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


def _worker_init() -> None:
    """In each worker at its start: SIGTERM interrupts its run as Ctrl-C does (the run
    discards the file it was writing, then the worker ends: :func:`_call`), and the worker
    dies with its parent: when the process that started it ends (killed by SIGTERM or
    SIGKILL, which no Python code of its may catch), the kernel sends the worker SIGTERM
    (Linux ``PR_SET_PDEATHSIG``) instead of leaving it to run on, orphaned, to its end.
    Elsewhere only the handler is set. The worker's CPU seconds so far (its start-up,
    imports) are booked as the cost ledger's ``start`` (``bpmcal.cost``)."""
    LEDGER.begin()
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM, 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() == 1:  # the parent ended before the request was made
        os._exit(130)


def _run_args(ctx, threads, progress) -> dict:
    """A run's own keywords: ``ctx=`` (its :class:`~bpmcal.lab.run_context.RunContext`
    with the run's threads and progress) for a pool of a context, else ``threads=`` and
    ``progress=``."""
    if ctx is not None:
        return {"ctx": ctx.with_run(threads, progress)}
    return {"threads": threads, "progress": progress}


def _call(fn: Callable, job: dict, threads: int, spec: tuple | None, tag: str, ctx=None):
    """One run in a worker: ``fn(**job, threads=threads, progress=...)`` (or ``ctx=``,
    :func:`_run_args`), its progress lines labelled with ``tag`` (the run's seed). An
    interrupted run (Ctrl-C reaches the whole process group; a stopped pool or a dead
    parent sends SIGTERM) ends the worker: it must not go on to the next queued run."""
    progress = None
    if spec is not None:
        label, every, enabled = spec
        progress = Progress(f"{label} [{tag}]", every=every, enabled=enabled)
    try:
        # with what the worker spent on it (its share of the stage's cost, bpmcal.cost)
        return fn(**job, **_run_args(ctx, threads, progress)), LEDGER.take("worker")
    except KeyboardInterrupt:
        os._exit(130)


class SeedPool:
    """Runs ``fn(**job, threads=..., progress=...)`` for a list of jobs on up to
    ``threads`` processes (module docs); a context manager that shuts its workers down on
    exit. ``map`` may be called many times (a closed loop: once per round); the workers
    are started at the first call that runs more than one job at once and kept.

    The pool of a stage's :class:`~bpmcal.lab.run_context.RunContext` (:meth:`of`) runs
    ``fn(**job, ctx=...)`` instead: the context with the run's own threads and progress
    (sent to a worker without its progress, which the worker builds again)."""

    def __init__(self, threads: int | None, progress=None):
        if threads is not None and (isinstance(threads, bool) or int(threads) < 1):
            raise ValueError(f"threads={threads!r}: expected an integer >= 1 or None")
        self.threads = None if threads is None else int(threads)
        self.progress = progress
        self.ctx = None
        self._ex: ProcessPoolExecutor | None = None

    @classmethod
    def of(cls, ctx) -> "SeedPool":
        """The pool of a stage's RunContext ``ctx``: its threads as CPUs, its progress,
        and ``ctx=`` for every run (class docs)."""
        pool = cls(ctx.threads, ctx.progress)
        pool.ctx = ctx
        return pool

    def __enter__(self) -> "SeedPool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Shut the workers down once their runs are done (nothing is running after a
        completed ``map``)."""
        if self._ex is not None:
            self._ex.shutdown(wait=True, cancel_futures=True)
            self._ex = None

    def stop(self) -> None:
        """Stop the workers now (a run failed, or this process was interrupted): queued
        runs are dropped, running ones are interrupted (SIGTERM, which a worker takes as
        Ctrl-C: each discards the file it was writing) and, after :data:`STOP_GRACE_S`,
        killed."""
        ex, self._ex = self._ex, None
        if ex is None:
            return
        procs = list((getattr(ex, "_processes", None) or {}).values())
        for p in procs:
            if p.is_alive():
                try:
                    os.kill(p.pid, signal.SIGTERM)
                except OSError:
                    pass
        end = time.monotonic() + STOP_GRACE_S
        for p in procs:
            p.join(max(0.0, end - time.monotonic()))
        for p in procs:
            if p.is_alive():
                p.kill()
                p.join(1.0)
        ex.shutdown(wait=False, cancel_futures=True)

    def workers_for(self, n_jobs: int) -> int:
        """Processes that run ``n_jobs`` jobs: min(threads, n_jobs), at least 1."""
        return max(1, min(self.threads or 1, int(n_jobs)))

    def map(self, fn: Callable, jobs: Sequence[dict], tags: Sequence[str] | None = None,
            done: Callable[[int, object], None] | None = None) -> list:
        """``[fn(**job, threads=t, progress=p) for job in jobs]`` (or ``ctx=``: class docs),
        the jobs side by side
        when there are CPUs for it; ``tags`` name each job in progress lines and errors
        (default its index). ``done(i, result)``, when given, is called as soon as job i
        has finished (in the order they finish; a journal of finished runs)."""
        jobs = list(jobs)
        tags = [str(t) for t in tags] if tags is not None else [str(i) for i in range(len(jobs))]
        n = self.workers_for(len(jobs))
        if n <= 1:
            out = []
            for i, job in enumerate(jobs):
                out.append(fn(**job, **_run_args(self.ctx, self.threads, self.progress)))
                if done is not None:
                    done(i, out[-1])
            return out
        each = max(1, self.threads // n)
        if self._ex is None:
            self._ex = ProcessPoolExecutor(self.threads, mp_context=mp.get_context("spawn"),
                                           initializer=_worker_init)
        spec = _progress_spec(self.progress)
        sent = None if self.ctx is None else self.ctx.with_run(None, None)  # picklable
        futures = [self._ex.submit(_call, fn, job, each, spec, tag, sent)
                   for job, tag in zip(jobs, tags)]
        index = {f: i for i, f in enumerate(futures)}
        results: dict[int, object] = {}
        try:
            pending = set(futures)
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in sorted(finished, key=index.get):
                    i = index[f]
                    try:
                        results[i], share = f.result()
                        LEDGER.add_worker(share)
                    except BrokenProcessPool as e:
                        raise WorkerLost(f"the worker process running {fn.__name__} [{tags[i]}] "
                                         "died (killed, or out of memory: each of the "
                                         f"{n} runs at once needs its own memory)") from e
                    if done is not None:
                        done(i, results[i])
        except BaseException:
            self.stop()
            raise
        return [results[i] for i in range(len(jobs))]
