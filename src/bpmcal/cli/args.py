"""What every ``bpmcal`` subcommand shares: argument types and the exit codes (the checks
of input and output files are in ``bpmcal.io.checks``). New subcommands use these so that
bad input always ends the same way:
one line on stderr, ``bpmcal <cmd>: error: <the bad value>: <what was expected>``, exit
code 2, no output file, and that before any work starts.

Exit codes (docs/troubleshooting.md lists them):

==  =======================================================================================
0   done
1   internal error (a bug in bpmcal): traceback, then a one-line hint
2   bad input (arguments, parameter values, input files, resource budget); nothing written
3   the DEM run failed (instability, genesis not converged, step budget); a *failure
    record* (status "failed" and the reason) was written; or it ended incomplete (a
    cut-off came before the peak and drop that define its measure: the run file has status
    "incomplete" and the reason). With ``--failed-ok`` (what the workflow rules pass) such
    a run exits 0: the failure is data, carried into the dataset
4   the system failed: disk full, a file-size limit, permission denied while writing, out
    of memory, a worker process killed, SIGTERM (a time limit); one line says what
    happened and what to do, files being written were discarded
130 interrupted (Ctrl-C / SIGINT); files being written were discarded
==  =======================================================================================

Use:

- ``type=`` converters for argparse: :func:`number`, :func:`integer`, ``SEED``,
  ``THREADS`` (NaN, inf, booleans and out-of-range values are refused by name);
  :func:`limited` for an option of a settings field (the field's bounds);
- :class:`Parser` (argparse errors as one line); ``bpmcal.io.checks.BadInput`` for
  anything else a user can get wrong.
"""
from __future__ import annotations

import argparse
import math

EXIT_OK = 0
EXIT_BUG = 1
EXIT_BAD_INPUT = 2
EXIT_RUN_FAILED = 3
EXIT_SYSTEM = 4
EXIT_INTERRUPTED = 130

class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line: ``PROG: error: MESSAGE (see PROG --help)``."""

    def error(self, message):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {' '.join(message.split())} "
                                  f"(see '{self.prog} --help')\n")


# ------------------------------------------------------------------------ argument types
def _cut(s: str, limit: int = 60) -> str:
    """``repr(s)`` of an argument for a message, cut to ``limit`` characters."""
    r = repr(s)
    return r if len(r) <= limit else f"{r[:limit]}... ({len(r) - limit:,} more characters)"


def number(name: str, lo: float | None = None, hi: float | None = None, *,
           lo_open: bool = False, hi_open: bool = False, unit: str = ""):
    """An argparse type: a finite float within [lo, hi] (open ends as told)."""
    u = f" {unit}" if unit else ""

    def rng():
        a = "-inf" if lo is None else f"{lo:g}"
        b = "inf" if hi is None else f"{hi:g}"
        return f"{'(' if lo_open or lo is None else '['}{a}, {b}{')' if hi_open or hi is None else ']'}"

    def conv(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}={_cut(s)}: expected a number{u}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{name}={s!r}: expected a finite number{u}")
        bad = (lo is not None and (v <= lo if lo_open else v < lo)) or \
              (hi is not None and (v >= hi if hi_open else v > hi))
        if bad:
            raise argparse.ArgumentTypeError(f"{name}={s!r}: expected a number in {rng()}{u}")
        return v
    conv.__name__ = name  # argparse names the type in some messages
    conv.bounds = (lo, lo_open, hi, hi_open)  # compared with the config schema's (tests)
    return conv


def positive(name, unit=""):
    return number(name, 0.0, lo_open=True, unit=unit)


def fraction(name):
    return number(name, 0.0, 1.0, lo_open=True, hi_open=True)


def integer(name: str, lo: int | None = None, hi: int | None = None):
    """An argparse type: an integer within [lo, hi]."""
    def conv(s):
        try:
            v = int(s, 10)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}={_cut(s)}: expected an integer") from None
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            a = "" if lo is None else f">= {lo}"
            b = "" if hi is None else f"<= {hi}"
            raise argparse.ArgumentTypeError(
                f"{name}={s!r}: expected an integer {' and '.join(x for x in (a, b) if x)}")
        return v
    conv.__name__ = name
    conv.bounds = (lo, False, hi, False)
    return conv


def limited(name: str, limit, *, unit: str = ""):
    """An argparse type of a settings field's ``limit`` (a
    ``bpmcal.analysis.calibration.loop_settings.Limit`` of kind "int" or "float"):
    :func:`integer` or :func:`number` within the field's bounds, so that the option
    accepts what the field accepts."""
    if limit.kind == "int":
        return integer(name, None if limit.lo is None else int(limit.lo),
                       None if limit.hi is None else int(limit.hi))
    return number(name, limit.lo, limit.hi, lo_open=limit.lo_open, hi_open=limit.hi_open,
                  unit=unit)


def integer_or(word: str, name: str, lo: int | None = None, hi: int | None = None):
    """An argparse type: ``word`` as it is, else :func:`integer` within [lo, hi]."""
    whole = integer(name, lo, hi)

    def conv(s):
        if s == word:
            return s
        try:
            return whole(s)
        except argparse.ArgumentTypeError as e:
            raise argparse.ArgumentTypeError(f"{e}, or {word!r}") from None
    conv.__name__ = name
    return conv


def choice(name: str, options):
    """An argparse type: one of ``options`` (the message names them)."""
    opts = tuple(options)

    def conv(s):
        if s not in opts:
            raise argparse.ArgumentTypeError(f"{name}={_cut(s)}: expected one of {', '.join(opts)}")
        return s
    conv.__name__ = name
    return conv


SEED = integer("seed", 0, 2 ** 32 - 1)
THREADS = integer("threads", 1, 4096)
