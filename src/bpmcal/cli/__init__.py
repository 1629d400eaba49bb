"""The ``bpmcal`` command: one subcommand per job of the study (workflow rules call these).

    bpmcal ucs --params FILE.yaml --out RUN.h5 [--set NAME=VALUE ...] [--scale S] [--seed N]
    bpmcal sample --design DESIGN.csv --sample ID --out UCS.h5 [--bts-out BTS.h5] [--dtt-out ...]
    bpmcal bts --params FILE.yaml --out RUN.h5 [--scale S] [--seed N] [--platen-velocity V]
    bpmcal dtt --params FILE.yaml --out RUN.h5 [--scale S] [--seed N] [--grip-velocity V]
    bpmcal triaxial --params FILE.yaml --sigma3 MPA --out RUN.h5 [--scale S] [--seed N]
    bpmcal summary RUN.h5 [--json]
    bpmcal vtk RUN.h5 --out DIR

Parameters are in the paper's units at this edge (mm, GPa, MPa, degrees); the package
works in SI inside. Bad input (arguments, parameter values, input files, output paths,
resource budgets) is reported before any work starts as one line on stderr,
``bpmcal CMD: error: ...``, with exit code 2, and nothing is written. Exit codes: 0 done,
1 internal error (a bug: traceback and a hint), 2 bad input, 3 the DEM run failed (or
ended incomplete) and its record was written (0 with ``--failed-ok``, what the workflow
rules pass), 4 system error (disk full, a file-size limit, memory, a killed worker,
SIGTERM), 130 interrupted. A closed stdout or stderr is no error of its own, and a command
that fails removes the folders it created and left empty.

The package only parses arguments and calls one stage (``bpmcal.stages``, the report) or
one I/O helper. This module holds ``main``, the registry ``COMMANDS`` and
``build_parser``; the subcommands are grouped by family, each ``_add_<cmd>`` (its options)
directly above its ``cmd_<cmd>`` (its handler):

- ``cli.runs``: the DEM runs ``ucs``, ``bts``, ``dtt``, ``triaxial``, ``impact``, the
  study's sample job ``sample``, and ``summary``, ``vtk``;
- ``cli.study``: ``design``, ``gather``, ``screen``, ``regress``, ``calibrate``,
  ``sweep-plan``, ``sweep-analyse``, ``report``;
- ``cli.verification``: ``verify``, ``transfer``, ``transfer-table``, ``scatter``,
  ``fresh-seeds``, ``fresh-seeds-table``, ``bts-size``, ``verification-tables``,
  ``envelopes``, ``impact-analyse``;
- ``cli.posterior``: ``posterior``, ``predictive``;
- ``cli.options``: the option groups several commands share and their readers;
- ``cli.args``: argument types and exit codes.

Every default comes from the settings it sets (the lab tests' settings dataclasses,
``Geometry``, the analysis classes and the stage functions: :func:`defaults_of`), never a
literal here. Each ``_add_<cmd>`` imports what that command needs, and ``main`` builds only
the parser of the command it runs: a DEM job (``bpmcal sample``, 150 per study) does not load
xgboost, statsmodels or matplotlib (tested: ``tests/architecture/test_imports.py``).
"""
from __future__ import annotations

import argparse
import errno
import os
import signal
import sys
import threading
import traceback

from .. import cost
from .. import params as P
from ..io.checks import BadInput
from .args import EXIT_BAD_INPUT, EXIT_BUG, EXIT_INTERRUPTED, EXIT_OK, EXIT_SYSTEM, Parser
from .options import (
    BTS_OPTIONS,
    DTT_OPTIONS,
    GENESES,
    add_bts_args,
    add_budget_args,
    add_dtt_args,
    add_outcome_args,
    add_run_args,
    add_source_args,
    add_specimen_args,
    bts_disc_of,
    bts_settings_of,
    dtt_cylinder_of,
    dtt_settings_of,
    run_geometry,
    run_settings,
)
from .posterior import _add_posterior, _add_predictive
from .runs import (
    _add_bts,
    _add_dtt,
    _add_impact,
    _add_sample,
    _add_summary,
    _add_triaxial,
    _add_ucs,
    _add_vtk,
)
from .study import (
    _add_calibrate,
    _add_design,
    _add_gather,
    _add_regress,
    _add_report,
    _add_screen,
    _add_sweep_analyse,
    _add_sweep_plan,
)
from .verification import (
    _add_bts_size,
    _add_envelopes,
    _add_fresh_seeds,
    _add_fresh_seeds_table,
    _add_impact_analyse,
    _add_scatter,
    _add_transfer,
    _add_transfer_table,
    _add_verification_tables,
    _add_verify,
)

#: ``bpmcal.cli``'s own names and the shared options re-exported from ``cli.options``
#: (``BTS_OPTIONS``/``DTT_OPTIONS`` name the bts/dtt config keys that are options, read by
#: ``cli.jobs``, which builds the workflow's commands; tests read ``GENESES``)
__all__ = ["COMMANDS", "build_parser", "main", "BTS_OPTIONS", "DTT_OPTIONS",
           "GENESES",
           "add_bts_args", "add_budget_args", "add_dtt_args", "add_outcome_args", "add_run_args",
           "add_source_args", "add_specimen_args", "bts_disc_of", "bts_settings_of",
           "dtt_cylinder_of", "dtt_settings_of", "run_geometry", "run_settings"]


def _param_help() -> str:
    rows = ["meso-parameters (keys of the --params YAML file and of --set; paper units):"]
    for p in P.PARAMS.values():
        unit = p.unit or "-"
        rows.append(f"  {p.name:12s} {p.symbol:9s} [{unit:3s}] Table 2 range {p.lo:g}-{p.hi:g}:"
                    f" {p.description}")
    rows.append("exit codes: 0 done, 2 bad input (nothing written), 3 the run failed or ended "
                "incomplete and its record was written (0 with --failed-ok), 1 internal "
                "error, 4 system error (disk full, memory, SIGTERM), 130 interrupted")
    return "\n".join(rows)


#: subcommand -> (help, adds its options, whether its help lists the parameters)
COMMANDS = {
    "ucs": ("one virtual uniaxial compression test -> HDF5", _add_ucs, True),
    "bts": ("one virtual Brazilian (diametral compression) test -> HDF5", _add_bts, True),
    "dtt": ("one virtual direct-tension test -> HDF5", _add_dtt, True),
    "triaxial": ("one virtual triaxial compression test -> HDF5", _add_triaxial, True),
    "impact": ("drop-hammer impact of a calibrated specimen", _add_impact, False),
    "sample": ("the study's sample job: a design sample's UCS test and, in the same process, "
               "its Brazilian, direct-tension and triaxial tests -> HDF5 each", _add_sample,
               True),
    "design": ("Latin-hypercube design over parameter ranges -> CSV", _add_design, False),
    "gather": ("collect per-sample run files into one dataset CSV", _add_gather, False),
    "screen": ("XGBoost screening of the dataset (Table 3)", _add_screen, False),
    "regress": ("three-stage stepwise regression (Table 4)", _add_regress, False),
    "calibrate": ("invert the models for the lab specimens", _add_calibrate, False),
    "verify": ("closed-loop DEM verification of a material card", _add_verify, False),
    "scatter": ("one card, several packing seeds: DEM scatter", _add_scatter, False),
    "transfer": ("run a verified card at full size; correct it there if needed",
                 _add_transfer, False),
    "transfer-table": ("the full-size transfer of every card, one table", _add_transfer_table,
                       False),
    "fresh-seeds": ("a verified card on fresh packing seeds (UCS and, with a sigma_t target, "
                    "Brazilian tests)", _add_fresh_seeds, False),
    "fresh-seeds-table": ("the fresh-seed check of every card against its lab targets",
                          _add_fresh_seeds_table, False),
    "bts-size": ("a verified card's σt size curve and σt at the lab's disc size",
                 _add_bts_size, False),
    "verification-tables": ("Tables 5 and 6 and Fig. 6", _add_verification_tables, False),
    "posterior": ("a verified card's posterior: what its targets pin and leave free",
                  _add_posterior, False),
    "predictive": ("posterior draws run in DEM: triaxial envelope and impact spreads",
                   _add_predictive, False),
    "envelopes": ("triaxial strength envelopes (Mohr-Coulomb, Hoek-Brown) per card",
                  _add_envelopes, False),
    "sweep-plan": ("bond-strength-ratio sweep: one row per ratio", _add_sweep_plan, False),
    "sweep-analyse": ("crack counts per ratio, the chosen ratio", _add_sweep_analyse, False),
    "impact-analyse": ("impact energy table, Fig. 7, t10-Ecs and JK fit", _add_impact_analyse,
                       False),
    "report": ("OUTDIR/report: every table and figure + index.md", _add_report, False),
    "summary": ("print the summary attributes of a run file", _add_summary, False),
    "vtk": ("export particles and cracks of a run for ParaView", _add_vtk, False),
}

def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``bpmcal`` parser; with ``only``, the options of that subcommand alone (the
    others are listed by name)."""
    ap = Parser(prog="bpmcal", description=__doc__.split("\n\n")[0],
                formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"bpmcal {_version()}")
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="{%s}" % ",".join(COMMANDS))
    for name, (help_, add, epilog) in COMMANDS.items():
        p = sub.add_parser(name, help=help_, formatter_class=argparse.RawDescriptionHelpFormatter,
                           epilog=_param_help() if epilog else None)
        if only is None or only == name:
            add(p)
    return ap


def _version():
    from .. import __version__
    return __version__


def _bad_input_types() -> tuple:
    from ..dem.errors import InputError
    from ..io.h5 import RunFileError
    from ..study.config import ConfigError

    return (BadInput, P.ParameterError, InputError, ConfigError, RunFileError)


def _system_error_types() -> tuple:
    """Failures of the machine, not of bpmcal or the input: memory, a worker process that
    died (killed, out of memory)."""
    from ..stages.pool import WorkerLost

    return (MemoryError, WorkerLost)


def _one_line(e) -> str:
    from ..io.safe_names import LINE_CHARS, clip

    return clip(" ".join(str(e).split()), LINE_CHARS)


#: errno -> (what happened, what to do) of a failed read or write (exit code 4)
_SYSTEM_ADVICE = {
    errno.ENOSPC: ("no space left on the device (the disk is full)",
                   "free space there or write the outputs to another file system"),
    errno.EDQUOT: ("disk quota exceeded", "free space in your quota or write elsewhere"),
    errno.EFBIG: ("file too large for a limit on file size (ulimit -f, or the file "
                  "system's)", "raise the limit or write to another file system"),
    errno.EACCES: ("permission denied", "check the permissions of the file and its folder"),
    errno.EPERM: ("operation not permitted", "check the permissions of the file and its "
                                             "folder"),
    errno.EROFS: ("read-only file system", "write the outputs to a writable folder"),
    errno.EIO: ("input/output error (a failing disk or network file system)",
                "check the file system, then run the command again"),
    errno.ENOMEM: ("out of memory", "free memory, or run fewer jobs at once"),
    errno.EMFILE: ("too many open files", "raise the limit (ulimit -n)"),
}


def _system_message(e: BaseException) -> str:
    """What happened and what to do, in one line, for a system error (exit code 4)."""
    if isinstance(e, MemoryError):
        return ("out of memory (system error): free memory, run fewer jobs at once, or a "
                "smaller specimen (--mem-budget-mb / resources.dem_mem_mb)")
    if not isinstance(e, OSError):  # a worker that died (stages.pool.WorkerLost)
        return f"{_one_line(e)} (system error): run it again with fewer jobs at once"
    name = f"{e.filename}: " if getattr(e, "filename", None) else ""
    what, todo = _SYSTEM_ADVICE.get(e.errno, (e.strerror or _one_line(e), ""))
    hint = f"; {todo}" if todo else ""
    return (f"{name}{what} (system error){hint}; no file was left under the name of the file "
            "being written")


class _Terminated(KeyboardInterrupt):
    """SIGTERM (a Slurm time limit, ``snakemake`` stopping its jobs, ``kill``): handled as
    Ctrl-C is (the file being written is discarded), reported as a system error."""


def _on_sigterm(signum, frame):
    raise _Terminated()


def _usable_std_streams() -> None:
    """A closed stdout or stderr (``2>&-``; the descriptor may even be reused by a file
    opened for reading since) is replaced by /dev/null for this process's messages: a
    message that cannot be shown must not turn into a second error (the exit code
    still tells)."""
    import fcntl

    for fd, name in ((1, "stdout"), (2, "stderr")):
        try:
            mode = fcntl.fcntl(fd, fcntl.F_GETFL) & os.O_ACCMODE
        except OSError:
            mode = None
        if mode not in (os.O_WRONLY, os.O_RDWR):
            setattr(sys, name, open(os.devnull, "w"))  # noqa: SIM115 - lives as sys.std*


def main(argv=None) -> int:
    """Run one subcommand; returns the exit code (see the module doc). As the ``bpmcal``
    command (``argv`` None: this process's command line) it ends the process when done:
    :func:`_end`."""
    rc = _run(argv)
    if argv is None and sys.getprofile() is None and sys.gettrace() is None:
        _end(rc)  # (a profiler or tracer, e.g. cProfile, writes its output at the teardown)
    return rc


def _end(rc: int) -> None:
    """End the process with exit code ``rc`` once its output is flushed and its exit
    handlers (``atexit``) have run, without tearing the interpreter down: the teardown
    (freeing every module, numba's and LLVM's objects among them) cost about 0.2 CPU s
    of every job, which no job needs (every file is closed, every worker joined). Not
    under a profiler or a tracer (``main``)."""
    import atexit

    for f in (sys.stdout, sys.stderr):
        try:
            f.flush()
        except (OSError, ValueError):
            pass
    getattr(threading, "_shutdown", lambda: None)()  # join the threads, as an exit does
    atexit._run_exitfuncs()
    os._exit(rc if isinstance(rc, int) else EXIT_BUG)


def _run(argv) -> int:
    """``main``'s work. A command that fails removes the folders it created and left
    empty."""
    from ..io.atomic import forget_created_dirs, remove_created_dirs

    os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
    _usable_std_streams()
    forget_created_dirs()
    old = None
    if threading.current_thread() is threading.main_thread():
        old = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        rc = _main(argv)
    finally:
        if old is not None:
            signal.signal(signal.SIGTERM, old)
    if rc != EXIT_OK:
        remove_created_dirs()
    return rc


def _main(argv) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    cmd = next((x for x in argv if not x.startswith("-")), None)
    ap = build_parser(only=cmd if cmd in COMMANDS else None)
    try:
        args = ap.parse_args(argv)
    except SystemExit as e:  # --help, --version, usage errors (one line, exit 2)
        return e.code if isinstance(e.code, int) else (0 if e.code is None else EXIT_BAD_INPUT)
    cost.begin()  # the CPU seconds so far (imports, the parser): the start (bpmcal.cost)
    try:
        bad_input, system = _bad_input_types(), _system_error_types()
    except Exception:  # noqa: BLE001 - a broken install is a bug, reported below
        bad_input, system = (BadInput, P.ParameterError), (MemoryError,)
    where = f"bpmcal {args.cmd}"
    try:
        return args.func(args)
    except bad_input as e:
        print(f"{where}: error: {_one_line(e)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except _Terminated:
        print(f"\n{where}: terminated (SIGTERM: a time limit, or the job was stopped); the "
              "file being written was discarded: run the command again to redo it",
              file=sys.stderr)
        return EXIT_SYSTEM
    except KeyboardInterrupt:
        print(f"\n{where}: interrupted; the file being written was discarded", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `bpmcal summary run.h5 | head`
        sys.stdout = open(os.devnull, "w")
        return EXIT_OK
    except (OSError, *system) as e:
        print(f"{where}: error: {_system_message(e)}", file=sys.stderr)
        return EXIT_SYSTEM
    except Exception:  # noqa: BLE001 - a bug: keep the traceback, add a hint
        traceback.print_exc()
        print(f"{where}: internal error (a bug in bpmcal, not in your input): please report it "
              "with the traceback above and the command line", file=sys.stderr)
        return EXIT_BUG
    finally:
        cost.print_cost_line(where)  # with BPMCAL_COST set (the workflow's jobs)

