"""Subcommands that run or tabulate the calibrated cards: the closed loop ``verify``,
``transfer`` to full size and ``transfer-table``, the seed ``scatter``, the fresh-seed
check (``fresh-seeds``, ``fresh-seeds-table``), σt at the lab's disc size (``bts-size``),
``verification-tables`` (Tables 5 and 6), the
triaxial ``envelopes`` and ``impact-analyse``.

Each ``_add_<cmd>`` (its options) stands directly above its ``cmd_<cmd>`` (the handler).
``verify``, ``transfer`` and ``fresh-seeds`` share the cylinder, the ``--bts-*`` disc, the
``--dtt-*`` test and the ``--tri-*`` triaxial test (:func:`_add_card_run_args`; read back
as one ``SeedTests``: ``options.seed_tests_of``); the closed loop's options are generated
from ``LoopSettings`` (``options.add_loop_args``), and every DEM command builds one
``RunContext`` (``options.run_context``).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..io.checks import BadInput
from ..stages import defaults_of
from ..stages.progress import Progress
from .args import integer, number, positive
from .options import (
    add_bts_args,
    add_dtt_args,
    add_loop_args,
    add_run_args,
    add_tri_args,
    bts_disc_of,
    bts_settings_of,
    file_arg,
    loop_settings_of,
    run_context,
    run_geometry,
    run_settings,
    seed_tests_of,
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


def _seeds(text) -> list[int]:
    try:
        seeds = [int(x) for x in text.split(",")]
    except ValueError:
        raise BadInput(f"--seeds {text!r}: expected comma-separated integers") from None
    bad = [x for x in seeds if not 0 <= x < 2 ** 32]
    if bad or len(seeds) < 2 or len(set(seeds)) != len(seeds):
        raise BadInput(f"--seeds {text!r}: expected at least 2 different seeds in [0, 2^32)")
    return seeds


#: the closed loop's settings the transfer takes (its --max-rounds are its own)
TRANSFER_LOOP = ("seed", "rtol", "range_margin", "jacobian_update")


def _add_verify(p):
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
    add_loop_args(p)
    _add_card_run_args(p, cmd_verify)


def cmd_verify(args) -> int:
    from ..stages.verification import verify

    prog = Progress(f"verify {Path(args.card).stem}", enabled=not args.quiet)
    v = verify(args.card, args.models, out_card=args.out_card, rounds=args.rounds, run=args.run,
               tests=seed_tests_of(args), loop=loop_settings_of(args),
               ctx=run_context(args, prog), bts_run=args.bts_run,
               seed_runs=args.seed_runs)["verification"]
    prog.done(f"{v['status']} after {v['rounds']} round(s): {v['message']}")
    return 0


def _add_transfer(p):
    from ..stages.transfer import MAX_CORRECTIONS, transfer

    d = defaults_of(transfer)
    p.add_argument("--card", required=True, help="a verified card (bpmcal verify)")
    p.add_argument("--models", required=True)
    file_arg(p, "--out-card", "output: the transferred card (calibrated_at_scale = --scale)")
    file_arg(p, "--rounds", "output table: one row per DEM round at this size")
    file_arg(p, "--run", "output: the run file of the best round")
    p.add_argument("--max-rounds", type=integer("max-rounds", 0, MAX_CORRECTIONS),
                   default=d["max_rounds"],
                   help="correction rounds at most after the transfer run, one DEM run "
                        f"each (default {d['max_rounds']})")
    add_loop_args(p, TRANSFER_LOOP)  # a response within max(rtol, 2 x its seed CV): as is
    _add_card_run_args(p, cmd_transfer)


def cmd_transfer(args) -> int:
    from ..stages.transfer import transfer

    prog = Progress(f"transfer {Path(args.card).stem}", enabled=not args.quiet)
    t = transfer(args.card, args.models, out_card=args.out_card, rounds=args.rounds, run=args.run,
                 tests=seed_tests_of(args, cylinder=False),
                 loop=loop_settings_of(args, TRANSFER_LOOP), ctx=run_context(args, prog),
                 max_rounds=args.max_rounds)["transfer"]
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
                      settings=run_settings(args), rtol=args.rtol, ctx=run_context(args))
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
                        "has a direct-tension target, dtt_MPa; else σt,d is the card's "
                        "prediction)")
    p.add_argument("--tri-runs", nargs="+", default=None,
                   help="output triaxial run files at --design-sigma3, one per seed (needed when "
                        "the card has a triaxial-strength target, tri_MPa)")
    file_arg(p, "--seed-runs", "output table: the responses of every seed")
    _add_card_run_args(p, cmd_fresh_seeds)


def cmd_fresh_seeds(args) -> int:
    from ..stages.fresh_seeds import fresh_seeds

    prog = Progress(f"fresh-seeds {Path(args.card).stem}", enabled=not args.quiet)
    df = fresh_seeds(args.card, seeds=_seeds(args.seeds), runs=args.runs,
                     seed_runs=args.seed_runs, tests=seed_tests_of(args),
                     ctx=run_context(args, prog), bts_runs=args.bts_runs,
                     dtt_runs=args.dtt_runs, tri_runs=args.tri_runs)
    prog.done(f"{int((df['status'] == 'ok').sum())} of {len(df)} seed(s) ok")
    print(df.to_string(index=False))
    return 0


def _add_bts_size(p):
    from ..stages.bts_size import SizeSettings

    d = SizeSettings()
    p.add_argument("--card", required=True, help="a verified card with a bts_MPa target")
    p.add_argument("--lab-diameter", required=True, type=positive("lab-diameter", "mm"),
                   help="the diameter of the lab's Brazilian discs [mm] (the lab CSV's "
                        "bts_diameter_mm)")
    file_arg(p, "--run-dir", "output folder: every disc's run file")
    file_arg(p, "--runs", "output table: one row per disc size and seed")
    file_arg(p, "--sizes", "output table: one row per disc size (seeds, valid, σt mean, SE)")
    file_arg(p, "--fit", "output table: the power-law fit and σt at the lab's size against "
                         "the lab's")
    p.add_argument("--seeds", type=integer("seeds", 2, 1000), default=d.seeds,
                   help=f"packing seeds at every size to start with (default {d.seeds})")
    p.add_argument("--max-seeds", type=integer("max-seeds", 2, 1000), default=d.max_seeds,
                   help="seeds at a size at most, added one at a time while its mean's "
                        f"standard error exceeds --target-se (default {d.max_seeds})")
    p.add_argument("--target-se", type=number("target-se", 0.0, 1.0, lo_open=True,
                                              hi_open=True), default=d.target_se,
                   help="the relative standard error of σt wanted at every size (default "
                        f"{d.target_se:g})")
    p.add_argument("--first-seed", type=integer("first-seed", 0, 2 ** 32 - 1),
                   default=d.first_seed,
                   help=f"the first packing seed (default {d.first_seed}; with --max-seeds below "
                        "2^32)")
    p.add_argument("--middle", action=argparse.BooleanOptionalAction, default=d.middle,
                   help="also measure the disc between the study's and the lab's (their "
                        "geometric mean; --no-middle: not)")
    p.add_argument("--quiet", action="store_true")
    add_run_args(p)
    add_bts_args(p, "bts_")
    p.set_defaults(func=cmd_bts_size)


def cmd_bts_size(args) -> int:
    from ..stages.bts_size import SizeSettings, bts_size

    prog = Progress(f"bts-size {Path(args.card).parent.name}", enabled=not args.quiet)
    sz = SizeSettings(seeds=args.seeds, max_seeds=args.max_seeds, target_se=args.target_se,
                      first_seed=args.first_seed, middle=args.middle)
    r = bts_size(args.card, lab_diameter_mm=args.lab_diameter,
                 disc=bts_disc_of(args, "bts_"), settings=bts_settings_of(args, "bts_"),
                 run_dir=args.run_dir, runs_table=args.runs, sizes_table=args.sizes,
                 fit_table=args.fit, size_settings=sz, ctx=run_context(args, prog),
                 note=lambda line: prog({"note": line}))
    f = r["fit"].iloc[0]
    prog.done(f"σt at {f['lab_diameter_mm']:g} mm: {f['sigma_lab_size_MPa']:.3f} ± "
              f"{f['sigma_lab_size_se']:.3f} MPa ({f['method']}); lab {f['lab_bts_MPa']:g} MPa")
    print(r["sizes"].to_string(index=False))
    print(r["fit"].to_string(index=False))
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
