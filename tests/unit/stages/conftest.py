"""The stages' shared fixture: a study folder with a planted card and models
(tests/support/planted_loop.py)."""
import pytest
from support.planted_loop import make_study


@pytest.fixture
def study(tmp_path):
    return make_study(tmp_path)
