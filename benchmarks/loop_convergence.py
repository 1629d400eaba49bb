"""How often the closed loop converges, and in how many rounds, with each Jacobian update
(``ClosedLoop(update=...)``), on a synthetic rock whose responses are known formulas.

No DEM: a "simulator" of five flat-joint parameters (fj_emod_GPa, fj_kratio, fj_ten_MPa,
fj_coh_MPa, fj_slit_frac) returns sigma_c, E, nu, sigma_t,d and sigma1 at 20 MPa from
formulas with the couplings the flat-joint Lac du Bonnet study measured
(docs/measurements/2026-11-27i-lac-du-bonnet-flatjoint-triaxial.md): nu grows exponentially
with fj_kratio, with sigma_c/E and, quadratically, with sigma_c/sigma_t (nu is measured at
half the peak, so a softer card, or one weak in tension, has cracked more by then: in that
study's design nu spans 0.13-2.65, highest where sigma_c/sigma_t is), slits soften the
card, weaken it in tension and raise its Hoek-Brown mi. Each (card, seed) gets a
deterministic scatter of the seed CVs measured in that study's loop rounds, half of it a
packing offset that the seed keeps for every card.

Per planted card, the study's path is imitated: a Latin-hypercube design of ``--samples``
cards, one seed each; the stepwise regression (main, quadratic, interaction) of each
response; the inversion for the card's responses on the loop seeds as targets; then the
closed loop from that card with the regression models (3 seeds, growing to 10, margin
0.25, polish, ``--max-rounds``), once per update rule. Printed and written (--out JSON): per
rule, the share of cards converged, the median rounds and runs of those, and the median
max |error| / tolerance of the best round of those that did not.

    python benchmarks/loop_convergence.py --cards 60 --commit SHA \
        --out benchmarks/results_loop_convergence_DATE.json \
        --markdown docs/measurements/DATE-loop-convergence.md

A synthetic rock is not the DEM: the record compares the rules on one family of response
surfaces whose scatter and couplings were taken from a real study, and says so.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import zlib

import numpy as np
import pandas as pd
from _study import record_header, write_record

from bpmcal.analysis.calibration import ClosedLoop, invert
from bpmcal.analysis.calibration.closed_loop import UPDATES
from bpmcal.analysis.stepwise import StepwiseRegression

FREE = ["fj_emod_GPa", "fj_kratio", "fj_ten_MPa", "fj_coh_MPa", "fj_slit_frac"]
RANGES = {"rmin_mm": [0.8, 0.8], "porosity": [0.3, 0.3], "fj_emod_GPa": [50.0, 130.0],
          "fj_kratio": [1.5, 5.0], "fj_ten_MPa": [4.0, 30.0], "fj_coh_MPa": [50.0, 300.0],
          "fj_fa_deg": [30.0, 30.0], "fj_fric": [0.6, 0.6], "fj_slit_frac": [0.0, 0.5]}
FIXED = {"rmin_mm": 0.8, "porosity": 0.3, "fj_fa_deg": 30.0, "fj_fric": 0.6}
RESPONSES = ["ucs_MPa", "E_GPa", "nu", "dtt_MPa", "tri_MPa"]
#: seed CV of each response, as in the loop rounds of record 2026-11-27i
CV = {"ucs_MPa": 0.06, "E_GPa": 0.03, "nu": 0.10, "dtt_MPa": 0.045, "tri_MPa": 0.03}
SIGMA3 = 20.0


def truth(p: dict) -> dict:
    """The synthetic rock's seed-free responses of card ``p`` (paper units)."""
    a, k, t = p["fj_emod_GPa"] / 90.0, p["fj_kratio"], p["fj_ten_MPa"] / 15.0
    c, s = p["fj_coh_MPa"] / 150.0, p["fj_slit_frac"]
    E = 60.0 * a * (1.0 - 0.08 * (k - 2.0)) * (1.0 - 0.7 * s)
    ucs = 190.0 * c ** 0.7 * t ** 0.25 * (1.0 - 0.5 * s) * (1.0 + 0.04 * (k - 2.0))
    dtt = 9.0 * t ** 0.9 * c ** 0.1 * (1.0 - 0.9 * s)
    nu = (0.2 * np.exp(0.5 * (k - 2.0)) * (1.0 + 0.8 * s) * (ucs / E / 2.9) ** 0.5
          * 0.5 * (1.0 + (ucs / dtt / 25.0) ** 2))
    mi = 12.0 + 60.0 * s
    tri = SIGMA3 + ucs * np.sqrt(mi * SIGMA3 / ucs + 1.0)
    return {"ucs_MPa": ucs, "E_GPa": E, "nu": nu, "dtt_MPa": dtt, "tri_MPa": tri}


def _normal(*key) -> np.ndarray:
    """Deterministic standard normals (one per response) from ``key``."""
    h = zlib.crc32(json.dumps(key, sort_keys=True, default=float).encode())
    return np.random.default_rng(h).standard_normal(len(RESPONSES))


def simulate(p: dict, seed: int) -> dict:
    """The responses of card ``p`` on packing ``seed``: the truth times (1 + scatter), half
    the variance the packing's own offset, half the card-and-packing's."""
    y = truth(p)
    card = tuple(round(float(p[q]), 9) for q in FREE)
    z = (_normal("packing", seed) + _normal("run", seed, card)) / np.sqrt(2.0)
    return {r: float(y[r] * (1.0 + CV[r] * zi)) for r, zi in zip(RESPONSES, z)}


def regression(n: int, seed: int) -> dict:
    """The study's path to the models: a Latin hypercube of ``n`` cards (sample i on packing
    i + 1000), one run each, the three-stage stepwise regression of every response."""
    from scipy.stats import qmc

    u = qmc.LatinHypercube(d=len(FREE), seed=seed).random(n)
    rows = []
    for i, ui in enumerate(u):
        p = dict(FIXED)
        p.update({q: RANGES[q][0] + x * (RANGES[q][1] - RANGES[q][0]) for q, x in zip(FREE, ui)})
        rows.append({**p, **simulate(p, 1000 + i)})
    df = pd.DataFrame(rows)
    res = StepwiseRegression(cv_folds=0, seed=seed).fit(df, {r: FREE for r in RESPONSES})
    return res.final_models


def one_card(i: int, models: dict, max_rounds: int) -> list[dict]:
    """A planted card inside the ranges' middle 80 %, its loop-seed mean as the targets, the
    inversion, and the loop from it with each update rule."""
    rng = np.random.default_rng(7000 + i)
    planted = dict(FIXED)
    planted.update({q: RANGES[q][0] + (0.1 + 0.8 * rng.random()) * (RANGES[q][1] - RANGES[q][0])
                    for q in FREE})
    lab = [simulate(planted, s) for s in range(501, 511)]  # the lab: ten other packings
    targets = {r: float(np.mean([y[r] for y in lab])) for r in RESPONSES}
    inv = invert(models, targets, FIXED, free=FREE, ratio=None, ranges=RANGES, seed=0)
    out = []
    for update in UPDATES:
        runs = []

        def sim(params, seed, runs=runs):
            runs.append(seed)
            return simulate(params, seed)

        loop = ClosedLoop(sim, targets, free=FREE, ratio=None, ranges=RANGES, models=models,
                          max_rounds=max_rounds, seeds_per_round=3, max_seeds=10, margin=0.25,
                          update=update)
        res = loop.run(inv.solution)
        h = res.history
        worst = float(np.nanmax([abs(h[f"err_{r}"].iloc[res.best_round])
                                 / h[f"tol_{r}"].iloc[res.best_round] for r in RESPONSES]))
        out.append({"card": i, "update": update, "inversion": inv.status, "status": res.status,
                    **{f"start_err_{r}": float(h[f"err_{r}"].iloc[0]) for r in RESPONSES},
                    "rounds": res.n_rounds, "runs": len(runs), "worst_err_over_tol": worst})
    return out


def summarise(rows: list[dict]) -> dict:
    """Per update rule: cards, converged, median rounds and runs of the converged, median
    worst |error| / tolerance of the best round of the others; and the paired outcomes."""
    df = pd.DataFrame(rows)
    out = {}
    for update, g in df.groupby("update", sort=False):
        ok, bad = g[g.status == "converged"], g[g.status != "converged"]
        out[update] = {"cards": len(g), "converged": len(ok),
                       "converged_within_6_rounds": int((ok.rounds <= 6).sum()),
                       "median_rounds_converged": float(ok.rounds.median()) if len(ok) else None,
                       "median_runs_converged": float(ok.runs.median()) if len(ok) else None,
                       "median_worst_err_over_tol_not_converged":
                           float(bad.worst_err_over_tol.median()) if len(bad) else None}
    first = df[df["update"] == UPDATES[0]]
    out["round1_abs_err_median"] = {c[10:]: float(first[c].abs().median())
                                    for c in first.columns if c.startswith("start_err_")}
    both = df.pivot(index="card", columns="update", values="status") == "converged"
    out["paired"] = {f"{a} only": int((both[a] & ~both[b]).sum())
                     for a in UPDATES for b in UPDATES if a != b}
    return out


def _num(v, digits: int = 1) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def markdown(rec: dict) -> str:
    s = rec["summary"]
    lines = [f"# The closed loop's Jacobian update rules on a synthetic flat-joint rock "
             f"({rec['date']})", "", "| | |", "|---|---|", f"| date | {rec['date']} |",
             f"| commit | {rec['commit']} |", f"| host | {rec['cpu_model']} ({rec['cpus']} CPUs) |",
             f"| load | {', '.join(f'{x:.2f}' for x in rec['load_average'])} |",
             f"| command | `{rec['command']}` |", f"| time | {rec['seconds']:.0f} s |", "",
             "What is compared, and how the synthetic rock was built: the docstring of "
             "`benchmarks/loop_convergence.py`. Every card: the loop from the regression's "
             f"inversion, 3 seeds per round growing to 10, at most {rec['max_rounds']} rounds, "
             "the study's other loop settings. Not the DEM: one family of response surfaces, "
             "with the scatter and couplings of the flat-joint Lac du Bonnet study.", "",
             "Round 1 (the regression's card) misses by a median |error| of "
             + ", ".join(f"{r} {100 * v:.1f} %" for r, v in s["round1_abs_err_median"].items())
             + ".", "",
             "| update rule | converged | of which within 6 rounds | median rounds (converged) "
             "| median runs (converged) | not converged: median worst error / tolerance |",
             "|---|---|---|---|---|---|"]
    for u in UPDATES:
        x = s[u]
        lines.append(f"| {u} | {x['converged']} of {x['cards']} | "
                     f"{x['converged_within_6_rounds']} | {_num(x['median_rounds_converged'])} | "
                     f"{_num(x['median_runs_converged'])} | "
                     f"{_num(x['median_worst_err_over_tol_not_converged'], 2)} |")
    lines += ["", "Paired by card: " + "; ".join(f"{k}: {v}" for k, v in s["paired"].items())
              + " (converged with one rule, not with the other).", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cards", type=int, default=30)
    ap.add_argument("--samples", type=int, default=40)
    ap.add_argument("--max-rounds", type=int, default=12)
    ap.add_argument("--design-seed", type=int, default=2018)
    ap.add_argument("--commit", default="")
    ap.add_argument("--out", default=None)
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args(argv)
    rec = {**record_header("loop_convergence.py", argv), "commit": args.commit,
           "max_rounds": args.max_rounds}
    t0 = time.time()
    models = regression(args.samples, args.design_seed)
    rows = [r for i in range(args.cards) for r in one_card(i, models, args.max_rounds)]
    rec.update({"seconds": time.time() - t0, "summary": summarise(rows), "cards": rows})
    write_record(rec, args.out, args.markdown, markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
