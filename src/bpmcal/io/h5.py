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
complete, so a file that exists is complete (``write_run``).

Readers raise :class:`RunFileError` (a ``ValueError``) naming the file when it is missing,
a directory, not HDF5 (another format, or truncated) or an HDF5 file that is not a bpmcal
run file; ``check_run_file`` does that check alone and returns the root attributes.
"""
from __future__ import annotations

import json
import math
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np

from .atomic import atomic_path
from .provenance import provenance

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


def write_run(path, *, test: str, inputs: dict, summary: dict | None = None,
              genesis: dict | None = None, series: dict | None = None,
              cracks: dict | None = None, particles_initial: dict | None = None,
              particles_final: dict | None = None, bonds: dict | None = None,
              status: str = "ok", error: str = "", extra: dict | None = None,
              groups: dict | None = None, cost=None) -> Path:
    """Write one run atomically (temporary file in the same directory, then rename).
    ``cost``: a callable giving the ``/cost`` attributes, called when everything else is
    written (so that they include the writing)."""
    path = Path(path)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        prov = provenance(inputs, stamp=True)
        _put_attrs(f, {"schema_version": SCHEMA_VERSION, "test": test, "status": status,
                       "error": error, **prov})
        _put_attrs(f.create_group("inputs"), inputs)
        _put_attrs(f.create_group("summary"), summary or {})
        _put_attrs(f.create_group("genesis"), genesis or {})
        if extra:
            _put_attrs(f.create_group("extra"), extra)
        if series:
            g = f.create_group("series")
            for k, v in series.items():
                ds = g.create_dataset(k, data=np.asarray(v), compression="gzip",
                                      shuffle=True)
                ds.attrs["unit"] = SERIES_UNITS.get(k, "")
        if cracks is not None:
            g = f.create_group("cracks")
            for k, v in cracks.items():
                g.create_dataset(k, data=np.asarray(v))
        for name, d in (("initial", particles_initial), ("final", particles_final)):
            if d:
                g = f.require_group("particles").create_group(name)
                for k, v in d.items():
                    g.create_dataset(k, data=np.asarray(v), compression="gzip",
                                     shuffle=True)
        for gname, arrays in (groups or {}).items():
            g = f.create_group(gname)
            for k, v in arrays.items():
                g.create_dataset(k, data=np.asarray(v))
        if bonds:
            g = f.create_group("bonds")
            for k, v in bonds.items():
                g.create_dataset(k, data=np.asarray(v), compression="gzip", shuffle=True)
        if cost is not None:
            _put_attrs(f.create_group("cost"), cost())
    return path


def _decode(v):
    if isinstance(v, bytes):
        v = v.decode()
    if isinstance(v, np.generic):
        v = v.item()
    return v


class RunFileError(ValueError):
    """A file is not a readable bpmcal run file (missing, not HDF5, truncated, foreign)."""


@contextmanager
def _open(path):
    """Open a run file for reading; every failure to open or read it is a RunFileError."""
    p = Path(path)
    if not p.exists():
        raise RunFileError(f"{path}: no such file")
    if p.is_dir():
        raise RunFileError(f"{path}: is a directory, expected an HDF5 run file")
    try:
        f = h5py.File(p, "r")
    except OSError as e:
        reason = str(e).split("(")[-1].rstrip(")") if "(" in str(e) else str(e)
        raise RunFileError(f"{path}: not a readable HDF5 file ({reason.strip()}); "
                           "expected a bpmcal run file (truncated, or another format?)") from None
    try:
        with f:
            yield f
    except (OSError, KeyError) as e:  # a damaged file that opens but cannot be read
        raise RunFileError(f"{path}: damaged HDF5 run file ({type(e).__name__}: "
                           f"{' '.join(str(e).split())})") from None


def check_run_file(path) -> dict:
    """The root attributes of a bpmcal run file; RunFileError if ``path`` is not one."""
    with _open(path) as f:
        attrs = {k: _decode(v) for k, v in f.attrs.items()}
    missing = [k for k in ("schema_version", "test", "status") if k not in attrs]
    if missing:
        raise RunFileError(f"{path}: an HDF5 file but not a bpmcal run file (no {', '.join(missing)} "
                           "attribute)")
    try:
        version = int(attrs["schema_version"])
    except (TypeError, ValueError):
        raise RunFileError(f"{path}: schema_version={attrs['schema_version']!r} is not an "
                           "integer") from None
    if version > SCHEMA_VERSION:
        raise RunFileError(f"{path}: run file schema_version {version} is newer than this bpmcal "
                           f"reads ({SCHEMA_VERSION}); update bpmcal")
    return attrs


def read_attrs(path, group: str = "/") -> dict:
    with _open(path) as f:
        if group not in f:
            return {}
        return {k: _decode(v) for k, v in f[group].attrs.items()}


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
        if "series" not in f:
            return pd.DataFrame()
        return pd.DataFrame({k: f["series"][k][()] for k in f["series"]})


def read_cracks(path):
    """Crack events as a DataFrame (x, y, z, nx, ny, nz split out)."""
    import pandas as pd
    with _open(path) as f:
        if "cracks" not in f:
            return pd.DataFrame()
        g = f["cracks"]
        d = {}
        for k in g:
            v = g[k][()]
            if v.ndim == 2 and v.shape[1] == 3:
                names = ("x", "y", "z") if k == "position" else tuple(f"{k}_{c}" for c in "xyz")
                for c, nm in enumerate(names):
                    d[nm] = v[:, c]
            else:
                d[k] = v
        return pd.DataFrame(d)


def read_particles(path, which: str = "final") -> dict:
    with _open(path) as f:
        key = f"particles/{which}"
        if key not in f:
            return {}
        return {k: f[key][k][()] for k in f[key]}


def read_group(path, name) -> dict:
    with _open(path) as f:
        if name not in f:
            return {}
        return {k: f[name][k][()] for k in f[name]}


def read_bonds(path) -> dict:
    with _open(path) as f:
        if "bonds" not in f:
            return {}
        return {k: f["bonds"][k][()] for k in f["bonds"]}


def json_safe(d: dict) -> dict:
    """NaN/inf -> None, numpy scalars -> Python, for JSON output."""
    out = {}
    for k, v in d.items():
        v = _decode(v)
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        out[k] = v
    return out
