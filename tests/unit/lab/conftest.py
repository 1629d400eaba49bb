"""Fixtures of the lab tests."""
import pytest


@pytest.fixture(scope="session")
def cache(packing_cache):
    """The lab tests' packing cache: the session's (tests/conftest.py)."""
    return packing_cache
