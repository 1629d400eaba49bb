"""A measurement record of a finished study's posteriors: per verified card what its lab
targets pin and leave free, each parameter's 90 % HDI beside the card's value, the
untargeted predictions' spreads (the surrogate's, and the predictive DEM draws' mi, c,
phi and eta_f), the learning curve, and what the posterior cost beside the study.

    python benchmarks/posterior_study.py --study CLONE/results \\
        [--cost benchmarks/results/results_cost_model_DATE_NAME.json] [--commit C] [--note TEXT] \\
        --out benchmarks/results/results_posterior_study_DATE.json \\
        --markdown docs/measurements/DATE-posterior-study.md
    python benchmarks/posterior_study.py --render benchmarks/results/results_posterior_study_DATE.json \\
        --markdown docs/measurements/DATE-posterior-study.md

What it reads: each specimen's posterior card (``<study>/posterior/<spec>/card.yaml``:
status, identifiability text, reach, parameters with HDIs, r-hat and ESS, the surrogate's
predictions, the learning curve) and its predictive table (``predictive.csv``: each DEM
draw's envelope and impact, the card's own row). The cost is read from a cost-model record
of the same study (``benchmarks/cost_model.py``): the CPU seconds of the rules
``posterior`` and ``posterior_predictive`` beside those of every job of the study.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from _study import record_header, write_record

#: the rules of the posterior (surrogate, sampler, refinement runs) and of its predictive
#: DEM runs, as ``workflow/rules`` names them
POSTERIOR_RULES = ("posterior",)
PREDICTIVE_RULES = ("posterior_predictive",)


def _f(x):
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def card_record(study: Path, spec: str) -> dict | None:
    """What the record keeps of one specimen's posterior (``None``: no posterior card)."""
    import pandas as pd

    from bpmcal.io import study_files as L
    from bpmcal.io.card import read_card
    from bpmcal.stages.predictive import summarise

    lay = L.StudyFiles(study)
    path = Path(lay.posterior_card(spec))
    if not path.exists():
        return None
    c = read_card(path, need=("posterior",))
    post = c["posterior"]
    v = c.get("verification") or {}
    out = {"specimen": spec, "loop_status": v.get("status"), "status": post.get("status"),
           "note": post.get("note") or "", "identifiability": post.get("identifiability", ""),
           "reach": (post.get("reach") or {}).get("text", ""),
           "hdi_prob": post.get("hdi_prob"), "parameters": {}, "predictions": {},
           "learning_curve": post.get("learning_curve") or [], "predictive": {}}
    table = Path(lay.posterior_table(spec))
    diag = pd.read_csv(table).set_index("parameter") if table.exists() else None
    for p, d in post["parameters"].items():
        row = {"card": _f(d["card"]), "mean": _f(d["mean"]), "sd": _f(d.get("sd")),
               "hdi": [_f(x) for x in d["hdi"]], "card_in_hdi": bool(d["card_in_hdi"]),
               "role": d.get("role")}
        if diag is not None and p in diag.index:
            for k in ("hdi_width_pct_of_range", "rhat", "ess_bulk"):
                row[k] = _f(diag.loc[p, k])
        out["parameters"][p] = row
    for r, d in (post.get("predictions") or {}).items():
        out["predictions"][r] = {"targeted": bool(d["targeted"]), "lab": _f(d.get("lab")),
                                 "card": _f(d["card"]), "mean": _f(d["mean"]),
                                 "interval": [_f(x) for x in d["interval"]]}
    curve = Path(lay.posterior_learning(spec))  # with the runs and p(reach) of each point
    if curve.exists():
        out["learning_curve"] = [{k: (v if k == "data" else _f(v)) for k, v in r.items()}
                                 for r in pd.read_csv(curve).to_dict("records")]
    pred = Path(lay.posterior_predictive(spec))
    if pred.exists():
        s = summarise(pd.read_csv(pred, dtype={"draw": str}))
        out["predictive"] = {k: {"card": _f(r["card"]), "draws": int(r["n"]), "mean": _f(r["mean"]),
                                 "low": _f(r["low"]), "high": _f(r["high"])}
                             for k, r in s.iterrows()}
    return out


def cost_record(cost_json: Path) -> dict:
    """The posterior's and the predictive runs' CPU seconds beside the study's (every job
    with a cost line), from a cost-model record."""
    rec = json.loads(Path(cost_json).read_text())
    rules = {r["rule"]: r for r in rec["rules"]}
    total = sum(r["cpu_s"] for r in rec["rules"])

    def cpu(names):
        return sum(rules[n]["cpu_s"] for n in names if n in rules)

    post, pred = cpu(POSTERIOR_RULES), cpu(PREDICTIVE_RULES)
    return {"cost_record": str(cost_json), "study_cpu_s": total, "posterior_cpu_s": post,
            "predictive_cpu_s": pred, "posterior_share": post / total if total else None,
            "predictive_share": pred / total if total else None,
            "jobs": {n: rules[n]["jobs"] for n in POSTERIOR_RULES + PREDICTIVE_RULES if n in rules}}


def record(study: Path, specimens, cost_json, commit, note, argv) -> dict:
    cards = [c for c in (card_record(study, s) for s in specimens) if c is not None]
    rec = {**record_header("posterior_study.py", argv), "commit": commit, "study": str(study),
           "note": note, "cards": cards}
    if cost_json:
        rec["cost"] = cost_record(Path(cost_json))
    return rec


def _n(x, fmt=".4g") -> str:
    return "–" if x is None else format(x, fmt)


def _card_lines(c: dict) -> list[str]:
    prob = 100 * (c["hdi_prob"] or 0.9)
    L = [f"## {c['specimen']}: closed loop {c['loop_status']}, posterior {c['status']}", ""]
    if c["note"]:
        L += [f"**{c['note']}**", ""]
    L += [f"{c['identifiability']} {c['reach']}", "",
          f"| parameter | role | card | mean | sd | {prob:.0f} % HDI | HDI width (% of range) "
          "| card in HDI | r-hat | ESS (bulk) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for p, d in c["parameters"].items():
        lo, hi = d["hdi"]
        L.append(f"| {p} | {d['role']} | {_n(d['card'])} | {_n(d['mean'])} | {_n(d['sd'], '.3g')} "
                 f"| {_n(lo)} – {_n(hi)} | {_n(d.get('hdi_width_pct_of_range'), '.1f')} "
                 f"| {'yes' if d['card_in_hdi'] else '**no**'} | {_n(d.get('rhat'), '.3f')} "
                 f"| {_n(d.get('ess_bulk'), '.0f')} |")
    L += ["", "The surrogate's predictions over the posterior (targeted and untargeted):", "",
          "| response | targeted | lab | card | mean | 90 % interval |", "|---|---|---|---|---|---|"]
    for r, d in c["predictions"].items():
        lo, hi = d["interval"]
        L.append(f"| {r} | {'yes' if d['targeted'] else 'no'} | {_n(d['lab'])} | {_n(d['card'])} "
                 f"| {_n(d['mean'])} | {_n(lo)} – {_n(hi)} |")
    if c["predictive"]:
        L += ["", "Posterior predictive in DEM (each draw a triaxial envelope and an impact "
              "at the reference velocity; the card's own beside them):", "",
              "| prediction | card | draws | mean | 90 % interval | interval width (% of the "
              "mean) |", "|---|---|---|---|---|---|"]
        for k, d in c["predictive"].items():
            w = (100 * (d["high"] - d["low"]) / abs(d["mean"])
                 if None not in (d["high"], d["low"], d["mean"]) and d["mean"] else None)
            L.append(f"| {k} | {_n(d['card'])} | {d['draws']} | {_n(d['mean'])} "
                     f"| {_n(d['low'])} – {_n(d['high'])} | {_n(w, '.1f')} |")
    if c["learning_curve"]:
        L += ["", "Learning curve (the posterior's mean HDI width against the DEM runs it "
              "was fitted on):", "", "| data | DEM runs near the card | DEM runs | HDI width "
              "(% of range) | p(reach) |", "|---|---|---|---|---|"]
        for p in c["learning_curve"]:
            L.append(f"| {p['data']} | {_n(p['dem_runs_near_card'], '.0f')} "
                     f"| {_n(p.get('dem_runs'), '.0f')} | {_n(p['width_pct_of_range'], '.1f')} "
                     f"| {_n(p.get('p_reach'), '.3g')} |")
    return L + [""]


def markdown(rec: dict) -> str:
    L = [f"# The posteriors of a finished study ({rec['date']})", "", "| | |", "|---|---|",
         f"| date | {rec['date']} |", f"| commit | {rec['commit']} |",
         f"| host | {rec['cpu_model']}, {rec['cpus']} cores |",
         f"| load | {', '.join(f'{x:.2f}' for x in rec['load_average'])} when recorded |",
         f"| command | `{rec['command']}` |", ""]
    if rec.get("note"):
        L += [rec["note"], ""]
    if rec.get("cost"):
        k = rec["cost"]
        L += ["## Cost beside the study", "",
              "| part | CPU s | share of the study's CPU |", "|---|---|---|",
              f"| the posterior (rule `posterior`: surrogate, sampler, refinement runs) "
              f"| {k['posterior_cpu_s']:.1f} | {100 * k['posterior_share']:.1f} % |",
              f"| the predictive DEM runs (rule `posterior_predictive`) "
              f"| {k['predictive_cpu_s']:.1f} | {100 * k['predictive_share']:.1f} % |",
              f"| the whole study (every job's cost line) | {k['study_cpu_s']:.1f} | 100 % |", "",
              f"From the cost-model record `{k['cost_record']}`.", ""]
    for c in rec["cards"]:
        L += _card_lines(c)
    L += ["This record is not edited; a new measurement gets a new record.", ""]
    return "\n".join(L)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--study", type=Path, help="a finished study's results folder")
    ap.add_argument("--specimens", nargs="+", default=["B1", "B2", "B3"])
    ap.add_argument("--cost", help="the cost-model record (JSON) of the same study")
    ap.add_argument("--commit", default="unknown")
    ap.add_argument("--note", default="")
    ap.add_argument("--render", help="render an existing JSON record")
    ap.add_argument("--out")
    ap.add_argument("--markdown")
    a = ap.parse_args(argv)
    if a.render:
        rec = json.loads(Path(a.render).read_text())
    else:
        if a.study is None:
            ap.error("--study or --render")
        rec = record(a.study, a.specimens, a.cost, a.commit, a.note, argv)
    write_record(rec, a.out, a.markdown, markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
