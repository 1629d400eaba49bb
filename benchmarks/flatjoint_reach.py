"""What flat joints reach: sigma_c/sigma_t and Hoek-Brown m_i of flat-joint cards against
their microstructure, beside the parallel-bond default study's span.

A base flat-joint card (Lac du Bonnet-like, ``BASE``) and one-at-a-time sweeps of its
microstructure: the slit fraction ``fj_slit_frac`` (0, 0.2, 0.4), the installation gap
``fj_gi_ratio`` (0, 0.2, 0.4) and the element count ``fj_nr`` x ``fj_nal`` (1x3, 2x4);
and of its element modulus ``fj_emod_GPa`` (60, 90: E scales with it).
Every card runs, on each packing seed, a UCS test (sigma_c, E, nu), a Brazilian test
(sigma_t = ``bts_MPa``, the mean of the valid discs: an invalid disc gives no sigma_t),
a direct-tension test on the UCS cylinder (sigma_t,d = ``dtt_MPa``, the mean of the valid
runs; Itasca's test of a flat-jointed material's tensile strength, whose Brazilian discs
often fail from the platens) and triaxial tests at sigma3 = 5 and 10 MPa, all with the
study's settings (``config/config.yaml``: sections specimen, ucs, bts, dtt (the schema's
defaults = ``DTTSettings()`` where the config has none; its ``scale`` is not used: the
cylinder is the UCS's), triaxial) at ``--scale``; sigma_c/sigma_t,d is the card's ratio;
the UCS
(sigma3 = 0) and the two triaxial peaks give a Mohr-Coulomb envelope (phi, c) and a
Hoek-Brown envelope (sigma_ci and m_i both fitted, as the study's ``bpmcal envelopes``;
also m_i with sigma_ci = sigma_c), ``bpmcal.analysis.envelopes``. One process, one numba
thread; the CPU seconds of each test are the process's (``time.process_time``).

The parallel-bond span the figure shows as a band is read from the record
``docs/measurements/2026-11-23-brazilian-and-triaxial-a1.md`` (table of the default
study's verified cards B1-B3: sigma_c/sigma_t and m_i), not typed in here.

    python benchmarks/flatjoint_reach.py run --scale 0.4 --seeds 1 [--quick] \\
        [--bts-contact-cap 0] [--budget-min 40] [--reuse OLD.json] \\
        --out benchmarks/results/results_flatjoint_reach.json \\
        --markdown docs/measurements/DATE-flatjoint-reach.md \\
        --figure docs/measurements/DATE-flatjoint-reach.png
    python benchmarks/flatjoint_reach.py markdown RECORD.json [--update] [--note TEXT] \\
        --out docs/measurements/DATE-flatjoint-reach.md \\
        --figure docs/measurements/DATE-flatjoint-reach.png

``--bts-contact-cap 0``: the Brazilian disc without the study's contact caps. A capped
flat-jointed disc need not split: the unbreakable cap wedges keep pressing the cracked
halves together and the load rises to the end of the test (no post-peak drop), so its
"peak" is no tensile strength (the record of 2026-11-26 says what was seen).
``markdown --update`` recomputes every card's figures from its stored runs (after a
change to ``card_result``); ``--note`` keeps a note in the JSON record and the page.

``--quick`` runs three cards (the slit-fraction sweep); ``--cards`` names any subset;
``--budget-min`` starts no further card once the elapsed wall time plus the slowest card
so far would exceed it (the record lists the cards not run); ``--reuse`` takes the cards
an earlier record measured with the same card, seeds, scales and settings instead of
running them again (the record says which); a reused card whose runs lack the
direct-tension test (a record from before it was added), or ran it with other dtt
settings, keeps its other runs and gets only the direct-tension tests. Write ``--out`` to
another file than ``--reuse`` (the JSON is rewritten after every card).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import shlex
import statistics
import sys
import time
from pathlib import Path

from _study import CONFIG, REPO, bts_disc_and_settings, section_settings, study_geometry
from bts_resolution import _config, _meta

#: the base card (a Lac du Bonnet-like granite, written out here in full)
BASE = dict(contact_model="flatjoint", rmin_mm=0.8, porosity=0.30, fj_emod_GPa=60.0,
            fj_kratio=2.0, fj_ten_MPa=10.0, fj_coh_MPa=100.0, fj_fa_deg=30.0, fj_fric=0.6,
            fj_gi_ratio=0.2, fj_slit_frac=0.2, fj_nr=1.0, fj_nal=3.0)

#: the swept variables: name -> (label, values as card overrides, the base's value)
SWEEPS = {
    "fj_slit_frac": ("slit fraction φS", [{"fj_slit_frac": v} for v in (0.0, 0.2, 0.4)]),
    "fj_gi_ratio": ("installation gap gi/R̄", [{"fj_gi_ratio": v} for v in (0.0, 0.2, 0.4)]),
    "elements": ("elements Nr × Nα", [{"fj_nr": 1.0, "fj_nal": 3.0},
                                      {"fj_nr": 2.0, "fj_nal": 4.0}]),
    # E scales with the element modulus (test_flatjoint_lab's scaling test): 90 GPa puts
    # the base card's E (48 GPa at 60) near Lac du Bonnet's 69 GPa
    "fj_emod_GPa": ("element modulus E* (GPa)", [{"fj_emod_GPa": v} for v in (60.0, 90.0)]),
}
#: the cards of ``--quick``: the slit-fraction sweep
QUICK = ("base", "slit0", "slit0.4")
#: confining stresses of the triaxial tests [MPa]
SIGMA3 = (5.0, 10.0)
#: the record with the parallel-bond default study's cards
PB_RECORD = "docs/measurements/2026-11-23-brazilian-and-triaxial-a1.md"


def card_name(over: dict) -> str:
    """A card's short name from its overrides of ``BASE`` (``base`` for none)."""
    diff = {k: v for k, v in over.items() if BASE[k] != v}
    if not diff:
        return "base"
    if "fj_nr" in diff or "fj_nal" in diff:
        o = {**BASE, **over}
        return f"el{int(o['fj_nr'])}x{int(o['fj_nal'])}"
    (k, v), = diff.items()
    return {"fj_slit_frac": "slit", "fj_gi_ratio": "gi", "fj_emod_GPa": "emod"}[k] + f"{v:g}"


def cards() -> dict[str, dict]:
    """Every card of the sweeps by name (the base once, first), as full parameter dicts."""
    out = {"base": dict(BASE)}
    for _, values in SWEEPS.values():
        for over in values:
            out.setdefault(card_name(over), {**BASE, **over})
    return out


def sweep_points(rec_cards: dict) -> dict:
    """Per swept variable: [(x label, card name)] in sweep order."""
    out = {}
    for var, (_, values) in SWEEPS.items():
        pts = []
        for over in values:
            o = {**BASE, **over}
            x = (f"{int(o['fj_nr'])}×{int(o['fj_nal'])}" if var == "elements" else f"{o[var]:g}")
            pts.append((x, card_name(over)))
        out[var] = pts
    return out


def pb_span(path: Path = REPO / PB_RECORD) -> dict:
    """The default study's verified cards (B1-B3) from the record's table: per card
    sigma_c/sigma_t and m_i, and their spans."""
    rows = {}
    for m in re.finditer(r"^\| (B\d) verified \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| [^|]+ \| "
                         r"[^|]+ \| ([\d.]+) ± [\d.]+ \|$", path.read_text(), flags=re.M):
        rows[m.group(1)] = {"sigma_c_MPa": float(m.group(2)), "sigma_t_MPa": float(m.group(3)),
                            "ratio": float(m.group(4)), "mi": float(m.group(5))}
    if len(rows) != 3:
        raise SystemExit(f"{path}: expected the rows of B1-B3 verified, found {sorted(rows)}")
    return {"record": PB_RECORD, "cards": rows,
            "ratio": [min(r["ratio"] for r in rows.values()),
                      max(r["ratio"] for r in rows.values())],
            "mi": [min(r["mi"] for r in rows.values()), max(r["mi"] for r in rows.values())]}


# ------------------------------------------------------------------ the runs
def _settings(cfg: dict, scale: float, bts_scale: float, bts_over: dict):
    from bpmcal.lab.triaxial import TriaxialSettings
    from bpmcal.lab.ucs import UCSSettings

    u = cfg["compression"]
    geo = study_geometry(cfg, scale)
    load = dict(platen_velocity=u["platen_velocity"], damping=u["damping"],
                stop_drop=u["stop_drop"], max_strain=u["max_strain"],
                platen_fric=u["platen_fric"], record_strain=u["record_strain"],
                end_cap=u["end_cap"], end_cap_factor=u["end_cap_factor"])
    ucs = UCSSettings(**load)
    tx = {s3: TriaxialSettings(sigma3=s3 * 1e6, servo_alpha=cfg["triaxial"]["servo_alpha"],
                               **load) for s3 in SIGMA3}
    return (geo, ucs, *bts_disc_and_settings(cfg, bts_scale, **bts_over), tx,
            _dtt_settings(cfg))


def _dtt_settings(cfg: dict):
    """The study's direct-tension settings: the config's ``dtt`` section (validated: the
    schema's defaults filled in), else ``DTTSettings()``; its ``scale`` is not used."""
    from bpmcal.lab.direct_tension import DTTSettings

    return section_settings(cfg, "dtt", DTTSettings)


def _dtt_dict(st) -> dict:
    from bpmcal.lab.direct_tension import settings_dict

    return settings_dict(st)


def _timed(fn, *args, **kw):
    """(summary or None, failure reason or "", CPU seconds) of one lab test."""
    from bpmcal.lab.runner import RUN_FAILURES

    c0 = time.process_time()
    try:
        s, why = fn(*args, **kw).summary, ""
    except RUN_FAILURES as e:
        s, why = None, f"{type(e).__name__}: {e}"
    return s, why, time.process_time() - c0


def run_seed(params: dict, seed: int, setup, cache: str, log) -> dict:
    """The four tests of one card on one packing seed."""
    from bpmcal.lab.runner import bts_test, triaxial_test, ucs_test

    geo, ucs, disc, bts, tx, _ = setup
    kw = dict(cache=cache, threads=1, keep_particles=False)
    out = {"seed": seed}
    s, why, cpu = _timed(ucs_test, params, seed, geo, ucs, **kw)
    out["ucs"] = {"ok": s is not None, "reason": why, "cpu_s": cpu, **({k: s[k] for k in (
        "ucs_MPa", "E_GPa", "nu", "n_balls", "n_bonds", "steps", "stop_reason",
        "cracks_tension", "cracks_shear")} if s else {})}
    log(f"  ucs seed {seed}: " + (f"σc {s['ucs_MPa']:.2f} MPa, E {s['E_GPa']:.2f} GPa, "
                                  f"ν {s['nu']:.3f}" if s else why) + f", CPU {cpu:.0f} s")
    s, why, cpu = _timed(bts_test, params, seed, disc, bts, **kw)
    out["bts"] = {"ok": s is not None, "reason": why, "cpu_s": cpu, **({
        "bts_MPa": s["bts_MPa"], "bts_peak_MPa": s["bts_peak_MPa"],
        "bts_valid": bool(s["bts_valid"]), "invalid_reason": s["bts_invalid_reason"],
        "balls_across": s["balls_across"], "n_balls": s["n_balls"], "steps": s["steps"]}
        if s else {})}
    log(f"  bts seed {seed}: " + (f"peak {s['bts_peak_MPa']:.2f} MPa, valid "
                                  f"{bool(s['bts_valid'])} {s['bts_invalid_reason']}"
                                  if s else why) + f", CPU {cpu:.0f} s")
    out["triaxial"] = {}
    for s3, st in tx.items():
        s, why, cpu = _timed(triaxial_test, params, seed, geo, st, **kw)
        out["triaxial"][f"{s3:g}"] = {"ok": s is not None, "reason": why, "cpu_s": cpu, **({
            "sigma3_MPa": s3, "sigma1_MPa": s["sigma1_MPa"], "E_GPa": s["E_GPa"],
            "nu": s["nu"], "steps": s["steps"], "stop_reason": s["stop_reason"],
            "sigma3_maxdev_rel": s["sigma3_maxdev_rel"]} if s else {})}
        log(f"  triaxial σ3 {s3:g} seed {seed}: "
            + (f"σ1 {s['sigma1_MPa']:.2f} MPa" if s else why) + f", CPU {cpu:.0f} s")
    out["dtt"] = run_dtt(params, seed, setup, cache, log)
    return out


def run_dtt(params: dict, seed: int, setup, cache: str, log) -> dict:
    """The direct-tension test of one card on one packing seed (the UCS cylinder)."""
    from bpmcal.lab.runner import dtt_test

    geo, dtt = setup[0], setup[5]
    s, why, cpu = _timed(dtt_test, params, seed, geo, dtt, cache=cache, threads=1,
                         keep_particles=False)
    log(f"  dtt seed {seed}: " + (f"peak {s['dtt_peak_MPa']:.2f} MPa, valid "
                                  f"{bool(s['dtt_valid'])} {s['dtt_invalid_reason']}"
                                  if s else why) + f", CPU {cpu:.0f} s")
    return {"ok": s is not None, "reason": why, "cpu_s": cpu, **({
        "dtt_MPa": s["dtt_MPa"], "dtt_peak_MPa": s["dtt_peak_MPa"],
        "dtt_valid": bool(s["dtt_valid"]), "invalid_reason": s["dtt_invalid_reason"],
        "E_t_GPa": s.get("E_t_GPa", math.nan), "fracture_height": s["fracture_height"],
        "balls_across": s["balls_across"], "n_balls": s["n_balls"], "steps": s["steps"],
        "stop_reason": s["stop_reason"], "cracks_tension": s["cracks_tension"],
        "cracks_shear": s["cracks_shear"]} if s else {})}


def _mean(v):
    v = [x for x in v if x is not None and math.isfinite(x)]
    return statistics.fmean(v) if v else math.nan


def card_result(runs: list[dict]) -> dict:
    """A card's figures from its seeds' runs: means, sigma_t over the valid discs, the
    envelopes through (0, sigma_c) and the triaxial means."""
    from bpmcal.analysis.envelopes import EnvelopeError, fit_hoek_brown, fit_mohr_coulomb

    u = [r["ucs"] for r in runs if r["ucs"]["ok"]]
    b = [r["bts"] for r in runs if r["bts"]["ok"]]
    bv = [x for x in b if x["bts_valid"]]
    d = [r["dtt"] for r in runs if r.get("dtt", {}).get("ok")]
    dv = [x for x in d if x["dtt_valid"]]
    out = {"sigma_c_MPa": _mean([x["ucs_MPa"] for x in u]), "E_GPa": _mean([x["E_GPa"] for x in u]),
           "nu": _mean([x["nu"] for x in u]),
           "sigma_t_MPa": _mean([x["bts_MPa"] for x in bv]),
           "bts_peak_all_MPa": _mean([x["bts_peak_MPa"] for x in b]),
           "bts_valid": f"{len(bv)}/{len(runs)}",
           "dtt_MPa": _mean([x["dtt_MPa"] for x in dv]),
           "dtt_peak_all_MPa": _mean([x["dtt_peak_MPa"] for x in d]),
           "dtt_valid": (f"{len(dv)}/{len(runs)}" if all("dtt" in r for r in runs)
                         else "not run"),
           "cpu_s": sum(r["ucs"]["cpu_s"] + r["bts"]["cpu_s"] + r.get("dtt", {}).get("cpu_s", 0)
                        + sum(t["cpu_s"] for t in r["triaxial"].values()) for r in runs)}
    out["ratio"] = out["sigma_c_MPa"] / out["sigma_t_MPa"]
    out["ratio_peak"] = out["sigma_c_MPa"] / out["bts_peak_all_MPa"]
    out["ratio_dtt"] = out["sigma_c_MPa"] / out["dtt_MPa"]
    out["ratio_dtt_peak"] = out["sigma_c_MPa"] / out["dtt_peak_all_MPa"]
    s1 = {s3: _mean([r["triaxial"][f"{s3:g}"].get("sigma1_MPa") for r in runs
                     if r["triaxial"][f"{s3:g}"]["ok"]]) for s3 in SIGMA3}
    out["sigma1_MPa"] = {f"{k:g}": v for k, v in s1.items()}
    pts = [(0.0, out["sigma_c_MPa"])] + [(k, v) for k, v in s1.items()]
    pts = [(a, c) for a, c in pts if math.isfinite(c)]
    x, y = [p[0] for p in pts], [p[1] for p in pts]
    out["envelope_points"] = len(pts)
    for key, fit in (("mc", lambda: fit_mohr_coulomb(x, y)), ("hb", lambda: fit_hoek_brown(x, y)),
                     ("hb_fixed", lambda: fit_hoek_brown(x, y, sigma_ci=out["sigma_c_MPa"]))):
        try:
            out[key] = fit().to_dict()
        except (EnvelopeError, ValueError) as e:
            out[key] = {"error": str(e)}
    out["phi_deg"] = out["mc"].get("phi_deg", math.nan)
    out["c_MPa"] = out["mc"].get("c", math.nan)
    out["mi"] = out["hb"].get("mi", math.nan)
    out["mi_fixed"] = out["hb_fixed"].get("mi", math.nan)
    return out


def _same_setup(old: dict, rec: dict) -> bool:
    """The same cylinder, disc, seeds and settings of the UCS, Brazilian and triaxial
    tests (the direct-tension settings are checked per card: ``_needs_dtt``)."""
    import copy

    renamed = {"ucs": "compression", "servo_gain": "servo_alpha"}  # keys of older records

    def other(s):
        s = {renamed.get(k, k): v for k, v in copy.deepcopy(s or {}).items()}
        for part in s.values():
            for o, n in (("post_peak_min", "post_peak_strain"), ("servo_gain", "servo_alpha")):
                if isinstance(part, dict) and o in part:
                    part[n] = part.pop(o)
        return {k: v for k, v in s.items() if k != "dtt"}
    return (all(old.get(k) == rec.get(k) for k in ("scale", "bts_scale", "seeds"))
            and other(old.get("settings")) == other(rec.get("settings")))


def _servo_alpha(settings: dict) -> float:
    """The triaxial servo's relaxation factor of a record's settings (``servo_gain`` in
    the records before the config key was renamed ``servo_alpha``)."""
    return settings["servo_alpha"] if "servo_alpha" in settings else settings["servo_gain"]


def _needs_dtt(card: dict, dtt_settings: dict) -> bool:
    """A reused card to run the direct-tension tests of: none yet, or other settings."""
    return (any("dtt" not in r for r in card["runs"])
            or card.get("dtt_settings") != dtt_settings)


def run(a, argv) -> dict:
    cfg = _config(a.config)
    bts_scale = a.bts_scale if a.bts_scale is not None else (cfg["bts"]["scale"] or a.scale)
    seeds = list(range(1, a.seeds + 1))
    allc = cards()
    names = list(QUICK) if a.quick else (a.cards.split(",") if a.cards else list(allc))
    bad = [n for n in names if n not in allc]
    if bad:
        raise SystemExit(f"--cards: unknown {bad}; expected some of {list(allc)}")
    from bpmcal.dem._jit import set_threads

    set_threads(1)
    bts_over = {} if a.bts_contact_cap is None else {"contact_cap": a.bts_contact_cap}
    setup = _settings(cfg, a.scale, bts_scale, bts_over)
    rec = {**_meta(argv), "command": "python benchmarks/flatjoint_reach.py " + shlex.join(argv),
           "config": str(a.config), "scale": a.scale, "bts_scale": bts_scale, "seeds": seeds,
           "sigma3_MPa": list(SIGMA3), "threads": 1, "nice": os.nice(0),
           "settings": {"specimen": cfg["specimen"], "ucs": cfg["compression"],
                        "bts": {**cfg["bts"], **bts_over}, "bts_overrides": bts_over,
                        "servo_alpha": cfg["triaxial"]["servo_alpha"],
                        "dtt": _dtt_dict(setup[5])},
           "base": BASE, "sweeps": {k: [v[0], v[1]] for k, v in SWEEPS.items()},
           "pb_span": pb_span(), "requested": names, "cards": {}, "not_run": [],
           "reused_from": None, "complete": False}
    old = {}
    if a.reuse:
        o = json.loads(Path(a.reuse).read_text())
        if _same_setup(o, rec):
            old = o["cards"]
            rec["reused_from"] = {"file": str(a.reuse), "commit": o["commit"], "date": o["date"]}
        else:
            print(f"--reuse {a.reuse}: other scale, seeds or settings; nothing reused",
                  flush=True)
    t0 = time.time()
    slowest = slowest_dtt = 0.0
    dtt_set = rec["settings"]["dtt"]

    def log(msg):
        print(f"[{(time.time() - t0) / 60:5.1f} min] {msg}", flush=True)

    with __import__("tempfile").TemporaryDirectory() as tmp:
        for name in names:
            params = allc[name]
            el = time.time() - t0
            if name in old and old[name]["params"] == params:
                card = {**old[name], "reused": True}
                if not _needs_dtt(card, dtt_set):
                    rec["cards"][name] = card
                    log(f"{name}: reused from {a.reuse}")
                    continue
                if a.budget_min and el + slowest_dtt > 60 * a.budget_min:
                    card.update(card_result(card["runs"]))  # kept, without the DTT
                    rec["cards"][name] = card
                    rec["dtt_not_run"] = rec.get("dtt_not_run", []) + [name]
                    log(f"{name}: reused without its direct-tension tests (elapsed "
                        f"{el / 60:.1f} min > budget {a.budget_min:g} min)")
                    continue
                log(f"{name}: reused from {a.reuse}; adding the direct-tension tests")
                w0 = time.time()
                runs = [{**r, "dtt": run_dtt(params, r["seed"], setup,
                                             str(Path(tmp) / "cache"), log)}
                        for r in card["runs"]]
                wall = time.time() - w0
                slowest_dtt = max(slowest_dtt, wall)
                # a full card: its old runs' wall time plus the direct-tension tests
                slowest = max(slowest, card.get("wall_s", 0.0) + wall)
                card.update(card_result(runs))
                card.update({"runs": runs, "dtt_added": True, "dtt_wall_s": wall,
                             "dtt_settings": dtt_set, "load_average_end": os.getloadavg()})
                rec["cards"][name] = card
                log(f"{name}: σt,d {card['dtt_MPa']:.2f} (valid {card['dtt_valid']}, peak "
                    f"{card['dtt_peak_all_MPa']:.2f}), σc/σt,d {card['ratio_dtt']:.2f}, "
                    f"wall {wall:.0f} s")
                rec["load_average_end"] = os.getloadavg()
                rec["wall_s"] = time.time() - t0
                if a.out:
                    Path(a.out).write_text(json.dumps(rec, indent=1, default=float) + "\n")
                continue
            if a.budget_min and el + slowest > 60 * a.budget_min:
                rec["not_run"].append(name)
                log(f"{name}: not run (elapsed {el / 60:.1f} min + slowest card "
                    f"{slowest / 60:.1f} min > budget {a.budget_min:g} min)")
                continue
            log(f"{name}: {params}")
            w0 = time.time()
            runs = [run_seed(params, s, setup, str(Path(tmp) / "cache"), log) for s in seeds]
            try:
                res = card_result(runs)
            except Exception as e:  # keep the runs: the figures can be recomputed
                if a.out:
                    Path(a.out + ".runs").write_text(json.dumps(runs, default=float))
                raise SystemExit(f"{name}: {type(e).__name__}: {e}") from e
            wall = time.time() - w0
            slowest = max(slowest, wall)
            rec["cards"][name] = {"params": params, "reused": False, "wall_s": wall,
                                  "load_average_end": os.getloadavg(), "dtt_settings": dtt_set,
                                  **res, "runs": runs}
            log(f"{name}: σc {res['sigma_c_MPa']:.1f}, σt {res['sigma_t_MPa']:.2f} "
                f"(valid {res['bts_valid']}), σt,d {res['dtt_MPa']:.2f} (valid "
                f"{res['dtt_valid']}), σc/σt,d {res['ratio_dtt']:.2f}, φ {res['phi_deg']:.1f}, "
                f"mi {res['mi']:.2f}, CPU {res['cpu_s']:.0f} s, wall {wall:.0f} s")
            rec["load_average_end"] = os.getloadavg()
            rec["wall_s"] = time.time() - t0
            if a.out:
                Path(a.out).write_text(json.dumps(rec, indent=1, default=float) + "\n")
    rec["complete"] = True
    rec["load_average_end"] = os.getloadavg()
    rec["wall_s"] = time.time() - t0
    return rec


# ------------------------------------------------------------------ the outputs
def _f(x, fmt):
    return "–" if x is None or not math.isfinite(x) else format(x, fmt)


def _reused(c: dict) -> str:
    if not c.get("reused"):
        return ""
    return " (reused, DTT added)" if c.get("dtt_added") else " (reused)"


def markdown(rec: dict, figure: str | None = None,
             raw: str = "benchmarks/results/results_flatjoint_reach.json") -> str:
    """The measurement record (docs/measurements) from the JSON record (``raw``: its
    path, as the page names it)."""
    pb = rec["pb_span"]
    stem = Path(figure).name if figure else None
    la = ", ".join(f"{x:.2f}" for x in rec["load_average_start"])
    lb = ", ".join(f"{x:.2f}" for x in rec.get("load_average_end", [math.nan] * 3))
    dtt = rec["settings"].get("dtt")
    lines = [f"# What flat joints reach: σc/σt and mi against the microstructure ({rec['date']})",
             "", "| | |", "|---|---|", f"| date | {rec['date']} |",
             f"| commit | {rec['commit']} ('+dirty': uncommitted changes under src/) |",
             f"| host | {rec['cpu_model']} ({rec['cpus']} CPUs) |",
             f"| load | load average at the start {la}, at the end {lb} |",
             f"| command | `{rec['command']}` |",
             f"| raw | `{raw}` |", "",
             "Generated by `python benchmarks/flatjoint_reach.py markdown` from the JSON record.",
             "",
             f"One process, {rec['threads']} numba thread, niceness {rec['nice']}; cylinder "
             f"at scale {rec['scale']:g} ({50 * rec['scale']:g} × {100 * rec['scale']:g} mm), "
             f"Brazilian disc at scale {rec['bts_scale']:g}, packing seeds "
             f"{', '.join(map(str, rec['seeds']))}; the study's settings "
             f"(`{Path(rec['config']).name}`: specimen, ucs, bts, triaxial servo alpha "
             f"{_servo_alpha(rec['settings']):g}"
             + (", dtt: " + ", ".join(f"{k} {v}" for k, v in dtt.items()) if dtt else "")
             + "). Per card: a UCS test (σc, E, ν), a "
             "Brazilian test (σt: the mean of the valid discs; an invalid disc gives no σt, "
             "its peak is in the JSON), a direct-tension test on the UCS cylinder (σt,d: the "
             "mean of the valid runs; Itasca's test of a flat-jointed material's tensile "
             "strength) and triaxial tests at σ3 = "
             f"{' and '.join(f'{s:g}' for s in rec['sigma3_MPa'])} MPa. The card's ratio is "
             "σc/σt,d; σc/σt (Brazilian) and, in brackets, σc over the Brazilian peak of an "
             "invalid disc are shown beside it. The envelopes go "
             "through (0, σc) and the triaxial peaks: Mohr–Coulomb φ, Hoek–Brown mi with σci "
             "fitted too (as `bpmcal envelopes`) and, in brackets, mi with σci = σc. CPU: the "
             "process's CPU seconds of the card's tests, genesis included.", "",
             "Base card: " + ", ".join(f"`{k}` {v:g}" if not isinstance(v, str) else f"`{k}` {v}"
                                       for k, v in rec["base"].items()) + ".", "",
             "| card | swept | σc (MPa) | E (GPa) | ν | σt,d (MPa) | DTT valid | σc/σt,d | "
             "σt (MPa) | Brazilian valid | Brazilian peak (MPa) | σc/σt (σc/peak) | φ (°) | "
             "mi (σci = σc) | σ1 at σ3 = "
             + " / ".join(f"{s:g}" for s in rec["sigma3_MPa"]) + " (MPa) | CPU s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, c in rec["cards"].items():
        p = c["params"]
        diff = [f"{k} {p[k]:g}" for k in p if k != "contact_model" and p[k] != rec["base"][k]]
        s1 = " / ".join(_f(c["sigma1_MPa"][f"{s:g}"], ".1f") for s in rec["sigma3_MPa"])
        lines.append(
            f"| {name}{_reused(c)} | {', '.join(diff) or 'base'} | "
            f"{_f(c['sigma_c_MPa'], '.1f')} | {_f(c['E_GPa'], '.1f')} | {_f(c['nu'], '.3f')} | "
            f"{_f(c.get('dtt_MPa', math.nan), '.2f')} | {c.get('dtt_valid', 'not run')} | "
            f"{_f(c.get('ratio_dtt', math.nan), '.1f')} | "
            f"{_f(c['sigma_t_MPa'], '.2f')} | {c['bts_valid']} | "
            f"{_f(c['bts_peak_all_MPa'], '.2f')} | {_f(c['ratio'], '.1f')} "
            f"({_f(c['ratio_peak'], '.1f')}) | "
            f"{_f(c['phi_deg'], '.1f')} | {_f(c['mi'], '.2f')} ({_f(c['mi_fixed'], '.2f')}) | "
            f"{s1} | {c['cpu_s']:.0f} |")
    lines.append("")
    rows = pb["cards"]
    each = ", ".join(f"{k} σc/σt {v['ratio']:g}, mi {v['mi']:g}" for k, v in rows.items())
    lines += [f"The parallel-bond span (the band in the figure): the default study's verified "
              f"cards in [{Path(pb['record']).name}]({Path(pb['record']).name}) "
              f"({each}): "
              f"σc/σt {pb['ratio'][0]:g}–{pb['ratio'][1]:g}, mi {pb['mi'][0]:g}–{pb['mi'][1]:g} "
              "(there mi is fitted with σci through σ3 = 0, 5, 10 and 20 MPa, and σt came from "
              "the Brazilian settings of that date).", ""]
    if stem:
        lines += [f"![σc/σt,d and mi against each swept variable]({stem})", ""]
    notes = []
    for name, c in rec["cards"].items():
        for r in c["runs"]:
            for t, x in [("UCS", r["ucs"]), ("Brazilian", r["bts"])] + [
                    (f"triaxial σ3 = {k}", v) for k, v in r["triaxial"].items()] + (
                    [("direct tension", r["dtt"])] if "dtt" in r else []):
                if not x["ok"]:
                    notes.append(f"{name}, seed {r['seed']}, {t}: failed ({x['reason']})")
            d = r.get("dtt")
            if d and d["ok"] and not d["dtt_valid"]:
                notes.append(f"{name}, seed {r['seed']}: direct-tension run invalid "
                             f"({d['invalid_reason']}; peak {d['dtt_peak_MPa']:.2f} MPa)")
            b = r["bts"]
            if b["ok"] and not b["bts_valid"]:
                notes.append(f"{name}, seed {r['seed']}: Brazilian disc invalid "
                             f"({b['invalid_reason']}; peak {b['bts_peak_MPa']:.2f} MPa)")
        for key in ("mc", "hb", "hb_fixed"):
            if "error" in c[key]:
                notes.append(f"{name}: no {key} envelope ({c[key]['error']})")
    if rec.get("reused_from"):
        r = rec["reused_from"]
        notes.append(f"cards marked (reused) were measured by an earlier run of this benchmark "
                     f"({r['date']}, commit {r['commit']}) with the same cards, seeds, scales "
                     "and settings, and taken from its record; (reused, DTT added): its UCS, "
                     "Brazilian and triaxial runs taken from there, the direct-tension tests "
                     "run by this run")
    if rec.get("dtt_not_run"):
        notes.append("reused without the direct-tension tests (the wall-time budget): "
                     + ", ".join(rec["dtt_not_run"]))
    if rec["not_run"]:
        notes.append("not run (the wall-time budget): " + ", ".join(rec["not_run"]))
    if not rec.get("complete", True):
        notes.append("the run did not finish: the record holds the cards done")
    notes += rec.get("notes", [])
    if notes:
        lines += ["Notes:", ""] + [f"- {n}" for n in notes] + [""]
    return "\n".join(lines)


def figure(rec: dict, path: str) -> None:
    """σc/σt,d and mi (rows) against each swept variable (columns), the parallel-bond span
    (σc/σt from Brazilian tests) as a band; σc over the Brazilian peak, open, only where a
    card has no valid direct-tension run."""
    from bpmcal.plots.style import C_ALT, C_SIM, DOUBLE
    from bpmcal.plots.style import figure as new_figure

    pb = rec["pb_span"]
    fig, axes = new_figure(DOUBLE, 3.6, nrows=2, ncols=len(SWEEPS), sharey="row")
    pts = sweep_points(rec["cards"])
    for j, (var, (label, _)) in enumerate(rec["sweeps"].items()):
        for i, (key, band, ylab) in enumerate((("ratio_dtt", pb["ratio"],
                                                r"$\sigma_c/\sigma_{t,d}$"),
                                               ("mi", pb["mi"], r"Hoek–Brown $m_i$"))):
            ax = axes[i, j]
            ax.axhspan(band[0], band[1], color="0.8", lw=0,
                       label="parallel bond, default study B1–B3 (σc/σt Brazilian)")
            xs = list(range(len(pts[var])))
            ys = [rec["cards"].get(n, {}).get(key, math.nan) for _, n in pts[var]]
            ax.plot(xs, ys, "o-", color=C_SIM,
                    label="flat joint, " + ("σc/σt,d (direct tension)" if i == 0
                                                  else "mi (σci fitted)"))
            if key == "ratio_dtt":  # no valid DTT: sigma_c over the Brazilian peak, open
                yp = [math.nan if math.isfinite(y) else
                      rec["cards"].get(n, {}).get("ratio_peak", math.nan)
                      for y, (_, n) in zip(ys, pts[var])]
                ax.plot(xs, yp, "o", color=C_SIM, mfc="none",
                        label="flat joint, σc / Brazilian peak (no valid direct-tension run)")
            if key == "mi":
                yf = [rec["cards"].get(n, {}).get("mi_fixed", math.nan) for _, n in pts[var]]
                ax.plot(xs, yf, "s--", color=C_ALT, mfc="none",
                        label=r"flat joint, $\sigma_{ci}=\sigma_c$")
            ax.set_xticks(xs, [x for x, _ in pts[var]])
            ax.set_xlim(-0.4, len(xs) - 0.6)
            if i == 1:
                ax.set_xlabel(label)
            if j == 0:
                ax.set_ylabel(ylab)
    seen = {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    fig.legend(list(seen.values()), list(seen), loc="lower center", ncol=2, frameon=False)
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    fig.savefig(path, bbox_inches="tight")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="part", required=True)
    r = sub.add_parser("run")
    r.add_argument("--scale", type=float, default=0.4)
    r.add_argument("--bts-scale", type=float, default=None,
                   help="the Brazilian disc's scale (default: the config's bts.scale)")
    r.add_argument("--bts-contact-cap", type=float, default=None,
                   help="the Brazilian test's contact caps (default: the config's bts."
                        "contact_cap; 0: none)")
    r.add_argument("--seeds", type=int, default=1, help="packing seeds 1..N")
    r.add_argument("--quick", action="store_true", help=f"only the cards {', '.join(QUICK)}")
    r.add_argument("--cards", default=None, help=f"a subset of {', '.join(cards())}")
    r.add_argument("--budget-min", type=float, default=None)
    r.add_argument("--reuse", default=None, help="an earlier JSON record to take cards from")
    r.add_argument("--config", default=str(CONFIG))
    r.add_argument("--out", default=None, help="the JSON record")
    r.add_argument("--markdown", default=None)
    r.add_argument("--figure", default=None)
    m = sub.add_parser("markdown")
    m.add_argument("record")
    m.add_argument("--out", default=None)
    m.add_argument("--figure", default=None, help="also draw the figure here (PNG)")
    m.add_argument("--note", action="append", default=[],
                   help="a note to keep in the record (written into the JSON)")
    m.add_argument("--update", action="store_true",
                   help="recompute every card's figures from its runs and rewrite the JSON")
    a = ap.parse_args(argv)
    if a.part == "run":
        rec = run(a, argv)
        if a.out:
            Path(a.out).write_text(json.dumps(rec, indent=1, default=float) + "\n")
    else:
        rec = json.loads(Path(a.record).read_text())
        if a.update or a.note:
            for c in rec["cards"].values():
                c.update(card_result(c["runs"]))
            rec["notes"] = rec.get("notes", []) + a.note
            Path(a.record).write_text(json.dumps(rec, indent=1, default=float) + "\n")
    fig = a.figure
    if fig:
        figure(rec, fig)
    raw = a.out if a.part == "run" else a.record
    text = markdown(rec, fig, **({"raw": raw} if raw else {}))
    md = a.markdown if a.part == "run" else a.out
    if md:
        Path(md).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
