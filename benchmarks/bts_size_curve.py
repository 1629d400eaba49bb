"""σt against the Brazilian disc's size (issue 56, item 3): why valid splits become rarer
on larger discs, and the size curve of a card. The measurement record behind
``lab.brazilian.similar_contact_cap`` and the ``bts_size`` stage.

Two parts, each a JSON record (date, commit, CPU model, load average at the start and end,
the exact command), rendered to Markdown by ``markdown``:

- ``validity``: the paper's A1 card (or ``--card``) on the discs of ``--scales`` (the ISRM
  50 x 25 mm disc x scale; balls of the card's Rmin, so a larger disc has more balls
  across), packing ``--seeds``, one disc per seed (``retests`` 0: the valid fraction is
  per disc), with the config's ``bts`` settings and two contact caps: the config's (in
  mean ball diameters, the same absolute size on every disc) and the cap scaled with the
  disc's diameter relative to the study's disc (``similar_contact_cap``: the same share
  of D on every disc); plus, on the study's disc, the cap that is the same share of it as
  the config's cap is of the largest disc (the converse). Per disc: the verdict, the
  reason, where the fracture started (``init_offset``), the pre-peak share grown from a
  platen, the peak, the caps' bonds and breaks.
- ``curve``: the size curve as the study's ``bts_size`` stage measures it
  (``stages.bts_size.size_curve``: the card at ``--scales``, ``--seeds``, the contact cap
  scaled with D) and its power-law fit.

    nice -n 19 python benchmarks/bts_size_curve.py validity --scales 0.55,0.8,1.0 \\
        --seeds 1,2,3,4,5 --out benchmarks/results/results_bts_size_validity_DATE.json
    nice -n 19 python benchmarks/bts_size_curve.py curve --scales 0.55,0.7416,1.0 \\
        --seeds 301,...,305 --max-seeds 8 --out benchmarks/results/results_bts_size_curve_DATE.json
    python benchmarks/bts_size_curve.py markdown RECORD.json [RECORD.json ...] \\
        --out docs/measurements/DATE-bts-size.md

One run at a time, one numba thread (the machine is shared); the JSON is rewritten after
every disc, so a stopped invocation keeps what it measured.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import yaml
from _study import CONFIG, REPO, bts_disc_and_settings, run_meta

from bpmcal.study.paper import A1


def _config(path) -> dict:
    from bpmcal.study.config import validate_config

    cfg = yaml.safe_load(Path(path).read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    return cfg


def _card(path):
    """(label, parameters) of ``--card`` (a card file) or the paper's A1."""
    if not path:
        return "A1", dict(A1)
    from bpmcal import params as P
    from bpmcal.io.card import card_parameters, read_card

    c = read_card(path, "--card")
    prm = card_parameters(c)
    return f"{c['specimen']} ({path})", {k: prm[k] for k in prm if k in P.ALL_PARAMS}


def _save(rec: dict, out) -> None:
    if out:
        tmp = Path(str(out) + ".tmp")
        tmp.write_text(json.dumps(rec, indent=1) + "\n")
        tmp.replace(out)


def _disc(params, seed, scale, cap, cfg, cache) -> dict:
    """One disc (no retest): its verdict, reason and where it broke."""
    from bpmcal.lab.runner import bts_test

    disc, st = bts_disc_and_settings(cfg, scale, contact_cap=cap, retests=0)
    c0 = time.process_time()
    s = bts_test(params, seed, disc, st, cache=cache, threads=1, keep_particles=False).summary
    return {"seed": seed, "scale": scale, "diameter_mm": s["diameter_mm"],
            "contact_cap": cap, "cap_share_of_D": cap * s["mean_ball_diameter_mm"]
            / s["diameter_mm"], "cpu_s": time.process_time() - c0,
            "n_balls": s["n_balls"], "balls_across": s["balls_across"],
            "bts_valid": bool(s["bts_valid"]), "bts_peak_MPa": s["bts_peak_MPa"],
            "bts_MPa": s["bts_MPa"], "reason": s["bts_invalid_reason"],
            "init_offset": s["init_offset"], "init_side": s["init_side"],
            "pre_contact_fraction": s["pre_contact_fraction"],
            "split_band_fraction": s["split_band_fraction"],
            "burst_cracks": s["burst_cracks"], "contact_cap_bonds": s["contact_cap_bonds"],
            "contact_cap_broken": s["contact_cap_broken"],
            "contact_events": s["contact_events"], "stop_reason": s["stop_reason"],
            "steps": s["steps"]}


def validity(a, argv) -> dict:
    from bpmcal.lab.brazilian import similar_contact_cap

    cfg = _config(a.config)
    label, params = _card(a.card)
    scales = [float(x) for x in a.scales.split(",")]
    seeds = [int(x) for x in a.seeds.split(",")]
    ref = float(cfg["bts"]["scale"])
    cap = float(cfg["bts"]["contact_cap"])
    jobs = []
    for sc in scales:
        jobs.append((sc, cap, "config's cap"))
        if sc != ref:
            jobs.append((sc, similar_contact_cap(cap, sc, ref), "cap scaled with D"))
    if ref in scales and max(scales) != ref:  # the converse on the study's disc
        jobs.append((ref, similar_contact_cap(cap, ref, max(scales)),
                     f"cap of the {max(scales):g} disc's share"))
    rec = {**run_meta("bts_size_curve.py", argv), "part": "validity", "card": label, "parameters": params,
           "config": str(a.config), "bts": cfg["bts"], "reference_scale": ref,
           "seeds": seeds, "runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        for sc, c, name in jobs:
            for s in seeds:
                r = {"variant": name, **_disc(params, s, sc, c, cfg, str(Path(tmp) / "c"))}
                rec["runs"].append(r)
                rec["load_average_end"] = list(os.getloadavg())
                _save(rec, a.out)
                print(f"scale {sc:g} cap {c:.3f} ({name}) seed {s}: "
                      f"{r['bts_peak_MPa']:.3f} MPa, valid {r['bts_valid']} "
                      f"{r['reason'][:70]}, CPU {r['cpu_s']:.1f} s", flush=True)
    return rec


def curve(a, argv) -> dict:
    from bpmcal.stages.bts_size import SizeSettings, fit_power_law, run_sizes, size_table

    cfg = _config(a.config)
    label, params = _card(a.card)
    scales = [float(x) for x in a.scales.split(",")]
    seeds = [int(x) for x in a.seeds.split(",")]
    disc, st = bts_disc_and_settings(cfg)
    study_mm = disc.scale * disc.diameter_mm
    sizes_mm = [s * disc.diameter_mm for s in scales]
    rec = {**run_meta("bts_size_curve.py", argv), "part": "curve", "card": label, "parameters": params,
           "config": str(a.config), "bts": cfg["bts"], "seeds": seeds,
           "max_seeds": a.max_seeds or len(seeds), "target_se": a.target_se}
    n = len(seeds)
    if seeds != list(range(seeds[0], seeds[0] + n)):
        raise SystemExit(f"--seeds {a.seeds}: expected consecutive seeds (the stage's)")
    with tempfile.TemporaryDirectory() as tmp:
        c0 = time.process_time()
        size = SizeSettings(seeds=n, max_seeds=max(n, a.max_seeds or n),
                            target_se=a.target_se, first_seed=seeds[0])
        runs = run_sizes(params, sizes_mm, disc, st, settings=size,
                         run_path=lambda d, s: Path(tmp) / f"{d}_{s}.h5",
                         note=lambda line: print(line, flush=True))
        rec["cpu_s"] = time.process_time() - c0
    runs["run"] = ""
    sizes = size_table(runs, study_mm, max(sizes_mm))
    fit = fit_power_law(sizes["diameter_mm"], sizes["mean_MPa"],
                        sizes["se_MPa"].where(sizes["valid"] >= 2), study_mm)
    rec.update(runs=runs.to_dict("records"), sizes=sizes.to_dict("records"), fit=fit,
               load_average_end=list(os.getloadavg()))
    _save(rec, a.out)
    return rec


def _f(v, fmt=".2f") -> str:
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def _validity_md(rec: dict) -> list[str]:
    out = [f"Card: {rec['card']}; one disc per seed ({', '.join(map(str, rec['seeds']))}), "
           "no retest; the study's disc is scale "
           f"{rec['reference_scale']:g}; the config's cap {rec['bts']['contact_cap']:g} mean "
           "ball diameters.", "",
           "| disc D (mm) | balls across | cap (mean ball diameters) | cap / D | variant | "
           "valid | σt of the valid (MPa) | peaks of all (MPa, mean) | invalid: why | "
           "CPU s per disc (median) |", "|---|---|---|---|---|---|---|---|---|---|"]
    groups: dict = {}
    biggest = max(r["diameter_mm"] for r in rec["runs"])
    for r in rec["runs"]:
        name = (f"the config's cap's share of the {biggest:g} mm disc"
                if r["variant"].startswith("cap of the") else r["variant"])
        groups.setdefault((r["scale"], r["contact_cap"], name), []).append(r)
    for (_, cap, name), rs in groups.items():
        v = [r["bts_MPa"] for r in rs if r["bts_valid"]]
        why: dict = {}
        for r in rs:
            if not r["bts_valid"]:
                k = r["reason"].split(":")[0]
                why[k] = why.get(k, 0) + 1
        out.append(
            f"| {rs[0]['diameter_mm']:.1f} | {statistics.fmean(r['balls_across'] for r in rs):.1f}"
            f" | {cap:.3f} | {statistics.fmean(r['cap_share_of_D'] for r in rs):.3f} | {name} | "
            f"{len(v)} of {len(rs)} | "
            + (f"{statistics.fmean(v):.2f}" if v else "–")
            + f" | {statistics.fmean(r['bts_peak_MPa'] for r in rs):.2f} | "
            + ("; ".join(f"{k} ({n})" for k, n in why.items()) or "–")
            + f" | {statistics.median(r['cpu_s'] for r in rs):.1f} |")
    share = {}
    for r in rec["runs"]:  # the discs with the study's cap share: the config's or scaled
        if r["variant"] == "cap scaled with D" or (r["variant"] == "config's cap"
                                                   and r["scale"] == rec["reference_scale"]):
            share.setdefault(r["diameter_mm"], []).append(r["bts_MPa"] if r["bts_valid"]
                                                          else math.nan)
    if len(share) > 1:
        from bpmcal.stages.bts_size import fit_power_law

        d = sorted(share)
        v = [[x for x in share[k] if x == x] for k in d]
        f = fit_power_law(d, [statistics.fmean(x) if x else math.nan for x in v],
                          [statistics.stdev(x) / math.sqrt(len(x)) if len(x) > 1 else math.nan
                           for x in v], min(d))
        cs = statistics.fmean(r["cap_share_of_D"] for r in rec["runs"]
                              if r["variant"] == "cap scaled with D")
        out += ["", f"The valid discs with the study's cap share ({cs:.3f} D), fitted as the "
                f"`bts_size` stage fits: σt = {_f(f['sigma_ref_MPa'], '.3f')} MPa x (D / "
                f"{min(d):g} mm)^-k, k = {_f(f['k'], '.3f')} ± {_f(f['k_se'], '.3f')} (SE; "
                f"χ² {_f(f['chi2'], '.2f')} on {f['n_sizes']} sizes)."]
    out += ["", "Per disc:", "",
            "| D (mm) | cap | seed | valid | peak (MPa) | initiation (R from the centre) | "
            "pre-peak share from a platen | burst cracks | cap bonds (broken) | why not |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rec["runs"]:
        out.append(f"| {r['diameter_mm']:.1f} | {r['contact_cap']:.3f} | {r['seed']} | "
                   f"{'yes' if r['bts_valid'] else 'no'} | {r['bts_peak_MPa']:.2f} | "
                   f"{_f(r['init_offset'])} {r['init_side']} | "
                   f"{_f(r['pre_contact_fraction'])} | {r['burst_cracks']} | "
                   f"{r['contact_cap_bonds']} ({r['contact_cap_broken']}) | {r['reason']} |")
    return out


def _curve_md(rec: dict) -> list[str]:
    f = rec["fit"]
    out = [f"Card: {rec['card']}; packing seeds {', '.join(map(str, rec['seeds']))} at every "
           f"size, then one more while the size's SE exceeded {rec['target_se']:g} of its "
           f"mean, up to {rec['max_seeds']} (`bts_size.SizeSettings`); each seed's test as "
           "the study runs it (an invalid disc retested, "
           "`bts.retests`); the contact cap scaled with D from the study's disc "
           f"(`similar_contact_cap`). CPU {rec['cpu_s']:.0f} s in all.", "",
           "| D (mm) | balls across | cap (mean ball diameters) | seeds | valid | discs tested "
           "| σt mean (MPa) | SE (MPa) | SE % |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rec["sizes"]:
        out.append(f"| {r['diameter_mm']:.1f} | {r['balls_across']:.1f} | "
                   f"{r['contact_cap']:.3f} | {r['seeds']} | {r['valid']} | {r['discs']} | "
                   f"{_f(r['mean_MPa'])} | {_f(r['se_MPa'], '.3f')} | {_f(r['se_pct'], '.1f')} |")
    out += ["", f"Fit: σt = {_f(f['sigma_ref_MPa'], '.3f')} MPa x (D / "
            f"{f['reference_mm']:g} mm)^-k, k = {_f(f['k'], '.3f')} ± {_f(f['k_se'], '.3f')} "
            f"(standard error; {f['n_sizes']} sizes, weighted by each mean's SE; "
            f"χ² {_f(f['chi2'], '.2f')})."]
    return out


def markdown(recs: list[dict], title: str, names: list[str]) -> str:
    lines = [f"# {title}", "",
             "Generated by `python benchmarks/bts_size_curve.py markdown` from the JSON "
             "records named below.", ""]
    for rec, name in zip(recs, names):
        end = rec.get("load_average_end") or []
        lines += [f"## {rec['part']}: {rec['date']}, commit {rec['commit']}", "",
                  f"Record: `benchmarks/results/{name}`.", "",
                  f"Host: {rec['cpu_model']} ({rec['cpus']} CPUs); load average at the start "
                  f"{', '.join(f'{x:.2f}' for x in rec['load_average_start'])}, at the end "
                  f"{', '.join(f'{x:.2f}' for x in end)}.", "",
                  f"Command: `{rec['command']}`", ""]
        lines += _validity_md(rec) if rec["part"] == "validity" else _curve_md(rec)
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="part", required=True)
    v = sub.add_parser("validity")
    c = sub.add_parser("curve")
    for p in (v, c):
        p.add_argument("--scales", default="0.55,0.8,1.0")
        p.add_argument("--seeds", default="1,2,3,4,5")
        p.add_argument("--card", default=None, help="a card file (default: the paper's A1)")
        p.add_argument("--config", default=str(CONFIG))
        p.add_argument("--out", default=None, help="write the JSON record here")
    c.add_argument("--max-seeds", type=int, default=None,
                   help="seeds at a size at most (more while its SE exceeds --target-se)")
    c.add_argument("--target-se", type=float, default=0.02)
    m = sub.add_parser("markdown")
    m.add_argument("records", nargs="+")
    m.add_argument("--title", default="σt against the Brazilian disc's size")
    m.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    if a.part == "markdown":
        recs = [json.loads(Path(r).read_text()) for r in a.records]
        text = markdown(recs, a.title, [Path(r).name for r in a.records])
        if a.out:
            Path(a.out).write_text(text)
        print(text)
        return 0
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    {"validity": validity, "curve": curve}[a.part](a, argv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
