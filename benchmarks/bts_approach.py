"""The Brazilian test's approach velocity: how many steps it saves, and whether σt moves.

Until the first bond breaks the disc is elastic, and the study closes the platens at
``bts.approach_velocity``; from the first crack on at ``bts.platen_velocity``. This runs
the study's Brazilian test (the config's ``bts`` and ``specimen`` sections, one thread) of
design samples at each approach velocity given, on the same disc packings (one packing
cache per sample: genesis once, then every velocity), and reports per sample and velocity
σt, validity, discs tested, steps and the test's wall seconds, and against the first
velocity: σt's change on the samples valid at both with the same disc, the steps' ratio.

    python benchmarks/bts_approach.py --samples 0:40 --approach 0.05 0.1 0.2 \
        --json benchmarks/results/results_bts_approach_DATE.json
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import yaml
from _study import CONFIG, REPO, bts_disc_and_settings, record_header, study_design


def _ids(spec: str) -> list[str]:
    if ":" in spec:
        lo, hi = (int(x) for x in spec.split(":"))
        return [f"s{i:03d}" for i in range(lo, hi)]
    return spec.split(",")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--samples", default="0:40", help="LO:HI (s000 ...) or s000,s001,...")
    ap.add_argument("--approach", type=float, nargs="+", default=[0.05, 0.1],
                    help="approach velocities, m/s (the first is the reference)")
    ap.add_argument("--json", help="write the rows and the summary here")
    a = ap.parse_args(argv)

    from bpmcal.lab.runner import bts_test, set_threads
    from bpmcal.stages.runs import params_from_design
    from bpmcal.study.config import validate_config

    cfg = yaml.safe_load(Path(a.config).read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    disc, study = bts_disc_and_settings(cfg)
    set_threads(1)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        design = Path(tmp) / "design.csv"
        study_design(cfg).to_csv(design, index=False)
        for sid in _ids(a.samples):
            p, seed, _ = params_from_design(design, sid)
            row = {"sample": sid}
            for v in a.approach:
                s = bts_test(p, seed, disc, replace(study, approach_velocity=v),
                             cache=Path(tmp) / sid).summary
                row[str(v)] = {"bts_MPa": float(s["bts_peak_MPa"]), "valid": bool(s["bts_valid"]),
                               "discs": int(s["discs"]), "disc_seed": int(s["disc_seed"]),
                               "steps": int(s["steps"]), "test_s": float(s["test_s"])}
                print(sid, v, row[str(v)], flush=True)
            rows.append(row)
    ref = str(a.approach[0])
    summary = {}
    for v in map(str, a.approach[1:]):
        same = [r for r in rows if r[ref]["valid"] and r[v]["valid"]
                and r[ref]["disc_seed"] == r[v]["disc_seed"]]
        d = [100 * (r[v]["bts_MPa"] / r[ref]["bts_MPa"] - 1) for r in same]
        summary[v] = {
            "valid": sum(r[v]["valid"] for r in rows), "valid_ref": sum(r[ref]["valid"] for r in rows),
            "discs": sum(r[v]["discs"] for r in rows), "discs_ref": sum(r[ref]["discs"] for r in rows),
            "steps_ratio": sum(r[v]["steps"] for r in rows) / sum(r[ref]["steps"] for r in rows),
            "test_s_ratio": sum(r[v]["test_s"] for r in rows) / sum(r[ref]["test_s"] for r in rows),
            "same_disc_valid": len(same),
            "bts_change_pct": {"median": statistics.median(d), "mean": statistics.fmean(d),
                               "sd": statistics.stdev(d) if len(d) > 1 else 0.0,
                               "min": min(d), "max": max(d)} if d else None}
        print(f"approach {v} against {ref}: {summary[v]}")
    if a.json:
        out = {**record_header("bts_approach.py", argv), "reference": ref, "summary": summary,
               "rows": rows}
        Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
