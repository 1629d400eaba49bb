"""The packing-seed scatter of a simulator against a closed-loop tolerance (:func:`scatter_table`).

One parameter set simulated with several packing seeds: per response the coefficient of
variation, the standard error of one closed-loop evaluation and the noise floor 2 SE;
a tolerance below that floor would make the loop chase packing noise. The job that runs
the DEM for it, the seed scatter, is ``bpmcal.stages.seed_scatter.seed_scatter``; this is
the pure table. With ``n_per_round`` seeds averaged per round the standard error shrinks
by sqrt(n).

The method: ``docs/methods/calibration.md`` (section "Closed loop").
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from bpmcal.params import TARGETS

from .._common import check_responses


def scatter_table(sims: pd.DataFrame | Sequence[Mapping[str, float]],
                  rtol: float | Mapping[str, float] = 0.01,
                  responses: Sequence[str] = TARGETS, n_per_round: int = 1) -> pd.DataFrame:
    """Judge a closed-loop tolerance against the packing-seed scatter of the simulator.

    ``sims`` holds the responses of ONE parameter set simulated with several packing seeds
    (one row per seed). Per response: n, mean, sample std (ddof=1), coefficient of variation
    ``cv = std / |mean|`` (the relative scatter of a single run), the relative standard
    error of one closed-loop evaluation ``se = cv / sqrt(n_per_round)`` (``n_per_round``
    seeds averaged per round), the noise floor ``2 se`` and ``noise_limited = rtol < 2 se``:
    such a tolerance is below the noise - a parameter set that is exactly right would fail
    it in more than ~5 % of evaluations and the loop would chase noise.
    """
    frame = pd.DataFrame(sims) if not isinstance(sims, pd.DataFrame) else sims
    responses = check_responses(responses)
    if not isinstance(n_per_round, (int, np.integer)) or n_per_round < 1:
        raise ValueError(f"n_per_round={n_per_round!r}: expected an integer >= 1")
    recs = []
    for r in responses:
        if r not in frame:
            raise ValueError(f"sims lacks response {r!r}; it has {list(frame.columns)}")
        v = pd.to_numeric(frame[r], errors="coerce").to_numpy(float)
        v = v[np.isfinite(v)]
        if len(v) < 2:
            raise ValueError(f"{r}: {len(v)} finite value(s); need at least 2 seeds to estimate the scatter")
        tol = float(rtol[r] if isinstance(rtol, Mapping) else rtol)
        mean, std = float(v.mean()), float(v.std(ddof=1))
        cv = std / abs(mean) if mean != 0 else math.inf
        se = cv / math.sqrt(n_per_round)
        recs.append({"response": r, "n": len(v), "mean": mean, "std": std, "cv": cv, "se": se,
                     "noise_floor": 2 * se, "rtol": tol, "noise_limited": tol < 2 * se})
    return pd.DataFrame.from_records(recs).set_index("response")
