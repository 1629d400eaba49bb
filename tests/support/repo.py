"""The repository under test: its root, its configs merged as Snakemake merges them, and
private copies of the workflow to run Snakemake in."""
import copy
import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

#: the repository's root (the folder holding Snakefile, config/, workflow/, src/)
REPO = Path(__file__).resolve().parents[2]
#: the config schema the study validates against
SCHEMA = REPO / "workflow" / "schemas" / "config.schema.yaml"


def update_config(a: dict, b: dict, keep=()) -> dict:
    """Update ``a`` with ``b`` in place as Snakemake's ``--configfile`` does: nested
    mappings are merged key by key, anything else (and any key in ``keep``) is replaced
    by a copy of ``b``'s value. Returns ``a``."""
    for k, v in b.items():
        if isinstance(v, dict) and isinstance(a.get(k), dict) and k not in keep:
            update_config(a[k], v, keep)
        else:
            a[k] = copy.deepcopy(v)
    return a


def merged_config(*names) -> dict:
    """The config files ``config/<name>`` merged in order, as ``--configfile`` merges them
    (later files update nested keys of earlier ones)."""
    cfg = {}
    for n in names:
        update_config(cfg, yaml.safe_load((REPO / "config" / n).read_text()))
    return cfg


def copy_workflow(dst: Path) -> Path:
    """A private copy of the workflow (its own .snakemake metadata and outputs)."""
    dst.mkdir(parents=True, exist_ok=True)
    shutil.copy(REPO / "Snakefile", dst)
    shutil.copytree(REPO / "workflow", dst / "workflow")
    shutil.copytree(REPO / "config", dst / "config")
    return dst


def scheduled_jobs(text: str) -> dict:
    """rule -> jobs of a dry run's job stats ({} for "Nothing to be done")."""
    import re

    m = re.search(r"Job stats:\njob\s+count\n[-\s]+\n(.*?)\ntotal", text, re.S)
    if not m:
        return {}
    return {ln.split()[0]: int(ln.split()[1]) for ln in m.group(1).splitlines() if ln.strip()}


#: Snakemake options after which it runs no job (a dry run, the linter, graphs):
#: :func:`run_snakemake` runs these in a fork of a process that has imported Snakemake
#: (its import is most of a dry run's time; the test suite makes a few hundred of them)
NO_JOBS = {"-n", "--dry-run", "--dryrun", "--lint", "--rulegraph", "--dag"}


def _snakemake_main(cwd: str, args: list, env: dict, out: str, err: str) -> None:
    """In a fork of the fork server (Snakemake imported): ``snakemake <args>`` in ``cwd``
    with the environment ``env`` (the caller's now, not the server's at its start), its
    standard output and error into the files ``out`` and ``err``; ends the process with
    Snakemake's exit status."""
    code = 1
    try:
        os.chdir(cwd)
        os.environ.clear()
        os.environ.update(env, NUMBA_THREADING_LAYER="omp")
        for fd, path in ((1, out), (2, err)):
            f = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            os.dup2(f, fd)
            os.close(f)
        sys.stdout = open(1, "w", closefd=False)
        sys.stderr = open(2, "w", closefd=False)
        sys.argv = ["snakemake", *args]
        from snakemake.cli import main
        from snakemake.workflow import Workflow

        Workflow._rundir = str(Path.cwd().absolute())  # taken at its import, in the server
        try:
            main(list(args))
            code = 0
        except SystemExit as e:  # as the interpreter ends on it: a message goes to stderr
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
            if e.code is not None and not isinstance(e.code, int):
                print(e.code, file=sys.stderr)
    except BaseException:  # noqa: BLE001 - reported on stderr, as the command line would
        import traceback

        traceback.print_exc()
    finally:
        import logging

        logging.shutdown()  # flushes every handler: os._exit does not
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


_FORKS = None


def _forks():
    """The fork server, with Snakemake imported once (multiprocessing's forkserver)."""
    global _FORKS
    if _FORKS is None:
        import multiprocessing as mp

        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["snakemake.cli", "support.repo"])
        _FORKS = ctx
    return _FORKS


def _run_forked(cwd, args, timeout) -> subprocess.CompletedProcess:
    """Snakemake in a fork; a fork that ends with an error before writing a word (not a
    Snakemake verdict: Snakemake says why it fails) is run once more in a new fork."""
    r = _fork_once(cwd, args, timeout)
    if r.returncode and r.stderr.startswith(NO_OUTPUT):
        r = _fork_once(cwd, args, timeout)
    return r


#: the start of the stderr of a fork that ended with an error and no output
NO_OUTPUT = "the forked snakemake ended with exit code"


def _fork_once(cwd, args, timeout) -> subprocess.CompletedProcess:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        out, err = os.path.join(d, "out"), os.path.join(d, "err")
        p = _forks().Process(target=_snakemake_main, args=(str(Path(cwd).resolve()),
                                                           [str(a) for a in args],
                                                           dict(os.environ), out, err))
        p.start()
        p.join(timeout)
        if p.is_alive():
            p.kill()
            p.join()
            raise subprocess.TimeoutExpired(["snakemake", *args], timeout)
        read = lambda f: Path(f).read_text() if os.path.exists(f) else ""  # noqa: E731
        stderr = read(err)
        if p.exitcode and not stderr:  # ended before its output went to the files
            stderr = f"{NO_OUTPUT} {p.exitcode} and no output"
        return subprocess.CompletedProcess(["snakemake", *args], p.exitcode, read(out), stderr)


def run_snakemake(cwd, *args, timeout=1200, env=None, pythonpath=()):
    """Run Snakemake in ``cwd`` with this interpreter; ``env`` adds variables, and
    ``pythonpath`` folders go first on PYTHONPATH. The completed process (output captured).
    A command that runs no job (:data:`NO_JOBS`) and needs no environment of its own runs
    in a fork of a process that has Snakemake imported, not in a new interpreter."""
    if not env and not pythonpath and NO_JOBS & set(map(str, args)):
        return _run_forked(cwd, args, timeout)
    e = dict(os.environ, NUMBA_THREADING_LAYER="omp", **(env or {}))
    if pythonpath:
        e["PYTHONPATH"] = os.pathsep.join([*map(str, pythonpath),
                                           *filter(None, [e.get("PYTHONPATH")])])
    return subprocess.run([sys.executable, "-m", "snakemake", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout, env=e)
