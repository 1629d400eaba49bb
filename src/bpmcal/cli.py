"""The ``bpmcal`` command: one subcommand per job of the study (workflow rules call these).

    bpmcal ucs --params FILE.yaml --out RUN.h5 [--set NAME=VALUE ...] [--scale S] [--seed N]
    bpmcal bts --params FILE.yaml --out RUN.h5 [--scale S] [--seed N] [--platen-velocity V]
    bpmcal triaxial --params FILE.yaml --sigma3 MPA --out RUN.h5 [--scale S] [--seed N]
    bpmcal summary RUN.h5 [--json]
    bpmcal vtk RUN.h5 --out DIR

Parameters are in the paper's units at this edge (mm, GPa, MPa, degrees); the package
works in SI inside. Bad or missing parameters are reported before any work starts.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

from . import params as P

EXIT_BAD_INPUT = 2


class Progress:
    """A one-line progress bar on a terminal, plain log lines (every ``every`` s) otherwise."""

    def __init__(self, label: str, stream=None, every: float = 10.0, enabled: bool = True):
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.label = label
        self.every = every
        self.enabled = enabled
        self._last = 0.0
        self._t0 = time.perf_counter()

    def __call__(self, d: dict):
        if not self.enabled:
            return
        now = time.perf_counter()
        if not self.tty and now - self._last < self.every:
            return
        self._last = now
        rate = d.get("steps", 0) / max(d.get("wall_s", now - self._t0), 1e-9)
        line = (f"{self.label}: strain {d.get('strain', 0) * 100:6.3f} %  stress "
                f"{d.get('stress_MPa', 0):7.2f} MPa (peak {d.get('peak_MPa', 0):7.2f})  cracks "
                f"{d.get('cracks', 0):6d}  {d.get('steps', 0):8d} steps  {rate:8.0f} steps/s")
        if self.tty:
            self.stream.write("\r" + line)
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def done(self, msg: str = ""):
        if self.enabled and self.tty:
            self.stream.write("\n")
        if msg and self.enabled:
            self.stream.write(msg + "\n")
            self.stream.flush()


def _param_help() -> str:
    rows = ["meso-parameters (keys of the --params YAML file and of --set; paper units):"]
    for p in P.PARAMS.values():
        unit = p.unit or "-"
        rows.append(f"  {p.name:12s} {p.symbol:9s} [{unit:3s}] Table 2 range {p.lo:g}-{p.hi:g}:"
                    f" {p.description}")
    return "\n".join(rows)


def _parse_set(items) -> dict:
    out = {}
    for it in items or []:
        if "=" not in it:
            raise P.ParameterError(f"--set {it!r}: expected NAME=VALUE")
        k, v = it.split("=", 1)
        k = k.strip()
        try:
            out[k] = float(v)
        except ValueError:
            raise P.ParameterError(f"--set {k}={v!r}: expected a number") from None
    return out


def load_params(path, overrides=()) -> dict:
    """Parameters from a YAML file (a flat mapping of the 8 names, or a material card whose
    ``parameters`` hold them) plus NAME=VALUE overrides, validated (unknown, missing,
    non-numeric or out-of-domain values raise)."""
    import yaml

    d = {}
    if path is not None:
        try:
            with open(path) as f:
                d = yaml.safe_load(f) or {}
        except FileNotFoundError:
            raise P.ParameterError(f"--params {path}: no such file") from None
        if not isinstance(d, dict):
            raise P.ParameterError(f"--params {path}: expected a mapping of parameter names "
                                   "to values")
        if isinstance(d.get("parameters"), dict):  # a material card
            d = dict(d["parameters"])
    d.update(_parse_set(overrides))
    return P.validate_params(d)


def _positive(name):
    def conv(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}={s!r}: expected a number") from None
        if not (v > 0 and math.isfinite(v)):
            raise argparse.ArgumentTypeError(f"{name}={s!r}: expected a positive number")
        return v
    return conv


def _fraction(name):
    def conv(s):
        v = _positive(name)(s)
        if v >= 1:
            raise argparse.ArgumentTypeError(f"{name}={s!r}: expected a fraction in (0, 1)")
        return v
    return conv


def params_from_design(path, sample_id) -> tuple[dict, int]:
    """The 8 parameters and the seed of one row of a design CSV."""
    import pandas as pd

    try:
        d = pd.read_csv(path)
    except FileNotFoundError:
        raise P.ParameterError(f"--design {path}: no such file") from None
    row = d[d["sample_id"] == sample_id]
    if len(row) != 1:
        raise P.ParameterError(f"--sample {sample_id!r}: not in {path} "
                               f"({len(d)} samples: {d['sample_id'].iloc[0]}..."
                               f"{d['sample_id'].iloc[-1]})")
    r = row.iloc[0]
    return {k: float(r[k]) for k in P.PARAMS}, int(r["seed"])


def cmd_ucs(a) -> int:
    from .lab.runner import run_ucs_file

    if a.design is not None:
        if a.sample is None:
            raise P.ParameterError("--design needs --sample ID")
        params, seed = params_from_design(a.design, a.sample)
        params.update(_parse_set(a.set))
        params = P.validate_params(params)
        a.seed = seed if a.seed is None else a.seed
    else:
        params = load_params(a.params, a.set)
    a.seed = 1 if a.seed is None else a.seed
    geo = run_geometry(a)
    st = run_settings(a)
    prog = Progress(f"ucs {Path(a.out).name}", enabled=not a.quiet)
    out = run_ucs_file(a.out, params, a.seed, geo, st, cache=a.specimen_cache, progress=prog,
                       threads=a.threads)
    if out.status == "ok":
        s = out.summary
        prog.done(f"{a.out}: sigma_c = {s['ucs_MPa']:.3f} MPa, E = {s['E_GPa']:.3f} GPa, "
                  f"nu = {s['nu']:.3f}, cracks {s['cracks_tension']}+{s['cracks_shear']}, "
                  f"{s['n_balls']} balls, {s['steps']} steps, {s['wall_s']:.1f} s "
                  f"({s['stop_reason']})")
    else:
        prog.done(f"{a.out}: FAILED ({out.error}); failure record written")
    return 0


def _run_params(a) -> tuple[dict, int]:
    """Parameters and seed of a run command: --params (+ --set), or a --design row."""
    if a.design is not None:
        if a.sample is None:
            raise P.ParameterError("--design needs --sample ID")
        params, seed = params_from_design(a.design, a.sample)
        params.update(_parse_set(a.set))
        params = P.validate_params(params)
        seed = seed if a.seed is None else a.seed
    else:
        params = load_params(a.params, a.set)
        seed = 1 if a.seed is None else a.seed
    return params, int(seed)


def _stress_mpa(name, text) -> float:
    """A stress in MPa >= 0 from the command line (one clear error line otherwise)."""
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise P.ParameterError(f"{name} {text!r}: expected a stress in MPa (a number "
                               ">= 0)") from None
    if not (math.isfinite(v) and v >= 0):
        raise P.ParameterError(f"{name} {text!r}: expected a stress in MPa >= 0 "
                               "(compression positive)")
    return v


def cmd_bts(a) -> int:
    from .lab.brazilian import BTSSettings
    from .lab.runner import bts_geometry, run_bts_file

    params, seed = _run_params(a)
    geo = bts_geometry(scale=a.scale, diameter_mm=a.diameter, thickness_mm=a.thickness,
                       sigma0_MPa=a.sigma0, install_gap_mm=a.install_gap,
                       relax_ratio=a.relax_ratio)
    st = BTSSettings(platen_velocity=a.platen_velocity, platen_fric=a.platen_fric,
                     damping=a.damping, stop_drop=a.stop_drop, max_strain=a.max_strain,
                     record_strain=a.record_strain)
    prog = Progress(f"bts {Path(a.out).name}", enabled=not a.quiet)
    out = run_bts_file(a.out, params, seed, geo, st, cache=a.specimen_cache, progress=prog,
                       threads=a.threads)
    if out.status == "ok":
        s = out.summary
        prog.done(f"{a.out}: sigma_t = {s['bts_MPa']:.3f} MPa (peak load "
                  f"{s['peak_load_N']:.1f} N, platen forces differ by "
                  f"{100 * s['platen_mismatch']:.2f} %), cracks {s['cracks_tension']}+"
                  f"{s['cracks_shear']}, {s['n_balls']} balls, {s['steps']} steps, "
                  f"{s['wall_s']:.1f} s ({s['stop_reason']})")
    else:
        prog.done(f"{a.out}: FAILED ({out.error}); failure record written")
    return 0


def cmd_triaxial(a) -> int:
    from .lab.runner import run_triaxial_file
    from .lab.triaxial import TriaxialSettings

    sigma3 = _stress_mpa("--sigma3", a.sigma3)  # before any work
    params, seed = _run_params(a)
    geo = run_geometry(a)
    st = TriaxialSettings(sigma3=sigma3 * 1e6, platen_velocity=a.platen_velocity,
                          strain_rate=a.strain_rate, damping=a.damping,
                          stop_drop=a.stop_drop, max_strain=a.max_strain,
                          platen_fric=a.platen_fric, record_strain=a.record_strain,
                          servo_alpha=a.servo_gain, servo_interval=a.servo_interval)
    prog = Progress(f"triaxial {Path(a.out).name}", enabled=not a.quiet)
    out = run_triaxial_file(a.out, params, seed, geo, st, cache=a.specimen_cache,
                            progress=prog, threads=a.threads)
    if out.status == "ok":
        s = out.summary
        dev = (f"{100 * s['sigma3_maxdev_rel']:.2f} %" if sigma3 > 0
               else f"{s['sigma3_maxdev_MPa']:.3f} MPa")
        prog.done(f"{a.out}: sigma3 = {sigma3:g} MPa, sigma1 = {s['sigma1_MPa']:.3f} MPa, "
                  f"E = {s['E_GPa']:.3f} GPa, nu = {s['nu']:.3f}, sigma3 held within {dev} "
                  f"up to the peak, cracks {s['cracks_tension']}+{s['cracks_shear']}, "
                  f"{s['steps']} steps, {s['wall_s']:.1f} s ({s['stop_reason']})")
    else:
        prog.done(f"{a.out}: FAILED ({out.error}); failure record written")
    return 0


def cmd_design(a) -> int:
    from .study.design import lhs_design

    try:
        ranges = json.loads(a.ranges)
    except json.JSONDecodeError as e:
        raise P.ParameterError(f"--ranges: not valid JSON ({e})") from None
    opt = None if a.optimization == "none" else a.optimization
    df = lhs_design(ranges, a.n, a.seed, optimization=opt)
    _write_csv(df, a.out)
    print(f"{a.out}: {len(df)} samples over {sorted(ranges)} (seed {a.seed})")
    return 0


def cmd_gather(a) -> int:
    import pandas as pd

    from .study.gather import gather, status_report

    design = pd.read_csv(a.design)
    runs = {sid: Path(a.runs) / f"{sid}.h5" for sid in design["sample_id"]}
    df = gather(design, runs)
    _write_csv(df, a.out)
    print(status_report(df))
    return 0


def _write_csv(df, path):
    """Write a table atomically (temporary name, then rename)."""
    from .io.atomic import atomic_path

    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)


def _json_arg(text, name):
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise P.ParameterError(f"{name}: not valid JSON ({e})") from None


def cmd_screen(a) -> int:
    from .study.pipeline import screen

    r = screen(a.dataset, a.out, a.tables, a.figures, threshold=a.threshold,
               importance=a.importance, n_splits=a.splits, n_repeats=a.repeats, seed=a.seed)
    print(r["note"])
    for k, v in r["selected"].items():
        print(f"{k}: {', '.join(v)}")
    return 0


def cmd_regress(a) -> int:
    from .study.pipeline import regress

    r = regress(a.dataset, a.selected, a.out, a.tables, a.figures, alpha_in=a.alpha_in,
                alpha_out=a.alpha_out, vif_max=a.vif_max, hierarchy=a.hierarchy,
                cv_folds=a.cv_folds, cv_repeats=a.cv_repeats, seed=a.seed)
    print(r["note"])
    print((Path(a.out) / "equations.md").read_text())
    return 0


def cmd_calibrate(a) -> int:
    from .study.pipeline import calibrate

    fixed = P.validate_params(_json_arg(a.fixed, "--fixed"), require_all=False)
    if a.n_boot == 1 or a.n_boot < 0:
        raise P.ParameterError(f"--n-boot {a.n_boot}: expected 0 (no bootstrap) "
                               "or an integer >= 2")
    free = a.free.split(",") if a.free else None
    ratio = None if a.ratio is not None and a.ratio <= 0 else a.ratio
    if a.ratio_from:
        ratio = float(json.loads(Path(a.ratio_from).read_text())["chosen_ratio"])
    r = calibrate(a.dataset, a.models, a.lab, a.out, fixed=fixed, ratio=ratio, free=free,
                  n_boot=a.n_boot, seed=a.seed, tables_dir=a.tables)
    print(r["table"].to_string())
    return 0


def cmd_verify(a) -> int:
    from .study.pipeline import verify

    prog = Progress(f"verify {Path(a.card).stem}", enabled=not a.quiet)
    v = verify(a.card, a.models, a.out, geometry=run_geometry(a), settings=run_settings(a),
               seed=a.seed, rtol=a.rtol, max_rounds=a.max_rounds, cache=a.specimen_cache,
               threads=a.threads, progress=prog)["verification"]
    prog.done(f"{v['status']} after {v['rounds']} round(s): {v['message']}")
    return 0


def cmd_scatter(a) -> int:
    from .study.pipeline import seed_scatter_runs

    seeds = [int(x) for x in a.seeds.split(",")]
    sc = seed_scatter_runs(a.card, a.out, geometry=run_geometry(a), settings=run_settings(a),
                           seeds=seeds, rtol=a.rtol, cache=a.specimen_cache, threads=a.threads)
    print(sc.to_string())
    return 0


def cmd_vtables(a) -> int:
    from .study.pipeline import verification_tables

    cards = {Path(c).parent.name: c for c in a.cards}
    r = verification_tables(cards, a.lab, a.tables, a.figures)
    print(r["table5"].to_string())
    print(r["table6"].to_string())
    return 0


def cmd_sweep_plan(a) -> int:
    from .analysis import models_from_dict
    from .study.pipeline import read_card
    from .study.sweep import ratio_grid, sweep_plan

    start, stop, step = (float(x) for x in a.ratios.split(","))
    card = read_card(a.card)
    models = models_from_dict(json.loads(Path(a.models).read_text()))
    plan = sweep_plan(card, models["ucs_MPa"], ratio_grid(start, stop, step), a.seed)
    _write_csv(plan, a.out)
    print(plan.to_string())
    return 0


def cmd_sweep_analyse(a) -> int:
    import pandas as pd

    from .io.h5 import read_cracks
    from .io.vtk import export_run
    from .plots.fracture import fig_failure_patterns, fig_ratio_cracks
    from .plots.style import save
    from .study.pipeline import write_table
    from .study.sweep import analyse_sweep, write_chosen

    plan = pd.read_csv(a.plan)
    df, chosen = analyse_sweep(plan, a.runs, a.criterion, a.target)
    write_table(df, Path(a.tables) / "ratio_sweep.csv", index=False)
    write_chosen(a.chosen, chosen)
    save(fig_ratio_cracks(df, chosen), Path(a.figures) / "fig4_ratio_cracks.png")
    show = sorted({plan["ratio"].iloc[0], chosen["chosen_ratio"], 1.0,
                   plan["ratio"].iloc[-1]} & set(plan["ratio"]))
    panels = {}
    for r in show:
        sid = plan.loc[plan["ratio"] == r, "sample_id"].iloc[0]
        run = Path(a.runs) / f"{sid}.h5"
        panels[f"a = {r:.1f}"] = read_cracks(run)
        export_run(run, Path(a.vtk) / sid)
    save(fig_failure_patterns(panels), Path(a.figures) / "fig5_failure_patterns.png")
    print(df.to_string())
    print(f"chosen: {chosen}")
    return 0


def cmd_impact(a) -> int:
    from .lab.impact import ImpactSettings
    from .lab.runner import run_impact_file
    from .study.pipeline import read_card

    card = read_card(a.card)
    params = dict(card.get("verification", {}).get("parameters") or card["parameters"])
    st = ImpactSettings(velocity=a.velocity, hammer_mass=a.hammer_mass * a.scale ** 3,
                        dp_ratio=a.dp_ratio, platen_fric=a.anvil_fric,
                        duration=a.duration_ms * 1e-3, record_dt=a.record_us * 1e-6)
    prog = Progress(f"impact {Path(a.out).name}", enabled=not a.quiet)
    out = run_impact_file(a.out, params, a.seed, run_geometry(a), st, cache=a.specimen_cache,
                          threads=a.threads, progress=prog)
    if out.status == "ok":
        s = out.summary
        prog.done(f"{a.out}: W_in = {s['W_in_J']:.3f} J, G_f = {s['G_f_J']:.3f} J, eta_f = "
                  f"{100 * s['eta_f']:.1f} %, t10 = {s['t10_pct']:.1f} %, closure "
                  f"{100 * s['closure_rel_max']:.3f} %, {s['steps']} steps, {s['wall_s']:.0f} s")
    else:
        prog.done(f"{a.out}: FAILED ({out.error})")
    return 0


def cmd_impact_analyse(a) -> int:
    import pandas as pd

    from .io.h5 import read_series, read_summary
    from .lab.fragments import fit_jk
    from .plots.fracture import fig_impact, fig_t10
    from .plots.style import save
    from .study.pipeline import write_table, write_text

    main_s = read_summary(a.main)
    ser = read_series(a.main)
    ser["cracks_total"] = ser["cracks_tension"] + ser["cracks_shear"]
    write_table(ser, Path(a.tables) / "impact_energy.csv", index=False)
    save(fig_impact(ser, main_s), Path(a.figures) / "fig7_impact_energy.png")
    rows = []
    for f in a.runs:
        s = read_summary(f)
        if s.get("status") != "ok":
            continue
        rows.append({"velocity": s["velocity"], "W_in_J": s["W_in_J"], "G_f_J": s["G_f_J"],
                     "eta_f": s["eta_f"], "ecs_kWh_t": s["ecs_kWh_t"], "t10_pct": s["t10_pct"],
                     "n_fragments": s["n_fragments"],
                     "largest_fragment_frac": s["largest_fragment_frac"],
                     "balls_per_t10_fragment": s["balls_per_t10_fragment"]})
    t = pd.DataFrame(rows).sort_values("velocity")
    try:
        fit = fit_jk(t["ecs_kWh_t"], t["t10_pct"])
    except (ValueError, RuntimeError) as e:
        fit = None
        print(f"JK fit failed: {e}")
    write_table(t, Path(a.tables) / "t10_ecs.csv", index=False)
    write_text(Path(a.tables) / "jk_fit.json", json.dumps(fit, indent=2) + "\n")
    save(fig_t10(t, fit), Path(a.figures) / "t10_ecs.png")
    print(t.to_string())
    print(f"JK fit: {fit}")
    return 0


def cmd_report(a) -> int:
    from .report.build import build

    cfg = _json_arg(Path(a.config).read_text(), "--config") if a.config.endswith(".json") \
        else __import__("yaml").safe_load(Path(a.config).read_text())
    index = build(a.outdir, cfg, a.out)
    print(index)
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
    from .io.vtk import export_run
    files = export_run(a.run, a.out)
    for f in files:
        print(f)
    return 0


def add_run_args(p):
    """Options of the specimen and of the UCS loading (shared by ucs, verify, scatter)."""
    p.add_argument("--scale", type=_positive("scale"), default=1.0,
                   help="specimen size factor on the 50 x 100 mm cylinder (default 1)")
    p.add_argument("--diameter", type=_positive("diameter"), default=50.0,
                   help="specimen diameter before scaling [mm] (default 50)")
    p.add_argument("--height", type=_positive("height"), default=100.0,
                   help="specimen height before scaling [mm] (default 100)")
    p.add_argument("--relax-ratio", type=_positive("relax-ratio"), default=1e-2,
                   help="genesis equilibrium: mean unbalanced-force ratio (default 1e-2)")
    p.add_argument("--record-strain", type=_positive("record-strain"), default=1e-5,
                   help="axial strain between records (default 1e-5)")
    p.add_argument("--platen-velocity", type=_positive("platen-velocity"), default=0.05,
                   help="speed of each platen [m/s] (default 0.05)")
    p.add_argument("--strain-rate", type=_positive("strain-rate"), default=None,
                   help="axial strain rate [1/s]; overrides --platen-velocity "
                        "(each platen then moves at rate x H / 2)")
    p.add_argument("--damping", type=float, default=0.7, help="local damping (default 0.7)")
    p.add_argument("--stop-drop", type=_fraction("stop-drop"), default=0.7,
                   help="stop when stress < this fraction of the peak after it (default 0.7)")
    p.add_argument("--max-strain", type=_positive("max-strain"), default=0.03,
                   help="stop at this axial strain (default 0.03)")
    p.add_argument("--platen-fric", type=float, default=0.0,
                   help="platen friction coefficient (default 0, frictionless)")
    p.add_argument("--sigma0", type=float, default=0.1,
                   help="locked-in isotropic stress after genesis [MPa] (default 0.1)")
    p.add_argument("--install-gap", type=float, default=0.0,
                   help="bond pairs with surface gap <= this [mm] (default 0)")
    p.add_argument("--threads", type=int, default=None, help="numba threads")
    p.add_argument("--specimen-cache", default=None,
                   help="directory of cached packings (default ~/.cache/bpmcal/packings or "
                        "$BPMCAL_SPECIMEN_CACHE)")


def run_geometry(a):
    from .lab.runner import Geometry
    return Geometry(scale=a.scale, diameter_mm=a.diameter, height_mm=a.height,
                    sigma0_MPa=a.sigma0, install_gap_mm=a.install_gap,
                    relax_ratio=a.relax_ratio)


def run_settings(a):
    from .lab.ucs import UCSSettings
    return UCSSettings(platen_velocity=a.platen_velocity, strain_rate=a.strain_rate,
                       damping=a.damping, stop_drop=a.stop_drop, max_strain=a.max_strain,
                       platen_fric=a.platen_fric, record_strain=a.record_strain)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="bpmcal", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"bpmcal {_version()}")
    sub = ap.add_subparsers(dest="cmd", required=True)

    u = sub.add_parser("ucs", help="one virtual uniaxial compression test -> HDF5",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog=_param_help())
    u.add_argument("--params", help="YAML file with the 8 meso-parameters", default=None)
    u.add_argument("--design", default=None,
                   help="take the parameters and the seed from this design CSV ...")
    u.add_argument("--sample", default=None, help="... row with this sample_id")
    u.add_argument("--out", required=True, help="output HDF5 file (written atomically)")
    u.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="override one parameter (repeatable)")
    u.add_argument("--seed", type=int, default=None,
                   help="packing seed (default 1, or the design row's)")
    add_run_args(u)
    u.add_argument("--quiet", action="store_true", help="no progress output")
    u.set_defaults(func=cmd_ucs)

    b = sub.add_parser("bts", help="one virtual Brazilian (diametral compression) test -> HDF5",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog=_param_help())
    b.add_argument("--params", help="YAML file with the 8 meso-parameters (or a material "
                                    "card)", default=None)
    b.add_argument("--design", default=None,
                   help="take the parameters and the seed from this design CSV ...")
    b.add_argument("--sample", default=None, help="... row with this sample_id")
    b.add_argument("--out", required=True, help="output HDF5 file (written atomically)")
    b.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="override one parameter (repeatable)")
    b.add_argument("--seed", type=int, default=None,
                   help="packing seed (default 1, or the design row's)")
    b.add_argument("--scale", type=_positive("scale"), default=1.0,
                   help="specimen size factor on the ISRM 50 x 25 mm disc (default 1)")
    b.add_argument("--diameter", type=_positive("diameter"), default=50.0,
                   help="disc diameter before scaling [mm] (default 50)")
    b.add_argument("--thickness", type=_positive("thickness"), default=25.0,
                   help="disc thickness before scaling [mm] (default 25, ISRM t = D/2)")
    b.add_argument("--platen-velocity", type=_positive("platen-velocity"), default=0.00625,
                   help="speed of each platen [m/s] (default 0.00625: halving it changes "
                        "sigma_t by < 2 %%, see the README)")
    b.add_argument("--platen-fric", type=float, default=0.3,
                   help="platen friction coefficient (default 0.3; with 0 the free disc "
                        "spins on the platens before it seats, and sigma_t is ~15 %% lower)")
    b.add_argument("--damping", type=float, default=0.7, help="local damping (default 0.7)")
    b.add_argument("--stop-drop", type=_fraction("stop-drop"), default=0.7,
                   help="stop when the load < this fraction of the peak after it "
                        "(default 0.7)")
    b.add_argument("--max-strain", type=_positive("max-strain"), default=0.05,
                   help="stop at this platen approach / D (default 0.05)")
    b.add_argument("--record-strain", type=_positive("record-strain"), default=1e-5,
                   help="platen approach / D between records (default 1e-5)")
    b.add_argument("--sigma0", type=float, default=0.1,
                   help="locked-in isotropic stress after genesis [MPa] (default 0.1)")
    b.add_argument("--install-gap", type=float, default=0.0,
                   help="bond pairs with surface gap <= this [mm] (default 0)")
    b.add_argument("--relax-ratio", type=_positive("relax-ratio"), default=1e-2,
                   help="genesis equilibrium: mean unbalanced-force ratio (default 1e-2)")
    b.add_argument("--threads", type=int, default=None, help="numba threads")
    b.add_argument("--specimen-cache", default=None,
                   help="directory of cached packings (default ~/.cache/bpmcal/packings or "
                        "$BPMCAL_SPECIMEN_CACHE)")
    b.add_argument("--quiet", action="store_true", help="no progress output")
    b.set_defaults(func=cmd_bts)

    t = sub.add_parser("triaxial", help="one virtual triaxial compression test -> HDF5",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog=_param_help())
    t.add_argument("--params", help="YAML file with the 8 meso-parameters (or a material "
                                    "card)", default=None)
    t.add_argument("--design", default=None,
                   help="take the parameters and the seed from this design CSV ...")
    t.add_argument("--sample", default=None, help="... row with this sample_id")
    t.add_argument("--sigma3", required=True, metavar="MPA",
                   help="confining stress [MPa] >= 0, held by a servo-controlled lateral wall")
    t.add_argument("--out", required=True, help="output HDF5 file (written atomically)")
    t.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="override one parameter (repeatable)")
    t.add_argument("--seed", type=int, default=None,
                   help="packing seed (default 1, or the design row's)")
    t.add_argument("--servo-gain", type=_positive("servo-gain"), default=0.8,
                   help="servo relaxation factor alpha in (0, 1] (default 0.8, as PFC)")
    t.add_argument("--servo-interval", type=int, default=1,
                   help="steps between servo updates (default 1)")
    add_run_args(t)
    t.add_argument("--quiet", action="store_true", help="no progress output")
    t.set_defaults(func=cmd_triaxial)

    d = sub.add_parser("design", help="Latin-hypercube design over parameter ranges -> CSV")
    d.add_argument("--ranges", required=True,
                   help='JSON mapping of parameter name to [low, high] (paper units)')
    d.add_argument("--n", type=int, required=True, help="number of samples")
    d.add_argument("--seed", type=int, required=True, help="design seed")
    d.add_argument("--optimization", default="random-cd",
                   choices=["random-cd", "lloyd", "none"], help="LHS optimisation")
    d.add_argument("--out", required=True, help="output CSV")
    d.set_defaults(func=cmd_design)

    g = sub.add_parser("gather", help="collect per-sample run files into one dataset CSV")
    g.add_argument("--design", required=True, help="design CSV")
    g.add_argument("--runs", required=True, help="directory of <sample_id>.h5 run files")
    g.add_argument("--out", required=True, help="output CSV")
    g.set_defaults(func=cmd_gather)

    sc = sub.add_parser("screen", help="XGBoost screening of the dataset (Table 3)")
    sc.add_argument("--dataset", required=True)
    sc.add_argument("--out", required=True, help="output directory (screening)")
    sc.add_argument("--tables", required=True, help="tables directory")
    sc.add_argument("--figures", required=True, help="figures directory")
    sc.add_argument("--threshold", type=float, default=10.0, help="selection threshold [%%]")
    sc.add_argument("--importance", default="gain",
                    choices=["gain", "total_gain", "permutation", "shap"],
                    help="importance type that drives the selection (default gain)")
    sc.add_argument("--splits", type=int, default=5, help="CV folds (default 5)")
    sc.add_argument("--repeats", type=int, default=10, help="permutation repeats")
    sc.add_argument("--seed", type=int, default=0)
    sc.set_defaults(func=cmd_screen)

    rg = sub.add_parser("regress", help="three-stage stepwise regression (Table 4)")
    rg.add_argument("--dataset", required=True)
    rg.add_argument("--selected", required=True, help="selected.json of the screening")
    rg.add_argument("--out", required=True, help="output directory (regression)")
    rg.add_argument("--tables", required=True)
    rg.add_argument("--figures", required=True)
    rg.add_argument("--alpha-in", type=float, default=0.05)
    rg.add_argument("--alpha-out", type=float, default=0.05)
    rg.add_argument("--vif-max", type=float, default=10.0)
    rg.add_argument("--hierarchy", default="strong", choices=["strong", "weak", "none"])
    rg.add_argument("--cv-folds", type=int, default=5)
    rg.add_argument("--cv-repeats", type=int, default=10)
    rg.add_argument("--seed", type=int, default=0)
    rg.set_defaults(func=cmd_regress)

    ca = sub.add_parser("calibrate", help="invert the models for the lab specimens")
    ca.add_argument("--dataset", required=True)
    ca.add_argument("--models", required=True, help="models.json of the regression")
    ca.add_argument("--lab", required=True, help="lab CSV")
    ca.add_argument("--out", required=True, help="directory of the material cards")
    ca.add_argument("--tables", default=None)
    ca.add_argument("--fixed", required=True, help="JSON of the fixed parameters")
    ca.add_argument("--free", default=None, help="comma-separated free parameters")
    ca.add_argument("--ratio", type=float, default=1.4,
                    help="bond-strength ratio pb_ten/pb_coh (<= 0: both free)")
    ca.add_argument("--ratio-from", default=None,
                    help="JSON file with the chosen ratio (the ratio sweep's choice)")
    ca.add_argument("--n-boot", type=int, default=200,
                    help="bootstrap resamples for the intervals (0: no bootstrap, else >= 2)")
    ca.add_argument("--seed", type=int, default=0)
    ca.set_defaults(func=cmd_calibrate)

    ve = sub.add_parser("verify", help="closed-loop DEM verification of a material card")
    ve.add_argument("--card", required=True)
    ve.add_argument("--models", required=True)
    ve.add_argument("--out", required=True, help="output directory")
    ve.add_argument("--seed", type=int, default=1, help="packing seed of the DEM runs")
    ve.add_argument("--rtol", type=float, default=0.01, help="relative tolerance (0.01)")
    ve.add_argument("--max-rounds", type=int, default=5, help="DEM runs at most")
    ve.add_argument("--quiet", action="store_true")
    add_run_args(ve)
    ve.set_defaults(func=cmd_verify)

    ss = sub.add_parser("scatter", help="one card, several packing seeds: DEM scatter")
    ss.add_argument("--card", required=True)
    ss.add_argument("--out", required=True)
    ss.add_argument("--seeds", required=True, help="comma-separated packing seeds")
    ss.add_argument("--rtol", type=float, default=0.01)
    add_run_args(ss)
    ss.set_defaults(func=cmd_scatter)

    vt = sub.add_parser("verification-tables", help="Tables 5 and 6 and Fig. 6")
    vt.add_argument("--cards", nargs="+", required=True, help="verification card.yaml files")
    vt.add_argument("--lab", required=True)
    vt.add_argument("--tables", required=True)
    vt.add_argument("--figures", required=True)
    vt.set_defaults(func=cmd_vtables)

    sp = sub.add_parser("sweep-plan", help="bond-strength-ratio sweep: one row per ratio")
    sp.add_argument("--card", required=True, help="material card (the initial calibration)")
    sp.add_argument("--models", required=True)
    sp.add_argument("--ratios", default="0.5,2.0,0.1", help="start,stop,step")
    sp.add_argument("--seed", type=int, default=1)
    sp.add_argument("--out", required=True)
    sp.set_defaults(func=cmd_sweep_plan)

    sa = sub.add_parser("sweep-analyse", help="crack counts per ratio, the chosen ratio")
    sa.add_argument("--plan", required=True)
    sa.add_argument("--runs", required=True, help="directory of <sample_id>.h5")
    sa.add_argument("--criterion", default="tensile_share",
                    choices=["tensile_share", "crack_count"])
    sa.add_argument("--target", type=float, default=0.6)
    sa.add_argument("--tables", required=True)
    sa.add_argument("--figures", required=True)
    sa.add_argument("--vtk", required=True, help="VTK output directory of the shown runs")
    sa.add_argument("--chosen", required=True, help="output JSON with the chosen ratio")
    sa.set_defaults(func=cmd_sweep_analyse)

    im = sub.add_parser("impact", help="drop-hammer impact of a calibrated specimen")
    im.add_argument("--card", required=True, help="material card (verified or calibrated)")
    im.add_argument("--out", required=True)
    im.add_argument("--velocity", type=_positive("velocity"), default=6.0, help="m/s")
    im.add_argument("--hammer-mass", type=_positive("hammer-mass"), default=4.383,
                    help="hammer mass at full size [kg]; scaled by scale^3 (default 4.383)")
    im.add_argument("--dp-ratio", type=float, default=0.1,
                    help="contact dashpot critical-damping ratio (default 0.1)")
    im.add_argument("--anvil-fric", dest="anvil_fric", type=float, default=0.3,
                    help="friction of anvil and hammer (default 0.3)")
    im.add_argument("--duration-ms", type=_positive("duration-ms"), default=10.0)
    im.add_argument("--record-us", type=_positive("record-us"), default=5.0)
    im.add_argument("--seed", type=int, default=1)
    im.add_argument("--quiet", action="store_true")
    add_run_args(im)
    im.set_defaults(func=cmd_impact)

    ia = sub.add_parser("impact-analyse", help="impact energy table, Fig. 7, t10-Ecs and JK fit")
    ia.add_argument("--main", required=True, help="the reference impact run (6 m/s)")
    ia.add_argument("--runs", nargs="+", required=True, help="impact runs of the velocity sweep")
    ia.add_argument("--tables", required=True)
    ia.add_argument("--figures", required=True)
    ia.set_defaults(func=cmd_impact_analyse)

    rp = sub.add_parser("report", help="results/report: every table and figure + index.md")
    rp.add_argument("--outdir", required=True, help="the study's output directory")
    rp.add_argument("--config", required=True, help="the study's (merged) config, JSON/YAML")
    rp.add_argument("--out", default=None, help="report directory (default OUTDIR/report)")
    rp.set_defaults(func=cmd_report)

    s = sub.add_parser("summary", help="print the summary attributes of a run file")
    s.add_argument("run")
    s.add_argument("--json", action="store_true", help="one JSON object")
    s.set_defaults(func=cmd_summary)

    v = sub.add_parser("vtk", help="export particles and cracks of a run for ParaView")
    v.add_argument("run")
    v.add_argument("--out", required=True, help="output directory")
    v.set_defaults(func=cmd_vtk)
    return ap


def _version():
    from . import __version__
    return __version__


def main(argv=None) -> int:
    os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
    ap = build_parser()
    a = ap.parse_args(argv)
    from .dem.errors import InputError
    try:
        return a.func(a)
    except (P.ParameterError, InputError) as e:
        print(f"bpmcal {a.cmd}: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
