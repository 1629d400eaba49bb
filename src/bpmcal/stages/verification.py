"""The ``verify`` job (``workflow/rules/analysis.smk``, ``bpmcal verify``): the closed
loop (Newton-Broyden, seed-averaged) on the DEM from a calibrated card until every
response is within the tolerance of the lab value or the rounds are used up -> verified
card, rounds table, the best round's run files (:func:`verify`). Its options are one
:class:`~bpmcal.analysis.calibration.LoopSettings` (checked when it is built), the tests a
seed runs one :class:`~.measure.SeedTests`, how its DEM runs one
:class:`~bpmcal.lab.run_context.RunContext`.

:func:`_dem_loop` runs the closed loop on the DEM (its runs and their journal:
:mod:`.loop_runs`; a seed's measurements: :mod:`.measure`); :mod:`.transfer` reuses it and
the helpers here. The seed scatter of a card is :mod:`.seed_scatter`'s job, Tables 5 and 6
:mod:`.verification_tables`'. Method: ``docs/methods/calibration.md`` ("Closed loop").
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from .. import params as P
from ..analysis.calibration import ClosedLoop, LoopSeeds, LoopSteps, SearchSpace
from ..analysis.calibration.loop_settings import LoopSettings
from ..analysis.calibration.specimens import MISS_ACCEPTED
from ..io.card import read_card, write_card
from ..io.checks import BadInput
from ..io.tables import write_table
from ..lab.run_context import RunContext
from ..lab.runner import bts_inputs, ucs_inputs
from ..params import BTS, SAMPLE_TESTS
from .inputs import CSV, H5, YAML, output_dirs, outputs, read_models
from .loop_runs import LoopRuns, seed_runs_table
from .runs import write_failure

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


def _dem_loop(c: dict, model_set, targets: dict, *, params: dict, run, bts_run=None, tests,
              loop: LoopSettings, ctx: RunContext, free=None, jacobian=None, rtol=None):
    """The closed loop of ``loop`` (:class:`LoopSettings`) on its seeds, growing to
    ``loop.max_seeds`` once every mean is within ``loop.grow_within`` tolerances (every
    round runs each seed into a temporary file: the tests of ``tests``
    (:class:`~.measure.SeedTests`) the targets ask for - the UCS test and, when σt is a
    target, the Brazilian test on its disc (or the direct-tension test on its cylinder)
    with the same seed, and when ``tri_MPa`` is one, its triaxial test on the UCS
    cylinder; the first seed's run files of the best round become ``run`` and
    ``bts_run``). A round's seeds run side by side on up to ``ctx.threads`` processes
    (:class:`~.pool.SeedPool`); a seed's σt is the mean of ``loop.tensile_specimens``
    specimens (:func:`~.measure.seed_strength`), raised up to
    ``loop.max_tensile_specimens`` for a card whose σt scatters too much for
    ``loop.tensile_seed_cv`` (:class:`LoopRuns`); with ``loop.triaxial_seeds`` = m only a
    round's first m seeds run the triaxial test (:class:`ClosedLoop`'s ``seed_caps``). The
    first step follows the regression models' Jacobian, or ``jacobian`` (responses x free
    parameters, physical units) when given; the measured rounds correct it by
    ``loop.jacobian_update`` (:class:`ClosedLoop`'s ``update``). ``rtol``: the tolerance
    of each target (default ``loop.rtol``; the transfer's are its own).
    Returns (ClosedLoopResult, per-round list of seed summaries, best round index, the
    tensile specimens per seed: :meth:`LoopRuns.specimen_record`)."""
    ratio = c.get("ratio_ten_coh")
    with_bts = BTS in targets
    caps = ({P.TRI: int(loop.triaxial_seeds)} if loop.triaxial_seeds and P.TRI in targets
            else {})
    runs = LoopRuns(Path(run).parent / f".{Path(run).stem}.rounds", list(targets),
                    tests=tests, ctx=ctx, loop=loop, caps=caps)
    ok = False
    try:
        free = free or [k for k, v in c["roles"].items() if v == "free"]
        jac = None if jacobian is None else pd.DataFrame.from_dict(jacobian, orient="index")
        if jac is not None and not (set(targets) <= set(jac.index) and set(free) <= set(jac.columns)
                                    and np.isfinite(jac.loc[list(targets), list(free)]
                                                    .to_numpy(float)).all()):
            jac = None  # learned for other targets or parameters: start from the models
        space = SearchSpace(ranges=c["ranges"], free=free, ratio=ratio,
                          bounds=c.get("calibration_bounds") or None)
        steps = LoopSteps(rtol=loop.rtol if rtol is None else rtol, max_rounds=loop.max_rounds,
                          margin=loop.range_margin, polish=loop.polish,
                          update=loop.jacobian_update)
        seeding = LoopSeeds(seeds=loop.seeds, max_seeds=max(loop.max_seeds, loop.seeds_per_round),
                            grow_within=loop.grow_within, seed_caps=caps or None)
        cl = ClosedLoop(runs.simulate, targets, space=space, steps=steps, seeding=seeding,
                        models=model_set if jac is None else None, jacobian=jac,
                        target_se=c.get("target_se") or None, report=_notes(ctx.progress),
                        simulate_seeds=runs.simulate_seeds)
        res = cl.run(params)
        best = res.best_round  # converged, else the smallest max |error| of the seed mean
        os.replace(runs.paths[best][0], run)  # the best round's first seed is the run file
        if bts_run is not None and with_bts:
            os.replace(runs.bts_paths[best][0], bts_run)
        ok = True
    finally:
        runs.close(ok)
    return res, runs.by_round, best, runs.specimen_record()


# long: the stage's reference docstring (55 lines, the card's verification section); the code is ~45 lines
def verify(card, models, *, out_card, rounds, run, tests, loop: LoopSettings = LoopSettings(),
           ctx: RunContext = RunContext(), free=None, bts_run=None, seed_runs=None) -> dict:
    """Closed-loop verification of one material card: round 1 is the paper's single pass
    (the regression's answer), later rounds correct the free parameters with a
    Newton-Broyden step until every response is within the tolerance of the lab value,
    or ``loop.max_rounds`` rounds are used up (``"auto"``: two per free parameter,
    :func:`~bpmcal.params.auto_rounds`; the card records the budget). ``loop`` holds every
    option of the loop (:class:`~bpmcal.analysis.calibration.LoopSettings`: the config's
    ``verification`` section), ``tests`` the tests a seed runs (:class:`~.measure.SeedTests`),
    ``ctx`` how its DEM runs (:class:`~bpmcal.lab.run_context.RunContext`). Every round runs
    the candidate on ``loop.seeds_per_round`` packing seeds (``loop.seed``, ``loop.seed +
    1``, ...) and steers their mean; a target is met when the mean lies within
    max(``loop.rtol``, 2 standard errors of the mean) of it
    (:class:`~bpmcal.analysis.ClosedLoop`), so the loop fits the rock, not one packing. A
    round costs ``seeds_per_round`` DEM runs, side by side on up to ``ctx.threads``
    processes (:mod:`bpmcal.stages.pool`; the card does not depend on how many). The seed
    set grows to ``loop.max_seeds`` seeds (``seed + seeds_per_round``, ...; at most
    ``seeds_per_round``: no growth) once every mean is within ``loop.grow_within``
    tolerances (the card records it) but their standard errors are too large to state
    them to ``rtol``, so the card is judged, and steered, on the mean of more packings (a
    fixed few packings' mean is itself off the rock's by ~CV/sqrt(k)); later rounds run
    the grown set.

    Writes the verified card (``out_card``; per round shown, the seed mean of every
    response, its seed standard deviation ``seed_sd`` and coefficient of variation
    ``seed_cv``, and ``n_seeds``), the rounds table (``rounds``: parameters, seed means,
    seed CVs, standard errors, tolerances, errors and step of every round) and ``run``,
    the run file of the best round's first seed (each run goes to a temporary file; any
    run can be redone with ``bpmcal ucs --params ... --seed``, the runs being
    deterministic); ``seed_runs`` (optional) the table of every seed run of every round
    (:func:`seed_runs_table`: round, seed, parameters, responses; the posterior's runs near
    the card). The loop stays inside the card's bounds (its design ``ranges``, narrowed by
    its ``calibration_bounds``; ``free``: the parameters it moves, default the card's free
    roles), each design range widened by ``loop.range_margin`` of its width (never past a
    ``calibration_bounds`` narrowing or the parameter's physical domain): the regression
    only starts the loop, every round measures the DEM, so the loop may follow a target
    just outside the sampled space. The card records the bounds searched
    (``verification.loop_bounds``) and every parameter that ended outside its design range
    (``verification.outside_design``: value and range; the message says so too). The card
    records ``calibrated_at_scale``, the specimen scale the loop ran at. With
    ``loop.polish`` a loop that converges with some mean more than one standard error
    from its target takes one more full Newton step towards the targets on the same
    seeds, if a round is left; that round is the card's when it is within tolerance too
    (:class:`~bpmcal.analysis.ClosedLoop`). ``loop.jacobian_update`` is how the measured
    rounds correct the loop's Jacobian: ``broyden`` (the secant between consecutive
    rounds) or ``history`` (a local linear fit to every round, the regression's Jacobian
    its prior); the card records it.

    A card whose inversion is ``unreachable`` is not a calibration: unless
    ``loop.from_unreachable`` the DEM is not run, the verified card says so
    (``verification.status: not-run`` with the reason and what to widen), ``rounds`` has
    its header only and ``run`` is a failure record ("not run: ..."). Returns the verified
    card.

    Every target of the card is verified: a card with a tensile-strength target
    (``bts_MPa``) runs, in every round, a Brazilian test beside the UCS test (the same
    packing seed; the disc and loading of ``tests``, default the ISRM disc at the
    cylinder's scale and genesis options), and the loop steers σt with the other
    responses; ``bts_run`` (optional) receives the best round's Brazilian run file (a
    failure record when the card has no σt target). A card with a direct-tension target
    (``dtt_MPa``) runs the direct-tension test instead, on the cylinder of ``tests``
    (default the UCS cylinder). An invalid tensile test (its fracture at a contact or a
    grip) is no measurement: that seed's test is run again on replacement seeds
    (:func:`~.measure.valid_tensile_run`), and the round fails only when none is valid.
    With ``loop.tensile_specimens`` = n > 1 a seed's σt is the mean of n specimens
    (:func:`~.measure.seed_strength`; the card records n, and the transfer and the
    fresh-seed check measure σt the same way). With ``loop.tensile_seed_cv`` that n is
    where the loop starts: a card whose specimens scatter more than n of them can average
    to that seed CV gets more, up to ``loop.max_tensile_specimens`` (:class:`LoopRuns`);
    the card records the count its last rounds used, the specimen CV, the seed CV
    expected and every raise (``verification.tensile``). A card with a triaxial-strength
    target (``tri_MPa``, σ1 at the study's design confinement) runs the triaxial test of
    ``tests.tri_settings`` (its ``sigma3``) on the UCS cylinder in every round (required
    then: BadInput without it); with ``loop.triaxial_seeds`` = m (default: every seed)
    only the first m seeds of the set run it, so a grown set judges the cheap targets on
    more packings than the costly triaxial one (the card records m). The verified card
    lists every target the best round misses by more than ``rtol``
    (``verification.missed``: target, lab value, DEM value, error in %); it is empty only
    when all are met."""
    c = read_card(card, "--card", need=("parameters", "targets", "roles"))
    if "ranges" not in c:
        raise P.ParameterError(f"--card {card}: the card has no 'ranges' (the design space); "
                               "rerun the calibrate step")
    model_set = read_models(models)
    targets = {k: float(v) for k, v in c["targets"].items()}
    _check_verify_inputs(card, models, c, model_set, targets, tests, ctx)
    outputs((out_card, "--out-card", YAML), (rounds, "--rounds", CSV), (run, "--run", H5),
            (bts_run, "--bts-run", H5), (seed_runs, "--seed-runs", CSV))
    output_dirs((ctx.cache, "--specimen-cache"))
    max_seeds = max(loop.max_seeds, loop.seeds_per_round)
    if c.get("status") == "unreachable" and not loop.from_unreachable:
        reason = ("the calibration is unreachable, so the closed loop did not start from it "
                  "(verification.from_unreachable: false); " + str(c.get("message", "")))
        section = {
            "status": "not-run", "message": reason, "rounds": 0, "rtol": loop.rtol,
            "seed": loop.seed, "seeds": loop.seeds, "n_seeds": loop.seeds_per_round,
            "max_seeds": max_seeds, "best_round": None, "single_pass": None,
            "closed_loop": None, "parameters": None, "widen": c.get("widen", []),
            "geometry": tests.geometry.to_dict()}
        if seed_runs is not None:
            write_table(seed_runs_table([]), seed_runs, index=False)
        return _not_run(c, out_card, "verification", section, rounds=rounds, run=run,
                        error=f"not run: {reason}", params=c["parameters"], seed=loop.seed,
                        tests=tests, bts_run=bts_run)
    res, by_round, best, tensile = _dem_loop(
        c, model_set, targets, params=c["parameters"], run=run, bts_run=bts_run, tests=tests,
        loop=loop, ctx=ctx, free=free)
    write_table(res.history, rounds, index=False)
    if seed_runs is not None:
        write_table(seed_runs_table(by_round), seed_runs, index=False)
    verified = dict(c)
    verified.update({
        "calibrated_at_scale": float(tests.geometry.scale),
        "verification": _verification_section(c, res, by_round, best, targets, loop=loop,
                                              tests=tests, max_seeds=max_seeds,
                                              tensile=tensile)})
    write_card(out_card, verified)
    if bts_run is not None and BTS not in targets:
        write_failure(bts_run, test="bts", inputs=bts_inputs(c["parameters"], loop.seed,
                                                             tests.disc, tests.bts_settings),
                      error="not run: the card has no tensile-strength target (bts_MPa)")
    return verified


def _check_verify_inputs(card, models, c: dict, model_set, targets: dict, tests, ctx) -> None:
    """The checks :func:`verify` makes before any output: a model of every tensile and
    triaxial target, the triaxial test's settings for a ``tri_MPa`` target, a Brazilian
    disc 3 of the largest balls across, and every specimen within the budget."""
    with_bts = BTS in targets
    with_dtt = "dtt_MPa" in targets
    disc = tests.disc
    check_tri_target(card, targets, tests.tri_settings, model_set, models)
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
    ctx.check_budget(c["parameters"], tests.geometry, *([disc] if with_bts else []),
                     *([tests.cylinder] if with_dtt else []))


def _not_run(c: dict, out_card, key: str, section: dict, *, rounds, run, error: str,
             params: dict, seed, tests, bts_run=None) -> dict:
    """A stage whose closed loop does not run (:func:`verify` from an unreachable card,
    :mod:`.transfer` from a card whose loop did not run): the rounds table with its header
    only, failure records (``error``) for the run files of the tests of ``tests``, and the
    card with its ``key`` section; returns the card."""
    write_table(pd.DataFrame(columns=["round"]), rounds, index=False)
    write_failure(run, test="ucs", inputs=ucs_inputs(params, seed, tests.geometry, tests.settings),
                  error=error)
    if bts_run is not None:
        write_failure(bts_run, test="bts",
                      inputs=bts_inputs(params, seed, tests.disc, tests.bts_settings), error=error)
    out = dict(c)
    out[key] = section
    write_card(out_card, out)
    return out


def _verification_section(c: dict, res, by_round: list, best: int, targets: dict, *,
                          loop: LoopSettings, tests, max_seeds: int, tensile=None) -> dict:
    """The verified card's ``verification`` section from the closed loop's result ``res``
    and its rounds' seed summaries ``by_round`` (``best``: the card's round; ``loop``,
    ``tests``: the loop's settings and tests; ``max_seeds``: the seed set's cap;
    ``tensile``: :meth:`LoopRuns.specimen_record`)."""
    margin = loop.range_margin
    message = res.message + _outside_text(res.outside, margin)
    if c.get("status") == "unreachable":
        message = ("started from an unreachable calibration at the user's request "
                   f"(verification.from_unreachable: true): {message}")
    v = {
        "status": res.status, "message": message, "rounds": len(by_round),
        "runs": sum(len(r) for r in by_round), "rtol": loop.rtol, "seed": loop.seed,
        "seeds": [int(x) for x in res.seeds], "n_seeds": int(res.n_seeds),
        "seeds_per_round": loop.seeds_per_round, "max_seeds": max_seeds,
        "polish": bool(loop.polish), "grow_within": float(loop.grow_within),
        "jacobian_update": loop.jacobian_update, "max_rounds": int(res.max_rounds),
        "best_round": best + 1, "run_seed": loop.seeds[0],
        "jacobian": {r: {p: float(x) for p, x in row.items()}
                     for r, row in res.jacobian.iterrows()},
        "single_pass": _responses(by_round[0], targets),
        "closed_loop": _responses(by_round[best], targets),
        "parameters": {k: float(v) for k, v in res.params.items() if k in P.ALL_PARAMS},
        "geometry": tests.geometry.to_dict(), **_loop_box(res, margin),
    }
    v["missed"] = _missed(v["closed_loop"], targets, loop.rtol)
    if res.sign_held:  # the regression's slopes the loop did not start from
        v["jacobian_sign_held"] = [dict(h) for h in res.sign_held]
    if BTS in targets:
        v["bts_geometry"] = tests.disc.to_dict()
    if "dtt_MPa" in targets:
        v["dtt_geometry"] = tests.cylinder.to_dict()
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
                + seed_cv_shortfall(tensile))
    if P.TRI in targets:
        v["tri_sigma3_MPa"] = tests.tri_settings.sigma3 / 1e6
        if loop.triaxial_seeds and loop.triaxial_seeds < max_seeds:  # σ1 on the first m seeds
            v["triaxial_seeds"] = int(loop.triaxial_seeds)
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


def _loop_box(res, margin: float) -> dict:
    """The card's record of the closed loop's bounds and what ended outside the design."""
    return {"range_margin": margin,
            "loop_bounds": {p: [float(a), float(b)] for p, (a, b) in res.loop_bounds.items()},
            "outside_design": {p: dict(v) for p, v in res.outside.items()}}


def outside_items(outside: dict) -> str:
    """``pb_kratio 5.58 outside its range 1-5; ...`` for a card's ``outside_design``."""
    return "; ".join(f"{p} {v['value']:.3g} outside its range {v['range'][0]:g}-{v['range'][1]:g}"
                     for p, v in outside.items())


def _outside_text(outside: dict, margin: float) -> str:
    if not outside:
        return ""
    return (f"; outside the design space (range margin {margin:g}): {outside_items(outside)}"
            " - the DEM was run there, the regression never sampled it")


def seed_cv_shortfall(t: dict) -> str:
    """How often 5 seeds read σt's seed CV above the target (``verification.tensile``)."""
    return (f"5 seeds read it above the {100 * t['seed_cv_target']:g} % aimed at "
            f"{100 * t['chance_above']:.0f} % of the time")
