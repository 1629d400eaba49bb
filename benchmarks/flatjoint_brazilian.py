"""Flat-jointed Brazilian discs that split, and the UCS Poisson's ratio before crack
dilation: the measurement behind record 2026-12-02b (issue 56, item 2).

Two parts, one JSON record (date, commit, CPU model, load average, the command):

- ``discs``: the study's Brazilian disc (config/config.yaml ``bts``, one disc per seed:
  ``retests`` 0) of each flat-joint card of ``CARDS`` at each ``--scales`` on packing
  ``--seeds``, with the test's defaults for flat joints (``contact_cap_bridge`` and
  ``split_drop`` None: caps that do not bridge the loaded diameter, the split at the first
  5 % drop) and, with ``--before``, with the parallel bond's settings the flat joints had
  before (caps that bridge, the split at a drop to 50 %). Per disc: valid, why not, the
  peak stress, the elements broken, the flat joints broken (contacts with a broken
  element), the balls and the CPU time.
- ``ucs``: the UCS test of each card of ``UCS_CARDS`` (seed 1, the study's cylinder at the
  card's scale): nu as the summary gives it (before crack dilation: ``lab.ucs``) beside
  nu over the whole 40-60 % window (the rule before), with ``nu_window_lo``/``_hi``.

    python benchmarks/flatjoint_brazilian.py --scales 0.55,0.8 --seeds 1,2,3,4,5 \\
        --out benchmarks/results/results_flatjoint_brazilian_DATE.json

Runs go two at a time (``--jobs``, one numba thread each).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from _study import (
    add_record_options,
    bts_disc_and_settings,
    record_header,
    rendered,
    source_commit,
    study_config,
)

from bpmcal.study.paper import A1

#: the verified card of the Lac du Bonnet flat-joint example (record 2026-11-29d) and a
#: flat-joint card with slits and an installation gap (fj_slit_frac 0.2, fj_gi_ratio 0.2)
LDB_FJ = {"contact_model": "flatjoint", "rmin_mm": 0.8, "porosity": 0.3,
          "fj_emod_GPa": 86.72, "fj_kratio": 1.7, "fj_ten_MPa": 11.63, "fj_coh_MPa": 115.0,
          "fj_fa_deg": 30.0, "fj_fric": 0.6}
FJ_SLIT = {"contact_model": "flatjoint", "rmin_mm": 0.8, "porosity": 0.3,
           "fj_emod_GPa": 60.0, "fj_kratio": 2.0, "fj_ten_MPa": 10.0, "fj_coh_MPa": 100.0,
           "fj_fa_deg": 30.0, "fj_fric": 0.6, "fj_slit_frac": 0.2, "fj_gi_ratio": 0.2}
#: a flat-joint card whose joints fail in shear before tension (low cohesion), with larger
#: balls and no slits, and a soft, weak one (low modulus and strengths, wider friction
#: angle): cards of another kind than the verified one
FJ_SHEAR = {"contact_model": "flatjoint", "rmin_mm": 1.0, "porosity": 0.35,
            "fj_emod_GPa": 40.0, "fj_kratio": 2.5, "fj_ten_MPa": 8.0, "fj_coh_MPa": 30.0,
            "fj_fa_deg": 20.0, "fj_fric": 0.5}
FJ_SOFT = {"contact_model": "flatjoint", "rmin_mm": 0.8, "porosity": 0.3,
           "fj_emod_GPa": 15.0, "fj_kratio": 1.5, "fj_ten_MPa": 4.0, "fj_coh_MPa": 40.0,
           "fj_fa_deg": 40.0, "fj_fric": 0.7}
CARDS = {"ldb_fj": LDB_FJ, "fj_slit02_gi02": FJ_SLIT, "fj_shear": FJ_SHEAR,
         "fj_soft": FJ_SOFT}
#: the paper's A1 (parallel bond: bpmcal.study.paper) and flat-joint cards with and
#: without slits
UCS_CARDS = {"a1": (A1, 0.4), "ldb_fj": (LDB_FJ, 0.3),
             "fj_slit02_gi0": ({**FJ_SLIT, "fj_gi_ratio": 0.0}, 0.3),
             "fj_slit04_gi02": ({**FJ_SLIT, "fj_slit_frac": 0.4}, 0.3)}
#: the Brazilian settings flat joints had before (those of parallel bonds)
BEFORE = {"contact_cap_bridge": True, "split_drop": 0.5}


def disc_run(card: str, scale: float, seed: int, variant: str, cap: float | None,
             across: float | None, loading: str, cfg: dict) -> dict:
    """One disc; ``cap``, ``across`` None and ``loading`` "": the study's."""
    from bpmcal.lab.runner import bts_test

    over = {"retests": 0, **(BEFORE if variant == "before" else {}),
            **({} if cap is None else {"contact_cap": cap}),
            **({} if across is None else {"min_balls_across": across}),
            **({"loading": loading} if loading else {})}
    geo, st = bts_disc_and_settings(cfg, scale=scale, **over)
    t0 = time.process_time()
    run = bts_test(CARDS[card], seed, geo, st, threads=1, keep_particles=False)
    s, c = run.summary, run.cracks
    pairs = np.unique(np.asarray(c["i"], np.int64) * 10_000_000 + np.asarray(c["j"]))
    return {"card": card, "scale": scale, "seed": seed, "variant": variant,
            "valid": bool(s["bts_valid"]), "reason": s["bts_invalid_reason"],
            "peak_MPa": s["bts_peak_MPa"], "bts_MPa": s["bts_MPa"],
            "elements_broken": int(np.size(c["step"])), "joints_broken": int(pairs.size),
            "n_balls": int(s["n_balls"]), "balls_across": s["balls_across"],
            "contact_cap_bonds": int(s["contact_cap_bonds"]),
            "contact_cap_bridge": bool(s["contact_cap_bridge"]),
            "contact_cap": st.contact_cap, "min_balls_across": st.min_balls_across,
            "diameter_mm": s["diameter_mm"], "disc_enlarged": bool(run.inputs["disc_enlarged"]),
            "split_drop": s["split_drop"], "steps": int(s["steps"]), "loading": st.loading,
            "cpu_s": time.process_time() - t0}


def ucs_run(card: str) -> dict:
    from bpmcal.lab.runner import Geometry, ucs_test
    from bpmcal.lab.ucs import fit_slope

    params, scale = UCS_CARDS[card]
    t0 = time.process_time()
    run = ucs_test(params, 1, Geometry(scale=scale), threads=1, keep_particles=False)
    s, se = run.summary, run.series
    sig, ea, er = (np.asarray(se[k]) for k in ("axial_stress", "axial_strain",
                                                 "lateral_strain"))
    ip = int(np.argmax(sig))
    pre = slice(0, ip + 1)
    w = (sig[pre] >= 0.4 * sig[ip]) & (sig[pre] <= 0.6 * sig[ip])
    return {"card": card, "scale": scale, "seed": 1, "ucs_MPa": s["ucs_MPa"],
            "E_GPa": s["E_GPa"], "nu": s["nu"], "nu_window_lo": s["nu_window_lo"],
            "nu_window_hi": s["nu_window_hi"],
            "nu_40_60": -fit_slope(ea[pre][w], er[pre][w]), "n_balls": int(s["n_balls"]),
            "cpu_s": time.process_time() - t0}


def render(recs: list[dict]) -> str:
    """Per card, disc and cap (the records' discs pooled): the median balls across, discs,
    valid, σt of the valid (mean, seed CV), the invalid discs' reasons (Markdown)."""
    groups: dict = {}
    for rec in recs:
        for r in rec["discs"]:
            d = r.get("diameter_mm", 50.0 * r["scale"])  # records before diameter_mm
            key = (r["card"], round(d, 2), r.get("contact_cap") or 1.5,
                   bool(r.get("disc_enlarged")), r.get("loading", "flat"))
            groups.setdefault(key, []).append(r)
    head = ["card", "disc [mm]", "balls across", "cap", "enlarged", "loading", "valid",
            "σt [MPa]",
            "seed CV", "why not (invalid discs)"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for (card, d, cap, big, how), rs in sorted(groups.items(), key=lambda kv: kv[0]):
        v = np.array([r["bts_MPa"] for r in rs if r["valid"]])
        across = float(np.median([r["balls_across"] for r in rs]))
        why = "; ".join(sorted({r["reason"].split(":")[0] for r in rs if not r["valid"]}))
        cv = f"{100 * v.std(ddof=1) / v.mean():.1f} %" if v.size > 1 else "–"
        out.append(f"| {card} | {d:g} | {across:.1f} | {cap:g} | {'yes' if big else 'no'} | "
                   f"{how} | {v.size} of {len(rs)} | "
                   f"{(f'{v.mean():.2f}' if v.size else '–')} | {cv} | {why} |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scales", default="0.55,0.8")
    ap.add_argument("--seeds", default="1,2,3,4,5")
    ap.add_argument("--cards", default=",".join(CARDS))
    ap.add_argument("--caps", default="", help="contact caps [mean ball diameters] to run "
                    "each disc with (default: the study's bts.contact_cap)")
    ap.add_argument("--min-across", default="", help="min_balls_across values to run each "
                    "disc with ('default': the contact model's; default: the study's)")
    ap.add_argument("--loading", default="", help="flat or jaws (default: the study's)")
    ap.add_argument("--before", default="", help="scales at which to run the before settings")
    ap.add_argument("--ucs", action="store_true", help="the UCS part too")
    ap.add_argument("--jobs", type=int, default=2)
    add_record_options(ap, "the per-card table")
    a = ap.parse_args(argv)
    if rendered(ap, a, render):
        return 0
    head = record_header("flatjoint_brazilian.py", sys.argv[1:] if argv is None else argv)
    head["commit"] = source_commit(a.commit)
    import bpmcal
    head["bpmcal_source"] = str(Path(bpmcal.__file__).parent)
    seeds = [int(x) for x in a.seeds.split(",")]
    cfg = study_config()
    caps = [float(x) for x in a.caps.split(",") if x] or [None]
    acr = [None if x == "default" else float(x) for x in a.min_across.split(",") if x] or [None]
    tasks = [(c, float(sc), sd, "after", cp, ac, a.loading) for c in a.cards.split(",")
             for sc in a.scales.split(",") for ac in acr for cp in caps for sd in seeds]
    tasks += [(c, float(sc), sd, "before", None, None, a.loading) for c in a.cards.split(",")
              for sc in a.before.split(",") if sc for sd in seeds]
    out = {**head, "discs": [], "ucs": []}

    def save():  # after every run: a long matrix cut short keeps what it measured
        out["load_average_end"] = list(os.getloadavg())
        Path(a.out).write_text(json.dumps(out, indent=1, default=float))

    with ProcessPoolExecutor(a.jobs) as ex:
        for r in (ex.map(ucs_run, UCS_CARDS) if a.ucs else []):
            out["ucs"].append(r)
            save()
        for r in ex.map(disc_run, *zip(*tasks), [cfg] * len(tasks)):
            out["discs"].append(r)
            save()
    save()
    return 0


if __name__ == "__main__":
    sys.exit(main())
