"""The packing cache: a relaxed packing (steps 1-3 of the genesis, ``lab.specimen``:
:func:`~bpmcal.lab.specimen.relax_packing`) depends only on its geometry, Rmin, radius
ratio, density, porosity and seed (``SpecimenSpec.key``, with the genesis version), not on
the material, so :func:`get_packing` relaxes it once and keeps it in a cache folder
(:func:`cache_dir`), written atomically (``io.atomic``). A damaged cache file is removed and
built again (a cache heals); a cache that cannot be written is no failure. The one file
the lab writes: a cache, not part of the study's file contract."""
from __future__ import annotations

import json
import os
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..cost import phase
from ..io.atomic import atomic_path
from .specimen import Packing, SpecimenSpec, relax_packing


def cache_dir() -> Path:
    """The packing cache: ``$BPMCAL_SPECIMEN_CACHE``, else ``~/.cache/bpmcal/packings``."""
    return Path(os.environ.get("BPMCAL_SPECIMEN_CACHE",
                               Path.home() / ".cache" / "bpmcal" / "packings"))


def get_packing(spec: SpecimenSpec, cache: str | os.PathLike | None = None,
                progress=None, threads=None) -> Packing:
    """The relaxed packing for ``spec``, from the cache directory when it is there
    (written atomically: temporary name, then rename); relaxed with ``threads`` numba
    threads when it is not."""
    d = Path(cache) if cache is not None else cache_dir()
    f = d / f"packing_{spec.key()}.npz"
    if f.exists():
        pk = _cached_packing(f, spec)
        if pk is not None:
            return pk
    with phase("relax"):  # the cost ledger: a packing relaxed, not read (bpmcal.cost)
        pk = relax_packing(spec, progress=progress, threads=threads)
    try:
        with atomic_path(f) as tmp, open(tmp, "wb") as fh:  # a file object: no ".npz" added
            np.savez(fh, pos=pk.pos, radius=pk.radius, report=json.dumps(pk.report),
                     spec=json.dumps(asdict(spec)))
    except OSError as e:  # a cache that cannot be written (full, read-only) is no failure
        _note(f"bpmcal: the packing cache {f} could not be written "
              f"({e.strerror or e}); going on without it")
    return pk


def _note(line: str) -> None:
    print(line, file=sys.stderr)


def _cached_packing(f: Path, spec: SpecimenSpec) -> Packing | None:
    """The packing cached in ``f``, or None when the file is damaged (truncated by a full
    disk, not a zip, arrays of the wrong shape or not finite): then it is removed with
    one line on stderr and the caller relaxes the packing again (a cache heals)."""
    import zipfile

    try:
        with np.load(f, allow_pickle=False) as z:
            pos, radius = np.asarray(z["pos"], float), np.asarray(z["radius"], float)
            report = json.loads(str(z["report"]))
        n = radius.shape[0] if radius.ndim == 1 else -1
        if n < 1 or pos.shape != (n, 3) or not (np.isfinite(pos).all()
                                                 and np.isfinite(radius).all()
                                                 and (radius > 0).all()):
            raise ValueError(f"arrays of shapes {pos.shape} and {radius.shape}, or not finite")
        if not isinstance(report, dict):
            raise ValueError("its report is not a mapping")
    except (OSError, EOFError, KeyError, ValueError, TypeError, zipfile.BadZipFile) as e:
        _note(f"bpmcal: the cached packing {f} is damaged ({type(e).__name__}: "
              f"{' '.join(str(e).split())[:120]}); it was removed and is built again")
        try:
            f.unlink()
        except OSError:
            pass
        return None
    return Packing(spec=spec, pos=pos, radius=radius, report=report)
