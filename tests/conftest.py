"""Fixtures for every test folder: one packing cache for the whole session.

``packing_cache`` is a session folder that also becomes ``BPMCAL_SPECIMEN_CACHE`` for the
session (autouse), so a specimen built without an explicit cache, in this process or in a
``bpmcal``/Snakemake subprocess, lands there and never in ``~/.cache/bpmcal/packings``.
Tests that pass a cache pass this one unless they need an empty cache of their own, so an
identical packing is relaxed once per session, not once per folder."""
import pytest


@pytest.fixture(scope="session", autouse=True)
def packing_cache(tmp_path_factory):
    """The session's packing cache (a folder; also ``$BPMCAL_SPECIMEN_CACHE``)."""
    d = tmp_path_factory.mktemp("packings")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("BPMCAL_SPECIMEN_CACHE", str(d))
        yield d
