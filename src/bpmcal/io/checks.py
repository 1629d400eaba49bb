"""Checks of the files a command reads and writes, shared by the CLI and the stages:
every problem is a :class:`BadInput` naming the file (or option) and what was expected,
raised before any work starts (the CLI turns it into one line on stderr and exit code 2).

- :func:`in_file`, :func:`read_yaml`, :func:`read_json`, :func:`read_csv` for inputs
  (missing, a directory, a FIFO or device, larger than :data:`MAX_INPUT_BYTES` or, YAML
  and JSON, :data:`MAX_TEXT_BYTES`, unreadable, binary, garbled, columns missing, no
  rows); YAML and JSON are read with bounds on their nesting (:data:`MAX_DEPTH`) and on
  YAML aliases (:data:`MAX_ALIASES`, :data:`MAX_YAML_NODES`: a few hundred bytes of
  aliases can stand for billions of values);
- :func:`out_file`, :func:`out_dir` for outputs, called before any work (after the other
  checks: they create the directory and prove it writable). The directories they create
  are remembered (``io.atomic.make_dirs``), so that a command that fails removes the ones
  it left empty (``io.atomic.remove_created_dirs``, called by ``bpmcal.cli``).

Values quoted in messages are cut (``safe_names.shown``).
"""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

from .atomic import make_dirs
from .safe_names import clip

H5_SUFFIXES = (".h5", ".hdf5")
#: the largest input file a command reads [bytes] (a design of 100,000 samples is ~15 MB;
#: a card or config a few kB); larger ones are refused before they are read
MAX_INPUT_BYTES = 256 * 2 ** 20
#: the largest YAML or JSON input [bytes] (a card or a config is a few kB, a regression's
#: models.json a few hundred): parsed in Python, 256 MB of YAML would take many minutes
MAX_TEXT_BYTES = 16 * 2 ** 20
#: the deepest nesting of a YAML or JSON input (a config is 4 levels deep)
MAX_DEPTH = 64
#: the most YAML aliases (``*name``) in one input file (a config uses none)
MAX_ALIASES = 1000
#: the most values a YAML input may stand for once its aliases are expanded (nine lines
#: of aliases can stand for 9^9 values: the "billion laughs")
MAX_YAML_NODES = 1_000_000


class BadInput(ValueError):
    """An expected failure caused by the user's input (exit code 2)."""


# ------------------------------------------------------------------------ input files
def in_file(path, flag: str, max_bytes: int = MAX_INPUT_BYTES) -> Path:
    """An existing, readable regular file of at most ``max_bytes`` (a FIFO, a device such
    as /dev/zero, a socket or a symlink loop is refused: reading it could block forever or
    never end)."""
    p = Path(path)
    if str(path) == "":
        raise BadInput(f"{flag} '': expected a file name")
    try:
        st = p.stat()
    except FileNotFoundError:
        raise BadInput(f"{flag} {path}: no such file") from None
    except OSError as e:  # a symlink loop, a name too long, a component not a directory
        raise BadInput(f"{flag} {path}: cannot be opened ({e.strerror or e})") from None
    if stat.S_ISDIR(st.st_mode):
        raise BadInput(f"{flag} {path}: is a directory, expected a file")
    if not stat.S_ISREG(st.st_mode):
        raise BadInput(f"{flag} {path}: not a regular file (a FIFO, device or socket); "
                       "expected a file")
    if st.st_size > max_bytes:
        raise BadInput(f"{flag} {path}: {st.st_size:,} bytes, larger than the {max_bytes:,} "
                       "an input file of bpmcal may have")
    if not os.access(p, os.R_OK):
        raise BadInput(f"{flag} {path}: not readable (permission denied)")
    return p


def read_text(path, flag: str, max_bytes: int | None = None) -> str:
    """A UTF-8 text file (a YAML or JSON input: at most :data:`MAX_TEXT_BYTES`)."""
    p = in_file(path, flag, MAX_TEXT_BYTES if max_bytes is None else max_bytes)
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise BadInput(f"{flag} {path}: not a UTF-8 text file (byte {e.start}: "
                       f"{e.object[e.start:e.start + 1]!r})") from None


def _yaml_loader():
    """PyYAML's safe loader, with YAML 1.2 floats: ``1e-9`` is a number (YAML 1.1, and so
    PyYAML, reads it as the string "1e-9"), and bounds: at most :data:`MAX_ALIASES`
    aliases and :data:`MAX_DEPTH` levels of nesting (a ``yaml.YAMLError`` beyond)."""
    import re

    import yaml

    class Loader(yaml.SafeLoader):
        _depth = 0
        _aliases = 0

        def get_single_node(self):
            node = super().get_single_node()
            if node is not None and _expanded_size(node, {}) > MAX_YAML_NODES:
                raise yaml.YAMLError(f"its aliases stand for more than {MAX_YAML_NODES:,} "
                                     "values")
            return node

        def compose_node(self, parent, index):
            if self.check_event(yaml.events.AliasEvent):
                self._aliases += 1
                if self._aliases > MAX_ALIASES:
                    raise yaml.YAMLError(f"more than {MAX_ALIASES} aliases (*name)")
            self._depth += 1
            try:
                if self._depth > MAX_DEPTH:
                    raise yaml.YAMLError(f"nested deeper than {MAX_DEPTH} levels")
                return super().compose_node(parent, index)
            finally:
                self._depth -= 1

    Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)$"), list("-+0123456789"))
    return Loader


def _expanded_size(node, sizes: dict) -> int:
    """The values a composed YAML node stands for with every alias expanded, counted once
    per distinct node (``sizes``: id -> size, so a shared node is not walked again)."""
    k = id(node)
    if k in sizes:
        return sizes[k]
    sizes[k] = 1  # (a recursive structure counts once)
    n = 1
    if isinstance(node.value, list):
        for item in node.value:
            parts = item if isinstance(item, tuple) else (item,)  # a mapping's (key, value)
            n += sum(_expanded_size(x, sizes) for x in parts)
            if n > MAX_YAML_NODES:
                break
    sizes[k] = n
    return n


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
        what = getattr(e, "problem", None) or (str(e).splitlines() or [""])[0]
        raise BadInput(f"{flag} {path}: not valid YAML{where} ({clip(what)})") from None
    except RecursionError:  # a structure the depth bound did not see (a recursive alias)
        raise BadInput(f"{flag} {path}: YAML nested too deeply") from None
    if mapping and not isinstance(d, dict):
        raise BadInput(f"{flag} {path}: expected a YAML mapping (name: value lines), got "
                       f"{'an empty file' if d is None else type(d).__name__}")
    return d


def parse_json(text: str, flag: str, max_chars: int = MAX_INPUT_BYTES):
    """JSON text (an option's value or a file's content), at most ``max_chars`` long and
    :data:`MAX_DEPTH` levels deep."""
    if len(text) > max_chars:
        raise BadInput(f"{flag}: {len(text):,} characters of JSON, more than {max_chars:,}")
    depth = _json_depth(text)
    if depth > MAX_DEPTH:
        raise BadInput(f"{flag}: JSON nested {depth} levels deep, more than {MAX_DEPTH}")
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise BadInput(f"{flag}: not valid JSON ({e.msg} at line {e.lineno}, column "
                       f"{e.colno})") from None
    except RecursionError:
        raise BadInput(f"{flag}: JSON nested too deeply") from None


def _json_depth(text: str) -> int:
    """The deepest nesting of brackets in JSON ``text`` outside its strings (an upper
    bound of the nesting json.loads would recurse to)."""
    import re

    if text.count("[") + text.count("{") <= MAX_DEPTH:
        return 0  # cannot be deeper (the common case, at no cost)
    bare = re.sub(r'"(?:[^"\\]|\\.)*"', '""', text)
    depth = top = 0
    for c in re.findall(r"[][{}]", bare):
        if c in "[{":
            depth += 1
            top = max(top, depth)
        else:
            depth -= 1
    return top


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
        make_dirs(d)
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
