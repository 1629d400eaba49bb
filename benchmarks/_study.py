"""What the cost benchmarks (``bts_study_cost.py``, ``host_independence_cost.py``) read of
the study they measure: its config's design samples, as the workflow draws them (rule
design: ``bpmcal design``), its UCS settings, and the host's CPU model.

bpmcal is imported inside the functions, so a script using them still runs with any
bpmcal version on ``PYTHONPATH``.
"""
from __future__ import annotations

import datetime as dt
import json
import os
import re
import shlex
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config" / "config.yaml"



def study_config(path=CONFIG) -> dict:
    """A study config as the workflow reads it: validated against the schema, its defaults
    filled in (what ``bpmcal.cli.jobs.job_argv`` builds a job's command from)."""
    import yaml

    from bpmcal.study.config import validate_config

    cfg = yaml.safe_load(Path(path).read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    return cfg


def study_targets(cfg: dict) -> frozenset:
    """The lab targets of a study config (``bpmcal.cli.jobs.lab_targets``), its lab CSV
    read from the repository wherever the script runs."""
    from bpmcal.cli.jobs import lab_targets
    from bpmcal.study.lab_data import load_lab

    return lab_targets(cfg, load_lab(REPO / cfg["lab"]["csv"]))


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def study_design(cfg: dict):
    """The study's design (a DataFrame with sample_id, the 8 parameters and seed) from a
    config's ``ranges`` and ``study`` sections; ``lhs_optimization: none`` is no
    optimisation, as ``bpmcal design --optimization none``."""
    from bpmcal.study.design import lhs_design

    st = cfg["study"]
    return lhs_design(cfg["ranges"], st["n_samples"], st["lhs_seed"],
                      optimization=None if st["lhs_optimization"] == "none"
                      else st["lhs_optimization"])


def design_samples(design, ids, a1_seeds, label="A1 s{seed}"):
    """(label, parameters, packing seed) of the rows ``ids`` of a design CSV, or, without a
    design, of the paper's A1 card on the packing seeds ``a1_seeds`` (labels from
    ``label``)."""
    import csv

    if design is None:
        from bpmcal.study.paper import A1  # the paper's card

        return [(label.format(seed=s), dict(A1), s) for s in a1_seeds]
    with open(design) as f:
        rows = {r["sample_id"]: r for r in csv.DictReader(f)}
    out = []
    for sid in ids:
        r = rows[sid]
        p = {k: float(v) for k, v in r.items() if k not in ("sample_id", "seed")}
        out.append((sid, p, int(r["seed"])))
    return out


def section_settings(cfg: dict, section: str, cls, **over):
    """The settings object ``cls`` of a config's ``section``: every key that is a field of
    this bpmcal's ``cls`` (a key is its field's name: tests/workflow/
    test_settings_sections.py), ``over`` replacing some; a section the config lacks gives
    the class's defaults."""
    from dataclasses import fields

    sec = cfg.get(section) or {}
    return cls(**{**{f.name: sec[f.name] for f in fields(cls) if f.name in sec}, **over})


def ucs_settings(cfg: dict):
    """The UCS test settings of a config's ``compression`` section."""
    from bpmcal.lab.ucs import UCSSettings

    return section_settings(cfg, "compression", UCSSettings)


def study_geometry(cfg: dict, scale: float | None = None):
    """The study's cylinder (``Geometry`` of a config's ``specimen`` section), at ``scale``
    instead of the section's when given."""
    from bpmcal.lab.runner import Geometry

    return section_settings(cfg, "specimen", Geometry,
                            **({} if scale is None else {"scale": scale}))


def bts_disc_and_settings(cfg: dict, scale: float | None = None, **over):
    """The study's Brazilian disc (``bts_geometry`` from a config's ``bts`` and
    ``specimen`` sections; ``scale`` instead of the config's) and its ``BTSSettings``
    (the ``bts`` keys it has, a field's config key being its name; ``over`` replaces some)."""
    from dataclasses import fields

    from bpmcal.lab.brazilian import BTSSettings
    from bpmcal.lab.runner import bts_geometry

    sp, b = cfg["specimen"], cfg["bts"]
    if scale is None:
        scale = b["scale"] if b.get("scale") is not None else sp["scale"]
    disc = bts_geometry(scale=scale, diameter_mm=b["diameter_mm"],
                        thickness_mm=b["thickness_mm"], sigma0_MPa=sp["sigma0_MPa"],
                        install_gap_mm=sp["install_gap_mm"], relax_ratio=sp["relax_ratio"],
                        genesis=sp["genesis"])
    kw = {f.name: b[f.name] for f in fields(BTSSettings) if f.name in b}
    return disc, BTSSettings(**{**kw, **over})


def run_meta(script: str, argv) -> dict:
    """A benchmark record's date, commit (``+dirty`` with uncommitted changes under src),
    host CPU, load at the start and command line (``python benchmarks/<script> ...``)."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO,
                                capture_output=True, text=True).stdout.strip()
        dirty = bool(subprocess.run(["git", "status", "--porcelain", "src"], cwd=REPO,
                                    capture_output=True, text=True).stdout.strip())
    except OSError:
        commit, dirty = "unknown", False
    return {"date": dt.date.today().isoformat(), "commit": commit + ("+dirty" if dirty else ""),
            "cpu_model": cpu_model(), "cpus": os.cpu_count(),
            "load_average_start": list(os.getloadavg()),
            "command": f"python benchmarks/{script} " + shlex.join(argv)}


def add_record_options(ap, what: str = "the table") -> None:
    """A benchmark's record options: ``--out`` (the JSON record to write), ``--render``
    (print ``what`` of one or more JSON records and stop) and ``--commit`` (the commit of
    the source when it runs from an export that git cannot name)."""
    ap.add_argument("--out", help="the JSON record to write")
    ap.add_argument("--render", nargs="+", help=f"print {what} of these JSON records and stop")
    ap.add_argument("--commit", default="", help="the commit of the source when it runs "
                    "from an export (git archive) that git cannot name")


def rendered(ap, a, render) -> bool:
    """Print ``render(records)`` of ``--render`` and say so (True), or check that a run has
    its ``--out`` (``ap.error`` otherwise) and say it has not (False)."""
    if a.render:
        print(render([json.loads(Path(f).read_text()) for f in a.render]), end="")
        return True
    if not a.out:
        ap.error("--out FILE is needed to run (or --render FILE ...)")
    return False


def source_commit(given: str = "") -> str:
    """The short commit of the source the benchmark runs, or ``given`` (``--commit``) when
    it runs from an export git cannot name."""
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO,
                             capture_output=True, text=True).stdout.strip()
    except OSError:
        out = ""
    return out or given


def record_header(script: str, argv) -> dict:
    """The fixed header of a measurement record: date, host CPU, load, the exact command."""
    return {"date": dt.date.today().isoformat(), "cpu_model": cpu_model(),
            "cpus": os.cpu_count(), "load_average": list(os.getloadavg()),
            "command": f"python benchmarks/{script} " + shlex.join(argv)}


def write_record(rec: dict, out, markdown_path, render, **json_kw) -> str:
    """Write the JSON record ``rec`` to ``out`` (when given) and its Markdown rendering
    (``render(rec)``) to ``markdown_path`` (when given); print and return the Markdown."""
    if out:
        Path(out).write_text(json.dumps(rec, indent=1, **json_kw) + "\n")
    text = render(rec)
    if markdown_path:
        Path(markdown_path).write_text(text)
    print(text)
    return text


def gnu_time(log: Path) -> dict:
    """Wall, user and system time, CPU minutes, peak memory and exit status from the output of
    ``/usr/bin/time -v``."""
    text = log.read_text()

    def grab(label):
        m = re.search(rf"{re.escape(label)}: (.+)", text)
        return m.group(1).strip() if m else None

    wall = grab("Elapsed (wall clock) time (h:mm:ss or m:ss)")
    parts = [float(x) for x in wall.split(":")] if wall else []
    wall_s = sum(v * 60 ** i for i, v in enumerate(reversed(parts))) if parts else None
    user, sys_ = float(grab("User time (seconds)")), float(grab("System time (seconds)"))
    rss = grab("Maximum resident set size (kbytes)")  # absent: not measured (time -f)
    return {"wall_s": wall_s, "user_s": user, "system_s": sys_,
            "cpu_min": (user + sys_) / 60, "max_rss_mb": float(rss) / 1024 if rss else None,
            "exit_status": int(grab("Exit status") or -1)}


def fresh_seed_lines(rows, within: str = "2 SE") -> list[str]:
    """The fresh-seed table of a record: target, n, mean, error, z-score, verdict against
    the lab; with the check against the closed loop when the rows carry it (records from
    before it render as they did)."""
    loop = any("judged_by" in h for h in rows)
    extra = " fresh − loop | t (limit) | passed |" if loop else ""
    lines = ["| target | n | mean | error | z-score | within " + within + " |" + extra,
             "|---|---|---|---|---|---|" + "---|" * (3 if loop else 0)]
    for h in rows:
        line = (f"| {h['response']} | {h['n']} | {float(h['mean']):.4g} | "
                f"{float(h['err_pct']):+.2f} % | {float(h['z_score']):+.2f} | {h['within_z_se']} |")
        if loop and h.get("judged_by") == "closed loop":
            line += (f" {float(h['diff_pct']):+.2f} % | {float(h['t_loop']):+.2f} "
                     f"({float(h['t_crit']):.2f}) | {h['passed']} |")
        elif loop:
            line += f" – | – | {h.get('passed')} (against the lab) |"
        lines.append(line)
    return lines
