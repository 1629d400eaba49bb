"""A planted card calibrated back from its own DEM responses: the closed loop and the
fresh-seed check on four targets (sigma_c, E, nu and sigma_t), with the regression of a
finished study.

The planted card (a parameter set inside Table 2; its strength ratio is not the study's)
is run on ``--lab-seeds`` packing seeds, none of which the loop or the fresh-seed check
uses; the means of its UCS and Brazilian tests become a lab row. Then, as the study does:
``bpmcal calibrate`` (sigma_t sets the strength ratio), ``bpmcal verify`` (the closed
loop, the study's verification settings) and ``bpmcal fresh-seeds`` (fresh seeds), all with
the study's specimen, UCS and bts settings. The record: the planted and the returned
parameters, every target's lab value, closed-loop mean, error and tolerance, the
fresh-seed verdicts, the planted card itself judged on the loop's seeds (how far the lab
seeds' mean lies from the loop seeds' mean of the true card), the runs and the CPU time.

    python benchmarks/planted_card.py --study CLONE/results --set pb_coh_MPa=37.5 \\
        --set pb_ten_MPa=30 --out benchmarks/results/results_planted_card_DATE.json \\
        --markdown docs/measurements/DATE-planted-card.md
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import yaml
from _study import CONFIG, REPO, cpu_model, fresh_seed_lines

from bpmcal.cli.jobs import job_argv

#: the planted card by default: Table 2 interior, strength ratio 0.8 (the study's 1.4-1.5)
PLANTED = dict(rmin_mm=0.8, porosity=0.34, pb_emod_GPa=25.0, pb_kratio=2.5, pb_ten_MPa=30.0,
               pb_coh_MPa=37.5, pb_fa_deg=35.0, fric=0.35)


#: the verification settings a planted-card record names (from its config)
LOOP_SETTINGS = ("max_rounds", "seeds_per_round", "max_seeds", "grow_within", "jacobian_update",
                 "tensile_specimens", "tensile_seed_cv", "max_tensile_specimens")


def _run(cmd, log):
    t = time.time()
    r = subprocess.run(cmd, capture_output=True, text=True)
    log.append({"cmd": shlex.join(cmd), "rc": r.returncode, "s": time.time() - t})
    if r.returncode != 0:
        raise SystemExit(f"{shlex.join(cmd)} failed:\n{r.stderr[-3000:]}")
    return r


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", help="the finished study's results folder (required to run)")
    ap.add_argument("--rejudge", nargs="+", metavar="RECORD",
                    help="print the fresh-seed check of these planted-card records (JSON) "
                         "that predate it, from what they kept; runs nothing")
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--lab-seeds", default="1001,1002,1003,1004,1005,1006,1007,1008,1009,1010")
    ap.add_argument("--out", help="the record (JSON; required to run)")
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--exact-lab", action="store_true",
                    help="write the lab values without their standard errors (the loop and "
                         "the fresh-seed check then take them as exact)")
    ap.add_argument("--keep", default=None, metavar="DIR",
                    help="work in DIR and keep it (the cards, rounds.csv, the run files)")
    a = ap.parse_args(argv)
    if a.rejudge:  # no runs: the check applied to records that predate it
        print(rejudge_markdown(a.rejudge))
        return 0
    if not (a.study and a.out):
        ap.error("--study and --out are required to run a planted card")
    from bpmcal.study.config import validate_config

    cfg = yaml.safe_load(Path(a.config).read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    planted = dict(PLANTED)
    for kv in a.set:
        k, v = kv.split("=", 1)
        planted[k] = float(v)
    study = Path(a.study)
    v = cfg["verification"]
    # the loop's and the fresh seeds' seeds side by side, as the study runs them (the
    # rows do not depend on it)
    loop_threads = cfg["resources"]["loop_threads"]
    log: list[dict] = []
    cpu0 = time.process_time()
    c0 = os.times()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(a.keep) if a.keep else Path(tmp)
        tmp.mkdir(parents=True, exist_ok=True)
        cache = str(tmp / "packings")

        def job(name, *, threads=1, **files):
            """The study's command of job ``name`` (bpmcal.cli.jobs.job_argv: every setting
            of --config, for a lab with a σt target) on these files, quiet."""
            return ["bpmcal", *job_argv(cfg, name, threads=threads, targets={"bts"},
                                        cache=cache, **files), "--quiet"]

        pf = tmp / "planted.yaml"
        # a --keep folder of the same planted card: its lab runs are read, not run again
        same = pf.exists() and yaml.safe_load(pf.read_text()) == planted
        pf.write_text(yaml.safe_dump(planted))
        reused: list[int] = []  # lab seeds whose runs the --keep folder had

        def run_lab(seeds):  # the lab's specimens: the planted card, one disc per seed
            from bpmcal.io.h5 import read_summary

            out = []
            for s in seeds:
                if same and (tmp / f"lab{s}.h5").exists() and (tmp / f"lab{s}.bts.h5").exists():
                    reused.append(s)
                else:
                    # the study's sample job on the planted card (a failed run stops here)
                    cmd = job("sample", output={"ucs": str(tmp / f"lab{s}.h5"),
                                                "bts": str(tmp / f"lab{s}.bts.h5")})
                    _run([a for a in cmd if a != "--failed-ok"]
                         + ["--params", str(pf), "--seed", str(s)], log)
                us = read_summary(tmp / f"lab{s}.h5")
                bs = read_summary(tmp / f"lab{s}.bts.h5")
                out.append({"seed": s, "ucs_MPa": us["ucs_MPa"], "E_GPa": us["E_GPa"],
                            "nu": us["nu"], "bts_MPa": bs["bts_MPa"],
                            "bts_valid": bool(bs["bts_valid"])})
            return out

        rows = run_lab([int(x) for x in a.lab_seeds.split(",")])
        labs = pd.DataFrame(rows)
        valid = labs[labs["bts_valid"]]
        lab = {k: float(labs[k].mean()) for k in ("ucs_MPa", "E_GPa", "nu")}
        lab["bts_MPa"] = float(valid["bts_MPa"].mean())
        # the lab values are means over the lab seeds: their standard errors, unless
        # --exact-lab (then the loop takes them as exact, as it did before target_se)
        lab_se = {} if a.exact_lab else {
            k: float((valid if k == "bts_MPa" else labs)[k].std(ddof=1)
                     / len(valid if k == "bts_MPa" else labs) ** 0.5) for k in lab}
        lab_csv = tmp / "lab.csv"
        se_cols = "".join(f",{k}_se" for k in lab_se)
        lab_csv.write_text(f"specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3,bts_MPa{se_cols}\nP1,"
                           + ",".join(repr(lab[k]) for k in ("ucs_MPa", "E_GPa", "nu"))
                           + f",,{lab['bts_MPa']!r}"
                           + "".join(f",{v!r}" for v in lab_se.values()) + "\n")
        card = tmp / "P1.yaml"
        models = str(study / "regression" / "models.json")
        # the study's initial calibration, the calibration section's fixed parameters at
        # the planted card's values
        c = cfg["calibration"]
        planted_cfg = {**cfg, "calibration": {**c, "fixed": {k: planted[k] for k in c["fixed"]}}}
        _run(["bpmcal", *job_argv(planted_cfg, "calibrate_initial", input={
            "dataset": str(study / "dataset.csv"), "models": models, "lab": str(lab_csv)},
            output={"cards": str(card)})], log)
        verified = tmp / "P1.verified.yaml"
        # the study's closed loop for a card with a σt target (every loop setting of the
        # verification section, the adaptive tensile specimens per seed too)
        _run(job("verify", threads=loop_threads, input={"card": str(card), "models": models},
                 output={"card": str(verified), "rounds": str(tmp / "rounds.csv"),
                         "run": str(tmp / "best.h5")}), log)
        # the fresh-seed check measures σt as the card's loop did
        seeds = [int(s) for s in v["fresh_seeds"]]
        _run(job("fresh_seeds", threads=loop_threads, input={"card": str(verified)}, output={
            "runs": [str(tmp / f"h{s}.h5") for s in seeds],
            "bts_runs": [str(tmp / f"h{s}.bts.h5") for s in seeds],
            "seed_runs": str(tmp / "fresh_seeds.csv")}), log)
        _run(["bpmcal", *job_argv(cfg, "fresh_seeds_table", input={
            "cards": [str(verified)], "seed_runs": [str(tmp / "fresh_seeds.csv")]},
            output={"table": str(tmp / "fresh_seeds_table.csv")})], log)
        cal = yaml.safe_load(card.read_text())
        ver = yaml.safe_load(verified.read_text())["verification"]
        # the planted card itself on the seeds of the loop's card round, measured as the
        # loop measures (σt the mean of the loop's tensile specimens per seed): how far
        # the lab seeds' mean lies from the loop seeds' mean of the true card
        own = _judge(own_runs(verified, planted, [int(s) for s in ver["seeds"]], tmp,
                              job, loop_threads, log),
                     lab, float(v["rtol"]), lab_se)
        hold = pd.read_csv(tmp / "fresh_seeds_table.csv")
        rounds = pd.read_csv(tmp / "rounds.csv")
    c1 = os.times()
    rec = {
        "date": dt.date.today().isoformat(), "cpu_model": cpu_model(), "cpus": os.cpu_count(),
        "load_average": os.getloadavg(),
        "command": "python benchmarks/planted_card.py " + shlex.join(argv),
        "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO,
                                 capture_output=True, text=True).stdout.strip(),
        "planted": planted, "lab_seeds": rows, "lab": lab, "lab_se": lab_se,
        "calibration": {"status": cal["status"], "parameters": cal["parameters"],
                        "strength_ratio": cal["strength_ratio"]},
        "verification": {k: ver[k] for k in ("status", "message", "rounds", "runs",
                                             "n_seeds", "parameters", "missed")},
        "closed_loop": {k: {"mean": ver["closed_loop"][k],
                            "err_pct": ver["closed_loop"]["errors_pct"][k],
                            "seed_cv": ver["closed_loop"]["seed_cv"].get(k)}
                        for k in lab},
        "tolerance_pct": {k: 100 * float(rounds.iloc[ver["best_round"] - 1][f"tol_{k}"])
                          for k in lab},
        "holdout": hold.to_dict("records"), "planted_on_loop_seeds": own,
        "own_tensile_specimens": int(ver.get("tensile_specimens", 1)),  # the card's count
        "tensile": ver.get("tensile"),
        "reused_runs": reused,
        # the loop's settings from --config (a config other than the default one can
        # change them; the record names them)
        "loop_settings": {k: v[k] for k in LOOP_SETTINGS if k in v},
        "cpu_s_children": (c1.children_user + c1.children_system)
                          - (c0.children_user + c0.children_system),
        "cpu_s_self": time.process_time() - cpu0, "commands": log,
    }
    # the loop's rounds (parameters, means, errors, tolerances, steps) beside the record
    rounds_csv = Path(a.out).with_name(rounds_name(a.out))
    rec["rounds_csv"] = os.path.relpath(rounds_csv.resolve(), REPO)
    rounds.to_csv(rounds_csv, index=False)
    Path(a.out).write_text(json.dumps(rec, indent=1, default=float) + "\n")
    text = markdown(rec)
    if a.markdown:
        Path(a.markdown).write_text(text)
    print(text)
    return 0


def own_runs(verified: Path, planted: dict, seeds: list, tmp: Path, job, threads: int,
             log) -> pd.DataFrame:
    """The planted card on ``seeds`` as the closed loop ran them: the study's fresh-seeds
    job (``job``: the planted record's command builder) of a copy of the verified card with
    the planted parameters (its specimens, settings and tensile specimens per seed).
    Returns the seed rows; ``bts_valid``: σt was measured."""
    card = yaml.safe_load(verified.read_text())
    card["parameters"] = {**card["parameters"], **planted}
    # the card stands for its loop's parameters (io.card.card_parameters): planted there
    card["verification"]["parameters"] = {**card["verification"]["parameters"], **planted}
    card["verification"]["seeds"] = []  # the planted card was fitted on no seed
    card.pop("transfer", None)
    own = tmp / "own.yaml"
    own.write_text(yaml.safe_dump(card))
    table = tmp / "own_seeds.csv"
    cmd = job("fresh_seeds", threads=threads, input={"card": str(own)}, output={
        "runs": [str(tmp / f"own{s}.h5") for s in seeds],
        "bts_runs": [str(tmp / f"own{s}.bts.h5") for s in seeds], "seed_runs": str(table)})
    i = cmd.index("--seeds")  # the loop's seeds, not the config's fresh ones
    _run([*cmd[:i + 1], ",".join(map(str, seeds)), *cmd[i + 2:]], log)
    runs = pd.read_csv(table)
    return runs.assign(bts_valid=runs["bts_MPa"].notna())


def rounds_name(out: str) -> str:
    """The file name of a record's closed-loop rounds (CSV, beside the record ``out``)."""
    return Path(out).stem.replace("results_planted_card_", "results_planted_card_rounds_") + ".csv"


def _rounds_path(rounds_csv: str) -> str:
    """The path of a record's rounds CSV: the record's own (relative to the repository);
    a bare name, from a record written before they moved to benchmarks/results/, lay in
    benchmarks/."""
    return rounds_csv if "/" in rounds_csv else f"benchmarks/{rounds_csv}"


def _loop_tensile_specimens(rec: dict) -> int:
    """The closed loop's tensile specimens per seed, from the record's verify command."""
    for c in rec.get("commands", []):
        words = c["cmd"].split()
        if words[:2] == ["bpmcal", "verify"] and "--tensile-specimens" in words:
            return int(words[words.index("--tensile-specimens") + 1])
    return 1


def _judge(runs: pd.DataFrame, lab: dict, rtol: float, lab_se: dict | None = None) -> dict:
    """Mean, error against the lab value and tolerance max(rtol, 2 SE) of every target
    over ``runs`` (sigma_t over the valid discs), as the closed loop judges a round (SE
    with the lab value's own standard error when ``lab_se`` gives it)."""
    out = {}
    for k in lab:
        x = runs.loc[runs["bts_valid"], k] if k == "bts_MPa" else runs[k]
        m = float(x.mean())
        se = float(x.std(ddof=1) / len(x) ** 0.5 / abs(m)) if len(x) > 1 else 0.0
        se = (se ** 2 + ((lab_se or {}).get(k, 0.0) / abs(lab[k])) ** 2) ** 0.5
        out[k] = {"n": int(len(x)), "mean": m, "err_pct": 100 * (m / lab[k] - 1),
                  "tol_pct": 100 * max(rtol, 2 * se)}
    return out


def markdown(rec: dict) -> str:
    p, got = rec["planted"], rec["verification"]["parameters"] or {}
    lines = [f"# A planted card calibrated back from its DEM responses: {rec['date']}", "",
             f"Host: {rec['cpu_model']} ({rec['cpus']} CPUs), commit {rec['commit']}, load "
             f"average when recorded {', '.join(f'{x:.2f}' for x in rec['load_average'])}; "
             f"CPU time of the runs {rec['cpu_s_children'] / 60:.1f} min"
             + (f" (the runs of {len(rec['reused_runs'])} lab seeds were read from the --keep "
                "folder of an earlier run of the same planted card, not run again)"
                if rec.get("reused_runs") else "") + ".", "",
             f"Command: `{rec['command']}`", "",
             f"Lab values: the means of the planted card over {len(rec['lab_seeds'])} packing "
             f"seeds (σt over the valid discs: "
             f"{sum(r['bts_valid'] for r in rec['lab_seeds'])} of {len(rec['lab_seeds'])})"
             + (", given to the study with their standard errors (`<target>_se`: "
                + ", ".join(f"{k} {v:.3g}" for k, v in rec["lab_se"].items())
                + "); the loop's and the fresh seeds' tolerance is then max(1 %, "
                  "2 sqrt(SE² + SE_lab²))." if rec.get("lab_se") else "."),
             "", "| parameter | planted | calibrated (regression) | verified (closed loop) |",
             "|---|---|---|---|"]
    for k in ("pb_emod_GPa", "pb_kratio", "pb_ten_MPa", "pb_coh_MPa"):
        lines.append(f"| {k} | {p[k]:g} | {rec['calibration']['parameters'][k]:.4g} | "
                     f"{got.get(k, float('nan')):.4g} |")
    v = rec["verification"]
    lines += ["", f"Closed loop: {v['status']} after {v['rounds']} round(s), {v['runs']} runs "
                  f"({v['n_seeds']} seeds in the card's round): {v['message']}"
              + (f" (every round: `{_rounds_path(rec['rounds_csv'])}`)" if rec.get("rounds_csv")
                 else ""), "",
              "| target | lab | closed-loop mean | error | tolerance "
              + ("max(1 %, 2 sqrt(SE² + SE_lab²))" if rec.get("lab_se") else "max(1 %, 2 SE)")
              + " | seed CV |",
              "|---|---|---|---|---|---|"]
    for k, c in rec["closed_loop"].items():
        cv = c["seed_cv"]
        lines.append(f"| {k} | {rec['lab'][k]:.4g} | {c['mean']:.4g} | {c['err_pct']:+.2f} % | "
                     f"{rec['tolerance_pct'][k]:.2f} % | "
                     f"{'–' if cv is None else f'{100 * cv:.1f} %'} |")
    if rec.get("tensile"):  # the loop adapted its discs per seed to the card
        from bpmcal.stages.verification_tables import tensile_note

        t = rec["tensile"]
        note = tensile_note({"tensile": t, "tensile_specimens": rec["own_tensile_specimens"]})
        lines += ["", "Discs per seed (`verification.tensile_seed_cv` "
                      f"{t['seed_cv_target']:g}, from {t['start']}, at most {t['max']}): "
                  + (note or f"σt of a seed: the mean of {rec['own_tensile_specimens']} "
                             f"discs, not raised (the discs scatter "
                             f"{100 * t.get('specimen_cv', float('nan')):.1f} %, a seed's σt "
                             f"{100 * t.get('seed_cv_expected', float('nan')):.1f} % expected)")
                  + "."]
    own = rec.get("planted_on_loop_seeds")
    if own:
        m = rec.get("own_tensile_specimens", 1)  # older records: one disc per seed
        loop_m = _loop_tensile_specimens(rec)
        lines += ["", "The planted card itself on the seeds of the loop's card round (the lab "
                      "values come from other seeds): judged as the loop judges a round"
                  + (f", σt the mean of {m} discs per seed as the loop measured it" if m > 1
                     else f", but σt on one disc per seed where the loop's σt was the mean of "
                          f"{loop_m}" if loop_m > 1 else ""), "",
                  "| target | n | mean | error against the lab | tolerance "
                  + ("max(1 %, 2 sqrt(SE² + SE_lab²))" if rec.get("lab_se") else "max(1 %, 2 SE)")
                  + " | within |",
                  "|---|---|---|---|---|---|"]
        for k, o in own.items():
            lines.append(f"| {k} | {o['n']} | {o['mean']:.4g} | {o['err_pct']:+.2f} % | "
                         f"{o['tol_pct']:.2f} % | {abs(o['err_pct']) <= o['tol_pct']} |")
    # the record key and this line keep the old name (bpmcal holdout, now fresh-seeds): the
    # dated pages in docs/measurements are rendered from their records with this text
    lines += ["", "Fresh seeds (`bpmcal holdout`, the study's holdout seeds):", "",
              *fresh_seed_lines(rec["holdout"], "2 sqrt(SE² + SE_lab²)" if rec.get("lab_se")
                                else "2 SE")]
    if rec.get("tensile"):  # the σt seed CV the target reads: over the fresh seeds
        h = next(h for h in rec["holdout"] if h["response"] == "bts_MPa")
        lines += ["", f"σt seed CV over the {h['n']} fresh seeds "
                      f"({rec['own_tensile_specimens']} discs per seed): "
                      f"{float(h['cv_pct']):.1f} %; over the loop's {rec['verification']['n_seeds']} "
                      f"seeds of the card's round: "
                      f"{100 * rec['closed_loop']['bts_MPa']['seed_cv']:.1f} %."]
    if any("passed" in h for h in rec["holdout"]):
        missed = [h["response"] for h in rec["holdout"] if not h["passed"]]
        ok = v["status"] == "converged" and not missed
        lines += ["", "The fresh-seed check (the fresh seeds against the closed loop's mean, "
                      f"at 2 normal standard errors shared among the {len(rec['holdout'])} "
                      "targets): "
                  + ("passed on every target" if not missed else "not passed on " + ", ".join(
                      missed)) + f". The planted-card target (the loop converges and the "
                  f"check passes): **{'met' if ok else 'not met'}**."]
    if rec.get("loop_settings"):
        lines += ["", "The loop's settings (the `verification` section of the command's "
                      "config): " + ", ".join(f"`{k}` {val}" for k, val
                                             in rec["loop_settings"].items()) + "."]
    if rec.get("note"):  # a hand-written note added to the record (JSON key "note")
        lines += ["", rec["note"]]
    return "\n".join(lines) + "\n"


def rejudge(rec: dict, z: float = 2.0) -> list[dict]:
    """The fresh-seed check of ``bpmcal fresh-seeds-table`` (the fresh seeds against the
    card's closed-loop mean: :func:`~bpmcal.stages.fresh_seeds.two_sample_check`, its
    targets sharing the level) applied to a planted-card record from before the check,
    from what it kept: each target's fresh mean, SD and count (``holdout``), the closed
    loop's mean and seed CV over its ``n_seeds`` (every seed gave σt in these loops:
    an invalid disc is replaced). One row per target, with the record's lab verdict."""
    from bpmcal.stages.fresh_seeds import two_sample_check

    n_loop, loop, out = rec["verification"]["n_seeds"], rec["closed_loop"], []
    for h in rec["holdout"]:
        k = h["response"]
        c = two_sample_check(float(h["mean"]), float(h["sd"]), int(h["n"]),
                             loop_mean=loop[k]["mean"], loop_sd=loop[k]["seed_cv"] * loop[k]["mean"],
                             loop_n=n_loop, lab=rec["lab"][k], z=z, targets=len(rec["holdout"]))
        out.append({"response": k, "loop_n": n_loop, "loop_mean": loop[k]["mean"], "n": h["n"],
                    "mean": h["mean"], "err_pct": h["err_pct"], "z_score": h["z_score"],
                    "within_z_se": h["within_z_se"], **c})
    return out


def rejudge_markdown(paths: list[str]) -> str:
    """The table of :func:`rejudge` over the records ``paths``: record, loop status,
    target, the closed loop's and the fresh seeds' means, their difference, t and its
    limit, the check's verdict beside the record's verdict against the lab."""
    lines = ["| record | closed loop | target | loop mean (seeds) | fresh mean (seeds) | "
             "fresh − loop | t (limit) | passed | against the lab: error, z, within 2 SE |",
             "|---|---|---|---|---|---|---|---|---|"]
    for f in paths:
        rec = json.loads(Path(f).read_text())
        for r in rejudge(rec):
            lines.append(
                f"| {Path(f).name} | {rec['verification']['status']} | {r['response']} | "
                f"{r['loop_mean']:.4g} ({r['loop_n']}) | {float(r['mean']):.4g} ({r['n']}) | "
                f"{r['diff_pct']:+.2f} % | {r['t_loop']:+.2f} ({r['t_crit']:.2f}) | "
                f"{r['reproduces_loop']} | {float(r['err_pct']):+.2f} %, "
                f"{float(r['z_score']):+.2f}, {r['within_z_se']} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
