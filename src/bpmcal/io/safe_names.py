"""Names and paths that come from user data: what is allowed, checked in one place.

- **Names** that become file names (lab specimens, sample ids): ``SAFE_NAME``, letters,
  digits, ``_ . -``, starting with a letter or digit, at most 64 characters, no ``..``.
  Such a name can never leave its folder (no ``/``, no ``..``, not absolute) nor be read
  as an option (no leading ``-``).
- **Paths** that the workflow puts on command lines (``outdir``, ``lab.csv``):
  ``SAFE_PATH``, letters (any script), digits, space and ``_ . , / + @ = : -``, not
  starting with ``-`` or a space. Every rule also shell-quotes them (``{x:q}``); the
  pattern is a second line of defence and keeps the paths usable where quoting is out of
  our hands (``sbatch --wrap="..."`` on a cluster, the user's own scripts), and it keeps
  ``{ }`` out (Snakemake would read them as wildcards).

The ``*_problem`` functions return ``None`` or a message naming the value and what is
expected; callers raise their own error type (config, CLI) with it.
"""
from __future__ import annotations

import re

SAFE_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
SAFE_NAME_RE = re.compile(SAFE_NAME)
SAFE_PATH = r"^[\w.,/+@=:][\w .,/+@=:-]*$"  # and no trailing space
_PATH_CHARS_RE = re.compile(r"^[\w .,/+@=:-]+$")
#: the longest path the workflow puts on a command line (``outdir``, ``lab.csv``)
MAX_PATH_CHARS = 1024
NAME_RULE = ("letters, digits, '_', '.', '-', starting with a letter or digit, at most 64 "
             "characters, no '..'")
PATH_RULE = ("letters, digits, spaces and _ . , / + @ = : - (no quotes, ;, $, `, \\, "
             "{ }, newlines), not starting with '-' or a space")


def name_problem(name) -> str | None:
    """None if ``name`` is a safe file-name stem, else what is wrong with it."""
    if not isinstance(name, str):
        return f"{shown(name)}: expected a text name ({NAME_RULE})"
    if not SAFE_NAME_RE.match(name) or ".." in name:
        return f"{shown(name)}: expected {NAME_RULE}"
    return None


def path_problem(path) -> str | None:
    """None if ``path`` may go on a workflow command line, else what is wrong with it."""
    if not isinstance(path, str):
        return f"{shown(path)}: expected a path as text"
    if not path or path != path.strip():
        return f"{shown(path)}: expected a non-empty path without leading/trailing spaces"
    if len(path) > MAX_PATH_CHARS:
        return f"{shown(path)}: {len(path):,} characters, expected at most {MAX_PATH_CHARS}"
    if path.startswith("-"):
        return f"{shown(path)}: must not start with '-' (it would read as an option)"
    if not _PATH_CHARS_RE.match(path):
        bad = sorted({c for c in path if not re.match(r"[\w .,/+@=:-]", c)})
        return (f"{shown(path)}: character(s) {shown(''.join(bad))} not allowed; expected "
                f"{PATH_RULE}")
    return None


# ------------------------------------------------------------------ text shown to a user
#: at most this many characters of a value quoted in a message (:func:`shown`)
SHOWN_CHARS = 80
#: a message line is cut to this many characters at the command's edge (``bpmcal.cli``)
LINE_CHARS = 2000


def clip(text: str, limit: int = SHOWN_CHARS) -> str:
    """``text`` cut to ``limit`` characters, the cut marked with how much was left out."""
    text = str(text)
    if len(text) <= limit:
        return text
    keep = max(8, limit - 24)
    return f"{text[:keep]}... ({len(text) - keep:,} more characters)"


def shown(value, limit: int = SHOWN_CHARS) -> str:
    """``repr(value)`` for a message: control characters escaped (``repr`` does that) and
    cut to ``limit`` characters; a huge or deeply nested value (a YAML alias bomb) is
    summarised by its type and size instead of being rendered."""
    if isinstance(value, (list, tuple, dict, set)):
        size = _size(value, 10 * limit)
        if size > limit:
            return f"<a {type(value).__name__} of {len(value):,} item(s)>"
    try:
        text = repr(value)
    except (RecursionError, ValueError):  # too deep; an int of too many digits
        return f"<a {type(value).__name__}>"
    return clip(text, limit)


def _size(value, stop: int, depth: int = 0) -> int:
    """The items and characters of a nested value, counted up to ``stop`` (a shared
    structure is never walked in full)."""
    if depth > 20:
        return stop + 1
    if isinstance(value, dict):
        value = [*value.keys(), *value.values()]
    if isinstance(value, (list, tuple, set)):
        n = len(value)
        for v in value:
            if n > stop:
                break
            n += _size(v, stop - n, depth + 1)
        return n
    return len(value) if isinstance(value, str) else 1


_CONTROL_RE = re.compile(r"[\x00-\x1f\x7f-\x9f\u200b-\u200f\u2028-\u202e\u2066-\u2069\ufeff]")


def printable(text) -> str:
    """``text`` (read from a file) safe to print on a terminal: control characters (escape
    sequences, carriage returns, newlines that could forge a line of their own) and
    invisible direction marks are shown escaped (``\\x1b``, ``\\n``, ``\\u202e``)."""
    s = text if isinstance(text, str) else str(text)
    return _CONTROL_RE.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), s)


def outdir_problem(path: str) -> str | None:
    """None if ``path`` (a safe path, :func:`path_problem`) may be a study's output folder:
    a relative path stays inside the working folder (no ``..`` that leaves it, not the
    working folder itself); an absolute one is taken as given, but not the file system's
    root (``/`` would become the working folder: the study's files name themselves
    ``outdir/...``)."""
    import posixpath

    norm = posixpath.normpath(path)
    if posixpath.isabs(norm):
        if norm in ("/", "//"):
            return f"{shown(path)}: the file system's root; expected a folder for the outputs"
        return None
    if norm == ".":
        return (f"{shown(path)}: the working folder itself; expected a folder inside it "
                "(e.g. results/my_rock) or an absolute path")
    if norm == ".." or norm.startswith("../"):
        return (f"{shown(path)}: leaves the working folder; expected a folder inside it "
                "(e.g. results/my_rock) or, to write elsewhere on purpose, an absolute path")
    return None
