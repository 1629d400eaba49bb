"""Subcommands that run one DEM test and write its run file: ``ucs``, ``bts``, ``dtt``,
``triaxial``, ``impact``; the study's sample job, ``sample`` (a UCS test and, in the same
process, the sample's Brazilian, direct-tension and triaxial tests); and the two that read
a run file: ``summary``, ``vtk``.

Each ``_add_<cmd>`` (its options) stands directly above its ``cmd_<cmd>`` (the handler).
A failed run writes its failure record and exits 3 (0 with ``--failed-ok``).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..cost import phase
from ..io.checks import BadInput
from ..stages import defaults_of
from ..stages.progress import Progress
from .args import EXIT_OK, EXIT_RUN_FAILED, SEED, integer, number, positive
from .options import (
    add_bts_args,
    add_dtt_args,
    add_outcome_args,
    add_run_args,
    add_source_args,
    add_specimen_args,
    add_tri_args,
    bts_disc_of,
    bts_settings_of,
    dtt_cylinder_of,
    dtt_settings_of,
    run_context,
    run_geometry,
    run_settings,
    tri_settings_of,
)


def _import_runs() -> None:
    """Import the run machinery (the engine and numba, h5py) first, in the cost ledger's
    phase ``imports`` (``bpmcal.cost``; the commands import it lazily)."""
    with phase("imports"):
        from ..stages import runs  # noqa: F401


def _run_done(args, cmd: str, out, path=None) -> int:
    """Exit code of a DEM run command (its output ``path``, default --out); the FAILED line
    is printed even with --quiet."""
    if out.status == "ok":
        return EXIT_OK
    record = "failure record" if out.status == "failed" else f"{out.status} run"
    where = (f"{record} written to {out.path}; the good run in {out.kept} was kept"
             if out.kept else f"{record} written")
    word = "FAILED" if out.status == "failed" else out.status.upper()
    print(f"bpmcal {cmd}: {word}: {path or args.out}: {out.error} ({where})", file=sys.stderr)
    sys.stderr.flush()
    return EXIT_OK if args.failed_ok and not out.kept else EXIT_RUN_FAILED


def study_scale_note(cmd: str, tests) -> str | None:
    """The one line a lab command prints when its specimens (``tests``: (test, geometry))
    are not at the default study's scale (``lab.runner.STUDY_SCALES``), the one setting in
    which its defaults differ from the study's, or None. Each test's specimen and the
    config key that sizes it in the study: ``lab.registry.LAB_TESTS``."""
    from ..lab.registry import kind
    from ..lab.runner import STUDY_SCALES

    parts = []
    for test, geo in tests:
        what, key = kind(test).scale, kind(test).scale_key
        study = STUDY_SCALES[what]
        if abs(geo.scale - study) > 1e-12:
            name = "cylinder" if what == "impact" else what
            parts.append(f"the {name} at scale {geo.scale:g} (the default study's {key} "
                         f"{study:g})")
    if not parts:
        return None
    return (f"bpmcal {cmd}: note: {', '.join(parts)}: another size than the default "
            "study's, so what it measures differs from the study's by the size effect; every "
            "other default is the study's")


def _note(args, cmd: str, tests) -> None:
    """Print :func:`study_scale_note` (stderr; not with --quiet) after the runs: a command
    refused for bad input prints its one error line only."""
    line = None if args.quiet else study_scale_note(cmd, tests)
    if line:
        print(line, file=sys.stderr)


def _lab_test(args, test: str, geometry, settings, done_line) -> int:
    """``ucs``, ``bts``, ``dtt`` and ``triaxial``: the run file
    (``stages.runs.lab_test_file``), its one-line result and the exit code."""
    return _lab_tests(args, test, [(test, args.out, geometry, settings, done_line)])


def _lab_tests(args, cmd: str, tests, flags=None) -> int:
    """Lab tests of one parameter set in one process (``stages.runs.lab_test_files``;
    ``tests``: (test, out, geometry, settings, done_line)) for the command ``cmd``: their
    run files, a one-line result each, and the exit code (that of the first test that did
    not succeed)."""
    from ..stages.runs import lab_test_files

    progs = [Progress(f"{t} {Path(o).name}", enabled=not args.quiet) for t, o, *_ in tests]
    outs = lab_test_files([(t, o, g, st) for t, o, g, st, _ in tests], params_file=args.params,
                          sets=args.set, design=args.design, sample=args.sample, seed=args.seed,
                          contact_model=args.contact_model,
                          ctx=run_context(args), progress=progs, flags=flags)
    rc = EXIT_OK
    for (test, path, _, _, done_line), prog, out in zip(tests, progs, outs):
        prog.done(f"{path}: {done_line(out.summary)}" if out.status == "ok" and out.summary
                  else "")
        r = _run_done(args, cmd, out, path)
        rc = r if rc == EXIT_OK else rc
    _note(args, cmd, [(t, g) for t, _, g, *_ in tests])
    return rc


def _add_ucs(p):
    add_source_args(p)
    add_run_args(p)
    add_outcome_args(p)
    p.set_defaults(func=cmd_ucs)


def _run_tail(s, balls: bool = True) -> str:
    """The end every test's one-line result shares: balls, steps, time and why it stopped."""
    head = f"{s['n_balls']} balls, " if balls else ""
    return f"{head}{s['steps']} steps, {s['wall_s']:.1f} s ({s['stop_reason']})"


def _ucs_line(s):
    return (f"sigma_c = {s['ucs_MPa']:.3f} MPa, E = {s['E_GPa']:.3f} GPa, "
            f"nu = {s['nu']:.3f}, cracks {s['cracks_tension']}+{s['cracks_shear']}, "
            f"{_run_tail(s)}")


def cmd_ucs(args) -> int:
    _import_runs()
    return _lab_test(args, "ucs", run_geometry(args), run_settings(args), _ucs_line)


def _add_sample(p):
    add_source_args(p)
    add_run_args(p)
    p.add_argument("--bts-out", default=None,
                   help="also run the Brazilian test of the same parameters and packing seed "
                        "(the --bts-* options below; the disc at --scale with the cylinder's "
                        "genesis options) into this HDF5 file, in the same process after the "
                        "UCS test (one start-up instead of two); each test writes its run "
                        "file or failure record")
    add_bts_args(p, "bts_")
    p.add_argument("--dtt-out", default=None,
                   help="also run the direct-tension test of the same parameters and packing "
                        "seed (the --dtt-* options below; the cylinder of --diameter x "
                        "--height at --dtt-scale) into this HDF5 file, after the other tests")
    add_dtt_args(p, "dtt_")
    p.add_argument("--tri-out", default=None,
                   help="also run a triaxial test of the same parameters and packing seed at "
                        "--design-sigma3 (the UCS cylinder and loading) into this HDF5 file, "
                        "after the other tests: the study's triaxial strength of every "
                        "sample (triaxial.design_sigma3_MPa)")
    add_tri_args(p)
    add_outcome_args(p)
    p.set_defaults(func=cmd_sample)


def cmd_sample(args) -> int:
    """The study's sample job (the workflow's rule ``sample``): the UCS test into --out and,
    in the same process on the same packing seed, the Brazilian, direct-tension and
    triaxial tests asked for (--bts-out, --dtt-out, --tri-out)."""
    _import_runs()
    tests = [("ucs", args.out, run_geometry(args), run_settings(args), _ucs_line)]
    flags = ["--out"]
    if args.bts_out is not None:  # the Brazilian test in this process
        tests.append(("bts", args.bts_out, bts_disc_of(args, "bts_"),
                      bts_settings_of(args, "bts_"), _bts_line))
        flags.append("--bts-out")
    if args.dtt_out is not None:  # ... and the direct-tension test
        tests.append(("dtt", args.dtt_out, dtt_cylinder_of(args, "dtt_"),
                      dtt_settings_of(args, "dtt_"), _dtt_line))
        flags.append("--dtt-out")
    if args.tri_out is not None:  # ... and the triaxial test at the design confinement
        if args.design_sigma3 is None:
            raise BadInput(f"--tri-out {args.tri_out}: needs --design-sigma3 MPA (the confining "
                           "stress of that triaxial test)")
        tests.append(("triaxial", args.tri_out, run_geometry(args), tri_settings_of(args),
                      _tri_line))
        flags.append("--tri-out")
    return _lab_tests(args, "sample", tests, flags=flags)


def _add_bts(p):
    from ..lab.runner import bts_geometry

    add_source_args(p)
    add_bts_args(p)
    add_specimen_args(p, bts_geometry(), "the ISRM 50 x 25 mm disc")
    add_outcome_args(p)
    p.set_defaults(func=cmd_bts)


def _bts_line(s):
    if not s.get("bts_valid", True):
        return (f"INVALID ({s.get('bts_invalid_reason', '')}); peak stress "
                f"{s['bts_peak_MPa']:.3f} MPa is no sigma_t, {_run_tail(s)}")
    return (f"sigma_t = {s['bts_MPa']:.3f} MPa (peak load {s['peak_load_N']:.1f} N, "
            f"platen forces differ by {100 * s['platen_mismatch']:.2f} %), cracks "
            f"{s['cracks_tension']}+{s['cracks_shear']}, {_run_tail(s)}")


def cmd_bts(args) -> int:
    _import_runs()
    return _lab_test(args, "bts", bts_disc_of(args), bts_settings_of(args), _bts_line)


def _add_dtt(p):
    from ..lab.runner import Geometry

    add_source_args(p)
    add_dtt_args(p)
    add_specimen_args(p, Geometry(), "the 50 x 100 mm cylinder")
    add_outcome_args(p)
    p.set_defaults(func=cmd_dtt)


def _dtt_line(s):
    st = (f"sigma_t = {s['dtt_MPa']:.3f} MPa" if s.get("dtt_valid")
          else f"INVALID ({s.get('dtt_invalid_reason', '')}); peak stress "
               f"{s['dtt_peak_MPa']:.3f} MPa is no sigma_t")
    return (f"{st}, fracture at {s['fracture_height']:.2f} of the gauge length, cracks "
            f"{s['cracks_tension']}+{s['cracks_shear']}, {_run_tail(s)}")


def cmd_dtt(args) -> int:
    _import_runs()
    return _lab_test(args, "dtt", dtt_cylinder_of(args), dtt_settings_of(args), _dtt_line)


def _add_triaxial(p):
    from ..lab.triaxial import TriaxialSettings

    td = TriaxialSettings()
    add_source_args(p)
    p.add_argument("--sigma3", required=True, metavar="MPA",
                   type=number("sigma3", 0.0, 1000.0, unit="MPa"),
                   help="confining stress [MPa] in [0, 1000], held by a servo-controlled "
                        "lateral wall")
    p.add_argument("--servo-alpha", type=number("servo-alpha", 0.0, 1.0, lo_open=True),
                           default=td.servo_alpha,
                           help="servo relaxation factor alpha in (0, 1] (default "
                                f"{td.servo_alpha:g}, as PFC)")
    p.add_argument("--servo-interval", type=integer("servo-interval", 1, 1000),
                   default=td.servo_interval,
                   help=f"steps between servo updates (default {td.servo_interval})")
    add_run_args(p, loading=td)
    add_outcome_args(p)
    p.set_defaults(func=cmd_triaxial)


def _tri_line(s):
    dev = (f"{100 * s['sigma3_maxdev_rel']:.2f} %" if s["sigma3_MPa"] > 0
           else f"{s['sigma3_maxdev_MPa']:.3f} MPa")
    return (f"sigma3 = {s['sigma3_MPa']:g} MPa, sigma1 = {s['sigma1_MPa']:.3f} MPa, "
            f"E = {s['E_GPa']:.3f} GPa, nu = {s['nu']:.3f}, sigma3 held within {dev} "
            f"up to the peak, cracks {s['cracks_tension']}+{s['cracks_shear']}, "
            f"{_run_tail(s, balls=False)}")


def cmd_triaxial(args) -> int:
    _import_runs()
    from ..lab.triaxial import TriaxialSettings

    st = run_settings(args, TriaxialSettings, sigma3=args.sigma3 * 1e6,
                      servo_alpha=args.servo_alpha, servo_interval=args.servo_interval)
    return _lab_test(args, "triaxial", run_geometry(args), st, _tri_line)


def _add_impact(p):
    from ..lab.impact import ImpactSettings
    from ..stages.runs import impact_file

    im, seed = ImpactSettings(), defaults_of(impact_file)["seed"]
    p.add_argument("--card", "--params", dest="card", required=True,
                   help="material card (verified or calibrated) or a YAML of the "
                        "meso-parameters of either contact model (--params is the same "
                        "option, as in the other lab tests)")
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
    p.add_argument("--anvil-fric", type=number("anvil-fric", 0.0, 10.0), default=im.anvil_fric,
                   help=f"friction of anvil and hammer (default {im.anvil_fric:g})")
    p.add_argument("--duration-ms", type=number("duration-ms", 0.0, 1000.0, lo_open=True,
                                                 unit="ms"),
                   default=im.duration * 1e3,
                   help=f"run at most this long [ms] (default {im.duration * 1e3:g})")
    p.add_argument("--record-us", type=positive("record-us", "us"),
                   default=im.record_dt * 1e6,
                   help=f"time between records [us] (default {im.record_dt * 1e6:g})")
    p.add_argument("--seed", type=SEED, default=seed, help=f"packing seed (default {seed})")
    add_outcome_args(p)
    add_run_args(p)
    p.set_defaults(func=cmd_impact)


def cmd_impact(args) -> int:
    _import_runs()
    from ..lab.impact import ImpactSettings
    from ..stages.runs import impact_file

    st = ImpactSettings(velocity=args.velocity, hammer_mass=args.hammer_mass * args.scale ** 3,
                        dp_ratio=args.dp_ratio, anvil_fric=args.anvil_fric,
                        duration=args.duration_ms * 1e-3, record_dt=args.record_us * 1e-6)
    prog = Progress(f"impact {Path(args.out).name}", enabled=not args.quiet)
    out = impact_file(args.card, args.out, geometry=run_geometry(args), settings=st,
                      seed=args.seed, ctx=run_context(args, prog))
    if out.status == "ok":
        s = out.summary
        prog.done(f"{args.out}: W_in = {s['W_in_J']:.3f} J, G_f = {s['G_f_J']:.3f} J, eta_f = "
                  f"{100 * s['eta_f']:.1f} %, t10 = {s['t10_pct']:.1f} %, closure "
                  f"{100 * s['closure_rel_max']:.3f} %, {s['steps']} steps, {s['wall_s']:.0f} s")
    else:
        prog.done()
    _note(args, "impact", [("impact", run_geometry(args))])
    return _run_done(args, "impact", out)


def _add_summary(p):
    p.add_argument("run")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.set_defaults(func=cmd_summary)


def cmd_summary(args) -> int:
    from ..io.h5 import json_safe, read_summary
    from ..io.safe_names import clip, printable

    s = read_summary(args.run)
    if args.json:
        print(json.dumps(json_safe(s), sort_keys=True))
    else:  # the file's strings escaped: no terminal escape, no line of their own
        for k in sorted(s, key=str):
            print(f"{printable(clip(k, 60)):24s} {printable(clip(s[k], 2000))}")
    return 0


def _add_vtk(p):
    p.add_argument("run")
    p.add_argument("--out", required=True, help="output directory")
    p.set_defaults(func=cmd_vtk)


def cmd_vtk(args) -> int:
    from ..io.checks import out_dir
    from ..io.h5 import read_summary
    from ..io.vtk import export_run

    s = read_summary(args.run)
    if s.get("status") != "ok":
        raise BadInput(f"{args.run}: a failure record (status {s.get('status')}: "
                       f"{s.get('error', '')}), no particles to export")
    out_dir(args.out, "--out")
    for f in export_run(args.run, args.out):
        print(f)
    return 0
