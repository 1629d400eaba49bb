"""Test helper (not part of bpmcal): record which files a ``bpmcal`` process reads.

Put this folder first on PYTHONPATH and set BPMCAL_AUDIT_DIR: every ``bpmcal`` process then
writes ``<pid>.jsonl`` there, its command line first, then one line per file it opened for
reading, by Python's ``open``/``os.open`` (audit events) or by ``h5py.File`` (its C
library opens the file, so ``h5py.File`` is wrapped when h5py is imported).
tests/workflow/test_smoke.py compares these reads with the files the rule graph declares.
Nothing happens without BPMCAL_AUDIT_DIR, or in other programs.
"""
import os
import sys

_DIR = os.environ.get("BPMCAL_AUDIT_DIR")


def _install():
    import importlib.abc
    import importlib.machinery
    import json

    log = open(os.path.join(_DIR, f"{os.getpid()}.jsonl"), "a", buffering=1)
    log.write(json.dumps({"argv": sys.argv, "cwd": os.getcwd()}) + "\n")
    seen = set()

    def record(path):
        try:
            p = os.path.abspath(os.fsdecode(path))
        except Exception:  # noqa: BLE001 - a file descriptor, or not a path
            return
        if p not in seen:
            seen.add(p)
            log.write(json.dumps({"read": p}) + "\n")

    def hook(event, args):
        if event != "open" or not args:
            return
        path, mode, flags = (tuple(args) + (None, None))[:3]
        if isinstance(path, int):
            return
        if mode is not None:
            if any(c in str(mode) for c in "wax+"):
                return
        elif flags is not None and flags & (os.O_WRONLY | os.O_RDWR):
            return
        record(path)

    sys.addaudithook(hook)

    class H5Finder(importlib.abc.MetaPathFinder):
        """Wrap h5py.File when h5py._hl.files is imported: log files opened read-only."""

        def find_spec(self, name, path, target=None):
            if name != "h5py._hl.files":
                return None
            spec = importlib.machinery.PathFinder.find_spec(name, path)
            if spec is None or spec.loader is None:
                return spec
            exec_module = spec.loader.exec_module

            def patched(module):
                exec_module(module)
                init = module.File.__init__

                def __init__(self, name, mode="r", *a, **kw):
                    if isinstance(name, (str, bytes, os.PathLike)) and mode in ("r", None):
                        record(name)
                    init(self, name, mode, *a, **kw)

                module.File.__init__ = __init__

            spec.loader.exec_module = patched
            return spec

    sys.meta_path.insert(0, H5Finder())


if _DIR and os.path.basename(sys.argv[0] if sys.argv else "") == "bpmcal":
    try:
        _install()
    except Exception:  # noqa: BLE001 - never break the program under test
        pass
