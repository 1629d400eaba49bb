"""The ``bpmcal`` command: one subcommand per job of the study (workflow rules call these).

    bpmcal ucs --params FILE.yaml --out RUN.h5 [--set NAME=VALUE ...] [--scale S] [--seed N]
    bpmcal bts --params FILE.yaml --out RUN.h5 [--scale S] [--seed N] [--platen-velocity V]
    bpmcal triaxial --params FILE.yaml --sigma3 MPA --out RUN.h5 [--scale S] [--seed N]
    bpmcal summary RUN.h5 [--json]
    bpmcal vtk RUN.h5 --out DIR

Parameters are in the paper's units at this edge (mm, GPa, MPa, degrees); the package
works in SI inside. Bad input (arguments, parameter values, input files, output paths,
resource budgets) is reported before any work starts as one line on stderr,
``bpmcal CMD: error: ...``, with exit code 2, and nothing is written. Exit codes: 0 done,
1 internal error (a bug: traceback and a hint), 2 bad input, 3 the DEM run failed and its
failure record was written (0 with ``--failed-ok``, what the workflow rules pass),
4 system error (disk full, permission), 130 interrupted. Helpers: ``bpmcal.cli_args``.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
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
    BadInput,
    Parser,
    fraction,
    in_file,
    integer,
    number,
    out_dir,
    out_file,
    parse_json,
    positive,
    read_csv,
    read_json,
    read_yaml,
)
from .io.paths import name_problem


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
        if "phase" in d:  # genesis: phase, steps, ratio, target, wall_s (of the phase)
            rate = d.get("steps", 0) / max(d.get("wall_s", 0.0), 1e-9)
            self._write(f"{self.label}: genesis, {d['phase']:16s} unbalanced-force ratio "
                        f"{d.get('ratio', 0):9.3g} (target {d.get('target', 0):g})  "
                        f"{d.get('steps', 0):8d} steps  {rate:8.0f} steps/s")
            return
        rate = d.get("steps", 0) / max(d.get("wall_s", now - self._t0), 1e-9)
        line = (f"{self.label}: strain {d.get('strain', 0) * 100:6.3f} %  stress "
                f"{d.get('stress_MPa', 0):7.2f} MPa (peak {d.get('peak_MPa', 0):7.2f})  cracks "
                f"{d.get('cracks', 0):6d}  {d.get('steps', 0):8d} steps  {rate:8.0f} steps/s")
        self._write(line)

    def _write(self, line: str):
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
    rows.append("exit codes: 0 done, 2 bad input (nothing written), 3 the run failed and its "
                "failure record was written (0 with --failed-ok), 1 internal error, "
                "4 system error, 130 interrupted")
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
    non-numeric, boolean, NaN or out-of-domain values raise)."""
    d = {}
    if path is not None:
        d = read_yaml(path, "--params")
        if "parameters" in d:  # a material card
            if not isinstance(d["parameters"], dict):
                raise BadInput(f"--params {path}: 'parameters' is not a mapping of parameter "
                               "names to values")
            d = dict(d["parameters"])
    d.update(_parse_set(overrides))
    try:
        return P.validate_params(d)
    except P.ParameterError as e:
        raise P.ParameterError(f"--params {path}: {e}" if path is not None else str(e)) from None


def params_from_design(path, sample_id) -> tuple[dict, int, str]:
    """The 8 parameters, the seed and a skip reason ("" to run) of one row of a design CSV.
    A sweep-plan row with status "unreachable" is not run: its reason is returned and its
    parameters (NaN strengths) are not validated."""
    from .study.sweep import UNREACHABLE

    d = read_csv(path, "--design", ["sample_id", *P.PARAMS, "seed"], dtype={"sample_id": str})
    row = d[d["sample_id"] == sample_id]
    if len(row) != 1:
        raise BadInput(f"--sample {sample_id!r}: {'not in' if len(row) == 0 else 'repeated in'} "
                       f"{path} ({len(d)} samples: {d['sample_id'].iloc[0]}..."
                       f"{d['sample_id'].iloc[-1]})")
    r = row.iloc[0]
    raw = r["seed"].item() if hasattr(r["seed"], "item") else r["seed"]
    try:
        seed = float(raw)
    except (TypeError, ValueError):
        seed = math.nan
    if not (math.isfinite(seed) and seed == int(seed) and 0 <= seed < 2 ** 32):
        raise BadInput(f"--design {path} sample {sample_id}: seed={raw!r}: expected an "
                       "integer in [0, 2^32)")
    if "status" in d.columns and str(r["status"]) == UNREACHABLE:
        reason = r["reason"] if "reason" in d.columns and isinstance(r["reason"], str) else ""
        return {k: r[k] for k in P.PARAMS}, int(seed), f"not run: unreachable ratio: {reason}"
    try:
        params = P.validate_params({k: r[k] for k in P.PARAMS})
    except P.ParameterError as e:
        raise P.ParameterError(f"--design {path} sample {sample_id}: {e}") from None
    return params, int(seed), ""


def _run_done(a, cmd: str, out) -> int:
    """Exit code of a DEM run command; the FAILED line is printed even with --quiet."""
    if out.status == "ok":
        return EXIT_OK
    where = (f"failure record written to {out.path}; the good run in {out.kept} was kept"
             if out.kept else "failure record written")
    print(f"bpmcal {cmd}: FAILED: {a.out}: {out.error} ({where})", file=sys.stderr)
    sys.stderr.flush()
    return EXIT_OK if a.failed_ok and not out.kept else EXIT_RUN_FAILED


def _float_or_nan(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _cache_dir(a):
    if getattr(a, "specimen_cache", None) is not None:
        out_dir(a.specimen_cache, "--specimen-cache")


def _check_budget(a, params, geo):
    from .lab.budget import check_budget

    check_budget(params, geo, max_balls=a.max_balls, mem_budget_mb=a.mem_budget_mb)


def _params_seed(a) -> tuple[dict, int, str]:
    """Parameters, packing seed and (for a plan row not to be run) the reason, of a DEM run
    command: ``--params`` (+ ``--set``) or a ``--design`` row (argparse makes the two
    exclusive)."""
    skip = ""
    if a.design is not None:
        if a.sample is None:
            raise BadInput("--design needs --sample ID (the row to run)")
        params, seed, skip = params_from_design(a.design, a.sample)
        if not skip and a.set:
            params = P.validate_params({**params, **_parse_set(a.set)})
        seed = seed if a.seed is None else a.seed
    else:
        if a.sample is not None:
            raise BadInput(f"--sample {a.sample}: needs --design FILE")
        params = load_params(a.params, a.set)
        seed = 1 if a.seed is None else a.seed
    return params, int(seed), skip


def _run_command(a, cmd: str, geo, run, inputs, done_line) -> int:
    """The common body of ``ucs``, ``bts`` and ``triaxial``: parameters and seed, resource
    budget, output path (all before any work), then the run (``run(params, seed,
    progress)`` -> RunOutcome), its one-line result and the exit code."""
    from .lab.runner import write_failure

    params, seed, skip = _params_seed(a)
    if not skip:
        _check_budget(a, params, geo)
    out_file(a.out)
    _cache_dir(a)
    if skip:
        inp = inputs({k: _float_or_nan(v) for k, v in params.items()}, seed)
        return _run_done(a, cmd, write_failure(a.out, test=cmd, inputs=inp, error=skip))
    prog = Progress(f"{cmd} {Path(a.out).name}", enabled=not a.quiet)
    out = run(params, seed, prog)
    if out.status == "ok":
        prog.done(f"{a.out}: {done_line(out.summary)}")
    else:
        prog.done()
    return _run_done(a, cmd, out)


def cmd_ucs(a) -> int:
    from .lab.runner import run_ucs_file, ucs_inputs

    geo, st = run_geometry(a), run_settings(a)
    return _run_command(
        a, "ucs", geo,
        lambda p, seed, prog: run_ucs_file(a.out, p, seed, geo, st, cache=a.specimen_cache,
                                           progress=prog, threads=a.threads,
                                           genesis_max_steps=a.genesis_max_steps),
        lambda p, seed: ucs_inputs(p, seed, geo, st),
        lambda s: (f"sigma_c = {s['ucs_MPa']:.3f} MPa, E = {s['E_GPa']:.3f} GPa, "
                   f"nu = {s['nu']:.3f}, cracks {s['cracks_tension']}+{s['cracks_shear']}, "
                   f"{s['n_balls']} balls, {s['steps']} steps, {s['wall_s']:.1f} s "
                   f"({s['stop_reason']})"))


def cmd_bts(a) -> int:
    from .lab.brazilian import BTSSettings
    from .lab.runner import bts_geometry, bts_inputs, run_bts_file

    geo = bts_geometry(scale=a.scale, diameter_mm=a.diameter, thickness_mm=a.thickness,
                       sigma0_MPa=a.sigma0, install_gap_mm=a.install_gap,
                       relax_ratio=a.relax_ratio, genesis=a.genesis)
    st = BTSSettings(platen_velocity=a.platen_velocity, platen_fric=a.platen_fric,
                     damping=a.damping, stop_drop=a.stop_drop, max_strain=a.max_strain,
                     record_strain=a.record_strain)
    return _run_command(
        a, "bts", geo,
        lambda p, seed, prog: run_bts_file(a.out, p, seed, geo, st, cache=a.specimen_cache,
                                           progress=prog, threads=a.threads,
                                           genesis_max_steps=a.genesis_max_steps),
        lambda p, seed: bts_inputs(p, seed, geo, st),
        lambda s: (f"sigma_t = {s['bts_MPa']:.3f} MPa (peak load {s['peak_load_N']:.1f} N, "
                   f"platen forces differ by {100 * s['platen_mismatch']:.2f} %), cracks "
                   f"{s['cracks_tension']}+{s['cracks_shear']}, {s['n_balls']} balls, "
                   f"{s['steps']} steps, {s['wall_s']:.1f} s ({s['stop_reason']})"))


def cmd_triaxial(a) -> int:
    from .lab.runner import run_triaxial_file, triaxial_inputs
    from .lab.triaxial import TriaxialSettings

    geo = run_geometry(a)
    st = TriaxialSettings(sigma3=a.sigma3 * 1e6, platen_velocity=a.platen_velocity,
                          strain_rate=a.strain_rate, damping=a.damping,
                          stop_drop=a.stop_drop, max_strain=a.max_strain,
                          platen_fric=a.platen_fric, record_strain=a.record_strain,
                          servo_alpha=a.servo_gain, servo_interval=a.servo_interval)

    def line(s):
        dev = (f"{100 * s['sigma3_maxdev_rel']:.2f} %" if a.sigma3 > 0
               else f"{s['sigma3_maxdev_MPa']:.3f} MPa")
        return (f"sigma3 = {a.sigma3:g} MPa, sigma1 = {s['sigma1_MPa']:.3f} MPa, "
                f"E = {s['E_GPa']:.3f} GPa, nu = {s['nu']:.3f}, sigma3 held within {dev} "
                f"up to the peak, cracks {s['cracks_tension']}+{s['cracks_shear']}, "
                f"{s['steps']} steps, {s['wall_s']:.1f} s ({s['stop_reason']})")

    return _run_command(
        a, "triaxial", geo,
        lambda p, seed, prog: run_triaxial_file(a.out, p, seed, geo, st,
                                                cache=a.specimen_cache, progress=prog,
                                                threads=a.threads,
                                                genesis_max_steps=a.genesis_max_steps),
        lambda p, seed: triaxial_inputs(p, seed, geo, st), line)


def cmd_design(a) -> int:
    from .study.design import lhs_design

    ranges = parse_json(a.ranges, "--ranges")
    if not isinstance(ranges, dict):
        raise BadInput(f"--ranges {a.ranges}: expected a JSON object "
                       '{"name": [low, high], ...}')
    out_file(a.out, suffixes=(".csv",))
    opt = None if a.optimization == "none" else a.optimization
    df = lhs_design(ranges, a.n, a.seed, optimization=opt)
    _write_csv(df, a.out)
    print(f"{a.out}: {len(df)} samples over {sorted(ranges)} (seed {a.seed})")
    return 0


def cmd_gather(a) -> int:
    from .study.gather import gather, status_report

    design = read_csv(a.design, "--design", ["sample_id", *P.PARAMS, "seed"],
                      dtype={"sample_id": str})
    for sid in design["sample_id"]:
        m = name_problem(sid)
        if m:
            raise BadInput(f"--design {a.design}: sample_id {m}")
    runs_dir = Path(a.runs)
    if not runs_dir.is_dir():
        raise BadInput(f"--runs {a.runs}: not a directory (expected the folder of the "
                       "<sample_id>.h5 run files)")
    out_file(a.out, suffixes=(".csv",))
    df = gather(design, {sid: runs_dir / f"{sid}.h5" for sid in design["sample_id"]})
    _write_csv(df, a.out)
    print(status_report(df))
    return 0


def _write_csv(df, path):
    """Write a table atomically (temporary name, then rename)."""
    from .io.atomic import atomic_path

    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)


def _json_arg(text, name):
    return parse_json(text, name)


def _dataset(path, flag="--dataset", min_ok: int = 1):
    """A gathered dataset CSV with the columns the analyses need and enough ok samples."""
    df = read_csv(path, flag, ["sample_id", *P.PARAMS, "status"])
    n_ok = int((df["status"] == "ok").sum())
    if n_ok < min_ok:
        raise BadInput(f"{flag} {path}: {n_ok} of {len(df)} samples have status ok; this step "
                       f"needs at least {min_ok}")
    return df


def _models(path, flag="--models"):
    from .analysis import models_from_dict

    d = read_json(path, flag)
    try:
        models = models_from_dict(d)
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise BadInput(f"{flag} {path}: not a models.json of 'bpmcal regress' "
                       f"({type(e).__name__}: {e})") from None
    if "ucs_MPa" not in models:
        raise BadInput(f"{flag} {path}: no model of ucs_MPa")
    return models


def _card(path, flag="--card", need=("parameters",)) -> dict:
    """A material card (YAML mapping) with the keys ``need`` and valid parameters."""
    d = read_yaml(path, flag)
    missing = [k for k in need if k not in d]
    if missing:
        raise BadInput(f"{flag} {path}: not a material card (no {', '.join(missing)}; "
                       "expected the output of 'bpmcal calibrate' or 'bpmcal verify')")
    if "parameters" in d:
        if not isinstance(d["parameters"], dict):
            raise BadInput(f"{flag} {path}: 'parameters' is not a mapping")
        try:
            P.validate_params(d["parameters"])
        except P.ParameterError as e:
            raise P.ParameterError(f"{flag} {path}: {e}") from None
    return d


def _out_dirs(a, *flags):
    for f in flags:
        v = getattr(a, f.lstrip("-").replace("-", "_"))
        if v is not None:
            out_dir(v, f)


def cmd_screen(a) -> int:
    from .study.pipeline import screen

    _dataset(a.dataset, min_ok=max(a.splits, 4))
    _out_dirs(a, "--out", "--tables", "--figures")
    r = screen(a.dataset, a.out, a.tables, a.figures, threshold=a.threshold,
               importance=a.importance, n_splits=a.splits, n_repeats=a.repeats, seed=a.seed)
    print(r["note"])
    for k, v in r["selected"].items():
        print(f"{k}: {', '.join(v)}")
    return 0


def cmd_regress(a) -> int:
    from .study.pipeline import regress

    _dataset(a.dataset, min_ok=max(a.cv_folds, 4))
    sel = read_json(a.selected, "--selected")
    if not isinstance(sel, dict) or not isinstance(sel.get("selected"), dict):
        raise BadInput(f"--selected {a.selected}: not a selected.json of 'bpmcal screen' "
                       "(no 'selected' mapping)")
    _out_dirs(a, "--out", "--tables", "--figures")
    r = regress(a.dataset, a.selected, a.out, a.tables, a.figures, alpha_in=a.alpha_in,
                alpha_out=a.alpha_out, vif_max=a.vif_max, hierarchy=a.hierarchy,
                cv_folds=a.cv_folds, cv_repeats=a.cv_repeats, seed=a.seed)
    print(r["note"])
    print((Path(a.out) / "equations.md").read_text())
    return 0


def cmd_calibrate(a) -> int:
    from .study.config import load_lab
    from .study.pipeline import calibrate

    load_lab(in_file(a.lab, "--lab"))  # specimen names become file names: check them first
    fixed = _json_arg(a.fixed, "--fixed")
    if not isinstance(fixed, dict):
        raise BadInput(f"--fixed {a.fixed}: expected a JSON object of parameter values")
    try:
        fixed = P.validate_params(fixed, require_all=False)
    except P.ParameterError as e:
        raise P.ParameterError(f"--fixed: {e}") from None
    if a.n_boot == 1:
        raise P.ParameterError(f"--n-boot {a.n_boot}: expected 0 (no bootstrap) "
                               "or an integer >= 2")
    free = a.free.split(",") if a.free else None
    if free:
        bad = [f for f in free if f not in P.PARAMS]
        if bad:
            raise BadInput(f"--free {a.free}: unknown parameter(s) {bad}; expected names from "
                           f"{list(P.PARAMS)}")
    ratio = None if a.ratio <= 0 else a.ratio
    if a.ratio_from:
        ch = read_json(a.ratio_from, "--ratio-from")
        if not isinstance(ch, dict) or "chosen_ratio" not in ch:
            raise BadInput(f"--ratio-from {a.ratio_from}: no 'chosen_ratio' (expected the "
                           "chosen.json of 'bpmcal sweep-analyse')")
        if ch["chosen_ratio"] is None:
            print(f"--ratio-from {a.ratio_from}: the sweep chose no ratio "
                  f"({ch.get('reason', 'no usable run')}); using --ratio {a.ratio:g}")
        else:
            ratio = P.as_number(ch["chosen_ratio"], f"--ratio-from {a.ratio_from}: "
                                "chosen_ratio", "a positive ratio", BadInput)
            if ratio <= 0:
                raise BadInput(f"--ratio-from {a.ratio_from}: chosen_ratio={ratio:g}: "
                               "expected a positive ratio")
    ranges = _json_arg(a.ranges, "--ranges")
    bounds = _json_arg(a.bounds, "--bounds") if a.bounds else {}
    for name, val in (("--ranges", ranges), ("--bounds", bounds)):
        if not isinstance(val, dict):
            raise BadInput(f"{name}: expected a JSON mapping of parameter name to "
                           f"[low, high] (paper units), got {val!r}")
    from .analysis.calibration import check_calibration_space

    check_calibration_space(free, fixed, ratio, ranges, bounds)
    _dataset(a.dataset)
    _models(a.models)
    _out_dirs(a, "--out", "--tables")
    r = calibrate(a.dataset, a.models, a.lab, a.out, fixed=fixed, ranges=ranges, bounds=bounds,
                  ratio=ratio, free=free, n_boot=a.n_boot, seed=a.seed, tables_dir=a.tables)
    print(r["table"].to_string())
    return 0


def _run_inputs(a, params):
    """Geometry and UCS settings of a DEM command and the budget of ``params``, checked;
    then the output folder and the cache folder."""
    geo, st = run_geometry(a), run_settings(a)
    _check_budget(a, params, geo)
    _out_dirs(a, "--out")
    _cache_dir(a)
    return geo, st


def cmd_verify(a) -> int:
    from .study.pipeline import verify

    card = _card(a.card, need=("parameters", "targets", "roles"))
    _models(a.models)
    geo, st = _run_inputs(a, card["parameters"])
    prog = Progress(f"verify {Path(a.card).stem}", enabled=not a.quiet)
    v = verify(a.card, a.models, a.out, geometry=geo, settings=st,
               seed=a.seed, rtol=a.rtol, max_rounds=a.max_rounds, cache=a.specimen_cache,
               threads=a.threads, progress=prog,
               from_unreachable=a.from_unreachable)["verification"]
    prog.done(f"{v['status']} after {v['rounds']} round(s): {v['message']}")
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
    from .study.pipeline import seed_scatter_runs

    seeds = _seeds(a.seeds)
    card = _card(a.card, need=("parameters", "specimen"))
    geo, st = _run_inputs(a, card["parameters"])
    sc = seed_scatter_runs(a.card, a.out, geometry=geo, settings=st,
                           seeds=seeds, rtol=a.rtol, cache=a.specimen_cache, threads=a.threads)
    print(sc.to_string())
    return 0


def cmd_vtables(a) -> int:
    from .study.config import load_lab
    from .study.pipeline import verification_tables

    cards = {}
    for c in a.cards:
        _card(c, "--cards", need=("parameters", "targets", "verification", "lab"))
        spec = Path(c).parent.name
        m = name_problem(spec)
        if m:
            raise BadInput(f"--cards {c}: folder name {m}")
        cards[spec] = c
    load_lab(in_file(a.lab, "--lab"))
    _out_dirs(a, "--tables", "--figures")
    r = verification_tables(cards, a.lab, a.tables, a.figures)
    print(r["table5"].to_string())
    print(r["table6"].to_string())
    return 0


def _ratios(text) -> tuple[float, float, float]:
    from .study.sweep import ratio_grid

    parts = text.split(",")
    try:
        start, stop, step = (float(x) for x in parts)
    except ValueError:
        raise BadInput(f"--ratios {text!r}: expected start,stop,step (three numbers)") from None
    try:
        ratio_grid(start, stop, step)
    except P.ParameterError as e:
        raise BadInput(f"--ratios {text!r}: {e}") from None
    return start, stop, step


def cmd_sweep_plan(a) -> int:
    from .study.sweep import ratio_grid, sweep_plan

    start, stop, step = _ratios(a.ratios)
    card = _card(a.card, need=("parameters", "targets"))
    if "ucs_MPa" not in (card["targets"] or {}):
        raise BadInput(f"--card {a.card}: no targets.ucs_MPa")
    models = _models(a.models)
    out_file(a.out, suffixes=(".csv",))
    plan = sweep_plan(card, models["ucs_MPa"], ratio_grid(start, stop, step), a.seed)
    _write_csv(plan, a.out)
    print(plan.to_string())
    bad = plan[plan["status"] != "planned"]
    for r in bad.itertuples():
        print(f"{r.sample_id}: {r.status}: {r.reason}")
    return 0


def cmd_sweep_analyse(a) -> int:
    from .io.h5 import read_cracks
    from .io.vtk import export_run
    from .plots.fracture import fig_failure_patterns, fig_ratio_cracks
    from .plots.style import save
    from .study.pipeline import write_table
    from .study.sweep import analyse_sweep, write_chosen

    plan = read_csv(a.plan, "--plan", ["sample_id", "ratio", "pb_ten_MPa", "pb_coh_MPa",
                                       "extrapolated"], dtype={"sample_id": str})
    for sid in plan["sample_id"]:
        m = name_problem(sid)
        if m:
            raise BadInput(f"--plan {a.plan}: sample_id {m}")
    if not Path(a.runs).is_dir():
        raise BadInput(f"--runs {a.runs}: not a directory")
    out_file(a.chosen, "--chosen", suffixes=(".json",))
    _out_dirs(a, "--tables", "--figures", "--vtk")
    df, chosen = analyse_sweep(plan, a.runs, a.criterion, a.target)
    write_table(df, Path(a.tables) / "ratio_sweep.csv", index=False)
    write_chosen(a.chosen, chosen)
    save(fig_ratio_cracks(df, chosen), Path(a.figures) / "fig4_ratio_cracks.png")
    ok = df[df["status"] == "ok"]
    show = sorted({ok["ratio"].iloc[0], chosen["chosen_ratio"], 1.0, ok["ratio"].iloc[-1]}
                  & set(ok["ratio"])) if len(ok) else []
    panels = {}
    for r in show:
        sid = ok.loc[ok["ratio"] == r, "sample_id"].iloc[0]
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

    card = _card(a.card, need=())
    if "parameters" in card or "verification" in card:
        params = (card.get("verification") or {}).get("parameters") or card.get("parameters")
    else:
        params = card  # a flat mapping of the 8 parameters
    if not isinstance(params, dict):
        raise BadInput(f"--card {a.card}: no parameters")
    try:
        params = P.validate_params(params)
    except P.ParameterError as e:
        raise P.ParameterError(f"--card {a.card}: {e}") from None
    geo = run_geometry(a)
    st = ImpactSettings(velocity=a.velocity, hammer_mass=a.hammer_mass * a.scale ** 3,
                        dp_ratio=a.dp_ratio, platen_fric=a.anvil_fric,
                        duration=a.duration_ms * 1e-3, record_dt=a.record_us * 1e-6)
    _check_budget(a, params, geo)
    out_file(a.out)
    _cache_dir(a)
    prog = Progress(f"impact {Path(a.out).name}", enabled=not a.quiet)
    out = run_impact_file(a.out, params, a.seed, geo, st, cache=a.specimen_cache,
                          threads=a.threads, progress=prog,
                          genesis_max_steps=a.genesis_max_steps)
    if out.status == "ok":
        s = out.summary
        prog.done(f"{a.out}: W_in = {s['W_in_J']:.3f} J, G_f = {s['G_f_J']:.3f} J, eta_f = "
                  f"{100 * s['eta_f']:.1f} %, t10 = {s['t10_pct']:.1f} %, closure "
                  f"{100 * s['closure_rel_max']:.3f} %, {s['steps']} steps, {s['wall_s']:.0f} s")
    else:
        prog.done()
    return _run_done(a, "impact", out)


def cmd_impact_analyse(a) -> int:
    import pandas as pd

    from .io.h5 import RunFileError, check_run_file, read_inputs, read_series, read_summary
    from .lab.fragments import fit_jk
    from .plots.fracture import fig_impact, fig_t10
    from .plots.style import fig_note, save
    from .study.pipeline import write_table, write_text

    check_run_file(a.main)
    for f in a.runs:
        in_file(f, "--runs")
    _out_dirs(a, "--tables", "--figures")
    main_s = read_summary(a.main)
    if main_s.get("status") == "ok":
        ser = read_series(a.main)
        ser["cracks_total"] = ser["cracks_tension"] + ser["cracks_shear"]
        fig7 = fig_impact(ser, main_s)
    else:
        ser = pd.DataFrame({"status": [main_s.get("status")], "error": [main_s.get("error")]})
        fig7 = fig_note("Fig. 7 not available", f"the impact run {Path(a.main).name} failed: "
                        f"{main_s.get('error', '')}")
        print(f"{a.main}: run failed ({main_s.get('error', '')}); Fig. 7 not drawn")
    write_table(ser, Path(a.tables) / "impact_energy.csv", index=False)
    save(fig7, Path(a.figures) / "fig7_impact_energy.png")
    cols = ["velocity", "W_in_J", "G_f_J", "eta_f", "ecs_kWh_t", "t10_pct", "n_fragments",
            "largest_fragment_frac", "balls_per_t10_fragment"]
    rows = []
    for f in a.runs:
        try:
            s = read_summary(f)
        except RunFileError as e:
            s = {"status": "unreadable", "error": str(e)}
        if s.get("status") != "ok":
            v = read_inputs(f).get("impact_velocity") if s["status"] == "failed" else None
            print(f"{f}: {s['status']} ({s.get('error', '')}); left out of the t10 fit")
            rows.append({"velocity": v, "status": s["status"], "error": s.get("error", "")})
            continue
        rows.append({**{c: s[c] for c in cols}, "status": "ok", "error": ""})
    t = pd.DataFrame(rows, columns=[*cols, "status", "error"]).sort_values("velocity")
    ok = t[t["status"] == "ok"]
    try:
        fit = fit_jk(ok["ecs_kWh_t"], ok["t10_pct"])
    except (ValueError, RuntimeError, TypeError) as e:
        fit = None
        print(f"JK fit failed: {e}")
    write_table(t, Path(a.tables) / "t10_ecs.csv", index=False)
    write_text(Path(a.tables) / "jk_fit.json", json.dumps(fit, indent=2) + "\n")
    save(fig_t10(ok, fit), Path(a.figures) / "t10_ecs.png")
    print(t.to_string())
    print(f"JK fit: {fit}")
    return 0


def cmd_report(a) -> int:
    from .io.atomic import write_text
    from .report.build import build

    if (a.config is None) == (a.config_json is None):
        raise BadInput("give the study config with exactly one of --config FILE and "
                       "--config-json TEXT")
    if a.config_json is not None:
        cfg = parse_json(a.config_json, "--config-json")
    elif a.config.endswith(".json"):
        cfg = read_json(a.config, "--config")
    else:
        cfg = read_yaml(a.config, "--config")
    if not isinstance(cfg, dict) or not isinstance(cfg.get("study"), dict):
        raise BadInput("--config: not a study config (no 'study' section)")
    if not Path(a.outdir).is_dir():
        raise BadInput(f"--outdir {a.outdir}: not a directory (expected the study's output "
                       "folder)")
    if a.config_out is not None:
        out_file(a.config_out, "--config-out", suffixes=(".json",))
    _out_dirs(a, "--out")
    if a.config_out is not None:
        write_text(a.config_out, json.dumps(cfg, indent=1, sort_keys=True) + "\n")
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
    from .io.h5 import read_summary
    from .io.vtk import export_run

    s = read_summary(a.run)
    if s.get("status") != "ok":
        raise BadInput(f"{a.run}: a failure record (status {s.get('status')}: "
                       f"{s.get('error', '')}), no particles to export")
    _out_dirs(a, "--out")
    files = export_run(a.run, a.out)
    for f in files:
        print(f)
    return 0


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


def add_outcome_args(p):
    """How a DEM run command reports: progress, and the exit code of a failed run."""
    p.add_argument("--quiet", action="store_true",
                   help="no progress output (a FAILED line is still printed)")
    p.add_argument("--failed-ok", action="store_true", help=FAILED_OK_HELP)


def add_budget_args(p):
    """Resource guards of a DEM command (checked before any work)."""
    from .lab.budget import GENESIS_MAX_STEPS, MAX_BALLS

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


GENESES = ("bpmcal", "pfc")  # = lab.specimen.GENESES (not imported: keeps --help fast)
GENESIS_HELP = ("specimen genesis after the packing: bpmcal (locked-in stress relieved to "
                "--sigma0, bonds on touching pairs) or pfc (Itasca's tutorial practice: "
                "every overlap relieved to zero force, bonds within a positive gap); default "
                "bpmcal")
INSTALL_GAP_HELP = ("bond pairs with surface gap <= this [mm] (default: the genesis's, 0 for "
                    "bpmcal, 0.0625 Rmin for pfc)")


def add_run_args(p):
    """Options of the specimen and of the UCS loading (shared by ucs, verify, scatter)."""
    p.add_argument("--scale", type=number("scale", 0.0, 10.0, lo_open=True), default=1.0,
                   help="specimen size factor on the 50 x 100 mm cylinder (default 1)")
    p.add_argument("--diameter", type=positive("diameter", "mm"), default=50.0,
                   help="specimen diameter before scaling [mm] (default 50)")
    p.add_argument("--height", type=positive("height", "mm"), default=100.0,
                   help="specimen height before scaling [mm] (default 100)")
    p.add_argument("--relax-ratio", type=number("relax-ratio", 0.0, 0.1, lo_open=True),
                   default=1e-2,
                   help="genesis equilibrium: mean unbalanced-force ratio (default 1e-2)")
    p.add_argument("--record-strain", type=number("record-strain", 0.0, 0.01, lo_open=True),
                   default=1e-5, help="axial strain between records (default 1e-5)")
    p.add_argument("--platen-velocity", type=number("platen-velocity", 0.0, 100.0,
                                                    lo_open=True, unit="m/s"), default=0.05,
                   help="speed of each platen [m/s] (default 0.05)")
    p.add_argument("--strain-rate", type=positive("strain-rate", "1/s"), default=None,
                   help="axial strain rate [1/s]; overrides --platen-velocity "
                        "(each platen then moves at rate x H / 2)")
    p.add_argument("--damping", type=number("damping", 0.0, 1.0, hi_open=True), default=0.7,
                   help="local damping in [0, 1) (default 0.7)")
    p.add_argument("--stop-drop", type=fraction("stop-drop"), default=0.7,
                   help="stop when stress < this fraction of the peak after it (default 0.7)")
    p.add_argument("--max-strain", type=number("max-strain", 0.0, 0.5, lo_open=True),
                   default=0.03, help="stop at this axial strain (default 0.03)")
    p.add_argument("--platen-fric", type=number("platen-fric", 0.0, 10.0), default=0.0,
                   help="platen friction coefficient in [0, 10] (default 0, frictionless)")
    p.add_argument("--sigma0", type=number("sigma0", 0.0, 100.0, unit="MPa"), default=0.1,
                   help="locked-in isotropic stress after genesis [MPa] (default 0.1)")
    p.add_argument("--install-gap", type=number("install-gap", 0.0, 1.0, unit="mm"),
                   default=None, help=INSTALL_GAP_HELP)
    p.add_argument("--genesis", choices=GENESES, default="bpmcal", help=GENESIS_HELP)
    p.add_argument("--threads", type=THREADS, default=None, help="numba threads (>= 1)")
    p.add_argument("--specimen-cache", default=None,
                   help="directory of cached packings (default ~/.cache/bpmcal/packings or "
                        "$BPMCAL_SPECIMEN_CACHE)")
    add_budget_args(p)


def run_geometry(a):
    from .lab.runner import Geometry
    return Geometry(scale=a.scale, diameter_mm=a.diameter, height_mm=a.height,
                    sigma0_MPa=a.sigma0, install_gap_mm=a.install_gap,
                    relax_ratio=a.relax_ratio, genesis=a.genesis)


def run_settings(a):
    from .lab.ucs import UCSSettings
    return UCSSettings(platen_velocity=a.platen_velocity, strain_rate=a.strain_rate,
                       damping=a.damping, stop_drop=a.stop_drop, max_strain=a.max_strain,
                       platen_fric=a.platen_fric, record_strain=a.record_strain)


FAILED_OK_HELP = ("a failed run (failure record written) exits 0 instead of 3; the workflow "
                  "passes this so that one failed sample does not stop the study")


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog="bpmcal", description=__doc__.split("\n\n")[0],
                formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"bpmcal {_version()}")
    sub = ap.add_subparsers(dest="cmd", required=True)

    u = sub.add_parser("ucs", help="one virtual uniaxial compression test -> HDF5",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog=_param_help())
    add_source_args(u)
    add_run_args(u)
    add_outcome_args(u)
    u.set_defaults(func=cmd_ucs)

    from .lab.brazilian import BTSSettings

    bd = BTSSettings()  # the defaults of the Brazilian test live in its settings
    b = sub.add_parser("bts", help="one virtual Brazilian (diametral compression) test -> HDF5",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog=_param_help())
    add_source_args(b)
    b.add_argument("--scale", type=number("scale", 0.0, 10.0, lo_open=True), default=1.0,
                   help="specimen size factor on the ISRM 50 x 25 mm disc (default 1)")
    b.add_argument("--diameter", type=positive("diameter", "mm"), default=50.0,
                   help="disc diameter before scaling [mm] (default 50)")
    b.add_argument("--thickness", type=positive("thickness", "mm"), default=25.0,
                   help="disc thickness before scaling [mm] (default 25, ISRM t = D/2)")
    b.add_argument("--platen-velocity", type=number("platen-velocity", 0.0, 100.0,
                                                    lo_open=True, unit="m/s"),
                   default=bd.platen_velocity,
                   help=f"speed of each platen [m/s] (default {bd.platen_velocity:g}: halving "
                        "it changes sigma_t by < 2 %%, see the README)")
    b.add_argument("--platen-fric", type=number("platen-fric", 0.0, 10.0),
                   default=bd.platen_fric,
                   help=f"platen friction coefficient (default {bd.platen_fric:g}; with 0 the "
                        "free disc spins on the platens before it seats, and sigma_t is ~15 %% "
                        "lower)")
    b.add_argument("--damping", type=number("damping", 0.0, 1.0, hi_open=True),
                   default=bd.damping, help=f"local damping in [0, 1) (default {bd.damping:g})")
    b.add_argument("--stop-drop", type=fraction("stop-drop"), default=bd.stop_drop,
                   help="stop when the load < this fraction of the peak after it "
                        f"(default {bd.stop_drop:g})")
    b.add_argument("--max-strain", type=number("max-strain", 0.0, 0.5, lo_open=True),
                   default=bd.max_strain,
                   help=f"stop at this platen approach / D (default {bd.max_strain:g})")
    b.add_argument("--record-strain", type=number("record-strain", 0.0, 0.01, lo_open=True),
                   default=bd.record_strain,
                   help=f"platen approach / D between records (default {bd.record_strain:g})")
    b.add_argument("--sigma0", type=number("sigma0", 0.0, 100.0, unit="MPa"), default=0.1,
                   help="locked-in isotropic stress after genesis [MPa] (default 0.1)")
    b.add_argument("--install-gap", type=number("install-gap", 0.0, 1.0, unit="mm"),
                   default=None, help=INSTALL_GAP_HELP)
    b.add_argument("--genesis", choices=GENESES, default="bpmcal", help=GENESIS_HELP)
    b.add_argument("--relax-ratio", type=number("relax-ratio", 0.0, 0.1, lo_open=True),
                   default=1e-2,
                   help="genesis equilibrium: mean unbalanced-force ratio (default 1e-2)")
    b.add_argument("--threads", type=THREADS, default=None, help="numba threads (>= 1)")
    b.add_argument("--specimen-cache", default=None,
                   help="directory of cached packings (default ~/.cache/bpmcal/packings or "
                        "$BPMCAL_SPECIMEN_CACHE)")
    add_budget_args(b)
    add_outcome_args(b)
    b.set_defaults(func=cmd_bts)

    from .lab.triaxial import TriaxialSettings

    td = TriaxialSettings()
    t = sub.add_parser("triaxial", help="one virtual triaxial compression test -> HDF5",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog=_param_help())
    add_source_args(t)
    t.add_argument("--sigma3", required=True, metavar="MPA",
                   type=number("sigma3", 0.0, 1000.0, unit="MPa"),
                   help="confining stress [MPa] in [0, 1000], held by a servo-controlled "
                        "lateral wall")
    t.add_argument("--servo-gain", type=number("servo-gain", 0.0, 1.0, lo_open=True),
                   default=td.servo_alpha,
                   help=f"servo relaxation factor alpha in (0, 1] (default {td.servo_alpha:g}, "
                        "as PFC)")
    t.add_argument("--servo-interval", type=integer("servo-interval", 1, 1000),
                   default=td.servo_interval,
                   help=f"steps between servo updates (default {td.servo_interval})")
    add_run_args(t)
    add_outcome_args(t)
    t.set_defaults(func=cmd_triaxial)

    d = sub.add_parser("design", help="Latin-hypercube design over parameter ranges -> CSV")
    d.add_argument("--ranges", required=True,
                   help='JSON mapping of parameter name to [low, high] (paper units)')
    d.add_argument("--n", type=integer("n", 2, 1_000_000), required=True,
                   help="number of samples")
    d.add_argument("--seed", type=SEED, required=True, help="design seed")
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
    sc.add_argument("--threshold", type=number("threshold", 0.0, 100.0), default=10.0,
                    help="selection threshold [%%]")
    sc.add_argument("--importance", default="gain",
                    choices=["gain", "total_gain", "permutation", "shap"],
                    help="importance type that drives the selection (default gain)")
    sc.add_argument("--splits", type=integer("splits", 2, 100), default=5,
                    help="CV folds (default 5)")
    sc.add_argument("--repeats", type=integer("repeats", 1, 1000), default=10,
                    help="permutation repeats")
    sc.add_argument("--seed", type=SEED, default=0)
    sc.set_defaults(func=cmd_screen)

    rg = sub.add_parser("regress", help="three-stage stepwise regression (Table 4)")
    rg.add_argument("--dataset", required=True)
    rg.add_argument("--selected", required=True, help="selected.json of the screening")
    rg.add_argument("--out", required=True, help="output directory (regression)")
    rg.add_argument("--tables", required=True)
    rg.add_argument("--figures", required=True)
    rg.add_argument("--alpha-in", type=number("alpha-in", 0.0, 0.5, lo_open=True), default=0.05)
    rg.add_argument("--alpha-out", type=number("alpha-out", 0.0, 0.5, lo_open=True),
                    default=0.05)
    rg.add_argument("--vif-max", type=number("vif-max", 1.0), default=10.0)
    rg.add_argument("--hierarchy", default="strong", choices=["strong", "weak", "none"])
    rg.add_argument("--cv-folds", type=integer("cv-folds", 2, 100), default=5)
    rg.add_argument("--cv-repeats", type=integer("cv-repeats", 1, 1000), default=10)
    rg.add_argument("--seed", type=SEED, default=0)
    rg.set_defaults(func=cmd_regress)

    ca = sub.add_parser("calibrate", help="invert the models for the lab specimens")
    ca.add_argument("--dataset", required=True)
    ca.add_argument("--models", required=True, help="models.json of the regression")
    ca.add_argument("--lab", required=True, help="lab CSV")
    ca.add_argument("--out", required=True, help="directory of the material cards")
    ca.add_argument("--tables", default=None)
    ca.add_argument("--fixed", required=True, help="JSON of the fixed parameters")
    ca.add_argument("--ranges", required=True,
                    help="JSON of the design space {name: [low, high]} the dataset was sampled "
                         "over (the config's ranges); it bounds the free parameters")
    ca.add_argument("--bounds", default=None,
                    help="JSON {name: [low, high]} narrowing --ranges for free parameters "
                         "(the config's calibration.bounds; wider than --ranges is an error)")
    ca.add_argument("--free", default=None, help="comma-separated free parameters")
    ca.add_argument("--ratio", type=number("ratio", None, 100.0), default=1.4,
                    help="bond-strength ratio pb_ten/pb_coh (<= 0: both free)")
    ca.add_argument("--ratio-from", default=None,
                    help="JSON file with the chosen ratio (the ratio sweep's choice; when it "
                         "holds none, --ratio is used)")
    ca.add_argument("--n-boot", type=integer("n-boot", 0, 1_000_000), default=200,
                    help="bootstrap resamples for the intervals (0: no bootstrap, else >= 2)")
    ca.add_argument("--seed", type=SEED, default=0)
    ca.set_defaults(func=cmd_calibrate)

    ve = sub.add_parser("verify", help="closed-loop DEM verification of a material card")
    ve.add_argument("--card", required=True)
    ve.add_argument("--models", required=True)
    ve.add_argument("--out", required=True, help="output directory")
    ve.add_argument("--seed", type=SEED, default=1, help="packing seed of the DEM runs")
    ve.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True), default=0.01,
                    help="relative tolerance (0.01)")
    ve.add_argument("--max-rounds", type=integer("max-rounds", 1, 50), default=5,
                    help="DEM runs at most")
    ve.add_argument("--from-unreachable", action="store_true",
                    help="run the closed loop even when the card's inversion is unreachable "
                         "(default: do not; the verified card says why)")
    ve.add_argument("--quiet", action="store_true")
    add_run_args(ve)
    ve.set_defaults(func=cmd_verify)

    ss = sub.add_parser("scatter", help="one card, several packing seeds: DEM scatter")
    ss.add_argument("--card", required=True)
    ss.add_argument("--out", required=True)
    ss.add_argument("--seeds", required=True, help="comma-separated packing seeds")
    ss.add_argument("--rtol", type=number("rtol", 0.0, 1.0, lo_open=True), default=0.01)
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
    sp.add_argument("--seed", type=SEED, default=1)
    sp.add_argument("--out", required=True)
    sp.set_defaults(func=cmd_sweep_plan)

    sa = sub.add_parser("sweep-analyse", help="crack counts per ratio, the chosen ratio")
    sa.add_argument("--plan", required=True)
    sa.add_argument("--runs", required=True, help="directory of <sample_id>.h5")
    sa.add_argument("--criterion", default="tensile_share",
                    choices=["tensile_share", "crack_count"])
    sa.add_argument("--target", type=number("target", 0.0), default=0.6)
    sa.add_argument("--tables", required=True)
    sa.add_argument("--figures", required=True)
    sa.add_argument("--vtk", required=True, help="VTK output directory of the shown runs")
    sa.add_argument("--chosen", required=True, help="output JSON with the chosen ratio")
    sa.set_defaults(func=cmd_sweep_analyse)

    im = sub.add_parser("impact", help="drop-hammer impact of a calibrated specimen")
    im.add_argument("--card", required=True, help="material card (verified or calibrated)")
    im.add_argument("--out", required=True)
    im.add_argument("--velocity", type=number("velocity", 0.0, 100.0, lo_open=True,
                                              unit="m/s"), default=6.0, help="m/s")
    im.add_argument("--hammer-mass", type=positive("hammer-mass", "kg"), default=4.383,
                    help="hammer mass at full size [kg]; scaled by scale^3 (default 4.383)")
    im.add_argument("--dp-ratio", type=number("dp-ratio", 0.0, 1.0), default=0.1,
                    help="contact dashpot critical-damping ratio in [0, 1] (default 0.1)")
    im.add_argument("--anvil-fric", dest="anvil_fric", type=number("anvil-fric", 0.0, 10.0),
                    default=0.3, help="friction of anvil and hammer (default 0.3)")
    im.add_argument("--duration-ms", type=positive("duration-ms", "ms"), default=10.0)
    im.add_argument("--record-us", type=positive("record-us", "us"), default=5.0)
    im.add_argument("--seed", type=SEED, default=1)
    im.add_argument("--quiet", action="store_true",
                    help="no progress output (a FAILED line is still printed)")
    im.add_argument("--failed-ok", action="store_true", help=FAILED_OK_HELP)
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
    rp.add_argument("--config", default=None, help="the study's (merged) config, JSON/YAML")
    rp.add_argument("--config-json", default=None,
                    help="... or the config as JSON text (what the workflow passes)")
    rp.add_argument("--config-out", default=None,
                    help="also write the config as JSON to this file")
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
    ap = build_parser()
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
