"""Atomic output: every file bpmcal writes appears under its final name only complete.

A writer writes to a temporary file in the same directory (so the rename cannot cross a
file system), then renames it; on any error, including KeyboardInterrupt, the temporary
file is removed. A process killed mid-write leaves at most a hidden temporary file, never
a partial file under the final name.

Temporary files are named ``.NAME.HOST.PID.RANDOM.tmp`` and created with
``O_CREAT | O_EXCL | O_NOFOLLOW``: the name is unpredictable, an existing file or a
planted symlink under that name is never opened (a new random name is drawn), and the
mode is ``open``'s normal one (0666 minus the umask), so the renamed file is as readable
as any other. Before writing, stale temporary files in the target directory are removed:
those of a process of this host that no longer runs (a killed run), the
``.NAME.PID.tmp`` files of earlier bpmcal versions whose process is gone, and any older
than a day (a run killed on another cluster node). ``.gitignore`` matches ``.*.tmp``.

A write that fails for want of space or permission (``OSError``) names the final file, not
the temporary one. Directories are created with :func:`make_dirs`, which remembers the ones
it created, so that a command that fails can remove those it left empty
(:func:`remove_created_dirs`, called by ``bpmcal.cli``).
"""
from __future__ import annotations

import errno
import os
import re
import secrets
import socket
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

#: temporary files of another host (a shared file system) count as stale after this [s]
STALE_AFTER_S = 24 * 3600.0

_TMP_RE = re.compile(r"^\.(?P<name>.+)\.(?P<host>[A-Za-z0-9-]*)\.(?P<pid>\d+)\.[0-9a-f]{16}\.tmp$")
_OLD_TMP_RE = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.tmp$")  # bpmcal <= 0.1.0


def _host() -> str:
    h = re.sub(r"[^A-Za-z0-9-]", "", socket.gethostname().split(".")[0])
    return h[:40]


def _alive(pid: int) -> bool:
    if pid <= 0:
        return True  # never signal a process group; keep the file
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, owned by someone else
    return True


def clean_stale_temps(directory, *, now: float | None = None) -> list[Path]:
    """Remove stale bpmcal temporary files in ``directory`` (see the module doc); returns
    what was removed. Best effort: a file that vanishes or cannot be removed is skipped.
    Symlinks are removed as links (never followed)."""
    d = Path(directory)
    removed = []
    host, me = _host(), os.getpid()
    now = time.time() if now is None else now
    try:
        entries = list(os.scandir(d))
    except OSError:
        return removed
    for e in entries:
        m = _TMP_RE.match(e.name)
        if m:
            same_host = m["host"] == host
        else:
            m = _OLD_TMP_RE.match(e.name)
            if not m:
                continue
            same_host = True  # the old names carry no host
        pid = int(m["pid"])
        try:
            st = e.stat(follow_symlinks=False)
            if e.is_dir(follow_symlinks=False):
                continue
        except OSError:
            continue
        if same_host and pid == me:
            continue  # one of our own writes in progress
        dead = same_host and not _alive(pid)
        if dead or now - st.st_mtime > STALE_AFTER_S:
            try:
                os.unlink(e.path)
                removed.append(Path(e.path))
            except OSError:
                pass
    return removed


#: directories created by :func:`make_dirs` since :func:`forget_created_dirs`, in order
_CREATED: list[Path] = []


def make_dirs(d) -> Path:
    """``mkdir -p d``, remembering each directory it created (:func:`remove_created_dirs`)."""
    d = Path(d)
    new = []
    a = d
    while not os.path.lexists(a) and a.parent != a:
        new.append(a)
        a = a.parent
    d.mkdir(parents=True, exist_ok=True)
    _CREATED.extend(reversed(new))
    return d


def forget_created_dirs() -> None:
    """Start a new record of created directories (a command starts)."""
    _CREATED.clear()


def remove_created_dirs() -> list[Path]:
    """Remove the directories :func:`make_dirs` created that are empty now, deepest first
    (a failed command leaves no empty folder behind); returns them."""
    removed = []
    for d in sorted(set(_CREATED), key=lambda p: len(p.parts), reverse=True):
        try:
            d.rmdir()  # only an empty directory
            removed.append(d)
        except OSError:
            pass
    _CREATED.clear()
    return removed


def _create_temp(path: Path) -> Path:
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(
        os, "O_CLOEXEC", 0)
    stem = path.name[:120]
    for _ in range(100):
        tmp = path.with_name(f".{stem}.{_host()}.{os.getpid()}.{secrets.token_hex(8)}.tmp")
        try:
            fd = os.open(tmp, flags, 0o666)
        except FileExistsError:
            continue
        except OSError as e:
            if e.errno == errno.ELOOP:  # a symlink under our name: draw another one
                continue
            raise
        os.close(fd)
        return tmp
    raise FileExistsError(f"could not create a unique temporary file beside {path}")


@contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Yield a new, empty temporary file beside ``path``; rename it to ``path`` when the
    block ends without error, delete it otherwise. The temporary name ends in ``.tmp``:
    writers that choose a format from the suffix must be told the format explicitly."""
    path = Path(path)
    make_dirs(path.parent)
    clean_stale_temps(path.parent)
    tmp = _create_temp(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        if e.filename in (None, str(tmp), tmp):  # name the file written, not its temporary
            raise OSError(e.errno, e.strerror, str(path)) from None
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)
