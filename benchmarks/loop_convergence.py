"""How often the closed loop converges, in how many rounds and runs, and how near the
planted card it ends, with each Jacobian update rule (``LoopSteps(update=...)``) and seed
growth rule (``grow_within``), on a synthetic rock whose responses are known formulas.

No DEM. Two rocks (``--rock``):

- ``fj`` (the default): five flat-joint parameters (fj_emod_GPa, fj_kratio, fj_ten_MPa,
  fj_coh_MPa, fj_slit_frac) give sigma_c, E, nu, sigma_t,d and sigma1 at 20 MPa from
  formulas with the couplings the flat-joint Lac du Bonnet study measured
  (docs/measurements/2026-11-27i-lac-du-bonnet-flatjoint-triaxial.md): nu grows
  exponentially with fj_kratio, with sigma_c/E and, quadratically, with sigma_c/sigma_t
  (nu is measured at half the peak, so a softer card, or one weak in tension, has cracked
  more by then), slits soften the card, weaken it in tension and raise its Hoek-Brown mi.
  The seed CVs are those of that study's loop rounds; targets are the mean of 10 other
  packings, taken as exact.
- ``pb``: four parallel-bond parameters (pb_emod_GPa, pb_kratio, pb_ten_MPa, pb_coh_MPa;
  the other four of Table 2 fixed at the planted cards') give sigma_c, E, nu and sigma_t
  from forms fitted to the default study's 150 DEM samples (``pb_truth``): each strength
  the soft minimum of a tensile-limited and a shear-limited one. The regression is fitted
  on a design over all eight parameters with one Brazilian disc per sample, as the study
  does; the loop measures sigma_t as the mean of 12 discs per seed. The targets are the
  mean of 20 other packings, given with their standard errors, as planted_card.py does.

Each (card, seed) gets a deterministic scatter of the rock's seed CVs, half of it a packing
offset that the seed keeps for every card. Per planted card (inside the ranges' middle
80 %), the study's path is imitated: a Latin-hypercube design of ``--samples`` cards, one
seed each; the stepwise regression (main, quadratic, interaction) of each response; the
inversion for the planted card's lab values as targets; then the closed loop from that
card with the regression models (3 seeds, growing to 10, margin 0.25, polish,
``--max-rounds``), once per update rule and ``--grow-within``. Printed and written (--out
JSON): per rule, the share of cards converged, the median rounds and runs of those, the
median max |error| / tolerance of the best round of those that did not, the mean runs of
every card, and the RMS error of the returned card's seed-free responses against the
planted card's (how near the rock itself the card ends, which no loop can see).

    python benchmarks/loop_convergence.py --rock pb --cards 60 --grow-within 1,2 \
        --commit SHA --out benchmarks/results/results_loop_convergence_DATE.json \
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
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd
from _study import record_header, write_record

from bpmcal.analysis.calibration import ClosedLoop, LoopSeeds, LoopSteps, Multistart, SearchSpace, invert
from bpmcal.analysis.calibration.loop_settings import UPDATES, LoopSettings
from bpmcal.analysis.stepwise import StepwiseRegression

#: the study's closed loop (LoopSettings' defaults: 3 seeds a round, growing to 10, range
#: margin 0.25); the update rule, growth rule and rounds are the record's
LOOP = LoopSettings()


@dataclass(frozen=True)
class Rock:
    """A synthetic rock: the free parameters, their design ranges, the fixed ones, the
    responses, each response's seed CV, the seed-free responses of a card (``truth``), the
    lab seeds whose mean is a planted card's target, and whether the targets carry their
    standard errors (``target_se``, as ``planted_card.py`` gives the study)."""

    name: str
    free: list
    ranges: dict
    fixed: dict
    responses: list
    cv: dict
    truth: Callable[[dict], dict]
    lab_seeds: range
    target_se: bool
    samples: int
    max_rounds: int | str
    design: dict | None = None  # the regression's design ranges (default: ``ranges``)
    design_cv: dict | None = None  # a design sample's seed CV (default: ``cv``)


SIGMA3 = 20.0


def fj_truth(p: dict) -> dict:
    """The flat-joint rock's seed-free responses of card ``p`` (paper units)."""
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


def _softmin(a: float, b: float, p: float) -> float:
    """(a^-p + b^-p)^(-1/p): the smaller of two strengths, rounded at the switch."""
    return (a ** -p + b ** -p) ** (-1.0 / p)


def pb_truth(p: dict) -> dict:
    """The parallel-bond rock's seed-free responses of card ``p`` (paper units; the eight
    parameters of Table 2). A strength is the soft minimum of a tensile-limited and a
    shear-limited one, each a bond strength times powers of kp* and Ecp and exponentials
    of porosity, mu, phi_p and Rmin; its coefficients are the least-squares fit of that
    form to the default study's 150 DEM samples (the 2026-11-26 design: log residual 0.075
    for sigma_c, 0.145 for sigma_t of one disc); E and nu are the log-linear fit to the
    same samples (R^2 0.998, 0.945; neither depends on the bond strengths). The two
    strengths' ratio is nearly the same on either side of the switch, so sigma_c and
    sigma_t pin sigma_cp and tau_cp only weakly: the difficulty of planted card Q
    (Ecp 35, kp* 1.8, sigma_cp 40, tau_cp 28) whose DEM loop ended at max_rounds."""
    le, lk = np.log(p["pb_emod_GPa"] / 30.0), np.log(p["pb_kratio"])
    ten, coh = p["pb_ten_MPa"], p["pb_coh_MPa"]
    x = np.array([1.0, lk, le, p["porosity"] - 0.28, p["fric"] - 0.35,
                  (p["pb_fa_deg"] - 35.0) / 10.0, p["rmin_mm"] - 0.8])
    ucs = _softmin(np.exp(x @ [1.827, -0.512, 0.009, -4.508, 0.282, 0.002, -0.077]) * ten,
                   np.exp(x @ [1.053, 0.260, 0.046, -4.866, 0.374, -0.058, 0.044]) * coh, 2.7)
    bts = _softmin(np.exp(x @ [-0.214, -0.471, -0.126, -2.880, 0.051, 0.009, 0.300]) * ten,
                   np.exp(x @ [-0.814, 0.098, -0.097, -3.682, 0.241, -0.117, 0.154]) * coh, 7.74)
    E = np.exp(1.428 - 0.241 * lk - 2.977 * p["porosity"] - 0.029 * p["rmin_mm"]
               + 0.150 * p["fric"]) * p["pb_emod_GPa"]
    nu = np.exp(-2.117 + 0.584 * lk + 0.444 * p["porosity"] - 0.181 * p["rmin_mm"]
                - 0.369 * p["fric"])
    return {"ucs_MPa": float(ucs), "E_GPa": float(E), "nu": float(nu), "bts_MPa": float(bts)}


ROCKS = {
    "fj": Rock(
        "fj", ["fj_emod_GPa", "fj_kratio", "fj_ten_MPa", "fj_coh_MPa", "fj_slit_frac"],
        {"rmin_mm": [0.8, 0.8], "porosity": [0.3, 0.3], "fj_emod_GPa": [50.0, 130.0],
         "fj_kratio": [1.5, 5.0], "fj_ten_MPa": [4.0, 30.0], "fj_coh_MPa": [50.0, 300.0],
         "fj_fa_deg": [30.0, 30.0], "fj_fric": [0.6, 0.6], "fj_slit_frac": [0.0, 0.5]},
        {"rmin_mm": 0.8, "porosity": 0.3, "fj_fa_deg": 30.0, "fj_fric": 0.6},
        ["ucs_MPa", "E_GPa", "nu", "dtt_MPa", "tri_MPa"],
        # seed CV of each response, as in the loop rounds of record 2026-11-27i
        {"ucs_MPa": 0.06, "E_GPa": 0.03, "nu": 0.10, "dtt_MPa": 0.045, "tri_MPa": 0.03},
        fj_truth, range(501, 511), False, 40, 12),
    "pb": Rock(
        "pb", ["pb_emod_GPa", "pb_kratio", "pb_ten_MPa", "pb_coh_MPa"],
        {"rmin_mm": [0.8, 0.8], "porosity": [0.34, 0.34], "pb_emod_GPa": [10.0, 50.0],
         "pb_kratio": [1.0, 5.0], "pb_ten_MPa": [10.0, 50.0], "pb_coh_MPa": [10.0, 50.0],
         "pb_fa_deg": [35.0, 35.0], "fric": [0.35, 0.35]},
        {"rmin_mm": 0.8, "porosity": 0.34, "pb_fa_deg": 35.0, "fric": 0.35},
        ["ucs_MPa", "E_GPa", "nu", "bts_MPa"],
        # seed CVs of the planted card Q (record 2026-11-29f): its 20 lab seeds' sigma_c,
        # E and nu; sigma_t of a seed's 12 discs (13.4 % a disc)
        {"ucs_MPa": 0.06, "E_GPa": 0.012, "nu": 0.016, "bts_MPa": 0.039},
        pb_truth, range(3001, 3021), True, 150, "auto",
        # the study's design: all eight parameters of Table 2, one disc per sample
        design={"rmin_mm": [0.6, 1.0], "porosity": [0.20, 0.36], "pb_emod_GPa": [10.0, 50.0],
                "pb_kratio": [1.0, 5.0], "pb_ten_MPa": [10.0, 50.0],
                "pb_coh_MPa": [10.0, 50.0], "pb_fa_deg": [15.0, 55.0], "fric": [0.15, 0.55]},
        design_cv={"ucs_MPa": 0.06, "E_GPa": 0.012, "nu": 0.016, "bts_MPa": 0.134}),
}


def _normal(n: int, *key) -> np.ndarray:
    """Deterministic standard normals (``n``, one per response) from ``key``."""
    h = zlib.crc32(json.dumps(key, sort_keys=True, default=float).encode())
    return np.random.default_rng(h).standard_normal(n)


def simulate(rock: Rock, p: dict, seed: int, cv: dict | None = None) -> dict:
    """The responses of card ``p`` on packing ``seed``: the truth times (1 + scatter), half
    the variance the packing's own offset, half the card-and-packing's (``cv``: the seed
    CVs, default the rock's)."""
    y = rock.truth(p)
    cv = rock.cv if cv is None else cv
    card = tuple(round(float(p[q]), 9) for q in (rock.free if rock.design is None else rock.design))
    n = len(rock.responses)
    z = (_normal(n, "packing", seed) + _normal(n, "run", seed, card)) / np.sqrt(2.0)
    return {r: float(y[r] * (1.0 + cv[r] * zi)) for r, zi in zip(rock.responses, z)}


def design_runs(rock: Rock, n: int, seed: int) -> tuple[pd.DataFrame, dict]:
    """The study's path to the models: a Latin hypercube of ``n`` cards (sample i on packing
    i + 1000), one run each (a DataFrame), and the three-stage stepwise regression of every
    response (its final models)."""
    from scipy.stats import qmc

    design = rock.design or {q: rock.ranges[q] for q in rock.free}
    u = qmc.LatinHypercube(d=len(design), seed=seed).random(n)
    rows = []
    for i, ui in enumerate(u):
        p = dict(rock.fixed)
        p.update({q: lo + x * (hi - lo) for (q, (lo, hi)), x in zip(design.items(), ui)})
        rows.append({**p, **simulate(rock, p, 1000 + i, rock.design_cv)})
    df = pd.DataFrame(rows)
    res = StepwiseRegression(cv_folds=0, seed=seed).fit(df, {r: list(design) for r in rock.responses})
    return df, res.final_models


def regression(rock: Rock, n: int, seed: int) -> dict:
    """The stepwise models of :func:`design_runs`."""
    return design_runs(rock, n, seed)[1]


def planted_card(rock: Rock, i: int) -> dict:
    """Planted card ``i``: the rock's fixed values and each free parameter drawn inside the
    middle 80 % of its range (from seed 7000 + i)."""
    rng = np.random.default_rng(7000 + i)
    planted = dict(rock.fixed)
    planted.update({q: rock.ranges[q][0] + (0.1 + 0.8 * rng.random())
                    * (rock.ranges[q][1] - rock.ranges[q][0]) for q in rock.free})
    return planted


def one_card(rock: Rock, i: int, models: dict, max_rounds, updates=UPDATES,
             grows: tuple = (None,)) -> list[dict]:
    """A planted card inside the ranges' middle 80 %, its lab seeds' mean as the targets
    (with their standard errors when ``rock.target_se``), the inversion, and the loop from
    it with each update rule and each ``grows`` (``grow_within``; None: the loop's
    default). A rule's label is the update rule, with ", grow g" when several are compared."""
    planted = planted_card(rock, i)
    lab = pd.DataFrame([simulate(rock, planted, s) for s in rock.lab_seeds])  # other packings
    targets = {r: float(lab[r].mean()) for r in rock.responses}
    target_se = ({r: float(lab[r].std(ddof=1) / len(lab) ** 0.5) for r in rock.responses}
                 if rock.target_se else None)
    inv = invert(models,
                 targets,
                 rock.fixed,
                 SearchSpace(ranges=rock.ranges, free=rock.free, ratio=None),
                 search=Multistart(seed=0))
    truth = rock.truth(planted)
    out = []
    for update, grow in [(u, g) for u in updates for g in grows]:
        runs = []

        def sim(params, seed, runs=runs):
            runs.append(seed)
            return simulate(rock, params, seed)

        seeding = LoopSeeds(seeds_per_round=LOOP.seeds_per_round, max_seeds=LOOP.max_seeds,
                            **({} if grow is None else {"grow_within": grow}))
        loop = ClosedLoop(sim, targets,
                          space=SearchSpace(ranges=rock.ranges, free=rock.free, ratio=None),
                          steps=LoopSteps(max_rounds=max_rounds, margin=LOOP.range_margin,
                                          update=update),
                          seeding=seeding, models=models, target_se=target_se)
        res = loop.run(inv.solution)
        h = res.history
        worst = float(np.nanmax([abs(h[f"err_{r}"].iloc[res.best_round])
                                 / h[f"tol_{r}"].iloc[res.best_round] for r in rock.responses]))
        label = update if len(grows) == 1 else f"{update}, grow {grow:g}"
        out.append({"card": i, "update": label, "inversion": inv.status, "status": res.status,
                    **{f"planted_{q}": planted[q] for q in rock.free},
                    **{f"start_err_{r}": float(h[f"err_{r}"].iloc[0]) for r in rock.responses},
                    "rounds": res.n_rounds, "runs": len(runs), "worst_err_over_tol": worst,
                    # the card's seed-free responses against the planted card's: how near
                    # the rock itself (not its lab or loop seeds) the card is
                    **{f"truth_err_{r}": float(rock.truth(res.params)[r] / truth[r] - 1)
                       for r in rock.responses}})
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
                           float(bad.worst_err_over_tol.median()) if len(bad) else None,
                       "mean_runs": float(g.runs.mean()),
                       "rms_truth_err": {c[10:]: float(np.sqrt((g[c] ** 2).mean()))
                                         for c in g.columns if c.startswith("truth_err_")}}
    rules = list(dict.fromkeys(df["update"]))
    first = df[df["update"] == rules[0]]
    out["round1_abs_err_median"] = {c[10:]: float(first[c].abs().median())
                                    for c in first.columns if c.startswith("start_err_")}
    both = df.pivot(index="card", columns="update", values="status") == "converged"
    out["paired"] = ({f"{a} only": int((both[a] & ~both[b]).sum())
                      for a in rules for b in rules if a != b} if len(rules) == 2 else
                     {f"{a}, not {b}": int((both[a] & ~both[b]).sum())
                      for a in rules for b in rules if a != b})
    return out


def _num(v, digits: int = 1) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def markdown(rec: dict) -> str:
    s = rec["summary"]
    rock = rec.get("rock", "fj")
    kind = {"fj": "flat-joint", "pb": "parallel-bond"}[rock]
    lines = [f"# The closed loop's Jacobian update rules on a synthetic {kind} rock "
             f"({rec['date']})", "", "| | |", "|---|---|", f"| date | {rec['date']} |",
             f"| commit | {rec['commit']} |", f"| host | {rec['cpu_model']} ({rec['cpus']} CPUs) |",
             f"| load | {', '.join(f'{x:.2f}' for x in rec['load_average'])} |",
             f"| command | `{rec['command']}` |", f"| time | {rec['seconds']:.0f} s |", "",
             "What is compared, and how the synthetic rock was built: the docstring of "
             "`benchmarks/loop_convergence.py`. Every card: the loop from the regression's "
             f"inversion, 3 seeds per round growing to 10, at most {rec['max_rounds']} rounds, "
             "the study's other loop settings. Not the DEM: one family of response surfaces, "
             + ("with the scatter and couplings of the flat-joint Lac du Bonnet study."
                if rock == "fj" else "fitted to the default parallel-bond study's samples, "
                "with the seed scatter of planted card Q (`pb_truth`); the lab values are "
                "the means of 20 other packings, given with their standard errors."), "",
             "Round 1 (the regression's card) misses by a median |error| of "
             + ", ".join(f"{r} {100 * v:.1f} %" for r, v in s["round1_abs_err_median"].items())
             + ".", "",
             "| update rule | converged | of which within 6 rounds | median rounds (converged) "
             "| median runs (converged) | not converged: median worst error / tolerance "
             "| mean runs (every card) | RMS error of the card's seed-free responses "
             "against the planted card's |",
             "|---|---|---|---|---|---|---|---|"]
    for u in [k for k in s if k not in ("round1_abs_err_median", "paired")]:
        x = s[u]
        lines.append(f"| {u} | {x['converged']} of {x['cards']} | "
                     f"{x['converged_within_6_rounds']} | {_num(x['median_rounds_converged'])} | "
                     f"{_num(x['median_runs_converged'])} | "
                     f"{_num(x['median_worst_err_over_tol_not_converged'], 2)} | "
                     + (f"{x['mean_runs']:.1f} | " + ", ".join(
                         f"{r} {100 * v:.2f} %" for r, v in x["rms_truth_err"].items()) + " |"
                        if "mean_runs" in x else "- | - |"))
    lines += ["", "Paired by card: " + "; ".join(f"{k}: {v}" for k, v in s["paired"].items())
              + " (converged with one rule, not with the other).", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rock", choices=list(ROCKS), default="fj",
                    help="the synthetic rock (fj: flat joint, five targets; pb: parallel "
                         "bond, four targets)")
    ap.add_argument("--cards", type=int, default=30)
    ap.add_argument("--samples", type=int, default=None,
                    help="design samples of the regression (default: the rock's)")
    ap.add_argument("--max-rounds", default=None,
                    help="the loop's round budget, an integer or auto (default: the rock's)")
    ap.add_argument("--updates", default=",".join(UPDATES),
                    help=f"the update rules compared, comma-separated (of {', '.join(UPDATES)})")
    ap.add_argument("--grow-within", default=None,
                    help="the loop's grow_within (the seed set grows once every mean is "
                         "within this many tolerances), comma-separated to compare several "
                         "(default: ClosedLoop's)")
    ap.add_argument("--design-seed", type=int, default=2018)
    ap.add_argument("--commit", default="")
    ap.add_argument("--out", default=None)
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args(argv)
    rock = ROCKS[args.rock]
    rounds = rock.max_rounds if args.max_rounds is None else args.max_rounds
    rounds = rounds if rounds == "auto" else int(rounds)
    updates = args.updates.split(",")
    bad = [u for u in updates if u not in UPDATES]
    if bad:
        ap.error(f"--updates: {bad} not among {list(UPDATES)}")
    rec = {**record_header("loop_convergence.py", argv), "commit": args.commit,
           "rock": rock.name, "max_rounds": rounds}
    grows = (None,) if args.grow_within is None else tuple(
        float(g) for g in args.grow_within.split(","))
    if grows != (None,):
        rec["grow_within"] = list(grows)
    t0 = time.time()
    models = regression(rock, args.samples or rock.samples, args.design_seed)
    rows = [r for i in range(args.cards) for r in one_card(rock, i, models, rounds, updates,
                                                             grows)]
    rec.update({"seconds": time.time() - t0, "summary": summarise(rows), "cards": rows})
    write_record(rec, args.out, args.markdown, markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
