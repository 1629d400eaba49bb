"""A measurement record of what one run of the default study computed, for the comparison
with the paper that the README and the docs quote: Table 3 shares, the regression's
adjusted R², the calibrated cards, the bond-strength ratio, Table 5 (single pass and
closed loop), Table 6, the packing-seed scatter, the fresh-seed check and the 6 m/s
impact, read from the run's ``results/`` (the report's ``tables/comparison.csv`` and the
stage tables beside it).

    python benchmarks/study_outputs.py CLONE --commit COMMIT \\
        --out benchmarks/results/results_study_outputs_DATE.json \\
        --markdown docs/measurements/DATE-default-study-results.md

``CLONE`` is the clone the study ran in (``snakemake --cores 2`` on
``config/config.yaml``); ``--commit`` is its commit (checked against the clone's git
``HEAD`` when it is a git checkout). The record carries the date, the host's CPU model,
the load average and this command; the Markdown page is rendered from the JSON
(``markdown``), and ``benchmarks/figures.py`` takes the quoted figures from it.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml
from _study import record_header, write_record

#: responses of Table 3 and their names in the record
RESPONSES = {"ucs_MPa": "σc", "E_GPa": "E", "nu": "ν", "bts_MPa": "σt"}
#: the calibrated parameters the README's table shows
CARD = ("pb_emod_GPa", "pb_kratio", "pb_ten_MPa", "pb_coh_MPa")


def _head(clone: Path) -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=clone,
                             capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    return out.stdout.strip() or None


def outputs(results: Path) -> dict:
    """The figures of one study run, from its ``results/`` folder."""
    out: dict = {}
    t3 = pd.read_csv(results / "tables" / "table3_importance.csv").set_index("feature")
    out["table3"] = {r: {f: float(t3.loc[f, r]) for f in t3.index}
                     for r in RESPONSES if r in t3.columns}
    fit = pd.read_csv(results / "tables" / "regression_fit.csv")
    out["adj_r2"] = {f"{r.response}/{r.stage}": float(r.adj_r2) for r in fit.itertuples()}
    cal = pd.read_csv(results / "tables" / "calibration.csv").set_index("specimen")
    out["calibration"] = {s: {p: float(cal.loc[s, p]) for p in CARD} | {
        "status": str(cal.loc[s, "status"])} for s in cal.index}
    chosen = json.loads((results / "ratio_sweep" / "chosen.json").read_text())
    out["ratio"] = {"chosen": chosen["chosen_ratio"], "criterion": chosen["criterion"],
                    "target": chosen["target"], "value": chosen["value"]}
    t5 = pd.read_csv(results / "tables" / "table5_verification.csv").set_index("specimen")
    t5_out = {}
    for s in t5.index:
        row = {}
        for stage in ("single_pass", "closed_loop"):
            errs = {r: float(t5.loc[s, f"{stage}_{r}_err_pct"]) for r in ("ucs_MPa", "E_GPa", "nu")}
            worst = max(errs, key=lambda k: abs(errs[k]))
            row[stage] = {"err_pct": errs, "largest_abs_err_pct": abs(errs[worst]),
                          "largest_response": worst}
        row["n_seeds"] = int(t5.loc[s, "n_seeds"])
        row["rounds"] = int(t5.loc[s, "rounds"])
        row["status"] = str(t5.loc[s, "status"])
        note = t5.loc[s, "note"]
        row["note"] = "" if isinstance(note, float) and math.isnan(note) else str(note)
        t5_out[s] = row
    out["table5"] = t5_out
    t6 = pd.read_csv(results / "tables" / "table6_prepeak_energy.csv").set_index("specimen")
    out["table6_up_err_pct"] = {s: float(t6.loc[s, "rel_error_pct"]) for s in t6.index}
    sc = pd.read_csv(results / "verification" / "seed_scatter" / "seed_scatter.csv")
    out["seed_scatter"] = {r.response: {"specimen": r.specimen, "n": int(r.n),
                                        "cv_pct": 100.0 * float(r.cv)} for r in sc.itertuples()}
    ho = pd.read_csv(results / "tables" / "fresh_seeds.csv")
    # the key keeps the old name: the dated records and benchmarks/figures.py use it
    out["holdout"] = {"seeds": str(ho["seeds"].iloc[0]), "targets": len(ho),
                      "within_2se": int(ho["within_z_se"].sum()),
                      "met": int(ho["met"].sum())}
    if "passed" in ho.columns:  # the check against the closed loop (tables since 2026-11-28)
        tg = ho[ho["role"] == "target"]
        out["holdout"]["passed"] = int(tg["passed"].astype(bool).sum())
        out["holdout"]["judged"] = len(tg)
    # σt of each verified card on the fresh seeds: its seed CV, and the discs per seed
    bt = ho[ho["response"] == "bts_MPa"]
    if len(bt):
        out["holdout"]["sigma_t"] = {
            r.specimen: {"n": int(r.n), "mean_MPa": float(r.mean), "cv_pct": float(r.cv_pct),
                         "discs_per_seed": int((yaml.safe_load((
                             results / "verification" / r.specimen / "card.yaml").read_text())
                             .get("verification") or {}).get("tensile_specimens", 1))}
            for r in bt.itertuples()}
    comp = pd.read_csv(results / "report" / "tables" / "comparison.csv")
    imp = comp[comp["section"] == "Impact"].set_index("quantity")
    w = imp.loc["W_in at 6 m/s, full-size equivalent"]
    e = imp.loc["eta_f = G_f / W_in"]
    energy = pd.read_csv(results / "tables" / "impact_energy.csv")
    out["impact_6ms"] = {"W_in_full_size_J": float(w["ours"]), "W_in_paper_J": float(w["paper"]),
                         "eta_f": float(e["ours"]), "eta_f_paper": float(e["paper"]),
                         "end_time_ms": 1e3 * float(energy["time"].iloc[-1]),
                         "closure_max_rel": float(energy["closure_rel"].abs().max())}
    return out


def _pct(x: float, nd: int = 1) -> str:
    return f"{x:.{nd}f} %"


def markdown(rec: dict) -> str:
    """The record's Markdown page (rendered from the JSON only)."""
    o = rec["outputs"]
    lines = [f"# The default study's outputs against the paper: {rec['date']}", "",
             "| | |", "|---|---|",
             f"| date | {rec['date']} |", f"| commit | {rec['commit']} |",
             f"| host | {rec['cpu_model']} ({rec['cpus']} CPUs) |",
             f"| load | load average when recorded {', '.join(f'{x:.2f}' for x in rec['load_average'])} |",
             f"| study | `{rec['study_command']}` in `{rec['clone']}` |",
             f"| recorded with | `{rec['command']}` |",
             f"| raw | `{rec['raw']}` |", "",
             "The run's time is in the default-study time record of the same date.", "",
             "## Table 3: XGBoost importance shares (%)", "",
             "| feature | " + " | ".join(RESPONSES[r] for r in o["table3"]) + " |",
             "|---|" + "---|" * len(o["table3"])]
    feats = next(iter(o["table3"].values())).keys()
    for f in feats:
        lines.append(f"| {f} | " + " | ".join(f"{o['table3'][r][f]:.1f}" for r in o["table3"]) + " |")
    lines += ["", "## Regression: adjusted R²", "", "| response | main | quadratic | interaction |",
              "|---|---|---|---|"]
    for r in RESPONSES:
        v = [o["adj_r2"].get(f"{r}/{s}") for s in ("main", "quadratic", "interaction")]
        if v[0] is not None:
            lines.append(f"| {RESPONSES[r]} | " + " | ".join(f"{x:.3f}" for x in v) + " |")
    lines += ["", "## Calibrated cards (single pass) and the bond-strength ratio", "",
              "| specimen | status | " + " | ".join(CARD) + " |", "|---|---|" + "---|" * len(CARD)]
    for s, c in o["calibration"].items():
        lines.append(f"| {s} | {c['status']} | " + " | ".join(f"{c[p]:.2f}" for p in CARD) + " |")
    r = o["ratio"]
    lines += ["", f"Chosen ratio a = {r['chosen']} ({r['criterion']} {r['value']:.3f}, "
                  f"target {r['target']}).", "",
              "## Table 5 and Table 6", "",
              "| specimen | single pass: largest error | closed loop: largest error | seeds | rounds "
              "| status | Table 6: Up error | note |", "|---|---|---|---|---|---|---|---|"]
    for s, t in o["table5"].items():
        sp, cl = t["single_pass"], t["closed_loop"]
        lines.append(f"| {s} | {_pct(sp['largest_abs_err_pct'], 2)} ({sp['largest_response']}) | "
                     f"{_pct(cl['largest_abs_err_pct'], 2)} ({cl['largest_response']}) | "
                     f"{t['n_seeds']} | {t['rounds']} | {t['status']} | "
                     f"{_pct(o['table6_up_err_pct'][s])} | {t['note']} |")
    h, i = o["holdout"], o["impact_6ms"]
    lines += ["", "## Seed scatter, fresh seeds, impact", "",
              "Packing-seed scatter of one calibrated set (CV of one run): "
              + ", ".join(f"{RESPONSES[k]} {_pct(v['cv_pct'])} ({v['specimen']}, {v['n']} seeds)"
                          for k, v in o["seed_scatter"].items()) + ".", "",
              (f"Fresh-seed check (seeds {h['seeds']}, against each card's closed loop): "
               f"{h['passed']} of {h['judged']} targets passed. Against the lab: "
               if "passed" in h else f"Fresh-seed check (seeds {h['seeds']}): ")
              + f"{h['within_2se']} of {h['targets']} targets "
              f"within 2 standard errors; {h['met']} of {h['targets']} met."
              + ("" if "sigma_t" not in h else " σt on the fresh seeds (mean, seed CV, discs "
                 "per seed): " + "; ".join(
                     f"{k} {v['mean_MPa']:.2f} MPa, {_pct(v['cv_pct'])}, {v['discs_per_seed']}"
                     for k, v in h["sigma_t"].items()) + "."), "",
              f"Impact at 6 m/s: W_in (full-size equivalent) {i['W_in_full_size_J']:.1f} J "
              f"(paper {i['W_in_paper_J']:.1f} J), η_f {_pct(100 * i['eta_f'])} (paper "
              f"{_pct(100 * i['eta_f_paper'])}); run ended at {i['end_time_ms']:.1f} ms; "
              f"largest energy-budget residual {_pct(100 * i['closure_max_rel'], 2)}."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clone", help="the clone the default study ran in")
    ap.add_argument("--commit", required=True)
    ap.add_argument("--study-command", default="snakemake --cores 2",
                    help="the command the study ran with")
    ap.add_argument("--out", required=True)
    ap.add_argument("--markdown", default=None)
    a = ap.parse_args(argv)
    clone = Path(a.clone)
    head = _head(clone)
    if head is not None and not a.commit.startswith(head) and not head.startswith(a.commit):
        ap.error(f"--commit {a.commit} is not the clone's HEAD {head}")
    rec = {**record_header("study_outputs.py", argv), "commit": a.commit, "clone": str(clone),
           "study_command": a.study_command, "raw": a.out,
           "outputs": outputs(clone / "results")}
    write_record(rec, a.out, a.markdown, markdown, ensure_ascii=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
