"""The posterior predictive in DEM (``workflow/rules/posterior.smk``, ``bpmcal predictive``):
the untargeted predictions of a card, run on posterior draws.

Each draw of ``posterior/<specimen>/draws.csv`` (:func:`bpmcal.stages.posterior.pick_draws`)
runs the triaxial tests at the study's confining stresses, whose envelope gives the
Mohr-Coulomb c and φ and the Hoek-Brown mi (:func:`bpmcal.stages.triaxial.fit_envelopes`),
and the drop-hammer test at the reference velocity, which gives η_f; the draws run side
by side on the stage's CPUs (:class:`~.pool.SeedPool`), every run file kept. The table
holds one row per draw and, beside them, the verified card's own values where the study
measured them (its triaxial envelope and, for the impact's card, its reference impact),
so the report can give each prediction's mean and interval over the posterior beside the
card's.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd

from .. import params as P
from ..io.checks import BadInput, read_csv
from ..io.h5 import RunFileError, read_summary
from ..io.tables import write_table
from .inputs import CSV, H5, outputs
from .pool import SeedPool
from .runs import run_impact_file, run_triaxial_file
from .triaxial import fit_envelopes

#: the predictions a draw's runs give (the envelope's and the impact's)
PREDICTIONS = ("mi", "c_MPa", "phi_deg", "eta_f")


def _draw_job(*, params: dict, tri_runs: list, sigma3: list, impact_run, geometry, tri_settings,
              impact_geometry, impact_settings, tri_seed: int, impact_seed: int, cache,
              genesis_max_steps, threads, progress) -> dict:
    """One draw (a :class:`SeedPool` job): its triaxial runs and impact run, and the
    predictions they give (NaN where a run failed, with the reason in ``note``)."""
    kw = dict(cache=cache, threads=threads, progress=progress,
              genesis_max_steps=genesis_max_steps)
    s1, notes = [], []
    for s3, out in zip(sigma3, tri_runs):
        st = dataclasses.replace(tri_settings, sigma3=float(s3) * 1e6)
        r = run_triaxial_file(out, params, tri_seed, geometry, st, keep_particles=False, **kw)
        ok = r.status == "ok"
        s1.append(float(r.summary.get("sigma1_MPa", math.nan)) if ok else math.nan)
        if not ok:
            notes.append(f"triaxial at {s3:g} MPa failed: {r.summary.get('error', '')}")
    good = np.isfinite(s1)
    env = fit_envelopes(np.asarray(sigma3, float)[good], np.asarray(s1, float)[good])
    row = {k: env[k] for k in ("mi", "c_MPa", "phi_deg")}
    row.update({f"sigma1_{s3:g}_MPa": v for s3, v in zip(sigma3, s1)})
    if env.get("fit_note"):
        notes.append(env["fit_note"])
    row["eta_f"] = math.nan
    if impact_run is not None:
        r = run_impact_file(impact_run, params, impact_seed, impact_geometry, impact_settings,
                            **kw)
        if r.status == "ok":
            row["eta_f"] = float(r.summary["eta_f"])
        else:
            notes.append(f"impact failed: {r.summary.get('error', '')}")
    row["note"] = "; ".join(notes)
    return row


def _card_values(envelopes, specimen: str, impact_run) -> dict:
    """The verified card's own predictions: its row of the triaxial envelope table (card
    kind verified) and its reference impact's η_f, where given."""
    out = {k: math.nan for k in PREDICTIONS}
    if envelopes is not None:
        t = read_csv(envelopes, "--envelopes")
        sel = t[(t["specimen"].astype(str) == specimen)
                & (t.get("card", pd.Series("verified", t.index)).astype(str) == "verified")]
        if len(sel):
            out.update({k: float(pd.to_numeric(sel.iloc[0].get(k), errors="coerce"))
                        for k in ("mi", "c_MPa", "phi_deg")})
    if impact_run is not None:
        try:
            s = read_summary(impact_run)
            if s.get("status") == "ok":
                out["eta_f"] = float(s["eta_f"])
        except RunFileError:
            pass
    return out


def predictive(draws, *, specimen: str, tri_runs, table, sigma3, geometry, tri_settings,
               impact_runs=None, impact_geometry=None, impact_settings=None, tri_seed=1,
               impact_seed=1, envelopes=None, card_impact=None, cache=None, threads=None,
               genesis_max_steps=None, progress=None) -> pd.DataFrame:
    """Run every draw of ``draws`` (module docstring): ``tri_runs`` are the triaxial run
    files draw by draw, ``sigma3`` (MPa) within each; ``impact_runs`` one per draw (None:
    no impact). ``envelopes`` (the study's triaxial envelope table) and ``card_impact``
    (the card's reference impact run) give the card's own row. Writes ``table``: one row
    per draw (its parameters and predictions) and the card's row (``draw`` = card)."""
    d = read_csv(draws, "--draws", ["draw"], min_rows=1)
    sigma3 = [float(x) for x in sigma3]
    n = len(d)
    if len(sigma3) < 2:
        raise BadInput(f"--sigma3 {sigma3}: expected at least two confining stresses (an "
                       "envelope)")
    if len(tri_runs) != n * len(sigma3):
        raise BadInput(f"--tri-runs: {len(tri_runs)} file(s) for {n} draw(s) x "
                       f"{len(sigma3)} stresses: expected one per draw and stress, draw by draw")
    if impact_runs is not None and len(impact_runs) != n:
        raise BadInput(f"--impact-runs: {len(impact_runs)} file(s) for {n} draw(s)")
    outputs((table, "--table", CSV), *((f, "--tri-runs", H5) for f in tri_runs),
            *((f, "--impact-runs", H5) for f in (impact_runs or [])))
    names = [c for c in d.columns if c in P.ALL_PARAMS]
    params = [{k: float(r[k]) for k in names} for _, r in d.iterrows()]
    for p in params:
        P.validate_params(p)
    k = len(sigma3)
    jobs = [dict(params=params[i], tri_runs=tri_runs[i * k:(i + 1) * k], sigma3=sigma3,
                 impact_run=None if impact_runs is None else impact_runs[i], geometry=geometry,
                 tri_settings=tri_settings, impact_geometry=impact_geometry,
                 impact_settings=impact_settings, tri_seed=tri_seed, impact_seed=impact_seed,
                 cache=cache, genesis_max_steps=genesis_max_steps) for i in range(n)]
    with SeedPool(threads, progress) as pool:
        rows = pool.map(_draw_job, jobs, tags=[f"draw {int(x)}" for x in d["draw"]])
    out = pd.DataFrame([{"draw": str(int(x)), **p, **r}
                        for x, p, r in zip(d["draw"], params, rows)])
    card = {"draw": "card", **_card_values(envelopes, specimen, card_impact), "note": ""}
    out = pd.concat([out, pd.DataFrame([card])], ignore_index=True)
    write_table(out, table, index=False)
    return out


def summarise(t: pd.DataFrame, prob: float = 0.9) -> pd.DataFrame:
    """Each prediction's mean and central ``prob`` interval over the draws of a predictive
    table, beside the card's value and the number of draws that gave it."""
    draws = t[t["draw"].astype(str) != "card"]
    card = t[t["draw"].astype(str) == "card"]
    q = (1 - prob) / 2
    rows = []
    for k in PREDICTIONS:
        if k not in t.columns:
            continue
        v = pd.to_numeric(draws[k], errors="coerce").to_numpy(float)
        v = v[np.isfinite(v)]
        c = float(pd.to_numeric(card[k], errors="coerce").iloc[0]) if len(card) else math.nan
        rows.append({"prediction": k, "card": c, "n": len(v),
                     "mean": float(v.mean()) if len(v) else math.nan,
                     "low": float(np.quantile(v, q)) if len(v) else math.nan,
                     "high": float(np.quantile(v, 1 - q)) if len(v) else math.nan})
    return pd.DataFrame(rows).set_index("prediction")
