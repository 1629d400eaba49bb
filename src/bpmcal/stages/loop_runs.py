"""The closed loop's DEM runs and their journal (:func:`.verification._dem_loop`; the
transfer runs its loop through it, the posterior's refinement its seeds with
:func:`loop_seed`).

:class:`LoopRuns` runs every round's seeds side by side on the stage's CPUs, journals each
finished run (:class:`~.journal.RunJournal`: a loop stopped part way reads them again) and
adapts a card's tensile specimens per seed to its specimen scatter. A seed is measured
whole by :func:`loop_seed`, or as pool jobs of its own (:func:`seed_parts`,
:func:`run_part`) put together by :func:`seed_record`; :func:`seed_runs_table` is the
loop's table of every seed run. The measurements themselves are :mod:`.measure`'s.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis.calibration.specimens import expected_cv, pooled_cv, specimens_needed
from ..params import SAMPLE_TESTS
from .journal import RunJournal, plain
from .measure import (
    RUNNERS,
    TENSILE_TEST_NAMES,
    SpecimenRun,
    combine_specimens,
    row_strength,
    specimen_run,
    specimen_text,
    specimen_values,
    specimens_of,
)
from .pool import SeedPool

#: the degrees of freedom of the pooled specimen CV before the loop raises a seed's count
#: on it (:class:`LoopRuns`): 3 seeds x 3 discs give 8, 3 seeds x 1 disc 2 (not enough)
MIN_SPECIMEN_DOF = 6


class LoopRuns:
    """The DEM runs of a closed loop (:func:`.verification._dem_loop`): every round's seeds
    run the tests ``tests`` (:class:`~.measure.SeedTests`) side by side on up to
    ``ctx.threads`` processes (:class:`SeedPool` of the stage's
    :class:`~bpmcal.lab.run_context.RunContext` ``ctx``), each finished run journaled in
    ``folder`` (:class:`RunJournal`: a loop stopped part way and started again with the
    same inputs reads the runs it had finished); per round the seeds' rows (``by_round``),
    UCS run files (``paths``) and Brazilian run files (``bts_paths``). ``caps``: target ->
    how many of the seed set's first seeds (from ``loop.seed`` on) measure it; a seed
    past a target's cap does not run its test. A seed's σt is the mean of
    ``loop.tensile_specimens`` specimens (:class:`~bpmcal.analysis.calibration.LoopSettings`).

    With ``loop.tensile_seed_cv`` (config ``verification.tensile_seed_cv``) and a σt
    target, the count of tensile specimens per seed adapts to the card: when a round
    starts, the specimen CV pooled over every specimen measured so far (:func:`pooled_cv`;
    at least ``MIN_SPECIMEN_DOF`` degrees of freedom) sets the count its seeds need
    (:func:`specimens_needed`: the chance of reading a seed CV above the aim over 5
    seeds below 10 %), never fewer than now nor more than
    ``loop.max_tensile_specimens``. A raise
    tops up that round's seeds (specimens m .. n-1 only, journaled like a run) and holds
    for every later round and seed, so a round's seeds are all measured alike."""

    def __init__(self, folder: Path, targets: list, *, tests, ctx, loop, caps=None):
        self.journal = RunJournal(folder)
        self.inputs = dict(targets=targets, tests=tests,
                           tensile_specimens=loop.tensile_specimens)
        self.ctx, self.progress = ctx, ctx.progress
        self.pool = SeedPool.of(ctx)
        self.by_round: list[list[dict]] = []
        self.paths: list[list[Path]] = []
        self.bts_paths: list[list[Path]] = []
        self._last: dict | None = None
        self.caps, self.first_seed = dict(caps or {}), int(loop.seed)
        self.tensile = next((r for r in targets if SAMPLE_TESTS.get(r) in TENSILE_TEST_NAMES), None)
        self.seed_cv = loop.tensile_seed_cv if self.tensile is not None else None
        self.max_specimens = loop.most_tensile_specimens
        self.start_specimens = loop.tensile_specimens
        self.raised: list[dict] = []
        if self.journal.resumable:
            self._note(f"{self.journal.resumable} finished run(s) of an earlier attempt in "
                       f"{folder}: a run with the same inputs is read, not run again")

    def _note(self, text: str) -> None:
        if self.progress is not None:
            self.progress({"note": text})

    def simulate_seeds(self, params: dict, seeds: list) -> list[dict]:
        """:class:`ClosedLoop`'s ``simulate_seeds``: the responses of ``params`` on each seed."""
        new_round = params != self._last
        if new_round:  # a new point: a new round (grown seeds join theirs)
            self._last = dict(params)
            self.by_round.append([])
            self.paths.append([])
            self.bts_paths.append([])
        jobs = [dict(self.inputs, params=params, seed=seed,
                     targets=[r for r in self.inputs["targets"]
                              if seed - self.first_seed < self.caps.get(r, math.inf)])
                for seed in seeds]
        k = len(self.by_round)
        done = self._seed_records(jobs, f"round {k}")
        rows = [dict(done[i]["row"]) for i in range(len(seeds))]
        outs = [dict(done[i]["out"]) for i in range(len(seeds))]
        for i in range(len(seeds)):
            self.paths[-1].append(self.journal.folder / done[i]["ucs"])
            if done[i]["bts"] is not None:
                self.bts_paths[-1].append(self.journal.folder / done[i]["bts"])
            rows[i]["round"], rows[i]["params"] = k, dict(params)
            self.by_round[-1].append(rows[i])
        if new_round and self.seed_cv is not None:
            self._adapt(params, seeds, rows, outs)
        return outs

    def _journaled(self, fn, jobs: list[dict], tags: list[str]) -> list[dict]:
        """``fn`` (returning (record, run files)) over ``jobs`` through the journal: a job
        whose inputs it holds is read back, the others run side by side, each journaled as
        soon as it ends. Returns every job's record, in order, as a reused run reads it."""
        # a run's key: its inputs and the genesis's step budget (a specimen that does not
        # settle within it is a failed run)
        keys = [RunJournal.key(**job, genesis_max_steps=self.ctx.genesis_max_steps)
                for job in jobs]
        done = {i: self.journal.get(key) for i, key in enumerate(keys)}
        todo = [i for i, rec in done.items() if rec is None]

        def finished(j, res):
            rec, files = res
            done[todo[j]] = self.journal.add(keys[todo[j]], rec, files)

        self.pool.map(fn, [dict(jobs[i], stem=self.journal.stem(keys[i])) for i in todo],
                      tags=[tags[i] for i in todo], done=finished)
        return [done[i] for i in range(len(jobs))]

    def _parts(self, jobs: list[dict], tag: str, first_specimen: int = 0) -> list:
        """Every seed job's parts (:func:`seed_parts`: its UCS test, each
        tensile specimen) side by side through the journal, the longest first. Returns
        per job (its UCS record or None, resp -> its specimens' records in order)."""
        parts = [(i, p) for i, job in enumerate(jobs) for p in seed_parts(job, first_specimen)]
        order = longest_first([p for _, p in parts])
        names = [f"{tag} seed {parts[i][1]['seed']} "
                 + ("UCS" if parts[i][1]["part"] == "ucs"
                    else f"{SAMPLE_TESTS[parts[i][1]['part']]} {parts[i][1]['j'] + 1}")
                 for i in order]
        recs = self._journaled(run_part, [parts[i][1] for i in order], names)
        out = [(None, {}) for _ in jobs]
        for i, rec in zip(order, recs):
            job, part = parts[i]
            if part["part"] == "ucs":
                out[job] = (rec, out[job][1])
            else:
                out[job][1].setdefault(part["part"], {})[part["j"]] = rec
        return [(u, {r: [v[j] for j in sorted(v)] for r, v in sp.items()}) for u, sp in out]

    def _seed_records(self, jobs: list[dict], tag: str) -> list[dict]:
        """The journal records of :func:`loop_seed` for the seed ``jobs``, their tests
        run as jobs of their own (:meth:`_parts`)."""
        return [seed_record(job, ucs, sp) for job, (ucs, sp) in
                zip(jobs, self._parts(jobs, tag))]

    def _specimen_cv(self) -> tuple[float, int]:
        """The tensile specimen CV pooled over every round so far (:func:`pooled_cv`)."""
        test = SAMPLE_TESTS[self.tensile]
        return pooled_cv([v for row in rnd for v in specimen_values(row, self.tensile, test)]
                         for rnd in self.by_round)

    def _adapt(self, params: dict, seeds: list, rows: list, outs: list) -> None:
        """Raise the tensile specimens per seed when the pooled specimen CV asks for more
        (class docs), topping up this round's ``rows`` and ``outs`` in place."""
        cv, dof = self._specimen_cv()
        k = self.inputs["tensile_specimens"]
        if dof < MIN_SPECIMEN_DOF:
            return
        need = specimens_needed(cv, self.seed_cv, least=k, most=self.max_specimens)
        if need <= k:
            return
        resp, test = self.tensile, SAMPLE_TESTS[self.tensile]
        self.raised.append({"round": len(self.by_round), "from": k, "to": need,
                            "specimen_cv": round(cv, 6), "dof": dof})
        self._note(f"tensile specimens per seed {k} -> {need} from round {len(self.by_round)}"
                   f": the {test} specimens scatter {100 * cv:.1f} % ({dof} degrees of "
                   f"freedom), and {k} per seed would read a seed CV above "
                   f"{100 * self.seed_cv:g} % over 5 seeds too often"
                   + (f" ({need} is verification.max_tensile_specimens)"
                      if need == self.max_specimens else ""))
        self.inputs["tensile_specimens"] = need
        top = [i for i, row in enumerate(rows) if _finite(row.get(resp))]
        jobs = [dict(self.inputs, params=params, seed=seeds[i], targets=[resp]) for i in top]
        done = [top_up_record(sp[resp], need - k) for _, sp in
                self._parts(jobs, f"round {len(self.by_round)} top-up", first_specimen=k)]
        for j, i in enumerate(top):
            rec, row = done[j], rows[i]
            old = specimen_values(row, resp, test)
            vals = old + [float(v) for v in rec["values"]]
            row[f"{test}_specimens"] = len(vals)
            row[f"{test}_specimen_MPa"] = specimen_text(vals)
            row[f"{test}_invalid"] = int(row.get(f"{test}_invalid", 0)) + int(rec["invalid"])
            ok = rec["status"] == "ok" and len(vals) == need and all(map(_finite, vals))
            # the old specimens' exact sum (their mean x k), not their 6-digit record
            row[resp] = (float(row[resp]) * k + sum(rec["values"])) / need if ok else math.nan
            if not ok:
                row["status"] = "failed"
            outs[i][resp] = row[resp]

    def specimen_record(self) -> dict:
        """The tensile specimens per seed of the loop: ``count`` (the last rounds'), and
        with a ``seed_cv`` target the pooled specimen CV (``specimen_cv``, ``dof``), the
        seed CV expected at ``count`` and its chance of reading above the target over 5
        seeds, and every raise (``raised``: round, from, to, CV, dof)."""
        out = {"count": int(self.inputs["tensile_specimens"])}
        if self.seed_cv is None:
            return out
        cv, dof = self._specimen_cv()
        out.update(seed_cv_target=float(self.seed_cv), start=self.start_specimens,
                   max=self.max_specimens, raised=list(self.raised))
        if dof:
            cvk, p = expected_cv(cv, out["count"], self.seed_cv)
            out.update(specimen_cv=round(cv, 6), dof=dof, seed_cv_expected=round(cvk, 6),
                       chance_above=round(p, 4))
        return out

    def simulate(self, params: dict, seed: int) -> dict:
        """:class:`ClosedLoop`'s ``simulate``: one seed."""
        return self.simulate_seeds(params, [seed])[0]

    def close(self, ok: bool) -> None:
        """Stop the workers; remove the journal when the loop's outputs are written (``ok``),
        else keep its finished runs for the next attempt."""
        self.pool.close()
        if ok:
            self.journal.remove()
        else:
            self.journal.keep_or_remove()
        if self.journal.reused:
            self._note(f"{self.journal.reused} run(s) read from the journal of an earlier "
                       "attempt, not run again")


def loop_seed(*, params: dict, seed: int, stem: Path, targets: list, tests, ctx,
              tensile_specimens: int = 1):
    """One seed of a closed-loop round (:func:`.verification._dem_loop`; run in a
    :class:`SeedPool` worker or in this process, with its
    :class:`~bpmcal.lab.run_context.RunContext` ``ctx``): the UCS test into ``<stem>.h5``
    and every per-sample test of the ``targets`` (``tests``: the
    :class:`~.measure.SeedTests`), an invalid one replaced, σt the mean of
    ``tensile_specimens`` specimens (:func:`~.measure.seed_strength`). Returns (its
    journal record: the seed's row, its responses, the names of the UCS run file and of
    the Brazilian one or None; every run file it wrote)."""
    kw = ctx.lab_kw()
    specimens = tests.specimens()
    res = RUNNERS["ucs"](Path(f"{stem}.h5"), params, seed, tests.geometry, tests.settings, **kw)
    row = dict(res.summary, status=res.status, seed=seed)
    out = ({r: float(res.summary[r]) for r in targets if r not in SAMPLE_TESTS}
           if res.status == "ok" else {r: math.nan for r in targets if r not in SAMPLE_TESTS})
    bts_path = None
    for resp in (r for r in SAMPLE_TESTS if r in targets):  # σt, σ1: a valid test, or NaN
        test = SAMPLE_TESTS[resp]
        geo, st = specimens[test]
        b, _ = row_strength(row, resp, lambda j, s, k, t=test: specimen_path(stem, t, j, k),
                            params, seed, geo, st, tensile_specimens=tensile_specimens, **kw)
        if test == "bts":
            bts_path = b.path
        if b.status != "ok" or not math.isfinite(row[resp]):
            row["status"] = "failed"
        out[resp] = row[resp]
    return ({"row": row, "out": out, "ucs": Path(res.path).name,
             "bts": None if bts_path is None else Path(bts_path).name}, run_files(stem))


# ---- a seed's tests as pool jobs of their own ---------------------------------------
# The UCS test and each tensile specimen (its replacements included) of every seed of a
# closed-loop round (and of a fresh-seed check: .fresh_seeds) run side by side on the
# stage's CPUs, not a seed per job: a round of 3 seeds run seed by seed on 2 CPUs keeps them
# at most 75 % busy (the third seed runs alone), its UCS tests and discs as jobs of their
# own (3 + 9 with 3 discs a seed) keep both busy to the round's last run. The numbers do
# not change: every run is deterministic in its inputs and packing seed, wherever and
# beside whatever it runs, and a seed's row is put together from its runs as loop_seed
# puts it together from the same runs one after the other (combine_specimens). The one
# difference: a specimen after a failed one (a failure, not an invalid test) runs, and is
# not counted, where the runs one after the other stop at the failure.


def seed_parts(job: dict, first_specimen: int = 0) -> list[dict]:
    """The pool jobs of one loop seed's ``job`` (:func:`loop_seed`'s
    arguments but the folder and the context): its UCS test (none with
    ``first_specimen`` > 0: a top-up of its tensile specimens) and every specimen j of each
    per-sample test of its targets (from ``first_specimen`` on)."""
    tests = job["tests"]
    base = {"params": job["params"], "seed": job["seed"], "geometry": tests.geometry,
            "settings": tests.settings}
    parts = [] if first_specimen else [dict(base, part="ucs")]
    specimens = tests.specimens()
    for resp in (r for r in SAMPLE_TESTS if r in job["targets"]):  # σt, σ1
        geo, st = specimens[SAMPLE_TESTS[resp]]
        n = specimens_of(resp, job.get("tensile_specimens", 1))
        parts += [dict(base, part=resp, j=j, geometry=geo, settings=st)
                  for j in range(first_specimen, n)]
    return parts


def longest_first(parts: list[dict]) -> list[int]:
    """The order to run ``parts`` in: the UCS tests, then the specimens by index (each
    seed's first specimens before any seed's later ones)."""
    return sorted(range(len(parts)), key=lambda i: (parts[i]["part"] != "ucs",
                                                     parts[i].get("j", 0)))


def run_part(*, part: str, params: dict, seed: int, geometry, settings, stem: Path, ctx,
             j: int = 0):
    """One pool job of :func:`seed_parts` (with its
    :class:`~bpmcal.lab.run_context.RunContext` ``ctx``): the UCS test into
    ``<stem>.h5``, or specimen ``j`` of the test of strength ``part`` into
    ``<stem>.<test><k>[.r<j>].h5`` (:func:`specimen_path`). Returns (its record: JSON-able,
    every run file it wrote)."""
    kw = ctx.lab_kw()
    if part == "ucs":
        res = RUNNERS["ucs"](Path(f"{stem}.h5"), params, seed, geometry, settings, **kw)
        rec = {"summary": dict(res.summary), "status": res.status,
               "ucs": Path(res.path).name}
    else:
        test = SAMPLE_TESTS[part]
        r = specimen_run(part, lambda j, s, k: specimen_path(stem, test, j, k), params,
                           seed, j, geometry, settings, **kw)
        rec = asdict(r)
    return rec, run_files(stem)


def _specimen_runs(records) -> list:
    return [SpecimenRun(**r) for r in records]


def seed_record(job: dict, ucs: dict, specimens: dict) -> dict:
    """A loop seed's journal record from its parts' records (``ucs``; ``specimens``: resp
    -> the records of its specimens in order), as :func:`loop_seed` gives
    it (and as the journal gives it back: JSON's types)."""
    targets, seed = job["targets"], job["seed"]
    row = dict(ucs["summary"], status=ucs["status"], seed=seed)
    ok = ucs["status"] == "ok"
    out = {r: float(ucs["summary"][r]) if ok else math.nan
           for r in targets if r not in SAMPLE_TESTS}
    bts_path = None
    for resp in (r for r in SAMPLE_TESTS if r in targets):
        test = SAMPLE_TESTS[resp]
        n = specimens_of(resp, job.get("tensile_specimens", 1))
        b, used, invalid, row[resp], values = combine_specimens(_specimen_runs(specimens[resp]), n)
        row[f"{test}_seed"], row[f"{test}_invalid"] = used, len(invalid)
        if n > 1:
            row[f"{test}_specimens"] = len(values)
            row[f"{test}_specimen_MPa"] = specimen_text(values)
        if test == "bts":
            bts_path = b.path
        if b.status != "ok" or not math.isfinite(row[resp]):
            row["status"] = "failed"
        out[resp] = row[resp]
    rec = {"row": row, "out": out, "ucs": ucs["ucs"],
           "bts": None if bts_path is None else Path(bts_path).name}
    return json.loads(json.dumps(rec, default=plain, allow_nan=True))


def top_up_record(records, n: int) -> dict:
    """The record of a seed's raised tensile specimens (their strengths, the count of
    invalid attempts, the status: :meth:`LoopRuns._adapt` reads it) from
    their parts' records in order; ``n``: how many were asked for."""
    b, _, invalid, _, values = combine_specimens(_specimen_runs(records), n)
    return {"values": [float(v) for v in values], "invalid": len(invalid), "status": b.status}


def specimen_path(stem, test: str, j: int, k: int) -> Path:
    """The run file of tensile specimen ``j``'s attempt ``k`` of a loop seed (``stem``):
    ``<stem>.<test><k>.h5`` for specimen 0, ``<stem>.<test><k>.r<j>.h5`` after it."""
    return Path(f"{stem}.{test}{k}{f'.r{j}' if j else ''}.h5")


def run_files(stem) -> list[Path]:
    """Every run file a loop job wrote under ``stem`` (the journal keeps them)."""
    return [Path(f) for f in Path(stem).parent.glob(f"{Path(stem).name}*.h5")]


def seed_runs_table(by_round: list[list[dict]]) -> pd.DataFrame:
    """One row per DEM seed of a closed loop (``verification/<specimen>/seeds.csv``): the
    round (1-based), the seed, every card parameter of that round (paper units), the run's
    status and every response it measured (a tensile seed's specimens in
    ``<test>_specimen_MPa``). The posterior's surrogate learns from these runs near the
    card (:mod:`bpmcal.stages.posterior`)."""
    recs = []
    for rnd in by_round:
        for row in rnd:
            rec = {"round": int(row["round"]), "seed": int(row["seed"]), **row["params"]}
            rec.update({k: v for k, v in row.items() if k not in ("round", "seed", "params")
                        and (v is None or isinstance(v, (str, bool, int, float, np.number)))})
            recs.append(rec)
    return pd.DataFrame(recs, columns=None if recs else ["round", "seed", "status"])


def _finite(x) -> bool:
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError):
        return False
