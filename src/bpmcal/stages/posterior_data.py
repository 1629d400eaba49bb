"""The runs a card's posterior learns from, and its parameter side, read from the study's
files (:mod:`.posterior`'s inputs):

- :func:`design_runs` — the design samples (``dataset.csv``, status ok; a tensile or
  triaxial strength only where its test was valid);
- :func:`seed_rows` — the closed loop's seed runs (``verification/<specimen>/seeds.csv``),
  the fresh seeds (``fresh_seeds/seeds.csv``, at the card's parameters) and the
  refinement's runs, one row per specimen (a seed's tensile discs are one row each);
- :func:`problem_of` — the card's free parameters, their prior box (the closed loop's:
  the design ranges widened by its margin), the fixed values and the strength ratio.

Columns follow the study's file contract (``bpmcal.io.study_files``); every run keeps the
``source`` it came from (:data:`bpmcal.analysis.posterior.SOURCES`).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .. import params as P
from ..analysis.calibration import CalibrationSpace
from ..analysis.posterior import TENSILE_SHARE, Problem, tensile_share
from ..io.checks import BadInput

#: the responses a posterior can learn from the runs: the targets' and the untargeted
#: predictions' (the failure mode's tensile crack share comes from the UCS cracks)
RESPONSES = (*P.ANALYSED, TENSILE_SHARE)


def _strength_ok(df: pd.DataFrame, resp: str) -> pd.Series:
    """Rows whose per-sample test of ``resp`` measured it (``<test>_status`` ok)."""
    col = f"{P.SAMPLE_TESTS[resp]}_status"
    return df[col].astype(str).eq("ok") if col in df.columns else pd.Series(True, df.index)


def design_runs(df: pd.DataFrame, params) -> pd.DataFrame:
    """The design's usable runs: one row per sample with status ok, its parameters, every
    response it has (a per-sample test's strength NaN where that test gave none) and the
    tensile crack share; ``source`` "design"."""
    ok = df[df["status"].astype(str) == "ok"].copy()
    out = ok[list(params)].astype(float)
    for r in P.ANALYSED:
        if r in ok.columns:
            v = pd.to_numeric(ok[r], errors="coerce")
            out[r] = v.where(_strength_ok(ok, r)) if r in P.SAMPLE_TESTS else v
    out[TENSILE_SHARE] = tensile_share(ok)
    out["source"], out["round"] = "design", np.nan
    out["run"] = ["design:" + str(x) for x in ok["sample_id"]] if "sample_id" in ok else "design"
    # each sample its own packing (its own seed)
    out["packing"] = ([f"design:{x}" for x in ok["seed"]] if "seed" in ok
                      else [f"design:{i}" for i in range(len(ok))])
    return out.reset_index(drop=True)


def seed_rows(df: pd.DataFrame, params: dict | None, source: str, names) -> pd.DataFrame:
    """One row per specimen of seed runs ``df`` (a loop's or the refinement's seeds.csv,
    whose rows carry their parameters, or the fresh seeds' at the card's ``params``): the
    UCS responses and crack share on the seed's row, each tensile specimen of a seed on a
    row of its own (``<test>_specimen_MPa``, else the seed's value); ``round`` and ``run``
    (source, round and seed: one id per DEM seed run) say which run a row came from, and
    ``packing`` which packing it ran on (a seed's, or its tensile specimen j's): a
    closed loop's rounds share their seeds' packings.
    Rows of failed runs keep only what they measured (NaN elsewhere)."""
    if df is None or df.empty:
        return pd.DataFrame(columns=[*names, "round", "run", "source", "packing"])
    rows = []
    for _, r in df.iterrows():
        base = {p: float(params[p] if params is not None else r[p]) for p in names}
        rnd = pd.to_numeric(r.get("round"), errors="coerce")
        base.update({"round": rnd, "run": f"{source}:{rnd}:{r.get('seed')}"})
        ok = str(r.get("status", "ok")) == "ok"
        ucs = {k: (float(pd.to_numeric(r.get(k), errors="coerce")) if ok else math.nan)
               for k in P.TARGETS}
        sh = tensile_share(pd.DataFrame([r]))
        seed = r.get("seed")
        rows.append({**base, **ucs, TENSILE_SHARE: float(sh.iloc[0]) if ok else math.nan,
                     "source": source, "packing": f"{seed}"})
        for resp, test in P.SAMPLE_TESTS.items():
            if resp not in r.index:
                continue
            text = r.get(f"{test}_specimen_MPa")
            vals = ([float(v) for v in str(text).split(";")]
                    if isinstance(text, str) and text.strip() else [r.get(resp)])
            for j, v in enumerate(vals):  # specimen j of a seed: its own packing
                v = float(pd.to_numeric(v, errors="coerce"))
                if math.isfinite(v):
                    rows.append({**base, resp: v, "source": source,
                                 "packing": f"{seed}/{test}{j}"})
    return pd.DataFrame(rows)


def problem_of(card: dict, flag: str = "--card") -> tuple[Problem, CalibrationSpace]:
    """The parameter side of a card's posterior (module docstring): the card's free
    parameters on the closed loop's box (its ``verification.loop_bounds`` when it has
    them, else the design ranges widened by its ``range_margin``)."""
    roles, params, ranges = card["roles"], card["parameters"], card["ranges"]
    free = [p for p, r in roles.items() if r == "free"]
    if not free:
        raise BadInput(f"{flag}: the card has no free parameter: nothing to infer")
    ratio = card.get("ratio_ten_coh")
    model = P.model_of(list(params))
    ten, coh = model.strength
    derived = ten if roles.get(ten) == "derived" else None
    fixed = {p: float(v) for p, v in params.items()
             if roles.get(p) == "fixed" and p != "contact_model"}
    space = CalibrationSpace(free, fixed, ratio if derived else None, ranges,
                             card.get("calibration_bounds") or None)
    v = card.get("verification") or {}
    lb = v.get("loop_bounds") or {}
    if all(p in lb for p in free):
        lo = np.array([float(lb[p][0]) for p in free])
        hi = np.array([float(lb[p][1]) for p in free])
    else:
        lo, hi = space.limits(space.loop_box(float(v.get("range_margin", 0.0))))
    prob = Problem(tuple(free), np.asarray(lo, float), np.asarray(hi, float), fixed,
                   {p: tuple(map(float, ranges[p])) for p in ranges},
                   ratio if derived else None, derived, coh if derived else None)
    return prob, space
