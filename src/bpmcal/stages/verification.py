"""The verification stages (``workflow/rules/analysis.smk``): re-run the DEM with a card.

- :func:`verify`: the closed loop (Newton-Broyden, seed-averaged) from a calibrated card
  until every response is within the tolerance of the lab value or the rounds are used
  up -> verified card, rounds table, the best round's run files;
- :func:`seed_scatter`: one card, several packing seeds -> run files and the scatter
  table (:func:`bpmcal.analysis.calibration.scatter_table`);
- :func:`verification_tables`: Tables 5 and 6 and Fig. 6 from the verified cards.

:func:`_dem_loop` runs the closed loop on the DEM (the UCS test, and the tensile test of
a σt target: :func:`valid_tensile_run`); :mod:`.transfer` and :mod:`.fresh_seeds` reuse it and
the helpers here. The DEM runners (``run_ucs_file``, ``run_bts_file``, ``run_dtt_file``)
are looked up in this module. Method: ``docs/methods/calibration.md`` ("Closed loop").
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .. import params as P
from ..analysis import ClosedLoop, scatter_table
from ..analysis.calibration import UPDATES
from ..analysis.calibration.closed_loop import check_grow_within, check_max_rounds
from ..analysis.calibration.specimens import (
    MISS_ACCEPTED,
    expected_cv,
    pooled_cv,
    specimens_needed,
)
from ..io.card import card_parameters, read_card, write_card
from ..io.checks import BadInput
from ..io.figures import save_figure
from ..io.h5 import read_series
from ..io.tables import write_table
from ..lab.brazilian import BTSSettings
from ..lab.budget import check_budget
from ..lab.direct_tension import DTTSettings
from ..lab.runner import bts_geometry as _isrm_disc
from ..lab.runner import bts_inputs, ucs_inputs
from ..params import BTS, SAMPLE_TESTS
from ..plots.calibration import fig_stress_strain
from . import defaults_of
from .inputs import CSV, H5, PNG, YAML, output_dirs, outputs, read_lab, read_models
from .journal import RunJournal, plain
from .pool import SeedPool
from .runs import (  # noqa: F401 (the per-sample tests' runners: _TEST_RUN names them)
    run_bts_file,
    run_dtt_file,
    run_triaxial_file,
    run_ucs_file,
    write_failure,
)

#: the defaults of the stages are those of the analysis they run
_LOOP = defaults_of(ClosedLoop)
_LOOP_GROW = _LOOP["grow_within"]

#: responses a verified card records per round besides the targets
_EXTRA = ("u_pre_MJm3", "peak_strain", "cracks_tension", "cracks_shear")


def _responses(rows: list[dict], targets: dict) -> dict:
    """The seed mean of every response over the runs of one round (``rows``: one summary
    per seed), its seed spread (``seed_sd``, ``seed_cv``: sample standard deviation and
    coefficient of variation, NaN with one seed), ``n_seeds`` and the errors of the mean
    in % of the lab value. σt (``bts_MPa``) is among them when it is a target; a target
    measured on fewer of the seeds (a seed cap, or a failed test) is listed with its
    count in ``n_measured``."""
    ok = [r for r in rows if r.get("status") == "ok"]
    scattered = [*P.TARGETS, *(r for r in SAMPLE_TESTS if r in targets)]
    d, sd, cv, n = {}, {}, {}, {}
    for k in [*scattered, *_EXTRA]:
        v = np.array([float(r.get(k, math.nan)) for r in ok], float)
        v = v[np.isfinite(v)] if k in SAMPLE_TESTS else v  # an invalid test is no measurement
        n[k] = len(v)
        d[k] = float(v.mean()) if len(v) else math.nan
        if k in scattered:
            sd[k] = float(v.std(ddof=1)) if len(v) > 1 else math.nan
            cv[k] = sd[k] / abs(d[k]) if len(v) > 1 and d[k] != 0 else math.nan
    d["errors_pct"] = {k: 100 * (d[k] / v - 1) for k, v in targets.items()}
    d["seed_sd"], d["seed_cv"] = sd, cv
    d["n_seeds"] = len(ok)
    fewer = {k: n[k] for k in targets if k in n and n[k] != len(ok)}
    if fewer:  # a target measured on fewer seeds (the triaxial seed cap)
        d["n_measured"] = fewer
    d["seeds"] = [int(r["seed"]) for r in rows]
    d["run_status"] = "ok" if ok and len(ok) == len(rows) else "failed"
    return d


def _missed(resp: dict, targets: dict, rtol: float) -> list[dict]:
    """Every target the DEM misses by more than ``rtol``: target, value, dem, error_pct."""
    return [{"target": k, "value": v, "dem": resp[k], "error_pct": resp["errors_pct"][k]}
            for k, v in targets.items()
            if not abs(resp["errors_pct"][k]) <= 100 * rtol]  # NaN (a failed run) is missed


def disc_geometry(geometry):
    """The Brazilian disc (ISRM 50 x 25 mm) at the scale and with the genesis options of
    the UCS cylinder ``geometry``."""
    return _isrm_disc(scale=geometry.scale, sigma0_MPa=geometry.sigma0_MPa,
                      install_gap_mm=geometry.install_gap_mm,
                      relax_ratio=geometry.relax_ratio, genesis=geometry.genesis)


#: an invalid Brazilian test (its fracture did not start in the central zone) is no
#: measurement: the closed loop and the fresh-seed check run the disc again on the next
#: replacement seeds, seed + k x BTS_REPLACEMENT_STRIDE (k = 1, 2, ...), at most
#: BTS_MAX_REPLACEMENTS times, before σt of that seed counts as a failed measurement
BTS_REPLACEMENT_STRIDE = 100_000
BTS_MAX_REPLACEMENTS = 3


#: the runner of each per-sample test (``P.SAMPLE_TESTS``' tests), looked up in this
#: module at the call, so tests can replace it
_TEST_RUN = {"bts": "run_bts_file", "dtt": "run_dtt_file", "tri": "run_triaxial_file"}


def test_strength(resp: str, outcome) -> float:
    """The strength ``resp`` (``P.SAMPLE_TESTS``' responses: ``bts_MPa``, ``dtt_MPa``,
    ``tri_MPa``) of a finished run's outcome, NaN for a failed one: the summary key the
    dataset reads it from (``study.gather.TEST_COLUMNS``)."""
    from ..study.gather import TEST_COLUMNS

    keys = TEST_COLUMNS[SAMPLE_TESTS[resp]][0]
    key = next(k for k, col in keys.items() if col == resp)
    return float(outcome.summary[key]) if outcome.status == "ok" else math.nan


def valid_tensile_run(test: str, path_of, params: dict, seed: int, geometry, settings, *,
                      max_replacements: int = BTS_MAX_REPLACEMENTS, **kw):
    """A per-sample test (``test``: "bts", the Brazilian disc ``geometry``; "dtt", the
    direct-tension cylinder; "tri", the triaxial test at the design confinement, whose
    runs have no validity check) of ``params`` on packing ``seed`` that measures its
    strength: an invalid run (``<test>_valid`` false) is replaced by the specimen of the
    next replacement seed (``seed + k x BTS_REPLACEMENT_STRIDE``), up to
    ``max_replacements`` times; a failed run (instability, genesis) is not replaced (it is
    a failure, not a measurement of the wrong thing). ``path_of(seed, k)`` names the run
    file of attempt k. Returns (the outcome used, the packing seed it ran on, the reasons
    of the invalid attempts); the outcome has ``<test>_MPa`` NaN when every attempt was
    invalid."""
    run_file = globals()[_TEST_RUN[test]]
    invalid = []
    for k in range(max_replacements + 1):
        s = int(seed) + k * BTS_REPLACEMENT_STRIDE
        b = run_file(path_of(s, k), params, s, geometry, settings, **kw)
        if b.status != "ok" or b.summary.get(f"{test}_valid", True):
            return b, s, invalid
        invalid.append(f"seed {s}: {b.summary.get(f'{test}_invalid_reason', 'invalid')}")
    return b, s, invalid


#: the tensile tests (``P.SAMPLE_TESTS``) whose strength a seed may measure on several
#: specimens (``tensile_specimens``): specimen j of packing seed s is packed with
#: ``replicate_seed(s, j)`` = s + j x TENSILE_REPLICATE_STRIDE (j = 0: s itself, the UCS
#: test's packing). Its packing may move on twice: a replacement as above (+ m x
#: BTS_REPLACEMENT_STRIDE, m <= BTS_MAX_REPLACEMENTS) and, for a Brazilian disc, the
#: test's own ISRM retests (+ k x ``lab.brazilian.RETEST_SEED_STEP``, k <= 10). The stride
#: keeps every such packing seed of every seed below 100,000 apart from every other
#: (:func:`packing_seed_gap`: the smallest difference of two offsets is the replacement
#: stride, 100,000) and below 2**32. (It was 1,000,000: then a retest of seed s, s +
#: 1,000,003, was specimen 1 of seed s + 3, and two seeds shared that disc.)
TENSILE_TESTS = ("bts", "dtt")
TENSILE_REPLICATE_STRIDE = 20_000_003
MAX_TENSILE_SPECIMENS = 50
#: the degrees of freedom of the pooled specimen CV before the loop raises a seed's count
#: on it (:class:`_LoopRuns`): 3 seeds x 3 discs give 8, 3 seeds x 1 disc 2 (not enough)
MIN_SPECIMEN_DOF = 6


def replicate_seed(seed: int, j: int) -> int:
    """The packing seed of specimen ``j`` (0, 1, ...) of packing ``seed``'s tensile test."""
    return int(seed) + int(j) * TENSILE_REPLICATE_STRIDE


def packing_seed_gap(max_retests: int = 10) -> tuple[int, int]:
    """(the smallest nonzero difference between two offsets from a packing seed, the
    largest offset) over every tensile specimen j < MAX_TENSILE_SPECIMENS, replacement
    m <= BTS_MAX_REPLACEMENTS and ISRM retest k <= ``max_retests`` (the offset j x
    TENSILE_REPLICATE_STRIDE + m x BTS_REPLACEMENT_STRIDE + k x RETEST_SEED_STEP): two
    seeds closer than the gap never share a packing, and a seed below 2**32 minus the
    largest offset stays a valid packing seed."""
    from ..lab.brazilian import RETEST_SEED_STEP

    steps = (TENSILE_REPLICATE_STRIDE, BTS_REPLACEMENT_STRIDE, RETEST_SEED_STEP)
    reach = (MAX_TENSILE_SPECIMENS - 1, BTS_MAX_REPLACEMENTS, max_retests)
    gap = min(abs(a * steps[0] + b * steps[1] + c * steps[2])
              for a in range(-reach[0], reach[0] + 1) for b in range(-reach[1], reach[1] + 1)
              for c in range(-reach[2], reach[2] + 1) if (a, b, c) != (0, 0, 0))
    return gap, sum(r * s for r, s in zip(reach, steps))


def check_triaxial_seeds(n, flag: str = "--triaxial-seeds"):
    """The closed loop's triaxial seed cap: None (every seed) or an integer >= 2 (a
    standard error needs two), else BadInput naming the value."""
    if n is None:
        return None
    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        raise BadInput(f"{flag} {n!r}: expected an integer >= 2 (how many of the closed "
                       "loop's seeds run the triaxial test), or none for every seed")
    return n


def check_seed_cv(cv, flag: str = "--tensile-seed-cv"):
    """The σt seed CV a closed loop aims at (None: a fixed count of specimens), a number
    in (0, 1), else BadInput naming the value."""
    if cv is None:
        return None
    if isinstance(cv, bool) or not isinstance(cv, (int, float)) \
            or not (math.isfinite(cv) and 0 < cv < 1):
        raise BadInput(f"{flag} {cv!r}: expected a fraction in (0, 1) (the seed CV of σt "
                       "to aim at, e.g. 0.05), or none for a fixed count of specimens")
    return float(cv)


def check_tensile_specimens(n, flag: str = "--tensile-specimens") -> int:
    """``n`` as the number of tensile specimens per seed: an integer in 1 ..
    MAX_TENSILE_SPECIMENS, else BadInput naming ``flag`` and the value."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) \
            or not 1 <= int(n) <= MAX_TENSILE_SPECIMENS:
        raise BadInput(f"{flag} {n!r}: expected an integer in 1 .. {MAX_TENSILE_SPECIMENS} "
                       "(tensile specimens per packing seed)")
    return int(n)


@dataclass
class SpecimenRun:
    """One tensile specimen of a packing seed, measured (:func:`specimen_run`): its run's
    status, error and file (the attempt used), the packing seed that attempt ran on, the
    invalid attempts' reasons and the strength (NaN: failed, or no valid attempt)."""

    status: str
    error: str
    path: str | None
    seed: int
    invalid: list
    value: float


def specimen_run(resp: str, path_of, params: dict, seed: int, j: int, geometry, settings,
                 **kw) -> SpecimenRun:
    """Specimen ``j`` of packing ``seed``'s test of strength ``resp`` (packed with
    ``replicate_seed(seed, j)``; an invalid run replaced: :func:`valid_tensile_run`);
    ``path_of(j, s, k)`` names the run file of its attempt k on packing s."""
    b, s, bad = valid_tensile_run(SAMPLE_TESTS[resp], lambda s, k: path_of(j, s, k), params,
                                  replicate_seed(seed, j), geometry, settings, **kw)
    return SpecimenRun(b.status, b.error, None if b.path is None else str(b.path), int(s),
                       list(bad), test_strength(resp, b))


def combine_specimens(runs, n: int):
    """A seed's strength from its specimens' :class:`SpecimenRun` in order (those after a
    failed one are not counted: a seed with a failed specimen has no strength): (the first
    specimen's run, or the failed one's, the packing seed the first ran on, every invalid
    attempt's reason, the mean of the ``n`` specimens or NaN, the specimens' strengths)."""
    first, used, invalid, values = None, None, [], []
    for r in runs:
        invalid += r.invalid
        values.append(r.value)
        if first is None:
            first, used = r, r.seed
        if r.status != "ok":
            first = r  # a failed specimen: the seed has no σt; the others do not count
            break
    v = np.array(values, float)
    mean = float(v.mean()) if len(v) == n and np.isfinite(v).all() else math.nan
    return first, used, invalid, mean, values


def seed_strength(resp: str, path_of, params: dict, seed: int, geometry, settings, *,
                  specimens: int = 1, start: int = 0, **kw):
    """The strength ``resp`` (``P.SAMPLE_TESTS``) of packing ``seed``: with ``specimens``
    = 1 its test's (:func:`valid_tensile_run`); a tensile strength (σt: Brazilian or
    direct tension, ``TENSILE_TESTS``) with ``specimens`` = n > 1 the mean of n specimens,
    packed with ``replicate_seed(seed, j)``, j = 0 .. n-1, each valid or replaced as one
    test is, as a laboratory states σt as the mean of several specimens: the seed's σt
    then scatters sqrt(n) times less from packing to packing, at n tests' cost.
    ``path_of(j, s, k)`` names the run file of specimen j's attempt k on packing s. The
    mean is NaN when a specimen failed or had no valid test (a seed is measured on all n,
    or it has no σt). ``start`` = m > 0 runs specimens m .. n-1 only (a seed's count
    raised after its first m were measured: :class:`_LoopRuns`); the mean is then theirs.
    Returns (the first specimen's :class:`SpecimenRun`, or the failed one's, the packing
    seed the first ran on, the invalid attempts' reasons of every specimen, the seed's
    strength, the specimens' strengths). The specimens run one after the other here;
    :meth:`_LoopRuns._parts` and :mod:`.fresh_seeds` run them side by side and combine them
    alike
    (:func:`combine_specimens`)."""
    test = SAMPLE_TESTS[resp]
    if specimens > 1 and test not in TENSILE_TESTS:
        raise BadInput(f"tensile specimens {specimens}: only a tensile strength "
                       f"({', '.join(TENSILE_TESTS)}) is measured on several specimens, "
                       f"not {resp}")
    runs = []
    for j in range(start, specimens):
        runs.append(specimen_run(resp, path_of, params, seed, j, geometry, settings, **kw))
        if runs[-1].status != "ok":
            break  # a failed specimen: the seed has no σt; the others need not run
    return combine_specimens(runs, specimens - start)


def valid_bts_run(path_of, params: dict, seed: int, disc, settings, **kw):
    """:func:`valid_tensile_run` of the Brazilian test."""
    return valid_tensile_run("bts", path_of, params, seed, disc, settings, **kw)


def _dem_loop(c: dict, model_set, targets: dict, *, params: dict, run, seeds, geometry,
              settings, rtol, max_rounds, cache, threads, progress, genesis_max_steps,
              free=None, disc=None, bts_settings=None, bts_run=None, max_seeds=None,
              jacobian=None, range_margin=0.0, polish=True, cylinder=None,
              dtt_settings=None, tri_settings=None, jacobian_update="broyden",
              tensile_specimens=1, triaxial_seeds=None, tensile_seed_cv=None,
              max_tensile_specimens=None, grow_within=_LOOP_GROW):
    """The closed loop on ``seeds``, growing to ``max_seeds`` once every mean is within
    ``grow_within`` tolerances (every round runs each seed
    into a temporary file: the UCS test and, when σt is a target, the Brazilian test on
    ``disc`` (or the direct-tension test on ``cylinder``) with the same seed, and when
    ``tri_MPa`` is one, the triaxial test with ``tri_settings`` on the UCS cylinder; the
    first seed's run files of the best round become
    ``run`` and ``bts_run``). A round's seeds run side by side on up to ``threads``
    processes (:class:`SeedPool`); a seed's σt is the mean of ``tensile_specimens``
    specimens (:func:`seed_strength`), raised up to ``max_tensile_specimens`` for a card
    whose σt scatters too much for ``tensile_seed_cv`` (:class:`_LoopRuns`); with
    ``triaxial_seeds`` = m only a round's first m
    seeds run the triaxial test (:class:`ClosedLoop`'s ``seed_caps``). The first step
    follows the regression models' Jacobian, or ``jacobian`` (responses x free
    parameters, physical units) when given; the measured
    rounds correct it by ``jacobian_update`` (:class:`ClosedLoop`'s ``update``).
    Returns (ClosedLoopResult, per-round list of seed summaries, best round index, the
    tensile specimens per seed: :meth:`_LoopRuns.specimen_record`)."""
    ratio = c.get("ratio_ten_coh")
    with_bts = BTS in targets
    caps = {P.TRI: int(triaxial_seeds)} if triaxial_seeds and P.TRI in targets else {}
    runs = _LoopRuns(Path(run).parent / f".{Path(run).stem}.rounds", list(targets),
                     geometry=geometry, settings=settings, genesis_max_steps=genesis_max_steps,
                     specimens={"bts": (disc, bts_settings), "dtt": (cylinder, dtt_settings),
                                "tri": (geometry, tri_settings)},
                     cache=cache, threads=threads, progress=progress,
                     tensile_specimens=tensile_specimens, caps=caps, first_seed=int(seeds[0]),
                     seed_cv=tensile_seed_cv, max_specimens=max_tensile_specimens)
    ok = False
    try:
        free = free or [k for k, v in c["roles"].items() if v == "free"]
        jac = None if jacobian is None else pd.DataFrame.from_dict(jacobian, orient="index")
        if jac is not None and not (set(targets) <= set(jac.index) and set(free) <= set(jac.columns)
                                    and np.isfinite(jac.loc[list(targets), list(free)]
                                                    .to_numpy(float)).all()):
            jac = None  # learned for other targets or parameters: start from the models
        loop = ClosedLoop(runs.simulate, targets, free=free, ratio=ratio,
                          models=model_set if jac is None else None, jacobian=jac,
                          rtol=rtol, max_rounds=max_rounds, ranges=c["ranges"],
                          bounds=c.get("calibration_bounds") or None, seeds=list(seeds),
                          max_seeds=max_seeds, margin=range_margin, polish=polish,
                          target_se=c.get("target_se") or None,
                          update=jacobian_update, report=_notes(progress),
                          simulate_seeds=runs.simulate_seeds, seed_caps=caps or None,
                          grow_within=grow_within)
        res = loop.run(params)
        best = res.best_round  # converged, else the smallest max |error| of the seed mean
        os.replace(runs.paths[best][0], run)  # the best round's first seed is the run file
        if bts_run is not None and with_bts:
            os.replace(runs.bts_paths[best][0], bts_run)
        ok = True
    finally:
        runs.close(ok)
    return res, runs.by_round, best, runs.specimen_record()


class _LoopRuns:
    """The DEM runs of a closed loop (:func:`_dem_loop`): every round's seeds side by side
    on up to ``threads`` processes (:class:`SeedPool`), each finished run journaled in
    ``folder`` (:class:`RunJournal`: a loop stopped part way and started again with the
    same inputs reads the runs it had finished); per round the seeds' rows (``by_round``),
    UCS run files (``paths``) and Brazilian run files (``bts_paths``). ``caps``: target ->
    how many of the seed set's first seeds (from ``first_seed`` on) measure it; a seed
    past a target's cap does not run its test.

    With ``seed_cv`` (config ``verification.tensile_seed_cv``) and a σt target, the count
    of tensile specimens per seed adapts to the card: when a round starts, the specimen
    CV pooled over every specimen measured so far (:func:`pooled_cv`; at least
    ``MIN_SPECIMEN_DOF`` degrees of freedom) sets the count its seeds need
    (:func:`specimens_needed`: the chance of reading a seed CV above ``seed_cv`` over 5
    seeds below 10 %), never fewer than now nor more than ``max_specimens``. A raise
    tops up that round's seeds (specimens m .. n-1 only, journaled like a run) and holds
    for every later round and seed, so a round's seeds are all measured alike."""

    def __init__(self, folder: Path, targets: list, *, geometry, settings, specimens: dict,
                 genesis_max_steps, cache, threads, progress, tensile_specimens=1,
                 caps=None, first_seed=1, seed_cv=None, max_specimens=None):
        self.journal = RunJournal(folder)
        self.inputs = dict(targets=targets, geometry=geometry, settings=settings,
                           specimens=specimens, genesis_max_steps=genesis_max_steps,
                           tensile_specimens=tensile_specimens)
        self.cache, self.progress = cache, progress
        self.pool = SeedPool(threads, progress)
        self.by_round: list[list[dict]] = []
        self.paths: list[list[Path]] = []
        self.bts_paths: list[list[Path]] = []
        self._last: dict | None = None
        self.caps, self.first_seed = dict(caps or {}), int(first_seed)
        self.tensile = next((r for r in targets if SAMPLE_TESTS.get(r) in TENSILE_TESTS), None)
        self.seed_cv = seed_cv if self.tensile is not None else None
        self.max_specimens = max(int(max_specimens or tensile_specimens), tensile_specimens)
        self.start_specimens = int(tensile_specimens)
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
        keys = [RunJournal.key(**job) for job in jobs]
        done = {i: self.journal.get(key) for i, key in enumerate(keys)}
        todo = [i for i, rec in done.items() if rec is None]

        def finished(j, res):
            rec, files = res
            done[todo[j]] = self.journal.add(keys[todo[j]], rec, files)

        self.pool.map(fn, [dict(jobs[i], cache=self.cache, stem=self.journal.stem(keys[i]))
                           for i in todo], tags=[tags[i] for i in todo], done=finished)
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
        """The journal records of :func:`_loop_seed` for the seed ``jobs``, their tests
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


def _loop_seed(*, params: dict, seed: int, stem: Path, targets: list, geometry, settings,
               specimens: dict, cache, genesis_max_steps, threads, progress,
               tensile_specimens: int = 1):
    """One seed of a closed-loop round (:func:`_dem_loop`; run in a :class:`SeedPool`
    worker or in this process): the UCS test into ``<stem>.h5`` and every per-sample test
    of the ``targets`` (``specimens``: test -> (specimen, settings)), an invalid one
    replaced, σt the mean of ``tensile_specimens`` specimens (:func:`seed_strength`).
    Returns (its journal record: the seed's row, its responses, the names of the UCS run
    file and of the Brazilian one or None; every run file it wrote)."""
    kw = dict(cache=cache, threads=threads, progress=progress,
              genesis_max_steps=genesis_max_steps)
    res = run_ucs_file(Path(f"{stem}.h5"), params, seed, geometry, settings, **kw)
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
# beside whatever it runs, and a seed's row is put together from its runs as _loop_seed
# puts it together from the same runs one after the other (combine_specimens). The one
# difference: a specimen after a failed one (a failure, not an invalid test) runs, and is
# not counted, where the runs one after the other stop at the failure.


def specimens_of(resp: str, tensile_specimens: int) -> int:
    """How many specimens measure ``resp`` on a seed (a tensile test's count; one else)."""
    return tensile_specimens if SAMPLE_TESTS[resp] in TENSILE_TESTS else 1


def seed_parts(job: dict, first_specimen: int = 0) -> list[dict]:
    """The pool jobs of one loop seed's ``job`` (:func:`_loop_seed`'s
    arguments but the folder and the pool's): its UCS test (none with
    ``first_specimen`` > 0: a top-up of its tensile specimens) and every specimen j of each
    per-sample test of its targets (from ``first_specimen`` on)."""
    base = {k: job[k] for k in ("params", "seed", "geometry", "settings", "genesis_max_steps")}
    parts = [] if first_specimen else [dict(base, part="ucs")]
    for resp in (r for r in SAMPLE_TESTS if r in job["targets"]):  # σt, σ1
        geo, st = job["specimens"][SAMPLE_TESTS[resp]]
        n = specimens_of(resp, job.get("tensile_specimens", 1))
        parts += [dict(base, part=resp, j=j, geometry=geo, settings=st)
                  for j in range(first_specimen, n)]
    return parts


def longest_first(parts: list[dict]) -> list[int]:
    """The order to run ``parts`` in: the UCS tests, then the specimens by index (each
    seed's first specimens before any seed's later ones)."""
    return sorted(range(len(parts)), key=lambda i: (parts[i]["part"] != "ucs",
                                                     parts[i].get("j", 0)))


def run_part(*, part: str, params: dict, seed: int, geometry, settings, stem: Path, cache,
             genesis_max_steps, threads, progress, j: int = 0):
    """One pool job of :func:`seed_parts`: the UCS test into ``<stem>.h5``, or specimen
    ``j`` of the test of strength ``part`` into ``<stem>.<test><k>[.r<j>].h5``
    (:func:`specimen_path`). Returns (its record: JSON-able, every run file
    it wrote)."""
    kw = dict(cache=cache, threads=threads, progress=progress,
              genesis_max_steps=genesis_max_steps)
    if part == "ucs":
        res = run_ucs_file(Path(f"{stem}.h5"), params, seed, geometry, settings, **kw)
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
    -> the records of its specimens in order), as :func:`_loop_seed` gives
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
    invalid attempts, the status: :meth:`_LoopRuns._adapt` reads it) from
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


def specimen_text(values) -> str:
    """A seed row's ``<test>_specimen_MPa``: each specimen's strength, ``;``-separated
    (:func:`specimen_values` reads it back)."""
    return ";".join(f"{v:.6g}" for v in values)


def specimen_values(row: dict, resp: str, test: str) -> list[float]:
    """The strengths of a seed row's tensile specimens (``<test>_specimen_MPa``, or the
    seed's one value ``row[resp]``)."""
    text = row.get(f"{test}_specimen_MPa")
    if isinstance(text, str) and text:
        return [float(v) for v in text.split(";")]
    return [float(row.get(resp, math.nan))]


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


def row_strength(row: dict, resp: str, path_of, params: dict, seed: int, geometry, settings,
                 *, tensile_specimens: int = 1, **kw):
    """:func:`seed_strength` of ``resp`` into a seed's ``row`` (the closed loop's and the
    fresh-seed check's): the strength, the packing seed used (``<test>_seed``), the count
    of invalid attempts (``<test>_invalid``) and, when σt is measured on
    ``tensile_specimens`` > 1 specimens (a tensile test's count; any other test has one),
    how many ran and each one's strength (``<test>_specimens``, ``<test>_specimen_MPa``:
    ``;``-separated, MPa; NaN: failed or no valid test). Returns (the outcome
    :func:`seed_strength` returns, the invalid attempts' reasons)."""
    test = SAMPLE_TESTS[resp]
    n = tensile_specimens if test in TENSILE_TESTS else 1
    b, used, invalid, row[resp], values = seed_strength(resp, path_of, params, seed, geometry,
                                                        settings, specimens=n, **kw)
    row[f"{test}_seed"], row[f"{test}_invalid"] = used, len(invalid)
    if n > 1:
        row[f"{test}_specimens"] = len(values)
        row[f"{test}_specimen_MPa"] = specimen_text(values)
    return b, invalid


# long: the stage's reference docstring (54 lines, the card's verification section); the code is ~60 lines
def verify(card, models, *, out_card, rounds, run, geometry, settings, seed=1,
           seeds_per_round=3, rtol=_LOOP["rtol"], max_rounds=_LOOP["max_rounds"], cache=None,
           threads=None, free=None, progress=None, from_unreachable=False, max_balls=None,
           mem_budget_mb=None, genesis_max_steps=None, bts_geometry=None, bts_settings=None,
           bts_run=None, max_seeds=10, range_margin=0.25, polish=True, dtt_geometry=None,
           dtt_settings=None, tri_settings=None, jacobian_update="broyden",
           tensile_specimens=3, triaxial_seeds=None, tensile_seed_cv=None,
           max_tensile_specimens=None, grow_within=_LOOP_GROW, seed_runs=None) -> dict:
    """Closed-loop verification of one material card: round 1 is the paper's single pass
    (the regression's answer), later rounds correct the free parameters with a
    Newton-Broyden step until every response is within the tolerance of the lab value,
    or ``max_rounds`` rounds are used up (``"auto"``: two per free parameter,
    :func:`~bpmcal.params.auto_rounds`; the card records the
    budget). Every round runs the candidate on
    ``seeds_per_round`` packing seeds (``seed``, ``seed + 1``, ...) and steers their mean;
    a target is met when the mean lies within max(``rtol``, 2 standard errors of the
    mean) of it (:class:`~bpmcal.analysis.ClosedLoop`), so the loop fits the rock, not
    one packing. A round costs ``seeds_per_round`` DEM runs, side by side on up to
    ``threads`` processes (:mod:`bpmcal.stages.pool`; the card does not depend on how
    many). The seed set grows to
    ``max_seeds`` seeds (``seed + seeds_per_round``, ...; at most ``seeds_per_round``:
    no growth) once every mean is within ``grow_within`` tolerances (config
    ``verification.grow_within``; the card records it) but their standard errors are too
    large to state them to ``rtol``, so the card is judged, and steered, on the mean of
    more packings (a fixed few packings' mean is itself off the rock's by ~CV/sqrt(k));
    later rounds run the grown set.

    Writes the verified card (``out_card``; per round shown, the seed mean of every
    response, its seed standard deviation ``seed_sd`` and coefficient of variation
    ``seed_cv``, and ``n_seeds``), the rounds table (``rounds``: parameters, seed means,
    seed CVs, standard errors, tolerances, errors and step of every round) and ``run``,
    the run file of the best round's first seed (each run goes to a temporary file; any
    run can be redone with ``bpmcal ucs --params ... --seed``, the runs being
    deterministic); ``seed_runs`` (optional) the table of every seed run of every round
    (:func:`seed_runs_table`: round, seed, parameters, responses; the posterior's runs near
    the card). The loop stays inside the card's bounds (its design ``ranges``,
    narrowed by its ``calibration_bounds``), each design range widened by
    ``range_margin`` of its width (config ``verification.range_margin``; never past a
    ``calibration_bounds`` narrowing or the parameter's physical domain): the regression
    only starts the loop, every round measures the DEM, so the loop may follow a target
    just outside the sampled space. The card records the bounds searched
    (``verification.loop_bounds``) and every parameter that ended outside its design range
    (``verification.outside_design``: value and range; the message says so too). The card
    records ``calibrated_at_scale``, the specimen scale the loop ran at. With ``polish``
    (config ``verification.polish``) a loop that converges with some mean more than one
    standard error from its target takes one more full Newton step towards the targets on
    the same seeds, if a round is left; that round is the card's when it is within
    tolerance too (:class:`~bpmcal.analysis.ClosedLoop`). ``jacobian_update`` (config
    ``verification.jacobian_update``) is how the measured rounds correct the loop's
    Jacobian: ``broyden`` (the secant between consecutive rounds) or ``history`` (a local
    linear fit to every round, the regression's Jacobian its prior); the card records it.

    A card whose inversion is ``unreachable`` is not a calibration: unless
    ``from_unreachable`` (config ``verification.from_unreachable``) the DEM is not run, the
    verified card says so (``verification.status: not-run`` with the reason and what to
    widen), ``rounds`` has its header only and ``run`` is a failure record ("not run: ...").
    Returns the verified card.

    Every target of the card is verified: a card with a tensile-strength target
    (``bts_MPa``) runs, in every round, a Brazilian test beside the UCS test (the same
    packing seed; the disc ``bts_geometry``, default the ISRM disc at the cylinder's scale
    and genesis options, :func:`disc_geometry`; loading ``bts_settings``, default
    ``BTSSettings()``), and the loop steers σt with the other responses; ``bts_run``
    (optional) receives the best round's Brazilian run file (a failure record when the
    card has no σt target). A card with a direct-tension target (``dtt_MPa``) runs the
    direct-tension test instead, on the cylinder ``dtt_geometry`` (default the UCS
    cylinder) with ``dtt_settings``. An invalid tensile test (its fracture at a contact
    or a grip) is no measurement: that seed's test is run again on replacement seeds
    (:func:`valid_tensile_run`), and the round fails only when none is valid. With
    ``tensile_specimens`` = n > 1 (config ``verification.tensile_specimens``) a seed's σt
    is the mean of n specimens (:func:`seed_strength`; the card records n, and the
    transfer and the fresh-seed check measure σt the same way). With ``tensile_seed_cv``
    (config ``verification.tensile_seed_cv``) that n is where the loop starts: a card
    whose specimens scatter more than n of them can average to that seed CV gets more,
    up to ``max_tensile_specimens`` (:class:`_LoopRuns`); the card records the count its
    last rounds used, the specimen CV, the seed CV expected and every raise
    (``verification.tensile``). A card with
    a triaxial-strength target (``tri_MPa``, σ1 at the study's design confinement) runs
    the triaxial test of ``tri_settings`` (its ``sigma3``) on the UCS cylinder in every
    round (required then: BadInput without it); with ``triaxial_seeds`` = m (config
    ``verification.triaxial_seeds``; default: every seed) only the first m seeds of the
    set run it, so a grown set judges the cheap targets on more packings than the costly
    triaxial one (the card records m). The verified
    card lists every target the best round misses by more than ``rtol``
    (``verification.missed``: target, lab value, DEM value, error in %); it is empty only
    when all are met."""
    c = read_card(card, "--card", need=("parameters", "targets", "roles"))
    if "ranges" not in c:
        raise P.ParameterError(f"--card {card}: the card has no 'ranges' (the design space); "
                               "rerun the calibrate step")
    if isinstance(seeds_per_round, bool) or not isinstance(seeds_per_round, int) \
            or seeds_per_round < 1:
        raise BadInput(f"--seeds-per-round {seeds_per_round!r}: expected an integer >= 1")
    model_set = read_models(models)
    targets = {k: float(v) for k, v in c["targets"].items()}
    disc = bts_geometry or disc_geometry(geometry)
    bts_settings = bts_settings or BTSSettings()
    cylinder = dtt_geometry or geometry
    dtt_settings = dtt_settings or DTTSettings()
    _check_verify_inputs(card, models, c, model_set, targets, geometry, disc, cylinder,
                         max_balls=max_balls, mem_budget_mb=mem_budget_mb,
                         tri_settings=tri_settings)
    outputs((out_card, "--out-card", YAML), (rounds, "--rounds", CSV), (run, "--run", H5),
            (bts_run, "--bts-run", H5), (seed_runs, "--seed-runs", CSV))
    output_dirs((cache, "--specimen-cache"))
    if isinstance(max_seeds, bool) or not isinstance(max_seeds, int) or max_seeds < 1:
        raise BadInput(f"--max-seeds {max_seeds!r}: expected an integer >= 1")
    max_seeds = max(max_seeds, seeds_per_round)
    range_margin = _check_margin(range_margin)
    jacobian_update = _check_update(jacobian_update)
    _check_rounds(max_rounds)
    grow_within = _check_grow(grow_within)
    tensile_specimens = check_tensile_specimens(tensile_specimens)
    tensile_seed_cv = check_seed_cv(tensile_seed_cv)
    max_tensile_specimens = check_tensile_specimens(  # never below the start: _LoopRuns
        max_tensile_specimens or tensile_specimens, "--max-tensile-specimens")
    triaxial_seeds = check_triaxial_seeds(triaxial_seeds)
    seeds = [int(seed) + i for i in range(seeds_per_round)]
    if c.get("status") == "unreachable" and not from_unreachable:
        reason = ("the calibration is unreachable, so the closed loop did not start from it "
                  "(verification.from_unreachable: false); " + str(c.get("message", "")))
        section = {
            "status": "not-run", "message": reason, "rounds": 0, "rtol": rtol, "seed": seed,
            "seeds": seeds, "n_seeds": seeds_per_round, "max_seeds": max_seeds,
            "best_round": None, "single_pass": None, "closed_loop": None, "parameters": None,
            "widen": c.get("widen", []), "geometry": geometry.to_dict()}
        if seed_runs is not None:
            write_table(seed_runs_table([]), seed_runs, index=False)
        return _not_run(c, out_card, "verification", section, rounds=rounds, run=run,
                        error=f"not run: {reason}", params=c["parameters"], seed=seed,
                        geometry=geometry, settings=settings, bts_run=bts_run, disc=disc,
                        bts_settings=bts_settings)
    res, by_round, best, tensile = _dem_loop(
        c, model_set, targets, params=c["parameters"], run=run, seeds=seeds,
        geometry=geometry, settings=settings, rtol=rtol, max_rounds=max_rounds, cache=cache,
        threads=threads, progress=progress, genesis_max_steps=genesis_max_steps, free=free,
        disc=disc, bts_settings=bts_settings, bts_run=bts_run, max_seeds=max_seeds,
        range_margin=range_margin, polish=bool(polish), cylinder=cylinder,
        dtt_settings=dtt_settings, tri_settings=tri_settings, jacobian_update=jacobian_update,
        tensile_specimens=tensile_specimens, triaxial_seeds=triaxial_seeds,
        tensile_seed_cv=tensile_seed_cv, max_tensile_specimens=max_tensile_specimens,
        grow_within=grow_within)
    write_table(res.history, rounds, index=False)
    if seed_runs is not None:
        write_table(seed_runs_table(by_round), seed_runs, index=False)
    verified = dict(c)
    verified.update({
        "calibrated_at_scale": float(geometry.scale),
        "verification": _verification_section(
            c, res, by_round, best, targets, rtol=rtol, seed=seed, seeds=seeds,
            seeds_per_round=seeds_per_round, max_seeds=max_seeds, polish=polish,
            geometry=geometry, range_margin=range_margin, disc=disc, cylinder=cylinder,
            tri_settings=tri_settings, jacobian_update=jacobian_update,
            tensile=tensile, triaxial_seeds=triaxial_seeds, grow_within=grow_within)})
    write_card(out_card, verified)
    if bts_run is not None and BTS not in targets:
        write_failure(bts_run, test="bts", inputs=bts_inputs(c["parameters"], seed, disc,
                                                             bts_settings),
                      error="not run: the card has no tensile-strength target (bts_MPa)")
    return verified


def _check_verify_inputs(card, models, c: dict, model_set, targets: dict, geometry, disc, cylinder, *,
                         max_balls, mem_budget_mb, tri_settings=None) -> None:
    """The checks :func:`verify` makes before any output: a model of every tensile and
    triaxial target, the triaxial test's settings for a ``tri_MPa`` target, a Brazilian
    disc 3 of the largest balls across, and every specimen within the budget."""
    with_bts = BTS in targets
    with_dtt = "dtt_MPa" in targets
    check_tri_target(card, targets, tri_settings, model_set, models)
    if with_dtt and "dtt_MPa" not in model_set:
        raise BadInput(f"--card {card}: a direct-tension target (dtt_MPa) but --models "
                       f"{models} has no model of dtt_MPa")
    if with_bts and BTS not in model_set:
        raise BadInput(f"--card {card}: a tensile-strength target (bts_MPa) but --models "
                       f"{models} has no model of bts_MPa")
    if with_bts:  # the disc must hold 3 of the largest balls across, for every round
        rmin = (max(c["ranges"][P.RMIN]) if c["roles"].get(P.RMIN) == "free"
                else float(c["parameters"][P.RMIN]))
        rmax = P.RADIUS_RATIO * rmin
        dd, tt = disc.diameter_mm * disc.scale, disc.height_mm * disc.scale
        if min(dd, tt) < 6 * rmax:
            raise BadInput(f"--card {card}: a tensile-strength target (bts_MPa), but the "
                           f"Brazilian disc at scale {disc.scale:g} ({dd:g} x {tt:g} mm) is "
                           f"less than 3 ball diameters across for Rmax = {rmax:g} mm: use "
                           "a larger --scale")
    if max_balls is not None:
        check_budget(c["parameters"], geometry, max_balls=max_balls,
                     mem_budget_mb=mem_budget_mb)
        if with_bts:
            check_budget(c["parameters"], disc, max_balls=max_balls,
                         mem_budget_mb=mem_budget_mb)
        if with_dtt:
            check_budget(c["parameters"], cylinder, max_balls=max_balls,
                         mem_budget_mb=mem_budget_mb)


def _not_run(c: dict, out_card, key: str, section: dict, *, rounds, run, error: str, params: dict,
             seed, geometry, settings, bts_run=None, disc=None, bts_settings=None) -> dict:
    """A stage whose closed loop does not run (:func:`verify` from an unreachable card,
    :mod:`.transfer` from a card whose loop did not run): the rounds table with its header
    only, failure records (``error``) for the run files, and the card with its ``key``
    section; returns the card."""
    write_table(pd.DataFrame(columns=["round"]), rounds, index=False)
    write_failure(run, test="ucs", inputs=ucs_inputs(params, seed, geometry, settings), error=error)
    if bts_run is not None:
        write_failure(bts_run, test="bts", inputs=bts_inputs(params, seed, disc, bts_settings),
                      error=error)
    out = dict(c)
    out[key] = section
    write_card(out_card, out)
    return out


def _verification_section(c: dict, res, by_round: list, best: int, targets: dict, *, rtol, seed, seeds,
                          seeds_per_round, max_seeds, polish, geometry, range_margin, disc,
                          cylinder, tri_settings=None, jacobian_update="broyden",
                          tensile=None, triaxial_seeds=None, grow_within=_LOOP_GROW) -> dict:
    """The verified card's ``verification`` section from the closed loop's result ``res``
    and its rounds' seed summaries ``by_round`` (``best``: the card's round; ``tensile``:
    :meth:`_LoopRuns.specimen_record`)."""
    message = res.message + _outside_text(res.outside, range_margin)
    if c.get("status") == "unreachable":
        message = ("started from an unreachable calibration at the user's request "
                   f"(verification.from_unreachable: true): {message}")
    v = {
        "status": res.status, "message": message, "rounds": len(by_round),
        "runs": sum(len(r) for r in by_round), "rtol": rtol, "seed": seed,
        "seeds": [int(x) for x in res.seeds], "n_seeds": int(res.n_seeds),
        "seeds_per_round": seeds_per_round, "max_seeds": max_seeds, "polish": bool(polish),
        "grow_within": float(grow_within), "jacobian_update": jacobian_update,
        "max_rounds": int(res.max_rounds),
        "best_round": best + 1, "run_seed": seeds[0],
        "jacobian": {r: {p: float(x) for p, x in row.items()}
                     for r, row in res.jacobian.iterrows()},
        "single_pass": _responses(by_round[0], targets),
        "closed_loop": _responses(by_round[best], targets),
        "parameters": {k: float(v) for k, v in res.params.items() if k in P.ALL_PARAMS},
        "geometry": geometry.to_dict(), **_loop_box(res, range_margin),
    }
    v["missed"] = _missed(v["closed_loop"], targets, rtol)
    if res.sign_held:  # the regression's slopes the loop did not start from
        v["jacobian_sign_held"] = [dict(h) for h in res.sign_held]
    if BTS in targets:
        v["bts_geometry"] = disc.to_dict()
    if "dtt_MPa" in targets:
        v["dtt_geometry"] = cylinder.to_dict()
    tensile = tensile or {"count": 1}
    if tensile["count"] > 1:  # σt of a seed: the mean of this many specimens
        v["tensile_specimens"] = int(tensile["count"])
    if "seed_cv_target" in tensile:  # the count adapted to the card's specimen scatter
        v["tensile"] = {k: x for k, x in tensile.items() if k != "count"}
        if tensile.get("chance_above", 0) >= MISS_ACCEPTED:
            why = ("the most verification.max_tensile_specimens allows"
                   if tensile["count"] >= tensile["max"] else
                   "the count set when the last round started, on fewer specimens")
            v["message"] += (
                f"; σt seed CV expected {100 * tensile['seed_cv_expected']:.1f} % at "
                f"{tensile['count']} tensile specimens per seed ({why}): "
                + _shortfall(tensile))
    if P.TRI in targets:
        v["tri_sigma3_MPa"] = tri_settings.sigma3 / 1e6
        if triaxial_seeds and triaxial_seeds < max_seeds:  # σ1 judged on the first m seeds
            v["triaxial_seeds"] = int(triaxial_seeds)
    return v


def check_tri_target(card, targets: dict, tri_settings, model_set=None, models=None) -> None:
    """A card with a triaxial-strength target (``tri_MPa``: σ1 at the study's design
    confinement) needs the triaxial test's settings (``--design-sigma3``) and, for the
    loop's first step, a regression model of ``tri_MPa``: BadInput naming what is
    missing."""
    if P.TRI not in targets:
        return
    if tri_settings is None:
        raise BadInput(f"--card {card}: a triaxial-strength target (tri_MPa = "
                       f"{targets[P.TRI]:g} MPa) needs --design-sigma3 MPA, the design "
                       "confinement that lab value was measured at "
                       "(triaxial.design_sigma3_MPa)")
    if model_set is not None and P.TRI not in model_set:
        raise BadInput(f"--card {card}: a triaxial-strength target (tri_MPa) but --models "
                       f"{models} has no model of tri_MPa")


def _notes(progress):
    """A line reporter that passes each line to ``progress`` as a note (None: none)."""
    return None if progress is None else (lambda line: progress({"note": line}))


def _loop_option(option: str, check, value):
    """``check(value)`` (a closed-loop check), its ValueError as BadInput naming ``option``."""
    try:
        return check(value)
    except ValueError as e:
        raise BadInput(f"{option}: {e}") from None


def _check_rounds(max_rounds) -> None:
    """BadInput naming ``max_rounds`` unless the closed loop takes it."""
    _loop_option("--max-rounds", check_max_rounds, max_rounds)


def _check_grow(grow_within) -> float:
    """BadInput naming ``grow_within`` unless the closed loop takes it; the factor."""
    return _loop_option("--grow-within", check_grow_within, grow_within)


def _check_update(rule) -> str:
    """The closed loop's Jacobian update rule, or BadInput naming the bad value."""
    if rule not in UPDATES:
        raise BadInput(f"--jacobian-update {rule!r}: expected one of {', '.join(UPDATES)}")
    return rule


def _check_margin(margin) -> float:
    if isinstance(margin, bool) or not isinstance(margin, (int, float)) \
            or not (math.isfinite(margin) and 0 <= margin <= 1):
        raise BadInput(f"--range-margin {margin!r}: expected a fraction of a range's width "
                       "in [0, 1]")
    return float(margin)


def _loop_box(res, margin: float) -> dict:
    """The card's record of the closed loop's bounds and what ended outside the design."""
    return {"range_margin": margin,
            "loop_bounds": {p: [float(a), float(b)] for p, (a, b) in res.loop_bounds.items()},
            "outside_design": {p: dict(v) for p, v in res.outside.items()}}


def _outside_items(outside: dict) -> str:
    """``pb_kratio 5.58 outside its range 1-5; ...`` for a card's ``outside_design``."""
    return "; ".join(f"{p} {v['value']:.3g} outside its range {v['range'][0]:g}-{v['range'][1]:g}"
                     for p, v in outside.items())


def _outside_text(outside: dict, margin: float) -> str:
    if not outside:
        return ""
    return (f"; outside the design space (range margin {margin:g}): {_outside_items(outside)}"
            " - the DEM was run there, the regression never sampled it")


def seed_scatter(card, *, runs, seeds, seed_runs, table, geometry, settings, rtol=_LOOP["rtol"],
                 cache=None, threads=None, max_balls=None, mem_budget_mb=None,
                 genesis_max_steps=None) -> pd.DataFrame:
    """One parameter set (a card's: :func:`card_parameters`, i.e. the closed loop's of a
    verified card, the transfer's of a transferred one), several packing seeds
    (``runs[i]`` is the run file of ``seeds[i]``): the scatter of the DEM responses
    (``seed_runs``: one row per seed; ``table``: coefficient of variation and noise floor
    per response), and whether the closed-loop tolerance is below it. The seeds run side
    by side on up to ``threads`` processes (:class:`SeedPool`)."""
    c = read_card(card, "--card", need=("parameters", "specimen"))
    params = card_parameters(c)
    if len(runs) != len(seeds):
        raise BadInput(f"--runs: {len(runs)} run file(s) for {len(seeds)} seed(s); expected "
                       "one per seed, in the order of --seeds")
    if max_balls is not None:
        check_budget(params, geometry, max_balls=max_balls, mem_budget_mb=mem_budget_mb)
    outputs(*((r, "--runs", H5) for r in runs), (seed_runs, "--seed-runs", CSV),
            (table, "--table", CSV))
    output_dirs((cache, "--specimen-cache"))
    with SeedPool(threads) as pool:  # the seeds side by side on `threads` CPUs
        rows = pool.map(_scatter_seed, [dict(params=params, seed=int(s), run=f,
                                             geometry=geometry, settings=settings, cache=cache,
                                             genesis_max_steps=genesis_max_steps)
                                        for s, f in zip(seeds, runs)],
                        tags=[f"seed {s}" for s in seeds])
    done = pd.DataFrame(rows)
    write_table(done, seed_runs, index=False)
    sc = scatter_table(done[done["status"] == "ok"], rtol=rtol)
    sc.insert(0, "specimen", c["specimen"])
    write_table(sc, table)
    return sc


def _scatter_seed(*, params: dict, seed: int, run, geometry, settings, cache,
                  genesis_max_steps, threads, progress) -> dict:
    """One seed of :func:`seed_scatter` (a :class:`SeedPool` job): its UCS test into
    ``run``; returns the seed's row."""
    out = run_ucs_file(run, params, seed, geometry, settings, cache=cache, threads=threads,
                       progress=progress, keep_particles=False,
                       genesis_max_steps=genesis_max_steps)
    r = dict(out.summary, status=out.status)
    return {"seed": seed, "status": r["status"],
            **{k: r.get(k, math.nan) for k in (*P.TARGETS, "u_pre_MJm3")}}


def tensile_note(v: dict) -> str:
    """What a card's ``verification.tensile`` says of its tensile specimens per seed when
    the loop raised their count or could not reach the seed CV it aims at ("" else)."""
    t = v.get("tensile") or {}
    if not t.get("raised") and t.get("chance_above", 0) < MISS_ACCEPTED:
        return ""
    n = int(v.get("tensile_specimens", 1))
    text = f"σt of a seed: the mean of {n} specimens"
    if t.get("raised"):
        r = t["raised"][0]
        text += f" (from round {r['round']}; {r['from']} before)"
    if "specimen_cv" in t:
        text += (f"; the specimens scatter {100 * t['specimen_cv']:.1f} % ({t['dof']} degrees "
                 f"of freedom), a seed's σt {100 * t['seed_cv_expected']:.1f} % expected")
    if t.get("chance_above", 0) >= MISS_ACCEPTED:
        text += ("; " + _shortfall(t) + (" (the count is verification.max_tensile_specimens)"
                                         if n >= t.get("max", n) else ""))
    return text


def _shortfall(t: dict) -> str:
    """How often 5 seeds read σt's seed CV above the target (``verification.tensile``)."""
    return (f"5 seeds read it above the {100 * t['seed_cv_target']:g} % aimed at "
            f"{100 * t['chance_above']:.0f} % of the time")


def verification_tables(cards, runs, lab, *, table5, table6, figure) -> dict:
    """Tables 5 and 6 and Fig. 6 from the verified cards and their best rounds' run files
    (``runs[i]`` belongs to ``cards[i]``). Table 5 holds the seed mean of every response
    (single pass and closed loop), its seed standard deviation (``_sd``) and CV
    (``_cv_pct``), the error of the mean and ``n_seeds``. A card whose closed loop did not run
    (``not-run``) keeps its row, with empty responses, status ``not-run`` and the reason in
    ``note``; its Fig. 6 panel says why it has no curve. When some card has a tensile
    strength target, Table 5 also has the σt columns (empty for the specimens without
    one), ``missed``: every target the closed loop misses by more than its tolerance,
    with the error in %, ``tensile_specimens`` (per seed) and ``tensile_note``
    (:func:`tensile_note`)."""
    if len(runs) != len(cards):
        raise BadInput(f"--runs: {len(runs)} run file(s) for {len(cards)} card(s); expected "
                       "one per card, in the same order")
    loaded = [read_card(c, "--cards", need=("specimen", "parameters", "targets",
                                            "verification", "lab")) for c in cards]
    lab_df = read_lab(lab)
    outputs((table5, "--table5", CSV), (table6, "--table6", CSV), (figure, "--figure", PNG))
    t5, t6, curves = [], [], {}
    tensile = [r for r in SAMPLE_TESTS if any(r in c["targets"] for c in loaded)]
    for c, run in zip(loaded, runs):
        spec = str(c["specimen"])
        v = c["verification"]
        row = {"specimen": spec}
        ran = v["status"] != "not-run"
        for which in ("single_pass", "closed_loop"):
            r = v[which] if ran else None
            for k in P.TARGETS:
                row[f"{which}_{k}"] = r[k] if ran else math.nan
                sd = (r.get("seed_sd") or {}).get(k) if ran else None
                cv = (r.get("seed_cv") or {}).get(k) if ran else None  # None: one seed (NaN)
                row[f"{which}_{k}_sd"] = math.nan if sd is None else float(sd)
                row[f"{which}_{k}_cv_pct"] = math.nan if cv is None else 100 * float(cv)
                row[f"{which}_{k}_err_pct"] = r["errors_pct"][k] if ran else math.nan
        for k in P.TARGETS:
            row[f"lab_{k}"] = c["targets"][k]
        row["n_seeds"] = v.get("n_seeds", 1)
        row["rounds"] = v["rounds"]
        row["status"] = v["status"]
        row["calibration_status"] = c.get("status")
        row["note"] = v["message"] if not ran else _outside_items(v.get("outside_design") or {})
        for resp in tensile:
            has = resp in c["targets"]
            for which in ("single_pass", "closed_loop"):
                row[f"{which}_{resp}"] = v[which][resp] if ran and has else math.nan
                row[f"{which}_{resp}_err_pct"] = (v[which]["errors_pct"][resp] if ran and has
                                                  else math.nan)
                cv = (v[which].get("seed_cv") or {}).get(resp) if ran and has else None
                row[f"{which}_{resp}_cv_pct"] = math.nan if cv is None else 100 * float(cv)
            row[f"lab_{resp}"] = c["targets"][resp] if has else math.nan
        if tensile:
            row["missed"] = "; ".join(f"{m['target']} {m['error_pct']:+.2f} %"
                                      for m in v.get("missed") or [])
            row["tensile_specimens"] = int(v.get("tensile_specimens", 1))
            row["tensile_note"] = tensile_note(v)
        t5.append(row)
        up_lab = c["lab"].get("u_pre_MJm3")
        up_sim = v["closed_loop"]["u_pre_MJm3"] if ran else math.nan
        t6.append({"specimen": spec, "sim_Up_MJm3": up_sim, "lab_Up_MJm3": up_lab,
                   "rel_error_pct": (100 * abs(up_sim - up_lab) / up_lab
                                     if up_lab and ran else math.nan),
                   "sim_peak_strain": v["closed_loop"]["peak_strain"] if ran else math.nan})
        curves[spec] = read_series(run) if ran else f"not run: {c.get('status')} calibration"
    t5 = pd.DataFrame(t5).set_index("specimen")
    t6 = pd.DataFrame(t6).set_index("specimen")
    write_table(t5, table5)
    write_table(t6, table6)
    save_figure(fig_stress_strain(curves, lab_df), figure)
    return {"table5": t5, "table6": t6}
