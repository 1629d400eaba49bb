"""numba configuration shared by every kernel module.

- Kernels are compiled with ``cache=True`` so a warm cache makes job start-up cheap
  (kernels live in importable modules, never in workflow scripts).
- The threading layer is pinned to OpenMP before the first parallel call: with TBB
  (pulled in by some Debian packages) numba's per-call overhead was measured to grow
  without bound (measured during the engine's early development; that measurement is
  not kept as a record in docs/measurements). Set ``NUMBA_THREADING_LAYER`` yourself
  to override.
- A damaged cached kernel is removed and compiled again (``jit_cache``).
- ``NUMBA_DISABLE_JIT=1`` keeps working: ``prange`` becomes ``range`` and every kernel
  runs as plain Python (slow, for debugging).
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")


def _source_hash() -> str:
    """Hash of the engine's source files. numba invalidates a cached function only when
    its own file changes, not when a kernel it calls (in another module) does; keying the
    cache directory on all engine sources makes a stale mixture impossible."""
    h = hashlib.sha256()
    for f in sorted(Path(__file__).resolve().parent.glob("*.py")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


if "NUMBA_CACHE_DIR" not in os.environ:
    _cache = Path(os.environ.get("BPMCAL_CACHE", Path.home() / ".cache" / "bpmcal"))
    os.environ["NUMBA_CACHE_DIR"] = str(_cache / "numba" / _source_hash())

import numba  # noqa: E402
from numba import njit, prange  # noqa: E402,F401

from ..cost import meter_numba  # noqa: E402

if not numba.config.CACHE_DIR:  # numba was imported before us: set it at run time
    numba.config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]

# numba's loading of each kernel at its first call is booked to the cost ledger's phase
# "kernels" (bpmcal.cost: what a job spends its CPU on; the kernels are untouched)
meter_numba()
from .jit_cache import heal_cache_loads  # noqa: E402

heal_cache_loads()  # a damaged cached kernel is removed and compiled again (one line)

#: True when numba is switched off for debugging.
JIT_DISABLED = bool(numba.config.DISABLE_JIT)

# fastmath only for "contract" (fused multiply-adds, which every x86-64 host with FMA
# forms alike: docs/reproducibility.md), none of its other flags: results must not depend
# on instruction-level reassociation, and NaN checks must not be optimised away (blow-up
# detection relies on them).
# error_model="numpy": a division by zero gives inf/nan (caught by the blow-up guard)
# instead of raising; without it every division carries an exception branch that stops
# LLVM from vectorising the bond blocks.
jit = njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
jit_parallel = njit(cache=True, nogil=True, parallel=True, error_model="numpy",
                    fastmath={"contract"})


def compiled(dispatcher, args):
    """The machine code numba's ``dispatcher`` runs for ``args``: the compiled version's
    entry point, which a caller may keep and call with arguments of the same types without
    numba's matching of the argument types at every call (12-17 us for the stepping
    kernel's namedtuples of arrays, a tenth of a step of 1,000 balls: a servo-controlled
    seating calls the engine one step at a time). None when that version is not compiled
    or loaded yet (call the dispatcher once) or numba is off."""
    if JIT_DISABLED:
        return None
    try:  # numba's dispatcher API (another numba without it: None, the dispatcher runs)
        sig = tuple(dispatcher.typeof_pyval(a) for a in args)
        cres = dispatcher.overloads.get(sig)
        return None if cres is None else cres.entry_point
    except (AttributeError, TypeError, ValueError):
        return None


#: the thread count a caller forced (``set_threads(n)``), or None: models choose their own
#: (``threads.AutoThreads``)
_FORCED: list = [None]


def set_threads(n: int | None) -> int:
    """Force the number of numba threads for this process (``None``: leave as is; models
    then choose theirs, ``threads.auto_threads``). Returns the number in use."""
    if n is not None:
        if int(n) < 1:
            raise ValueError(f"threads must be >= 1, got {n}")
        _FORCED[0] = min(int(n), numba.config.NUMBA_NUM_THREADS)
        numba.set_num_threads(_FORCED[0])
    return numba.get_num_threads()


def forced_threads() -> int | None:
    """The thread count forced by :func:`set_threads`, or None."""
    return _FORCED[0]


def unforce_threads() -> None:
    """Let models choose their thread count again (tests; a long-lived process)."""
    _FORCED[0] = None
