"""The report's verification section: Table 5 (the verified cards' DEM against the lab,
single pass and closed loop), Table 6 (the pre-peak energy density), the packing-seed
scatter of one calibrated set, and the verified cards on fresh packing seeds (the check
against each card's closed loop, the same seeds against the lab, σt predicted for the
cards without a tensile target). A file that is not there (a partial study) leaves its
part out."""
from __future__ import annotations

import math
import statistics
from pathlib import Path

import pandas as pd

from .. import params as P
from ..io import study_files as L
from ..io.card import read_card
from ..io.tables import markdown_table
from ..stages.fresh_seeds import check_level, false_alarm
from ..study import paper
from .cells import compare, num, read_table


def _pm(r, col: str) -> str:
    """A Table 5 cell: the seed mean ± the seed standard deviation (the mean alone with
    one seed)."""
    sd = r.get(f"{col}_sd", math.nan)
    return num(r[col]) + (f" ± {num(sd)}" if pd.notna(sd) else "")


def section(lay, comp, ref=False) -> str:
    """Table 5 (the DEM against the lab, single pass and closed loop), Table 6 (the
    pre-peak energy), the packing-seed scatter and the fresh seeds
    (:func:`fresh_seeds_section`); with ``ref`` (the paper's study) the paper's values
    beside ours, each recorded in ``comp`` (:func:`~bpmcal.report.cells.compare`)."""
    t5 = read_table(lay, L.TABLE5, index_col=0)
    if t5 is None:
        return ""
    rows, notes = [], []
    for spec, r in t5.iterrows():
        th = paper.VERIFIED.get(spec) if ref else None
        ran = r.get("status") != "not-run"
        if not ran:
            notes.append(f"- **{spec}: closed loop not run** — {r.get('note', '')}")
        tens = [resp for resp in P.SAMPLE_TESTS  # σt (σ1 at the design σ3) a target
                if f"lab_{resp}" in t5.columns and pd.notna(r.get(f"lab_{resp}"))]
        if ran and isinstance(r.get("note"), str) and r["note"]:
            notes.append(f"- **{spec}: outside the design space** — {r['note']} (the closed "
                         "loop ran the DEM there, within verification.range_margin; the "
                         "regression never sampled it)")
        if ran and isinstance(r.get("tensile_note"), str) and r["tensile_note"]:
            notes.append(f"- **{spec}: tensile specimens per seed** — {r['tensile_note']}")
        if ran and P.BTS in tens and Path(lay.bts_size_fit(spec)).exists():
            f = pd.read_csv(lay.bts_size_fit(spec)).iloc[0]
            notes.append(f"- **{spec}: σt** is compared here on the study's "
                         f"{num(f['reference_mm'], 'g')} mm disc; the lab's discs are "
                         f"{num(f['lab_diameter_mm'], 'g')} mm: σt there "
                         f"{num(f['sigma_lab_size_MPa'])} ± {num(f['sigma_lab_size_se'])} MPa "
                         f"({f['method']}), error {num(f['err_pct'], '+.2f')} % against the "
                         "lab (\"σt at the lab's disc size\")")
        if ran and isinstance(r.get("missed"), str) and r["missed"]:
            notes.append(f"- **{spec}: target(s) missed by the closed loop** — {r['missed']} "
                         "(error of the DEM in % of the lab value; no target is left out)")
        for k in (*P.TARGETS, *tens):
            if th and ran and k in P.TARGETS:
                compare(comp, "Table 5", f"{spec} {k}, DEM (closed loop vs paper's PFC3D)",
                        r[f"closed_loop_{k}"], th[k], P.RESPONSES[k].unit)
                compare(comp, "Table 5", f"{spec} {k} error % (closed loop vs paper)",
                        r[f"closed_loop_{k}_err_pct"], th["err_pct"][k], "%")
            if ran:
                row = [spec, P.RESPONSES[k].symbol, num(r[f"lab_{k}"]),
                       _pm(r, f"single_pass_{k}"), num(r[f"single_pass_{k}_err_pct"], "+.2f"),
                       _pm(r, f"closed_loop_{k}"), num(r[f"closed_loop_{k}_err_pct"], "+.2f"),
                       num(r.get("n_seeds", 1), ".0f")]
            else:
                row = [spec, P.RESPONSES[k].symbol, num(r[f"lab_{k}"]), "not run", "", "not run", "",
                       ""]
            if ref:
                row += ([num(th[k]) if th else "–", num(th["err_pct"][k], ".2f") if th else "–"]
                        if k in P.TARGETS else ["–", "–"])
            rows.append(row)
    header = ["specimen", "response", "lab", "DEM, single pass", "error", "DEM, closed loop", "error",
              "seeds"]
    if ref:
        header += ["paper (PFC3D)", "paper error"]
    s = ("## Table 5: verification (errors in % of the lab value)\n\n"
         "DEM values are the mean of the packing seeds of the round ± their standard deviation "
         "(the scatter of one run); the error is that of the mean.\n\n"
         + markdown_table(rows, header) + "\n")
    if notes:
        s += "\n" + "\n".join(notes) + "\n"
    return s + _table6(lay, comp, ref) + _seed_scatter(lay) + fresh_seeds_section(lay)


def _table6(lay, comp, ref=False) -> str:
    """Table 6: the pre-peak energy density, DEM against the lab (and the paper's)."""
    t6 = read_table(lay, L.TABLE6, index_col=0)
    if t6 is None:
        return ""
    rows = []
    for spec, r in t6.iterrows():
        th = paper.PREPEAK.get(spec, {}) if ref else {}
        if th:
            compare(comp, "Table 6", f"{spec} Up, DEM", r["sim_Up_MJm3"], th["sim"], "MJ/m³")
            compare(comp, "Table 6", f"{spec} Up error %", r["rel_error_pct"], th["err_pct"],
                    "%")
        row = [spec, num(r["lab_Up_MJm3"]), num(r["sim_Up_MJm3"]), num(r["rel_error_pct"], ".1f")]
        if ref:
            row += [num(th.get("sim")), num(th.get("err_pct"), ".1f")]
        rows.append(row)
    header = ["specimen", "lab", "DEM (ours)" if ref else "DEM", "error %"]
    if ref:
        header += ["paper PFC3D", "paper error %"]
    return ("\n## Table 6: pre-peak energy density Up (MJ/m³)\n\n"
            + markdown_table(rows, header) + "\n")


def _seed_scatter(lay) -> str:
    """The packing-seed scatter of one calibrated set (``seed_scatter``), if it ran."""
    sc = Path(lay.seed_scatter)
    if not sc.exists():
        return ""
    t = pd.read_csv(sc)
    rows = [[r["response"], num(r["cv"] * 100, ".2f"), num(r["noise_floor"] * 100, ".2f"),
             "yes" if r["noise_limited"] else "no"] for _, r in t.iterrows()]
    return ("\n### Packing-seed scatter of one calibrated set\n\n"
            + markdown_table(rows, ["response", "CV of one run (%)", "noise floor 2 se (%)",
                                    "1 % tolerance below the noise?"]) + "\n")


def _loop_seeds(lay, specs) -> int | None:
    """The median number of packing seeds the verified cards of ``specs`` were judged on
    (their closed loops' ``n_seeds``, Table 5), None when Table 5 does not say."""
    t = read_table(lay, L.TABLE5)
    if t is None:
        return None
    if "n_seeds" not in t.columns or "specimen" not in t.columns:
        return None
    ks = [int(k) for k in t.loc[t["specimen"].astype(str).isin(specs), "n_seeds"].dropna()
          if int(k) > 1]
    return int(statistics.median_low(ks)) if ks else None


def _triaxial_seeds(lay, spec: str, k: int) -> int | None:
    """The seeds of a closed loop that ran the triaxial test (``verification.triaxial_seeds``
    of the verified card of ``spec``, below ``k``; a study-wide setting, so one card
    says it for all: the first judged specimen's, read only for a σ1 target), None when
    every seed did."""
    f = Path(lay.verified_card(spec))
    v = (read_card(f).get("verification") or {}) if f.exists() else {}
    m = int(v["triaxial_seeds"]) if v.get("triaxial_seeds") else None
    return m if m and m < k else None


def fresh_seeds_section(lay) -> str:
    """The verified cards on fresh packing seeds (``fresh_seeds_table``), if it ran: the
    check against each card's closed loop, then the same seeds against the lab."""
    t = read_table(lay, L.FRESH_SEEDS)
    if t is None:
        return ""
    ratio = direct_over_brazilian(t)
    pred = t[t["role"] == "prediction"] if "role" in t.columns else t.iloc[:0]
    t = t[t["role"] != "prediction"] if "role" in t.columns else t
    if "passed" not in t.columns:  # a table of an older bpmcal: judged against the lab only
        t = t.assign(passed=t["within_z_se"], judged_by="lab",
                     lab_because="a table of an older bpmcal, which judged against the lab only")
    notes = (t["note"].astype(object).fillna("").astype(str) if "note" in t.columns
             else pd.Series("", t.index))
    z = float(t["z"].iloc[0]) if len(t) else 2.0
    seeds = t["seeds"].iloc[0] if len(t) else ""
    by_loop = t[(t["judged_by"] == "closed loop") & (notes == "")]
    return ("\n### The verified cards on fresh packing seeds\n\n"
            f"Each verified card re-run on packing seeds its closed loop never saw ({seeds}). "
            + _fresh_check(t, notes, by_loop, z) + _fresh_against_lab(lay, t, notes, z)
            + _predicted_tension(pred) + ratio)


def _fresh_check(t: pd.DataFrame, notes: pd.Series, by_loop: pd.DataFrame, z: float) -> str:
    """The fresh-seed check: the fresh seeds' mean against the closed loop's (same card,
    same specimens, other packings), its verdict and table; a card whose closed loop did
    not converge is named (the check does not verify it)."""
    alpha = 100 * check_level(z)
    judged = t[notes == ""]
    miss = judged[~judged["passed"].astype(bool)]
    text = ("**The check**: do the fresh seeds read as the card's closed loop read on its own "
            "seeds? The same parameters on the same specimens differ between two sets of "
            "packings by sampling alone, so Student's two-sample t of the two means is judged "
            f"at the level of {z:g} normal standard errors ({alpha:.2f} %) shared among a "
            "card's targets: a card that generalises fails one target or more with that "
            "probability, whatever its number of targets and seeds. The closed loop judged "
            "its own mean against the lab (Table 5): together, the card meets the lab on "
            "packings it never saw. ")
    if len(by_loop):
        lo, hi = by_loop["mdd_pct"].min(), by_loop["mdd_pct"].max()
        text += (f"These seeds tell a difference of {lo:.1f}–{hi:.1f} % from noise (found "
                 "half the time). ")
    other = judged[judged["judged_by"] != "closed loop"]
    if len(other):
        why = (other.groupby("specimen")["lab_because"].first() if "lab_because" in other
               else pd.Series("", index=sorted(set(other["specimen"]))))
        text += ("Judged against the lab instead (no closed-loop mean of the same runs): "
                 + ", ".join(f"{sp} ({w})" if isinstance(w, str) and w else sp
                             for sp, w in why.items()) + ". ")
    text += ("Every card reproduces its closed loop." if miss.empty else
             "**Not reproduced**: " + ", ".join(
                 f"{r.specimen} {P.RESPONSES[r.response].symbol} "
                 + (f"({r.diff_pct:+.2f} % off the loop's mean, t = {r.t_loop:+.2f}, limit "
                    f"{r.t_crit:.2f})" if r.judged_by == "closed loop"
                    else f"({r.err_pct:+.2f} % off the lab, z = {r.z_score:+.2f})")
                 for r in miss.itertuples()) + ".")
    unverified = []
    if "loop_status" in by_loop.columns:  # the table says each card's loop status
        for sp, st in by_loop.groupby("specimen")["loop_status"].first().items():
            if isinstance(st, str) and st and st != "converged":
                unverified.append(f"{sp} ({st})")
    if unverified:
        text += (" The closed loops of " + ", ".join(unverified) + " did not converge: those "
                 "cards are checked against means that miss the lab (Table 5), and passing "
                 "here does not verify them.")
    skipped = sorted(set(t.loc[notes != "", "specimen"]))
    if skipped:
        text += " Not run: " + "; ".join(
            f"{sp} ({notes[t['specimen'] == sp].iloc[0]})" for sp in skipped) + "."
    rows = []
    for _, r in t.iterrows():
        loop = r["judged_by"] == "closed loop"
        rows.append([r["specimen"], P.RESPONSES[r["response"]].symbol,
                     f"{num(r['loop_mean'])} ± {num(r['loop_se'])} ({int(r['loop_n'])})"
                     if loop else "–",
                     f"{num(r['mean'])} ± {num(r['se'])}" + (
                         f" ({int(r['n'])}" + (f", {int(r['n_failed'])} failed)"
                                               if r["n_failed"] else ")")),
                     num(r["diff_pct"], "+.2f") if loop else "–",
                     f"{num(r['t_loop'], '+.2f')} ({num(r['t_crit'], '.2f')})" if loop else "–",
                     num(r["mdd_pct"], ".1f") if loop else "–",
                     "yes" if r["passed"] else "**no**"])
    return (text + "\n\n" + markdown_table(rows, [
        "specimen", "response", "closed loop: mean ± se (seeds)", "fresh seeds: mean ± se (seeds)",
        "fresh − loop %", "t (limit)", "detectable %", "passed"]) + "\n")


def _fresh_against_lab(lay, t: pd.DataFrame, notes: pd.Series, z: float) -> str:
    """The same fresh seeds against the lab value: the error, its z-score (the fresh
    seeds' and the lab's standard errors), ``within_z_se`` and the loop's own tolerance,
    with the odds that a card exactly on its targets misses them."""
    rows = [[r["specimen"], P.RESPONSES[r["response"]].symbol, num(r["lab"]),
             f"{num(r['mean'])} ± {num(r['se'])}", num(r["err_pct"], "+.2f"),
             num(r["z_score"], "+.2f"), "yes" if r["within_z_se"] else "no",
             "yes" if r["met"] else "no"] for _, r in t.iterrows()]
    miss = t[~t["within_z_se"].astype(bool) & (notes == "")]
    verdict = ("Every target lies within "
               f"{z:g} standard errors of the fresh seeds' mean." if miss.empty else
               "Outside " f"{z:g} standard errors: " + ", ".join(
                   f"{r.specimen} {P.RESPONSES[r.response].symbol} ({r.err_pct:+.2f} %, "
                   f"z = {r.z_score:+.2f})" for r in miss.itertuples()) + ".")
    judged = t[notes == ""]
    if len(judged):
        n = int(judged["n"].median())
        verdict += (f" A card exactly on its targets still misses this comparison with "
                    f"probability {100 * false_alarm(n, z):.1f} % per target on {n} seeds "
                    "(the standard error comes from the same seeds: Student's t with "
                    f"{n - 1} degrees of freedom), so one miss or more among these "
                    f"{len(judged)} targets has probability "
                    f"{100 * false_alarm(n, z, len(judged)):.0f} % even then.")
        specs = sorted(set(judged["specimen"]))
        k = _loop_seeds(lay, specs)
        if k:
            m = (_triaxial_seeds(lay, specs[0], k)
                 if P.TRI in set(judged["response"]) else None)
            ks = [m if r == P.TRI and m else k for r in judged["response"]]
            p_any = (1 - math.prod(1 - false_alarm(n, z, loop_seeds=kr) for kr in ks) if m
                     else false_alarm(n, z, len(judged), loop_seeds=k))
            fewer = (f" ({P.RESPONSES[P.TRI].symbol} on the first {m} of them: "
                     f"{100 * false_alarm(n, z, loop_seeds=m):.1f} %)" if m else "")
            verdict += (f" A card fitted exactly to the mean of its closed loop's {k} seeds "
                        "carries that mean's own error onto the fresh seeds, which their "
                        "standard error does not count: "
                        f"{100 * false_alarm(n, z, loop_seeds=k):.1f} % per target{fewer}, "
                        f"{100 * p_any:.0f} % for one miss or more. That is why the check "
                        "above compares with the closed loop's mean.")
    return ("\nThe same seeds against the lab value: the error of their mean, its z-score "
            "(the fresh seeds' and the lab's standard errors), whether the lab value lies "
            f"within {z:g} standard errors and whether the mean meets the loop's own "
            f"tolerance max(rtol, {z:g} standard errors). A measurement, not the check: "
            + verdict + "\n\n"
            + markdown_table(rows, ["specimen", "response", "lab", "fresh seeds: mean ± se",
                                    "error %", "z", f"within {z:g} se", "met"]) + "\n")


def _predicted_tension(pred: pd.DataFrame) -> str:
    """σt of the cards that have no tensile target, on the fresh seeds: the prediction
    and its seed scatter (the precision one disc of the study's size gives)."""
    if not len(pred):
        return ""
    rows = [[r["specimen"], P.RESPONSES[r["response"]].unicode, f"{num(r['mean'])} ± {num(r['se'])}",
             num(r["cv_pct"], ".1f"), f"{int(r['n'])}"] for _, r in pred.iterrows()]
    return ("\nThe tensile strengths each card has no lab value for, on the same fresh seeds "
            "(a prediction; valid tests only, an invalid specimen rerun on a replacement "
            "seed). The CV is the scatter of one specimen between packings: a single disc or "
            "cylinder of the study's size measures the strength to about that, the mean of n "
            "to CV/√n.\n\n"
            + markdown_table(rows, ["specimen", "response", "fresh seeds: mean ± se",
                                    "seed CV %", "valid seeds"]) + "\n")


def direct_over_brazilian(t: pd.DataFrame) -> str:
    """Each card's direct/Brazilian ratio σt,d/σt on its fresh seeds (a fresh-seeds table
    ``t`` with rows of both ``dtt_MPa`` and ``bts_MPa``, targets or predictions): the ratio
    of the two means, its standard error from theirs (first order; the two are measured on
    different specimens of the same packing seeds), "" when no card has both."""
    rows = []
    for sp, g in t.groupby("specimen", sort=False):
        by = {r["response"]: r for _, r in g.iterrows()}
        if not {"dtt_MPa", "bts_MPa"} <= set(by):
            continue
        d, b = by["dtt_MPa"], by["bts_MPa"]
        if not (math.isfinite(d["mean"]) and math.isfinite(b["mean"]) and b["mean"] > 0):
            rows.append([sp, "–", "–", f"{int(d['n'])}, {int(b['n'])}"])
            continue
        r = d["mean"] / b["mean"]
        se = r * math.hypot(d["se"] / d["mean"], b["se"] / b["mean"])
        rows.append([sp, f"{num(d['mean'])} / {num(b['mean'])}",
                     f"{r:.2f} ± {se:.2f}" if math.isfinite(se) else f"{r:.2f}",
                     f"{int(d['n'])}, {int(b['n'])}"])
    if not rows:
        return ""
    return ("\nThe direct/Brazilian ratio σt,d/σt of each card on the same fresh seeds (rock: "
            "about 0.7–0.8; the ratio of the two means, ± its standard error from theirs; "
            "the cylinder and the disc are different specimens of each packing seed):\n\n"
            + markdown_table(rows, ["specimen", "σt,d / σt [MPa]", "σt,d/σt",
                                    "valid seeds (direct, Brazilian)"]) + "\n")
