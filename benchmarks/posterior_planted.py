"""Does the posterior hold a planted DEM card? Planted parallel-bond cards measured as a
laboratory would measure a rock, then the posterior of a finished study's design with
active refinement in the DEM, and the planted parameters checked against its 90 %
highest-density intervals.

Per planted card (``--cards`` of them, drawn inside the middle 70 % of Table 2's ranges
of Ecp, kp*, σcp and τcp, the other four at the study's calibration values; or one card
from ``--set``): ``--lab-seeds`` packing seeds of the study's UCS test and
``--lab-discs`` Brazilian discs each (the study's disc and loading), whose means and
standard errors become the lab targets σc, E, ν, σt; the inversion of the study's
regression for them (σt frees both strengths) starts the posterior; the posterior of the
study's design runs, refined in the DEM (``--refine`` seed runs at most, 2 seeds a point,
measured as the closed loop measures a seed); then, per free parameter, whether the
planted value lies in the HDI, the HDI widths and the identifiability. No closed loop
runs: the refinement alone brings runs near the card.

    python benchmarks/posterior_planted.py --study CLONE/results --cards 8 \\
        --out benchmarks/results/results_posterior_planted_DATE.json \\
        --markdown docs/measurements/DATE-posterior-planted.md
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from _study import (
    CONFIG,
    bts_disc_and_settings,
    record_header,
    study_config,
    study_geometry,
    ucs_settings,
    write_record,
)

FREE = ("pb_emod_GPa", "pb_kratio", "pb_ten_MPa", "pb_coh_MPa")


def planted_cards(n: int, cfg: dict, seed: int = 2026) -> list[dict]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        p = {k: float(v) for k, v in cfg["calibration"]["fixed"].items()}
        for q in FREE:
            lo, hi = cfg["ranges"][q]
            p[q] = lo + (0.15 + 0.7 * rng.random()) * (hi - lo)
        out.append(p)
    return out


def dem_of(cfg: dict, threads: int, cache):
    """The DEM of the refinement runs: (the tests a seed runs, how they run)."""
    from bpmcal.lab.run_context import RunContext
    from bpmcal.stages.measure import SeedTests

    geo = study_geometry(cfg)
    disc, bts = bts_disc_and_settings(cfg)
    return (SeedTests(geo, ucs_settings(cfg), bts_geometry=disc, bts_settings=bts),
            RunContext(cache=cache, threads=threads,
                       genesis_max_steps=cfg["resources"]["genesis_max_steps"]))


def lab_targets(card: dict, dem, seeds, discs: int, folder: Path) -> tuple[dict, dict, float]:
    """The planted card measured on ``seeds`` (UCS, ``discs`` Brazilian discs each): the
    targets and their standard errors (σt over every disc)."""
    from bpmcal.stages.posterior import _measure

    t = time.time()
    rows = pd.DataFrame(_measure(card, list(seeds), ["ucs_MPa", "E_GPa", "nu", "bts_MPa"], *dem,
                                 folder, 0, discs))
    rows = rows[rows["status"] == "ok"]
    out, se = {}, {}
    for r in ("ucs_MPa", "E_GPa", "nu"):
        v = rows[r].to_numpy(float)
        out[r], se[r] = float(v.mean()), float(v.std(ddof=1) / np.sqrt(len(v)))
    col = "bts_specimen_MPa"
    d = (np.array([float(x) for s in rows[col] for x in str(s).split(";")])
         if col in rows and discs > 1 else rows["bts_MPa"].to_numpy(float))
    out["bts_MPa"], se["bts_MPa"] = float(d.mean()), float(d.std(ddof=1) / np.sqrt(len(d)))
    return out, se, time.time() - t


# long: one planted card from its lab measurement to the posterior's verdict, step by step
def one_card(i: int, planted: dict, cfg: dict, study: Path, dem, a, folder: Path) -> dict:
    from bpmcal.analysis.calibration import Multistart, SearchSpace, invert
    from bpmcal.analysis.posterior import PosteriorSettings
    from bpmcal.stages.inputs import read_dataset, read_models
    from bpmcal.stages.posterior import RefineSettings, _fit, _measure, refine_posterior
    from bpmcal.stages.posterior_data import design_runs, problem_of

    t0 = time.process_time()
    seeds = [5000 + 100 * i + k for k in range(a.lab_seeds)]
    targets, se, lab_s = lab_targets(planted, dem, seeds, a.lab_discs, folder)
    models = read_models(study / "regression" / "models.json")
    fixed = {k: v for k, v in planted.items() if k not in FREE}
    inv = invert(models,
                 targets,
                 fixed,
                 SearchSpace(ranges=cfg["ranges"], free=list(FREE), ratio=None),
                 search=Multistart(seed=0))
    card = {"parameters": inv.solution, "roles": {k: ("free" if k in FREE else "fixed")
                                                  for k in inv.solution},
            "ranges": cfg["ranges"], "targets": targets, "target_se": se,
            "verification": {"range_margin": cfg["verification"]["range_margin"]}}
    prob, _ = problem_of(card)
    point = {k: float(v) for k, v in inv.solution.items()}
    for j, q in enumerate(prob.free):  # the start inside the prior box
        point[q] = float(np.clip(point[q], prob.lo[j], prob.hi[j]))
    df = read_dataset(study / "dataset.csv")
    params = [q for q in planted if q in df.columns and df[q].nunique() > 1]
    runs = design_runs(df, params)
    settings = PosteriorSettings(seed=i)

    def fit(r):
        return _fit(r, card, se, models, prob, params, point, settings, None)

    post = fit(runs)

    def measure(p, s, step):
        return _measure(p, s, list(targets), *dem, folder, step, 1)

    post, runs, rows, hist = refine_posterior(
        post, runs, fit, RefineSettings(max_runs=a.refine, seed=7000 + 100 * i), measure, params)
    s = post.summary
    inside = {q: bool(s.loc[q, "hdi_low"] <= planted[q] <= s.loc[q, "hdi_high"]) for q in FREE}
    freest = post.identifiability["directions"][-1]
    return {"card": i, "planted": {q: planted[q] for q in FREE}, "targets": targets, "se": se,
            "inversion": inv.status, "start": {q: point[q] for q in FREE},
            "mean": {q: float(s.loc[q, "mean"]) for q in FREE},
            "hdi": {q: [float(s.loc[q, "hdi_low"]), float(s.loc[q, "hdi_high"])] for q in FREE},
            "inside": inside, "all_inside": all(inside.values()),
            "width_pct": {q: float(s.loc[q, "hdi_width_pct_of_range"]) for q in FREE},
            "identifiability": post.identifiability["sentence"],
            "freest": {k: freest[k] for k in ("text", "class", "ratio")},
            "p_reach": post.reach["p_reach"], "refine_runs": len(rows), "refine": hist,
            "converged": post.converged, "lab_wall_s": lab_s,
            "cpu_s_this_process": time.process_time() - t0}


def markdown(rec: dict) -> str:
    h = rec["header"]
    rows = rec["rows"]
    cov = np.mean([v for r in rows for v in r["inside"].values()]) if rows else float("nan")
    lines = [f"# Posterior coverage on planted DEM cards ({h['date']})", "", "| | |", "|---|---|",
             f"| date | {h['date']} |", f"| commit | {rec['commit']} |",
             f"| host | {h['cpu_model']}, {h['cpus']} cores |",
             f"| load | {h['load_average'][0]:.1f} at the start |",
             f"| command | `{h['command']}` |", f"| study | {rec['study']} |", "",
             f"Coverage of the 90 % HDIs over {len(rows)} planted cards x 4 parameters: "
             f"**{100 * cov:.0f} %** (every parameter inside on "
             f"{sum(r['all_inside'] for r in rows)} of {len(rows)} cards).", "",
             "| card | planted Ecp, kp*, σcp, τcp | 90 % HDIs | inside | widths (% of range) | "
             "refinement runs | freest direction |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        pl = ", ".join(f"{r['planted'][q]:.3g}" for q in FREE)
        hd = "; ".join(f"{r['hdi'][q][0]:.3g}-{r['hdi'][q][1]:.3g}" for q in FREE)
        ins = ", ".join("yes" if r["inside"][q] else "**no**" for q in FREE)
        wd = ", ".join(f"{r['width_pct'][q]:.0f}" for q in FREE)
        lines.append(f"| {r['card']} | {pl} | {hd} | {ins} | {wd} | {r['refine_runs']} | "
                     f"{r['freest']['text']} ({r['freest']['class']}) |")
    lines += ["", "This record is not edited; a new measurement gets a new record.", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--study", required=True, help="a finished study's results folder")
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--cards", type=int, default=8)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--lab-seeds", type=int, default=8)
    ap.add_argument("--lab-discs", type=int, default=2)
    ap.add_argument("--refine", type=int, default=12)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--commit", default="")
    ap.add_argument("--out")
    ap.add_argument("--markdown")
    a = ap.parse_args(argv)
    cfg = study_config(a.config)  # validated from the repository, wherever it runs
    header = record_header("posterior_planted.py", sys.argv[1:] if argv is None else argv)
    study = Path(a.study)
    dem = dem_of(cfg, a.threads, str(study / "cache" / "packings"))
    rows = []
    cards = planted_cards(a.first + a.cards, cfg)[a.first:]
    with tempfile.TemporaryDirectory() as tmp:
        for k, p in enumerate(cards):
            r = one_card(a.first + k, p, cfg, study, dem, a, Path(tmp))
            rows.append(r)
            print(f"card {r['card']}: inside {r['inside']} widths {r['width_pct']} refine "
                  f"{r['refine_runs']}", flush=True)
            rec = {"header": header, "commit": a.commit, "study": str(study), "rows": rows}
            write_record(rec, a.out, a.markdown, markdown, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
