"""Experimental design: a seeded Latin hypercube over the meso-parameter ranges.

``lhs_design(ranges, n, seed)`` draws ``n`` points with scipy.stats.qmc.LatinHypercube
(optionally optimised for space filling), scales them to the ranges (paper units) and
gives every sample its own packing seed, derived from the design seed so that the whole
study is reproducible from one number. Output columns: ``sample_id``
(``bpmcal.io.study_files.sample_ids``: s000, s001, ...), the 8 parameters, ``seed``.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import qmc

from .. import params as P
from ..io.study_files import sample_ids


def validate_ranges(ranges: dict) -> dict[str, tuple[float, float]]:
    """{name: [lo, hi]} in paper units -> checked tuples (names, order, domain)."""
    out = {}
    unknown = sorted(set(ranges) - set(P.PARAMS))
    if unknown:
        raise P.ParameterError(f"ranges: unknown parameter(s) {unknown}")
    for name, r in ranges.items():
        if not isinstance(r, (list, tuple)) or len(r) != 2:
            raise P.ParameterError(f"ranges.{name}={r!r}: expected [low, high]")
        lo = P.as_number(r[0], f"ranges.{name}[0]", "a number (low)")
        hi = P.as_number(r[1], f"ranges.{name}[1]", "a number (high)")
        if not lo <= hi:
            raise P.ParameterError(f"ranges.{name}=[{lo:g}, {hi:g}]: low must not exceed high")
        P.validate_params({name: lo}, require_all=False)
        P.validate_params({name: hi}, require_all=False)
        out[name] = (lo, hi)
    return out


def lhs_design(ranges: dict, n: int, seed: int, optimization: str | None = "random-cd",
               fixed: dict | None = None) -> pd.DataFrame:
    """Latin-hypercube design over ``ranges`` (paper units); ``fixed`` parameters are
    constant columns. Parameters with lo == hi are treated as fixed."""
    if int(n) < 2:
        raise P.ParameterError(f"n_samples={n!r}: expected at least 2")
    rng = validate_ranges(ranges)
    fixed = dict(fixed or {})
    varied = [k for k, (lo, hi) in rng.items() if hi > lo]
    fixed.update({k: lo for k, (lo, hi) in rng.items() if hi == lo})
    missing = [p for p in P.PARAMS if p not in varied and p not in fixed]
    if missing:
        raise P.ParameterError(f"design: no range or fixed value for {missing}")
    sampler = qmc.LatinHypercube(d=len(varied), seed=int(seed), optimization=optimization)
    u = sampler.random(int(n))
    lo = np.array([rng[k][0] for k in varied])
    hi = np.array([rng[k][1] for k in varied])
    x = qmc.scale(u, lo, hi)
    df = pd.DataFrame(x, columns=varied)
    for k, v in fixed.items():
        df[k] = float(v)
    df = df[[p for p in P.PARAMS]]
    df.insert(0, "sample_id", sample_ids(n))
    seeds = np.random.SeedSequence(int(seed)).generate_state(int(n), dtype=np.uint32)
    df["seed"] = (seeds % 2_000_000_000).astype(np.int64)
    return df
