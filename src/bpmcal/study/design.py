"""Experimental design: a seeded Latin hypercube over the meso-parameter ranges.

``lhs_design(ranges, n, seed)`` draws ``n`` points with scipy.stats.qmc.LatinHypercube
(optionally optimised for space filling), scales them to the ranges (paper units) and
gives every sample its own packing seed, derived from the design seed so that the whole
study is reproducible from one number. Output columns: ``sample_id``
(``bpmcal.io.study_files.sample_ids``: s000, s001, ...), the contact model's card
parameters (the paper's 8 for the parallel bond; :data:`bpmcal.params.MODELS`), ``seed``.
The model is the one whose names the ranges and fixed values use. An integer parameter
(a flat joint's element counts) is designed on its integer levels: the hypercube's
strata of [lo, hi + 1) floored, so every level between lo and hi is equally likely.

A design has at most :data:`MAX_SAMPLES` samples (one DEM job each); the space-filling
optimisations grow faster than the sample count (random-cd took 21 s for 5,000 samples and
45 s for 10,000 on a loaded 2-core machine, lloyd 86 s for 150 in 8 dimensions), so they
are bounded by :data:`MAX_OPTIMIZED` (``optimization: none`` draws 100,000 samples in
well under a second): :func:`design_size_problem`, used by the config's validation and
the ``design`` command alike.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import qmc

from .. import params as P
from ..io.study_files import sample_ids

#: the most samples of a design (the config's ``study.n_samples``, ``bpmcal design --n``)
MAX_SAMPLES = 100_000
#: the most samples each space-filling optimisation is run on (module doc)
MAX_OPTIMIZED = {"random-cd": 5_000, "lloyd": 100}


def design_size_problem(n, optimization: str | None) -> str | None:
    """None if a design of ``n`` samples with ``optimization`` (None or "none": plain
    LHS) is within the bounds, else what is wrong and what to do."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 2 <= n <= MAX_SAMPLES:
        return f"{n!r} samples: expected an integer in [2, {MAX_SAMPLES:,}]"
    limit = MAX_OPTIMIZED.get(optimization or "none")
    if limit is not None and n > limit:
        return (f"{n:,} samples with the {optimization} optimisation: it takes minutes above "
                f"{limit:,} samples; use no optimisation (lhs_optimization: none, "
                "--optimization none) or fewer samples")
    return None


def validate_ranges(ranges: dict, model: P.ContactModel | None = None) -> dict[str, tuple[float, float]]:
    """{name: [lo, hi]} in paper units -> checked tuples (names, order, domain); the
    names are ``model``'s (default: the model whose names the ranges use)."""
    out = {}
    model = model or P.model_of(ranges)
    unknown = sorted(set(ranges) - set(model.params))
    if unknown:
        raise P.ParameterError(f"ranges: unknown parameter(s) {unknown} for the contact model "
                               f"{model.name}; expected names from {list(model.params)}")
    for name, r in ranges.items():
        if not isinstance(r, (list, tuple)) or len(r) != 2:
            raise P.ParameterError(f"ranges.{name}={r!r}: expected [low, high]")
        lo = P.as_number(r[0], f"ranges.{name}[0]", "a number (low)")
        hi = P.as_number(r[1], f"ranges.{name}[1]", "a number (high)")
        if not lo <= hi:
            raise P.ParameterError(f"ranges.{name}=[{lo:g}, {hi:g}]: low must not exceed high")
        named = {"contact_model": model.name}
        P.validate_params({**named, name: lo}, require_all=False)
        P.validate_params({**named, name: hi}, require_all=False)
        out[name] = (lo, hi)
    return out


def lhs_design(ranges: dict, n: int, seed: int, optimization: str | None = "random-cd",
               fixed: dict | None = None, contact_model: str | None = None) -> pd.DataFrame:
    """Latin-hypercube design over ``ranges`` (paper units); ``fixed`` parameters are
    constant columns. Parameters with lo == hi are treated as fixed; a model's optional
    keys with neither a range nor a fixed value take its defaults. ``contact_model``:
    the model's name (default: the one whose names ``ranges`` and ``fixed`` use)."""
    problem = design_size_problem(n, optimization)
    if problem:
        raise P.ParameterError(f"design: {problem}")
    fixed = dict(fixed or {})
    model = (P.contact_model(contact_model) if contact_model is not None
             else P.model_of({**ranges, **fixed}))
    rng = validate_ranges(ranges, model)
    varied = [k for k, (lo, hi) in rng.items() if hi > lo]
    fixed.update({k: lo for k, (lo, hi) in rng.items() if hi == lo})
    fixed.update({k: v for k, v in (model.defaults or {}).items() if k not in varied and k not in fixed})
    missing = [p for p in model.params if p not in varied and p not in fixed]
    if missing:
        raise P.ParameterError(f"design: no range or fixed value for {missing}")
    sampler = qmc.LatinHypercube(d=len(varied), seed=int(seed), optimization=optimization)
    u = sampler.random(int(n))
    lo = np.array([rng[k][0] for k in varied])
    hi = np.array([rng[k][1] for k in varied])
    whole = np.array([model.is_integer(k) for k in varied], bool)
    x = qmc.scale(u, lo, hi + whole)  # an integer parameter: strata of [lo, hi + 1)
    x[:, whole] = np.minimum(np.floor(x[:, whole]), hi[whole])
    df = pd.DataFrame(x, columns=varied)
    for k, v in fixed.items():
        df[k] = float(v)
    # the quiet keys (a strength scatter) only when the study gives one
    df = df[[k for k in model.params if k not in model.quiet
             or not (df[k] == (model.defaults or {})[k]).all()]]
    df.insert(0, "sample_id", sample_ids(n))
    seeds = np.random.SeedSequence(int(seed)).generate_state(int(n), dtype=np.uint32)
    df["seed"] = (seeds % 2_000_000_000).astype(np.int64)
    return df
