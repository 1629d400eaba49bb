"""Fixtures of the engine tests."""
import pytest
from support.dem_util import material


@pytest.fixture
def mat():
    """The default test material (``dem_util.material()``)."""
    return material()
