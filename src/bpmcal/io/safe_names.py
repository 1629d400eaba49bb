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
NAME_RULE = ("letters, digits, '_', '.', '-', starting with a letter or digit, at most 64 "
             "characters, no '..'")
PATH_RULE = ("letters, digits, spaces and _ . , / + @ = : - (no quotes, ;, $, `, \\, "
             "{ }, newlines), not starting with '-' or a space")


def name_problem(name) -> str | None:
    """None if ``name`` is a safe file-name stem, else what is wrong with it."""
    if not isinstance(name, str):
        return f"{name!r}: expected a text name ({NAME_RULE})"
    if not SAFE_NAME_RE.match(name) or ".." in name:
        return f"{name!r}: expected {NAME_RULE}"
    return None


def path_problem(path) -> str | None:
    """None if ``path`` may go on a workflow command line, else what is wrong with it."""
    if not isinstance(path, str):
        return f"{path!r}: expected a path as text"
    if not path or path != path.strip():
        return f"{path!r}: expected a non-empty path without leading/trailing spaces"
    if path.startswith("-"):
        return f"{path!r}: must not start with '-' (it would read as an option)"
    if not _PATH_CHARS_RE.match(path):
        bad = sorted({c for c in path if not re.match(r"[\w .,/+@=:-]", c)})
        return f"{path!r}: character(s) {''.join(bad)!r} not allowed; expected {PATH_RULE}"
    return None
