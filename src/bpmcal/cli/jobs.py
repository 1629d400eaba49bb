"""Every study job's ``bpmcal`` command line, built from a validated study config: one
source for the workflow's rules and for the benchmarks that rerun a job of a study.

``job_argv(config, job, input=..., output=..., wildcards=..., threads=...)`` is the argv of
``bpmcal`` (the subcommand first) for the job of the Snakemake rule ``job``: the config's
settings as the command's options (the option groups of :mod:`bpmcal.cli.options`: the
specimen and its loading, ``--bts-*``, ``--dtt-*``, the design triaxial test, the closed
loop's ``LoopSettings``), the job's files and wildcards, each under its option.
``job_options(config, job)`` is the same command without the files and threads: what a
rule hands to Snakemake as a plain value, whose change reruns the job (Snakemake does not
compare a parameter that is derived from the job's files).

A rule's ``input``/``output`` names are the keys the job reads here (a Snakemake
``Namedlist`` or a dict); a file option whose key is absent or empty is left out when the
command does not need it (``optional``), so a benchmark passes the files it has.

Which tests a closed loop, a transfer, the fresh seeds and the posterior run follows the
study's lab targets (:func:`lab_targets`: a σt, direct-tension or triaxial column with a
value); a benchmark with its own lab passes ``targets``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

from ..io import study_files as L
from .options import BTS_OPTIONS, DTT_OPTIONS, loop_argv

#: lab targets that add a test to a card's runs (their lab CSV column: ``<name>_MPa``)
TARGETS = ("bts", "dtt", "tri")


def lab_targets(config: dict, lab=None) -> frozenset:
    """The study's lab targets that add a test to a card's runs: ``bts`` (a σt target),
    ``dtt`` (a direct-tension strength), ``tri`` (a triaxial strength at the design
    confinement), each when the lab CSV's column (``lab``, else read) has a value."""
    if lab is None:
        from ..study.lab_data import load_lab

        lab = load_lab(config["lab"]["csv"])
    return frozenset(t for t in TARGETS
                     if f"{t}_MPa" in lab.columns and bool(lab[f"{t}_MPa"].notna().any()))


@dataclass(frozen=True)
class _Ref:
    """A token of the job's own: a file of its ``input``/``output``, a wildcard or its
    threads (``source``), after ``flag``; ``optional``: left out when absent or empty."""

    flag: str | None
    source: str
    key: str | None = None
    optional: bool = False
    #: (value, what it stands for) pairs: the token is what its source's value stands for
    #: (None: the value itself)
    table: tuple | None = None


def _in(flag, key, optional=False):
    return _Ref(flag, "input", key, optional)


def _out(flag, key, optional=False):
    return _Ref(flag, "output", key, optional)


def _wc(flag, key, optional=False):
    return _Ref(flag, "wildcards", key, optional)


THREADS = _Ref("--threads", "threads", optional=True)  # none: the command chooses


def _pairs(opts: dict) -> list[str]:
    return [str(x) for k, v in opts.items() for x in (k, v)]


# ------------------------------------------------------------------ the config's option groups
def specimen_args(cfg: dict, scale=None, loading: bool = True, ucs: bool = True,
                  cache: str | None = None) -> list[str]:
    """The specimen (``specimen``), its axial loading (``compression``; ``loading`` False
    for a job that loads no cylinder axially: the impact; ``ucs`` False for one that runs
    no UCS test, without its approach: the triaxial tests) and the resources' guards, as
    options of ``bpmcal sample/ucs/verify/...``; the packing cache the study's own
    (``outdir/cache/packings``) unless ``cache``."""
    sp, u, r = cfg["specimen"], cfg["compression"], cfg["resources"]
    opts = {
        "--scale": sp["scale"] if scale is None else scale,
        "--diameter": sp["diameter_mm"],
        "--height": sp["height_mm"],
        "--sigma0": sp["sigma0_MPa"],
        "--genesis": sp["genesis"],
        "--relax-ratio": sp["relax_ratio"],
    }
    if loading:
        for k in ("platen_velocity", "damping", "stop_drop", "max_strain", "platen_fric",
                  "record_strain", "end_cap", "end_cap_factor"):
            opts["--" + k.replace("_", "-")] = u[k]
    if loading and u["density_scaling"] is not None:  # null: the true masses
        opts["--density-scaling"] = u["density_scaling"]
    if loading and ucs:
        opts["--approach-velocity"] = u["approach_velocity"]
        opts["--approach-ramp"] = u["approach_ramp"]
    opts.update({
        "--specimen-cache": cache or L.StudyFiles(cfg["outdir"]).packings,
        "--max-balls": r["max_balls"],
        "--mem-budget-mb": r["dem_mem_mb"],
        "--genesis-max-steps": r["genesis_max_steps"],
    })
    if sp["install_gap_mm"] is not None:  # null: the genesis's own gap
        opts["--install-gap"] = sp["install_gap_mm"]
    return _pairs(opts)


def bts_args(cfg: dict) -> list[str]:
    """The ``--bts-*`` options of the ``bts`` section: every Brazilian test of the study
    (the samples' and, for a card with a σt target, the closed loops') runs with the same
    disc and loading; a ``BTSSettings`` field that is an option is its config key."""
    b = cfg["bts"]
    opts = {"--bts-diameter": b["diameter_mm"], "--bts-thickness": b["thickness_mm"]}
    if b["scale"] is not None:  # null: the disc at the cylinder's scale
        opts["--bts-scale"] = b["scale"]
    for f in BTS_OPTIONS:
        if b[f] is not None:  # null (min_balls_across): the option's default, by contact model
            opts[f"--bts-{f.replace('_', '-')}"] = b[f]
    return _pairs(opts)


def dtt_args(cfg: dict) -> list[str]:
    """The ``--dtt-*`` options of the ``dtt`` section (the UCS cylinder at ``dtt.scale``)."""
    d = cfg["dtt"]
    opts = {} if d["scale"] is None else {"--dtt-scale": d["scale"]}  # null: the cylinder's
    for f in DTT_OPTIONS:
        if d[f] is not None:  # null (density_scaling): the option's default
            opts[f"--dtt-{f.replace('_', '-')}"] = d[f]
    return _pairs(opts)


def tri_args(cfg: dict) -> list[str]:
    """The triaxial test at the design confinement (``triaxial.design_sigma3_MPa``) on the
    UCS cylinder and loading."""
    t = cfg["triaxial"]
    return _pairs({"--design-sigma3": t["design_sigma3_MPa"],
                   "--tri-servo-alpha": t["servo_alpha"],
                   "--design-stop-drop": t["design_stop_drop"]})


def _tests(cfg: dict, bts: bool, dtt: bool, tri: bool) -> list[str]:
    return ((bts_args(cfg) if bts else []) + (dtt_args(cfg) if dtt else [])
            + (tri_args(cfg) if tri else []))


def _impact(cfg: dict, keys) -> dict:
    i = cfg["impact"]
    names = {"hammer_mass_kg": "--hammer-mass", "scale": "--impact-scale",
             "seed": "--seed"}
    return {names.get(k, "--" + k.replace("_", "-")): i[k] for k in keys}


# ------------------------------------------------------------------ the jobs
def _design(c, t, cache):
    st = c["study"]
    return ["design", "--ranges", json.dumps(c["ranges"]), "--n", str(st["n_samples"]),
            "--seed", str(st["lhs_seed"]), "--optimization", str(st["lhs_optimization"]),
            _out("--out", "design")]


def _sample(c, t, cache):
    on = {k: bool(c[k]["enabled"]) for k in ("bts", "dtt")}
    tri = c["triaxial"]["design_sigma3_MPa"] is not None
    # a benchmark without a design passes --params and --seed instead
    return ["sample", _in("--design", "design", True), _wc("--sample", "sample", True),
            _out("--out", "ucs"), THREADS, "--failed-ok", *specimen_args(c, cache=cache),
            _out("--bts-out", "bts", True), *(bts_args(c) if on["bts"] else []),
            _out("--dtt-out", "dtt", True), *(dtt_args(c) if on["dtt"] else []),
            _out("--tri-out", "tri", True), *(tri_args(c) if tri else [])]


def _gather(c, t, cache):
    return ["gather", _in("--design", "design"), _in("--runs", "runs"),
            _in("--bts-runs", "bts", True), _in("--dtt-runs", "dtt", True),
            _in("--tri-runs", "tri", True), _out("--out", "dataset")]


def _screen(c, t, cache):
    s = c["screening"]
    return ["screen", _in("--dataset", "dataset"), _out("--selected", "selected"),
            _out("--table3", "table3"), _out("--figure", "fig"),
            _out("--importance-table", "importance"), _out("--cv-table", "cv"),
            _out("--shadow-table", "shadow"), _out("--summary", "summary"),
            *_pairs({"--threshold": s["threshold_pct"], "--importance": s["importance"],
                     "--n-splits": s["n_splits"], "--n-repeats": s["n_repeats"],
                     "--rule": s["rule"], "--tensile-rule": s["tensile_rule"],
                     "--seed": s["seed"]})]


def _regress(c, t, cache):
    r = c["regression"]
    outs = [("--models", "models"), ("--equations", "equations"),
            ("--summaries", "summaries"), ("--coefficients", "coefficients"),
            ("--candidates", "candidates"), ("--table4", "table4"), ("--fit-table", "fit"),
            ("--figure", "fig")]
    return ["regress", _in("--dataset", "dataset"), _in("--selected", "selected"),
            *(_out(f, k) for f, k in outs),
            *_pairs({f"--{k.replace('_', '-')}": r[k] for k in (
                "alpha_in", "alpha_out", "vif_max", "hierarchy", "cv_folds", "cv_repeats",
                "seed")})]


def _calibration(c) -> list[str]:
    cal = c["calibration"]
    return ["--fixed", json.dumps(cal["fixed"]), "--free", ",".join(cal["free"]),
            "--ranges", json.dumps(c["ranges"]), "--bounds", json.dumps(cal["bounds"])]


def _calibrate_initial(c, t, cache):
    cal = c["calibration"]
    return ["calibrate", _in("--dataset", "dataset"), _in("--models", "models"),
            _in("--lab", "lab"), _out("--cards", "cards"), *_calibration(c),
            "--ratio", str(cal["strength_ratio"]), "--n-boot", "0",
            "--seed", str(cal["seed"])]


def _calibrate(c, t, cache):
    cal = c["calibration"]
    return ["calibrate", _in("--dataset", "dataset"), _in("--models", "models"),
            _in("--lab", "lab"), _out("--cards", "cards"), _out("--table", "table"),
            *_calibration(c), "--ratio", str(cal["strength_ratio"]),
            _in("--ratio-from", "chosen", True), "--n-boot", str(cal["n_boot"]),
            "--seed", str(cal["seed"])]


def _loop_files(cmd):
    return [cmd, _in("--card", "card"), _in("--models", "models"),
            _out("--out-card", "card"), _out("--rounds", "rounds"), _out("--run", "run")]


def _verify(c, t, cache):
    # the closed loop's settings only (LoopSettings' fields): changing another
    # verification key (fresh_seeds, scatter_seeds) must not rerun the closed loops
    return [*_loop_files("verify"), _out("--seed-runs", "seeds", True),
            *loop_argv(c["verification"], tensile=bool({"bts", "dtt"} & t),
                       triaxial="tri" in t),
            THREADS, *specimen_args(c, cache=cache),
            *_tests(c, "bts" in t, "dtt" in t, "tri" in t)]


def _transfer(c, t, cache):
    from ..study.config import transfer_seed

    v = c["verification"]
    return [*_loop_files("transfer"),
            # the first packing seed no closed loop may use (grown seed sets included)
            *_pairs({"--seed": transfer_seed(v), "--rtol": v["rtol"],
                     "--range-margin": v["range_margin"],
                     "--jacobian-update": v["jacobian_update"],
                     "--max-rounds": c["transfer"]["max_rounds"]}),
            THREADS, *specimen_args(c, scale=c["transfer"]["scale"], cache=cache),
            *_tests(c, "bts" in t, "dtt" in t, "tri" in t)]


def _transfer_table(c, t, cache):
    return ["transfer-table", _in("--cards", "cards"), _out("--table", "table")]


def _seed_scatter(c, t, cache):
    seeds = c["verification"]["scatter_seeds"]
    return ["scatter", _in("--card", "card"), "--seeds", ",".join(str(s) for s in seeds),
            _out("--runs", "runs"), _out("--seed-runs", "seed_runs"),
            _out("--table", "table"), "--rtol", str(c["verification"]["rtol"]), THREADS,
            *specimen_args(c, cache=cache)]


def _fresh_seeds(c, t, cache):
    seeds = c["verification"]["fresh_seeds"]
    return ["fresh-seeds", _in("--card", "card"), "--seeds", ",".join(str(s) for s in seeds),
            _out("--runs", "runs"), _out("--bts-runs", "bts_runs", True),
            _out("--dtt-runs", "dtt_runs", True), _out("--tri-runs", "tri_runs", True),
            _out("--seed-runs", "seed_runs"), THREADS, *specimen_args(c, cache=cache),
            # every card's σt (and σt,d) on the fresh seeds when the study runs the test
            # (a target, or the card's prediction)
            *_tests(c, bool(c["bts"]["enabled"]), "dtt" in t or bool(c["dtt"]["enabled"]),
                    "tri" in t)]


def _fresh_seeds_table(c, t, cache):
    return ["fresh-seeds-table", _in("--cards", "cards"), _in("--seed-runs", "seed_runs"),
            _out("--table", "table"), "--rtol", str(c["verification"]["rtol"])]


def _verification_tables(c, t, cache):
    return ["verification-tables", _in("--cards", "cards"), _in("--runs", "runs"),
            _in("--lab", "lab"), _out("--table5", "table5"), _out("--table6", "table6"),
            _out("--figure", "fig6")]


def _sweep_plan(c, t, cache):
    s = c["ratio_sweep"]
    return ["sweep-plan", _in("--card", "card"), _in("--models", "models"),
            "--ratios", ",".join(str(x) for x in s["ratios"]), "--seed", str(s["seed"]),
            _out("--out", "plan")]


def _sweep_ucs(c, t, cache):
    return ["ucs", _in("--design", "plan"), _wc("--sample", "rid"), _out("--out", "run"),
            THREADS, "--failed-ok", *specimen_args(c, cache=cache)]


def _sweep_analyse(c, t, cache):
    s = c["ratio_sweep"]
    return ["sweep-analyse", _in("--plan", "plan"), _in("--runs", "runs"),
            "--criterion", str(s["criterion"]), "--target", str(s["target"]),
            _out("--table", "table"), _out("--chosen", "chosen"), _out("--fig4", "fig4"),
            _out("--fig5", "fig5"), _out("--vtk", "vtk")]


#: what an impact run reads of the impact section (not the velocities: a job's own is
#: its wildcard)
IMPACT_KEYS = ("hammer_mass_kg", "dp_ratio", "anvil_fric", "duration_ms", "record_us", "seed")


def _impact_job(c, t, cache):
    return ["impact", _in("--card", "card"), _out("--out", "run"), _wc("--velocity", "v"),
            *_pairs(_impact(c, IMPACT_KEYS)), THREADS, "--failed-ok",
            *specimen_args(c, scale=c["impact"]["scale"], loading=False, cache=cache)]


def _impact_analyse(c, t, cache):
    return ["impact-analyse", _in("--main", "main"), _in("--runs", "runs"),
            _out("--energy", "energy"), _out("--t10", "t10"), _out("--jk-fit", "jk_fit"),
            _out("--fig7", "fig7"), _out("--fig-t10", "figt10")]


def _triaxial(c, t, cache):
    tx = c["triaxial"]
    return ["triaxial", _in("--params", "card"), _wc("--sigma3", "s3"),
            "--seed", str(tx["seed"]), "--servo-alpha", str(tx["servo_alpha"]),
            _out("--out", "run"), THREADS, "--failed-ok",
            *specimen_args(c, ucs=False, cache=cache)]


def _triaxial_envelopes(c, t, cache):
    s3 = ",".join(f"{float(x):g}" for x in c["triaxial"]["sigma3_MPa"])
    return ["envelopes", _in("--cards", "cards"), _in("--runs", "runs"), "--sigma3", s3,
            _in("--lab", "lab"), _in("--lab-triaxial", "lab_triaxial", True),
            _out("--lab-table", "lab_table", True), _out("--table", "table"),
            _out("--points", "points"), _out("--figure", "fig")]


def _posterior(c, t, cache):
    p, r = c["posterior"], c["posterior"]["refine"]
    tri = "tri" in t or c["triaxial"]["design_sigma3_MPa"] is not None
    return ["posterior", _in("--card", "card"), _in("--dataset", "dataset"),
            _in("--models", "models"), _in("--loop-seeds", "loop"),
            _in("--fresh-seeds", "fresh", True), _out("--out-card", "card"),
            _out("--table", "table"), _out("--predictions", "predictions"),
            _out("--netcdf", "netcdf"), _out("--figure", "figure"),
            _out("--refine-runs", "refine"), _out("--draws", "draws"),
            "--n-draws", str(p["predictive"]["draws"]),
            _out("--learning", "learning", True),
            _out("--learning-figure", "learning_figure", True),
            *_pairs({"--surrogate": p["surrogate"], "--posterior-seed": p["seed"],
                     "--hdi-prob": p["hdi_prob"], "--rhat-max": p["rhat_max"],
                     "--ess-min": p["ess_min"], "--sampler-max-steps": p["max_steps"],
                     "--refine-max-runs": r["max_runs"], "--refine-ratio": r["ratio"],
                     "--refine-seeds": r["seeds"], "--refine-seed": r["seed"]}),
            THREADS, *specimen_args(c, cache=cache),
            *_tests(c, "bts" in t, "dtt" in t, tri)]


def predictive_sigma3(cfg: dict) -> list[float]:
    """The confining stresses of the posterior predictive's triaxial runs
    (``posterior.predictive.sigma3_MPa``; null: ``triaxial.sigma3_MPa``)."""
    return [float(x) for x in (cfg["posterior"]["predictive"]["sigma3_MPa"]
                               or cfg["triaxial"]["sigma3_MPa"])]


def _posterior_predictive(c, t, cache):
    tx = c["triaxial"]
    return ["predictive", _in("--draws", "draws"), _wc("--specimen", "spec"),
            _out("--table", "table"),
            "--sigma3", ",".join(f"{x:g}" for x in predictive_sigma3(c)),
            _out("--tri-runs", "tri"), _out("--impact-runs", "impact", True),
            _in("--envelopes", "envelopes", True), _in("--card-impact", "card_impact", True),
            "--triaxial-seed", str(tx["seed"]), "--servo-alpha", str(tx["servo_alpha"]),
            *_pairs({"--impact-seed": c["impact"]["seed"],
                     **_impact(c, ("scale", "velocity", *IMPACT_KEYS[:-1]))}),
            THREADS, *specimen_args(c, ucs=False, cache=cache)]


def study_disc_mm(cfg: dict) -> float:
    """The study's Brazilian disc [mm]: ``bts.scale`` (null: the cylinder's scale) times
    ``bts.diameter_mm``."""
    b = cfg["bts"]
    return (b["scale"] if b["scale"] is not None else cfg["specimen"]["scale"]) * b["diameter_mm"]


def bts_size_diameters(cfg: dict, lab=None) -> dict:
    """Specimen -> its lab discs' diameter [mm], where the lab CSV gives one that differs
    from the study's disc (:func:`~bpmcal.study.lab_data.lab_disc_diameters`): the
    specimens of the ``bts_size`` job."""
    from ..study.lab_data import lab_disc_diameters, load_lab

    lab = load_lab(cfg["lab"]["csv"]) if lab is None else lab
    return lab_disc_diameters(lab, study_disc_mm(cfg))


def _bts_size(c, t, cache):
    s = c["bts_size"]
    lab_mm = tuple((k, f"{v:g}") for k, v in bts_size_diameters(c).items())
    return ["bts-size", _in("--card", "card"), _Ref("--lab-diameter", "wildcards", "spec",
                                                   table=lab_mm),
            _out("--run-dir", "run_dir"), _out("--runs", "runs"), _out("--sizes", "sizes"),
            _out("--fit", "fit"), THREADS,
            *_pairs({"--seeds": s["seeds"], "--max-seeds": s["max_seeds"],
                     "--target-se": s["target_se"], "--first-seed": s["first_seed"]}),
            "--middle" if s["middle"] else "--no-middle",
            *specimen_args(c, cache=cache), *bts_args(c)]


def _report(c, t, cache):
    return ["report", "--config-json", json.dumps(c), _out("--config-out", "config")]


#: the workflow's rules and their commands
JOBS = {
    "design": _design, "sample": _sample, "gather": _gather, "screen": _screen,
    "regress": _regress, "calibrate_initial": _calibrate_initial, "calibrate": _calibrate,
    "verify": _verify, "transfer": _transfer, "transfer_table": _transfer_table,
    "seed_scatter": _seed_scatter, "fresh_seeds": _fresh_seeds,
    "fresh_seeds_table": _fresh_seeds_table, "verification_tables": _verification_tables,
    "sweep_plan": _sweep_plan, "sweep_ucs": _sweep_ucs, "sweep_analyse": _sweep_analyse,
    "impact": _impact_job, "impact_analyse": _impact_analyse, "triaxial": _triaxial,
    "triaxial_envelopes": _triaxial_envelopes, "posterior": _posterior,
    "posterior_predictive": _posterior_predictive, "bts_size": _bts_size, "report": _report,
}


#: the jobs whose tests follow the lab targets (a card's runs)
TARGETED = ("verify", "transfer", "fresh_seeds", "posterior")


def _tokens(config: dict, job: str, targets, cache) -> list:
    if job not in JOBS:
        raise KeyError(f"job {job!r}: expected one of {', '.join(JOBS)}")
    if targets is None:  # the study's own lab, read only by the jobs whose tests it sets
        targets = lab_targets(config) if job in TARGETED else ()
    t = frozenset(targets)
    bad = t - set(TARGETS)
    if bad:
        raise ValueError(f"targets {sorted(bad)}: expected some of {', '.join(TARGETS)}")
    return JOBS[job](config, t, cache)


def job_options(config: dict, job: str, targets=None, cache: str | None = None) -> list[str]:
    """The command of ``job`` without its files, wildcards and threads: every config value
    the job reads, as the options it passes (a rule's plain parameter: changing one reruns
    the job, and nothing else does)."""
    return [x for x in _tokens(config, job, targets, cache) if isinstance(x, str)]


def _items(m) -> dict:
    if m is None:
        return {}
    return dict(m.items())


def job_argv(config: dict, job: str, *, input=None, output=None, wildcards=None,
             threads=None, targets=None, cache: str | None = None) -> list[str]:
    """The argv of ``bpmcal`` (subcommand first) for the job of rule ``job``: its config's
    settings, and its ``input``/``output`` files and ``wildcards`` (Snakemake's named
    lists or dicts, under the rule's names) and ``threads`` each after its option.
    ``targets``: the lab targets (default: the config's lab, :func:`lab_targets`);
    ``cache``: the packing cache (default: the study's)."""
    ns = {"input": _items(input), "output": _items(output),
          "wildcards": _items(wildcards), "threads": threads}
    out: list[str] = []
    for tok in _tokens(config, job, targets, cache):
        if isinstance(tok, str):
            out.append(tok)
            continue
        v = ns[tok.source] if tok.key is None else ns[tok.source].get(tok.key)
        if tok.table is not None:
            v = dict(tok.table).get(v)
        vals = [] if v is None else [str(x) for x in v] if isinstance(v, list) else [str(v)]
        if not vals:
            if tok.optional:
                continue
            raise KeyError(f"job {job!r}: no {tok.source} {tok.key or ''} for {tok.flag}")
        out += [tok.flag, *vals] if tok.flag else vals
    return out
