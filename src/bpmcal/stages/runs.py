"""DEM run files: one virtual lab test (``bpmcal.lab.runner``) written to one HDF5 file
(``bpmcal.io.h5``), or its failure record.

``run_test_file`` writes any lab test of the registry (``lab.registry.LAB_TESTS``);
``RUN_FILES`` holds it per test, as ``run_ucs_file`` (what ``bpmcal ucs`` and ``bpmcal
sample`` and the workflow's ``sample`` and ``sweep_ucs`` rules call), ``run_bts_file``,
``run_dtt_file``, ``run_triaxial_file`` and ``run_impact_file``. A run that
failed (one of ``lab.runner.RUN_FAILURES``: numerical instability, a specimen that cannot
be built or does not settle, a servo that does not converge) produces a *failure record*
(status "failed" and the message) instead of an exception, so a study is not stopped by
one bad sample; any other exception is a bug and propagates. A failure record never
replaces a good run file: if ``out`` already holds a run with status "ok", the record goes
beside it as ``NAME.failed.h5`` and the outcome says so (``kept``).

A run whose loading a cut-off stopped before the peak and the drop that define its measure
(``lab.registry.incomplete_reason``) is written whole with status "incomplete" and the
reason: it is kept for inspection but is no measurement (every reader treats any status
other than "ok" as a failed measurement).

``lab_test_file``, ``lab_test_files`` and ``impact_file`` are the whole jobs of
``bpmcal ucs|bts|dtt|triaxial``, ``bpmcal sample`` and ``bpmcal impact``: where the
parameters come from (a parameter file or material card, ``--set`` overrides, or a design
row), the resource budget and the output, all checked before any work.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import params as P
from ..cost import LEDGER, phase
from ..dem.errors import InputError
from ..io.card import card_parameters, check_card, is_card
from ..io.checks import BadInput, out_dir, out_file, read_model_table, read_yaml
from ..io.h5 import RunFileError, RunRecord, check_run_file, write_run
from ..io.safe_names import clip, shown
from ..lab.budget import BudgetError
from ..lab.reach import screen_test_loading
from ..lab.registry import LAB_TESTS, incomplete_reason, kind
from ..lab.run_context import RunContext
from ..lab.runner import (
    RUN_FAILURES,
    Geometry,
    LabRun,
    default_geometry,
    lab_test,
    specimen_spec,
    test_inputs,
)


@dataclass
class RunOutcome:
    status: str
    summary: dict = field(default_factory=dict)
    error: str = ""
    path: object = None
    kept: object = None  # a good run file left in place (the record went beside it)


def failed_path(out):
    """Where a failure record goes when ``out`` already holds a good run."""
    out = Path(out)
    return out.with_name(f"{out.stem}.failed{out.suffix}")


def file_cost() -> dict:
    """The ``/cost`` attributes of the run file being written: what the process spent
    since the run file it wrote before (``bpmcal.cost``)."""
    d = LEDGER.take("file")
    return {**d, "process_cpu_s": time.process_time(), "pid": os.getpid()}


def _not_over_a_good_run(out) -> tuple[Path, Path | None]:
    """Where a run that did not succeed goes: ``out``, or beside it when ``out`` is a good
    run file (never overwrite a good result with a failure); and the good file kept."""
    out = Path(out)
    if out.is_file():
        try:
            if check_run_file(out).get("status") == "ok":
                return failed_path(out), out
        except RunFileError:
            pass  # not a good run: replace it
    return out, None


def write_failure(out, *, test: str, inputs: dict, error: str, wall_s: float = 0.0
                  ) -> RunOutcome:
    """Write a failure record (status "failed", the reason) to ``out``, or beside it if
    ``out`` is a good run file (never overwrite a good result with a failure)."""
    out, kept = _not_over_a_good_run(out)
    with phase("write"):
        write_run(out, RunRecord(test=test, inputs=inputs, status="failed", error=error,
                                 summary={"wall_s": wall_s}), cost=file_cost)
    return RunOutcome(status="failed", error=error, path=out, kept=kept)


def write_lab_run(out, r: LabRun) -> RunOutcome:
    """Write a finished test to ``out`` (HDF5, atomically): status "ok", or "incomplete"
    with the reason when a cut-off stopped its loading before what defines its measure
    (``lab.registry.incomplete_reason``: the whole run is kept for inspection, but it is
    no measurement, and it goes beside a good run file rather than over it)."""
    reason = incomplete_reason(r.test, r.summary)
    status, kept = ("incomplete", None) if reason else ("ok", None)
    if reason:
        out, kept = _not_over_a_good_run(out)
    with phase("write"):
        write_run(out, RunRecord(test=r.test, inputs=r.inputs, summary=r.summary,
                                 genesis=r.genesis, series=r.series, cracks=r.cracks,
                                 particles_initial=r.particles_initial,
                                 particles_final=r.particles_final, bonds=r.bonds,
                                 groups=r.groups, status=status, error=reason),
                  cost=file_cost)
    return RunOutcome(status=status, summary=r.summary, error=reason, path=out, kept=kept)


def _run_file(out, test: str, inputs: dict, run) -> RunOutcome:
    """``run()`` -> LabRun written to ``out``, or the failure record of a failed run."""
    t0 = time.perf_counter()
    try:
        r = run()
    except RUN_FAILURES as e:
        return write_failure(out, test=test, inputs=inputs, error=f"{type(e).__name__}: {e}",
                             wall_s=time.perf_counter() - t0)
    return write_lab_run(out, r)


def run_test_file(test: str, out, params: dict, seed: int, geometry: Geometry | None = None,
                  settings=None, *, cache=None, threads=None, progress=None,
                  keep_particles: bool = True, genesis_max_steps: int | None = None
                  ) -> RunOutcome:
    """Run one lab test ``test`` (``lab.registry.LAB_TESTS``; ``lab.runner.lab_test``)
    and write ``out`` (HDF5, test ``test``). Returns the outcome; unstable runs and
    unbuildable specimens give status "failed" (and a failure-record file). ``geometry``
    defaults to the test's specimen (``lab.runner.default_geometry``: the ISRM disc
    50 x 25 mm at scale 1 for the Brazilian test, the 50 x 100 mm cylinder else),
    ``settings`` to its settings class's defaults."""
    st = settings or kind(test).settings()
    geo = geometry or default_geometry(test)
    p = P.validate_params(params)  # bad input: raise before any work
    return _run_file(out, test, test_inputs(test, p, seed, geo, st),
                     lambda: lab_test(test, p, seed, geo, st, cache=cache, threads=threads,
                                      progress=progress, keep_particles=keep_particles,
                                      genesis_max_steps=genesis_max_steps))


def _file_writer(test: str):
    """:func:`run_test_file` of ``test``, as ``run_<test>_file(out, params, seed,
    geometry=None, settings=None, **kw)``."""
    def write(out, params: dict, seed: int, geometry: Geometry | None = None, settings=None,
              **kw) -> RunOutcome:
        return run_test_file(test, out, params, seed, geometry, settings, **kw)

    write.__name__ = write.__qualname__ = f"run_{test}_file"
    write.__doc__ = (f"One {kind(test).title} test written to ``out``: "
                     f"``run_test_file({test!r}, out, ...)``.")
    return write


#: the run-file writer of each lab test, by its name (``lab.registry.LAB_TESTS``)
RUN_FILES = {test: _file_writer(test) for test in LAB_TESTS}
run_ucs_file = RUN_FILES["ucs"]
run_bts_file = RUN_FILES["bts"]
run_dtt_file = RUN_FILES["dtt"]
run_triaxial_file = RUN_FILES["triaxial"]
run_impact_file = RUN_FILES["impact"]


# ------------------------------------------------------------------ the run commands
def parse_set(items) -> dict:
    """``NAME=VALUE`` overrides (``--set``) as numbers."""
    out = {}
    for it in items or []:
        if "=" not in it:
            raise P.ParameterError(f"--set {shown(it)}: expected NAME=VALUE")
        k, v = it.split("=", 1)
        k = k.strip()
        try:
            out[k] = float(v)
        except ValueError:
            raise P.ParameterError(f"--set {clip(k)}={shown(v)}: expected a number") from None
    return out


def load_params(path, overrides=(), contact_model=None) -> dict:
    """Parameters from a YAML file (a flat mapping of the 8 names, or a material card: the
    parameters it stands for, ``card_parameters``, i.e. a verified card's closed-loop
    parameters) plus NAME=VALUE overrides, validated (unknown, missing, non-numeric,
    boolean, NaN or out-of-domain values raise). ``contact_model`` (``--contact-model``)
    names the card's contact model (a card naming the other one, or using its keys, is
    refused)."""
    d = {}
    if path is not None:
        d = read_yaml(path, "--params")
        if is_card(d):
            d = card_parameters(check_card(d, f"--params {path}"))
    d.update(parse_set(overrides))
    if contact_model is not None:
        d["contact_model"] = contact_model
    try:
        return P.validate_params(d)
    except P.ParameterError as e:
        raise P.ParameterError(f"--params {path}: {e}" if path is not None else str(e)) from None


def params_from_design(path, sample_id) -> tuple[dict, int, str]:
    """The card parameters, the seed and a skip reason ("" to run) of one row of a design
    CSV; the contact model is the one whose names the design's columns use (the paper's
    8 parameters: the parallel bond). A sweep-plan row with status "unreachable" is not
    run: its reason is returned and its parameters (NaN strengths) are not validated."""
    d, model = read_model_table(path, "--design", lambda m: ["sample_id", *m.params, "seed"],
                                dtype={"sample_id": str})
    names = [k for k in model.params if k in d.columns]  # (quiet keys may be absent)
    row = d[d["sample_id"] == sample_id]
    if len(row) != 1:
        raise BadInput(f"--sample {sample_id!r}: {'not in' if len(row) == 0 else 'repeated in'} "
                       f"{path} ({len(d)} samples: {d['sample_id'].iloc[0]}..."
                       f"{d['sample_id'].iloc[-1]})")
    r = row.iloc[0]
    raw = r["seed"].item() if hasattr(r["seed"], "item") else r["seed"]
    try:
        seed = float(raw)
    except (TypeError, ValueError):
        seed = math.nan
    if not (math.isfinite(seed) and seed == int(seed) and 0 <= seed < 2 ** 32):
        raise BadInput(f"--design {path} sample {sample_id}: seed={raw!r}: expected an "
                       "integer in [0, 2^32)")
    from ..study.sweep import UNREACHABLE  # (pandas: not at module level, see io.tables)

    if "status" in d.columns and str(r["status"]) == UNREACHABLE:
        reason = r["reason"] if "reason" in d.columns and isinstance(r["reason"], str) else ""
        return {k: r[k] for k in names}, int(seed), f"not run: unreachable ratio: {reason}"
    try:
        params = P.validate_params({k: r[k] for k in names})
    except P.ParameterError as e:
        raise P.ParameterError(f"--design {path} sample {sample_id}: {e}") from None
    return params, int(seed), ""


def run_source(*, params_file=None, sets=(), design=None, sample=None, seed=None,
               contact_model=None) -> tuple[dict, int, str]:
    """Parameters, packing seed and (for a plan row not to be run) the reason, of a DEM run
    command: ``params_file`` (+ ``sets``) or a ``design`` row ``sample`` (exclusive)."""
    skip = ""
    if design is not None:
        if sample is None:
            raise BadInput("--design needs --sample ID (the row to run)")
        params, row_seed, skip = params_from_design(design, sample)
        row_model = params.get("contact_model", P.DEFAULT_CONTACT_MODEL)
        if contact_model not in (None, row_model):
            raise BadInput(f"--contact-model {contact_model}: the design {design} has "
                           f"{row_model} cards (its columns name that model's parameters)")
        if not skip and sets:
            params = P.validate_params({**params, **parse_set(sets)})
        seed = row_seed if seed is None else seed
    else:
        if sample is not None:
            raise BadInput(f"--sample {sample}: needs --design FILE")
        params = load_params(params_file, sets, contact_model)
        seed = 1 if seed is None else seed
    return params, int(seed), skip


def _float_or_nan(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def lab_test_file(test: str, out, *, geometry, settings, params_file=None, sets=(),
                  design=None, sample=None, seed=None, ctx: RunContext = RunContext(),
                  keep_particles: bool = True) -> RunOutcome:
    """The job of ``bpmcal ucs|bts|dtt|triaxial``: parameters and seed (a parameter file or a
    design row), the resource budget (``ctx``, :class:`~bpmcal.lab.run_context.RunContext`),
    the output path and the cache folder, all checked before any work; then the run file,
    or the failure record of a failed run or of a plan row that is not to be run."""
    return lab_test_files([(test, out, geometry, settings)], params_file=params_file,
                          sets=sets, design=design, sample=sample, seed=seed, ctx=ctx,
                          keep_particles=keep_particles)[0]


def lab_test_files(tests, *, params_file=None, sets=(), design=None, sample=None, seed=None,
                   ctx: RunContext = RunContext(), progress=None, keep_particles: bool = True,
                   flags=None, contact_model=None) -> list[RunOutcome]:
    """Several lab tests of one parameter set and packing seed in one process, one after
    the other: ``tests`` is a list of ``(test, out, geometry, settings)``. The study's
    sample job runs the UCS test and the Brazilian test this way (``bpmcal sample
    --bts-out``): one process start-up (imports, numba's cached kernels) instead of two,
    about 1 s of a ~2.5 s Brazilian job. Every input of every test (budget, output path)
    is checked before the first one runs; each test writes its own run file or failure
    record, whatever happened to the others. ``flags``: the option naming each output in
    error messages (default ``--out``); ``ctx``: how the runs go (cache, threads, budgets,
    :class:`~bpmcal.lab.run_context.RunContext`); ``progress``: a list of one progress
    callable per test (default: ``ctx.progress`` for all)."""
    with phase("inputs"):  # the cost ledger (bpmcal.cost)
        params, seed, skips = _checked_tests(tests, params_file=params_file, sets=sets,
                                             design=design, sample=sample, seed=seed, ctx=ctx,
                                             flags=flags, contact_model=contact_model)
    progs = list(progress) if progress is not None else [ctx.progress] * len(tests)
    done = []
    for (test, out, geometry, settings), prog, skip in zip(tests, progs, skips):
        if skip:
            inp = test_inputs(test, {k: _float_or_nan(v) for k, v in params.items()}, seed,
                              geometry, settings)
            done.append(write_failure(out, test=test, inputs=inp, error=skip))
            continue
        done.append(run_test_file(test, out, params, seed, geometry, settings,
                             keep_particles=keep_particles,
                             **dict(ctx.lab_kw(), progress=prog)))
    return done


def _checked_tests(tests, *, params_file, sets, design, sample, seed, ctx, flags,
                   contact_model) -> tuple[dict, int, list]:
    """``lab_test_files``' inputs, all checked before any work: the parameters, the
    packing seed and, per test, the reason not to run it ("" to run)."""
    params, seed, skip = run_source(params_file=params_file, sets=sets, design=design,
                                    sample=sample, seed=seed, contact_model=contact_model)
    flags = flags or ["--out"] * len(tests)
    skips = [skip] * len(tests)
    if not skip:
        for i, (test, _, geometry, settings) in enumerate(tests):
            ctx.check_budget(params, geometry)
            try:  # buildable at all (e.g. 3 ball diameters across)
                specimen_spec(P.validate_params(params), seed, geometry)
            except InputError as e:
                raise InputError(f"the {kind(test).specimen}: {e}") from None
            try:
                screen_test_loading(test, P.validate_params(params), geometry, settings)
            except BudgetError as e:
                if design is None:
                    raise
                skips[i] = str(e)  # a design row: recorded as failed, the study goes on
    seen = {}
    for (_, out, _, _), flag in zip(tests, flags):
        key = Path(os.path.realpath(out))  # (no error on a symlink loop: out_file names it)
        if key in seen:
            raise BadInput(f"{flag} {out}: the same file as {seen[key]} {out}; expected one "
                           "output file per test")
        seen[key] = flag
        out_file(out, flag)
    if ctx.cache is not None:
        out_dir(ctx.cache, "--specimen-cache")
    return params, seed, skips


def impact_file(card, out, *, geometry, settings, seed=1,
                ctx: RunContext = RunContext()) -> RunOutcome:
    """The job of ``bpmcal impact``: the parameters of ``card`` (a verified card's closed
    loop, else its calibration, or a flat mapping of the 8 parameters), checked with the
    budget (``ctx``, :class:`~bpmcal.lab.run_context.RunContext`), the output and the cache
    folder before any work; then the run file."""
    d = read_yaml(card, "--card")
    if is_card(d) or "verification" in d:
        d = card_parameters(check_card(d, f"--card {card}"))
    try:
        params = P.validate_params(d)
    except P.ParameterError as e:
        raise P.ParameterError(f"--card {card}: {e}") from None
    ctx.check_budget(params, geometry)
    out_file(out)
    if ctx.cache is not None:
        out_dir(ctx.cache, "--specimen-cache")
    return run_impact_file(out, params, seed, geometry, settings, **ctx.lab_kw())
