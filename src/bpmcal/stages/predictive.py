"""The posterior predictive in DEM (``workflow/rules/posterior.smk``, ``bpmcal predictive``):
the untargeted predictions of a card, run on posterior draws.

Each draw of ``posterior/<specimen>/draws.csv`` (:func:`bpmcal.stages.posterior.pick_draws`)
runs the triaxial tests at the study's confining stresses, whose envelope gives the
Mohr-Coulomb c and φ and the Hoek-Brown mi (:func:`bpmcal.stages.triaxial.fit_envelopes`),
and the drop-hammer test at the reference velocity, which gives η_f; every run of every
draw is a job of its own on the stage's CPUs (:class:`~.pool.SeedPool`, the longest first,
so that no CPU idles while another finishes a draw), every run file kept. Every finished
run is journaled (:class:`~.journal.RunJournal`, in ``.<table's stem>.runs`` beside the
table) as soon as it ends: a stage stopped part way (a time limit, a kill; a flat-jointed
impact can take a quarter of an hour) and started again with the same inputs reads the
runs it had finished instead of running them again; the journal goes once the table is
written. The table
holds one row per draw and, beside them, the verified card's own values where the study
measured them (its triaxial envelope and, for the impact's card, its reference impact),
so the report can give each prediction's mean and interval over the posterior beside the
card's.
"""
from __future__ import annotations

import dataclasses
import math
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .. import params as P
from ..io.checks import BadInput, read_csv
from ..io.h5 import RunFileError, read_summary
from ..io.tables import write_table
from ..lab.impact import ImpactSettings
from ..lab.run_context import RunContext
from ..lab.runner import Geometry
from ..lab.triaxial import TriaxialSettings
from .inputs import CSV, H5, outputs
from .journal import RunJournal
from .pool import SeedPool
from .runs import run_impact_file, run_triaxial_file
from .settings import SEED, check_fields, setting
from .triaxial import DEFAULT_SIGMA3_MPA, fit_envelopes

#: the predictions a draw's runs give (the envelope's and the impact's)
PREDICTIONS = ("mi", "c_MPa", "phi_deg", "eta_f")


@dataclass(frozen=True)
class PredictiveSettings:
    """How every draw is run (``bpmcal predictive``'s options): the triaxial tests at the
    confining stresses ``sigma3_MPa`` (MPa, at least two different ones: an envelope) on
    the cylinder ``geometry`` loaded as ``tri_settings`` say (their ``sigma3`` is each
    test's), packed with ``tri_seed``; the drop hammer on ``impact_geometry`` as
    ``impact_settings`` say, packed with ``impact_seed`` (both needed when the stage is
    given impact run files). Checked when built."""

    sigma3_MPa: tuple = DEFAULT_SIGMA3_MPA
    geometry: Geometry = field(default_factory=Geometry)
    tri_settings: TriaxialSettings = field(default_factory=TriaxialSettings)
    impact_geometry: Geometry | None = None
    impact_settings: ImpactSettings | None = None
    tri_seed: int = setting(1, SEED)
    impact_seed: int = setting(1, SEED)

    def __post_init__(self):
        check_fields(self)
        sigma3 = tuple(float(x) for x in self.sigma3_MPa)
        if len(sigma3) < 2:
            raise BadInput(f"--sigma3 {list(sigma3)}: expected at least two confining "
                           "stresses (an envelope)")
        object.__setattr__(self, "sigma3_MPa", sigma3)
        if (self.impact_geometry is None) != (self.impact_settings is None):
            raise BadInput("predictive settings: impact_geometry and impact_settings go "
                           "together (both, or neither: no impact)")


def _run_job(*, kind: str, stem, params: dict, seed: int, geometry, settings, ctx
             ) -> tuple[dict, list]:
    """One run of a draw (a :class:`SeedPool` job, with its
    :class:`~bpmcal.lab.run_context.RunContext` ``ctx``): a triaxial test (``kind`` "tri",
    at ``settings.sigma3``) or the drop hammer ("impact") into ``<stem>.h5`` (in the
    journal's folder); its record (whether it ran, the value the draw needs of it: σ1 at
    failure, η_f, NaN for a failed run; the error; the file's name) and the file."""
    kw = ctx.lab_kw()
    out = Path(f"{stem}.h5")
    if kind == "tri":
        r = run_triaxial_file(out, params, seed, geometry, settings, keep_particles=False, **kw)
        key = "sigma1_MPa"
    else:
        r = run_impact_file(out, params, seed, geometry, settings, **kw)
        key = "eta_f"
    ok = r.status == "ok"
    path = Path(r.path) if r.path is not None else out
    return ({"ok": ok, "value": float(r.summary.get(key, math.nan)) if ok else math.nan,
             "error": r.error or r.summary.get("error", ""), "file": path.name},
            [path] if path.exists() else [])


def _place(src: Path, dst) -> None:
    """The journaled run file ``src`` at its output path ``dst`` (a hard link where the
    file system allows, else a copy; through a temporary name, so ``dst`` appears only
    complete)."""
    dst = Path(dst)
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(f".{dst.name}.part")
    tmp.unlink(missing_ok=True)
    try:
        os.link(src, tmp)
    except OSError:
        shutil.copy2(src, tmp)
    os.replace(tmp, dst)


def _run_journaled(jobs: list[dict], tags: list[str], journal: RunJournal, ctx: RunContext
                   ) -> list[dict]:
    """Every job (:func:`_run_job`'s arguments but ``stem``) through ``journal`` (module
    docstring): a job it holds is read back, the others run side by side, each journaled
    as it ends. Returns every job's record, in order."""
    folder = journal.folder
    if journal.resumable:
        print(f"predictive: {journal.resumable} finished run(s) of an earlier attempt in "
              f"{folder}: read back, not run again", flush=True)
    keys = [RunJournal.key(**job, genesis_max_steps=ctx.genesis_max_steps) for job in jobs]
    done = {i: journal.get(k) for i, k in enumerate(keys)}
    todo = [i for i, rec in done.items() if rec is None]

    def finished(j, res):
        rec, files = res
        done[todo[j]] = journal.add(keys[todo[j]], rec, files)

    with SeedPool.of(ctx) as pool:  # every run its own job: no idle tail
        pool.map(_run_job, [dict(jobs[i], stem=journal.stem(keys[i])) for i in todo],
                 tags=[tags[i] for i in todo], done=finished)
    return [dict(done[i], path=folder / done[i]["file"]) for i in range(len(jobs))]


def _draw_row(sigma3: list, tri: list[dict], impact: dict | None) -> dict:
    """A draw's predictions from its runs (:func:`_run_job`'s records: the triaxial tests
    in the order of ``sigma3``, the impact or None): the envelope's and η_f (NaN where a
    run failed, with the reason in ``note``)."""
    s1 = [t["value"] for t in tri]
    notes = [f"triaxial at {s3:g} MPa failed: {t['error']}"
             for s3, t in zip(sigma3, tri) if not t["ok"]]
    good = np.isfinite(s1)
    env = fit_envelopes(np.asarray(sigma3, float)[good], np.asarray(s1, float)[good])
    row = {k: env[k] for k in ("mi", "c_MPa", "phi_deg")}
    row.update({f"sigma1_{s3:g}_MPa": v for s3, v in zip(sigma3, s1)})
    if env.get("fit_note"):
        notes.append(env["fit_note"])
    row["eta_f"] = math.nan
    if impact is not None:
        if impact["ok"]:
            row["eta_f"] = impact["value"]
        else:
            notes.append(f"impact failed: {impact['error']}")
    row["note"] = "; ".join(notes)
    return row


def _draw_jobs(params: list, tri_runs: list, impact_runs, settings: PredictiveSettings
               ) -> list[tuple]:
    """Every run of every draw as its own pool job (:func:`_run_job`), the longest first so
    that the stage's CPUs stay busy to its end: the impacts, then the triaxial tests from
    the highest confinement down. Returns (draw, index: -1 for the impact, else the
    stress's, its output file, job) in that order."""
    sigma3 = settings.sigma3_MPa
    k, jobs = len(sigma3), []
    if impact_runs is not None:
        jobs += [(i, -1, impact_runs[i], dict(kind="impact", params=p,
                                              seed=settings.impact_seed,
                                              geometry=settings.impact_geometry,
                                              settings=settings.impact_settings))
                 for i, p in enumerate(params)]
    for j in sorted(range(k), key=lambda j: -sigma3[j]):
        st = dataclasses.replace(settings.tri_settings, sigma3=float(sigma3[j]) * 1e6)
        jobs += [(i, j, tri_runs[i * k + j], dict(kind="tri", params=p, seed=settings.tri_seed,
                                                  geometry=settings.geometry, settings=st))
                 for i, p in enumerate(params)]
    return jobs


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


def predictive(draws, *, specimen: str, tri_runs, table, settings: PredictiveSettings,
               impact_runs=None, envelopes=None, card_impact=None,
               ctx: RunContext = RunContext()) -> pd.DataFrame:
    """Run every draw of ``draws`` (module docstring) as ``settings`` say
    (:class:`PredictiveSettings`): ``tri_runs`` are the triaxial run files draw by draw,
    ``settings.sigma3_MPa`` within each; ``impact_runs`` one per draw (None: no impact);
    ``ctx``: how the DEM runs (:class:`~bpmcal.lab.run_context.RunContext`).
    ``envelopes`` (the study's triaxial envelope table) and ``card_impact``
    (the card's reference impact run) give the card's own row. Writes ``table``: one row
    per draw (its parameters and predictions) and the card's row (``draw`` = card)."""
    d = read_csv(draws, "--draws", ["draw"], min_rows=1)
    sigma3 = list(settings.sigma3_MPa)
    n = len(d)
    if len(tri_runs) != n * len(sigma3):
        raise BadInput(f"--tri-runs: {len(tri_runs)} file(s) for {n} draw(s) x "
                       f"{len(sigma3)} stresses: expected one per draw and stress, draw by draw")
    if impact_runs is not None and len(impact_runs) != n:
        raise BadInput(f"--impact-runs: {len(impact_runs)} file(s) for {n} draw(s)")
    if impact_runs is not None and settings.impact_settings is None:
        raise BadInput("--impact-runs: given, but the settings have no impact specimen and "
                       "settings (impact_geometry, impact_settings)")
    outputs((table, "--table", CSV), *((f, "--tri-runs", H5) for f in tri_runs),
            *((f, "--impact-runs", H5) for f in (impact_runs or [])))
    names = [c for c in d.columns if c in P.ALL_PARAMS]
    params = [{k: float(r[k]) for k in names} for _, r in d.iterrows()]
    for p in params:
        P.validate_params(p)
    jobs = _draw_jobs(params, tri_runs, impact_runs, settings)
    names_of = {-1: "impact"} | {j: f"triaxial {s3:g} MPa" for j, s3 in enumerate(sigma3)}
    journal = RunJournal(Path(table).parent / f".{Path(table).stem}.runs")
    try:
        done = _run_journaled([job for *_, job in jobs],
                              [f"draw {int(d['draw'].iloc[i])} {names_of[j]}"
                               for i, j, *_ in jobs], journal, ctx)
        for (_, _, dst, _), rec in zip(jobs, done):
            _place(rec["path"], dst)
        out = _table(d, params, sigma3, done, jobs, envelopes, specimen, card_impact)
        write_table(out, table, index=False)
    except BaseException:
        journal.keep_or_remove()  # the finished runs are read back next time
        raise
    journal.remove()
    return out


def _table(d, params, sigma3, done, jobs, envelopes, specimen, card_impact) -> pd.DataFrame:
    """The stage's table: one row per draw (its parameters and predictions) and the
    card's row."""
    n = len(d)
    runs = {(i, j): r for (i, j, *_), r in zip(jobs, done)}
    rows = [_draw_row(sigma3, [runs[i, j] for j in range(len(sigma3))],
                      runs.get((i, -1))) for i in range(n)]
    out = pd.DataFrame([{"draw": str(int(x)), **p, **r}
                        for x, p, r in zip(d["draw"], params, rows)])
    card = {"draw": "card", **_card_values(envelopes, specimen, card_impact), "note": ""}
    return pd.concat([out, pd.DataFrame([card])], ignore_index=True)


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
