"""Checks of the files a command reads and writes, shared by the CLI and the stages:
every problem is a :class:`BadInput` naming the file (or option) and what was expected,
raised before any work starts (the CLI turns it into one line on stderr and exit code 2).

- :func:`in_file`, :func:`read_yaml`, :func:`read_json`, :func:`read_csv` for inputs
  (missing, a directory, unreadable, binary, garbled, columns missing, no rows);
- :func:`out_file`, :func:`out_dir` for outputs, called before any work (after the other
  checks: they create the directory and prove it writable).
"""
from __future__ import annotations

import json
import os
from pathlib import Path

H5_SUFFIXES = (".h5", ".hdf5")


class BadInput(ValueError):
    """An expected failure caused by the user's input (exit code 2)."""


# ------------------------------------------------------------------------ input files
def in_file(path, flag: str) -> Path:
    """An existing, readable regular file."""
    p = Path(path)
    if str(path) == "":
        raise BadInput(f"{flag} '': expected a file name")
    if not p.exists():
        raise BadInput(f"{flag} {path}: no such file")
    if p.is_dir():
        raise BadInput(f"{flag} {path}: is a directory, expected a file")
    if not os.access(p, os.R_OK):
        raise BadInput(f"{flag} {path}: not readable (permission denied)")
    return p


def read_text(path, flag: str) -> str:
    p = in_file(path, flag)
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise BadInput(f"{flag} {path}: not a UTF-8 text file (byte {e.start}: "
                       f"{e.object[e.start:e.start + 1]!r})") from None


def _yaml_loader():
    """PyYAML's safe loader, with YAML 1.2 floats: ``1e-9`` is a number (YAML 1.1, and so
    PyYAML, reads it as the string "1e-9")."""
    import re

    import yaml

    class Loader(yaml.SafeLoader):
        pass

    Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)$"), list("-+0123456789"))
    return Loader


def read_yaml(path, flag: str, *, mapping: bool = True):
    """A YAML file (a mapping unless ``mapping=False``); binary or garbled files, a
    directory, a missing file are BadInput naming the file and the place of the error.
    ``1e-9`` is read as a number (YAML 1.2), booleans stay booleans."""
    import yaml

    text = read_text(path, flag)
    try:
        d = yaml.load(text, Loader=_yaml_loader())  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        what = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise BadInput(f"{flag} {path}: not valid YAML{where} ({what})") from None
    if mapping and not isinstance(d, dict):
        raise BadInput(f"{flag} {path}: expected a YAML mapping (name: value lines), got "
                       f"{'an empty file' if d is None else type(d).__name__}")
    return d


def parse_json(text: str, flag: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise BadInput(f"{flag}: not valid JSON ({e.msg} at line {e.lineno}, column "
                       f"{e.colno})") from None


def read_json(path, flag: str):
    return parse_json(read_text(path, flag), f"{flag} {path}")


def read_csv(path, flag: str, columns=(), *, min_rows: int = 1, dtype=None):
    """A CSV table with at least the given ``columns`` and ``min_rows`` rows."""
    import pandas as pd

    p = in_file(path, flag)
    try:
        df = pd.read_csv(p, dtype=dtype)
    except pd.errors.EmptyDataError:
        raise BadInput(f"{flag} {path}: empty file, expected a CSV table with columns "
                       f"{list(columns)}") from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as e:
        raise BadInput(f"{flag} {path}: not a readable CSV table "
                       f"({' '.join(str(e).split())[:200]})") from None
    return require_columns(df, path, flag, columns, min_rows=min_rows)


def require_columns(df, path, flag: str, columns=(), *, min_rows: int = 1):
    """``df`` (read from ``path``) when it has the given ``columns`` and ``min_rows`` rows,
    else BadInput naming what is missing (the checks of :func:`read_csv`)."""
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise BadInput(f"{flag} {path}: missing column(s) {missing}; has {list(df.columns)}")
    if len(df) < min_rows:
        raise BadInput(f"{flag} {path}: {len(df)} data row(s), expected at least {min_rows} "
                       "(only a header?)")
    return df


def read_model_table(path, flag: str, columns, dtype=None):
    """A CSV whose parameter columns are one contact model's (a design, a dataset, a sweep
    plan), read once: the table and its model (:func:`bpmcal.params.model_of` of its
    columns). ``columns(model)``: the columns it must have; BadInput names what is
    missing, or the mix of two models' names."""
    from .. import params as P

    df = read_csv(path, flag, (), min_rows=0, dtype=dtype)
    try:
        model = P.model_of(df.columns)
    except P.ParameterError as e:
        raise BadInput(f"{flag} {path}: {e}") from None
    # a model's quiet keys (its strength scatter) are left out of a table while at their
    # defaults (ContactModel.quiet): never required
    need = [c for c in columns(model) if c not in model.quiet]
    return require_columns(df, path, flag, need), model


# ------------------------------------------------------------------------ outputs
def _probe_dir(d: Path, flag: str, shown) -> None:
    """Create ``d`` (and parents) and prove it writable with a probe file (O_EXCL, removed
    at once): a real check, also for root and on read-only or special file systems."""
    a = d
    while not a.exists() and a.parent != a:
        a = a.parent
    if a.exists() and not a.is_dir():
        raise BadInput(f"{flag} {shown}: {a} is not a directory")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise BadInput(f"{flag} {shown}: cannot create directory {d} ({e.strerror or e})") from None
    probe = d / f".bpmcal-write-test.{os.getpid()}.{os.urandom(4).hex()}"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise BadInput(f"{flag} {shown}: cannot write in {d} ({e.strerror or e})") from None


def out_file(path, flag: str = "--out", suffixes=H5_SUFFIXES) -> Path:
    """Check an output file before any work: a sane suffix, not a directory, not a special
    file, its directory created if needed and proven writable. Call it after the other
    inputs are checked (it may create the directory)."""
    s = str(path)
    if not s.strip():
        raise BadInput(f"{flag} {s!r}: expected a file name")
    p = Path(path)
    if s.endswith(("/", os.sep)) or p.is_dir():
        raise BadInput(f"{flag} {s}: is a directory, expected a file name ending in "
                       f"{' or '.join(suffixes)}")
    if suffixes and p.suffix.lower() not in suffixes:
        raise BadInput(f"{flag} {s}: expected a file name ending in {' or '.join(suffixes)}")
    if p.exists() and not p.is_file():
        raise BadInput(f"{flag} {s}: exists and is not a regular file")
    _probe_dir(p.parent if str(p.parent) else Path("."), flag, s)
    return p


def out_dir(path, flag: str = "--out") -> Path:
    """Check an output directory before any work: not an existing file; created if needed
    and proven writable. Call it after the other inputs are checked."""
    s = str(path)
    if not s.strip():
        raise BadInput(f"{flag} {s!r}: expected a directory name")
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise BadInput(f"{flag} {s}: exists and is not a directory")
    _probe_dir(p, flag, s)
    return p
