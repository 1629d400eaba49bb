"""Fixtures for every test folder, and where the test run writes.

**Nothing outside the repository** (but the system's temporary folder) is written by
``python -m pytest`` unless asked for:

- the numba cache goes to ``<repo>/.cache/test/bpmcal`` (ignored by git) instead of
  ``~/.cache/bpmcal``; set ``BPMCAL_CACHE`` (or ``NUMBA_CACHE_DIR``) to use another one,
  e.g. ``BPMCAL_CACHE=~/.cache/bpmcal`` to share the compiled kernels with your studies;
- Snakemake's and matplotlib's caches (``XDG_CACHE_HOME``, ``MPLCONFIGDIR``) go to
  ``<repo>/.cache/test/`` too, for this process and every ``bpmcal``/Snakemake subprocess;
- the Slurm tests, which install and start system services, run only with
  ``BPMCAL_TEST_SLURM=1`` (tests/support/slurm_cluster.py).

These are set here, at import, before any test module imports ``bpmcal`` (its numba
cache folder is fixed when ``bpmcal.dem`` is first imported).

``packing_cache`` is a session folder that also becomes ``BPMCAL_SPECIMEN_CACHE`` for the
session (autouse), so a specimen built without an explicit cache, in this process or in a
``bpmcal``/Snakemake subprocess, lands there and never in ``~/.cache/bpmcal/packings``.
Tests that pass a cache pass this one unless they need an empty cache of their own, so an
identical packing is relaxed once per session, not once per folder. With pytest-xdist
(``-n 2``: the README's command) the workers share it (the cache writes a packing under a
temporary name and renames it).

**Order**: the test files that hold slow tests run first (they hold the long fixtures:
whole smoke studies), the others after them in their usual order, so that under
``-n 2 --dist loadfile`` the two workers start on the long files and fill in with the
short ones, instead of meeting the long ones last."""
import os
from pathlib import Path

import pytest

#: the test run's caches, inside the repository
LOCAL_CACHE = Path(__file__).resolve().parents[1] / ".cache" / "test"

if "NUMBA_CACHE_DIR" not in os.environ:
    os.environ.setdefault("BPMCAL_CACHE", str(LOCAL_CACHE / "bpmcal"))
os.environ["XDG_CACHE_HOME"] = str(LOCAL_CACHE / "xdg")
os.environ["MPLCONFIGDIR"] = str(LOCAL_CACHE / "matplotlib")


@pytest.fixture(scope="session", autouse=True)
def packing_cache(tmp_path_factory):
    """The session's packing cache (a folder; also ``$BPMCAL_SPECIMEN_CACHE``)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):  # one cache for the workers of a run
        d = tmp_path_factory.getbasetemp().parent / "packings"
        d.mkdir(exist_ok=True)
    else:
        d = tmp_path_factory.mktemp("packings")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("BPMCAL_SPECIMEN_CACHE", str(d))
        yield d


def pytest_collection_modifyitems(config, items):
    """The files with slow tests first (module docstring), otherwise the collection's order."""
    slow_files = {it.path for it in items if it.get_closest_marker("slow") is not None}
    items[:] = sorted(items, key=lambda it: it.path not in slow_files)  # stable
