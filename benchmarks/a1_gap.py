"""The A1 gap (issue 56, item 4): each named cause of the difference between bpmcal's
and the paper's PFC3D σc, E and ν on the paper's card A1, measured on the full-size
cylinder (50 x 100 mm, scale 1) one cause at a time, beside the paper's three calibrated
cards A1-A3 against their Table 5 PFC3D re-runs.

Each variant is the base run (the library's UCS test: ``pfc`` genesis with its
installation gap, platens at 0.05 m/s after a 0.1 m/s approach, local damping 0.7,
frictionless platens, no end caps) with one thing changed:

- ``genesis_bpmcal``: the other relief and bonding (packing method: ``lab.specimen``);
- ``gap_0``, ``gap_x2``: the installation gap 0 and twice the ``pfc`` genesis's;
- ``relax_1e-3``: a tenfold tighter equilibrium before bonding (relax_ratio);
- ``sigma0_1``: the ``bpmcal`` genesis with 1 MPa of locked-in stress (it relieves to
  sigma0; the ``pfc`` genesis leaves none);
- ``pb_rmul_1.1``: the bond radius multiplier lambda-bar 1.1 (PFC's default 1; the paper
  does not state it);
- ``linear_4/pi``: the linear contacts 4/pi (1.27) x stiffer, E* x 4/pi with E-bar
  unchanged: the contact-stiffness convention of PFC 4 (ball stiffness k = 4 R Ec in
  3D, two in series: 2 R Ec for equal balls) against PFC 5+'s deformability method
  (pi r^2 E* / L = (pi/2) R E* for equal balls), the one area or length convention that
  differs between PFC versions (the parallel bond's, pi (lambda r)^2 and E-bar / L, is
  the same in both);
- ``pb_mcf_0``: the moment-contribution factor beta-bar 0 (bonds carry no bending or
  twisting moment; PFC's default 1);
- ``damping_0.3``: local damping 0.3 instead of PFC's 0.7;
- ``slow``: the platens at 0.02 m/s from the start (no fast approach). The ball density
  is not a separate variant: with local (non-viscous) damping and rate-independent
  contact laws the run depends on the density only through v / sqrt(E / rho), so a
  density x 6.25 is the platen speed x 2.5 (the ``slow`` variant reversed);
- ``platen_fric_0.5``: platen friction 0.5 instead of 0;
- ``unstated_hi``: phi_p 55 deg and mu 0.55, the top of Table 2's ranges, for the two
  parameters the paper does not state (bpmcal uses the ranges' midpoints 35 deg, 0.35);
- ``gap_x2+linear_4/pi``: the two together;
- ``A2``, ``A3``: the paper's other two cards, base settings; ``A2:gap_x2+linear_4/pi``,
  ``A3:...``: with the two changes together.

Every run reports σc, E, ν, its genesis's coordination, bonds per ball and achieved
porosity, and the difference from the paper's PFC3D values (Table 5) of its card. One JSON
record (date, commit, CPU model, load, the command), written after every run:

    python benchmarks/a1_gap.py --out benchmarks/results/results_a1_gap_DATE.json

``--scale`` runs a smaller cylinder (a screening; the record says which).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from pathlib import Path

from _study import add_record_options, rendered, run_meta

#: variant -> (card, Geometry fields, UCSSettings fields, Material fields)
VARIANTS = {
    "base": ("A1", {}, {}, {}),
    "genesis_bpmcal": ("A1", {"genesis": "bpmcal"}, {}, {}),
    "gap_0": ("A1", {"install_gap_mm": 0.0}, {}, {}),
    "gap_x2": ("A1", {"install_gap_mm": "x2"}, {}, {}),
    "relax_1e-3": ("A1", {"relax_ratio": 1e-3}, {}, {}),
    "sigma0_1": ("A1", {"genesis": "bpmcal", "sigma0_MPa": 1.0}, {}, {}),
    "pb_rmul_1.1": ("A1", {}, {}, {"pb_rmul": 1.1}),
    "pb_mcf_0": ("A1", {}, {}, {"pb_mcf": 0.0}),
    "linear_4/pi": ("A1", {}, {}, {"emod": "x4/pi"}),
    "damping_0.3": ("A1", {}, {"damping": 0.3}, {}),
    "slow": ("A1", {}, {"platen_velocity": 0.02, "approach_velocity": 0.0}, {}),
    "platen_fric_0.5": ("A1", {}, {"platen_fric": 0.5}, {}),
    "unstated_hi": ("A1", {}, {}, {}),
    "gap_x2+linear_4/pi": ("A1", {"install_gap_mm": "x2"}, {}, {"emod": "x4/pi"}),
    "A2": ("A2", {}, {}, {}),
    "A3": ("A3", {}, {}, {}),
    "A2:gap_x2+linear_4/pi": ("A2", {"install_gap_mm": "x2"}, {}, {"emod": "x4/pi"}),
    "A3:gap_x2+linear_4/pi": ("A3", {"install_gap_mm": "x2"}, {}, {"emod": "x4/pi"}),
}
#: card changes of a variant (paper units)
CARD_OVER = {"unstated_hi": {"pb_fa_deg": 55.0, "fric": 0.55}}
#: the genesis keys reported per run
GENESIS_KEYS = ("n_balls", "n_bonds", "coordination", "bonds_per_ball", "contacts_per_ball",
                "porosity_achieved", "install_gap_mm", "locked_in_stress_MPa")


def run(variant: str, scale: float, seed: int) -> dict:
    import bpmcal.lab.runner as runner
    from bpmcal.lab.runner import Geometry, ucs_test
    from bpmcal.lab.specimen import PFC_GAP_RATIO
    from bpmcal.lab.ucs import UCSSettings
    from bpmcal.study.paper import CARDS, VERIFIED

    card_name, geo_kw, st_kw, mat_kw = VARIANTS[variant]
    card = {**CARDS[card_name], **CARD_OVER.get(variant, {})}
    if geo_kw.get("install_gap_mm") == "x2":
        geo_kw = {**geo_kw, "install_gap_mm": 2 * PFC_GAP_RATIO * card["rmin_mm"]}
    if mat_kw:  # the engine fields a card does not carry (bpmcal.params: fixed)
        base = runner.card_material

        def card_material(p, *a, **kw):
            mat, micro = base(p, *a, **kw)
            over = {k: (mat.emod * 4.0 / math.pi if v == "x4/pi" else v)
                    for k, v in mat_kw.items()}
            return dataclasses.replace(mat, **over), micro
        runner.card_material = card_material
    t0 = time.process_time()
    r = ucs_test(card, seed, Geometry(scale=scale, **geo_kw), UCSSettings(**st_kw),
                 threads=1, keep_particles=False)
    s = r.summary
    ref = VERIFIED[f"B{card_name[1]}"]
    out = {"variant": variant, "card": card_name, "scale": scale, "seed": seed,
           "ucs_MPa": s["ucs_MPa"], "E_GPa": s["E_GPa"], "nu": s["nu"],
           **{k: s.get(k) for k in GENESIS_KEYS},
           "steps": s.get("steps"), "cpu_s": time.process_time() - t0}
    for k in ("ucs_MPa", "E_GPa", "nu"):
        out[f"{k}_vs_pfc3d_pct"] = 100.0 * (out[k] / ref[k] - 1.0)
    return out


def render(recs: list[dict]) -> str:
    """The records' runs (pooled; a later run of a variant replaces an earlier one), each
    beside the base run and the paper's PFC3D (Markdown)."""
    runs = {r["variant"]: r for rec in recs for r in rec["runs"]}
    base = runs.get("base")
    head = ["variant", "card", "σc [MPa]", "E [GPa]", "ν", "bonds per ball", "porosity",
            "Δσc, ΔE, Δν vs base [%]", "σc, E, ν vs PFC3D [%]", "CPU [s]"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for v, r in runs.items():
        if base is not None and r["card"] == "A1":
            d = ", ".join(f"{100 * (r[k] / base[k] - 1):+.1f}" for k in ("ucs_MPa", "E_GPa", "nu"))
        else:
            d = "–"
        pfc = ", ".join(f"{r[f'{k}_vs_pfc3d_pct']:+.1f}" for k in ("ucs_MPa", "E_GPa", "nu"))
        out.append(f"| `{v}` | {r['card']} | {r['ucs_MPa']:.2f} | {r['E_GPa']:.3f} | "
                   f"{r['nu']:.3f} | {r['bonds_per_ball']:.2f} | {r['porosity_achieved']:.4f} "
                   f"| {d} | {pfc} | {r['cpu_s']:.0f} |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=1)
    add_record_options(ap)
    a = ap.parse_args(argv)
    if rendered(ap, a, render):
        return 0
    unknown = [v for v in a.variants.split(",") if v not in VARIANTS]
    if unknown:
        ap.error(f"--variants {','.join(unknown)}: expected some of {', '.join(VARIANTS)}")
    rec = {**run_meta("a1_gap.py", sys.argv[1:] if argv is None else argv), "runs": []}
    rec["commit"] = rec["commit"] or a.commit

    def save():
        rec["load_average_end"] = list(os.getloadavg())
        Path(a.out).write_text(json.dumps(rec, indent=1, default=float) + "\n")

    from concurrent.futures import ProcessPoolExecutor
    vs = a.variants.split(",")
    with ProcessPoolExecutor(a.jobs, max_tasks_per_child=1) as ex:  # a patched material
        futs = [ex.submit(run, v, a.scale, a.seed) for v in vs]  # stays in its process
        for f in futs:
            rec["runs"].append(f.result())
            print(json.dumps(rec["runs"][-1], default=float), flush=True)
            save()
    save()
    return 0


if __name__ == "__main__":
    sys.exit(main())
