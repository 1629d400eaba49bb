"""Subcommands that run or tabulate the calibrated cards: the closed loop ``verify``,
``transfer`` to full size and ``transfer-table``, the seed ``scatter``, the fresh-seed
check (``fresh-seeds``, ``fresh-seeds-table``), ``verification-tables`` (Tables 5 and 6), the
triaxial ``envelopes`` and ``impact-analyse``.

Each ``_add_<cmd>`` (its options) stands directly above its ``cmd_<cmd>`` (the handler).
``verify``, ``transfer`` and ``fresh-seeds`` share the cylinder, the ``--bts-*`` disc, the
``--dtt-*`` test and the ``--tri-*`` triaxial test (:func:`_add_card_run_args`).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..io.checks import BadInput
from ..stages import defaults_of
from ..stages.progress import Progress
from .args import SEED, integer, integer_or, number
from .options import (
    add_bts_args,
    add_dtt_args,
    add_run_args,
    add_tri_args,
    bts_disc_of,
    bts_settings_of,
    budget_of,
    dtt_cylinder_of,
    dtt_settings_of,
    file_arg,
    run_geometry,
    run_settings,
    tri_settings_of,
)


def _add_card_run_args(p, func):
    """The options every command that runs a card's UCS (and Brazilian) tests shares
    (verify, transfer, fresh-seeds): --quiet, the cylinder and loading, the --bts-* disc, the
    --dtt-* direct-tension test, the --tri-* triaxial test at the design confinement."""
    p.add_argument("--quiet", action="store_true")
    add_run_args(p)
    add_bts_args(p, "bts_")
    add_dtt_args(p, "dtt_")
    add_tri_args(p)
    p.set_defaults(func=func)


def _add_range_margin(p, d):
    from ..analysis.calibration import UPDATES

    p.add_argument("--range-margin", type=number("range-margin", 0.0, 1.0),
                   default=d["range_margin"],
                   help="the closed loop may leave each design range (the card's ranges) by "
                        "this fraction of its width, inside the parameter's physical domain "
                        "and never past the card's calibration bounds; the card lists what "
                        f"ends outside (default {d['range_margin']:g}; 0: stay inside)")
    p.add_argument("--jacobian-update", choices=UPDATES, default=d["jacobian_update"],
                   help="how the measured rounds correct the closed loop's Jacobian: "
                        "broyden (the secant between consecutive rounds) or history (a local "
                        "linear fit to every round, the regression's Jacobian its prior; "
                        "docs/methods/calibration.md) (default "
                        f"{d['jacobian_update']})")


def _seeds(text) -> list[int]:
    try:
        seeds = [int(x) for x in text.split(",")]
    except ValueError:
        raise BadInput(f"--seeds {text!r}: expected comma-separated integers") from None
    bad = [x for x in seeds if not 0 <= x < 2 ** 32]
    if bad or len(seeds) < 2 or len(set(seeds)) != len(seeds):
        raise BadInput(f"--seeds {text!r}: expected at least 2 different seeds in [0, 2^32)")
    return seeds


def _add_verify(p):
    from ..params import AUTO_ROUNDS, ROUNDS_PER_FREE
    from ..stages.measure import MAX_TENSILE_SPECIMENS, TENSILE_REPLICATE_STRIDE
    from ..stages.verification import verify

    d = defaults_of(verify)
    p.add_argument("--card", required=True)
    p.add_argument("--models", required=True)
    file_arg(p, "--out-card", "output: the verified card")
    file_arg(p, "--rounds", "output table: one row per DEM round")
    file_arg(p, "--run", "output: the run file of the best round")
    p.add_argument("--seed-runs", default=None,
                   help="output table (optional): every seed run of every round (round, seed, "
                        "parameters, responses): the runs near the card a posterior learns "
                        "from (bpmcal posterior)")
    p.add_argument("--bts-run", default=None,
                   help="output (optional): the Brazilian run file of the best round when the "
                        "card has a tensile-strength target (bts_MPa), else a failure record "
                        "saying so; the disc is the ISRM 50 x 25 mm one at --scale")
    p.add_argument("--seed", type=SEED, default=d["seed"],
                   help=f"first packing seed of the DEM runs (default {d['seed']})")
    p.add_argument("--seeds-per-round", type=integer("seeds-per-round", 1, 50),
                   default=d["seeds_per_round"],
                   help="packing seeds per round (--seed, --seed + 1, ...); the loop steers "
                        f"their mean (default {d['seeds_per_round']})")
    p.add_argument("--max-seeds", type=integer("max-seeds", 1, 200), default=d["max_seeds"],
                   help="the seed set may grow to this many seeds once the means are within "
                        "--grow-within tolerances but their standard errors are too large to "
                        f"state them to --rtol (default {d['max_seeds']}; at most "
                        "--seeds-per-round: no growth)")
    p.add_argument("--grow-within", type=number("grow-within", 1.0),
                   default=d["grow_within"],
                   help="the seed set grows once every mean is within this many tolerances "
                        "(a few seeds' spread can understate the scatter, so close to the "
                        "targets the loop steers the grown set, not those seeds; "
                        f"1: only once within tolerance; default {d['grow_within']:g})")
    p.add_argument("--tensile-specimens",
                   type=integer("tensile-specimens", 1, MAX_TENSILE_SPECIMENS),
                   default=d["tensile_specimens"],
                   help="a seed's sigma_t (Brazilian or direct tension) is the mean of this "
                        "many valid specimens, packed with seed + j x "
                        f"{TENSILE_REPLICATE_STRIDE:,}; the card records it and the transfer "
                        "and the fresh-seed check measure sigma_t "
                        f"the same way (default {d['tensile_specimens']})")
    p.add_argument("--tensile-seed-cv",
                   type=number("tensile-seed-cv", 0.0, 1.0, lo_open=True, hi_open=True),
                   default=d["tensile_seed_cv"],
                   help="adapt the tensile specimens per seed to the card: once the "
                        "specimens measured scatter too much for --tensile-specimens of "
                        "them to average to this seed CV (read over 5 seeds, missed at "
                        "most 1 time in 10), later seeds and the round just started get "
                        "more, up to --max-tensile-specimens (default: a fixed count)")
    p.add_argument("--max-tensile-specimens",
                   type=integer("max-tensile-specimens", 1, MAX_TENSILE_SPECIMENS),
                   default=d["max_tensile_specimens"],
                   help="the most tensile specimens per seed --tensile-seed-cv may ask for "
                        "(default: --tensile-specimens, no raise)")
    p.add_argument("--triaxial-seeds", type=integer("triaxial-seeds", 2, 200),
                   default=d["triaxial_seeds"],
                   help="with a triaxial-strength target (tri_MPa), only the first N seeds of "
                        "the loop's seed set run the triaxial test, so a set grown to "
                        "--max-seeds judges the other targets on more packings (default: "
                        "every seed)")
    p.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True), default=d["rtol"],
                   help=f"relative tolerance (default {d['rtol']:g})")
    p.add_argument("--max-rounds", type=integer_or(AUTO_ROUNDS, "max-rounds", 1, 50),
                   default=d["max_rounds"],
                   help=f"rounds at most, each of --seeds-per-round DEM runs, or "
                        f"{AUTO_ROUNDS} ({ROUNDS_PER_FREE} per free parameter: 6 for the "
                        f"paper's three, 8 with both strengths free; default {d['max_rounds']})")
    p.add_argument("--from-unreachable", action="store_true",
                   help="run the closed loop even when the card's inversion is unreachable "
                        "(default: do not; the verified card says why)")
    p.add_argument("--polish", action=argparse.BooleanOptionalAction, default=d["polish"],
                   help="when the loop converges with a mean more than one standard error "
                        "from its target and a round is left, take one more full Newton step "
                        "towards the targets on the same seeds; kept if within tolerance "
                        f"(default {'on' if d['polish'] else 'off'})")
    _add_range_margin(p, d)
    _add_card_run_args(p, cmd_verify)


def cmd_verify(args) -> int:
    from ..stages.verification import verify

    prog = Progress(f"verify {Path(args.card).stem}", enabled=not args.quiet)
    v = verify(args.card, args.models, out_card=args.out_card, rounds=args.rounds, run=args.run,
               geometry=run_geometry(args), settings=run_settings(args), seed=args.seed,
               seeds_per_round=args.seeds_per_round, max_seeds=args.max_seeds, rtol=args.rtol,
               max_rounds=args.max_rounds, cache=args.specimen_cache,
               threads=args.threads, progress=prog, from_unreachable=args.from_unreachable,
               bts_run=args.bts_run, bts_geometry=bts_disc_of(args, "bts_"),
               bts_settings=bts_settings_of(args, "bts_"), range_margin=args.range_margin,
               polish=args.polish, dtt_geometry=dtt_cylinder_of(args, "dtt_"),
               jacobian_update=args.jacobian_update, tensile_specimens=args.tensile_specimens,
               triaxial_seeds=args.triaxial_seeds, tensile_seed_cv=args.tensile_seed_cv,
               max_tensile_specimens=args.max_tensile_specimens,
               grow_within=args.grow_within, seed_runs=args.seed_runs,
               dtt_settings=dtt_settings_of(args, "dtt_"), tri_settings=tri_settings_of(args),
               **budget_of(args))["verification"]
    prog.done(f"{v['status']} after {v['rounds']} round(s): {v['message']}")
    return 0


def _add_transfer(p):
    from ..stages.transfer import transfer

    d = defaults_of(transfer)
    p.add_argument("--card", required=True, help="a verified card (bpmcal verify)")
    p.add_argument("--models", required=True)
    file_arg(p, "--out-card", "output: the transferred card (calibrated_at_scale = --scale)")
    file_arg(p, "--rounds", "output table: one row per DEM round at this size")
    file_arg(p, "--run", "output: the run file of the best round")
    p.add_argument("--seed", type=SEED, default=d["seed"],
                   help=f"packing seed of the run(s) (default {d['seed']})")
    p.add_argument("--max-rounds", type=integer("max-rounds", 0, 50), default=d["max_rounds"],
                   help="correction rounds at most after the transfer run, one DEM run "
                        f"each (default {d['max_rounds']})")
    p.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True), default=d["rtol"],
                   help="relative tolerance; a response within max(rtol, 2 x its seed CV "
                        f"from the verification) needs no correction (default {d['rtol']:g})")
    _add_range_margin(p, d)
    _add_card_run_args(p, cmd_transfer)


def cmd_transfer(args) -> int:
    from ..stages.transfer import transfer

    prog = Progress(f"transfer {Path(args.card).stem}", enabled=not args.quiet)
    t = transfer(args.card, args.models, out_card=args.out_card, rounds=args.rounds, run=args.run,
                 geometry=run_geometry(args), settings=run_settings(args), seed=args.seed,
                 max_rounds=args.max_rounds, rtol=args.rtol, cache=args.specimen_cache,
                 threads=args.threads, progress=prog, bts_geometry=bts_disc_of(args, "bts_"),
                 bts_settings=bts_settings_of(args, "bts_"), range_margin=args.range_margin,
                 dtt_settings=dtt_settings_of(args, "dtt_"), tri_settings=tri_settings_of(args),
                 jacobian_update=args.jacobian_update, **budget_of(args))["transfer"]
    prog.done(f"{t['status']} after {t['rounds']} round(s) at scale {t['scale']:g}: "
              f"{t['message']}")
    return 0


def _add_transfer_table(p):
    file_arg(p, "--cards", "transferred cards", nargs="+")
    file_arg(p, "--table", "output table: verified vs full-size responses per card")
    p.set_defaults(func=cmd_transfer_table)


def cmd_transfer_table(args) -> int:
    from ..stages.transfer import transfer_table

    print(transfer_table(args.cards, table=args.table).to_string(index=False))
    return 0


def _add_scatter(p):
    from ..stages.seed_scatter import seed_scatter

    d = defaults_of(seed_scatter)
    p.add_argument("--card", required=True)
    p.add_argument("--seeds", required=True, help="comma-separated packing seeds")
    file_arg(p, "--runs", "output run files, one per seed in the order of --seeds", nargs="+")
    file_arg(p, "--seed-runs", "output table: the responses of every seed")
    file_arg(p, "--table", "output table: CV and noise floor per response")
    p.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True), default=d["rtol"])
    add_run_args(p)
    p.set_defaults(func=cmd_scatter)


def cmd_scatter(args) -> int:
    from ..stages.seed_scatter import seed_scatter

    sc = seed_scatter(args.card, runs=args.runs, seeds=_seeds(args.seeds),
                      seed_runs=args.seed_runs, table=args.table, geometry=run_geometry(args),
                      settings=run_settings(args), rtol=args.rtol, cache=args.specimen_cache,
                      threads=args.threads, **budget_of(args))
    print(sc.to_string())
    return 0


def _add_fresh_seeds(p):
    p.add_argument("--card", required=True, help="a verified card (bpmcal verify)")
    p.add_argument("--seeds", required=True,
                   help="comma-separated fresh packing seeds (none of the card's closed loop "
                        "or transfer)")
    file_arg(p, "--runs", "output UCS run files, one per seed in the order of --seeds", nargs="+")
    p.add_argument("--bts-runs", nargs="+", default=None,
                   help="output Brazilian run files, one per seed (needed when the card has a "
                        "tensile-strength target; failure records 'not run' without one)")
    p.add_argument("--dtt-runs", nargs="+", default=None,
                   help="output direct-tension run files, one per seed (needed when the card "
                        "has a direct-tension target, dtt_MPa)")
    p.add_argument("--tri-runs", nargs="+", default=None,
                   help="output triaxial run files at --design-sigma3, one per seed (needed when "
                        "the card has a triaxial-strength target, tri_MPa)")
    file_arg(p, "--seed-runs", "output table: the responses of every seed")
    _add_card_run_args(p, cmd_fresh_seeds)


def cmd_fresh_seeds(args) -> int:
    from ..stages.fresh_seeds import fresh_seeds

    prog = Progress(f"fresh-seeds {Path(args.card).stem}", enabled=not args.quiet)
    df = fresh_seeds(args.card, seeds=_seeds(args.seeds), runs=args.runs,
                     seed_runs=args.seed_runs, bts_runs=args.bts_runs,
                     geometry=run_geometry(args), settings=run_settings(args),
                     bts_geometry=bts_disc_of(args, "bts_"),
                     bts_settings=bts_settings_of(args, "bts_"),
                     dtt_runs=args.dtt_runs, dtt_geometry=dtt_cylinder_of(args, "dtt_"),
                     dtt_settings=dtt_settings_of(args, "dtt_"), tri_runs=args.tri_runs,
                     tri_settings=tri_settings_of(args), cache=args.specimen_cache,
                     threads=args.threads, progress=prog, **budget_of(args))
    prog.done(f"{int((df['status'] == 'ok').sum())} of {len(df)} seed(s) ok")
    print(df.to_string(index=False))
    return 0


def _add_fresh_seeds_table(p):
    from ..stages.fresh_seeds import fresh_seeds_table

    d = defaults_of(fresh_seeds_table)
    file_arg(p, "--cards", "verified cards", nargs="+")
    file_arg(p, "--seed-runs", "their seed tables (bpmcal fresh-seeds), in the same order", nargs="+")
    file_arg(p, "--table", "output table: fresh-seed mean, standard error and verdict per "
                           "card and target")
    p.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True, hi_open=True),
                   default=d["rtol"],
                   help=f"the closed loop's relative tolerance (default {d['rtol']:g})")
    p.add_argument("--z", type=number("z", 0.0, 10.0, lo_open=True), default=d["z"],
                   help=f"standard errors a target may lie from the mean (default {d['z']:g})")
    p.set_defaults(func=cmd_fresh_seeds_table)


def cmd_fresh_seeds_table(args) -> int:
    from ..stages.fresh_seeds import fresh_seeds_table

    print(fresh_seeds_table(args.cards, args.seed_runs, table=args.table, rtol=args.rtol,
                            z=args.z).to_string(index=False))
    return 0


def _add_verification_tables(p):
    file_arg(p, "--cards", "verified cards", nargs="+")
    file_arg(p, "--runs", "their best rounds' run files, in the same order", nargs="+")
    p.add_argument("--lab", required=True)
    file_arg(p, "--table5", "output table: Table 5")
    file_arg(p, "--table6", "output table: Table 6")
    file_arg(p, "--figure", "output figure: Fig. 6")
    p.set_defaults(func=cmd_verification_tables)


def cmd_verification_tables(args) -> int:
    from ..stages.verification_tables import verification_tables

    r = verification_tables(args.cards, args.runs, args.lab, table5=args.table5,
                            table6=args.table6, figure=args.figure)
    print(r["table5"].to_string())
    print(r["table6"].to_string())
    return 0


def _add_envelopes(p):
    from ..stages.triaxial import DEFAULT_SIGMA3_MPA

    file_arg(p, "--cards", "material cards (calibrated or verified)", nargs="+")
    file_arg(p, "--runs", "their triaxial run files: for each card, one per --sigma3, in order",
          nargs="+")
    p.add_argument("--sigma3", type=_sigma3_list,
                   default=list(DEFAULT_SIGMA3_MPA), metavar="MPA,MPA,...",
                   help="the confining stresses of each card's runs [MPa] (default "
                        f"{','.join(f'{x:g}' for x in DEFAULT_SIGMA3_MPA)})")
    p.add_argument("--lab", default=None,
                   help="the lab CSV: --lab-triaxial's specimens must be among its specimens")
    p.add_argument("--lab-triaxial", default=None,
                   help="lab triaxial points (CSV: specimen, sigma3_MPa, sigma1_MPa)")
    file_arg(p, "--table", "output table: envelopes per card")
    file_arg(p, "--points", "output table: every run, ok or failed")
    file_arg(p, "--figure", "output figure: sigma1 vs sigma3 with the envelopes")
    p.add_argument("--lab-table", default=None,
                   help="output table: the lab points against each card's envelopes "
                        "(with --lab-triaxial)")
    p.set_defaults(func=cmd_envelopes)


def _sigma3_list(text) -> list[float]:
    """--sigma3 of ``bpmcal envelopes``: comma-separated confining stresses >= 0 [MPa]."""
    import math

    try:
        vals = [float(x) for x in str(text).split(",")]
    except ValueError:
        vals = []
    if not vals or any(not (math.isfinite(v) and v >= 0) for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r}: expected comma-separated confining "
                                         "stresses >= 0 in MPa, e.g. 0,5,10,20")
    return vals


def cmd_envelopes(args) -> int:
    from ..stages.triaxial import envelopes

    r = envelopes(args.cards, args.runs, sigma3=args.sigma3, table=args.table, points=args.points,
                  figure=args.figure, lab=args.lab, lab_triaxial=args.lab_triaxial,
                  lab_table=args.lab_table)
    cols = ["specimen", "card", "runs_ok", "runs", "c_MPa", "phi_deg", "mi", "sigma_c_MPa",
            "sigma_t_MPa", "note"]
    print(r["envelopes"].reindex(columns=cols).to_string(index=False))
    return 0


def _add_impact_analyse(p):
    p.add_argument("--main", required=True, help="the reference impact run (6 m/s)")
    file_arg(p, "--runs", "impact runs of the velocity sweep", nargs="+")
    file_arg(p, "--energy", "output table: energy budget of the reference run")
    file_arg(p, "--t10", "output table: t10 vs specific energy")
    file_arg(p, "--jk-fit", "output JSON: the JK fit")
    file_arg(p, "--fig7", "output figure: Fig. 7")
    file_arg(p, "--fig-t10", "output figure: t10 vs Ecs")
    p.set_defaults(func=cmd_impact_analyse)


def cmd_impact_analyse(args) -> int:
    from ..stages.impact_energy import impact_analyse

    r = impact_analyse(args.main, args.runs, energy=args.energy, t10=args.t10, jk_fit=args.jk_fit,
                       fig7=args.fig7, fig_t10_png=args.fig_t10)
    for n in r["notes"]:
        print(n)
    print(r["t10"].to_string())
    print(f"JK fit: {r['fit']}")
    return 0
