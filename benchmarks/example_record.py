"""A measurement record of one finished own-rock study (an example config run in a clone):
what each lab specimen's card reached and at what cost, for either contact model.

    python benchmarks/example_record.py CLONE --configfile config/examples/X.yaml \\
        --time CLONE.time --load CLONE.load --commit COMMIT --note "..." \\
        --out benchmarks/results/results_example_NAME_DATE.json \\
        --markdown docs/measurements/DATE-NAME.md

``CLONE`` holds the finished study (``snakemake --cores 2 --configfile ...`` run under
``/usr/bin/time -v``, whose output is ``--time``; ``--load`` the ``uptime`` lines before
and after). A study run in parts (e.g. ``--until calibrate``, then the rest) gives one
``--time`` and one ``--load`` file per part: the record sums the times (peak memory: the
largest) and keeps every part's. The record: the contact model, the regression card (status, parameters,
predicted responses), the closed loop (status, rounds, runs, every target's mean, error
and tolerance), the fresh-seed check (mean, error, z-score, verdict per target), the
triaxial envelopes (Hoek-Brown mi of the verified card beside the lab points'), and the
study's wall and CPU time. ``markdown`` renders the JSON (the docs test re-renders it).
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import shlex
import sys
from pathlib import Path

import pandas as pd
import yaml
from _study import REPO, cpu_model, fresh_seed_lines, gnu_time


def _merged(clone: Path, overlays: list[str]) -> dict:
    sys.path.insert(0, str(REPO / "tests"))
    from support.repo import update_config

    cfg = yaml.safe_load((clone / "config" / "config.yaml").read_text())
    for o in overlays:
        update_config(cfg, yaml.safe_load((clone / o).read_text()))
    return cfg


def collect(clone: Path, overlays: list[str]) -> dict:
    cfg = _merged(clone, overlays)
    out = clone / cfg["outdir"]
    lab = pd.read_csv(clone / cfg["lab"]["csv"], comment="#")
    rec = {"contact_model": cfg.get("contact_model", "linearpbond"), "outdir": cfg["outdir"],
           "n_samples": cfg["study"]["n_samples"], "scale": cfg["specimen"]["scale"],
           "design_sigma3_MPa": (cfg.get("triaxial") or {}).get("design_sigma3_MPa"),
           "specimens": {}}
    hold = out / "tables" / "fresh_seeds.csv"
    hold = pd.read_csv(hold) if hold.exists() else None
    env = out / "tables" / "triaxial_envelopes.csv"
    env = pd.read_csv(env) if env.exists() else None
    for spec in lab["specimen"].astype(str):
        card = yaml.safe_load((out / "calibration" / f"{spec}.yaml").read_text())
        s = {"calibrated": {"status": card["status"], "parameters": card["parameters"],
                            "predicted": card.get("predicted"), "targets": card["targets"],
                            "strength_ratio": card.get("strength_ratio")}}
        vpath = out / "verification" / spec / "card.yaml"
        if vpath.exists():
            v = yaml.safe_load(vpath.read_text())["verification"]
            rounds = pd.read_csv(out / "verification" / spec / "rounds.csv")
            best = rounds.iloc[v["best_round"] - 1]
            s["verified"] = {
                "status": v["status"], "message": v["message"], "rounds": v["rounds"],
                "runs": v["runs"], "n_seeds": v["n_seeds"], "parameters": v["parameters"],
                "targets": {k: {"mean": v["closed_loop"][k],
                                "err_pct": v["closed_loop"]["errors_pct"][k],
                                "tol_pct": 100 * float(best[f"tol_{k}"]),
                                "seed_cv_pct": 100 * float(v["closed_loop"]["seed_cv"].get(k, float("nan")))}
                            for k in card["targets"]}}
        if hold is not None:
            h = hold[(hold["specimen"].astype(str) == spec) & (hold["role"] == "target")]
            keys = ("response", "n", "mean", "err_pct", "z_score", "within_z_se",
                    # the check against the closed loop (tables from before it lack them)
                    "judged_by", "diff_pct", "t_loop", "t_crit", "passed")
            s["fresh_seeds"] = [{k: r[k] for k in keys if k in r} for r in h.to_dict("records")]
        if env is not None:
            e = env[env["specimen"].astype(str) == spec]
            s["envelopes"] = [{k: r[k] for k in ("card", "status", "mi", "phi_deg", "c_MPa")}
                              for r in e.to_dict("records")]
        rec["specimens"][spec] = s
    return rec


def rejudge(rec: dict, lab_csv: str, z: float = 2.0, triaxial_seeds: int | None = None) -> list[dict]:
    """The fresh-seed check of ``bpmcal fresh-seeds-table`` (each specimen's fresh seeds
    against its closed-loop mean, the card's targets sharing the level:
    :func:`~bpmcal.stages.fresh_seeds.two_sample_check`) applied to an example record from
    before the check, from what it kept: the fresh seeds' mean, count and z-score against
    the lab value of ``lab_csv`` (their SD is the z-score's standard error times sqrt(n),
    with the lab value's own ``<target>_se`` taken out), the loop's mean, seed CV and seed
    count (σ1's: ``triaxial_seeds``, the loop's first seeds that ran the triaxial test,
    when its config capped them; the record does not keep it). One row per specimen and
    target."""
    import math

    from bpmcal.stages.fresh_seeds import two_sample_check

    lab = pd.read_csv(REPO / lab_csv, comment="#").set_index("specimen")
    out = []
    for spec, s in rec["specimens"].items():
        v = s["verified"]
        for f in s.get("fresh_seeds") or []:
            k, n = f["response"], int(f["n"])
            lab_v = float(lab.loc[spec, k])
            lab_se = float(lab.loc[spec, f"{k}_se"]) if f"{k}_se" in lab.columns else 0.0
            both = (float(f["mean"]) - lab_v) / float(f["z_score"])
            sd = math.sqrt(max(both ** 2 - lab_se ** 2, 0.0) * n)
            t = v["targets"][k]
            m = triaxial_seeds if k == "tri_MPa" and triaxial_seeds else v["n_seeds"]
            c = two_sample_check(float(f["mean"]), sd, n, loop_mean=t["mean"],
                                 loop_sd=t["seed_cv_pct"] / 100 * t["mean"],
                                 loop_n=m, lab=lab_v, z=z, targets=len(v["targets"]))
            out.append({"specimen": spec, "response": k, "loop_n": m,
                        "loop_mean": t["mean"], "n": n, "mean": f["mean"], "sd": sd,
                        "err_pct": f["err_pct"], "z_score": f["z_score"],
                        "within_z_se": f["within_z_se"], **c})
    return out


def rejudge_markdown(path: str, lab_csv: str, triaxial_seeds: int | None = None) -> str:
    """The table of :func:`rejudge` for the record ``path`` and its lab CSV."""
    rec = json.loads(Path(path).read_text())
    lines = ["| record | target | loop mean (seeds) | fresh mean (seeds) | fresh − loop | "
             "t (limit) | passed | limit of one target alone | against the lab: error, z |",
             "|---|---|---|---|---|---|---|---|---|"]
    from bpmcal.stages.fresh_seeds import check_limit

    for r in rejudge(rec, lab_csv, triaxial_seeds=triaxial_seeds):
        one = check_limit(r["dof"])  # the limit of one target alone
        lines.append(f"| {Path(path).name} | {r['response']} | {r['loop_mean']:.4g} "
                     f"({r['loop_n']}) | {float(r['mean']):.4g} ({r['n']}) | "
                     f"{r['diff_pct']:+.2f} % | {r['t_loop']:+.2f} ({r['t_crit']:.2f}) | "
                     f"{r['reproduces_loop']} | {one:.2f} | {float(r['err_pct']):+.2f} %, "
                     f"{float(r['z_score']):+.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--rejudge"]:  # no runs: the check applied to a record that predates it
        rj = argparse.ArgumentParser(description="the fresh-seed check of an example record")
        rj.add_argument("--rejudge", required=True, metavar="RECORD")
        rj.add_argument("--lab", required=True, help="the lab CSV the record's study used")
        rj.add_argument("--triaxial-seeds", type=int, default=None,
                        help="verification.triaxial_seeds of the record's study, if set")
        r = rj.parse_args(argv)
        print(rejudge_markdown(r.rejudge, r.lab, r.triaxial_seeds))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clone")
    ap.add_argument("--configfile", nargs="+", required=True)
    ap.add_argument("--time", nargs="+", required=True)
    ap.add_argument("--load", nargs="+", required=True)
    ap.add_argument("--commit", required=True)
    ap.add_argument("--title", required=True)
    ap.add_argument("--note", default="")
    ap.add_argument("--out", required=True)
    ap.add_argument("--markdown", required=True)
    a = ap.parse_args(argv)
    clone = Path(a.clone)
    rec = {"title": a.title, "date": dt.date.today().isoformat(), "commit": a.commit,
           "cpu_model": cpu_model(),
           "load": [ln for f in a.load for ln in Path(f).read_text().strip().splitlines()],
           "study_command": "snakemake --cores 2 --configfile " + " ".join(a.configfile),
           "command": "python benchmarks/example_record.py " + shlex.join(argv),
           "note": a.note, "page": Path(a.markdown).name, **_times(a.time),
           **collect(clone, a.configfile)}
    Path(a.out).write_text(json.dumps(rec, indent=1, default=float) + "\n")
    Path(a.markdown).write_text(markdown(rec))
    print(markdown(rec))
    return 0


def _times(files: list[str]) -> dict:
    """The summed ``gnu_time`` of the study's parts (peak memory and exit status: the
    largest), with every part's own under ``parts`` when there are several."""
    parts = [gnu_time(Path(f)) for f in files]
    out = {k: sum(p[k] for p in parts) for k in ("wall_s", "user_s", "system_s", "cpu_min")}
    rss = [p["max_rss_mb"] for p in parts if p["max_rss_mb"] is not None]
    out.update(max_rss_mb=max(rss) if len(rss) == len(parts) else None,
               exit_status=max(p["exit_status"] for p in parts))
    if len(parts) > 1:
        out["parts"] = parts
    return out


def _f(x, fmt=".4g"):
    try:
        return format(float(x), fmt)
    except (TypeError, ValueError):
        return "–"


def markdown(rec: dict) -> str:
    load = " / ".join(x.split("load average:")[-1].strip() for x in rec["load"])
    lines = [f"# {rec['title']} ({rec['date']})", "", "| | |", "|---|---|",
             f"| date | {rec['date']} |", f"| commit | {rec['commit']} |",
             f"| host | {rec['cpu_model']} |",
             f"| load | {load} (before / after) |",
             f"| study | `{rec['study_command']}` |", f"| recorded with | `{rec['command']}` |", "",
             f"Contact model `{rec['contact_model']}`, {rec['n_samples']} samples at scale "
             f"{rec['scale']:g}. Study wall time {rec['wall_s'] / 60:.1f} min, CPU "
             f"{rec['cpu_min']:.1f} min, peak memory of one process "
             + (f"{rec['max_rss_mb']:.0f} MiB." if rec.get("max_rss_mb") is not None
                else "not measured.")
             + (" The study ran in " + str(len(rec["parts"])) + " parts (wall / CPU min: "
                + ", ".join(f"{p['wall_s'] / 60:.1f} / {p['cpu_min']:.1f}" for p in rec["parts"])
                + ")." if rec.get("parts") else "")]
    if rec.get("note"):
        lines += ["", rec["note"]]
    for spec, s in rec["specimens"].items():
        c = s["calibrated"]
        lines += ["", f"## {spec}", "", f"Regression card: **{c['status']}**; strength ratio "
                  f"{_f((c.get('strength_ratio') or {}).get('value'))} "
                  f"(set by {(c.get('strength_ratio') or {}).get('set_by', '–')}).", "",
                  "| parameter | regression card | verified card |", "|---|---|---|"]
        vp = (s.get("verified") or {}).get("parameters") or {}
        for k, x in c["parameters"].items():
            lines.append(f"| {k} | {_f(x)} | {_f(vp.get(k))} |")
        v = s.get("verified")
        if v:
            lines += ["", f"Closed loop: **{v['status']}** after {v['rounds']} round(s), "
                          f"{v['runs']} runs ({v['n_seeds']} seeds in the card's round): "
                          f"{v['message']}", "",
                      "| target | lab | regression predicted | closed-loop mean | error | tolerance "
                      "| seed CV |",
                      "|---|---|---|---|---|---|---|"]
            for k, t in v["targets"].items():
                lines.append(f"| {k} | {_f(c['targets'][k])} | {_f((c.get('predicted') or {}).get(k))} | "
                             f"{_f(t['mean'])} | {t['err_pct']:+.2f} % | {t['tol_pct']:.2f} % | "
                             f"{_f(t['seed_cv_pct'], '.1f')} % |")
        if s.get("fresh_seeds"):
            lines += ["", "Fresh seeds:", "", *fresh_seed_lines(s["fresh_seeds"])]
        if s.get("envelopes"):
            lines += ["", "Triaxial envelopes (Hoek-Brown mi, Mohr-Coulomb φ and c):", "",
                      "| card | status | mi | φ (°) | c (MPa) |", "|---|---|---|---|---|"]
            for e in s["envelopes"]:
                lines.append(f"| {e['card']} | {e['status']} | {_f(e['mi'])} | {_f(e['phi_deg'])} | "
                             f"{_f(e['c_MPa'])} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
