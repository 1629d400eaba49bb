"""numba's kernel cache, healed: a cached kernel whose files are damaged (a disk that
filled while numba wrote them, a copy cut short, two numba versions in one folder) makes
numba's loader raise (``UnpicklingError``, ``EOFError``, ...) and every run that needs the
kernel stop. :func:`heal_cache_loads` wraps numba's loader so that such a kernel's cache
files are removed and the kernel is compiled again (numba then writes a fresh cache), with
one line on stderr for the whole process. Installed once by ``dem._jit``.
"""
from __future__ import annotations

import os
import sys

#: the cache folder of the first damaged kernel reported (one line per process)
_TOLD: list = []


def _discard(cache) -> list[str]:
    """Remove the index and data files of one function's cache; their names."""
    cf = cache._cache_file
    folder = cf._cache_path
    stem = cf._index_name[: -len(".nbi")]
    gone = []
    try:
        names = os.listdir(folder)
    except OSError:
        return gone
    for name in names:
        if name == cf._index_name or (name.startswith(stem + ".") and name.endswith(".nbc")):
            try:
                os.unlink(os.path.join(folder, name))
                gone.append(name)
            except OSError:
                pass
    return gone


def heal_cache_loads() -> None:
    """Wrap ``numba.core.caching.Cache.load_overload`` (once): a load that raises is a
    damaged cache entry, discarded; the kernel is then compiled as if it were not cached."""
    from numba.core import caching

    load = caching.Cache.load_overload
    if getattr(load, "_bpmcal_heals", False):
        return

    def load_overload(self, sig, target_context):
        try:
            return load(self, sig, target_context)
        except Exception as e:  # noqa: BLE001 - whatever a damaged file makes numba raise
            _discard(self)
            if not _TOLD:  # one line for the process, however many kernels are damaged
                _TOLD.append(self._cache_path)
                print(f"bpmcal: numba's kernel cache in {self._cache_path} is damaged "
                      f"({type(e).__name__} reading {getattr(self._py_func, '__name__', '?')}"
                      "); damaged kernels are removed and compiled again (this run starts "
                      "slower)", file=sys.stderr)
            return None

    load_overload._bpmcal_heals = True
    caching.Cache.load_overload = load_overload
