"""Subcommands of a card's posterior: ``posterior`` (the posterior over the free
parameters, what the targets pin and leave free, reach, refinement runs) and
``predictive`` (the posterior's draws run in DEM: triaxial envelope and impact).

Each ``_add_<cmd>`` (its options) stands directly above its ``cmd_<cmd>`` (the handler).
"""
from __future__ import annotations

from pathlib import Path

from ..stages import defaults_of
from ..stages.progress import Progress
from .args import SEED, integer, number
from .options import file_arg, run_context, run_geometry, run_settings, seed_tests_of
from .verification import _add_card_run_args


def _add_posterior(p):
    from ..analysis.posterior import PosteriorSettings
    from ..stages.posterior import RefineSettings, posterior

    d, s, r = defaults_of(posterior), defaults_of(PosteriorSettings), defaults_of(RefineSettings)
    p.add_argument("--card", required=True, help="a verified card (bpmcal verify)")
    p.add_argument("--dataset", required=True, help="the study's dataset (bpmcal gather)")
    p.add_argument("--models", required=True, help="the regression's models.json: each "
                   "response's stepwise terms are its surrogate's basis")
    p.add_argument("--loop-seeds", default=None,
                   help="the closed loop's seed runs (bpmcal verify --seed-runs)")
    p.add_argument("--fresh-seeds", default=None,
                   help="the fresh-seed check's seed runs (bpmcal fresh-seeds --seed-runs)")
    file_arg(p, "--out-card", "output: the card with its posterior section")
    file_arg(p, "--table", "output table: one row per calibrated parameter")
    file_arg(p, "--predictions", "output table: one row per response, its spread over the "
                                 "posterior")
    file_arg(p, "--netcdf", "output: the draws as arviz InferenceData (NetCDF, .nc)")
    file_arg(p, "--figure", "output: the pair plot (PNG; its PDF beside it)")
    p.add_argument("--learning", default=None,
                   help="output table (optional): the learning curve, the posterior's width "
                        "against the DEM runs near the card")
    p.add_argument("--learning-figure", default=None, help="output (optional): its plot")
    p.add_argument("--refine-runs", default=None,
                   help="output table (optional): the refinement's DEM seed runs")
    p.add_argument("--draws", default=None,
                   help="output table (optional): --n-draws posterior draws for bpmcal "
                        "predictive")
    p.add_argument("--n-draws", type=integer("n-draws", 0, 1000), default=d["n_draws"],
                   help=f"how many draws --draws holds (default {d['n_draws']})")
    p.add_argument("--surrogate", choices=("auto", "gp", "stepwise"), default=s["surrogate"],
                   help="the surrogate: auto (the better held-out prediction near the card), "
                        f"gp or stepwise (default {s['surrogate']})")
    p.add_argument("--posterior-seed", type=SEED, default=s["seed"],
                   help=f"the sampler's seed (default {s['seed']})")
    p.add_argument("--hdi-prob", type=number("hdi-prob", 0.0, 1.0, lo_open=True, hi_open=True),
                   default=s["hdi_prob"], help=f"interval probability (default {s['hdi_prob']:g})")
    p.add_argument("--rhat-max", type=number("rhat-max", 1.0, 2.0, lo_open=True),
                   default=s["rhat_max"], help=f"convergence: R-hat at most (default "
                                               f"{s['rhat_max']:g})")
    p.add_argument("--ess-min", type=integer("ess-min", 10, 1_000_000), default=s["ess_min"],
                   help=f"convergence: effective sample size at least (default {s['ess_min']})")
    p.add_argument("--sampler-max-steps", type=integer("sampler-max-steps", 100, 10_000_000),
                   default=s["max_steps"], help=f"sampler steps at most (default {s['max_steps']})")
    p.add_argument("--refine-max-runs", type=integer("refine-max-runs", 0, 1000),
                   default=r["max_runs"],
                   help="DEM seed runs the refinement may add, measured as the card's closed "
                        "loop measured it (the specimen and loading options must be the "
                        f"loop's; default {r['max_runs']}; 0: none)")
    p.add_argument("--refine-ratio", type=number("refine-ratio", 0.0, 100.0, lo_open=True),
                   default=r["ratio"], help="refine while a target's surrogate error exceeds "
                   f"this multiple of its lab side's sd (default {r['ratio']:g})")
    p.add_argument("--refine-seeds", type=integer("refine-seeds", 1, 50), default=r["seeds"],
                   help=f"packing seeds per refinement point (default {r['seeds']})")
    p.add_argument("--refine-seed", type=SEED, default=r["seed"],
                   help=f"the refinement's first packing seed (default {r['seed']})")
    _add_card_run_args(p, cmd_posterior)


def cmd_posterior(args) -> int:
    from ..analysis.posterior import PosteriorSettings
    from ..stages.posterior import PosteriorOutputs, RefineSettings, posterior

    prog = Progress(f"posterior {Path(args.card).parent.name}", enabled=not args.quiet)
    settings = PosteriorSettings(surrogate=args.surrogate, seed=args.posterior_seed,
                                 hdi_prob=args.hdi_prob, rhat_max=args.rhat_max,
                                 ess_min=args.ess_min, max_steps=args.sampler_max_steps)
    refine = RefineSettings(max_runs=args.refine_max_runs, ratio=args.refine_ratio,
                            seeds=args.refine_seeds, seed=args.refine_seed)
    files = PosteriorOutputs(out_card=args.out_card, table=args.table,
                             predictions=args.predictions, netcdf=args.netcdf,
                             figure=args.figure, learning=args.learning,
                             learning_figure=args.learning_figure,
                             refine_runs=args.refine_runs, draws=args.draws)
    out = posterior(args.card, args.dataset, args.models, files=files,
                    loop_seeds=args.loop_seeds, fresh_seeds=args.fresh_seeds,
                    n_draws=args.n_draws, settings=settings, refine=refine,
                    tests=seed_tests_of(args) if args.refine_max_runs else None,
                    design_sigma3=args.design_sigma3, ctx=run_context(args, prog))["posterior"]
    prog.done(f"{out['status']}: {out['identifiability']} {out['reach']['text']}")
    return 0


def _add_predictive(p):
    from ..lab.impact import ImpactSettings
    from ..lab.triaxial import TriaxialSettings

    im, td = ImpactSettings(), TriaxialSettings()
    p.add_argument("--draws", required=True, help="the posterior's draws (bpmcal posterior "
                   "--draws)")
    p.add_argument("--specimen", required=True, help="the lab specimen the card is of")
    file_arg(p, "--table", "output table: one row per draw (parameters, mi, c, phi, eta_f) "
                           "and the card's")
    p.add_argument("--sigma3", required=True, type=_stresses,
                   help="comma-separated confining stresses [MPa] of every draw's triaxial "
                        "tests (at least two)")
    file_arg(p, "--tri-runs", "output: the triaxial run files, draw by draw, --sigma3 within "
                              "each", nargs="+")
    p.add_argument("--impact-runs", nargs="+", default=None,
                   help="output: each draw's drop-hammer run file (default: no impact)")
    p.add_argument("--envelopes", default=None,
                   help="the study's triaxial envelope table: the verified card's mi, c, phi")
    p.add_argument("--card-impact", default=None,
                   help="the card's reference impact run: its eta_f")
    p.add_argument("--triaxial-seed", type=SEED, default=1, help="packing seed of the "
                   "triaxial runs (the study's triaxial.seed; default 1)")
    p.add_argument("--servo-alpha", type=number("servo-alpha", 0.0, 1.0, lo_open=True),
                   default=td.servo_alpha, help=f"confining servo's factor (default "
                                                f"{td.servo_alpha:g})")
    p.add_argument("--impact-seed", type=SEED, default=1, help="packing seed of the impact "
                   "runs (default 1)")
    p.add_argument("--impact-scale", type=number("impact-scale", 0.0, 4.0, lo_open=True),
                   default=0.5, help="size factor of the impact specimen (the study's "
                                     "impact.scale; default 0.5)")
    p.add_argument("--velocity", type=number("velocity", 0.0, 100.0, lo_open=True, unit="m/s"),
                   default=im.velocity, help=f"hammer velocity (default {im.velocity:g})")
    p.add_argument("--hammer-mass", type=number("hammer-mass", 0.0, lo_open=True, unit="kg"),
                   default=im.hammer_mass, help="hammer mass at full size [kg], scaled by "
                                                f"scale^3 (default {im.hammer_mass:g})")
    p.add_argument("--dp-ratio", type=number("dp-ratio", 0.0, 1.0), default=im.dp_ratio)
    p.add_argument("--anvil-fric", type=number("anvil-fric", 0.0, 10.0), default=im.anvil_fric)
    p.add_argument("--duration-ms", type=number("duration-ms", 0.0, 1000.0, lo_open=True,
                                                 unit="ms"),
                   default=im.duration * 1e3)
    p.add_argument("--record-us", type=number("record-us", 0.0, lo_open=True, unit="us"),
                   default=im.record_dt * 1e6)
    _add_card_run_args(p, cmd_predictive)


def _stresses(text) -> list[float]:
    import argparse

    try:
        v = [float(x) for x in str(text).split(",")]
    except ValueError:
        v = []
    if len(v) < 2 or len(set(v)) != len(v) or not all(0 <= x <= 1000 for x in v):
        raise argparse.ArgumentTypeError(f"{str(text)[:60]!r}: expected at least two different "
                                         "comma-separated stresses in [0, 1000] MPa")
    return v


def cmd_predictive(args) -> int:
    import dataclasses

    from ..lab.impact import ImpactSettings
    from ..lab.triaxial import TriaxialSettings
    from ..stages.predictive import PredictiveSettings, predictive, summarise

    prog = Progress(f"predictive {args.specimen}", enabled=not args.quiet)
    geo = run_geometry(args)
    st = run_settings(args, TriaxialSettings, servo_alpha=args.servo_alpha)
    igeo = dataclasses.replace(geo, scale=args.impact_scale)
    ist = ImpactSettings(velocity=args.velocity,
                         hammer_mass=args.hammer_mass * args.impact_scale ** 3,
                         dp_ratio=args.dp_ratio, anvil_fric=args.anvil_fric,
                         duration=args.duration_ms * 1e-3, record_dt=args.record_us * 1e-6)
    settings = PredictiveSettings(sigma3_MPa=args.sigma3, geometry=geo, tri_settings=st,
                                  impact_geometry=igeo, impact_settings=ist,
                                  tri_seed=args.triaxial_seed, impact_seed=args.impact_seed)
    t = predictive(args.draws, specimen=args.specimen, tri_runs=args.tri_runs, table=args.table,
                   settings=settings, impact_runs=args.impact_runs, envelopes=args.envelopes,
                   card_impact=args.card_impact, ctx=run_context(args, prog))
    prog.done(summarise(t).to_string())
    return 0
