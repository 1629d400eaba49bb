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
from .args import SEED, integer, number
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
    from ..analysis import XGBScreening

    d = defaults_of(XGBScreening)
    p.add_argument("--dataset", required=True)
    for flag, h in (("--selected", "output JSON: the selected candidates per response"),
                    ("--table3", "output table (CSV, Markdown beside): Table 3"),
                    ("--figure", "output figure (PNG, PDF beside): importance shares"),
                    ("--importance-table", "output table: every importance type"),
                    ("--cv-table", "output table: cross-validated R² of the models"),
                    ("--shadow-table", "output table: largest shadow-feature share"),
                    ("--summary", "output text: the screening summary")):
        file_arg(p, flag, h)
    p.add_argument("--threshold", type=number("threshold", 0.0, 100.0), default=d["threshold"],
                   help=f"selection threshold [%%] (default {d['threshold']:g})")
    p.add_argument("--importance", default=d["importance"],
                   choices=["gain", "total_gain", "permutation", "shap"],
                   help=f"importance type that drives the selection (default {d['importance']})")
    from ..analysis.screening import RULES
    from ..stages.screening import TENSILE_RULE

    p.add_argument("--rule", default=d["rule"], choices=RULES,
                   help=f"selection rule of σc, E, ν: threshold (the paper's: share above "
                        f"--threshold) or above_noise (also every parameter above the largest "
                        f"shadow share) (default {d['rule']})")
    p.add_argument("--tensile-rule", default=TENSILE_RULE, choices=RULES,
                   help=f"selection rule of σt (default {TENSILE_RULE})")
    p.add_argument("--n-splits", type=integer("n-splits", 2, 100), default=d["n_splits"],
                   help=f"CV folds (default {d['n_splits']})")
    p.add_argument("--n-repeats", type=integer("n-repeats", 1, 1000), default=d["n_repeats"],
                   help=f"permutation repeats (default {d['n_repeats']})")
    p.add_argument("--seed", type=SEED, default=d["seed"])
    p.set_defaults(func=cmd_screen)


def cmd_screen(args) -> int:
    from ..stages.screening import screen

    r = screen(args.dataset, selected=args.selected, table3_csv=args.table3,
               figure=args.figure, importance_table=args.importance_table,
               cv_table=args.cv_table, shadow_table=args.shadow_table, summary=args.summary,
               threshold=args.threshold, importance=args.importance, n_splits=args.n_splits,
               n_repeats=args.n_repeats, seed=args.seed, rule=args.rule,
               tensile_rule=args.tensile_rule)
    print(r["note"])
    for k, v in r["selected"].items():
        print(f"{k}: {', '.join(v)}")
    return 0


def _add_regress(p):
    from ..analysis import StepwiseRegression

    d = defaults_of(StepwiseRegression)
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
    p.add_argument("--alpha-in", type=number("alpha-in", 0.0, 0.5, lo_open=True),
                   default=d["alpha_in"])
    p.add_argument("--alpha-out", type=number("alpha-out", 0.0, 0.5, lo_open=True),
                   default=d["alpha_out"])
    p.add_argument("--vif-max", type=number("vif-max", 1.0), default=d["vif_max"])
    p.add_argument("--hierarchy", default=d["hierarchy"], choices=["strong", "weak", "none"])
    p.add_argument("--cv-folds", type=integer("cv-folds", 2, 100), default=d["cv_folds"])
    p.add_argument("--cv-repeats", type=integer("cv-repeats", 1, 1000), default=d["cv_repeats"])
    p.add_argument("--seed", type=SEED, default=d["seed"])
    p.set_defaults(func=cmd_regress)


def cmd_regress(args) -> int:
    from ..stages.regression import regress

    r = regress(args.dataset, args.selected, models=args.models, equations=args.equations,
                summaries=args.summaries, coefficients=args.coefficients,
                candidates=args.candidates, table4=args.table4, fit_table=args.fit_table,
                figure=args.figure, alpha_in=args.alpha_in, alpha_out=args.alpha_out,
                vif_max=args.vif_max, hierarchy=args.hierarchy, cv_folds=args.cv_folds,
                cv_repeats=args.cv_repeats, seed=args.seed)
    print(r["note"])
    print(r["equations"])
    return 0


def _add_calibrate(p):
    from ..stages.calibration import calibrate

    d = defaults_of(calibrate)
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
    p.add_argument("--ratio", type=number("ratio", None, 100.0), default=d["ratio"],
                   help=f"strength ratio of the model's strength pair, {pairs} (<= 0: both "
                        f"free; default {d['ratio']:g})")
    p.add_argument("--ratio-from", default=None,
                   help="JSON file with the chosen ratio (the ratio sweep's choice; when it "
                        "holds none, --ratio is used)")
    p.add_argument("--n-boot", type=integer("n-boot", 0, 1_000_000), default=d["n_boot"],
                   help="bootstrap resamples for the intervals (0: no bootstrap, else >= 2; "
                        f"default {d['n_boot']})")
    p.add_argument("--seed", type=SEED, default=d["seed"])
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args) -> int:
    from ..stages.calibration import calibrate

    fixed = parse_json(args.fixed, "--fixed")
    ranges = parse_json(args.ranges, "--ranges")
    bounds = parse_json(args.bounds, "--bounds") if args.bounds else {}
    r = calibrate(args.dataset, args.models, args.lab, cards=args.cards, table=args.table,
                  fixed=fixed, ranges=ranges, bounds=bounds,
                  ratio=None if args.ratio <= 0 else args.ratio, ratio_from=args.ratio_from,
                  free=args.free.split(",") if args.free else None, n_boot=args.n_boot,
                  seed=args.seed)
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
