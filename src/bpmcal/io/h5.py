"""One HDF5 file per virtual test run: the schema, an atomic writer and readers.

StudyFiles (``SCHEMA_VERSION`` 1)::

    /                 attrs: schema_version, bpmcal_version, git_commit, created_utc,
                             test ("ucs" | "bts" | "triaxial" | "impact"),
                             status ("ok" | "failed"), error,
                             inputs_hash (of /inputs; older files: config_hash),
                             hostname, slurm_job_id
    /inputs           attrs: meso-parameters (paper units, names of params.py), geometry
                             (diameter_mm, height_mm, scale), seed, test settings
    /summary          attrs: results (``ucs_MPa``, ``E_GPa``, ``nu``, ``peak_strain``,
                             ``u_pre_MJm3``, ``cracks_tension``, ``cracks_shear``, ``n_balls``,
                             ``n_bonds``, ``porosity_achieved``, ``coordination``, ``steps``,
                             ``wall_s``, ``stop_reason``, ...); Brazilian runs
                             ``bts_MPa``, ``peak_load_N``, ``platen_mismatch``, ...;
                             triaxial runs ``sigma1_MPa``, ``sigma3_MPa``, ``E_GPa``,
                             ``nu``, ``sigma3_maxdev_rel``, ...
    /genesis          attrs: the specimen genesis report
    /series/<name>    1-D datasets, one row per record (attr ``unit``)
    /cracks/<name>    one row per broken bond: step, time [s], position [m] (n, 3),
                      normal (n, 3), mode (1 tension, 2 shear), radius [m], energy [J],
                      sigma, tau, sigma_n [Pa]
    /particles/initial  position (n, 3) [m], radius (n,) [m]
    /particles/final    position, velocity, angular_velocity
    /bonds            i, j, state (0 intact, 1 tension, 2 shear), break_step
    /fragments        (impact runs) mass [kg], size [m] (equivalent-sphere diameter) of
                      every fragment; /particles/final/fragment holds each ball's label
    /cost             attrs: what the process spent on this run (``bpmcal.cost``), since
                      the run file it wrote before (the first: since it began), this
                      file's writing included: cpu_s, phases (JSON: CPU seconds by phase
                      path), ball_steps (JSON: the engine's ball-steps by phase path),
                      process_cpu_s (the process's CPU seconds when written), pid

A file is written under a temporary name in the same directory and renamed when
complete, so a file that exists is complete (``write_run``). The HDF5 image is built in
memory and then written as plain bytes: a full disk or a file-size limit is an ``OSError``
naming the file (``ENOSPC``, ``EFBIG``), never an error inside the HDF5 library (which
h5py raises as ``RuntimeError`` and which could crash the interpreter at exit).

Readers raise :class:`RunFileError` (a ``ValueError``) naming the file when it is missing,
a directory or not a regular file, not HDF5 (another format, or truncated) or an HDF5 file
that is not a bpmcal run file; ``check_run_file`` does that check alone and returns the
root attributes. The array readers refuse a dataset of more than :data:`MAX_ELEMENTS`
values (a file of a few kB can declare terabytes of compressed fill values).
"""
from __future__ import annotations

import io
import json
import math
import stat
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from .atomic import atomic_path
from .provenance import provenance
from .safe_names import clip, shown

SCHEMA_VERSION = 1

#: units of the series columns (SI; strains dimensionless, compression positive)
SERIES_UNITS = {
    "step": "", "time": "s", "axial_strain": "", "lateral_strain": "", "axial_strain_central": "",
    "volumetric_strain": "", "axial_stress": "Pa", "stress_top": "Pa", "stress_bottom": "Pa",
    "cracks_tension": "", "cracks_shear": "", "kinetic": "J", "strain_linear": "J",
    "strain_bond": "J", "slip": "J", "damping": "J", "dashpot": "J", "released": "J",
    "work_walls": "J", "unbalanced": "",
    # Brazilian runs
    "displacement": "m", "diametral_strain": "", "load": "N", "load_bottom": "N",
    "load_top": "N", "tensile_stress": "Pa", "arc_deg": "deg",
    # triaxial runs
    "lateral_strain_wall": "", "confining_stress": "Pa", "deviator": "Pa", "wall_radius": "m",
    # impact runs
    "hammer_z": "m", "hammer_v": "m/s", "W_in": "J", "W_in_paper": "J", "work_gravity": "J",
    "eta_f": "", "closure_rel": "",
}


def _attr(v):
    """A value h5py can store as an attribute (None -> "", dict/list -> JSON)."""
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v)
    return str(v)


def _put_attrs(obj, d: dict):
    for k, v in d.items():
        obj.attrs[k] = _attr(v)


@dataclass(frozen=True)
class RunRecord:
    """What a run file holds (:func:`write_run`): its ``test`` and ``inputs``, ``status``
    ("ok", "failed", "incomplete") and ``error``; the attribute groups ``summary``,
    ``genesis`` and ``extra``; the datasets ``series``, ``cracks``, ``particles_initial``,
    ``particles_final`` and ``bonds``; and named ``groups`` of datasets of their own."""

    test: str
    inputs: dict
    summary: dict | None = None
    genesis: dict | None = None
    series: dict | None = None
    cracks: dict | None = None
    particles_initial: dict | None = None
    particles_final: dict | None = None
    bonds: dict | None = None
    status: str = "ok"
    error: str = ""
    extra: dict | None = None
    groups: dict | None = None


def write_run(path, record: RunRecord, *, cost=None) -> Path:
    """Write one run (``record``) atomically (built in memory, written to a temporary file
    in the same directory, then renamed). ``cost``: a callable giving the ``/cost``
    attributes, called when everything else is in the file (so that they include building
    it)."""
    path = Path(path)
    image = io.BytesIO()
    with h5py.File(image, "w") as f:
        _fill(f, record)
        if cost is not None:
            _put_attrs(f.create_group("cost"), cost())
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(image.getbuffer())
    return path


def _fill(f, r: RunRecord) -> None:
    """The groups and datasets of a run file (:func:`write_run`) in the open file ``f``."""
    prov = provenance(r.inputs, stamp=True)
    _put_attrs(f, {"schema_version": SCHEMA_VERSION, "test": r.test, "status": r.status,
                   "error": r.error, **prov})
    _put_attrs(f.create_group("inputs"), r.inputs)
    _put_attrs(f.create_group("summary"), r.summary or {})
    _put_attrs(f.create_group("genesis"), r.genesis or {})
    if r.extra:
        _put_attrs(f.create_group("extra"), r.extra)
    if r.series:
        g = f.create_group("series")
        for k, v in r.series.items():
            ds = g.create_dataset(k, data=np.asarray(v), compression="gzip",
                                  shuffle=True)
            ds.attrs["unit"] = SERIES_UNITS.get(k, "")
    if r.cracks is not None:
        g = f.create_group("cracks")
        for k, v in r.cracks.items():
            g.create_dataset(k, data=np.asarray(v))
    for name, d in (("initial", r.particles_initial), ("final", r.particles_final)):
        if d:
            g = f.require_group("particles").create_group(name)
            for k, v in d.items():
                g.create_dataset(k, data=np.asarray(v), compression="gzip",
                                 shuffle=True)
    for gname, arrays in (r.groups or {}).items():
        g = f.create_group(gname)
        for k, v in arrays.items():
            g.create_dataset(k, data=np.asarray(v))
    if r.bonds:
        g = f.create_group("bonds")
        for k, v in r.bonds.items():
            g.create_dataset(k, data=np.asarray(v), compression="gzip", shuffle=True)


def _decode(v):
    if isinstance(v, bytes):
        v = v.decode(errors="backslashreplace")
    if isinstance(v, np.generic):
        v = v.item()
    return v


class RunFileError(ValueError):
    """A file is not a readable bpmcal run file (missing, not HDF5, truncated, foreign)."""


#: the most values one dataset of a run file may hold to be read (a full-size specimen's
#: positions are ~0.2 M values, 2 M balls' 6 M): more is a damaged or crafted file
MAX_ELEMENTS = 50_000_000


@contextmanager
def _open(path):
    """Open a run file for reading; every failure to open or read it is a RunFileError."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise RunFileError(f"{path}: no such file") from None
    except OSError as e:  # a symlink loop, a path through a file
        raise RunFileError(f"{path}: cannot be opened ({e.strerror or e})") from None
    if stat.S_ISDIR(st.st_mode):
        raise RunFileError(f"{path}: is a directory, expected an HDF5 run file")
    if not stat.S_ISREG(st.st_mode):
        raise RunFileError(f"{path}: not a regular file (a FIFO, device or socket); "
                           "expected an HDF5 run file")
    try:
        f = h5py.File(p, "r")
    except OSError as e:
        reason = str(e).split("(")[-1].rstrip(")") if "(" in str(e) else str(e)
        raise RunFileError(f"{path}: not a readable HDF5 file ({reason.strip()}); "
                           "expected a bpmcal run file (truncated, or another format?)") from None
    try:
        with f:
            yield f
    except RunFileError:
        raise
    except (OSError, KeyError, RuntimeError, TypeError, ValueError) as e:  # opens, unreadable
        raise RunFileError(f"{path}: damaged HDF5 run file ({type(e).__name__}: "
                           f"{clip(' '.join(str(e).split()), 200)})") from None


def check_run_file(path) -> dict:
    """The root attributes of a bpmcal run file; RunFileError if ``path`` is not one."""
    with _open(path) as f:
        attrs = {k: _decode(v) for k, v in f.attrs.items()}
    missing = [k for k in ("schema_version", "test", "status") if k not in attrs]
    if missing:
        raise RunFileError(f"{path}: an HDF5 file but not a bpmcal run file (no {', '.join(missing)} "
                           "attribute)")
    bad = [k for k in ("test", "status") if not isinstance(attrs[k], str)]
    if bad:
        raise RunFileError(f"{path}: {bad[0]}={shown(attrs[bad[0]])}: expected text; not a "
                           "bpmcal run file")
    try:
        version = int(attrs["schema_version"])
    except (TypeError, ValueError, OverflowError):
        raise RunFileError(f"{path}: schema_version={shown(attrs['schema_version'])} is not an "
                           "integer") from None
    if version > SCHEMA_VERSION:
        raise RunFileError(f"{path}: run file schema_version {version} is newer than this bpmcal "
                           f"reads ({SCHEMA_VERSION}); update bpmcal")
    return attrs


def read_attrs(path, group: str = "/") -> dict:
    with _open(path) as f:
        if group not in f:
            return {}
        if not isinstance(f[group], h5py.Group):
            raise RunFileError(f"{path}: /{group.strip('/')} is not a group")
        return {k: _decode(v) for k, v in f[group].attrs.items()}


def _values(path, ds):
    """The values of dataset ``ds`` of run file ``path``: numbers (or text), at most
    :data:`MAX_ELEMENTS` of them, else a RunFileError naming it."""
    if not isinstance(ds, h5py.Dataset):
        raise RunFileError(f"{path}: {ds.name} is not a dataset")
    if ds.dtype.kind not in "biuf" or ds.dtype.names:
        raise RunFileError(f"{path}: {ds.name} holds {ds.dtype} values, expected numbers")
    if ds.size > MAX_ELEMENTS:
        raise RunFileError(f"{path}: {ds.name} declares {ds.size:,} values {ds.shape}, more "
                           f"than a run file holds ({MAX_ELEMENTS:,}): a damaged or foreign "
                           "file")
    return ds[()]


def _arrays(path, f, name) -> dict:
    """Every dataset of group ``name`` (:func:`_values`), {} if there is none."""
    if name not in f:
        return {}
    g = f[name]
    if not isinstance(g, h5py.Group):
        raise RunFileError(f"{path}: {g.name} is not a group")
    return {k: _values(path, g[k]) for k in g}


def read_summary(path) -> dict:
    """Summary results plus status/error/test and provenance, as one flat dict (a
    RunFileError if ``path`` is not a bpmcal run file)."""
    out = check_run_file(path)
    out.update(read_attrs(path, "summary"))
    return out


def read_inputs(path) -> dict:
    return read_attrs(path, "inputs")


def read_genesis(path) -> dict:
    return read_attrs(path, "genesis")


def read_series(path):
    """Time series as a pandas DataFrame (SI units; see ``SERIES_UNITS``)."""
    import pandas as pd
    with _open(path) as f:
        d = _arrays(path, f, "series")
    try:
        return pd.DataFrame(d)
    except ValueError as e:  # columns of different lengths, or not 1-D
        raise RunFileError(f"{path}: /series is damaged ({e})") from None


def read_cracks(path):
    """Crack events as a DataFrame (x, y, z, nx, ny, nz split out)."""
    import pandas as pd
    with _open(path) as f:
        g = _arrays(path, f, "cracks")
    d = {}
    for k, v in g.items():
        if v.ndim == 2 and v.shape[1] == 3:
            names = ("x", "y", "z") if k == "position" else tuple(f"{k}_{c}" for c in "xyz")
            for c, nm in enumerate(names):
                d[nm] = v[:, c]
        else:
            d[k] = v
    try:
        return pd.DataFrame(d)
    except ValueError as e:
        raise RunFileError(f"{path}: /cracks is damaged ({e})") from None


def read_particles(path, which: str = "final") -> dict:
    with _open(path) as f:
        return _arrays(path, f, f"particles/{which}")


def read_group(path, name) -> dict:
    with _open(path) as f:
        return _arrays(path, f, name)


def read_bonds(path) -> dict:
    with _open(path) as f:
        return _arrays(path, f, "bonds")


def json_safe(d: dict) -> dict:
    """NaN/inf -> None, numpy scalars -> Python, arrays -> lists (of a crafted file's
    attribute), anything else JSON cannot hold -> its text, for JSON output."""
    out = {}
    for k, v in d.items():
        v = _decode(v)
        if isinstance(v, np.ndarray):
            v = v.tolist() if v.dtype.kind in "biuf" else str(v)
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        elif not isinstance(v, (str, int, float, bool, list, type(None))):
            v = str(v)
        out[str(k)] = v
    return out
