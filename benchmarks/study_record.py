"""A measurement record of whole default-study runs: their time (from ``/usr/bin/time -v``)
and what they measured of sigma_t (the dataset's Brazilian tests and the regression).

Run each study in a fresh clone with empty caches, e.g.

    /usr/bin/time -v snakemake --cores 2 > study.log 2> time.log

then

    python benchmarks/study_record.py --run before=CLONE1,TIME1,COMMIT1 \\
        --run after=CLONE2,TIME2,COMMIT2 --out benchmarks/results/results_default_study_DATE.json \\
        --markdown docs/measurements/DATE-default-study.md

A run is ``label=clone directory,time log,commit``; its results are read from the clone's
``results/`` (``dataset.csv``, ``tables/regression_fit.csv``).
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import pandas as pd
from _study import gnu_time as _time
from _study import record_header, write_record


def _results(clone: Path) -> dict:
    out = {}
    ds = pd.read_csv(clone / "results" / "dataset.csv")
    out["samples"] = len(ds)
    out["ucs_ok"] = int((ds["status"] == "ok").sum())
    if "bts_status" in ds.columns:
        st = ds["bts_status"].value_counts().to_dict()
        out["bts_status"] = {str(k): int(v) for k, v in st.items()}
        out["bts_valid_fraction"] = st.get("ok", 0) / len(ds)
        ok = ds[ds["bts_status"] == "ok"]
        out["bts_MPa_range"] = [float(ok["bts_MPa"].min()), float(ok["bts_MPa"].max())]
        both = ds[(ds["status"] == "ok") & (ds["bts_status"] == "ok")]
        q = both["ucs_MPa"] / both["bts_MPa"]
        out["ucs_over_bts_range"] = [float(q.min()), float(q.max())]
        out["bts_wall_s_median"] = float(ok["bts_wall_s"].median())
        if "bts_balls_across" in ds.columns:
            out["bts_balls_across_range"] = [float(ds["bts_balls_across"].min()),
                                             float(ds["bts_balls_across"].max())]
        if "bts_error" in ds.columns:
            inv = ds[ds["bts_status"] == "invalid"]
            err = inv["bts_error"].fillna("").astype(str)
            out["bts_invalid_reasons"] = {
                "next to a platen": int(err.str.startswith("fracture initiated next").sum()),
                "grown from a platen": int(err.str.startswith("a fracture grew").sum()),
                "off the diameter": int(err.str.startswith(
                    "the fracture did not follow").sum()),
                "no split": int(err.str.contains("did not split").sum())}
        if "bts_discs" in ds.columns:  # Brazilian retests (bts.retests)
            d = ds["bts_discs"].astype(float)
            out["bts_discs"] = {"first_valid": int(((d == 1) & (ds["bts_status"] == "ok")).sum()),
                                "retested": int((d > 1).sum()), "total": int(d.sum()),
                                "samples": int(d.notna().sum())}
    out["ucs_wall_s_median"] = float(ds.loc[ds["status"] == "ok", "wall_s"].median())
    fit = pd.read_csv(clone / "results" / "tables" / "regression_fit.csv")
    out["adj_r2"] = {f"{r.response}/{r.stage}": float(r.adj_r2) for r in fit.itertuples()}
    sel = json.loads((clone / "results" / "screening" / "selected.json").read_text())
    rule = (sel.get("rule") or {}).get("bts_MPa", "threshold")
    out["bts_rule"] = rule
    if "bts_status" in ds.columns and rule != "threshold":
        out["adj_r2_threshold_rule"] = _threshold_rule_r2(clone, ds, sel)
    return out


def _threshold_rule_r2(clone: Path, ds: pd.DataFrame, sel: dict) -> dict:
    """σt's adjusted R² per stage had its candidates been chosen by the paper's threshold
    rule (the screening's gain shares above its threshold), on the same dataset and with
    the regression's default settings: what the study's σt rule changed."""
    from bpmcal.analysis import StepwiseRegression

    imp = pd.read_csv(clone / "results" / "screening" / "importance_all_types.csv")
    t = imp[(imp["response"] == "bts_MPa") & (imp["gain_mean"] > sel["threshold_pct"])]
    cands = list(t.sort_values("gain_mean", ascending=False)["parameter"])
    rows = ds[ds["bts_status"] == "ok"]
    res = StepwiseRegression().fit(rows, {"bts_MPa": cands})
    return {"candidates": cands, **{f"bts_MPa/{k}": float(m.adj_r2)
                                    for k, m in res.models["bts_MPa"].items()}}


_STAMP = r"\[(\w{3} \w{3} +\d+ \d\d:\d\d:\d\d \d{4})\]\n"


def job_times(log: Path) -> dict:
    """Each rule's jobs and the sum of their wall seconds, from Snakemake's log (its
    stderr, which the ``/usr/bin/time`` log also holds): a job runs from its start stamp
    (``[date]`` then ``rule NAME:``) to its ``Finished jobid`` stamp. With ``--cores 1`` one
    job runs at a time, so a rule's sum is its share of the run's wall time."""
    import datetime as dt

    text = log.read_text()

    def when(stamp):
        return dt.datetime.strptime(" ".join(stamp.split()), "%a %b %d %H:%M:%S %Y")

    start = {}
    for m in re.finditer(_STAMP + r"(?:local)?rule (\S+):\n(?:    .*\n)*?    jobid: (\d+)", text):
        start[m.group(3)] = (m.group(2), when(m.group(1)))
    out = {}
    for m in re.finditer(_STAMP + r"Finished jobid: (\d+)", text):
        if m.group(2) in start:
            rule, t0 = start[m.group(2)]
            r = out.setdefault(rule, {"jobs": 0, "wall_s": 0.0})
            r["jobs"] += 1
            r["wall_s"] += (when(m.group(1)) - t0).total_seconds()
    return out


def _load(path: Path) -> list[list[float]]:
    """The load averages (1, 5, 15 min) of each ``uptime`` line of a file: taken before
    and after a run, they say whether the machine was quiet while it ran."""
    return [[float(x) for x in m.group(1).split(", ")] for m in
            re.finditer(r"load average: ([\d.]+, [\d.]+, [\d.]+)", path.read_text())]


def rejudge(clone: Path) -> dict:
    """The validity check of today (``lab.validity.bts_validity``) applied to the Brazilian
    run files of a study whose runs predate it (their cracks, series and initial
    particles): how many would have been valid, and why the others not."""
    import numpy as np

    from bpmcal.io import h5
    from bpmcal.lab.validity import bts_validity

    counts = {"valid": 0, "invalid": 0, "not judged": 0}
    reasons = {}
    for f in sorted((clone / "results" / "bts").glob("s*.h5")):
        try:
            s = h5.read_summary(f)
            if s.get("status") != "ok":
                counts["not judged"] += 1
                continue
            cr = h5.read_cracks(f)
            ser = h5.read_series(f)
            ini = h5.read_particles(f, "initial")
        except Exception:  # noqa: BLE001 - a damaged file is not judged
            counts["not judged"] += 1
            continue
        step = cr["step"].to_numpy() if "step" in cr else np.zeros(len(cr))
        pos = cr[["x", "y", "z"]].to_numpy()
        ip = int(np.argmax(ser["load"].to_numpy()))
        c = ini["position"][:, :2].mean(axis=0)
        v = bts_validity({"step": step, "pos": pos}, ser["step"].to_numpy(), ip, centre=c,
                         radius=0.5e-3 * float(s["diameter_mm"]),
                         mean_ball_diameter=2.0 * float(np.mean(ini["radius"])),
                         ended=s.get("stop_reason") == "post_peak_drop")
        if v["bts_valid"]:
            counts["valid"] += 1
        else:
            counts["invalid"] += 1
            key = v["bts_invalid_reason"].split(":")[0]
            key = ("started next to a platen" if key.startswith("fracture initiated") else
                   "grew from a platen before the peak" if key.startswith("a fracture grew")
                   else key)
            reasons[key] = reasons.get(key, 0) + 1
    return {"counts": counts, "reasons": reasons}


def markdown(rec: dict) -> str:
    lines = [f"# The default study before and after: {rec['date']}", "",
             f"Host: {rec['cpu_model']} ({rec['cpus']} CPUs); load average when recorded "
             f"{', '.join(f'{x:.2f}' for x in rec['load_average'])}.", "",
             f"Recorded with: `{rec['command']}`", "",
             "| run | commit | load (1 min) at start / end | wall"
             + (" (Snakemake's cores)" if any("cores" in r for r in rec["runs"].values()) else "")
             + " | CPU (user + system) | "
             "peak RSS | samples: Brazilian valid / invalid / failed | σt adj. R² (main → "
             "quadratic → interaction) | σc/σt of the samples |",
             "|---|---|---|---|---|---|---|---|---|"]
    for label, r in rec["runs"].items():
        t, res = r["time"], r["results"]
        st = res.get("bts_status", {})
        r2 = [res["adj_r2"].get(f"bts_MPa/{s}") for s in ("main", "quadratic", "interaction")]
        q = res.get("ucs_over_bts_range")
        lines.append(
            f"| {label} | {r['commit']} | "
            + (" / ".join(f"{x[0]:.2f}" for x in r["load"]) if r.get("load") else "not recorded")
            + f" | {t['wall_s'] / 60:.1f} min"
            + (f" ({r['cores']})" if "cores" in r else "")
            + f" | {t['cpu_min']:.1f} min | "
            f"{t['max_rss_mb']:.0f} MB | {st.get('ok', 0)} / {st.get('invalid', 0)} / "
            f"{st.get('failed', 0)} | "
            + " → ".join(f"{x:.3f}" for x in r2 if x is not None)
            + (f" | {q[0]:.1f}–{q[1]:.1f} |" if q else " | – |"))
    (first, a), *rest = rec["runs"].items()
    for label, r in rest:
        b = r["time"]
        same = r.get("cores") == a.get("cores")  # wall times compare on the same cores only
        lines += ["", f"{label} / {first}: CPU time {b['cpu_min'] / a['time']['cpu_min']:.2f}"
                      + (f", wall time {b['wall_s'] / a['time']['wall_s']:.2f}." if same else
                         f" (wall times not compared: {r.get('cores')} cores against "
                         f"{a.get('cores')}).")]
    jobs = {label: r["jobs"] for label, r in rec["runs"].items() if r.get("jobs")}
    if jobs:
        rules = sorted({k for j in jobs.values() for k in j},  # largest first, then by name
                       key=lambda k: (-max(j.get(k, {}).get("wall_s", 0) for j in jobs.values()), k))
        lines += ["", "Job time by rule (the sum of its jobs' wall time, min, and its jobs, "
                      "from Snakemake's log; with `--cores 1` one job runs at a time):", "",
                  "| rule | " + " | ".join(jobs) + " |", "|---|" + "---|" * len(jobs)]
        for k in rules:
            lines.append(f"| {k} | " + " | ".join(
                f"{j[k]['wall_s'] / 60:.1f} ({j[k]['jobs']})" if k in j else "–"
                for j in jobs.values()) + " |")
        lines.append("| all jobs | " + " | ".join(
            f"{sum(v['wall_s'] for v in j.values()) / 60:.1f}" for j in jobs.values()) + " |")
    for label, r in rec["runs"].items():
        if r.get("note"):
            lines += ["", f"{label}: {r['note']}"]
        res = r["results"]
        dd = res.get("bts_discs")
        if dd:
            lines += ["", f"{label}: Brazilian discs: {dd['first_valid']} of {dd['samples']} "
                          f"first discs valid ({100 * dd['first_valid'] / dd['samples']:.1f} %); "
                          f"{dd['retested']} samples tested another disc (bts.retests), "
                          f"{dd['total']} discs in all; samples with a valid σt "
                          f"{res['bts_status'].get('ok', 0)} of {dd['samples']} "
                          f"({100 * res['bts_status'].get('ok', 0) / dd['samples']:.1f} %)"]
        tr = res.get("adj_r2_threshold_rule")
        if tr:
            lines += ["", f"{label}: σt's candidates chosen by screening.tensile_rule "
                          f"`{res['bts_rule']}`; with the paper's threshold rule instead "
                          f"({', '.join(tr['candidates'])}) the same dataset gives σt adj. R² "
                          + " → ".join(f"{tr[f'bts_MPa/{s}']:.3f}" for s in
                                       ("main", "quadratic", "interaction")
                                       if f"bts_MPa/{s}" in tr)]
        rj = r.get("rejudged")
        if rj:
            c = rj["counts"]
            lines += ["", f"{label}: its Brazilian runs judged afterwards by today's validity "
                          f"check (`lab.validity`): {c['valid']} valid, {c['invalid']} invalid"
                          + (f" ({', '.join(f'{k}: {v}' for k, v in rj['reasons'].items())})"
                             if rj["reasons"] else "")
                          + (f", {c['not judged']} not judged" if c["not judged"] else "")]
        inv = r["results"].get("bts_invalid_reasons")
        if inv and sum(inv.values()):
            lines += ["", f"{label}: invalid Brazilian tests by reason: "
                      + ", ".join(f"{k} {v}" for k, v in inv.items())]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", action="append", required=True,
                    help="label=clone directory,time log,commit[,uptime log]")
    ap.add_argument("--out", required=True)
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--rejudge", action="append", default=[],
                    help="a run label whose Brazilian runs predate the validity check: "
                         "judge them now")
    ap.add_argument("--note", action="append", default=[], metavar="LABEL=TEXT",
                    help="what a run's record must say that its numbers do not (e.g. other "
                         "jobs on the host while it ran)")
    a = ap.parse_args(argv)
    notes = dict(n.split("=", 1) for n in a.note)
    runs = {}
    for item in a.run:
        label, rest = item.split("=", 1)
        clone, tlog, commit, *load = rest.split(",")
        runs[label] = {"commit": commit, "clone": clone, "time": _time(Path(tlog)),
                       "results": _results(Path(clone)), "jobs": job_times(Path(tlog))}
        cores = re.search(r"Provided cores: (\d+)", Path(tlog).read_text())
        if cores:  # Snakemake's --cores, from its log
            runs[label]["cores"] = int(cores.group(1))
        if load:
            runs[label]["load"] = _load(Path(load[0]))
        if label in notes:
            runs[label]["note"] = notes[label]
        if label in a.rejudge:
            runs[label]["rejudged"] = rejudge(Path(clone))
    write_record({**record_header("study_record.py", argv), "runs": runs}, a.out, a.markdown,
                 markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
