"""sigma_t of a Brazilian disc against its resolution, and the loading that makes a valid
test the rule: the measurement record behind the study's ``bts`` settings.

Three parts, each a JSON record (date, commit, CPU model, load average, the command):

- ``curve``: the paper's A1 card on discs of ``--scales`` (the ISRM 50 x 25 mm disc x
  scale) and packing ``--seeds``, with the config's ``bts`` settings: per size the balls
  across the diameter (D / mean ball diameter), sigma_t (mean of the valid runs), its seed
  CV, the valid fraction and the CPU time of a run (the disc's packing included, as in the
  study, where every sample packs its own disc).
- ``loadings``: the config's disc size under every loading variant (flat platens or
  ISRM jaws, with and without contact caps): A1 on ``--a1-seeds`` (valid fraction and
  sigma_t seed CV) and ``--design-samples`` design samples of the config (valid fraction,
  how far the caps move sigma_t).
- ``dtt``: the direct-tension test of A1 on the UCS cylinder (the config's ``dtt``
  settings), its sigma_t, seed CV and cost, for comparison.
- ``cards``: sigma_t of each card file of ``--cards`` (a study's calibrated or verified
  cards: the parameters the card stands for) and of A1, on packing ``--seeds``, with the
  config's ``bts`` settings: valid fraction, mean and seed CV per card. With
  ``--specimens N`` each seed is measured as the study's closed loop and fresh-seed check
  measure it (``stages.measure.seed_strength``: N discs on packings seed + j x the
  replicate stride,
  an invalid disc replaced), and the seed CV is given for a seed's sigma_t as the mean of
  its first k = 1 .. N discs (``verification.tensile_specimens`` = k).

    python benchmarks/bts_resolution.py curve --scales 0.4,0.55,0.7,0.85,1.0 \\
        --seeds 1,2,3,4,5 --out benchmarks/results/results_bts_resolution_DATE.json
    python benchmarks/bts_resolution.py loadings --a1-seeds 1,...,10 \\
        --design-samples 12 --out benchmarks/results/results_bts_loadings_DATE.json
    python benchmarks/bts_resolution.py dtt --seeds 1,...,8 \\
        --out benchmarks/results/results_bts_dtt_DATE.json
    python benchmarks/bts_resolution.py cards --cards results/verification/B1/card.yaml,... \
        --seeds 1,...,5 --out benchmarks/results/results_bts_cards_DATE.json
    python benchmarks/bts_resolution.py markdown RECORD.json [RECORD.json ...] \\
        --out docs/measurements/DATE-bts-resolution.md

Runs go two at a time (``--jobs``, one numba thread each).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import yaml
from _study import (
    CONFIG,
    REPO,
    bts_disc_and_settings,
    run_meta,
    section_settings,
    study_design,
    study_geometry,
)

# the σt seed CV a card must meet over 5 seeds (issue 24), the chance of missing it that
# the choice of ``verification.tensile_specimens`` accepts: the closed loop's own rule
from bpmcal.analysis.calibration.specimens import CV_TARGET, MISS_ACCEPTED, N_CHECK, expected_cv
from bpmcal.stages.measure import TENSILE_REPLICATE_STRIDE
from bpmcal.study.paper import A1

#: loading variants of the ``loadings`` part: name -> BTSSettings overrides
VARIANTS = {
    "flat, caps": {"loading": "flat"},
    "flat, no caps": {"loading": "flat", "contact_cap": 0.0},
    "jaws, caps": {"loading": "jaws"},
    "jaws, no caps": {"loading": "jaws", "contact_cap": 0.0},
    "flat, caps 2": {"loading": "flat", "contact_cap": 2.0},
    "flat, caps 2.5": {"loading": "flat", "contact_cap": 2.5},
    "jaws, caps 2": {"loading": "jaws", "contact_cap": 2.0},
}
#: the variants the ``loadings`` part runs unless ``--variants`` names others
DEFAULT_VARIANTS = ("flat, caps", "flat, no caps", "jaws, caps", "jaws, no caps")


def _run(job):
    """One disc: (label, params, seed, scale, overrides, cache) -> its summary numbers."""
    label, params, seed, scale, over, cache, cfg = job
    from bpmcal.lab.runner import bts_test

    disc, st = bts_disc_and_settings(cfg, scale, **over)
    c0 = time.process_time()
    r = bts_test(params, seed, disc, st, cache=cache, threads=1, keep_particles=False)
    s = r.summary
    return {"label": label, "seed": seed, "scale": scale, "variant": over,
            "cpu_s": time.process_time() - c0, "genesis_s": s["genesis_s"],
            "test_s": s["test_s"], "n_balls": s["n_balls"],
            "balls_across": s["balls_across"], "bts_valid": bool(s["bts_valid"]),
            "bts_peak_MPa": s["bts_peak_MPa"], "bts_MPa": s["bts_MPa"],
            "init_offset": s["init_offset"], "reason": s["bts_invalid_reason"],
            "steps": s["steps"], "contact_events": s["contact_events"]}


def _run_seed(job):
    """One packing seed measured as the study measures it: (label, params, seed, N,
    cache, cfg) -> its N discs' sigma_t (each valid, or replaced as the study replaces an
    invalid disc; NaN when no replacement was valid) and the CPU time of them all."""
    label, params, seed, n, cache, cfg = job
    from bpmcal.stages.measure import seed_strength

    disc, st = bts_disc_and_settings(cfg)
    c0 = time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        b, _, invalid, _, values = seed_strength(
            "bts_MPa", lambda j, s, k: Path(tmp) / f"{j}_{s}_{k}.h5", params, seed, disc, st,
            specimens=n, cache=cache, threads=1, keep_particles=False)
    return {"label": label, "seed": seed, "specimens": n, "status": b.status,
            "values_MPa": [float(v) for v in values], "invalid": invalid,
            "cpu_s": time.process_time() - c0}


def _k_means(values, k: int) -> list[float]:
    """A seed's sigma_t as the mean of its first k discs, for each seed's disc values in
    ``values`` whose first k were all measured (NaN: a disc with no valid test)."""
    return [statistics.fmean(v[:k]) for v in values
            if len(v) >= k and all(x == x for x in v[:k])]


def _stats_k(rows, n):
    """Per k = 1 .. n: a seed's sigma_t as the mean of its first k discs, its mean and
    seed CV over the seeds where all k were measured."""
    out = {}
    for k in range(1, n + 1):
        v = _k_means([r["values_MPa"] for r in rows], k)
        mean = statistics.fmean(v) if v else float("nan")
        out[str(k)] = {"seeds": len(v), "sigma_t_mean_MPa": mean,
                       "seed_cv": statistics.stdev(v) / mean if len(v) > 1 else float("nan")}
    return {"k": out, "n_seeds": len(rows),
            "invalid_discs": sum(len(r["invalid"]) for r in rows),
            "cpu_s_per_seed_median": statistics.median(r["cpu_s"] for r in rows)}


def _run_dtt(job):
    """One direct-tension test: (params, seed, scale, cfg) -> its summary numbers."""
    params, seed, scale, cfg, cache = job
    from bpmcal.lab.direct_tension import DTTSettings
    from bpmcal.lab.runner import dtt_test

    st = section_settings(cfg, "dtt", DTTSettings)
    geo = study_geometry(cfg, scale)
    c0 = time.process_time()
    s = dtt_test(params, seed, geo, st, cache=cache, threads=1, keep_particles=False).summary
    r = {"label": "A1", "seed": seed, "scale": scale, "variant": "dtt",
         "cpu_s": time.process_time() - c0, "n_balls": s["n_balls"],
         "balls_across": s["balls_across"], "bts_valid": bool(s["dtt_valid"]),
         "bts_peak_MPa": s["dtt_peak_MPa"], "bts_MPa": s["dtt_MPa"],
         "fracture_height": s["fracture_height"], "reason": s["dtt_invalid_reason"],
         "E_t_GPa": s["E_t_GPa"], "steps": s["steps"]}
    print(f"A1 dtt scale {scale:g} seed {seed}: {r['bts_peak_MPa']:.3f} MPa, valid "
          f"{r['bts_valid']}, CPU {r['cpu_s']:.1f} s", flush=True)
    return r


def dtt(a, argv) -> dict:
    cfg = _config(a.config)
    meta = run_meta("bts_resolution.py", argv)
    scale = cfg["dtt"]["scale"] or cfg["specimen"]["scale"]
    seeds = [int(x) for x in a.seeds.split(",")]
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(max_workers=a.jobs) as ex:
        rows = list(ex.map(_run_dtt, [(dict(A1), s, scale, cfg, str(Path(tmp) / "c"))
                                      for s in seeds]))
    return {**meta, "part": "dtt", "config": str(a.config), "dtt": cfg["dtt"], "scale": scale,
            "load_average_end": os.getloadavg(), "stats": _stats(rows), "runs": rows}


def _disc_line(r) -> str:
    return (f"{r['label']} scale {r['scale']:g} seed {r['seed']} {r['variant']}: "
            f"{r['bts_peak_MPa']:.3f} MPa, valid {r['bts_valid']}, "
            f"{r['balls_across']:.1f} across, CPU {r['cpu_s']:.1f} s")


def _seed_line(r) -> str:
    return (f"{r['label']} seed {r['seed']}: "
            f"{', '.join(f'{v:.3f}' for v in r['values_MPa'])} MPa, "
            f"{len(r['invalid'])} invalid, CPU {r['cpu_s']:.1f} s")


def _pool(jobs, n, run=_run, line=_disc_line):
    """``run`` over ``jobs`` on ``n`` processes, printing ``line`` of each result."""
    with ProcessPoolExecutor(max_workers=n) as ex:
        out = []
        for r in ex.map(run, jobs):
            print(line(r), flush=True)
            out.append(r)
        return out


def _stats(rows):
    v = [r["bts_MPa"] for r in rows if r["bts_valid"]]
    mean = statistics.fmean(v) if v else float("nan")
    cv = statistics.stdev(v) / mean if len(v) > 1 else float("nan")
    return {"n": len(rows), "n_valid": len(v), "valid_fraction": len(v) / len(rows),
            "sigma_t_mean_MPa": mean, "seed_cv": cv,
            "peak_mean_all_MPa": statistics.fmean(r["bts_peak_MPa"] for r in rows),
            "balls_across": statistics.fmean(r["balls_across"] for r in rows),
            "n_balls": statistics.fmean(r["n_balls"] for r in rows),
            "cpu_s_median": statistics.median(r["cpu_s"] for r in rows)}


def _config(path) -> dict:
    """The config, validated (the schema's defaults filled in), as the workflow reads it."""
    from bpmcal.study.config import validate_config

    cfg = yaml.safe_load(Path(path).read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    return cfg


def curve(a, argv) -> dict:
    cfg = _config(a.config)
    meta = run_meta("bts_resolution.py", argv)
    scales = [float(x) for x in a.scales.split(",")]
    seeds = [int(x) for x in a.seeds.split(",")]
    name, prm = "A1", dict(A1)
    if a.card:  # another card's curve (a verified or planted card file)
        from bpmcal import params as P
        from bpmcal.io.card import card_parameters

        card = yaml.safe_load(Path(a.card).read_text())
        name = f"{card.get('specimen', Path(a.card).stem)} ({Path(a.card).name})"
        prm = {k: float(card_parameters(card)[k]) for k in P.PARAMS}
    with tempfile.TemporaryDirectory() as tmp:
        jobs = [(name, prm, s, sc, {}, str(Path(tmp) / f"c{sc}"), cfg)
                for sc in scales for s in seeds]
        rows = _pool(jobs, a.jobs)
    per = {}
    for sc in scales:
        per[f"{sc:g}"] = {"scale": sc, "diameter_mm": cfg["bts"]["diameter_mm"] * sc,
                          **_stats([r for r in rows if r["scale"] == sc])}
    return {**meta, "part": "curve", "config": str(a.config), "bts": cfg["bts"],
            **({"card": name, "parameters": prm, "seeds": seeds} if a.card else {}),
            "load_average_end": os.getloadavg(), "sizes": per, "runs": rows}


def loadings(a, argv) -> dict:
    cfg = _config(a.config)
    meta = run_meta("bts_resolution.py", argv)
    scale = cfg["bts"]["scale"] or cfg["specimen"]["scale"]
    seeds = [int(x) for x in a.a1_seeds.split(",")]
    design = study_design(cfg)
    step = max(1, len(design) // max(1, a.design_samples))
    picks = design.iloc[::step].head(a.design_samples)
    from bpmcal import params as P

    with tempfile.TemporaryDirectory() as tmp:
        jobs = []
        names = [v.strip() for v in a.variants.split(";")] if a.variants else DEFAULT_VARIANTS
        for name in names:
            if name not in VARIANTS:
                raise SystemExit(f"--variants: {name!r} is not one of {sorted(VARIANTS)}")
        for name in names:
            over = VARIANTS[name]
            jobs += [("A1", dict(A1), s, scale, over, str(Path(tmp) / "a1"), cfg)
                     for s in seeds]
            jobs += [(row.sample_id, {k: float(getattr(row, k)) for k in P.PARAMS},
                      int(row.seed), scale, over, str(Path(tmp) / row.sample_id), cfg)
                     for row in picks.itertuples()]
        rows = _pool(jobs, a.jobs)
    out = {}
    for name in names:
        over = VARIANTS[name]
        mine = [r for r in rows if r["variant"] == over]
        out[name] = {"a1": _stats([r for r in mine if r["label"] == "A1"]),
                     "design": _stats([r for r in mine if r["label"] != "A1"])}
    return {**meta, "part": "loadings", "config": str(a.config), "bts": cfg["bts"],
            "scale": scale, "design_samples": list(picks["sample_id"]),
            "load_average_end": os.getloadavg(), "variants": out, "runs": rows}


def cards(a, argv) -> dict:
    from bpmcal import params as P
    from bpmcal.io.card import card_parameters

    cfg = _config(a.config)
    meta = run_meta("bts_resolution.py", argv)
    scale = cfg["bts"]["scale"] or cfg["specimen"]["scale"]
    seeds = [int(x) for x in a.seeds.split(",")]
    named = {} if a.without_a1 else {"A1": dict(A1)}
    for f in (x for x in a.cards.split(",") if x):
        card = yaml.safe_load(Path(f).read_text())
        prm = card_parameters(card)
        named[f"{card['specimen']} ({Path(f).parent.name}/{Path(f).name})"] = {
            k: float(prm[k]) for k in P.PARAMS}
    rec = {**meta, "part": "cards", "config": str(a.config), "bts": cfg["bts"],
           "scale": scale, "seeds": seeds, "parameters": named,
           "replicate_stride": TENSILE_REPLICATE_STRIDE}
    with tempfile.TemporaryDirectory() as tmp:
        if a.specimens > 1:  # each seed as the study measures it, N discs
            jobs = [(name, prm, s, a.specimens, str(Path(tmp) / f"c{i}"), cfg)
                    for i, (name, prm) in enumerate(named.items()) for s in seeds]
            rows = _pool(jobs, a.jobs, _run_seed, _seed_line)
            return {**rec, "specimens": a.specimens, "load_average_end": os.getloadavg(),
                    "cards": {n: _stats_k([r for r in rows if r["label"] == n], a.specimens)
                              for n in named}, "seed_runs": rows}
        jobs = [(name, prm, s, scale, {}, str(Path(tmp) / f"c{i}"), cfg)
                for i, (name, prm) in enumerate(named.items()) for s in seeds]
        rows = _pool(jobs, a.jobs)
    return {**rec, "load_average_end": os.getloadavg(),
            "cards": {n: _stats([r for r in rows if r["label"] == n]) for n in named},
            "runs": rows}


#: the JSON record of each part
_STEM = {"loadings": "loadings", "curve": "resolution", "dtt": "dtt", "cards": "cards"}


def _record_name(rec: dict) -> str:
    """The JSON record's file name, ``results_bts_<stem>_<date>.json``: the part's stem,
    ``specimens`` for the ``cards`` part with several discs per seed."""
    stem = "specimens" if rec.get("specimens", 1) > 1 else _STEM[rec["part"]]
    return f"results_bts_{stem}_{rec['date']}.json"


def markdown(records: list[dict], title: str | None = None, names=None,
             folder: str = "benchmarks/results") -> str:
    """The measurement record as Markdown (docs/measurements), from the JSON records
    (``names``: their file names, else each part's ``results_bts_<stem>_<date>.json``, in
    ``folder``: the records' folder, ``benchmarks`` for those written before they moved);
    with several ``cards --specimens`` records, the expected seed CVs pooled over them."""
    lines = [f"# {title}", "", "Generated by `python benchmarks/bts_resolution.py markdown` "
             "from the JSON records named below; the seed CV is over the valid runs only "
             "(an invalid run gives no σt).", ""] if title else []
    names = names or [_record_name(r) for r in records]
    for rec, name in zip(records, names):
        lines += [f"## {rec['part']}: {rec['date']}, commit {rec['commit']}", "",
                  f"Record: `{folder}/{name}`.", "",
                  f"Host: {rec['cpu_model']} ({rec['cpus']} CPUs); load average at the start "
                  f"{', '.join(f'{x:.2f}' for x in rec['load_average_start'])}, at the end "
                  f"{', '.join(f'{x:.2f}' for x in rec['load_average_end'])}.", "",
                  f"Command: `{rec['command']}`", ""]
        if rec["part"] == "curve":
            if rec.get("card"):
                lines += [f"The card {rec['card']} ("
                          + ", ".join(f"{k} {v:g}" for k, v in rec["parameters"].items())
                          + f"), one disc per packing seed {_seed_span(rec['seeds'])} at "
                          "each size, the study's other Brazilian settings:", ""]
            lines += ["| scale | D (mm) | balls across | balls | runs | valid | σt mean of the "
                      "valid (MPa) | seed CV | CPU s per run (median) |",
                      "|---|---|---|---|---|---|---|---|---|"]
            for s in rec["sizes"].values():
                lines.append(
                    f"| {s['scale']:g} | {s['diameter_mm']:.1f} | {s['balls_across']:.1f} | "
                    f"{s['n_balls']:.0f} | {s['n']} | {s['n_valid']} | "
                    f"{s['sigma_t_mean_MPa']:.2f} | {100 * s['seed_cv']:.1f} % | "
                    f"{s['cpu_s_median']:.1f} |")
        elif rec["part"] == "dtt":
            st = rec["stats"]
            lines += ["The direct-tension test of the A1 card on the UCS cylinder (the study's "
                      "dtt settings), for comparison with the Brazilian disc.", "",
                      "| scale | balls across | balls | runs | valid | σt mean of the valid "
                      "(MPa) | seed CV | CPU s per run (median) |",
                      "|---|---|---|---|---|---|---|---|",
                      f"| {rec['scale']:g} | {st['balls_across']:.1f} | {st['n_balls']:.0f} | "
                      f"{st['n']} | {st['n_valid']} | {st['sigma_t_mean_MPa']:.2f} | "
                      f"{100 * st['seed_cv']:.1f} % | {st['cpu_s_median']:.1f} |"]
        elif rec["part"] == "cards" and rec.get("specimens", 1) > 1:
            n = rec["specimens"]
            lines += [f"σt of each card at the study's Brazilian settings (disc scale "
                      f"{rec['scale']:g}), packing seeds {_seed_span(rec['seeds'])}, each seed "
                      f"measured on {n} discs as the closed loop and the fresh-seed check "
                      "measure it (an invalid disc replaced by another packing). A seed's σt "
                      "is the mean of its first k discs (`verification.tensile_specimens` = "
                      "k); its mean and seed CV over the seeds:", "",
                      "| card | seeds | invalid discs replaced | "
                      + " | ".join(f"k = {k}: σt (MPa), seed CV" for k in range(1, n + 1))
                      + " | CPU s per seed of N discs (median) |",
                      "|---|---|---|" + "---|" * n + "---|"]
            for name, st in rec["cards"].items():
                ks = " | ".join(f"{st['k'][str(k)]['sigma_t_mean_MPa']:.2f}, "
                                f"{100 * st['k'][str(k)]['seed_cv']:.1f} %"
                                for k in range(1, n + 1))
                lines.append(f"| {name} | {st['n_seeds']} | {st['invalid_discs']} | {ks} | "
                             f"{st['cpu_s_per_seed_median']:.1f} |")
            lines += _specimens_expected(rec) + _block_cvs(rec)
        elif rec["part"] == "cards":
            lines += [f"σt of each card at the study's Brazilian settings (disc scale "
                      f"{rec['scale']:g}), packing seeds {', '.join(map(str, rec['seeds']))}.",
                      "", "| card | runs | valid | σt mean of the valid (MPa) | seed CV | "
                      "balls across | CPU s per run (median) |", "|---|---|---|---|---|---|---|"]
            for name, st in rec["cards"].items():
                lines.append(f"| {name} | {st['n']} | {st['n_valid']} | "
                             f"{st['sigma_t_mean_MPa']:.2f} | {100 * st['seed_cv']:.1f} % | "
                             f"{st['balls_across']:.1f} | {st['cpu_s_median']:.1f} |")
        else:
            ds = rec["design_samples"]
            lines += [f"Disc scale {rec['scale']:g}; design samples "
                      + (f"{', '.join(ds)}." if len(ds) <= 24 else
                         f"{ds[0]} to {ds[-1]} ({len(ds)}: every sample of the design, each "
                         "with the study's packing seed)."), "",
                      "| loading | A1: valid | A1: σt mean (MPa) | A1: seed CV | design: valid "
                      "| CPU s per run (median) |", "|---|---|---|---|---|---|"]
            for name, v in rec["variants"].items():
                a1, d = v["a1"], v["design"]
                lines.append(f"| {name} | {a1['n_valid']}/{a1['n']} | "
                             f"{a1['sigma_t_mean_MPa']:.2f} | {100 * a1['seed_cv']:.1f} % | "
                             f"{d['n_valid']}/{d['n']} | "
                             f"{statistics.median([a1['cpu_s_median'], d['cpu_s_median']]):.1f} |")
        lines.append("")
    spec = [r for r in records if r["part"] == "cards" and r.get("specimens", 1) > 1]
    if len(spec) > 1:
        lines += [f"## pooled: the {len(spec)} records above", ""] + _expected_table(
            disc_cv(spec), "Every disc of each card over the records above") + [""]
    return "\n".join(lines)


def disc_cv(recs) -> dict:
    """Per card of ``cards --specimens`` records (one, or a list pooled): (the seed CV of
    one disc from every valid disc, the mean σt of disc 0 of each seed, that of the other
    discs, the number of discs)."""
    recs = [recs] if isinstance(recs, dict) else recs
    out = {}
    for name in dict.fromkeys(n for r in recs for n in r["cards"]):
        vals = [r["values_MPa"] for rec in recs for r in rec["seed_runs"] if r["label"] == name]
        v = [x for r in vals for x in r if x == x]
        first = [r[0] for r in vals if r and r[0] == r[0]]
        rest = [x for r in vals for x in r[1:] if x == x]
        out[name] = (statistics.stdev(v) / statistics.fmean(v), statistics.fmean(first),
                     statistics.fmean(rest), len(v))
    return out


def _expected_table(cvs: dict, what: str, n: int = 4, stride: int = 1_000_000) -> list[str]:
    """The table of :func:`expected_cv` for k = 1 .. n and each card of ``cvs``
    (:func:`disc_cv`), and the smallest k whose chance is below MISS_ACCEPTED for all."""
    lines = [f"{what}: the disc CV, the seed CV expected of a k-disc mean (the disc CV / √k; "
             "discs on distinct packings are independent) and the chance that the seed CV "
             f"measured over {N_CHECK} seeds exceeds {100 * CV_TARGET:g} % (χ² with "
             f"{N_CHECK - 1} degrees of freedom). The mean of disc 0 (packed with the seed "
             "itself, as the seed's UCS cylinder is) beside that of the other discs (seed + "
             f"j x {stride:,}):", "",
             "| card | discs | disc CV | disc 0 / discs 1+: σt (MPa) | "
             + " | ".join(f"k = {k}: CV, P(CV{N_CHECK} > {100 * CV_TARGET:g} %)"
                          for k in range(1, n + 1)) + " |",
             "|---|---|---|---|" + "---|" * n]
    worst = {k: 0.0 for k in range(1, n + 1)}
    for name, (cv, first, rest, count) in cvs.items():
        cells = []
        for k in range(1, n + 1):
            cvk, p = expected_cv(cv, k)
            worst[k] = max(worst[k], p)
            cells.append(f"{100 * cvk:.1f} %, {100 * p:.0f} %")
        lines.append(f"| {name} | {count} | {100 * cv:.1f} % | {first:.2f} / {rest:.2f} | "
                     + " | ".join(cells) + " |")
    ok = [k for k in worst if worst[k] < MISS_ACCEPTED]
    return lines + ["", f"The smallest k whose chance is below {100 * MISS_ACCEPTED:g} % for "
                    f"every card: **{ok[0] if ok else 'none of 1–' + str(n)}**."]


def _block_cvs(rec: dict) -> list[str]:
    """The seed CV of a k-disc mean measured over each block of N_CHECK consecutive seeds
    (the target's own sample size): per card and k, the largest over the blocks."""
    n, seeds = rec["specimens"], rec["seeds"]
    blocks = [seeds[i:i + N_CHECK] for i in range(0, len(seeds) - N_CHECK + 1, N_CHECK)]
    lines = ["", f"Measured over each of the {len(blocks)} blocks of {N_CHECK} consecutive "
             f"seeds ({_seed_span(blocks[0])}, {_seed_span(blocks[1])}, …): the largest seed "
             "CV of a k-disc mean over the blocks:" if len(blocks) > 1 else "", "",
             "| card | " + " | ".join(f"k = {k}" for k in range(1, n + 1)) + " |",
             "|---|" + "---|" * n]
    for name in rec["cards"]:
        by_seed = {r["seed"]: r["values_MPa"] for r in rec["seed_runs"] if r["label"] == name}
        cells = []
        for k in range(1, n + 1):
            cvs = []
            for b in blocks:
                v = _k_means([by_seed[s] for s in b], k)
                if len(v) > 1:
                    cvs.append(statistics.stdev(v) / statistics.fmean(v))
            cells.append(f"{100 * max(cvs):.1f} %" if cvs else "–")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines if len(blocks) > 1 else []


def _specimens_expected(rec: dict) -> list[str]:
    """:func:`_expected_table` of one ``cards --specimens`` record."""
    # records since 2026-11-29 name the replicate stride and give k up to their N
    new = "replicate_stride" in rec
    return [""] + _expected_table(
        disc_cv(rec), f"Expected from every disc of a card ({rec['specimens']} per seed)",
        rec["specimens"] if new else 4, rec.get("replicate_stride", 1_000_000))


def _seed_span(seeds) -> str:
    """``1–30`` for a run of consecutive seeds, else the list."""
    if len(seeds) > 2 and seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"{seeds[0]}–{seeds[-1]}"
    return ", ".join(map(str, seeds))


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="part", required=True)
    c = sub.add_parser("curve")
    c.add_argument("--scales", default="0.4,0.55,0.7,0.85,1.0")
    c.add_argument("--seeds", default="1,2,3,4,5")
    c.add_argument("--card", default=None,
                   help="a card file (verified or planted) instead of the paper's A1")
    dd = sub.add_parser("dtt")
    dd.add_argument("--seeds", default="1,2,3,4,5,6,7,8")
    lo = sub.add_parser("loadings")
    lo.add_argument("--a1-seeds", default="1,2,3,4,5,6,7,8,9,10")
    lo.add_argument("--design-samples", type=int, default=12)
    lo.add_argument("--variants", default=None,
                    help="loading variants to run, separated by ';' (default: "
                         + "; ".join(DEFAULT_VARIANTS) + f"; known: {'; '.join(VARIANTS)})")
    ca = sub.add_parser("cards")
    ca.add_argument("--cards", required=True, help="card files, separated by ','")
    ca.add_argument("--seeds", default="1,2,3,4,5")
    ca.add_argument("--specimens", type=int, default=1,
                    help="discs per seed, measured as the study's loop measures a seed")
    ca.add_argument("--without-a1", action="store_true",
                    help="the given cards only (by default the paper's A1 runs beside them)")
    for p in (c, lo, dd, ca):
        p.add_argument("--config", default=str(CONFIG))
        p.add_argument("--jobs", type=int, default=2)
        p.add_argument("--out", default=None, help="write the JSON record here")
    m = sub.add_parser("markdown")
    m.add_argument("records", nargs="+")
    m.add_argument("--title", default=None)
    m.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    if a.part == "markdown":
        text = markdown([json.loads(Path(f).read_text()) for f in a.records], a.title,
                        [Path(f).name for f in a.records])
        if a.out:
            Path(a.out).parent.mkdir(parents=True, exist_ok=True)
            Path(a.out).write_text(text)
        print(text)
        return 0
    rec = {"curve": curve, "loadings": loadings, "dtt": dtt, "cards": cards}[a.part](a, argv)
    text = json.dumps(rec, indent=1, default=float)
    if a.out:
        Path(a.out).write_text(text + "\n")
    print(markdown([rec]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
