"""What the study's Brazilian test of every sample costs, and whether its settings are sound.

For design samples of a config (default ``config/config.yaml``: the cylinder at scale
0.4, the disc at ``bts.scale``), one process,
one numba thread, a fresh packing cache per sample (as in the study, where every sample is
packed once for its cylinder and once for its disc):

- ``ucs``: the UCS run of the sample with the config's ``specimen``/``ucs`` settings;
- ``bts``: the Brazilian run with the config's ``bts`` settings (what the study runs; the
  peak stress is reported, and whether the run is a valid test);
- ``ref``: the careful Brazilian run (``BTSSettings``' defaults until they became the
  study's: the whole test at 0.00625 m/s, 0.002 of diametral strain past the peak);
- ``half``: the study's settings with half the platen speed (the rate test; first
  ``--rate-samples`` samples only).

CPU time (``time.process_time``, the better measure on a shared machine) and wall time of
each run, sigma_t of each, and the medians. The study grows by about
``sum(bts CPU) / sum(ucs CPU)`` times its sample time (the samples are ~3/4 of the
default study's time; docs/measurements/2026-11-24-default-study-timings.md).

    python benchmarks/bts_study_cost.py --samples s000,s001,s002,s003,s004,s005 \
        --rate-samples 4 [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import yaml
from _study import CONFIG, REPO, bts_disc_and_settings, cpu_model, study_design, ucs_settings


def _timed(f):
    c, w = time.process_time(), time.perf_counter()
    r = f()
    return r, time.process_time() - c, time.perf_counter() - w


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="override bts settings of the config (e.g. platen_velocity=0.0125)")
    ap.add_argument("--samples", default="s000,s001,s002,s003,s004,s005")
    ap.add_argument("--rate-samples", type=int, default=4)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--no-ref", action="store_true", help="skip the careful reference run")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)

    from bpmcal.lab.brazilian import BTSSettings
    from bpmcal.lab.runner import Geometry, bts_geometry, bts_test, set_threads, ucs_test
    from bpmcal.stages.runs import params_from_design
    from bpmcal.study.config import validate_config

    cfg = yaml.safe_load(Path(a.config).read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    sp, b = cfg["specimen"], cfg["bts"]
    for kv in a.set:
        k, v = kv.split("=", 1)
        b[k] = v if k == "loading" else float(v)
    common = dict(sigma0_MPa=sp["sigma0_MPa"], install_gap_mm=sp["install_gap_mm"],
                  relax_ratio=sp["relax_ratio"], genesis=sp["genesis"])
    geo = Geometry(scale=sp["scale"], diameter_mm=sp["diameter_mm"],
                   height_mm=sp["height_mm"], **common)
    disc, study = bts_disc_and_settings(cfg)  # after the --set overrides of cfg["bts"]
    ucs_st = ucs_settings(cfg)
    # the careful reference: a slow platen from the start, stopped well past the split (the
    # library's defaults until they became the study's)
    ref = BTSSettings(platen_velocity=0.00625, approach_velocity=0.0, stop_drop=0.7,
                      post_peak_strain=0.002)
    half = replace(study, platen_velocity=study.platen_velocity / 2)
    set_threads(a.threads)

    with tempfile.TemporaryDirectory() as tmp:
        design = Path(tmp) / "design.csv"
        study_design(cfg).to_csv(design, index=False)
        # warm-up: numba's cached kernels loaded once, not charged to the first sample
        p0, s0, _ = params_from_design(design, "s000")
        bts_test({**p0, "rmin_mm": 0.6}, s0, bts_geometry(scale=0.3), BTSSettings(max_steps=2000),
                 cache=Path(tmp) / "warm")
        rows = []
        for i, sid in enumerate(a.samples.split(",")):
            p, seed, _ = params_from_design(design, sid)
            cache = Path(tmp) / sid  # fresh: the sample's cylinder and disc are packed here
            row = {"sample": sid}
            for name, f in [
                    ("ucs", lambda: ucs_test(p, seed, geo, ucs_st, cache=cache)),
                    ("bts", lambda: bts_test(p, seed, disc, study, cache=cache)),
                    *([] if a.no_ref else
                      [("ref", lambda: bts_test(p, seed, disc, ref, cache=cache))]),
                    *([("half", lambda: bts_test(p, seed, disc, half, cache=cache))]
                      if i < a.rate_samples else [])]:
                r, cpu, wall = _timed(f)
                s = r.summary
                row[f"{name}_cpu_s"], row[f"{name}_wall_s"] = cpu, wall
                row[f"{name}_MPa"] = s.get("bts_peak_MPa", s.get("ucs_MPa"))
                if "bts_valid" in s:
                    row[f"{name}_valid"] = bool(s["bts_valid"])
                row[f"{name}_steps"] = s.get("steps")
                if name == "bts":
                    row["n_balls_disc"] = s["n_balls"]
                    row["approach_strain"] = s.get("approach_strain")
                    row["peak_strain"] = s["peak_strain"]
                print(f"{sid} {name}: {row[f'{name}_MPa']:.4f} MPa, {s.get('steps')} steps, "
                      f"CPU {cpu:.1f} s, wall {wall:.1f} s", flush=True)
            if "ref_MPa" in row:
                row["bts_vs_ref_pct"] = 100 * (row["bts_MPa"] / row["ref_MPa"] - 1)
            if "half_MPa" in row:
                row["half_vs_bts_pct"] = 100 * (row["half_MPa"] / row["bts_MPa"] - 1)
            rows.append(row)

    def med(k):
        v = [r[k] for r in rows if k in r]
        return statistics.median(v) if v else None

    out = {
        "cpu_model": cpu_model(), "load_average": os.getloadavg(), "threads": a.threads,
        "scale": sp["scale"], "disc_scale": disc.scale,
        "study_bts_settings": {k: getattr(study, k) for k in (
            "loading", "contact_cap", "platen_velocity", "approach_velocity", "stop_drop",
            "post_peak_strain")},
        "samples": rows,
        "median_cpu_s": {k: med(f"{k}_cpu_s") for k in ("ucs", "bts", "ref", "half")},
        "median_wall_s": {k: med(f"{k}_wall_s") for k in ("ucs", "bts", "ref", "half")},
        "bts_over_ucs_cpu": sum(r["bts_cpu_s"] for r in rows) / sum(r["ucs_cpu_s"] for r in rows),
        "ref_over_ucs_cpu": (None if a.no_ref else sum(r["ref_cpu_s"] for r in rows)
                             / sum(r["ucs_cpu_s"] for r in rows)),
        "max_abs_bts_vs_ref_pct": max((abs(r["bts_vs_ref_pct"]) for r in rows
                                       if "bts_vs_ref_pct" in r), default=None),
        "median_half_vs_bts_pct": med("half_vs_bts_pct"),
        "max_abs_half_vs_bts_pct": max((abs(r["half_vs_bts_pct"]) for r in rows
                                        if "half_vs_bts_pct" in r), default=None),
    }
    if a.json:
        print(json.dumps(out, indent=1, default=float))
    else:
        print(f"CPU {out['cpu_model']}, load average {out['load_average']}")
        print(f"median CPU s: {out['median_cpu_s']}")
        print(f"median wall s: {out['median_wall_s']}")
        print(f"sum CPU bts/ucs = {out['bts_over_ucs_cpu']:.2f} (ref/ucs "
              f"{out['ref_over_ucs_cpu']})")
        print(f"sigma_t study vs ref: max |diff| {out['max_abs_bts_vs_ref_pct']} %; "
              f"half speed vs study: max |diff| {out['max_abs_half_vs_bts_pct']} %, median "
              f"{out['median_half_vs_bts_pct']} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
