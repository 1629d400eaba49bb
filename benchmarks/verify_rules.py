"""The default study's closed loops under several loop settings, side by side: each of a
finished study's calibrated cards (``results/calibration/<specimen>.yaml``) is verified
again with ``bpmcal verify`` (the study's verification and specimen settings from
``--config``) once per ``--setting``, and the record lists, per setting and specimen, how
the loop ended, its rounds, runs, the round its seed set grew in, the card's errors and
tolerances, and the CPU time; per setting, the totals.

    python benchmarks/verify_rules.py --study CLONE/results \\
        --setting "grow 1:grow_within=1" --setting "grow 2:grow_within=2" \\
        --commit SHA --out benchmarks/results/results_verify_rules_DATE.json \\
        --markdown docs/measurements/DATE-verify-rules.md

A setting is ``label:key=value,key=value`` over the config's ``verification`` keys that
``bpmcal verify`` takes (the fields of ``LoopSettings``: grow_within, jacobian_update,
max_rounds, max_seeds, ...; each value checked as the field checks it), and the command's
command is the workflow's (``bpmcal.cli.jobs.job_argv``: every setting of the config). The
loops are deterministic, so their rounds and runs are figures; the CPU times are those of
one run each on the recording host, with whatever ran beside it (the load is recorded).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml
from _study import CONFIG, REPO, record_header, study_targets, write_record

from bpmcal.analysis.calibration.loop_settings import LIMITS
from bpmcal.cli.jobs import job_argv


def setting(text: str) -> tuple[str, dict]:
    """``label:key=value,...`` -> (label, {key: value}); an unknown key (a key that is no
    ``LoopSettings`` field) or a bad value is refused."""
    label, _, body = text.partition(":")
    kv = dict(x.split("=", 1) for x in body.split(",") if x)
    bad = [k for k in kv if k not in LIMITS or LIMITS[k].kind == "bool"]
    if not label or bad:
        raise SystemExit(f"--setting {text!r}: expected label:key=value,... with keys among "
                         f"{sorted(k for k, lim in LIMITS.items() if lim.kind != 'bool')}")
    try:
        return label, {k: LIMITS[k].parse(v, k) for k, v in kv.items()}
    except ValueError as e:
        raise SystemExit(f"--setting {text!r}: {e}") from None


def verify_cmd(cfg: dict, card: Path, models: Path, out: Path, over: dict,
               targets=None) -> list[str]:
    """The study's ``bpmcal verify`` command for ``card`` (the workflow's:
    ``bpmcal.cli.jobs.job_argv``), with ``over`` replacing keys of the config's verification
    section; its packing cache beside the settings' folders; quiet. ``targets``: the lab's
    (default: the config's lab CSV)."""
    cfg = {**cfg, "verification": {**cfg["verification"], **over}}
    if targets is None:
        targets = study_targets(cfg)
    return ["bpmcal", *job_argv(cfg, "verify", input={"card": str(card), "models": str(models)},
                                output={"card": str(out / "card.yaml"),
                                        "rounds": str(out / "rounds.csv"),
                                        "run": str(out / "best_round.h5")},
                                threads=cfg["resources"]["loop_threads"], targets=targets,
                                cache=str(out.parent.parent / "packings")), "--quiet"]


def one(cfg, study: Path, spec: str, label: str, over: dict, work: Path) -> dict:
    out = work / label.replace(" ", "_").replace(",", "") / spec
    out.mkdir(parents=True, exist_ok=True)
    cmd = verify_cmd(cfg, study / "calibration" / f"{spec}.yaml",
                     study / "regression" / "models.json", out, over)
    c0 = os.times()
    r = subprocess.run(cmd, capture_output=True, text=True)
    c1 = os.times()
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{r.stderr[-3000:]}")
    v = yaml.safe_load((out / "card.yaml").read_text())["verification"]
    rounds = pd.read_csv(out / "rounds.csv")
    best = rounds.iloc[v["best_round"] - 1]
    targets = list(v["closed_loop"]["errors_pct"])
    grown = rounds.index[rounds["grown"] > 0]
    return {"setting": label, "specimen": spec, "status": v["status"], "rounds": v["rounds"],
            "runs": v["runs"], "n_seeds": v["n_seeds"],
            "grown_in_round": int(grown[0]) + 1 if len(grown) else None,
            "errors_pct": {t: float(v["closed_loop"]["errors_pct"][t]) for t in targets},
            "tolerance_pct": {t: 100 * float(best[f"tol_{t}"]) for t in targets},
            "cpu_s": (c1.children_user + c1.children_system)
                     - (c0.children_user + c0.children_system)}


def markdown(rec: dict) -> str:
    lines = [f"# The default study's closed loops under {len(rec['settings'])} loop settings "
             f"({rec['date']})", "", "| | |", "|---|---|", f"| date | {rec['date']} |",
             f"| commit | {rec['commit']} |", f"| host | {rec['cpu_model']} ({rec['cpus']} CPUs) |",
             f"| load | {', '.join(f'{x:.2f}' for x in rec['load_average'])} |",
             f"| command | `{rec['command']}` |", "",
             f"Every calibrated card of the study in `{rec['study']}` verified again with "
             "`bpmcal verify` (the config's verification settings, each setting's keys "
             "replaced): what is compared, the docstring of `benchmarks/verify_rules.py`.",
             "", "| setting | keys | specimen | status | rounds | runs | seeds | grown in round "
             "| errors (tolerances) | CPU s |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rec["runs"]:
        keys = ", ".join(f"{k} {v}" for k, v in rec["settings"][r["setting"]].items())
        err = ", ".join(f"{t} {e:+.2f} % ({r['tolerance_pct'][t]:.2f} %)"
                        for t, e in r["errors_pct"].items())
        lines.append(f"| {r['setting']} | {keys} | {r['specimen']} | {r['status']} | "
                     f"{r['rounds']} | {r['runs']} | {r['n_seeds']} | "
                     f"{r['grown_in_round'] or '-'} | {err} | {r['cpu_s']:.0f} |")
    lines += ["", "| setting | converged | runs | CPU s |", "|---|---|---|---|"]
    for label in rec["settings"]:
        rs = [r for r in rec["runs"] if r["setting"] == label]
        lines.append(f"| {label} | {sum(r['status'] == 'converged' for r in rs)} of {len(rs)} | "
                     f"{sum(r['runs'] for r in rs)} | {sum(r['cpu_s'] for r in rs):.0f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", required=True, help="a finished study's results folder")
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--specimens", default=None,
                    help="comma-separated (default: every card in <study>/calibration)")
    ap.add_argument("--setting", action="append", required=True, metavar="LABEL:KEY=VALUE,...")
    ap.add_argument("--work", default="/tmp/verify_rules")
    ap.add_argument("--commit", default="")
    ap.add_argument("--out", default=None)
    ap.add_argument("--markdown", default=None)
    a = ap.parse_args(argv)
    from bpmcal.study.config import validate_config

    cfg = yaml.safe_load(Path(a.config).read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    study = Path(a.study)
    specs = (a.specimens.split(",") if a.specimens
             else sorted(p.stem for p in (study / "calibration").glob("*.yaml")))
    settings = dict(setting(s) for s in a.setting)
    rec = {**record_header("verify_rules.py", argv), "commit": a.commit, "study": str(study),
           "settings": settings}
    rec["runs"] = [one(cfg, study, spec, label, over, Path(a.work))
                   for label, over in settings.items() for spec in specs]
    write_record(rec, a.out, a.markdown, markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
