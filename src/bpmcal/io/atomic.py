"""Atomic output: every file bpmcal writes appears under its final name only complete.

A writer writes to a temporary name in the same directory (so the rename cannot cross a
file system), then renames it; on any error, including KeyboardInterrupt, the temporary
file is removed. A process killed mid-write leaves at most a hidden ``.NAME.PID.tmp``
file, never a partial file under the final name. Temporary files are created with
``open``'s normal mode (umask applies), so the renamed file is as readable as any other.
"""
from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator


@contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it to ``path`` when the block ends
    without error, delete it otherwise. The temporary name ends in ``.tmp``: writers that
    choose a format from the suffix must be told the format explicitly."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)
