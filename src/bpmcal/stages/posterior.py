"""The posterior stage (``workflow/rules/posterior.smk``, ``bpmcal posterior``): how sure a
verified card is.

From the design samples, the closed loop's seed runs and the fresh seeds
(:mod:`.posterior_data`) it fits a surrogate of every target and of the untargeted
predictions (:func:`bpmcal.analysis.posterior.fit_surrogate`), samples the posterior over
the card's free parameters given its lab targets
(:func:`bpmcal.analysis.posterior.fit_posterior`), and, where the surrogate's own error
near the posterior is large beside the lab side's scatter, runs the DEM where it narrows
the posterior most and samples again (:func:`refine_posterior`, at most ``RefineSettings.max_runs``
seed runs). It writes the card with its ``posterior`` section, the parameter and
prediction tables, the draws as arviz InferenceData (NetCDF), the pair plot, the
learning curve (posterior width against the DEM runs near the card) and the draws the
posterior predictive runs in DEM (:mod:`.predictive`).

Method: ``docs/methods/posterior.md``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from .. import params as P
from ..analysis.posterior import (
    TENSILE_SHARE,
    PosteriorSettings,
    fit_posterior,
    fit_surrogate,
)
from ..analysis.stepwise import design_matrix
from ..io.atomic import atomic_path
from ..io.card import card_parameters, read_card, write_card
from ..io.checks import BadInput, read_csv
from ..io.figures import save_figure
from ..io.tables import write_table
from ..lab.run_context import RunContext
from ..plots.posterior import fig_learning, fig_pairs
from .inputs import CSV, PNG, YAML, outputs, read_dataset, read_models
from .posterior_data import RESPONSES, design_runs, problem_of, seed_rows

NC = (".nc",)


@dataclass(frozen=True)
class RefineSettings:
    """Active refinement (module docstring): at most ``max_runs`` DEM seed runs, points of
    ``seeds`` seeds each from packing seed ``seed`` on, where a target's surrogate error
    over the posterior exceeds ``ratio`` times the lab side's sd."""

    max_runs: int = 6
    ratio: float = 0.5
    seeds: int = 2
    seed: int = 201

    def __post_init__(self):
        for k in ("max_runs", "seeds", "seed"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or v < (0 if k != "seeds" else 1):
                raise BadInput(f"refine {k}={v!r}: expected an integer >= "
                               f"{0 if k != 'seeds' else 1}")
        if not (isinstance(self.ratio, (int, float)) and math.isfinite(self.ratio)
                and self.ratio > 0):
            raise BadInput(f"refine ratio={self.ratio!r}: expected a number > 0")


def _basis(models: dict, resp: str, params):
    """The raw basis of a response's surrogate: its stepwise model's terms, or (no model)
    the linear terms of every designed parameter."""
    terms = models[resp].terms if resp in models else tuple((p,) for p in params)

    def basis(Pq):
        return design_matrix(Pq, terms)

    return basis


def _read_seeds(path, flag):
    if path is None:
        return None
    return read_csv(path, flag, min_rows=0)


def _check_se(card: dict, flag: str) -> dict:
    se = card.get("target_se") or {}
    if not isinstance(se, dict):
        raise BadInput(f"{flag}: target_se is not a mapping of target -> standard error")
    for r, v in se.items():
        try:
            x = float(v)
        except (TypeError, ValueError):
            x = math.nan
        if not (math.isfinite(x) and x >= 0):
            raise BadInput(f"{flag}: target_se.{r} = {str(v)[:40]!r}: expected a standard "
                           "error >= 0 (the lab table's <target>_se)")
    return {r: float(v) for r, v in se.items()}


def _inputs(card, dataset, models, loop_seeds, fresh_seeds):
    """The checked inputs: card, models, the runs (design and near the card), problem."""
    c = read_card(card, "--card", need=("parameters", "roles", "ranges", "targets"))
    se = _check_se(c, f"--card {card}")
    df = read_dataset(dataset)
    model_set = read_models(models)
    prob, _ = problem_of(c, f"--card {card}")
    params = [p for p in P.model_of(list(c["parameters"])).params
              if p in df.columns and df[p].nunique() > 1]
    if not params:
        raise BadInput(f"--dataset {dataset}: no designed parameter varies over its samples")
    runs = [design_runs(df, params)]
    point = {k: float(v) for k, v in card_parameters(c).items() if k in P.ALL_PARAMS}
    loop = _read_seeds(loop_seeds, "--loop-seeds")
    if loop is not None and len(loop):
        miss = [p for p in params if p not in loop.columns]
        if miss:
            raise BadInput(f"--loop-seeds {loop_seeds}: no column(s) {miss}: expected the "
                           "closed loop's seeds.csv (bpmcal verify --seed-runs)")
        runs.append(seed_rows(loop, None, "loop", params))
    fresh = _read_seeds(fresh_seeds, "--fresh-seeds")
    if fresh is not None and len(fresh):
        runs.append(seed_rows(fresh, point, "fresh", params))
    return c, se, model_set, prob, params, pd.concat(runs, ignore_index=True), point


def _surrogates(runs, targets, params, ranges, model_set, settings, extra) -> dict:
    out = {}
    for r in [*targets, *extra]:
        if r not in runs.columns or not np.isfinite(runs[r].to_numpy(float)).any():
            if r in targets:
                raise BadInput(f"target {r}: no design run or run near the card measured it "
                               "(is its test in the study?)")
            continue
        try:
            out[r] = fit_surrogate(runs, r, params, ranges, _basis(model_set, r, params),
                                   choice=settings.surrogate, seed=settings.seed)
        except ValueError as e:
            if r in targets:
                raise BadInput(f"target {r}: {e}") from None
    return out


def _extra(runs, targets) -> list[str]:
    """The untargeted responses the runs measured (their spread over the posterior)."""
    return [r for r in RESPONSES if r not in targets and r in runs.columns
            and np.isfinite(runs[r].to_numpy(float)).sum() >= 10]


def _tests(surr: dict, targets, design_sigma3) -> dict:
    """The tests the study can run that may pin what the targets leave free."""
    t = {}
    if P.BTS in surr and P.BTS not in targets:
        t["bts"] = {"response": P.BTS, "n": 10, "what": "σt on 10 Brazilian discs"}
    if "dtt_MPa" in surr and "dtt_MPa" not in targets:
        t["dtt"] = {"response": "dtt_MPa", "n": 5, "what": "σt,d on 5 direct-tension specimens"}
    if P.TRI in surr and P.TRI not in targets:
        where = f" at σ3 = {design_sigma3:g} MPa" if design_sigma3 is not None else ""
        t["tri"] = {"response": P.TRI, "n": 1, "what": f"one triaxial test{where}"}
    if TENSILE_SHARE in surr:
        t["share"] = {"response": TENSILE_SHARE, "n": 1,
                      "what": "the failure mode's tensile-crack share of a UCS test (e.g. "
                              "acoustic emission or thin sections)"}
    return t


def _fit(runs, c, se, model_set, prob, params, point, settings, design_sigma3):
    targets = {k: float(v) for k, v in c["targets"].items()}
    extra = _extra(runs, targets)
    surr = _surrogates(runs, targets, params, prob.ranges, model_set, settings, extra)
    try:
        res = fit_posterior(surr, prob, targets, point, target_se=se, settings=settings,
                            tests=_tests(surr, targets, design_sigma3))
    except ValueError as e:
        raise BadInput(f"--card: {e}") from None
    return res


def _check_geometry(c: dict, tests, card) -> None:
    """A refinement run must measure the card as its closed loop did: the same cylinder
    (scale, size, genesis; ``tests``: the :class:`~.measure.SeedTests` of the runs).
    BadInput naming the difference."""
    loop = (c.get("verification") or {}).get("geometry")
    if not loop:
        return
    mine = tests.geometry.to_dict()

    def same(a, b):
        if isinstance(a, str) or isinstance(b, str):
            return a == b
        return math.isclose(float(a), float(b), rel_tol=1e-9)

    keys = ("scale", "diameter_mm", "height_mm", "sigma0_MPa", "relax_ratio", "genesis")
    diff = [f"{k} {mine[k]!r} (the loop's {loop[k]!r})" for k in keys
            if k in loop and loop[k] is not None and not same(mine[k], loop[k])]
    if diff:
        raise BadInput(f"--card {card}: the refinement would run another specimen than the "
                       f"card's closed loop: {'; '.join(diff)}; pass the loop's specimen "
                       "options (--scale, ...) or --refine-max-runs 0")


def _width(res) -> float:
    """The posterior's width: the mean over free parameters of the 90 % HDI's width, in %
    of the design range."""
    s = res.summary
    return float(s.loc[list(res.problem.free), "hdi_width_pct_of_range"].mean())


# ---------------------------------------------------------------- active refinement
def surrogate_ratio(res) -> dict:
    """Per target: the surrogate's own error over the posterior's draws (root mean square)
    beside the lab side's sd, the ratio that decides a refinement."""
    cols = res.problem.columns(res.chains.flat)
    out = {}
    for r in res.targets:
        _, s = res.surrogates[r].predict(cols)
        out[r] = float(np.sqrt(np.mean(s ** 2)) / res.lab_sd[r])
    return out


def refine_point(res) -> dict:
    """The draw where the surrogates' error, each in units of its lab side's sd, is
    largest: a run there narrows the posterior most (its mass and the model's ignorance
    meet there)."""
    flat = res.chains.flat
    cols = res.problem.columns(flat)
    score = np.zeros(len(flat))
    for r in res.targets:
        _, s = res.surrogates[r].predict(cols)
        score += (s / res.lab_sd[r]) ** 2
    i = int(np.argmax(score))
    full = res.problem.columns(flat[i:i + 1])
    return {k: float(v[0]) for k, v in full.items()}


def _measure(point: dict, seeds: list[int], targets: list[str], tests, ctx: RunContext,
             folder: Path, it: int, tensile_specimens: int) -> list[dict]:
    """The card measured at ``point`` on ``seeds`` as the closed loop measures a seed
    (:func:`bpmcal.stages.loop_runs.loop_seed`: the tests of ``tests``, a
    :class:`~.measure.SeedTests`), side by side on the CPUs of ``ctx``; the seed rows (the
    loop's seeds.csv columns, ``round`` = the refinement's step)."""
    from .loop_runs import loop_seed
    from .pool import SeedPool

    folder.mkdir(parents=True, exist_ok=True)
    jobs = [dict(params=point, seed=s, stem=folder / f"refine{it}.seed{s}", targets=targets,
                 tests=tests, tensile_specimens=tensile_specimens) for s in seeds]
    with SeedPool.of(ctx) as pool:
        done = pool.map(loop_seed, jobs, tags=[f"refine {it} seed {s}" for s in seeds])
    rows = []
    for rec, files in done:
        row = {"round": it, "seed": int(rec["row"]["seed"]), **point}
        row.update({k: v for k, v in rec["row"].items() if k not in ("seed", "params", "round")
                    and (v is None or isinstance(v, (str, bool, int, float, np.number)))})
        rows.append(row)
        for f in files:
            Path(f).unlink(missing_ok=True)
    return rows


def refine_posterior(res, runs, fit, rs: RefineSettings, measure, params, progress=None):
    """Refinement rounds (module docstring) until every target's surrogate ratio is at
    most ``rs.ratio`` or ``rs.max_runs`` seed runs are spent: ``measure(point, seeds,
    step)`` returns the seed rows of a card measured at ``point`` (the DEM's:
    :func:`_measure`; None: no refinement), ``fit(runs)`` the posterior on runs. Returns
    (the last posterior, the runs with the new ones, the refinement's seed rows, its
    history)."""
    history = [{"step": 0, "runs": 0, **{f"ratio_{r}": v for r, v in
                                          surrogate_ratio(res).items()}}]
    rows: list[dict] = []
    it = 0
    while measure is not None and len(rows) + rs.seeds <= rs.max_runs:
        ratios = surrogate_ratio(res)
        if max(ratios.values()) <= rs.ratio:
            break
        it += 1
        point = refine_point(res)
        seeds = [rs.seed + len(rows) + j for j in range(rs.seeds)]
        if progress is not None:
            progress({"note": f"refinement {it}: surrogate error up to "
                              f"{max(ratios.values()):.2f} x the lab side's sd; DEM on "
                              f"seeds {seeds}"})
        new = measure(point, seeds, it)
        rows += new
        runs = pd.concat([runs, seed_rows(pd.DataFrame(new), None, "refine", params)],
                         ignore_index=True)
        res = fit(runs)
        history.append({"step": it, "runs": len(rows),
                        **{f"ratio_{r}": v for r, v in surrogate_ratio(res).items()}})
    return res, runs, rows, history


# ---------------------------------------------------------------- the learning curve
#: the learning curve's posteriors: converged to these looser figures (a width, not a
#: reported posterior)
CURVE_SETTINGS = dict(ess_min=200, rhat_max=1.05, max_steps=12000)


def _stages(runs: pd.DataFrame) -> list[tuple[str, pd.Series]]:
    """The nested data sets of the learning curve: the design alone, then the closed
    loop's rounds one by one, the fresh seeds, the refinement's steps."""
    src = runs["source"]
    rnd = pd.to_numeric(runs["round"], errors="coerce")
    keep = src.eq("design")
    out = [("design", keep.copy())]
    for r in sorted(rnd[src.eq("loop")].dropna().unique()):
        keep = keep | (src.eq("loop") & (rnd == r))
        out.append((f"loop round {int(r)}", keep.copy()))
    if src.eq("fresh").any():
        keep = keep | src.eq("fresh")
        out.append(("fresh seeds", keep.copy()))
    for r in sorted(rnd[src.eq("refine")].dropna().unique()):
        keep = keep | (src.eq("refine") & (rnd == r))
        out.append((f"refinement {int(r)}", keep.copy()))
    return out


def learning_curve(runs: pd.DataFrame, fit_on) -> pd.DataFrame:
    """The posterior's width (:func:`_width`; and each free parameter's HDI width) against
    the DEM seed runs near the card, one row per nested data set (:func:`_stages`)."""
    rows = []
    for label, keep in _stages(runs):
        sub = runs[keep]
        res = fit_on(sub)
        near = sub.loc[~sub["source"].eq("design"), "run"].nunique()
        row = {"data": label, "dem_runs_near_card": int(near),
               "dem_runs": int(sub["run"].nunique()), "width_pct_of_range": _width(res),
               "p_reach": res.reach["p_reach"], "converged": res.converged}
        for p in res.problem.free:
            row[f"hdi_width_{p}"] = float(res.summary.loc[p, "hdi_width_pct_of_range"])
        rows.append(row)
    return pd.DataFrame(rows)


# ---------------------------------------------------------------- outputs
def card_section(res, *, refine: dict, curve: pd.DataFrame | None) -> dict:
    """The card's ``posterior`` section: status (converged or not) and the note that
    stands next to it, what the targets pin and leave free, each parameter's value with
    its interval, the predictions' spreads, reach, the lab side, the surrogates and the
    sampler's convergence."""
    c = res.chains
    s = res.summary
    prob = res.settings.hdi_prob
    pars = {p: {"card": float(s.loc[p, "card"]), "mean": float(s.loc[p, "mean"]),
                "sd": float(s.loc[p, "sd"]),
                "hdi": [float(s.loc[p, "hdi_low"]), float(s.loc[p, "hdi_high"])],
                "card_quantile": float(s.loc[p, "card_quantile"]),
                "card_in_hdi": bool(s.loc[p, "card_in_hdi"]), "role": s.loc[p, "role"],
                "hdi_cut_by_prior": str(s.loc[p, "hdi_cut_by_prior"])}
            for p in s.index}
    preds = {r: {"targeted": bool(row["targeted"]), "card": float(row["card"]),
                 "mean": float(row["mean"]), "interval": [float(row["low"]), float(row["high"])],
                 **({"lab": float(row["lab"])} if row["targeted"] else {})}
             for r, row in res.predictions.iterrows()}
    ident = res.identifiability
    out = {
        "status": "converged" if res.converged else "not-converged",
        "note": " ".join(res.notes),
        "identifiability": ident["sentence"],
        "hdi_prob": prob,
        "parameters": pars,
        "directions": [{k: d[k] for k in ("text", "class", "ratio", "weights")}
                       for d in ident["directions"]],
        "suggestions": [{k: r[k] for k in ("test", "what", "narrows_by", "ratio")}
                        for r in res.suggestions[:3]],
        "predictions": preds,
        "reach": {k: res.reach[k] for k in ("reachable", "p_reach", "chi2_min", "dof", "text")},
        "lab_sd": {r: {"sd": float(v), "scale": "log" if r in res.surrogates and
                       res.surrogates[r].describe()["scale"] == "log" else "linear",
                       "from": res.lab_sd_source[r]} for r, v in res.lab_sd.items()},
        "surrogates": {r: sg.describe() for r, sg in res.surrogates.items()},
        "sampler": {"steps": int(c.steps), "walkers": int(c.chain.shape[0]),
                    "draws": int(len(res.draws)), "rhat_max": float(np.max(c.rhat)),
                    "ess_bulk_min": float(np.min(c.ess_bulk)),
                    "ess_tail_min": float(np.min(c.ess_tail)), "tau_max": float(np.max(c.tau)),
                    "acceptance": float(c.acceptance), "seed": res.settings.seed},
        "refine": refine,
    }
    if curve is not None and len(curve):
        out["learning_curve"] = [{"data": r["data"], "dem_runs_near_card":
                                  int(r["dem_runs_near_card"]),
                                  "width_pct_of_range": float(r["width_pct_of_range"])}
                                 for _, r in curve.iterrows()]
    return out


def pick_draws(res, n: int, seed: int) -> pd.DataFrame:
    """``n`` draws of the posterior (seeded, without replacement) as full parameter sets:
    the posterior predictive's DEM runs (:mod:`.predictive`)."""
    flat = res.chains.flat
    idx = np.sort(np.random.default_rng(seed).choice(len(flat), size=min(n, len(flat)),
                                                     replace=False))
    df = res.problem.frame(flat[idx])
    df.insert(0, "draw", np.arange(1, len(idx) + 1))
    return df


def _write_netcdf(res, path) -> None:
    idata = res.to_inference_data()
    with atomic_path(Path(path)) as tmp:
        idata.to_netcdf(str(tmp), engine="h5netcdf")


@dataclass(frozen=True)
class PosteriorOutputs:
    """The files :func:`posterior` writes: ``out_card`` (the card with its ``posterior``
    section), ``table`` (parameters), ``predictions`` (responses), ``netcdf`` (the draws
    as arviz InferenceData), ``figure`` (pair plot); optional (None: not written)
    ``learning`` (the learning curve) and ``learning_figure`` (its plot), ``refine_runs``
    (the refinement's seed rows) and ``draws`` (the draws for the predictive DEM runs)."""

    out_card: str | Path
    table: str | Path
    predictions: str | Path
    netcdf: str | Path
    figure: str | Path
    learning: str | Path | None = None
    learning_figure: str | Path | None = None
    refine_runs: str | Path | None = None
    draws: str | Path | None = None

    def check(self) -> None:
        """Every output path checked before any work (``stages.inputs.outputs``), each
        named by its ``bpmcal posterior`` option."""
        outputs((self.out_card, "--out-card", YAML), (self.table, "--table", CSV),
                (self.predictions, "--predictions", CSV), (self.netcdf, "--netcdf", NC),
                (self.figure, "--figure", PNG), (self.learning, "--learning", CSV),
                (self.learning_figure, "--learning-figure", PNG),
                (self.refine_runs, "--refine-runs", CSV), (self.draws, "--draws", CSV))


def posterior(card, dataset, models, *, files: PosteriorOutputs, loop_seeds=None,
              fresh_seeds=None, n_draws: int = 8,
              settings: PosteriorSettings = PosteriorSettings(),
              refine: RefineSettings = RefineSettings(), tests=None,
              design_sigma3=None, ctx: RunContext = RunContext()) -> dict:
    """The posterior of one verified card (module docstring). Inputs: the card, the
    dataset and the regression's models (the surrogates' basis), the loop's and the fresh
    seeds' tables (optional). Outputs: ``files`` (:class:`PosteriorOutputs`; its ``draws``
    holds ``n_draws`` posterior draws for the predictive DEM runs). ``refine`` needs
    ``tests`` to run (the :class:`~.measure.SeedTests` of the card's closed loop; its DEM
    runs as ``ctx`` says, :class:`~bpmcal.lab.run_context.RunContext`, which also takes
    the stage's notes); without it the surrogate's error is only reported. Returns the
    card."""
    files.check()
    if isinstance(n_draws, bool) or not isinstance(n_draws, int) or n_draws < 0:
        raise BadInput(f"--draws-n {n_draws!r}: expected an integer >= 0")
    with threadpool_limits(limits=1):  # small matrices: BLAS threads only spin
        return _posterior(card, dataset, models, files=files, loop_seeds=loop_seeds,
                          fresh_seeds=fresh_seeds, n_draws=n_draws, settings=settings,
                          refine=refine, tests=tests, design_sigma3=design_sigma3, ctx=ctx)


# long: the stage's job in its order (the fit, refinement, curve, every output); each step
# is one call
def _posterior(card, dataset, models, *, files, loop_seeds, fresh_seeds, n_draws, settings,
               refine, tests, design_sigma3, ctx) -> dict:
    c, se, model_set, prob, params, runs, point = _inputs(card, dataset, models, loop_seeds,
                                                          fresh_seeds)
    if tests is not None and refine.max_runs:
        _check_geometry(c, tests, card)

    def fit(r, s=settings):
        return _fit(r, c, se, model_set, prob, params, point, s, design_sigma3)

    res = fit(runs)
    folder = Path(files.out_card).parent / f".{Path(files.out_card).stem}.refine"
    tensile_n = int((c.get("verification") or {}).get("tensile_specimens", 1))
    measure = None
    if tests is not None and refine.max_runs:
        targets = list(c["targets"])

        def measure(point, seeds, it):
            return _measure(point, seeds, targets, tests, ctx, folder, it, tensile_n)

    res, runs, rows, history = refine_posterior(res, runs, fit, refine, measure, params,
                                                ctx.progress)
    curve = None
    if files.learning is not None:
        cheap = PosteriorSettings(**{**settings.__dict__, **CURVE_SETTINGS})
        curve = learning_curve(runs, lambda r: fit(r, cheap))
    ref = {"max_runs": refine.max_runs, "ratio_limit": refine.ratio, "runs": len(rows),
           "ran": tests is not None, "history": history}
    out = dict(c)
    out["posterior"] = card_section(res, refine=ref, curve=curve)
    write_table(res.summary, files.table)
    write_table(res.predictions, files.predictions)
    _write_netcdf(res, files.netcdf)
    save_figure(fig_pairs(res), files.figure)
    if files.learning is not None:
        write_table(curve, files.learning, index=False)
        if files.learning_figure is not None:
            save_figure(fig_learning(curve), files.learning_figure)
    if files.refine_runs is not None:
        write_table(pd.DataFrame(rows, columns=None if rows else ["round", "seed"]),
                    files.refine_runs, index=False)
    if files.draws is not None:
        write_table(pick_draws(res, n_draws, settings.seed), files.draws, index=False)
    write_card(files.out_card, out)
    return out
