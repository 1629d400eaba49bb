"""A journal of a long stage's finished runs: a closed loop stopped part way (killed, a
Slurm time limit, a power loss) and started again with the same inputs reads the runs it
had finished instead of running them again.

Every finished run is one line of ``journal.jsonl`` in the stage's working folder
(appended and flushed to disk as soon as the run ends), under a key that hashes
everything its result depends on: the run's own inputs (parameters, packing seed,
specimens, loading settings, responses asked for) and the bpmcal that runs it (its
version and a hash of its source files, so an edited checkout is another bpmcal). The
run files it wrote stay beside it under names derived from the key. A run is reused only
when its key matches and its files are there, so a changed setting or another bpmcal
runs again; since every run is deterministic, a reused run is the run that would have
been made. A line cut short by a kill is skipped. The stage removes the folder once its
outputs are written; after a failure the folder stays for the next attempt.

One process at a time works in a folder: the journal holds an exclusive lock on
``.lock`` in it (``flock``) from its start until the stage removes or keeps the folder,
and a second stage pointed at the same folder (two runs of one command, or a child
process left running by a killed one) stops at once with a message naming the folder
and the process holding it, instead of removing the runs under the first.
"""
from __future__ import annotations

import fcntl
import functools
import hashlib
import json
import os
from pathlib import Path

import numpy as np

from .. import __version__
from ..io.checks import BadInput

FILE = "journal.jsonl"
LOCK = ".lock"


@functools.lru_cache(maxsize=1)
def source_hash() -> str:
    """A hash of every Python source file of the installed bpmcal package (its path
    inside the package and its bytes)."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def plain(x):
    """A JSON-able form of what a run's row may hold (numpy scalars and arrays, paths)."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


class RunJournal:
    """The finished runs of one stage's working ``folder`` (module docs)."""

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self._lock = _lock(self.folder / LOCK)
        self.path = self.folder / FILE
        self.entries: dict[str, dict] = {}
        self.reused = 0
        if self.path.exists():
            for line in self.path.read_text().splitlines():
                try:
                    e = json.loads(line)
                    key, files = e["key"], e["files"]
                except (ValueError, KeyError, TypeError):
                    continue  # cut short by a kill, or not ours
                if all((self.folder / f).exists() for f in files):
                    self.entries[key] = e
        self.resumable = len(self.entries)

    @staticmethod
    def key(**inputs) -> str:
        """The hash of a run's ``inputs`` (dataclasses by their repr: every field) and of
        the bpmcal that runs it."""
        text = json.dumps({"inputs": inputs, "bpmcal": __version__, "source": source_hash()},
                          sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()

    def stem(self, key: str) -> Path:
        """Where the run of ``key`` writes its files (``<stem>.h5``, ``<stem>.<test>.h5``)."""
        return self.folder / key[:24]

    def get(self, key: str) -> dict | None:
        """The record of the finished run of ``key`` (counted as reused), or None."""
        e = self.entries.get(key)
        if e is not None:
            self.reused += 1
        return None if e is None else e["record"]

    def add(self, key: str, record: dict, files: list[Path]) -> dict:
        """Journal a finished run: its ``record`` (JSON-able, NaN allowed) and the files
        it wrote (in the folder), flushed to disk before the stage goes on. Returns the
        record as a later attempt reads it back (JSON's types)."""
        e = {"key": key, "files": [Path(f).name for f in files], "record": record}
        line = json.dumps(e, default=plain, allow_nan=True)
        with open(self.path, "a") as fh:
            fh.write(line + "\n")
            fh.flush()
            os.fsync(fh.fileno())
        self.entries[key] = json.loads(line)
        return self.entries[key]["record"]

    def remove(self) -> None:
        """Remove the folder and the files in it (the stage's outputs are written; the
        folder holds files only)."""
        if self.folder.is_dir():
            for f in self.folder.iterdir():
                f.unlink(missing_ok=True)
            self.folder.rmdir()
        self.release()

    def keep_or_remove(self) -> None:
        """After a failure: keep the folder when it holds a finished run, else remove it."""
        if not self.entries:
            self.remove()
        self.release()

    def release(self) -> None:
        """Let another process work in the folder (the lock's file stays, unlocked)."""
        if self._lock is not None:
            os.close(self._lock)
            self._lock = None


def _lock(path: Path) -> int:
    """An exclusive lock on ``path`` (created; the holder's pid written in it), or
    BadInput naming the folder and the process that holds it."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
        os.close(fd)
        raise BadInput(f"{path.parent}: another bpmcal process (pid {holder}) is working in "
                       "this folder; wait for it to end, or stop it, and run again (two "
                       "stages sharing one working folder would remove each other's "
                       "runs)") from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, str(os.getpid()).encode(), 0)
    return fd

