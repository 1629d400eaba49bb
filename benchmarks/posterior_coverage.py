"""Does the posterior hold the truth? Planted cards on the synthetic rocks of
``loop_convergence.py`` (responses known formulas, packing scatter from real studies),
each taken through the study's path and then the posterior, and the planted parameters
checked against its 90 % highest-density intervals.

No DEM. Per planted card (inside the ranges' middle 80 %): the rock's design (a Latin
hypercube, one run each) and its stepwise regression; the lab targets as the mean of the
card's own 20 lab packings with their standard errors (``--se-factor`` f measures the
card on 20 / f^2 packings instead: 0.25 is a lab with 16 times the specimens, whose
means sit closer to the card as its standard errors shrink); the inversion; the closed
loop from it (3 seeds growing to 10, margin 0.25, the loop's defaults), every run kept;
the posterior on the design and the loop's runs, with active refinement (``--refine``
seed runs at most, on the rock);
then, per free parameter, whether the planted value lies in the HDI. Variants
(``--case``):

- ``pb``: the parallel-bond rock, targets σc, E, ν, σt, free Ecp, kp*, σcp, τcp;
- ``pb-ratio``: targets σc, E, ν, free Ecp, kp*, τcp with σcp = 1.5 τcp (the planted
  cards obey that ratio): the default study's three free parameters, a card its targets
  pin;
- ``pb-pair``: targets σc, E, ν, free Ecp, kp*, σcp, τcp: the strength pair free, a
  ridge the posterior should show;
- ``fj``: the flat-joint rock, targets σc, E, ν, σt,d, σ1 at 20 MPa, five free.

Printed and written (--out JSON, --markdown): per case, the coverage per parameter and
over all, the median HDI width (% of the design range), the identifiability classes, the
share of cards whose freest direction is the strength pair, the runs and the CPU time.

    python benchmarks/posterior_coverage.py --case pb-ratio pb pb-pair fj --cards 25 \\
        --out benchmarks/results/results_posterior_coverage_DATE.json \\
        --markdown docs/measurements/DATE-posterior-coverage.md

A synthetic rock is not the DEM: this checks the posterior's machinery (surrogate,
likelihood, sampler) on response surfaces whose scatter and couplings come from real
studies; the DEM's planted cards are ``posterior_planted.py``'s.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
from _study import record_header, write_record
from loop_convergence import ROCKS, design_runs, simulate
from loop_convergence import planted_card as planted_of

from bpmcal.analysis.calibration import ClosedLoop, LoopSeeds, LoopSteps, Multistart, SearchSpace, invert
from bpmcal.analysis.posterior import PosteriorSettings, Problem, fit_posterior, fit_surrogate
from bpmcal.analysis.stepwise import design_matrix
from bpmcal.stages.posterior import RefineSettings, refine_posterior

RATIO = 1.5
CASES = {
    "pb": ("pb", ["ucs_MPa", "E_GPa", "nu", "bts_MPa"], None),
    "pb-ratio": ("pb", ["ucs_MPa", "E_GPa", "nu"], RATIO),
    "pb-pair": ("pb", ["ucs_MPa", "E_GPa", "nu"], None),
    "fj": ("fj", ["ucs_MPa", "E_GPa", "nu", "dtt_MPa", "tri_MPa"], None),
}


def design(rock, n: int, seed: int = 11):
    """The rock's design runs (``loop_convergence.design_runs``, labelled for the
    posterior: source design, one packing each), its stepwise models and parameters."""
    df, models = design_runs(rock, n, seed)
    df["source"], df["round"], df["run"] = "design", np.nan, [f"d{i}" for i in range(n)]
    df["packing"] = [f"d{i}" for i in range(n)]
    return df, models, list(rock.design or {q: rock.ranges[q] for q in rock.free})


def planted_card(rock, i: int, ratio):
    """Card ``i`` of the closed-loop benchmark; with ``ratio``, sigma_cp = ratio x tau_cp."""
    p = planted_of(rock, i)
    if ratio is not None:  # the card obeys the ratio: tau_cp chosen, sigma_cp follows
        lo, hi = rock.ranges["pb_ten_MPa"]
        p["pb_coh_MPa"] = min(p["pb_coh_MPa"], 0.9 * hi / ratio)
        p["pb_ten_MPa"] = ratio * p["pb_coh_MPa"]
    return p


def lab_seeds(rock, i: int, n: int | None = None) -> range:
    """Card ``i``'s lab packings (``n`` of them, default as many as the rock's
    ``lab_seeds``): its own (a rock's lab tests its own specimens). The
    rock's ``lab_seeds`` shared by every card would give every card the same packing
    offsets in its targets, one draw repeated, and the cards' coverages would not be
    independent trials (``loop_convergence.py`` keeps them: it measures the loop)."""
    shift = 1000 * (i + 1)
    n = len(rock.lab_seeds) if n is None else int(n)
    if n > 1000:
        raise ValueError(f"{n} lab packings: at most 1000 (the cards' seed blocks)")
    return range(rock.lab_seeds.start + shift, rock.lab_seeds.start + shift + n)


def _problem(rock, free, ratio, margin: float = 0.25) -> Problem:
    lo = np.array([rock.ranges[q][0] for q in free])
    w = np.array([rock.ranges[q][1] - rock.ranges[q][0] for q in free])
    lo, hi = np.maximum(lo - margin * w, 1e-3 * w), lo + (1 + margin) * w
    fixed = {k: v for k, v in rock.fixed.items()}
    ranges = {q: tuple(rock.ranges[q]) for q in rock.ranges}
    if ratio is None:
        return Problem(tuple(free), lo, hi, fixed, ranges)
    return Problem(tuple(free), lo, hi, fixed, ranges, ratio, "pb_ten_MPa", "pb_coh_MPa")


# long: one planted card through the study's path and the posterior, each step one call
def one_case(case: str, i: int, se_factor: float, n_design: int, refine_max: int,
             cache: dict) -> dict:
    rock_name, targets_r, ratio = CASES[case]
    rock = ROCKS[rock_name]
    if rock_name not in cache:
        cache[rock_name] = design(rock, n_design)
    df, models, names = cache[rock_name]
    free = [q for q in rock.free if not (ratio is not None and q == "pb_ten_MPa")]
    t0 = time.process_time()
    planted = planted_card(rock, i, ratio)
    # a lab whose standard errors are se_factor times the rock's: 1 / se_factor^2 times
    # the specimens, so its means come closer to the card as its errors shrink
    n_lab = max(3, round(len(rock.lab_seeds) / se_factor ** 2))
    lab = pd.DataFrame([simulate(rock, planted, s) for s in lab_seeds(rock, i, n_lab)])
    targets = {r: float(lab[r].mean()) for r in targets_r}
    se = {r: float(lab[r].std(ddof=1) / len(lab) ** 0.5) for r in targets_r}
    inv = invert({r: models[r] for r in targets_r},
                 targets,
                 rock.fixed,
                 SearchSpace(ranges=rock.ranges, free=free, ratio=ratio),
                 search=Multistart(seed=0))
    runs = []

    def sim(params, seed):
        y = simulate(rock, params, seed)
        runs.append({**{q: params[q] for q in names}, **y, "seed": seed})
        return y

    loop = ClosedLoop(sim,
                      targets,
                      space=SearchSpace(ranges=rock.ranges, free=free, ratio=ratio),
                      steps=LoopSteps(margin=0.25),
                      seeding=LoopSeeds(seeds_per_round=3, max_seeds=10),
                      models={r: models[r] for r in targets_r},
                      target_se=se)
    res = loop.run(inv.solution)
    near = pd.DataFrame(runs)
    near["source"] = "loop"
    near["round"] = near.groupby([q for q in names]).ngroup() + 1
    near["run"] = [f"l{j}" for j in range(len(near))]
    near["packing"] = near["seed"].astype(str)
    all_runs = pd.concat([df, near], ignore_index=True)
    prob = _problem(rock, free, ratio)
    card = {q: float(res.params[q]) for q in free}
    card = {q: float(np.clip(card[q], a, b)) for q, a, b in zip(free, prob.lo, prob.hi)}
    settings = PosteriorSettings(seed=i)

    def basis_of(r):
        terms = models[r].terms

        def basis(P):
            return design_matrix(P, terms)
        return basis

    space = rock.design or rock.ranges

    def fit(rr):
        surr = {r: fit_surrogate(rr, r, names, space, basis_of(r), seed=i)
                for r in targets_r}
        return fit_posterior(surr, prob, targets, card, target_se=se, settings=settings)

    post = fit(all_runs)
    extra = 0
    if refine_max:
        def measure(point, seeds, step):
            return [{**{q: point[q] for q in names}, **simulate(rock, point, s),
                     "seed": s, "round": step, "status": "ok"} for s in seeds]

        post, all_runs, rows, _ = refine_posterior(
            post, all_runs, fit, RefineSettings(max_runs=refine_max, seed=90000 + 100 * i),
            measure, names)
        extra = len(rows)
    s = post.summary
    inside = {q: bool(s.loc[q, "hdi_low"] <= planted[q] <= s.loc[q, "hdi_high"]) for q in free}
    dirs = post.identifiability["directions"]
    freest = dirs[-1]
    pair = (abs(freest["weights"].get("pb_ten_MPa", 0)) >= 0.3
            and abs(freest["weights"].get("pb_coh_MPa", 0)) >= 0.3)
    return {"case": case, "card": i, "se_factor": se_factor, "loop": res.status,
            "loop_runs": len(runs), "refine_runs": extra, "converged": post.converged,
            "inside": inside, "all_inside": all(inside.values()),
            "width_pct": {q: float(s.loc[q, "hdi_width_pct_of_range"]) for q in free},
            "classes": [d["class"] for d in dirs], "freest_is_pair": bool(pair),
            "freest_ratio": float(freest["ratio"]), "p_reach": post.reach["p_reach"],
            "cpu_s": time.process_time() - t0}


def summarise(rows: list[dict]) -> dict:
    out = {}
    for (case, f), g in pd.DataFrame(rows).groupby(["case", "se_factor"], sort=False):
        ins = pd.DataFrame(list(g["inside"]))
        widths = pd.DataFrame(list(g["width_pct"]))
        out[f"{case} se x{f:g}"] = {
            "cards": len(g), "coverage": float(ins.to_numpy().mean()),
            "coverage_per_parameter": {q: float(ins[q].mean()) for q in ins},
            "all_inside": float(g["all_inside"].mean()),
            "median_width_pct": {q: float(widths[q].median()) for q in widths},
            "freest_is_pair": float(g["freest_is_pair"].mean()),
            "median_freest_ratio": float(g["freest_ratio"].median()),
            "pinned_all": float(np.mean([all(c == "pinned" for c in cl) for cl in g["classes"]])),
            "converged": float(g["converged"].mean()),
            "median_loop_runs": float(g["loop_runs"].median()),
            "mean_refine_runs": float(g["refine_runs"].mean()),
            "median_cpu_s": float(g["cpu_s"].median())}
    return out


def markdown(rec: dict) -> str:
    h = rec["header"]
    lines = [f"# Posterior coverage on planted cards of the synthetic rocks ({h['date']})", "",
             "| | |", "|---|---|", f"| date | {h['date']} |", f"| commit | {rec['commit']} |",
             f"| host | {h['cpu_model']}, {h['cpus']} cores |",
             f"| load | {h['load_average'][0]:.1f} at the start (others' jobs; CPU time is "
             "the figure) |", f"| command | `{h['command']}` |", "",
             *([rec["note"], ""] if rec.get("note") else []),
             "Each planted card went through the study's path on a synthetic rock "
             "(benchmarks/loop_convergence.py: design, stepwise regression, inversion, "
             "closed loop) and then the posterior (design and loop runs, active refinement "
             "on the rock); a parameter is covered when its planted value lies in its 90 % "
             "HDI. Nominal coverage: 90 %.", "",
             "| case | cards | coverage (all parameters) | all inside | per parameter | "
             "median HDI width (% of range) | freest direction the strength pair | "
             "all pinned | converged | loop runs (median) | refinement runs (mean) | "
             "CPU s (median) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for k, v in rec["summary"].items():
        per = ", ".join(f"{q} {100 * c:.0f} %" for q, c in v["coverage_per_parameter"].items())
        wid = ", ".join(f"{q} {w:.1f}" for q, w in v["median_width_pct"].items())
        lines.append(f"| {k} | {v['cards']} | {100 * v['coverage']:.0f} % | "
                     f"{100 * v['all_inside']:.0f} % | {per} | {wid} | "
                     f"{100 * v['freest_is_pair']:.0f} % | {100 * v['pinned_all']:.0f} % | "
                     f"{100 * v['converged']:.0f} % | {v['median_loop_runs']:.0f} | "
                     f"{v['mean_refine_runs']:.1f} | {v['median_cpu_s']:.0f} |")
    lines += ["", "This record is not edited; a new measurement gets a new record.", ""]
    return "\n".join(lines)


_CACHE: dict = {}  # a worker's designs (one per rock)


def _one(job: tuple) -> dict:
    case, i, f, n_design, refine = job
    return one_case(case, i, f, n_design, refine, _CACHE)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", nargs="+", choices=list(CASES), default=list(CASES))
    ap.add_argument("--cards", type=int, default=25)
    ap.add_argument("--first", type=int, default=0, help="the first card's index")
    ap.add_argument("--se-factor", type=float, nargs="+", default=[1.0])
    ap.add_argument("--design", type=int, default=150, help="design samples")
    ap.add_argument("--refine", type=int, default=6, help="refinement seed runs at most")
    ap.add_argument("--jobs", type=int, default=1, help="cards side by side (processes)")
    ap.add_argument("--commit", default="")
    ap.add_argument("--rows", help="append each card's row to this JSONL file as it ends "
                    "(a long run cut short keeps what it measured)")
    ap.add_argument("--from-rows", nargs="+", metavar="JSONL",
                    help="no runs: the record of the rows in these files (several runs')")
    ap.add_argument("--note", default="", help="a line for the record (e.g. the runs' commands)")
    ap.add_argument("--out")
    ap.add_argument("--markdown")
    a = ap.parse_args(argv)
    header = record_header("posterior_coverage.py", argv)
    if a.from_rows:
        rows = [json.loads(line) for f in a.from_rows for line in Path(f).read_text().splitlines()
                if line.strip()]
        rec = {"header": header, "commit": a.commit, "note": a.note, "rows": rows,
               "summary": summarise(rows)}
        write_record(rec, a.out, a.markdown, markdown, default=float)
        return 0
    jobs = [(case, i, f, a.design, a.refine) for case in a.case for f in a.se_factor
            for i in range(a.first, a.first + a.cards)]
    rows = []
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:  # each worker its own designs
        for r in pool.map(_one, jobs):
            rows.append(r)
            if a.rows:
                with open(a.rows, "a") as fh:
                    fh.write(json.dumps(r, default=float) + "\n")
            print(f"{r['case']} se x{r['se_factor']:g} card {r['card']}: inside {r['inside']} "
                  f"widths { {q: round(w, 1) for q, w in r['width_pct'].items()} } "
                  f"classes {r['classes']} {r['cpu_s']:.0f} s", flush=True)
    rec = {"header": header, "commit": a.commit, "note": a.note, "rows": rows,
               "summary": summarise(rows)}
    write_record(rec, a.out, a.markdown, markdown, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
