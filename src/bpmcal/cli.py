"""The ``bpmcal`` command: one subcommand per job of the study (workflow rules call these).

    bpmcal ucs --params FILE.yaml --out RUN.h5 [--set NAME=VALUE ...] [--scale S] [--seed N]
    bpmcal bts --params FILE.yaml --out RUN.h5 [--scale S] [--seed N] [--platen-velocity V]
    bpmcal dtt --params FILE.yaml --out RUN.h5 [--scale S] [--seed N] [--grip-velocity V]
    bpmcal triaxial --params FILE.yaml --sigma3 MPA --out RUN.h5 [--scale S] [--seed N]
    bpmcal summary RUN.h5 [--json]
    bpmcal vtk RUN.h5 --out DIR

Parameters are in the paper's units at this edge (mm, GPa, MPa, degrees); the package
works in SI inside. Bad input (arguments, parameter values, input files, output paths,
resource budgets) is reported before any work starts as one line on stderr,
``bpmcal CMD: error: ...``, with exit code 2, and nothing is written. Exit codes: 0 done,
1 internal error (a bug: traceback and a hint), 2 bad input, 3 the DEM run failed and its
failure record was written (0 with ``--failed-ok``, what the workflow rules pass),
4 system error (disk full, permission), 130 interrupted.

This module only parses arguments and calls one stage (``bpmcal.stages``, the report) or
one I/O helper; argument types and exit codes: ``bpmcal.cli_args``. Every default comes
from the settings it sets (the lab tests' settings dataclasses, ``Geometry``, the
analysis classes and the stage functions: :func:`defaults_of`), never a literal here.
Each subcommand's options are added by its ``_add_<cmd>`` function, which imports what
that command needs, and ``main`` builds only the parser of the command it runs: a DEM
job (``bpmcal ucs``, 150 per study) does not load xgboost, statsmodels or matplotlib.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import traceback
from pathlib import Path

from . import params as P
from .cli_args import (
    EXIT_BAD_INPUT,
    EXIT_BUG,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_RUN_FAILED,
    EXIT_SYSTEM,
    SEED,
    THREADS,
    Parser,
    choice,
    fraction,
    integer,
    number,
    positive,
)
from .io.checks import BadInput, parse_json
from .lab.budget import GENESIS_MAX_STEPS, MAX_BALLS
from .stages import defaults_of
from .stages.progress import Progress


def _param_help() -> str:
    rows = ["meso-parameters (keys of the --params YAML file and of --set; paper units):"]
    for p in P.PARAMS.values():
        unit = p.unit or "-"
        rows.append(f"  {p.name:12s} {p.symbol:9s} [{unit:3s}] Table 2 range {p.lo:g}-{p.hi:g}:"
                    f" {p.description}")
    rows.append("exit codes: 0 done, 2 bad input (nothing written), 3 the run failed and its "
                "failure record was written (0 with --failed-ok), 1 internal error, "
                "4 system error, 130 interrupted")
    return "\n".join(rows)


# ------------------------------------------------------------------------ DEM runs
def _run_done(a, cmd: str, out, path=None) -> int:
    """Exit code of a DEM run command (its output ``path``, default --out); the FAILED line
    is printed even with --quiet."""
    if out.status == "ok":
        return EXIT_OK
    where = (f"failure record written to {out.path}; the good run in {out.kept} was kept"
             if out.kept else "failure record written")
    print(f"bpmcal {cmd}: FAILED: {path or a.out}: {out.error} ({where})", file=sys.stderr)
    sys.stderr.flush()
    return EXIT_OK if a.failed_ok and not out.kept else EXIT_RUN_FAILED


def _budget(a) -> dict:
    return {"max_balls": a.max_balls, "mem_budget_mb": a.mem_budget_mb,
            "genesis_max_steps": a.genesis_max_steps}


def run_geometry(a):
    from .lab.runner import Geometry

    return Geometry(scale=a.scale, diameter_mm=a.diameter, height_mm=a.height,
                    sigma0_MPa=a.sigma0, install_gap_mm=a.install_gap,
                    relax_ratio=a.relax_ratio, genesis=a.genesis)


def run_settings(a, cls=None, **extra):
    """The loading settings (``cls``: UCSSettings, the default, or TriaxialSettings)."""
    if cls is None:
        from .lab.ucs import UCSSettings as cls
    return cls(platen_velocity=a.platen_velocity, strain_rate=a.strain_rate,
               damping=a.damping, stop_drop=a.stop_drop, max_strain=a.max_strain,
               platen_fric=a.platen_fric, record_strain=a.record_strain,
               end_cap=a.end_cap, end_cap_factor=a.end_cap_factor, **extra)


def _lab_test(a, test: str, geometry, settings, done_line) -> int:
    """``ucs``, ``bts`` and ``triaxial``: the run file (``stages.runs.lab_test_file``), its
    one-line result and the exit code."""
    return _lab_tests(a, [(test, a.out, geometry, settings, done_line)])


def _lab_tests(a, tests, flags=None) -> int:
    """Lab tests of one parameter set in one process (``stages.runs.lab_test_files``;
    ``tests``: (test, out, geometry, settings, done_line)): their run files, a one-line
    result each, and the exit code (that of the first test that did not succeed)."""
    from .stages.runs import lab_test_files

    progs = [Progress(f"{t} {Path(o).name}", enabled=not a.quiet) for t, o, *_ in tests]
    outs = lab_test_files([(t, o, g, st) for t, o, g, st, _ in tests], params_file=a.params,
                          sets=a.set, design=a.design, sample=a.sample, seed=a.seed,
                          cache=a.specimen_cache, threads=a.threads, progress=progs,
                          flags=flags, **_budget(a))
    rc = EXIT_OK
    for (test, path, _, _, done_line), prog, out in zip(tests, progs, outs):
        prog.done(f"{path}: {done_line(out.summary)}" if out.status == "ok" and out.summary
                  else "")
        r = _run_done(a, test, out, path)
        rc = r if rc == EXIT_OK else rc
    return rc


def _ucs_line(s):
    return (f"sigma_c = {s['ucs_MPa']:.3f} MPa, E = {s['E_GPa']:.3f} GPa, "
            f"nu = {s['nu']:.3f}, cracks {s['cracks_tension']}+{s['cracks_shear']}, "
            f"{s['n_balls']} balls, {s['steps']} steps, {s['wall_s']:.1f} s "
            f"({s['stop_reason']})")


def _bts_line(s):
    if not s.get("bts_valid", True):
        return (f"INVALID ({s.get('bts_invalid_reason', '')}); peak stress "
                f"{s['bts_peak_MPa']:.3f} MPa is no sigma_t, {s['n_balls']} balls, "
                f"{s['steps']} steps, {s['wall_s']:.1f} s ({s['stop_reason']})")
    return (f"sigma_t = {s['bts_MPa']:.3f} MPa (peak load {s['peak_load_N']:.1f} N, "
            f"platen forces differ by {100 * s['platen_mismatch']:.2f} %), cracks "
            f"{s['cracks_tension']}+{s['cracks_shear']}, {s['n_balls']} balls, "
            f"{s['steps']} steps, {s['wall_s']:.1f} s ({s['stop_reason']})")


def cmd_ucs(a) -> int:
    tests = [("ucs", a.out, run_geometry(a), run_settings(a), _ucs_line)]
    flags = ["--out"]
    if a.bts_out is not None:  # the study's sample job: the Brazilian test in this process
        tests.append(("bts", a.bts_out, bts_disc_of(a, "bts_"), bts_settings_of(a, "bts_"),
                      _bts_line))
        flags.append("--bts-out")
    if a.dtt_out is not None:  # ... and the direct-tension test
        tests.append(("dtt", a.dtt_out, dtt_cylinder_of(a, "dtt_"),
                      dtt_settings_of(a, "dtt_"), _dtt_line))
        flags.append("--dtt-out")
    return _lab_tests(a, tests, flags=flags)


def cmd_bts(a) -> int:
    return _lab_test(a, "bts", bts_disc_of(a), bts_settings_of(a), _bts_line)


def _dtt_line(s):
    st = (f"sigma_t = {s['dtt_MPa']:.3f} MPa" if s.get("dtt_valid")
          else f"INVALID ({s.get('dtt_invalid_reason', '')}); peak stress "
               f"{s['dtt_peak_MPa']:.3f} MPa is no sigma_t")
    return (f"{st}, fracture at {s['fracture_height']:.2f} of the gauge length, cracks "
            f"{s['cracks_tension']}+{s['cracks_shear']}, {s['n_balls']} balls, "
            f"{s['steps']} steps, {s['wall_s']:.1f} s ({s['stop_reason']})")


def cmd_dtt(a) -> int:
    return _lab_test(a, "dtt", dtt_cylinder_of(a), dtt_settings_of(a), _dtt_line)


def cmd_triaxial(a) -> int:
    from .lab.triaxial import TriaxialSettings

    st = run_settings(a, TriaxialSettings, sigma3=a.sigma3 * 1e6, servo_alpha=a.servo_gain,
                      servo_interval=a.servo_interval)

    def line(s):
        dev = (f"{100 * s['sigma3_maxdev_rel']:.2f} %" if a.sigma3 > 0
               else f"{s['sigma3_maxdev_MPa']:.3f} MPa")
        return (f"sigma3 = {a.sigma3:g} MPa, sigma1 = {s['sigma1_MPa']:.3f} MPa, "
                f"E = {s['E_GPa']:.3f} GPa, nu = {s['nu']:.3f}, sigma3 held within {dev} "
                f"up to the peak, cracks {s['cracks_tension']}+{s['cracks_shear']}, "
                f"{s['steps']} steps, {s['wall_s']:.1f} s ({s['stop_reason']})")

    return _lab_test(a, "triaxial", run_geometry(a), st, line)


def cmd_impact(a) -> int:
    from .lab.impact import ImpactSettings
    from .stages.runs import impact_file

    st = ImpactSettings(velocity=a.velocity, hammer_mass=a.hammer_mass * a.scale ** 3,
                        dp_ratio=a.dp_ratio, platen_fric=a.anvil_fric,
                        duration=a.duration_ms * 1e-3, record_dt=a.record_us * 1e-6)
    prog = Progress(f"impact {Path(a.out).name}", enabled=not a.quiet)
    out = impact_file(a.card, a.out, geometry=run_geometry(a), settings=st, seed=a.seed,
                      cache=a.specimen_cache, threads=a.threads, progress=prog, **_budget(a))
    if out.status == "ok":
        s = out.summary
        prog.done(f"{a.out}: W_in = {s['W_in_J']:.3f} J, G_f = {s['G_f_J']:.3f} J, eta_f = "
                  f"{100 * s['eta_f']:.1f} %, t10 = {s['t10_pct']:.1f} %, closure "
                  f"{100 * s['closure_rel_max']:.3f} %, {s['steps']} steps, {s['wall_s']:.0f} s")
    else:
        prog.done()
    return _run_done(a, "impact", out)


# ------------------------------------------------------------------------ the study
def cmd_design(a) -> int:
    from .stages.study import design

    ranges = parse_json(a.ranges, "--ranges")
    opt = None if a.optimization == "none" else a.optimization
    df = design(ranges, a.n, a.seed, a.out, optimization=opt)
    print(f"{a.out}: {len(df)} samples over {sorted(ranges)} (seed {a.seed})")
    return 0


def cmd_gather(a) -> int:
    from .stages.study import gather

    _, report = gather(a.design, a.runs, a.out, bts_runs=a.bts_runs, dtt_runs=a.dtt_runs)
    print(report)
    return 0


def cmd_screen(a) -> int:
    from .stages.analysis import screen

    r = screen(a.dataset, selected=a.selected, table3_csv=a.table3, figure=a.figure,
               importance_table=a.importance_table, cv_table=a.cv_table,
               shadow_table=a.shadow_table, summary=a.summary, threshold=a.threshold,
               importance=a.importance, n_splits=a.splits, n_repeats=a.repeats, seed=a.seed)
    print(r["note"])
    for k, v in r["selected"].items():
        print(f"{k}: {', '.join(v)}")
    return 0


def cmd_regress(a) -> int:
    from .stages.analysis import regress

    r = regress(a.dataset, a.selected, models=a.models, equations=a.equations,
                summaries=a.summaries, coefficients=a.coefficients, candidates=a.candidates,
                table4=a.table4, fit_table=a.fit_table, figure=a.figure,
                alpha_in=a.alpha_in, alpha_out=a.alpha_out, vif_max=a.vif_max,
                hierarchy=a.hierarchy, cv_folds=a.cv_folds, cv_repeats=a.cv_repeats,
                seed=a.seed)
    print(r["note"])
    print(r["equations"])
    return 0


def cmd_calibrate(a) -> int:
    from .stages.analysis import calibrate

    fixed = parse_json(a.fixed, "--fixed")
    ranges = parse_json(a.ranges, "--ranges")
    bounds = parse_json(a.bounds, "--bounds") if a.bounds else {}
    r = calibrate(a.dataset, a.models, a.lab, cards=a.cards, table=a.table, fixed=fixed,
                  ranges=ranges, bounds=bounds, ratio=None if a.ratio <= 0 else a.ratio,
                  ratio_from=a.ratio_from, free=a.free.split(",") if a.free else None,
                  n_boot=a.n_boot, seed=a.seed)
    if r["note"]:
        print(r["note"])
    print(r["table"].to_string())
    return 0


def cmd_verify(a) -> int:
    from .stages.analysis import verify

    prog = Progress(f"verify {Path(a.card).stem}", enabled=not a.quiet)
    v = verify(a.card, a.models, out_card=a.out_card, rounds=a.rounds, run=a.run,
               geometry=run_geometry(a), settings=run_settings(a), seed=a.seed,
               seeds_per_round=a.seeds_per_round, max_seeds=a.max_seeds, rtol=a.rtol,
               max_rounds=a.max_rounds, cache=a.specimen_cache,
               threads=a.threads, progress=prog, from_unreachable=a.from_unreachable,
               bts_run=a.bts_run, bts_geometry=bts_disc_of(a, "bts_"),
               bts_settings=bts_settings_of(a, "bts_"), range_margin=a.range_margin,
               polish=a.polish, dtt_geometry=dtt_cylinder_of(a, "dtt_"),
               dtt_settings=dtt_settings_of(a, "dtt_"), **_budget(a))["verification"]
    prog.done(f"{v['status']} after {v['rounds']} round(s): {v['message']}")
    return 0


def cmd_transfer(a) -> int:
    from .stages.analysis import transfer

    prog = Progress(f"transfer {Path(a.card).stem}", enabled=not a.quiet)
    t = transfer(a.card, a.models, out_card=a.out_card, rounds=a.rounds, run=a.run,
                 geometry=run_geometry(a), settings=run_settings(a), seed=a.seed,
                 max_rounds=a.max_rounds, rtol=a.rtol, cache=a.specimen_cache,
                 threads=a.threads, progress=prog, bts_geometry=bts_disc_of(a, "bts_"),
                 bts_settings=bts_settings_of(a, "bts_"), range_margin=a.range_margin,
                 dtt_settings=dtt_settings_of(a, "dtt_"), **_budget(a))["transfer"]
    prog.done(f"{t['status']} after {t['rounds']} round(s) at scale {t['scale']:g}: "
              f"{t['message']}")
    return 0


def cmd_transfer_table(a) -> int:
    from .stages.analysis import transfer_table

    print(transfer_table(a.cards, table=a.table).to_string(index=False))
    return 0


def _seeds(text) -> list[int]:
    try:
        seeds = [int(x) for x in text.split(",")]
    except ValueError:
        raise BadInput(f"--seeds {text!r}: expected comma-separated integers") from None
    bad = [x for x in seeds if not 0 <= x < 2 ** 32]
    if bad or len(seeds) < 2 or len(set(seeds)) != len(seeds):
        raise BadInput(f"--seeds {text!r}: expected at least 2 different seeds in [0, 2^32)")
    return seeds


def cmd_scatter(a) -> int:
    from .stages.analysis import seed_scatter

    sc = seed_scatter(a.card, runs=a.runs, seeds=_seeds(a.seeds), seed_runs=a.seed_runs,
                      table=a.table, geometry=run_geometry(a), settings=run_settings(a),
                      rtol=a.rtol, cache=a.specimen_cache, threads=a.threads, **_budget(a))
    print(sc.to_string())
    return 0


def cmd_holdout(a) -> int:
    from .stages.holdout import holdout

    prog = Progress(f"holdout {Path(a.card).stem}", enabled=not a.quiet)
    df = holdout(a.card, seeds=_seeds(a.seeds), runs=a.runs, seed_runs=a.seed_runs,
                 bts_runs=a.bts_runs, geometry=run_geometry(a), settings=run_settings(a),
                 bts_geometry=bts_disc_of(a, "bts_"), bts_settings=bts_settings_of(a, "bts_"),
                 dtt_runs=a.dtt_runs, dtt_geometry=dtt_cylinder_of(a, "dtt_"),
                 dtt_settings=dtt_settings_of(a, "dtt_"), cache=a.specimen_cache,
                 threads=a.threads, progress=prog, **_budget(a))
    prog.done(f"{int((df['status'] == 'ok').sum())} of {len(df)} seed(s) ok")
    print(df.to_string(index=False))
    return 0


def cmd_holdout_table(a) -> int:
    from .stages.holdout import holdout_table

    print(holdout_table(a.cards, a.seed_runs, table=a.table, rtol=a.rtol, z=a.z)
          .to_string(index=False))
    return 0


def cmd_vtables(a) -> int:
    from .stages.analysis import verification_tables

    r = verification_tables(a.cards, a.runs, a.lab, table5=a.table5, table6=a.table6,
                            figure=a.figure)
    print(r["table5"].to_string())
    print(r["table6"].to_string())
    return 0


def cmd_envelopes(a) -> int:
    from .stages.triaxial import envelopes

    r = envelopes(a.cards, a.runs, sigma3=a.sigma3, table=a.table, points=a.points,
                  figure=a.figure, lab=a.lab, lab_triaxial=a.lab_triaxial,
                  lab_table=a.lab_table)
    cols = ["specimen", "card", "runs_ok", "runs", "c_MPa", "phi_deg", "mi", "sigma_c_MPa",
            "sigma_t_MPa", "note"]
    print(r["envelopes"].reindex(columns=cols).to_string(index=False))
    return 0


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


def _ratios(text) -> tuple[float, float, float]:
    try:
        start, stop, step = (float(x) for x in text.split(","))
    except ValueError:
        raise BadInput(f"--ratios {text!r}: expected start,stop,step (three numbers)") from None
    return start, stop, step


def cmd_sweep_plan(a) -> int:
    from .stages.fracture import sweep_plan

    plan = sweep_plan(a.card, a.models, ratios=_ratios(a.ratios), seed=a.seed, out=a.out)
    print(plan.to_string())
    for r in plan[plan["status"] != "planned"].itertuples():
        print(f"{r.sample_id}: {r.status}: {r.reason}")
    return 0


def cmd_sweep_analyse(a) -> int:
    from .stages.fracture import sweep_analyse

    df, chosen = sweep_analyse(a.plan, a.runs, criterion=a.criterion, target=a.target,
                               table=a.table, chosen=a.chosen, fig4=a.fig4, fig5=a.fig5,
                               vtk=a.vtk)
    print(df.to_string())
    print(f"chosen: {chosen}")
    return 0


def cmd_impact_analyse(a) -> int:
    from .stages.fracture import impact_analyse

    r = impact_analyse(a.main, a.runs, energy=a.energy, t10=a.t10, jk_fit=a.jk_fit,
                       fig7=a.fig7, fig_t10_png=a.fig_t10)
    for n in r["notes"]:
        print(n)
    print(r["t10"].to_string())
    print(f"JK fit: {r['fit']}")
    return 0


def cmd_report(a) -> int:
    from .report.build import report

    print(report(a.outdir, config=a.config, config_json=a.config_json,
                 config_out=a.config_out))
    return 0


def cmd_summary(a) -> int:
    from .io.h5 import json_safe, read_summary

    s = read_summary(a.run)
    if a.json:
        print(json.dumps(json_safe(s), sort_keys=True))
    else:
        for k in sorted(s):
            print(f"{k:24s} {s[k]}")
    return 0


def cmd_vtk(a) -> int:
    from .io.checks import out_dir
    from .io.h5 import read_summary
    from .io.vtk import export_run

    s = read_summary(a.run)
    if s.get("status") != "ok":
        raise BadInput(f"{a.run}: a failure record (status {s.get('status')}: "
                       f"{s.get('error', '')}), no particles to export")
    out_dir(a.out, "--out")
    for f in export_run(a.run, a.out):
        print(f)
    return 0


# ------------------------------------------------------------------------ shared options
def add_source_args(p):
    """Where a DEM run command takes its parameters and seed from, and its output file."""
    src = p.add_mutually_exclusive_group()
    src.add_argument("--params", default=None,
                     help="YAML file with the 8 meso-parameters (or a material card)")
    src.add_argument("--design", default=None,
                     help="take the parameters and the seed from this design CSV ...")
    p.add_argument("--sample", default=None, help="... row with this sample_id")
    p.add_argument("--out", required=True, help="output HDF5 file (written atomically)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="override one parameter (repeatable)")
    p.add_argument("--seed", type=SEED, default=None,
                   help="packing seed (default 1, or the design row's)")


FAILED_OK_HELP = ("a failed run (failure record written) exits 0 instead of 3; the workflow "
                  "passes this so that one failed sample does not stop the study")


def add_outcome_args(p):
    """How a DEM run command reports: progress, and the exit code of a failed run."""
    p.add_argument("--quiet", action="store_true",
                   help="no progress output (a FAILED line is still printed)")
    p.add_argument("--failed-ok", action="store_true", help=FAILED_OK_HELP)


def add_budget_args(p):
    """Resource guards of a DEM command (checked before any work)."""
    p.add_argument("--max-balls", type=integer("max-balls", 1), default=MAX_BALLS,
                   help="refuse a specimen estimated to hold more balls than this "
                        f"(default {MAX_BALLS:,})")
    p.add_argument("--mem-budget-mb", type=positive("mem-budget-mb", "MB"), default=None,
                   help="refuse a run estimated to need more memory than this [MB] "
                        "(default 80 %% of this machine's memory)")
    p.add_argument("--genesis-max-steps", type=integer("genesis-max-steps", 1000),
                   default=GENESIS_MAX_STEPS,
                   help="a specimen that has not settled after this many steps is a failed "
                        f"run (default {GENESIS_MAX_STEPS:,})")


GENESES = ("bpmcal", "pfc")  # = lab.specimen.GENESES (tested equal)


def add_specimen_args(p, geo=None, what: str = "the 50 x 100 mm cylinder"):
    """The specimen of a DEM command (``Geometry``'s fields; defaults from ``geo``)."""
    from .lab.runner import Geometry

    geo = geo or Geometry()
    p.add_argument("--scale", type=number("scale", 0.0, 10.0, lo_open=True), default=geo.scale,
                   help=f"specimen size factor on {what} (default {geo.scale:g})")
    p.add_argument("--sigma0", type=number("sigma0", 0.0, 100.0, unit="MPa"),
                   default=geo.sigma0_MPa, help="locked-in isotropic stress after genesis "
                                                f"[MPa] (default {geo.sigma0_MPa:g})")
    p.add_argument("--install-gap", type=number("install-gap", 0.0, 1.0, unit="mm"),
                   default=geo.install_gap_mm,
                   help="bond pairs with surface gap <= this [mm] (default: the genesis's, 0 "
                        "for bpmcal, 0.0625 Rmin for pfc)")
    p.add_argument("--genesis", choices=GENESES, default=geo.genesis,
                   help="specimen genesis after the packing: bpmcal (locked-in stress relieved "
                        "to --sigma0, bonds on touching pairs) or pfc (Itasca's tutorial "
                        "practice: every overlap relieved to zero force, bonds within a "
                        f"positive gap); default {geo.genesis}")
    p.add_argument("--relax-ratio", type=number("relax-ratio", 0.0, 0.1, lo_open=True),
                   default=geo.relax_ratio,
                   help="genesis equilibrium: mean unbalanced-force ratio "
                        f"(default {geo.relax_ratio:g})")
    p.add_argument("--threads", type=THREADS, default=None, help="numba threads (>= 1)")
    p.add_argument("--specimen-cache", default=None,
                   help="directory of cached packings (default ~/.cache/bpmcal/packings or "
                        "$BPMCAL_SPECIMEN_CACHE)")
    add_budget_args(p)


def add_run_args(p, loading=None):
    """Options of the cylinder and of its axial loading (shared by ucs, triaxial, verify,
    scatter, impact); the loading defaults are ``loading``'s (default ``UCSSettings()``)."""
    from .lab.runner import Geometry
    from .lab.ucs import UCSSettings

    geo, ld = Geometry(), loading or UCSSettings()
    p.add_argument("--diameter", type=positive("diameter", "mm"), default=geo.diameter_mm,
                   help=f"specimen diameter before scaling [mm] (default {geo.diameter_mm:g})")
    p.add_argument("--height", type=positive("height", "mm"), default=geo.height_mm,
                   help=f"specimen height before scaling [mm] (default {geo.height_mm:g})")
    p.add_argument("--record-strain", type=number("record-strain", 0.0, 0.01, lo_open=True),
                   default=ld.record_strain,
                   help=f"axial strain between records (default {ld.record_strain:g})")
    p.add_argument("--platen-velocity", type=number("platen-velocity", 0.0, 100.0,
                                                    lo_open=True, unit="m/s"),
                   default=ld.platen_velocity,
                   help=f"speed of each platen [m/s] (default {ld.platen_velocity:g})")
    p.add_argument("--strain-rate", type=positive("strain-rate", "1/s"), default=ld.strain_rate,
                   help="axial strain rate [1/s]; overrides --platen-velocity "
                        "(each platen then moves at rate x H / 2)")
    p.add_argument("--damping", type=number("damping", 0.0, 1.0, hi_open=True),
                   default=ld.damping, help=f"local damping in [0, 1) (default {ld.damping:g})")
    p.add_argument("--stop-drop", type=fraction("stop-drop"), default=ld.stop_drop,
                   help="stop when stress < this fraction of the peak after it "
                        f"(default {ld.stop_drop:g})")
    p.add_argument("--max-strain", type=number("max-strain", 0.0, 0.5, lo_open=True),
                   default=ld.max_strain,
                   help=f"stop at this axial strain (default {ld.max_strain:g})")
    p.add_argument("--platen-fric", type=number("platen-fric", 0.0, 10.0),
                   default=ld.platen_fric,
                   help=f"platen friction coefficient in [0, 10] (default {ld.platen_fric:g})")
    p.add_argument("--end-cap", type=number("end-cap", 0.0, 10.0), default=ld.end_cap,
                   metavar="D",
                   help="end caps: the bonds within D mean ball diameters of a platen get "
                        "--end-cap-factor x their strength (not their stiffness), so that the "
                        "wall-packed end layers do not decide the strength; 0 = none, 1 = the "
                        f"first layer of balls (default {ld.end_cap:g}; README \"Where the "
                        "specimens fail\")")
    p.add_argument("--end-cap-factor", type=number("end-cap-factor", 1.0, 1e6),
                   default=ld.end_cap_factor,
                   help="strength factor of the end caps' bonds in [1, 1e6] "
                        f"(default {ld.end_cap_factor:g})")
    add_specimen_args(p, geo)


def _file(p, flag, help_, nargs=None):
    """A required file option (an input or a declared output of the job)."""
    p.add_argument(flag, required=True, nargs=nargs, help=help_)


# ------------------------------------------------------------------------ subcommands
def _add_ucs(p):
    add_source_args(p)
    add_run_args(p)
    p.add_argument("--bts-out", default=None,
                   help="also run the Brazilian test of the same parameters and packing seed "
                        "(the --bts-* options below; the disc at --scale with the cylinder's "
                        "genesis options) into this HDF5 file, in the same process after the "
                        "UCS test: the study's sample job (one start-up instead of two); each "
                        "test writes its run file or failure record")
    add_bts_args(p, "bts_")
    p.add_argument("--dtt-out", default=None,
                   help="also run the direct-tension test of the same parameters and packing "
                        "seed (the --dtt-* options below; the cylinder of --diameter x "
                        "--height at --dtt-scale) into this HDF5 file, after the other tests")
    add_dtt_args(p, "dtt_")
    add_outcome_args(p)
    p.set_defaults(func=cmd_ucs)


def _add_bts(p):
    from .lab.runner import bts_geometry

    add_source_args(p)
    add_bts_args(p)
    add_specimen_args(p, bts_geometry(), "the ISRM 50 x 25 mm disc")
    add_outcome_args(p)
    p.set_defaults(func=cmd_bts)


#: BTSSettings fields that are command options: ``bpmcal bts --FIELD`` and, for the closed
#: loop of a card with a σt target, ``bpmcal verify/transfer --bts-FIELD`` (the study
#: passes its `bts` section to all three, so σt is measured as for the regression's model)
BTS_OPTIONS = ("loading", "jaw_ratio", "contact_cap", "contact_cap_factor", "central_zone",
               "platen_velocity", "approach_velocity", "platen_fric", "damping", "stop_drop",
               "post_peak_min", "max_strain", "record_strain")


def add_bts_args(p, prefix: str = ""):
    """The Brazilian disc and loading options (defaults: ``BTSSettings`` and the ISRM disc)
    on ``p``: ``--OPTION``, or ``--bts-OPTION`` with ``prefix="bts_"`` (verify, transfer);
    read back by :func:`bts_settings_of` and :func:`bts_disc_of` with the same prefix."""
    from .lab.brazilian import BTSSettings
    from .lab.runner import BTS_DIAMETER_MM, BTS_THICKNESS_MM

    bd = BTSSettings()  # the defaults of the Brazilian test live in its settings
    g = p.add_argument_group("Brazilian test" + (" of a card with a tensile-strength target"
                                                 if prefix else ""))

    def lab(name):  # the option without its dashes: "platen-velocity", "bts-damping"
        return (prefix + name).replace("_", "-")

    def opt(name):
        return "--" + lab(name)

    g.add_argument(opt("diameter"), type=positive(lab("diameter"), "mm"),
                   default=BTS_DIAMETER_MM,
                   help=f"disc diameter before scaling [mm] (default {BTS_DIAMETER_MM:g})")
    if prefix:  # `bpmcal bts` scales its disc with its own --scale
        g.add_argument(opt("scale"), type=number(lab("scale"), 0.0, 10.0, lo_open=True),
                       default=None,
                       help="size factor of the disc (default: the cylinder's --scale); the "
                            "disc is sized for the sigma_t measurement (README: resolution)")
    g.add_argument(opt("thickness"), type=positive(lab("thickness"), "mm"),
                   default=BTS_THICKNESS_MM,
                   help=f"disc thickness before scaling [mm] (default {BTS_THICKNESS_MM:g}, "
                        "ISRM t = D/2)")
    from .lab.brazilian import LOADINGS

    spec = {
        "loading": (choice(lab("loading"), LOADINGS),
                    "how the disc is loaded: flat (two planar platens) or jaws (ISRM curved "
                    "jaws, radius --jaw-ratio x the disc's) (default {d})"),
        "jaw_ratio": (number(lab("jaw_ratio"), 1.0, 100.0, lo_open=True),
                      "jaw radius / disc radius, > 1 (default {d:g}, ISRM)"),
        "contact_cap": (number(lab("contact_cap"), 0.0, 10.0),
                        "contact caps: the bonds within this many mean ball diameters of a "
                        "loading contact get --contact-cap-factor x their strength (not "
                        "their stiffness), so that the test fails in the disc, not at its "
                        "contacts; 0 = none (default {d:g})"),
        "contact_cap_factor": (number(lab("contact_cap_factor"), 1.0, 1e6),
                               "strength factor of the contact caps' bonds (default {d:g})"),
        "central_zone": (number(lab("central_zone"), 0.0, 1.0, lo_open=True),
                         "a valid fracture starts within this fraction of the radius of the "
                         "disc centre along the loaded diameter (default {d:g}, ISRM)"),
        "platen_velocity": (number(lab("platen_velocity"), 0.0, 100.0, lo_open=True,
                                   unit="m/s"),
                            "speed of each platen [m/s] (default {d:g}: halving it changes "
                            "sigma_t by < 2 %%, see the README)"),
        "approach_velocity": (number(lab("approach_velocity"), 0.0, 100.0, unit="m/s"),
                              "speed of each platen until the first crack [m/s] (default "
                              "{d:g}: off, the whole test at the platen velocity)"),
        "platen_fric": (number(lab("platen_fric"), 0.0, 10.0),
                        "platen friction coefficient (default {d:g}; with 0 the free disc "
                        "spins on the platens before it seats, and sigma_t is ~15 %% lower)"),
        "damping": (number(lab("damping"), 0.0, 1.0, hi_open=True),
                    "local damping in [0, 1) (default {d:g})"),
        "stop_drop": (fraction(lab("stop_drop")),
                      "stop when the load < this fraction of the peak after it "
                      "(default {d:g})"),
        "post_peak_min": (number(lab("post_peak_min"), 0.0, 0.5),
                          "stop only this much platen approach / D past the peak (default "
                          "{d:g}; 0 stops at the load drop, enough for sigma_t)"),
        "max_strain": (number(lab("max_strain"), 0.0, 0.5, lo_open=True),
                       "stop at this platen approach / D (default {d:g})"),
        "record_strain": (number(lab("record_strain"), 0.0, 0.01, lo_open=True),
                          "platen approach / D between records (default {d:g})"),
    }
    assert tuple(spec) == BTS_OPTIONS
    for f, (kind, text) in spec.items():
        d = getattr(bd, f)
        g.add_argument(opt(f), type=kind, default=d, help=text.format(d=d))


def bts_settings_of(a, prefix: str = ""):
    """``BTSSettings`` from the options of :func:`add_bts_args`."""
    from .lab.brazilian import BTSSettings

    return BTSSettings(**{f: getattr(a, prefix + f) for f in BTS_OPTIONS})


def bts_disc_of(a, prefix: str = ""):
    """The disc of the options of :func:`add_bts_args` at --scale, with the cylinder's
    genesis options."""
    from .lab.runner import bts_geometry

    scale = getattr(a, prefix + "scale", None) if prefix else None
    return bts_geometry(scale=a.scale if scale is None else scale,
                        diameter_mm=getattr(a, prefix + "diameter"),
                        thickness_mm=getattr(a, prefix + "thickness"), sigma0_MPa=a.sigma0,
                        install_gap_mm=a.install_gap, relax_ratio=a.relax_ratio,
                        genesis=a.genesis)


def _add_dtt(p):
    from .lab.runner import Geometry

    add_source_args(p)
    add_dtt_args(p)
    add_specimen_args(p, Geometry(), "the 50 x 100 mm cylinder")
    add_outcome_args(p)
    p.set_defaults(func=cmd_dtt)


#: DTTSettings fields that are command options (``bpmcal dtt --FIELD``)
DTT_OPTIONS = ("grip_velocity", "grip_length", "grip_clearance", "damping", "stop_drop",
               "post_peak_min", "max_strain", "record_strain")


def add_dtt_args(p, prefix: str = ""):
    """The direct-tension cylinder and loading options (defaults: ``DTTSettings`` and the
    UCS cylinder) on ``p``: ``--OPTION``, or ``--dtt-OPTION`` with ``prefix="dtt_"``; read
    back by :func:`dtt_settings_of` and :func:`dtt_cylinder_of` with the same prefix."""
    from .lab.direct_tension import DTTSettings
    from .lab.runner import Geometry

    dd, geo = DTTSettings(), Geometry()
    g = p.add_argument_group("direct-tension test")

    def lab(name):
        return (prefix + name).replace("_", "-")

    if prefix:  # the UCS cylinder (--diameter, --height) at its own scale
        g.add_argument("--" + lab("scale"), type=number(lab("scale"), 0.0, 10.0, lo_open=True),
                       default=None,
                       help="size factor of the direct-tension cylinder (default: the UCS "
                            "cylinder's --scale)")
    else:
        g.add_argument("--diameter", type=positive("diameter", "mm"), default=geo.diameter_mm,
                       help=f"cylinder diameter before scaling [mm] (default "
                            f"{geo.diameter_mm:g})")
        g.add_argument("--height", type=positive("height", "mm"), default=geo.height_mm,
                       help=f"cylinder height before scaling [mm] (default {geo.height_mm:g})")
    spec = {
        "grip_velocity": (number(lab("grip_velocity"), 0.0, 100.0, lo_open=True, unit="m/s"),
                          "speed of each grip [m/s] (default {d:g})"),
        "grip_length": (number(lab("grip_length"), 0.0, 0.45, lo_open=True, hi_open=True),
                        "fraction of the height held by each grip, in (0, 0.45) "
                        "(default {d:g})"),
        "grip_clearance": (number(lab("grip_clearance"), 0.0, 100.0),
                           "a fracture closer than this many mean ball diameters to a grip's "
                           "face is next to the grip: the run is invalid (default {d:g})"),
        "damping": (number(lab("damping"), 0.0, 1.0, hi_open=True),
                    "local damping in [0, 1) (default {d:g})"),
        "stop_drop": (fraction(lab("stop_drop")),
                      "stop when the load < this fraction of the peak after it "
                      "(default {d:g})"),
        "post_peak_min": (number(lab("post_peak_min"), 0.0, 0.5),
                          "... at least this axial strain past the peak (default {d:g})"),
        "max_strain": (number(lab("max_strain"), 0.0, 0.5, lo_open=True),
                       "stop at this axial strain (default {d:g})"),
        "record_strain": (number(lab("record_strain"), 0.0, 0.01, lo_open=True),
                          "axial strain between records (default {d:g})"),
    }
    assert tuple(spec) == DTT_OPTIONS
    for f, (kind, text) in spec.items():
        d = getattr(dd, f)
        g.add_argument("--" + lab(f), type=kind, default=d, help=text.format(d=d))


def dtt_settings_of(a, prefix: str = ""):
    """``DTTSettings`` from the options of :func:`add_dtt_args`."""
    from .lab.direct_tension import DTTSettings

    return DTTSettings(**{f: getattr(a, prefix + f) for f in DTT_OPTIONS})


def dtt_cylinder_of(a, prefix: str = ""):
    """The cylinder of the options of :func:`add_dtt_args` at --scale, with the genesis
    options."""
    from .lab.runner import Geometry

    scale = getattr(a, prefix + "scale", None) if prefix else None
    return Geometry(scale=a.scale if scale is None else scale, diameter_mm=a.diameter,
                    height_mm=a.height, sigma0_MPa=a.sigma0, install_gap_mm=a.install_gap,
                    relax_ratio=a.relax_ratio, genesis=a.genesis)


def _add_triaxial(p):
    from .lab.triaxial import TriaxialSettings

    td = TriaxialSettings()
    add_source_args(p)
    p.add_argument("--sigma3", required=True, metavar="MPA",
                   type=number("sigma3", 0.0, 1000.0, unit="MPa"),
                   help="confining stress [MPa] in [0, 1000], held by a servo-controlled "
                        "lateral wall")
    p.add_argument("--servo-gain", type=number("servo-gain", 0.0, 1.0, lo_open=True),
                   default=td.servo_alpha,
                   help=f"servo relaxation factor alpha in (0, 1] (default {td.servo_alpha:g}, "
                        "as PFC)")
    p.add_argument("--servo-interval", type=integer("servo-interval", 1, 1000),
                   default=td.servo_interval,
                   help=f"steps between servo updates (default {td.servo_interval})")
    add_run_args(p, loading=td)
    add_outcome_args(p)
    p.set_defaults(func=cmd_triaxial)


def _add_impact(p):
    from .lab.impact import ImpactSettings
    from .stages.runs import impact_file

    im, seed = ImpactSettings(), defaults_of(impact_file)["seed"]
    p.add_argument("--card", required=True,
                   help="material card (verified or calibrated) or a YAML of the 8 parameters")
    p.add_argument("--out", required=True)
    p.add_argument("--velocity", type=number("velocity", 0.0, 100.0, lo_open=True,
                                             unit="m/s"), default=im.velocity,
                   help=f"hammer velocity [m/s] (default {im.velocity:g})")
    p.add_argument("--hammer-mass", type=positive("hammer-mass", "kg"), default=im.hammer_mass,
                   help="hammer mass at full size [kg]; scaled by scale^3 "
                        f"(default {im.hammer_mass:g})")
    p.add_argument("--dp-ratio", type=number("dp-ratio", 0.0, 1.0), default=im.dp_ratio,
                   help="contact dashpot critical-damping ratio in [0, 1] "
                        f"(default {im.dp_ratio:g})")
    p.add_argument("--anvil-fric", dest="anvil_fric", type=number("anvil-fric", 0.0, 10.0),
                   default=im.platen_fric,
                   help=f"friction of anvil and hammer (default {im.platen_fric:g})")
    p.add_argument("--duration-ms", type=positive("duration-ms", "ms"),
                   default=im.duration * 1e3,
                   help=f"run at most this long [ms] (default {im.duration * 1e3:g})")
    p.add_argument("--record-us", type=positive("record-us", "us"),
                   default=im.record_dt * 1e6,
                   help=f"time between records [us] (default {im.record_dt * 1e6:g})")
    p.add_argument("--seed", type=SEED, default=seed, help=f"packing seed (default {seed})")
    add_outcome_args(p)
    add_run_args(p)
    p.set_defaults(func=cmd_impact)


def _add_design(p):
    from .study.design import lhs_design

    opt = defaults_of(lhs_design)["optimization"]
    p.add_argument("--ranges", required=True,
                   help='JSON mapping of parameter name to [low, high] (paper units)')
    p.add_argument("--n", type=integer("n", 2, 1_000_000), required=True,
                   help="number of samples")
    p.add_argument("--seed", type=SEED, required=True, help="design seed")
    p.add_argument("--optimization", default=opt, choices=["random-cd", "lloyd", "none"],
                   help=f"LHS optimisation (default {opt})")
    p.add_argument("--out", required=True, help="output CSV")
    p.set_defaults(func=cmd_design)


def _add_gather(p):
    p.add_argument("--design", required=True, help="design CSV")
    _file(p, "--runs", "the run files, one per sample: <sample_id>.h5 (a sample without one "
                       "is 'missing')", nargs="+")
    p.add_argument("--bts-runs", nargs="+", default=None,
                   help="the Brazilian run files, one per sample: <sample_id>.h5 (adds "
                        "bts_MPa, bts_status, bts_error; a sample without one is 'missing')")
    p.add_argument("--dtt-runs", nargs="+", default=None,
                   help="the direct-tension run files, one per sample: <sample_id>.h5 (adds "
                        "dtt_MPa, dtt_status, dtt_error)")
    p.add_argument("--out", required=True, help="output CSV")
    p.set_defaults(func=cmd_gather)


def _add_screen(p):
    from .analysis import XGBScreening

    d = defaults_of(XGBScreening)
    p.add_argument("--dataset", required=True)
    for flag, h in (("--selected", "output JSON: the selected candidates per response"),
                    ("--table3", "output table (CSV, Markdown beside): Table 3"),
                    ("--figure", "output figure (PNG, PDF beside): importance shares"),
                    ("--importance-table", "output table: every importance type"),
                    ("--cv-table", "output table: cross-validated R² of the models"),
                    ("--shadow-table", "output table: largest shadow-feature share"),
                    ("--summary", "output text: the screening summary")):
        _file(p, flag, h)
    p.add_argument("--threshold", type=number("threshold", 0.0, 100.0), default=d["threshold"],
                   help=f"selection threshold [%%] (default {d['threshold']:g})")
    p.add_argument("--importance", default=d["select_by"],
                   choices=["gain", "total_gain", "permutation", "shap"],
                   help=f"importance type that drives the selection (default {d['select_by']})")
    p.add_argument("--splits", type=integer("splits", 2, 100), default=d["n_splits"],
                   help=f"CV folds (default {d['n_splits']})")
    p.add_argument("--repeats", type=integer("repeats", 1, 1000), default=d["n_repeats"],
                   help=f"permutation repeats (default {d['n_repeats']})")
    p.add_argument("--seed", type=SEED, default=d["seed"])
    p.set_defaults(func=cmd_screen)


def _add_regress(p):
    from .analysis import StepwiseRegression

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
        _file(p, flag, h)
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


def _add_calibrate(p):
    from .stages.analysis import calibrate

    d = defaults_of(calibrate)
    p.add_argument("--dataset", required=True)
    p.add_argument("--models", required=True, help="models.json of the regression")
    p.add_argument("--lab", required=True, help="lab CSV")
    _file(p, "--cards", "output material cards, one per lab specimen: <specimen>.yaml",
          nargs="+")
    p.add_argument("--table", default=None, help="output table: the calibrated parameters")
    p.add_argument("--fixed", required=True, help="JSON of the fixed parameters")
    p.add_argument("--ranges", required=True,
                   help="JSON of the design space {name: [low, high]} the dataset was sampled "
                        "over (the config's ranges); it bounds the free parameters")
    p.add_argument("--bounds", default=None,
                   help="JSON {name: [low, high]} narrowing --ranges for free parameters "
                        "(the config's calibration.bounds; wider than --ranges is an error)")
    p.add_argument("--free", default=None, help="comma-separated free parameters")
    p.add_argument("--ratio", type=number("ratio", None, 100.0), default=d["ratio"],
                   help=f"bond-strength ratio pb_ten/pb_coh (<= 0: both free; default "
                        f"{d['ratio']:g})")
    p.add_argument("--ratio-from", default=None,
                   help="JSON file with the chosen ratio (the ratio sweep's choice; when it "
                        "holds none, --ratio is used)")
    p.add_argument("--n-boot", type=integer("n-boot", 0, 1_000_000), default=d["n_boot"],
                   help="bootstrap resamples for the intervals (0: no bootstrap, else >= 2; "
                        f"default {d['n_boot']})")
    p.add_argument("--seed", type=SEED, default=d["seed"])
    p.set_defaults(func=cmd_calibrate)


def _add_verify(p):
    from .stages.analysis import verify

    d = defaults_of(verify)
    p.add_argument("--card", required=True)
    p.add_argument("--models", required=True)
    _file(p, "--out-card", "output: the verified card")
    _file(p, "--rounds", "output table: one row per DEM round")
    _file(p, "--run", "output: the run file of the best round")
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
                        "tolerance but their standard errors are too large to state them to "
                        f"--rtol (default {d['max_seeds']}; at most --seeds-per-round: no "
                        "growth)")
    p.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True), default=d["rtol"],
                   help=f"relative tolerance (default {d['rtol']:g})")
    p.add_argument("--max-rounds", type=integer("max-rounds", 1, 50), default=d["max_rounds"],
                   help=f"rounds at most, each of --seeds-per-round DEM runs "
                        f"(default {d['max_rounds']})")
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


def _add_range_margin(p, d):
    p.add_argument("--range-margin", type=number("range-margin", 0.0, 1.0),
                   default=d["range_margin"],
                   help="the closed loop may leave each design range (the card's ranges) by "
                        "this fraction of its width, inside the parameter's physical domain "
                        "and never past the card's calibration bounds; the card lists what "
                        f"ends outside (default {d['range_margin']:g}; 0: stay inside)")


def _add_card_run_args(p, func):
    """The options every command that runs a card's UCS (and Brazilian) tests shares
    (verify, transfer, holdout): --quiet, the cylinder and loading, the --bts-* disc, the
    --dtt-* direct-tension test."""
    p.add_argument("--quiet", action="store_true")
    add_run_args(p)
    add_bts_args(p, "bts_")
    add_dtt_args(p, "dtt_")
    p.set_defaults(func=func)


def _add_transfer(p):
    from .stages.analysis import transfer

    d = defaults_of(transfer)
    p.add_argument("--card", required=True, help="a verified card (bpmcal verify)")
    p.add_argument("--models", required=True)
    _file(p, "--out-card", "output: the transferred card (calibrated_at_scale = --scale)")
    _file(p, "--rounds", "output table: one row per DEM round at this size")
    _file(p, "--run", "output: the run file of the best round")
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


def _add_transfer_table(p):
    _file(p, "--cards", "transferred cards", nargs="+")
    _file(p, "--table", "output table: verified vs full-size responses per card")
    p.set_defaults(func=cmd_transfer_table)


def _add_scatter(p):
    from .stages.analysis import seed_scatter

    d = defaults_of(seed_scatter)
    p.add_argument("--card", required=True)
    p.add_argument("--seeds", required=True, help="comma-separated packing seeds")
    _file(p, "--runs", "output run files, one per seed in the order of --seeds", nargs="+")
    _file(p, "--seed-runs", "output table: the responses of every seed")
    _file(p, "--table", "output table: CV and noise floor per response")
    p.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True), default=d["rtol"])
    add_run_args(p)
    p.set_defaults(func=cmd_scatter)


def _add_holdout(p):
    p.add_argument("--card", required=True, help="a verified card (bpmcal verify)")
    p.add_argument("--seeds", required=True,
                   help="comma-separated fresh packing seeds (none of the card's closed loop "
                        "or transfer)")
    _file(p, "--runs", "output UCS run files, one per seed in the order of --seeds", nargs="+")
    p.add_argument("--bts-runs", nargs="+", default=None,
                   help="output Brazilian run files, one per seed (needed when the card has a "
                        "tensile-strength target; failure records 'not run' without one)")
    p.add_argument("--dtt-runs", nargs="+", default=None,
                   help="output direct-tension run files, one per seed (needed when the card "
                        "has a direct-tension target, dtt_MPa)")
    _file(p, "--seed-runs", "output table: the responses of every seed")
    _add_card_run_args(p, cmd_holdout)


def _add_holdout_table(p):
    from .stages.holdout import holdout_table

    d = defaults_of(holdout_table)
    _file(p, "--cards", "verified cards", nargs="+")
    _file(p, "--seed-runs", "their holdout seed tables, in the same order", nargs="+")
    _file(p, "--table", "output table: fresh-seed mean, standard error and verdict per "
                        "card and target")
    p.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True, hi_open=True),
                   default=d["rtol"],
                   help=f"the closed loop's relative tolerance (default {d['rtol']:g})")
    p.add_argument("--z", type=number("z", 0.0, 10.0, lo_open=True), default=d["z"],
                   help=f"standard errors a target may lie from the mean (default {d['z']:g})")
    p.set_defaults(func=cmd_holdout_table)


def _add_vtables(p):
    _file(p, "--cards", "verified cards", nargs="+")
    _file(p, "--runs", "their best rounds' run files, in the same order", nargs="+")
    p.add_argument("--lab", required=True)
    _file(p, "--table5", "output table: Table 5")
    _file(p, "--table6", "output table: Table 6")
    _file(p, "--figure", "output figure: Fig. 6")
    p.set_defaults(func=cmd_vtables)


def _add_envelopes(p):
    from .stages.triaxial import DEFAULT_SIGMA3_MPA

    _file(p, "--cards", "material cards (calibrated or verified)", nargs="+")
    _file(p, "--runs", "their triaxial run files: for each card, one per --sigma3, in order",
          nargs="+")
    p.add_argument("--sigma3", type=_sigma3_list,
                   default=list(DEFAULT_SIGMA3_MPA), metavar="MPA,MPA,...",
                   help="the confining stresses of each card's runs [MPa] (default "
                        f"{','.join(f'{x:g}' for x in DEFAULT_SIGMA3_MPA)})")
    p.add_argument("--lab", default=None,
                   help="the lab CSV: --lab-triaxial's specimens must be among its specimens")
    p.add_argument("--lab-triaxial", default=None,
                   help="lab triaxial points (CSV: specimen, sigma3_MPa, sigma1_MPa)")
    _file(p, "--table", "output table: envelopes per card")
    _file(p, "--points", "output table: every run, ok or failed")
    _file(p, "--figure", "output figure: sigma1 vs sigma3 with the envelopes")
    p.add_argument("--lab-table", default=None,
                   help="output table: the lab points against each card's envelopes "
                        "(with --lab-triaxial)")
    p.set_defaults(func=cmd_envelopes)


def _add_sweep_plan(p):
    from .stages.fracture import sweep_plan

    d = defaults_of(sweep_plan)
    p.add_argument("--card", required=True, help="material card (the initial calibration)")
    p.add_argument("--models", required=True)
    p.add_argument("--ratios", default=",".join(f"{x:g}" for x in d["ratios"]),
                   help="start,stop,step (default %(default)s)")
    p.add_argument("--seed", type=SEED, default=d["seed"],
                   help=f"packing seed of the runs (default {d['seed']})")
    p.add_argument("--out", required=True)
    p.set_defaults(func=cmd_sweep_plan)


def _add_sweep_analyse(p):
    from .stages.fracture import sweep_analyse

    d = defaults_of(sweep_analyse)
    p.add_argument("--plan", required=True)
    _file(p, "--runs", "the run files of the plan's rows: <sample_id>.h5", nargs="+")
    p.add_argument("--criterion", default=d["criterion"], choices=["tensile_share", "crack_count"])
    p.add_argument("--target", type=number("target", 0.0), default=d["target"])
    _file(p, "--table", "output table: cracks per ratio")
    _file(p, "--chosen", "output JSON: the chosen ratio")
    _file(p, "--fig4", "output figure: Fig. 4")
    _file(p, "--fig5", "output figure: Fig. 5")
    _file(p, "--vtk", "output folder: ParaView files of the runs Fig. 5 shows")
    p.set_defaults(func=cmd_sweep_analyse)


def _add_impact_analyse(p):
    p.add_argument("--main", required=True, help="the reference impact run (6 m/s)")
    _file(p, "--runs", "impact runs of the velocity sweep", nargs="+")
    _file(p, "--energy", "output table: energy budget of the reference run")
    _file(p, "--t10", "output table: t10 vs specific energy")
    _file(p, "--jk-fit", "output JSON: the JK fit")
    _file(p, "--fig7", "output figure: Fig. 7")
    _file(p, "--fig-t10", "output figure: t10 vs Ecs")
    p.set_defaults(func=cmd_impact_analyse)


def _add_report(p):
    p.add_argument("--outdir", default=None,
                   help="the study's output directory (its files: bpmcal.io.layout; default: "
                        "the config's outdir)")
    p.add_argument("--config", default=None, help="the study's (merged) config, JSON/YAML")
    p.add_argument("--config-json", default=None,
                   help="... or the config as JSON text (what the workflow passes)")
    p.add_argument("--config-out", default=None, help="also write the config as JSON to this file")
    p.set_defaults(func=cmd_report)


def _add_summary(p):
    p.add_argument("run")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.set_defaults(func=cmd_summary)


def _add_vtk(p):
    p.add_argument("run")
    p.add_argument("--out", required=True, help="output directory")
    p.set_defaults(func=cmd_vtk)


#: subcommand -> (help, adds its options, whether its help lists the parameters)
COMMANDS = {
    "ucs": ("one virtual uniaxial compression test -> HDF5", _add_ucs, True),
    "bts": ("one virtual Brazilian (diametral compression) test -> HDF5", _add_bts, True),
    "dtt": ("one virtual direct-tension test -> HDF5", _add_dtt, True),
    "triaxial": ("one virtual triaxial compression test -> HDF5", _add_triaxial, True),
    "impact": ("drop-hammer impact of a calibrated specimen", _add_impact, False),
    "design": ("Latin-hypercube design over parameter ranges -> CSV", _add_design, False),
    "gather": ("collect per-sample run files into one dataset CSV", _add_gather, False),
    "screen": ("XGBoost screening of the dataset (Table 3)", _add_screen, False),
    "regress": ("three-stage stepwise regression (Table 4)", _add_regress, False),
    "calibrate": ("invert the models for the lab specimens", _add_calibrate, False),
    "verify": ("closed-loop DEM verification of a material card", _add_verify, False),
    "scatter": ("one card, several packing seeds: DEM scatter", _add_scatter, False),
    "transfer": ("run a verified card at full size; correct it there if needed",
                 _add_transfer, False),
    "transfer-table": ("the full-size transfer of every card, one table", _add_transfer_table,
                       False),
    "holdout": ("a verified card on fresh packing seeds (UCS and, with a sigma_t target, "
                "Brazilian tests)", _add_holdout, False),
    "holdout-table": ("the fresh-seed check of every card against its lab targets",
                      _add_holdout_table, False),
    "verification-tables": ("Tables 5 and 6 and Fig. 6", _add_vtables, False),
    "envelopes": ("triaxial strength envelopes (Mohr-Coulomb, Hoek-Brown) per card",
                  _add_envelopes, False),
    "sweep-plan": ("bond-strength-ratio sweep: one row per ratio", _add_sweep_plan, False),
    "sweep-analyse": ("crack counts per ratio, the chosen ratio", _add_sweep_analyse, False),
    "impact-analyse": ("impact energy table, Fig. 7, t10-Ecs and JK fit", _add_impact_analyse,
                       False),
    "report": ("OUTDIR/report: every table and figure + index.md", _add_report, False),
    "summary": ("print the summary attributes of a run file", _add_summary, False),
    "vtk": ("export particles and cracks of a run for ParaView", _add_vtk, False),
}


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``bpmcal`` parser; with ``only``, the options of that subcommand alone (the
    others are listed by name)."""
    ap = Parser(prog="bpmcal", description=__doc__.split("\n\n")[0],
                formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"bpmcal {_version()}")
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name, (help_, add, epilog) in COMMANDS.items():
        p = sub.add_parser(name, help=help_, formatter_class=argparse.RawDescriptionHelpFormatter,
                           epilog=_param_help() if epilog else None)
        if only is None or only == name:
            add(p)
    return ap


def _version():
    from . import __version__
    return __version__


def _bad_input_types() -> tuple:
    from .dem.errors import InputError
    from .io.h5 import RunFileError
    from .study.config import ConfigError

    return (BadInput, P.ParameterError, InputError, ConfigError, RunFileError)


def _one_line(e) -> str:
    return " ".join(str(e).split())


def main(argv=None) -> int:
    """Run one subcommand; returns the exit code (see the module doc)."""
    os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
    argv = sys.argv[1:] if argv is None else list(argv)
    cmd = next((x for x in argv if not x.startswith("-")), None)
    ap = build_parser(only=cmd if cmd in COMMANDS else None)
    try:
        a = ap.parse_args(argv)
    except SystemExit as e:  # --help, --version, usage errors (one line, exit 2)
        return e.code if isinstance(e.code, int) else (0 if e.code is None else EXIT_BAD_INPUT)
    try:
        bad_input = _bad_input_types()
    except Exception:  # noqa: BLE001 - a broken install is a bug, reported below
        bad_input = (BadInput, P.ParameterError)
    where = f"bpmcal {a.cmd}"
    try:
        return a.func(a)
    except bad_input as e:
        print(f"{where}: error: {_one_line(e)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"\n{where}: interrupted; the file being written was discarded", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `bpmcal summary run.h5 | head`
        sys.stdout = open(os.devnull, "w")
        return EXIT_OK
    except OSError as e:
        name = f"{e.filename}: " if getattr(e, "filename", None) else ""
        print(f"{where}: error: {name}{e.strerror or _one_line(e)} (system error)",
              file=sys.stderr)
        return EXIT_SYSTEM
    except Exception:  # noqa: BLE001 - a bug: keep the traceback, add a hint
        traceback.print_exc()
        print(f"{where}: internal error (a bug in bpmcal, not in your input): please report it "
              "with the traceback above and the command line", file=sys.stderr)
        return EXIT_BUG


if __name__ == "__main__":
    sys.exit(main())
