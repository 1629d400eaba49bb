"""Option groups that several ``bpmcal`` subcommands share, and their readers.

An ``add_*_args(p)`` function adds one group of options to a subparser; a reader
(``run_geometry``, ``run_settings``, ``bts_settings_of``, ``bts_disc_of``,
``dtt_settings_of``, ``dtt_cylinder_of``, ``seed_tests_of``, ``loop_settings_of``) turns the
parsed namespace back into the settings object a stage takes, and :func:`run_context`
builds the one ``RunContext`` of a DEM command (cache, threads, budgets, progress). Every
default is the settings' own (the lab tests' settings dataclasses, ``Geometry``,
``RunContext``, ``LoopSettings``), never a literal here. The lab modules are imported
inside the functions, so that importing this module loads no engine.

The closed loop's options are generated from the fields of ``LoopSettings`` (their
names, defaults, limits and help lines: :func:`add_loop_args`), and so is the jobs'
command line of a config's ``verification`` section (:func:`loop_argv`, read by
:mod:`bpmcal.cli.jobs`).

``BTS_OPTIONS`` and ``DTT_OPTIONS`` name the settings fields that are options, under the
same names as the keys of the study config's ``bts`` and ``dtt`` sections; the jobs'
commands (:mod:`bpmcal.cli.jobs`, for the workflow and the benchmarks) build their
``--bts-*`` and ``--dtt-*`` options from them.
"""
from __future__ import annotations

import argparse
import dataclasses

from ..lab.run_context import MIN_GENESIS_STEPS, RunContext
from ..params import CONTACT_MODELS
from .args import SEED, THREADS, choice, fraction, integer, number, positive


def add_source_args(p):
    """Where a DEM run command takes its parameters and seed from, and its output file."""
    src = p.add_mutually_exclusive_group()
    src.add_argument("--params", default=None,
                     help="YAML file with the meso-parameters of either contact model "
                          "(or a material card)")
    src.add_argument("--design", default=None,
                     help="take the parameters and the seed from this design CSV ...")
    p.add_argument("--sample", default=None, help="... row with this sample_id")
    p.add_argument("--out", required=True, help="output HDF5 file (written atomically)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="override one parameter (repeatable)")
    p.add_argument("--seed", type=SEED, default=None,
                   help="packing seed (default 1, or the design row's)")
    p.add_argument("--contact-model", default=None, type=choice("contact-model", CONTACT_MODELS),
                   help="contact model of a card built with --set (linearpbond or "
                        "flatjoint; default: the card's own, parallel bond if it names none)")


FAILED_OK_HELP = ("a failed run (failure record written) exits 0 instead of 3; the workflow "
                  "passes this so that one failed sample does not stop the study")


def add_outcome_args(p):
    """How a DEM run command reports: progress, and the exit code of a failed run."""
    p.add_argument("--quiet", action="store_true",
                   help="no progress output (a FAILED line is still printed)")
    p.add_argument("--failed-ok", action="store_true", help=FAILED_OK_HELP)


def add_budget_args(p):
    """Resource guards of a DEM command (checked before any work; defaults:
    ``RunContext``'s)."""
    d = RunContext()
    p.add_argument("--max-balls", type=integer("max-balls", 1), default=d.max_balls,
                   help="refuse a specimen estimated to hold more balls than this "
                        f"(default {d.max_balls:,})")
    p.add_argument("--mem-budget-mb", type=positive("mem-budget-mb", "MB"), default=None,
                   help="refuse a run estimated to need more memory than this [MB] "
                        "(default 80 %% of this machine's memory)")
    p.add_argument("--genesis-max-steps",
                   type=integer("genesis-max-steps", MIN_GENESIS_STEPS),
                   default=d.genesis_max_steps,
                   help="a specimen that has not settled after this many steps is a failed "
                        f"run (default {d.genesis_max_steps:,})")


def run_context(args, progress=None) -> RunContext:
    """The one ``RunContext`` of a DEM command: its ``--specimen-cache``, ``--threads``,
    ``--max-balls``, ``--mem-budget-mb`` and ``--genesis-max-steps``
    (:func:`add_specimen_args`), and ``progress`` (the command's progress line, or None)."""
    return RunContext(cache=args.specimen_cache, threads=args.threads, max_balls=args.max_balls,
                      mem_budget_mb=args.mem_budget_mb,
                      genesis_max_steps=args.genesis_max_steps, progress=progress)


GENESES = ("bpmcal", "pfc")  # = lab.specimen.GENESES (tested equal)


def add_specimen_args(p, geo=None, what: str = "the 50 x 100 mm cylinder"):
    """The specimen of a DEM command (``Geometry``'s fields; defaults from ``geo``)."""
    from ..lab.runner import Geometry

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
    p.add_argument("--threads", type=THREADS, default=None,
                   help="numba threads (>= 1); default: chosen by the run from its ball "
                        "count and the CPUs free, again every half second "
                        "(bpmcal.dem.threads). Commands that run several seeds (verify, "
                        "fresh-seeds, scatter) take it as CPUs: up to this many seeds run "
                        "side by side, one process each")
    p.add_argument("--specimen-cache", default=None,
                   help="directory of cached packings (default ~/.cache/bpmcal/packings or "
                        "$BPMCAL_SPECIMEN_CACHE)")
    add_budget_args(p)


#: the help of every test's density-scaling option (``{d}``: what its default does)
DENSITY_SCALING_HELP = ("PFC's density scaling: each ball's inertial mass raised so that "
                        "its critical timestep reaches this quantile of the balls' own "
                        "(0.5: the median ball's), for fewer steps to the same quasi-static "
                        "answer; 0: the true masses (default: {d})")
#: what the axial tests' (UCS, triaxial) density scaling is by default
AXIAL_DENSITY_DEFAULT = "by contact model, 0.5 for parallel bonds, the true masses for flat joints"


def add_run_args(p, loading=None):
    """Options of the cylinder and of its axial loading (shared by ucs, triaxial, verify,
    scatter, impact); the loading defaults are ``loading``'s (default ``UCSSettings()``)."""
    from ..lab.runner import Geometry
    from ..lab.ucs import UCSSettings

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
    p.add_argument("--density-scaling", type=number("density-scaling", 0.0, 1.0),
                   default=ld.density_scaling, metavar="Q", help=DENSITY_SCALING_HELP.format(
                       d=AXIAL_DENSITY_DEFAULT))
    p.add_argument("--max-strain", type=number("max-strain", 0.0, 0.5, lo_open=True),
                   default=ld.max_strain,
                   help=f"stop at this axial strain (default {ld.max_strain:g})")
    p.add_argument("--max-steps", type=integer("max-steps", 1), default=ld.max_steps,
                   help="stop the loading after this many steps; a loading estimated to "
                        "need more, whose steps would take over ten minutes, is refused "
                        f"before it starts (default {ld.max_steps})")
    p.add_argument("--platen-fric", type=number("platen-fric", 0.0, 10.0),
                   default=ld.platen_fric,
                   help=f"platen friction coefficient in [0, 10] (default {ld.platen_fric:g})")
    p.add_argument("--end-cap", type=number("end-cap", 0.0, 10.0), default=ld.end_cap,
                   metavar="D",
                   help="end caps: the bonds within D mean ball diameters of a platen get "
                        "--end-cap-factor x their strength (not their stiffness), so that the "
                        "wall-packed end layers do not decide the strength; 0 = none, 1 = the "
                        f"first layer of balls (default {ld.end_cap:g}; the measurement: "
                        "docs/measurements/2026-11-26-end-layers.md)")
    p.add_argument("--end-cap-factor", type=number("end-cap-factor", 1.0, 1e6),
                   default=ld.end_cap_factor,
                   help="strength factor of the end caps' bonds in [1, 1e6] "
                        f"(default {ld.end_cap_factor:g})")
    if hasattr(ld, "approach_velocity"):  # the UCS test's (the triaxial test has none)
        p.add_argument("--approach-velocity", type=number("approach-velocity", 0.0, 100.0,
                                                          unit="m/s"),
                       default=ld.approach_velocity,
                       help="speed of each platen until the first crack [m/s], then "
                            "--platen-velocity (the specimen is elastic up to there; default "
                            f"{ld.approach_velocity:g}; 0 or a speed not above "
                            "--platen-velocity: off)")
        p.add_argument("--approach-ramp", type=number("approach-ramp", 0.0, 1000.0),
                       default=ld.approach_ramp,
                       help="the platens slow from the approach velocity to "
                            "--platen-velocity over this many times the time a compression "
                            "wave takes to cross the specimen (default "
                            f"{ld.approach_ramp:g}; 0: at once)")
    add_specimen_args(p, geo)


def run_geometry(args):
    from ..lab.runner import Geometry

    return Geometry(scale=args.scale, diameter_mm=args.diameter, height_mm=args.height,
                    sigma0_MPa=args.sigma0, install_gap_mm=args.install_gap,
                    relax_ratio=args.relax_ratio, genesis=args.genesis)


def run_settings(args, cls=None, **extra):
    """The loading settings (``cls``: UCSSettings, the default, or TriaxialSettings)."""
    if cls is None:
        from ..lab.ucs import UCSSettings as cls
    fields = {f.name for f in dataclasses.fields(cls)}
    approach = {k: getattr(args, k) for k in ("approach_velocity", "approach_ramp")
                if k in fields and hasattr(args, k)}  # the UCS test's
    return cls(platen_velocity=args.platen_velocity, strain_rate=args.strain_rate,
               damping=args.damping, stop_drop=args.stop_drop, max_strain=args.max_strain,
               density_scaling=args.density_scaling,
               platen_fric=args.platen_fric, record_strain=args.record_strain,
               end_cap=args.end_cap, end_cap_factor=args.end_cap_factor,
               max_steps=args.max_steps, **approach, **extra)


def file_arg(p, flag, help_, nargs=None):
    """A required file option (an input or a declared output of the job)."""
    p.add_argument(flag, required=True, nargs=nargs, help=help_)


#: BTSSettings fields that are command options: ``bpmcal bts --FIELD`` and, for the closed
#: loop of a card with a σt target, ``bpmcal verify/transfer --bts-FIELD`` (the study
#: passes its `bts` section to all three, so σt is measured as for the regression's model)
BTS_OPTIONS = ("min_balls_across", "loading", "jaw_ratio", "contact_cap", "contact_cap_factor",
               "central_zone", "retests", "platen_velocity", "approach_velocity", "approach_damage",
               "platen_fric", "damping", "stop_drop", "density_scaling", "post_peak_strain",
               "max_strain", "record_strain")

def _add_options(g, spec: dict, defaults, lab) -> None:
    """The options of ``spec`` (field -> (type, help with ``{d}`` for the default)) on
    ``g``, named ``--lab(field)``."""
    for f, (kind, text) in spec.items():
        d = getattr(defaults, f)
        g.add_argument("--" + lab(f), type=kind, default=d, help=text.format(d=d))


def _stop_spec(lab) -> dict:
    """The options every quasi-static tensile test shares (damping and the load-drop stop),
    in the ``spec`` form of :func:`add_bts_args` and :func:`add_dtt_args`."""
    return {
        "damping": (number(lab("damping"), 0.0, 1.0, hi_open=True),
                    "local damping in [0, 1) (default {d:g})"),
        "stop_drop": (fraction(lab("stop_drop")),
                      "stop when the load < this fraction of the peak after it "
                      "(default {d:g})"),
        "density_scaling": (number(lab("density_scaling"), 0.0, 1.0),
                            DENSITY_SCALING_HELP.replace("{d}", "the true masses")),
    }


def add_bts_args(p, prefix: str = ""):
    """The Brazilian disc and loading options (defaults: ``BTSSettings`` and the ISRM disc)
    on ``p``: ``--OPTION``, or ``--bts-OPTION`` with ``prefix="bts_"`` (verify, transfer);
    read back by :func:`bts_settings_of` and :func:`bts_disc_of` with the same prefix."""
    from ..lab.brazilian import BTSSettings
    from ..lab.runner import BTS_DIAMETER_MM, BTS_THICKNESS_MM

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
                            "disc is sized for the sigma_t measurement (the resolution curve: "
                            "docs/measurements/2026-11-26-tensile-strength.md)")
    g.add_argument(opt("thickness"), type=positive(lab("thickness"), "mm"),
                   default=BTS_THICKNESS_MM,
                   help=f"disc thickness before scaling [mm] (default {BTS_THICKNESS_MM:g}, "
                        "ISRM t = D/2)")
    from ..lab.brazilian import FLATJOINT_MIN_ACROSS, LOADINGS, MAX_ACROSS

    spec = {
        "min_balls_across": (number(lab("min_balls_across"), 0.0, MAX_ACROSS), "a coarser "
                             "disc is enlarged to this many mean ball diameters across (default "
                             f"{{d}}: 0 for parallel bonds, {FLATJOINT_MIN_ACROSS:g} for flat joints)"),
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
        "retests": (integer(lab("retests"), 0, 10),
                    "discs tested after an invalid one, each packed with a further seed; the "
                    "first valid disc is the test (ISRM: an invalid test is discarded) "
                    "(default {d}; 0: one disc)"),
        "platen_velocity": (number(lab("platen_velocity"), 0.0, 100.0, lo_open=True,
                                   unit="m/s"),
                            "speed of each platen [m/s] (default {d:g}; its effect on sigma_t: "
                            "docs/lab-tests.md)"),
        "approach_velocity": (number(lab("approach_velocity"), 0.0, 100.0, unit="m/s"),
                              "speed of each platen until the approach's share of the "
                              "bonds has broken [m/s] (default {d:g}; 0: off, the whole "
                              "test at the platen velocity)"),
        "approach_damage": (number(lab("approach_damage"), 0.0, 1.0, hi_open=True),
                            "the approach ends once this fraction of the disc's bonds has "
                            "broken (default {d:g}; 0: at the first crack)"),
        "platen_fric": (number(lab("platen_fric"), 0.0, 10.0),
                        "platen friction coefficient (default {d:g}; with 0 the free disc "
                        "spins on the platens before it seats, and sigma_t is ~15 %% lower)"),
        **_stop_spec(lab),
        "post_peak_strain": (number(lab("post_peak_strain"), 0.0, 0.5),
                             "stop only this much platen approach / D (a strain) past the peak "
                             "(default {d:g}; 0 stops at the load drop, enough for sigma_t)"),
        "max_strain": (number(lab("max_strain"), 0.0, 0.5, lo_open=True),
                       "stop at this platen approach / D (default {d:g})"),
        "record_strain": (number(lab("record_strain"), 0.0, 0.01, lo_open=True),
                          "platen approach / D between records (default {d:g})"),
    }
    assert tuple(spec) == BTS_OPTIONS
    _add_options(g, spec, bd, lab)


def bts_settings_of(args, prefix: str = ""):
    """``BTSSettings`` from the options of :func:`add_bts_args`."""
    from ..lab.brazilian import BTSSettings

    return BTSSettings(**{f: getattr(args, prefix + f) for f in BTS_OPTIONS})


def bts_disc_of(args, prefix: str = ""):
    """The disc of the options of :func:`add_bts_args` at --scale, with the cylinder's
    genesis options."""
    from ..lab.runner import bts_geometry

    scale = getattr(args, prefix + "scale", None) if prefix else None
    return bts_geometry(scale=args.scale if scale is None else scale,
                        diameter_mm=getattr(args, prefix + "diameter"),
                        thickness_mm=getattr(args, prefix + "thickness"), sigma0_MPa=args.sigma0,
                        install_gap_mm=args.install_gap, relax_ratio=args.relax_ratio,
                        genesis=args.genesis)


#: DTTSettings fields that are command options (``bpmcal dtt --FIELD``)
DTT_OPTIONS = ("grip_velocity", "grip_length", "grip_clearance", "damping", "stop_drop",
               "density_scaling", "post_peak_strain", "max_strain", "record_strain")


def add_dtt_args(p, prefix: str = ""):
    """The direct-tension cylinder and loading options (defaults: ``DTTSettings`` and the
    UCS cylinder) on ``p``: ``--OPTION``, or ``--dtt-OPTION`` with ``prefix="dtt_"``; read
    back by :func:`dtt_settings_of` and :func:`dtt_cylinder_of` with the same prefix."""
    from ..lab.direct_tension import DTTSettings
    from ..lab.runner import Geometry

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
        **_stop_spec(lab),
        "post_peak_strain": (number(lab("post_peak_strain"), 0.0, 0.5),
                             "... at least this axial strain past the peak (default {d:g})"),
        "max_strain": (number(lab("max_strain"), 0.0, 0.5, lo_open=True),
                       "stop at this axial strain (default {d:g})"),
        "record_strain": (number(lab("record_strain"), 0.0, 0.01, lo_open=True),
                          "axial strain between records (default {d:g})"),
    }
    assert tuple(spec) == DTT_OPTIONS
    _add_options(g, spec, dd, lab)


def dtt_settings_of(args, prefix: str = ""):
    """``DTTSettings`` from the options of :func:`add_dtt_args`."""
    from ..lab.direct_tension import DTTSettings

    return DTTSettings(**{f: getattr(args, prefix + f) for f in DTT_OPTIONS})


def dtt_cylinder_of(args, prefix: str = ""):
    """The cylinder of the options of :func:`add_dtt_args` at --scale, with the genesis
    options."""
    from ..lab.runner import Geometry

    scale = getattr(args, prefix + "scale", None) if prefix else None
    return Geometry(scale=args.scale if scale is None else scale, diameter_mm=args.diameter,
                    height_mm=args.height, sigma0_MPa=args.sigma0,
                    install_gap_mm=args.install_gap, relax_ratio=args.relax_ratio,
                    genesis=args.genesis)


#: the design triaxial test's stop: its peak alone is used, and replayed on 40 recorded
#: runs a drop to 0.9 of the peak (0.2 % strain past it) kept every peak at 63 % of the
#: loading steps (docs/measurements/2026-11-27j-tri-stop-replay.md)
DESIGN_STOP_DROP = 0.9


def add_tri_args(p):
    """The triaxial test at the study's design confinement (``triaxial.design_sigma3_MPa``):
    ``--design-sigma3`` and ``--tri-servo-alpha``. The cylinder and its axial loading are the
    UCS test's options (as the cards' triaxial runs take them from the compression
    section); read back by :func:`tri_settings_of`."""
    from ..lab.triaxial import TriaxialSettings

    td = TriaxialSettings()
    g = p.add_argument_group("triaxial test at the design confinement")
    g.add_argument("--design-sigma3", type=number("design-sigma3", 0.0, 1000.0, lo_open=True,
                                               unit="MPa"),
                   default=None, metavar="MPA",
                   help="confining stress [MPa] of the triaxial test of each packing seed, "
                        "on the UCS cylinder with the UCS loading (the study's "
                        "triaxial.design_sigma3_MPa; default none)")
    g.add_argument("--tri-servo-alpha", type=number("tri-servo-alpha", 0.0, 1.0, lo_open=True),
                   default=td.servo_alpha,
                   help=f"servo relaxation factor alpha in (0, 1] (default {td.servo_alpha:g})")
    g.add_argument("--design-stop-drop", type=number("design-stop-drop", 0.0, 1.0, lo_open=True,
                                                     hi_open=True),
                   default=DESIGN_STOP_DROP,
                   help="stop that triaxial test once sigma1 - sigma3 has fallen below this "
                        "fraction of its peak (and post_peak_strain past it): only its peak "
                        f"is used (default {DESIGN_STOP_DROP:g}; the cards' triaxial runs "
                        "keep the compression section's stop_drop)")


def tri_settings_of(args):
    """``TriaxialSettings`` of the options of :func:`add_tri_args` and the UCS loading
    options (the stop drop: ``--design-stop-drop``), or None without ``--design-sigma3``."""
    from ..lab.triaxial import TriaxialSettings

    if args.design_sigma3 is None:
        return None
    st = run_settings(args, TriaxialSettings, sigma3=args.design_sigma3 * 1e6,
                      servo_alpha=args.tri_servo_alpha)
    return dataclasses.replace(st, stop_drop=args.design_stop_drop)


def seed_tests_of(args, cylinder: bool = True):
    """The tests a card's seed runs (``stages.measure.SeedTests``) from the options of
    ``verify``, ``transfer``, ``fresh-seeds`` and ``posterior``: the cylinder and its
    loading, the ``--bts-*`` disc, the ``--dtt-*`` test (its cylinder; ``cylinder``
    False: the UCS cylinder, as the transfer's) and the triaxial test at
    ``--design-sigma3``."""
    from ..stages.measure import SeedTests

    return SeedTests(geometry=run_geometry(args), settings=run_settings(args),
                     bts_geometry=bts_disc_of(args, "bts_"),
                     bts_settings=bts_settings_of(args, "bts_"),
                     dtt_geometry=dtt_cylinder_of(args, "dtt_") if cylinder else None,
                     dtt_settings=dtt_settings_of(args, "dtt_"),
                     tri_settings=tri_settings_of(args))


# ------------------------------------------------------------------ the closed loop's options
def _loop_fields(names=None) -> list:
    from ..analysis.calibration.loop_settings import LoopSettings

    return [f for f in dataclasses.fields(LoopSettings) if names is None or f.name in names]


def _loop_type(name: str, limit):
    """An argparse type of the option ``name`` of a ``LoopSettings`` field of ``limit``:
    its value checked by the field's own check (one set of limits), refused naming the
    option."""
    def conv(s):
        try:
            return limit.parse(s, name)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    conv.__name__ = name
    conv.bounds = limit.bounds  # compared with the config schema's (tests)
    return conv


def add_loop_args(p, names=None):
    """The closed loop's options (``bpmcal verify``; ``transfer`` the ``names`` it takes):
    one ``--FIELD`` per field of ``LoopSettings``, its default, its limits and its help
    line the field's; a bool an on/off switch (``--polish``/``--no-polish``); read back by
    :func:`loop_settings_of`."""
    from ..stages.measure import TENSILE_REPLICATE_STRIDE

    for f in _loop_fields(names):
        limit, text, d = f.metadata["limit"], f.metadata["help"], f.default
        opt = "--" + f.name.replace("_", "-")
        if limit.kind == "bool":
            p.add_argument(opt, action=argparse.BooleanOptionalAction, default=d,
                           help=text.format(d="on" if d else "off"))
        elif limit.kind == "choice":
            p.add_argument(opt, choices=limit.words, default=d, help=text.format(d=d))
        else:
            p.add_argument(opt, type=_loop_type(opt[2:], limit), default=d,
                           help=text.format(d=d, stride=TENSILE_REPLICATE_STRIDE))


def loop_settings_of(args, names=None):
    """``LoopSettings`` from the options of :func:`add_loop_args` (those of ``names``; the
    other fields keep their defaults)."""
    from ..analysis.calibration.loop_settings import LoopSettings

    return LoopSettings(**{f.name: getattr(args, f.name) for f in _loop_fields(names)})


def loop_argv(section: dict, *, tensile: bool = False, triaxial: bool = False) -> list[str]:
    """The ``bpmcal verify`` options of a config's ``verification`` section (the ``verify``
    job's, :mod:`bpmcal.cli.jobs`): ``--FIELD VALUE`` for every ``LoopSettings`` field,
    a bool as its switch, the section's values checked as ``LoopSettings`` checks them.
    Left out: a null (the option's default is the same none) and a field that cannot act
    on this study (its ``needs``: ``tensile``, a σt target; ``triaxial``, a σ1 target; a
    field's name, that field set), so that changing it reruns nothing."""
    from ..analysis.calibration.loop_settings import LoopSettings

    fs = _loop_fields()
    LoopSettings(**{f.name: section[f.name] for f in fs if f.name in section})  # checked
    have = {"tensile": tensile, "triaxial": triaxial}
    out = []
    for f in fs:
        v = section.get(f.name, f.default)
        if v is None or not all(have[n] if n in have else section.get(n) is not None
                                for n in f.metadata["needs"]):
            continue
        name = f.name.replace("_", "-")
        if f.metadata["limit"].kind == "bool":
            out.append(f"--{name}" if v else f"--no-{name}")
        else:
            out += [f"--{name}", str(v)]
    return out
