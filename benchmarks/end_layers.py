"""Do the platen ends control a UCS specimen's strength? (issue 14, item 7)

    python benchmarks/end_layers.py [--scale 0.4] [--seeds 1 2 3 4 5 6]
        [--design DESIGN.csv --samples s000 s001 ...] [--cap 1.0 2.0] [--factor 1000]
        [--profile-only] [--json out.json]

Without ``--design`` the specimens are the paper's A1 card on the given packing seeds;
with it, the design's samples (their parameters and packing seeds). Every specimen is
built once (``lab.runner.make_specimen``, the default ``pfc`` genesis, one thread) and

1. **its boundary layers are measured** before loading: the balls by the distance of their
   centre from the nearer platen, in slices of half a mean ball diameter d (bonds per ball,
   bonds per cm^3 of slab, the bonds' contact points located in the slab), against the
   bulk (centres in the middle half of the height); the intact bonds crossing horizontal
   planes at distances 0.25 d ... 3 d from the platens and in the middle half (bonds per
   cm^2 of cross-section, and their bonded area projected on the plane over the
   cross-section, the "bonded area fraction"); the balls touching each platen per cm^2;
   bonds per ball by radius in the middle of the height;
2. **it is tested twice** (``lab.ucs.run_ucs``, the default loading, frictionless platens,
   the default end caps off), on two copies of the same bonded specimen: as built, and with
   an *end cap* (what ``UCSSettings.end_cap`` installs): every bond
   whose contact point lies within ``cap`` x d of a platen gets ``factor`` x its tensile
   strength and cohesion (``Model.set_bond_strength_factors``; stiffnesses unchanged, so
   the cap changes E only through the cracks it prevents). For each: sigma_c, E, nu, the
   platen stresses at the peak (top, bottom: equilibrium within the specimen), the cracks'
   heights h = z / H (median, shares below 0.4, in 0.4-0.6, above 0.6, at the peak and at
   the end of the test), the crack share within 1 d and 2 d of a platen against the bond
   share there, and the cracks just outside the cap.

If the ends controlled sigma_c, the cap would raise it well beyond the packing scatter
(seed CV of sigma_c ~ 2-3 %) and move failure into the middle; if the bulk controls,
sigma_c barely changes and the cracks merely relocate.

Tables (markdown) on stdout; every number in ``--json``. CPU seconds (process time) per
specimen are printed: report those, not wall time, on a shared machine.
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _study import design_samples  # noqa: E402

#: slices of the boundary-layer profile, in mean ball diameters from the nearer platen
SLICE = 0.5
N_SLICES = 8
#: planes (distance from the nearer platen, mean ball diameters) whose crossing bonds count
PLANES = (0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0)


def contact_points(m, bi, bj):
    """Contact points of the pairs (the middle of the overlap or gap), unit normals i->j."""
    pos, r = m.positions, m.radii
    d = pos[bj] - pos[bi]
    ln = np.linalg.norm(d, axis=1)
    n = d / ln[:, None]
    gap = ln - r[bi] - r[bj]
    return pos[bi] + n * (r[bi] + 0.5 * gap)[:, None], n


def platen_distance(z, zb, zt):
    return np.minimum(z - zb, zt - z)


def profile(sp) -> dict:
    """The boundary layers of a bonded specimen before loading (module docstring)."""
    m = sp.model
    pos, r = m.positions, m.radii
    zb, zt = sp.z_bottom, sp.z_top
    H = zt - zb
    R0 = sp.radius0
    area = math.pi * R0 * R0
    dbar = 2.0 * float(r.mean())
    bi, bj = m.bond_pairs()
    cp_all, _ = contact_points(m, bi, bj)
    dbond_all = platen_distance(cp_all[:, 2], zb, zt) / dbar  # every bond (crack analysis)
    intact = m.bond_states == 0  # genesis cracks (if any) are left out of the profile
    bi, bj = bi[intact], bj[intact]
    nbond = np.bincount(bi, minlength=m.n) + np.bincount(bj, minlength=m.n)
    cp, nrm = contact_points(m, bi, bj)
    dball = platen_distance(pos[:, 2], zb, zt) / dbar
    dbond = platen_distance(cp[:, 2], zb, zt) / dbar
    bulk_b = (pos[:, 2] >= zb + 0.25 * H) & (pos[:, 2] <= zt - 0.25 * H)
    bulk_c = (cp[:, 2] >= zb + 0.25 * H) & (cp[:, 2] <= zt - 0.25 * H)
    vol_bulk = area * 0.5 * H
    out = {"n_balls": int(m.n), "n_bonds": int(bi.size), "dbar_mm": dbar * 1e3,
           "H_mm": H * 1e3, "H_over_dbar": H / dbar,
           "bulk_bonds_per_ball": float(nbond[bulk_b].mean()),
           "bulk_bonds_per_cm3": float(np.count_nonzero(bulk_c) / (vol_bulk * 1e6)),
           "bulk_solid_fraction": float((4 / 3 * math.pi * r[bulk_b] ** 3).sum() / vol_bulk)}
    sl = []
    for k in range(N_SLICES):
        lo, hi = k * SLICE, (k + 1) * SLICE
        b = (dball >= lo) & (dball < hi)
        c = (dbond >= lo) & (dbond < hi)
        vol = 2 * area * SLICE * dbar  # both ends
        sl.append({"d_lo": lo, "d_hi": hi, "balls": int(b.sum()),
                   "bonds_per_ball": float(nbond[b].mean()) if b.any() else math.nan,
                   "bonds_per_cm3": float(np.count_nonzero(c) / (vol * 1e6)),
                   "solid_fraction": float((4 / 3 * math.pi * r[b] ** 3).sum() / vol)})
    out["slices"] = sl
    rb = m.material.pb_rmul * np.minimum(r[bi], r[bj])
    abond = math.pi * rb * rb * np.abs(nrm[:, 2])  # bonded area projected on a horizontal plane
    zi, zj = pos[bi, 2], pos[bj, 2]

    def crossing(zp):
        x = (np.minimum(zi, zj) < zp) & (np.maximum(zi, zj) >= zp)
        return np.count_nonzero(x), float(abond[x].sum())

    pl = []
    for p in PLANES:
        n0, a0 = crossing(zb + p * dbar)
        n1, a1 = crossing(zt - p * dbar)
        pl.append({"d": p, "bonds_per_cm2": 0.5 * (n0 + n1) / (area * 1e4),
                   "area_fraction": 0.5 * (a0 + a1) / area})
    mid = [crossing(zb + f * H) for f in np.linspace(0.25, 0.75, 11)]
    out["planes"] = pl
    out["bulk_plane_bonds_per_cm2"] = float(np.mean([c[0] for c in mid]) / (area * 1e4))
    out["bulk_plane_area_fraction"] = float(np.mean([c[1] for c in mid]) / area)
    out["bulk_plane_area_fraction_min"] = float(min(c[1] for c in mid) / area)
    # balls touching a platen (surface within 0.01 Rmin of it; the pfc genesis relieved
    # their overlaps, so the engine counts no active contact before loading)
    tol = 0.01 * float(r.min())
    touch = (pos[:, 2] - r - zb <= tol) | (zt - pos[:, 2] - r <= tol)
    out["platen_contacts_per_cm2"] = 0.5 * np.count_nonzero(touch) / (area * 1e4)
    out["platen_balls_bonds_per_ball"] = float(nbond[touch].mean())
    rho = np.hypot(pos[:, 0], pos[:, 1]) / R0
    middle = (pos[:, 2] >= zb + 0.1 * H) & (pos[:, 2] <= zt - 0.1 * H)
    edges = (0.0, 0.5, 0.7, 0.85, 1.01)
    out["radial"] = [{"r_lo": a, "r_hi": b,
                      "bonds_per_ball": float(nbond[middle & (rho >= a) & (rho < b)].mean())}
                     for a, b in zip(edges[:-1], edges[1:])]
    out["_dbond"] = dbond_all  # for the crack analysis (not in the JSON)
    return out


def shares(h) -> dict:
    h = np.asarray(h, float)
    if h.size == 0:
        return {"n": 0, "median": math.nan, "bottom": math.nan, "middle": math.nan,
                "top": math.nan, "location": "none"}
    med = float(np.median(h))
    return {"n": int(h.size), "median": med, "bottom": float(np.mean(h < 0.4)),
            "middle": float(np.mean((h >= 0.4) & (h <= 0.6))), "top": float(np.mean(h > 0.6)),
            "location": "bottom" if med < 0.4 else "top" if med > 0.6 else "middle"}


def test(sp, dbond, cap_idx=None, factor=1000.0) -> dict:
    """One UCS test of ``sp`` (its model is modified), with the end cap when
    ``cap_idx`` is given."""
    from bpmcal.lab.ucs import UCSSettings, run_ucs

    m = sp.model
    if cap_idx is not None:
        f = np.ones(m.n_bonds)
        f[cap_idx] = factor
        m.set_bond_strength_factors(f)
    c0 = time.process_time()
    # the caps of this script only (the default caps of run_ucs off: end_cap=0)
    res = run_ucs(sp, UCSSettings(end_cap=0.0))
    cpu = time.process_time() - c0
    s = res.summary
    ser = res.series
    ip = int(np.argmax(ser["axial_stress"]))
    peak_step = int(ser["step"][ip])
    ev = res.cracks
    H = sp.z_top - sp.z_bottom
    load = ev["step"] >= 0
    h = (ev["pos"][load, 2] - sp.z_bottom) / H
    pre = ev["step"][load] <= peak_step
    dcr = dbond[ev["bond"][load]]  # distance of the cracked bonds from the platens (d)
    out = {"ucs_MPa": s["ucs_MPa"], "E_GPa": s["E_GPa"], "nu": s["nu"],
           "E_central_GPa": s["E_central_GPa"], "peak_strain": s["peak_strain"],
           "stress_top_peak_MPa": float(ser["stress_top"][ip] / 1e6),
           "stress_bottom_peak_MPa": float(ser["stress_bottom"][ip] / 1e6),
           "cracks_peak": int(pre.sum()), "cracks_end": int(load.sum()),
           "end": shares(h), "peak": shares(h[pre]), "cpu_s": cpu,
           "stop_reason": s["stop_reason"]}
    nb = dbond.size
    for lim in (1.0, 2.0):
        bond_share = float(np.count_nonzero(dbond <= lim) / nb)
        out[f"within_{lim:g}d"] = {
            "bond_share": bond_share,
            "crack_share_peak": float(np.mean(dcr[pre] <= lim)) if pre.any() else math.nan,
            "crack_share_end": float(np.mean(dcr <= lim)) if dcr.size else math.nan}
    if cap_idx is not None:
        capped = np.zeros(nb, bool)
        capped[cap_idx] = True
        out["capped_bonds"] = int(capped.sum())
        out["capped_broken"] = int(np.count_nonzero(m.bond_states[capped] != 0))
    return out


def run_specimen(label, params, seed, scale, caps, factor, profile_only, threads=1):
    from bpmcal.lab.runner import Geometry, make_specimen
    from bpmcal.lab.specimen import end_cap_bonds

    c0 = time.process_time()
    sp = make_specimen(params, seed, Geometry(scale=scale), threads=threads)
    cpu_gen = time.process_time() - c0
    prof = profile(sp)
    dbond = prof.pop("_dbond")
    row = {"label": label, "seed": seed, "scale": scale, "params": params, "profile": prof,
           "genesis_cpu_s": cpu_gen, "tests": {}}
    if profile_only:
        return row
    for cap in caps:
        sp2 = copy.deepcopy(sp)
        idx = end_cap_bonds(sp2, cap)  # the selection of lab.specimen.apply_end_caps
        row["tests"][f"cap {cap:g}d"] = test(sp2, dbond, idx, factor)
    row["tests"]["none"] = test(sp, dbond)  # the original specimen last
    return row


def fmt_profile(rows):
    print("\n### Boundary layers (before loading)\n")
    print("| specimen | balls | d (mm) | H/d | bulk bonds/ball | bonds/ball at d from the "
          "platen: 0-0.5, 0.5-1, 1-1.5, 1.5-2, 2-2.5 d | bulk bonds/cm3 | bonds/cm3 0-0.5, "
          "0.5-1, 1-1.5 d | bonded area fraction of planes at 0.5, 1, 1.5, 2 d; bulk mean "
          "(min) | platen contacts /cm2 | bonds/ball by r/R 0-.5, .5-.7, .7-.85, .85-1 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        p = row["profile"]
        s = p["slices"]
        pl = {q["d"]: q for q in p["planes"]}
        print(f"| {row['label']} | {p['n_balls']} | {p['dbar_mm']:.2f} | {p['H_over_dbar']:.1f} "
              f"| {p['bulk_bonds_per_ball']:.2f} | "
              + ", ".join(f"{q['bonds_per_ball']:.2f}" for q in s[:5])
              + f" | {p['bulk_bonds_per_cm3']:.0f} | "
              + ", ".join(f"{q['bonds_per_cm3']:.0f}" for q in s[:3])
              + " | " + ", ".join(f"{pl[d]['area_fraction']:.3f}" for d in (0.5, 1.0, 1.5, 2.0))
              + f"; {p['bulk_plane_area_fraction']:.3f} ({p['bulk_plane_area_fraction_min']:.3f})"
              + f" | {p['platen_contacts_per_cm2']:.1f} | "
              + ", ".join(f"{q['bonds_per_ball']:.2f}" for q in p["radial"]) + " |")


def fmt_tests(rows):
    print("\n### UCS with and without the end cap\n")
    print("| specimen | ends | sigma_c (MPa) | E (GPa) | nu | cracks at peak / end | crack h "
          "median at peak, end | shares h<0.4 / 0.4-0.6 / >0.6 at peak | ... at end | cracks "
          "within 1 d of a platen at peak, end (bond share) | capped bonds broken | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        for k, t in row["tests"].items():
            w = t["within_1d"]
            brk = f"{t['capped_broken']} / {t['capped_bonds']}" if "capped_bonds" in t else "-"
            print(f"| {row['label']} | {k} | {t['ucs_MPa']:.2f} | {t['E_GPa']:.3f} | "
                  f"{t['nu']:.3f} | {t['cracks_peak']} / {t['cracks_end']} | "
                  f"{t['peak']['median']:.2f}, {t['end']['median']:.2f} | "
                  f"{t['peak']['bottom']:.2f} / {t['peak']['middle']:.2f} / {t['peak']['top']:.2f} | "
                  f"{t['end']['bottom']:.2f} / {t['end']['middle']:.2f} / {t['end']['top']:.2f} | "
                  f"{w['crack_share_peak']:.2f}, {w['crack_share_end']:.2f} ({w['bond_share']:.2f}) | "
                  f"{brk} | {t['cpu_s']:.0f} |")
    caps = [k for k in rows[0]["tests"] if k != "none"]
    for k in caps:
        d = [100 * (r["tests"][k]["ucs_MPa"] / r["tests"]["none"]["ucs_MPa"] - 1) for r in rows]
        e = [100 * (r["tests"][k]["E_GPa"] / r["tests"]["none"]["E_GPa"] - 1) for r in rows]
        print(f"\n{k}: d sigma_c = " + ", ".join(f"{x:+.1f}" for x in d)
              + f" % (mean {np.mean(d):+.2f}, sd {np.std(d, ddof=1) if len(d) > 1 else 0:.2f});"
              " d E = " + ", ".join(f"{x:+.2f}" for x in e) + " %")
    s0 = [r["tests"]["none"]["ucs_MPa"] for r in rows]
    if len(s0) > 1:
        print(f"without cap: sigma_c mean {np.mean(s0):.2f} MPa, CV "
              f"{100 * np.std(s0, ddof=1) / np.mean(s0):.1f} %")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scale", type=float, default=0.4)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6])
    ap.add_argument("--design", default=None)
    ap.add_argument("--samples", nargs="+", default=[])
    ap.add_argument("--cap", type=float, nargs="+", default=[1.0],
                    help="end-cap heights in mean ball diameters (default 1)")
    ap.add_argument("--factor", type=float, default=1000.0,
                    help="strength factor of the capped bonds (default 1000)")
    ap.add_argument("--profile-only", action="store_true")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = []
    c0 = time.process_time()
    for label, params, seed in design_samples(a.design, a.samples, a.seeds, "A1 s{seed}"):
        row = run_specimen(label, params, seed, a.scale, a.cap, a.factor, a.profile_only,
                           a.threads)
        rows.append(row)
        print(f"{label}: genesis {row['genesis_cpu_s']:.0f} CPU s, "
              + ", ".join(f"{k}: {t['ucs_MPa']:.2f} MPa" for k, t in row["tests"].items()),
              file=sys.stderr, flush=True)
        if a.json:
            with open(a.json, "w") as fh:
                json.dump(rows, fh, indent=1, default=float)
    fmt_profile(rows)
    if not a.profile_only:
        fmt_tests(rows)
    print(f"\nCPU s in total: {time.process_time() - c0:.0f}")


if __name__ == "__main__":
    main()
