"""The report's section on how sure the cards are: every verified card's posterior
(``bpmcal posterior``) and its predictive in DEM (``bpmcal predictive``).

Per specimen: the card's status with the note that stands next to it (a free direction
that moves the failure mode), what the targets pin and leave free, reach, each
parameter's value with its interval, the untargeted predictions' spreads, the pair plot
and the learning curve; the predictive draws' mi, c, φ and η_f (mean and interval beside
the card's). Files that are not there (a partial study) leave their part out. Reads the
files ``StudyFiles.posterior_report_files`` lists and copies its tables and figures into
``report/posterior/<specimen>/``.
"""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import pandas as pd

from ..analysis.posterior import TENSILE_SHARE
from ..io import study_files as L
from ..io.card import read_card
from ..io.tables import markdown_table


def _copy(lay: L.StudyFiles, files) -> None:
    for f in files:
        if f.endswith(".yaml") or not Path(f).exists():
            continue
        dst = Path(lay.report_copy(f))
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(f, dst)


def _rel(lay: L.StudyFiles, path: str) -> str:
    """A copied file's link from ``report/index.md``."""
    return str(Path(lay.report_copy(path)).relative_to(lay.report_dir))


def _num(v, fmt=".3g") -> str:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return "–"
    return format(x, fmt) if math.isfinite(x) else "–"


#: which end of an HDI the prior box cuts (a card's ``hdi_cut_by_prior``), in the table
_CUT = {"": "no", "low": "**at its lower bound**", "high": "**at its upper bound**",
        "both": "**at both bounds**"}


def _parameters(post: dict) -> str:
    rows = []
    for p, d in post["parameters"].items():
        lo, hi = d["hdi"]
        rows.append({"parameter": p, "card": _num(d["card"], ".4g"), "mean": _num(d["mean"], ".4g"),
                     f"{100 * post['hdi_prob']:.0f} % HDI": f"{_num(lo, '.4g')} – {_num(hi, '.4g')}",
                     "card in HDI": "yes" if d["card_in_hdi"] else "**no**",
                     "HDI cut by the prior": _CUT.get(d.get("hdi_cut_by_prior", ""), "–"),
                     "role": d["role"]})
    return markdown_table(pd.DataFrame(rows), index=False)


def _predictions(post: dict) -> str:
    rows = []
    for r, d in post["predictions"].items():
        scale = 100 if r == TENSILE_SHARE else 1
        lo, hi = d["interval"]
        rows.append({"response": "tensile crack share (%)" if r == TENSILE_SHARE else r,
                     "targeted": "yes" if d["targeted"] else "no",
                     "lab": _num(d.get("lab")), "card": _num(scale * d["card"]),
                     "mean over posterior": _num(scale * d["mean"]),
                     "interval": f"{_num(scale * lo)} – {_num(scale * hi)}"})
    return markdown_table(pd.DataFrame(rows), index=False)


def _predictive(path: str) -> str:
    from ..stages.predictive import summarise

    if not Path(path).exists():
        return ""
    s = summarise(pd.read_csv(path, dtype={"draw": str}))
    names = {"mi": "Hoek-Brown mi", "c_MPa": "cohesion c (MPa)", "phi_deg": "friction angle φ (°)",
             "eta_f": "η_f (impact)"}
    rows = [{"prediction": names.get(k, k), "card": _num(r["card"]), "draws": int(r["n"]),
             "mean": _num(r["mean"]), "90 % interval": f"{_num(r['low'])} – {_num(r['high'])}"}
            for k, r in s.iterrows()]
    return ("Posterior predictive in DEM (each draw's triaxial envelope and impact, beside "
            "the card's own):\n\n" + markdown_table(pd.DataFrame(rows), index=False) + "\n")


def section(lay: L.StudyFiles, cfg: dict, specimens) -> str:
    """The posterior section of ``index.md`` (module docstring); empty when the study ran
    no posterior."""
    pc = cfg.get("posterior") or {}
    if not pc.get("enabled", False):
        return ""
    pred = pc.get("predictive") or {}
    pred_specs = list(specimens)[: int(pred.get("specimens", 0))] if pred.get("draws") else []
    files = lay.posterior_report_files(specimens, bool(pc.get("learning_curve")), pred_specs)
    _copy(lay, files)
    S = ["## How sure the cards are: posterior over the free parameters\n",
         "Each verified card's posterior given its lab targets (a surrogate of the DEM "
         "fitted to the design and every run near the card, its own error in the "
         "likelihood; method: docs/methods/posterior.md).\n"]
    for spec in specimens:
        card_path = lay.posterior_card(spec)
        if not Path(card_path).exists():
            continue
        c = read_card(card_path, need=("posterior",))
        post = c["posterior"]
        v = c.get("verification") or {}
        status = f"closed loop **{v.get('status', '–')}**, posterior {post['status']}"
        S.append(f"### {spec}: {status}\n")
        if post.get("note"):
            S.append(f"**{post['note']}**\n")
        S.append(f"{post['identifiability']} {post['reach']['text']}\n")
        S.append(_parameters(post) + "\n")
        S.append(_predictions(post) + "\n")
        if spec in pred_specs:
            S.append(_predictive(lay.posterior_predictive(spec)))
        S.append(f"![pair plot of {spec}]({_rel(lay, lay.posterior_pairs(spec))})\n")
        if Path(lay.posterior_learning_figure(spec)).exists():
            curve = post.get("learning_curve") or []
            tail = (f" (from {curve[0]['width_pct_of_range']:.1f} % of the range on the design "
                    f"alone to {curve[-1]['width_pct_of_range']:.1f} % after "
                    f"{curve[-1]['dem_runs_near_card']} runs near the card)") if curve else ""
            S.append(f"Learning curve{tail}:\n\n"
                     f"![learning curve of {spec}]({_rel(lay, lay.posterior_learning_figure(spec))})\n")
    return "\n".join(S) + "\n"
