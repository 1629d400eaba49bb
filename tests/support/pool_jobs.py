"""Jobs for tests/unit/stages/test_pool.py: module-level functions, importable by name in the
spawned worker processes of a SeedPool (a test module's own functions may not be)."""
import os


def whoami(*, x, threads, progress):
    """x squared, with the process and the thread count and progress label it got."""
    if progress is not None:
        progress({"note": f"job {x}"})
    return {"x2": x * x, "pid": os.getpid(), "threads": threads,
            "label": None if progress is None else progress.label}


def fails(*, x, threads, progress):
    raise ValueError(f"planted failure of job {x}")


def dies(*, x, threads, progress):
    os._exit(9)  # a worker killed mid-run (out of memory, a signal)


def _mark(marker):
    """Write this worker's pid to ``marker`` whole (written then renamed): a test polling
    for the file never reads it half written."""
    from pathlib import Path
    marker = Path(marker)
    part = marker.with_name(f".{marker.name}.{os.getpid()}.part")  # not matched by w*
    part.write_text(str(os.getpid()))
    os.replace(part, marker)


def sleepy(*, x, marker, threads, progress):
    """Write this worker's pid to ``marker`` and sleep ``x`` seconds (a long run)."""
    import time
    _mark(marker)
    time.sleep(x)
    return x


def fails_soon(*, x, marker, threads, progress):
    import time
    time.sleep(1.0)
    raise ValueError("planted failure beside a long run")


def burns(*, x, threads, progress):
    """About ``x`` CPU seconds in the cost ledger's phase ``burn`` (bpmcal.cost)."""
    import time

    from bpmcal.cost import phase
    with phase("burn"):
        t = time.process_time()
        while time.process_time() - t < x:
            pass
    return x


def context(*, x, ctx):
    """A job of a RunContext's pool: x, and the context it got (its threads and progress
    label; its cache and genesis budget, the stage's)."""
    if ctx.progress is not None:
        ctx.progress({"note": f"job {x}"})
    return {"x": x, "pid": os.getpid(), "threads": ctx.threads, "cache": ctx.cache,
            "steps": ctx.genesis_max_steps,
            "label": getattr(ctx.progress, "label", None)}
