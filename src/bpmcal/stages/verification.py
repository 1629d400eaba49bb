"""The ``verify`` job (``workflow/rules/analysis.smk``, ``bpmcal verify``): the closed
loop (Newton-Broyden, seed-averaged) on the DEM from a calibrated card until every
response is within the tolerance of the lab value or the rounds are used up -> verified
card, rounds table, the best round's run files (:func:`verify`), and the checks of its
options.

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
from ..analysis import ClosedLoop
from ..analysis.calibration import UPDATES
from ..analysis.calibration.closed_loop import check_grow_within, check_max_rounds
from ..analysis.calibration.specimens import MISS_ACCEPTED
from ..io.card import read_card, write_card
from ..io.checks import BadInput
from ..io.tables import write_table
from ..lab.brazilian import BTSSettings
from ..lab.budget import check_budget
from ..lab.direct_tension import DTTSettings
from ..lab.runner import bts_inputs, ucs_inputs
from ..params import BTS, SAMPLE_TESTS
from . import defaults_of
from .inputs import CSV, H5, YAML, output_dirs, outputs, read_models
from .loop_runs import LoopRuns, seed_runs_table
from .measure import check_seed_cv, check_tensile_specimens, check_triaxial_seeds, disc_geometry
from .runs import write_failure

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
    processes (:class:`~.pool.SeedPool`); a seed's σt is the mean of ``tensile_specimens``
    specimens (:func:`~.measure.seed_strength`), raised up to ``max_tensile_specimens`` for a card
    whose σt scatters too much for ``tensile_seed_cv`` (:class:`LoopRuns`); with
    ``triaxial_seeds`` = m only a round's first m
    seeds run the triaxial test (:class:`ClosedLoop`'s ``seed_caps``). The first step
    follows the regression models' Jacobian, or ``jacobian`` (responses x free
    parameters, physical units) when given; the measured
    rounds correct it by ``jacobian_update`` (:class:`ClosedLoop`'s ``update``).
    Returns (ClosedLoopResult, per-round list of seed summaries, best round index, the
    tensile specimens per seed: :meth:`LoopRuns.specimen_record`)."""
    ratio = c.get("ratio_ten_coh")
    with_bts = BTS in targets
    caps = {P.TRI: int(triaxial_seeds)} if triaxial_seeds and P.TRI in targets else {}
    runs = LoopRuns(Path(run).parent / f".{Path(run).stem}.rounds", list(targets),
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
    (:func:`~.measure.valid_tensile_run`), and the round fails only when none is valid. With
    ``tensile_specimens`` = n > 1 (config ``verification.tensile_specimens``) a seed's σt
    is the mean of n specimens (:func:`~.measure.seed_strength`; the card records n, and the
    transfer and the fresh-seed check measure σt the same way). With ``tensile_seed_cv``
    (config ``verification.tensile_seed_cv``) that n is where the loop starts: a card
    whose specimens scatter more than n of them can average to that seed CV gets more,
    up to ``max_tensile_specimens`` (:class:`LoopRuns`); the card records the count its
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
    max_tensile_specimens = check_tensile_specimens(  # never below the start: LoopRuns
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
    :meth:`LoopRuns.specimen_record`)."""
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
                + seed_cv_shortfall(tensile))
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
