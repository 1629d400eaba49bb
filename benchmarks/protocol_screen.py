"""Loading protocols of the quasi-static tests side by side, paired on design samples: steps,
particle-steps, CPU seconds, and the responses (σc, E, ν of the UCS test, σt and validity
of the Brazilian test).

Every sample of the study's design (the config's ``study`` and ``ranges`` sections, as the
workflow's rule ``design`` draws it) runs the study's sample job's tests (the config's
``specimen``, ``compression`` and ``bts`` sections, one thread) once per protocol, on the
same packings (one packing cache per sample, kept in ``--cache``: genesis relaxes each
packing once, every protocol reuses it, as the study's specimen cache does). A protocol is
a name and the settings it replaces:

    {"ref": {}, "fast": {"ucs": {"approach_velocity": 0.2}, "bts": {"approach_velocity": 0.2}}}

(``--protocols FILE.json`` or inline JSON). The rows go to ``--out`` (JSON lines, one per
sample, protocol and test; a row already there is not run again, so an interrupted screen
resumes), with per test: the balls, the loading's steps (a Brazilian test: of every disc,
its seating included), the particle-steps, the CPU seconds of the test (``bpmcal.cost``'s
ledger: genesis, test and retests), and the responses. ``--series DIR`` also keeps each
run's series and crack events (``.npz``) for replaying stop rules on them.

    python benchmarks/protocol_screen.py --samples 0:40 --protocols P.json \
        --out /tmp/screen.jsonl --cache /tmp/screen_cache

``benchmarks/protocol_compare.py`` pairs the rows of two protocols.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _study import (  # noqa: E402
    CONFIG,
    REPO,
    bts_disc_and_settings,
    study_design,
    study_geometry,
    ucs_settings,
)

#: the summary values a row keeps of each test
KEEP = {"ucs": ("ucs_MPa", "E_GPa", "nu", "peak_strain", "u_pre_MJm3", "crack_init_MPa",
                "stop_reason", "steps", "records", "dt", "cracks_tension", "cracks_shear",
                "cracks_tension_peak", "cracks_shear_peak", "n_bonds"),
        "bts": ("bts_MPa", "bts_peak_MPa", "bts_valid", "bts_invalid_reason", "discs",
                "disc_seed", "stop_reason", "steps", "seat_steps", "peak_step", "peak_strain",
                "approach_strain", "contact_events", "balls_across", "init_offset",
                "split_band_fraction", "pre_contact_fraction", "records", "dt",
                "cracks_tension", "cracks_shear", "n_bonds")}


def _ids(spec: str) -> list[str]:
    if ":" in spec:
        lo, hi = (int(x) for x in spec.split(":"))
        return [f"s{i:03d}" for i in range(lo, hi)]
    return spec.split(",")


def _plain(v):
    if isinstance(v, (np.bool_, bool)):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, (np.floating, float)):
        return float(v)
    return v


class DiscLog:
    """Wraps the lab-test driver as ``lab.runner`` calls it (``run_test``): every disc a
    Brazilian test runs (retests too)."""

    def __init__(self):
        self.discs = []

    def install(self):
        from bpmcal.lab import runner
        from bpmcal.lab.brazilian import BrazilianTest

        inner = runner.run_test

        def run_test(test, progress=None):
            res = inner(test, progress)
            if not isinstance(test, BrazilianTest):
                return res
            sp, s, ser = test.sp, res.summary, res.series
            cr = np.asarray(ser["cracks_tension"]) + np.asarray(ser["cracks_shear"])
            first = np.flatnonzero(cr > 0)
            self.discs.append({
                "n_balls": int(sp.model.n), "steps": int(s["steps"]),
                "seat_steps": int(s["seat_steps"]), "peak_step": int(s["peak_step"]),
                "first_crack_step": int(ser["step"][first[0]]) if first.size else -1,
                "valid": bool(s["bts_valid"]), "reason": s["bts_invalid_reason"],
                "bts_peak_MPa": float(s["bts_peak_MPa"]), "stop_reason": s["stop_reason"]})
            self.last = res
            return res

        runner.run_test = run_test


def run_one(test, p, seed, geo, st, cache, log):
    from bpmcal.cost import LEDGER
    from bpmcal.lab.runner import bts_test, ucs_test

    LEDGER.take("screen")
    c0 = time.process_time()
    if test == "ucs":
        run = ucs_test(p, seed, geo, st, cache=cache, threads=1, keep_particles=False)
    else:
        log.discs = []
        run = bts_test(p, seed, geo, st, cache=cache, threads=1, keep_particles=False)
    cpu = time.process_time() - c0
    led = LEDGER.take("screen")
    s = run.summary
    row = {k: _plain(s.get(k)) for k in KEEP[test]}
    n = int(s["n_balls"])
    if test == "ucs":
        ser = run.series
        ip = int(np.argmax(ser["axial_stress"]))
        row.update(n_balls=n, peak_step=int(ser["step"][ip]), loading_steps=int(s["steps"]),
                   particle_steps=n * int(s["steps"]))
    else:
        d = log.discs
        row.update(n_balls=n, disc_runs=d,
                   loading_steps=sum(x["steps"] + x["seat_steps"] for x in d),
                   particle_steps=sum(x["n_balls"] * (x["steps"] + x["seat_steps"]) for x in d))
    row["cpu_s"] = cpu
    ph = {}
    for k, v in led["phases"].items():  # CPU by phase: genesis (packing, build), test
        part = "genesis" if "/genesis" in k else "test" if "/test" in k else "rest"
        part = ("retest_" if k.startswith("bts_retest") else "") + part
        ph[part] = ph.get(part, 0.0) + v
    row["cpu_phases"] = ph
    row["ledger_ball_steps"] = int(sum(led["ball_steps"].values()))
    row["ledger_test_ball_steps"] = int(sum(v for k, v in led["ball_steps"].items()
                                            if "/test/" in k or k.endswith("test/engine")))
    return row, run


def save_series(path: Path, run) -> None:
    arrs = {f"series_{k}": np.asarray(v) for k, v in run.series.items()}
    arrs.update({f"cracks_{k}": np.asarray(v) for k, v in run.cracks.items()})
    np.savez_compressed(path, **arrs)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--samples", default="0:20", help="LO:HI (s000 ...) or s000,s001,...")
    ap.add_argument("--protocols", default='{"ref": {}}',
                    help="JSON (inline or a file): name -> {test: {setting: value}}")
    ap.add_argument("--tests", nargs="+", default=["ucs", "bts"], choices=["ucs", "bts"])
    ap.add_argument("--out", required=True, help="JSON lines, appended (resumes)")
    ap.add_argument("--cache", required=True, help="packing caches, one folder per sample")
    ap.add_argument("--series", help="keep every run's series and cracks here (.npz)")
    a = ap.parse_args(argv)

    from bpmcal.lab.runner import set_threads
    from bpmcal.stages.runs import params_from_design
    from bpmcal.study.config import validate_config

    text = a.protocols
    protos = json.loads(Path(text).read_text() if Path(text).is_file() else text)
    cfg = yaml.safe_load(Path(a.config).read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    geo = study_geometry(cfg)
    disc, bts_st = bts_disc_and_settings(cfg)
    base = {"ucs": (geo, ucs_settings(cfg)), "bts": (disc, bts_st)}
    set_threads(1)
    log = DiscLog()
    log.install()
    out = Path(a.out)
    done = set()
    if out.is_file():
        for line in out.read_text().splitlines():
            r = json.loads(line)
            done.add((r["sample"], r["protocol"], r["test"]))
    ser_dir = Path(a.series) if a.series else None
    if ser_dir:
        ser_dir.mkdir(parents=True, exist_ok=True)
    design = Path(a.cache) / "design.csv"
    design.parent.mkdir(parents=True, exist_ok=True)
    if not design.is_file():
        study_design(cfg).to_csv(design, index=False)
    for sid in _ids(a.samples):
        p, seed, _ = params_from_design(design, sid)
        for name, over in protos.items():
            for test in a.tests:
                if (sid, name, test) in done:
                    continue
                g, st = base[test]
                st = replace(st, **over.get(test, {}))
                row, run = run_one(test, p, seed, g, st, Path(a.cache) / sid, log)
                row = {"sample": sid, "protocol": name, "test": test, **row}
                if ser_dir:
                    save_series(ser_dir / f"{sid}_{name}_{test}.npz", run)
                with out.open("a") as f:
                    f.write(json.dumps(row) + "\n")
                show = {k: row.get(k) for k in ("ucs_MPa", "E_GPa", "nu", "bts_MPa", "discs",
                                                "loading_steps", "cpu_s")}
                print(sid, name, test, show, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
