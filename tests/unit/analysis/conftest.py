"""Synthetic datasets with known answers for the analysis tests."""
import numpy as np
import pandas as pd
import pytest

from bpmcal.params import PARAM_NAMES, PARAMS


def lhs_design(n: int, seed: int) -> pd.DataFrame:
    """A dataset-shaped frame: Latin-hypercube sample of the 8 parameters over the Table 2
    ranges, plus sample_id, seed, status and error columns (responses added by the tests)."""
    rng = np.random.default_rng(seed)
    cols = {}
    for p in PARAM_NAMES:
        lo, hi = PARAMS[p].lo, PARAMS[p].hi
        cols[p] = lo + (hi - lo) * (rng.permutation(n) + rng.random(n)) / n
    df = pd.DataFrame(cols)
    df.insert(0, "sample_id", [f"s{i:03d}" for i in range(n)])
    df["seed"] = np.arange(n)
    df["status"] = "ok"
    df["error"] = ""
    return df


@pytest.fixture(scope="session")
def design():
    return lhs_design
