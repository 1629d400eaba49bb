"""Subcommands of the study's dataset and analysis: ``design``, ``gather``, ``screen``,
``regress``, ``calibrate``, the bond-strength-ratio sweep (``sweep-plan``,
``sweep-analyse``) and ``report``.

Each ``_add_<cmd>`` (its options, defaults from the stage's or the analysis class's
signature) stands directly above its ``cmd_<cmd>`` (the handler, which calls one stage and
prints its result). xgboost, statsmodels and matplotlib are imported by the stages, inside
the handlers.
"""
from __future__ import annotations

from ..io.checks import BadInput, parse_json
from ..stages import defaults_of
from .args import SEED, integer, limited, number
from .options import file_arg


def _add_design(p):
    from ..study.design import MAX_SAMPLES, lhs_design

    opt = defaults_of(lhs_design)["optimization"]
    p.add_argument("--ranges", required=True,
                   help='JSON mapping of parameter name to [low, high] (paper units)')
    p.add_argument("--n", type=integer("n", 2, MAX_SAMPLES), required=True,
                   help=f"number of samples (at most {MAX_SAMPLES:,})")
    p.add_argument("--seed", type=SEED, required=True, help="design seed")
    p.add_argument("--optimization", default=opt, choices=["random-cd", "lloyd", "none"],
                   help=f"LHS optimisation (default {opt})")
    p.add_argument("--out", required=True, help="output CSV")
    p.set_defaults(func=cmd_design)


def cmd_design(args) -> int:
    from ..stages.dataset import design

    ranges = parse_json(args.ranges, "--ranges")
    opt = None if args.optimization == "none" else args.optimization
    df = design(ranges, args.n, args.seed, args.out, optimization=opt)
    print(f"{args.out}: {len(df)} samples over {sorted(ranges)} (seed {args.seed})")
    return 0


def _add_gather(p):
    p.add_argument("--design", required=True, help="design CSV")
    file_arg(p, "--runs", "the run files, one per sample: <sample_id>.h5 (a sample without "
                          "one is 'missing')", nargs="+")
    p.add_argument("--bts-runs", nargs="+", default=None,
                   help="the Brazilian run files, one per sample: <sample_id>.h5 (adds "
                        "bts_MPa, bts_status, bts_error; a sample without one is 'missing')")
    p.add_argument("--dtt-runs", nargs="+", default=None,
                   help="the direct-tension run files, one per sample: <sample_id>.h5 (adds "
                        "dtt_MPa, dtt_status, dtt_error)")
    p.add_argument("--tri-runs", nargs="+", default=None,
                   help="the triaxial run files at the design confinement, one per sample: "
                        "<sample_id>.h5 (adds tri_MPa, tri_status, tri_error)")
    p.add_argument("--out", required=True, help="output CSV")
    p.set_defaults(func=cmd_gather)


def cmd_gather(args) -> int:
    from ..stages.dataset import gather

    _, report = gather(args.design, args.runs, args.out, bts_runs=args.bts_runs,
                       dtt_runs=args.dtt_runs, tri_runs=args.tri_runs)
    print(report)
    return 0


def _add_screen(p):
    from ..stages.screening import ScreeningSettings
    from ..stages.settings import limits

    d, lim = defaults_of(ScreeningSettings), limits(ScreeningSettings)
    p.add_argument("--dataset", required=True)
    for flag, h in (("--selected", "output JSON: the selected candidates per response"),
                    ("--table3", "output table (CSV, Markdown beside): Table 3"),
                    ("--figure", "output figure (PNG, PDF beside): importance shares"),
                    ("--importance-table", "output table: every importance type"),
                    ("--cv-table", "output table: cross-validated R² of the models"),
                    ("--shadow-table", "output table: largest shadow-feature share"),
                    ("--summary", "output text: the screening summary")):
        file_arg(p, flag, h)
    p.add_argument("--threshold", type=limited("threshold", lim["threshold"]),
                   default=d["threshold"],
                   help=f"selection threshold [%%] (default {d['threshold']:g})")
    p.add_argument("--importance", default=d["importance"], choices=lim["importance"].words,
                   help=f"importance type that drives the selection (default {d['importance']})")
    p.add_argument("--rule", default=d["rule"], choices=lim["rule"].words,
                   help=f"selection rule of σc, E, ν: threshold (the paper's: share above "
                        f"--threshold) or above_noise (also every parameter above the largest "
                        f"shadow share) (default {d['rule']})")
    p.add_argument("--tensile-rule", default=d["tensile_rule"],
                   choices=lim["tensile_rule"].words,
                   help=f"selection rule of σt (default {d['tensile_rule']})")
    p.add_argument("--n-splits", type=limited("n-splits", lim["n_splits"]),
                   default=d["n_splits"], help=f"CV folds (default {d['n_splits']})")
    p.add_argument("--n-repeats", type=limited("n-repeats", lim["n_repeats"]),
                   default=d["n_repeats"],
                   help=f"permutation repeats (default {d['n_repeats']})")
    p.add_argument("--seed", type=SEED, default=d["seed"])
    p.set_defaults(func=cmd_screen)


def cmd_screen(args) -> int:
    from ..stages.screening import ScreeningSettings, screen

    settings = ScreeningSettings(threshold=args.threshold, importance=args.importance,
                                 rule=args.rule, tensile_rule=args.tensile_rule,
                                 n_splits=args.n_splits, n_repeats=args.n_repeats,
                                 seed=args.seed)
    r = screen(args.dataset, selected=args.selected, table3_csv=args.table3,
               figure=args.figure, importance_table=args.importance_table,
               cv_table=args.cv_table, shadow_table=args.shadow_table, summary=args.summary,
               settings=settings)
    print(r["note"])
    for k, v in r["selected"].items():
        print(f"{k}: {', '.join(v)}")
    return 0


def _add_regress(p):
    from ..stages.regression import RegressionSettings
    from ..stages.settings import limits

    d, lim = defaults_of(RegressionSettings), limits(RegressionSettings)
    p.add_argument("--dataset", required=True)
    p.add_argument("--selected", required=True, help="selected.json of the screening")
    for flag, h in (("--models", "output JSON: the fitted models"),
                    ("--equations", "output Markdown: the equations of every stage"),
                    ("--summaries", "output text: the statsmodels summaries"),
                    ("--coefficients", "output table: coefficients"),
                    ("--candidates", "output table: Table 4 over all candidate terms"),
                    ("--table4", "output table: Table 4 (retained terms)"),
                    ("--fit-table", "output table: adjusted and CV R² per stage"),
                    ("--figure", "output figure: predicted vs simulated")):
        file_arg(p, flag, h)
    for name in ("alpha_in", "alpha_out", "vif_max", "hierarchy", "cv_folds", "cv_repeats"):
        opt = name.replace("_", "-")
        if lim[name].kind == "choice":
            p.add_argument(f"--{opt}", default=d[name], choices=lim[name].words)
        else:
            p.add_argument(f"--{opt}", type=limited(opt, lim[name]), default=d[name])
    p.add_argument("--seed", type=SEED, default=d["seed"])
    p.set_defaults(func=cmd_regress)


def cmd_regress(args) -> int:
    from ..stages.regression import RegressionSettings, regress

    settings = RegressionSettings(alpha_in=args.alpha_in, alpha_out=args.alpha_out,
                                  vif_max=args.vif_max, hierarchy=args.hierarchy,
                                  cv_folds=args.cv_folds, cv_repeats=args.cv_repeats,
                                  seed=args.seed)
    r = regress(args.dataset, args.selected, models=args.models, equations=args.equations,
                summaries=args.summaries, coefficients=args.coefficients,
                candidates=args.candidates, table4=args.table4, fit_table=args.fit_table,
                figure=args.figure, settings=settings)
    print(r["note"])
    print(r["equations"])
    return 0


def _add_calibrate(p):
    from ..stages.calibration import CalibrationSettings
    from ..stages.settings import limits

    d, lim = defaults_of(CalibrationSettings), limits(CalibrationSettings)
    p.add_argument("--dataset", required=True)
    p.add_argument("--models", required=True, help="models.json of the regression")
    p.add_argument("--lab", required=True, help="lab CSV")
    file_arg(p, "--cards", "output material cards, one per lab specimen: <specimen>.yaml",
          nargs="+")
    p.add_argument("--table", default=None, help="output table: the calibrated parameters")
    p.add_argument("--fixed", required=True, help="JSON of the fixed parameters")
    p.add_argument("--ranges", required=True,
                   help="JSON of the design space {name: [low, high]} the dataset was sampled "
                        "over (the config's ranges); it bounds the free parameters")
    p.add_argument("--bounds", default=None,
                   help="JSON {name: [low, high]} narrowing --ranges for free parameters "
                        "(the config's calibration.bounds; wider than --ranges is an error)")
    from ..params import MODELS

    free = "; ".join(f"{m.name}: {','.join(m.free)}" for m in MODELS.values())
    pairs = ", ".join(f"{m.ten}/{m.coh} ({m.name})" for m in MODELS.values())
    p.add_argument("--free", default=None,
                   help=f"comma-separated free parameters (default, by the contact model the "
                        f"names use: {free})")
    p.add_argument("--ratio", type=number("ratio", None, lim["strength_ratio"].hi),
                   default=d["strength_ratio"],
                   help=f"strength ratio of the model's strength pair, {pairs} (<= 0: both "
                        f"free; default {d['strength_ratio']:g})")
    p.add_argument("--ratio-from", default=None,
                   help="JSON file with the chosen ratio (the ratio sweep's choice; when it "
                        "holds none, --ratio is used)")
    p.add_argument("--n-boot", type=limited("n-boot", lim["n_boot"]), default=d["n_boot"],
                   help="bootstrap resamples for the intervals (0: no bootstrap, else >= 2; "
                        f"default {d['n_boot']})")
    p.add_argument("--seed", type=SEED, default=d["seed"])
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args) -> int:
    from ..stages.calibration import CalibrationSettings, calibrate

    fixed = parse_json(args.fixed, "--fixed")
    ranges = parse_json(args.ranges, "--ranges")
    bounds = parse_json(args.bounds, "--bounds") if args.bounds else {}
    settings = CalibrationSettings(fixed=fixed, free=args.free.split(",") if args.free else None,
                                   strength_ratio=None if args.ratio <= 0 else args.ratio,
                                   bounds=bounds, n_boot=args.n_boot, seed=args.seed)
    r = calibrate(args.dataset, args.models, args.lab, cards=args.cards, table=args.table,
                  ranges=ranges, settings=settings, ratio_from=args.ratio_from)
    if r["note"]:
        print(r["note"])
    print(r["table"].to_string())
    return 0


def _add_sweep_plan(p):
    from ..stages.ratio_sweep import sweep_plan

    d = defaults_of(sweep_plan)
    p.add_argument("--card", required=True, help="material card (the initial calibration)")
    p.add_argument("--models", required=True)
    p.add_argument("--ratios", default=",".join(f"{x:g}" for x in d["ratios"]),
                   help="start,stop,step (default %(default)s)")
    p.add_argument("--seed", type=SEED, default=d["seed"],
                   help=f"packing seed of the runs (default {d['seed']})")
    p.add_argument("--out", required=True)
    p.set_defaults(func=cmd_sweep_plan)


def _ratios(text) -> tuple[float, float, float]:
    try:
        start, stop, step = (float(x) for x in text.split(","))
    except ValueError:
        raise BadInput(f"--ratios {text!r}: expected start,stop,step (three numbers)") from None
    return start, stop, step


def cmd_sweep_plan(args) -> int:
    from ..stages.ratio_sweep import sweep_plan

    plan = sweep_plan(args.card, args.models, ratios=_ratios(args.ratios), seed=args.seed,
                      out=args.out)
    print(plan.to_string())
    for r in plan[plan["status"] != "planned"].itertuples():
        print(f"{r.sample_id}: {r.status}: {r.reason}")
    return 0


def _add_sweep_analyse(p):
    from ..stages.ratio_sweep import sweep_analyse

    d = defaults_of(sweep_analyse)
    p.add_argument("--plan", required=True)
    file_arg(p, "--runs", "the run files of the plan's rows: <sample_id>.h5", nargs="+")
    p.add_argument("--criterion", default=d["criterion"], choices=["tensile_share", "crack_count"])
    p.add_argument("--target", type=number("target", 0.0), default=d["target"])
    file_arg(p, "--table", "output table: cracks per ratio")
    file_arg(p, "--chosen", "output JSON: the chosen ratio")
    file_arg(p, "--fig4", "output figure: Fig. 4")
    file_arg(p, "--fig5", "output figure: Fig. 5")
    file_arg(p, "--vtk", "output folder: ParaView files of the runs Fig. 5 shows")
    p.set_defaults(func=cmd_sweep_analyse)


def cmd_sweep_analyse(args) -> int:
    from ..stages.ratio_sweep import sweep_analyse

    df, chosen = sweep_analyse(args.plan, args.runs, criterion=args.criterion,
                               target=args.target, table=args.table, chosen=args.chosen,
                               fig4=args.fig4, fig5=args.fig5, vtk=args.vtk)
    print(df.to_string())
    print(f"chosen: {chosen}")
    return 0


def _add_report(p):
    p.add_argument("--outdir", default=None,
                   help="the study's output directory (its files: bpmcal.io.study_files; default: "
                        "the config's outdir)")
    p.add_argument("--config", default=None, help="the study's (merged) config, JSON/YAML")
    p.add_argument("--config-json", default=None,
                   help="... or the config as JSON text (what the workflow passes)")
    p.add_argument("--config-out", default=None, help="also write the config as JSON to this file")
    p.set_defaults(func=cmd_report)


def cmd_report(args) -> int:
    from ..report.build import report

    print(report(args.outdir, config=args.config, config_json=args.config_json,
                 config_out=args.config_out))
    return 0
