"""The verification tables job (rule ``verification_tables`` in
``workflow/rules/analysis.smk``, ``bpmcal verification-tables``): Tables 5 and 6 and Fig. 6
from the verified cards (:func:`verification_tables`), and the note Table 5 and the report
give of a card's tensile specimens per seed (:func:`tensile_note`).
"""
from __future__ import annotations

import math

import pandas as pd

from .. import params as P
from ..analysis.calibration.specimens import MISS_ACCEPTED
from ..io.card import read_card
from ..io.checks import BadInput
from ..io.figures import save_figure
from ..io.h5 import read_series
from ..io.tables import write_table
from ..params import SAMPLE_TESTS
from ..plots.calibration import fig_stress_strain
from .inputs import CSV, PNG, outputs, read_lab
from .verification import outside_items, seed_cv_shortfall


def tensile_note(v: dict) -> str:
    """What a card's ``verification.tensile`` says of its tensile specimens per seed when
    the loop raised their count or could not reach the seed CV it aims at ("" else)."""
    t = v.get("tensile") or {}
    if not t.get("raised") and t.get("chance_above", 0) < MISS_ACCEPTED:
        return ""
    n = int(v.get("tensile_specimens", 1))
    text = f"σt of a seed: the mean of {n} specimens"
    if t.get("raised"):
        r = t["raised"][0]
        text += f" (from round {r['round']}; {r['from']} before)"
    if "specimen_cv" in t:
        text += (f"; the specimens scatter {100 * t['specimen_cv']:.1f} % ({t['dof']} degrees "
                 f"of freedom), a seed's σt {100 * t['seed_cv_expected']:.1f} % expected")
    if t.get("chance_above", 0) >= MISS_ACCEPTED:
        text += ("; " + seed_cv_shortfall(t)
                 + (" (the count is verification.max_tensile_specimens)"
                    if n >= t.get("max", n) else ""))
    return text


def verification_tables(cards, runs, lab, *, table5, table6, figure) -> dict:
    """Tables 5 and 6 and Fig. 6 from the verified cards and their best rounds' run files
    (``runs[i]`` belongs to ``cards[i]``). Table 5 holds the seed mean of every response
    (single pass and closed loop), its seed standard deviation (``_sd``) and CV
    (``_cv_pct``), the error of the mean and ``n_seeds``. A card whose closed loop did not run
    (``not-run``) keeps its row, with empty responses, status ``not-run`` and the reason in
    ``note``; its Fig. 6 panel says why it has no curve. When some card has a tensile
    strength target, Table 5 also has the σt columns (empty for the specimens without
    one), ``missed``: every target the closed loop misses by more than its tolerance,
    with the error in %, ``tensile_specimens`` (per seed) and ``tensile_note``
    (:func:`tensile_note`)."""
    if len(runs) != len(cards):
        raise BadInput(f"--runs: {len(runs)} run file(s) for {len(cards)} card(s); expected "
                       "one per card, in the same order")
    loaded = [read_card(c, "--cards", need=("specimen", "parameters", "targets",
                                            "verification", "lab")) for c in cards]
    lab_df = read_lab(lab)
    outputs((table5, "--table5", CSV), (table6, "--table6", CSV), (figure, "--figure", PNG))
    t5, t6, curves = [], [], {}
    tensile = [r for r in SAMPLE_TESTS if any(r in c["targets"] for c in loaded)]
    for c, run in zip(loaded, runs):
        spec = str(c["specimen"])
        v = c["verification"]
        row = {"specimen": spec}
        ran = v["status"] != "not-run"
        for which in ("single_pass", "closed_loop"):
            r = v[which] if ran else None
            for k in P.TARGETS:
                row[f"{which}_{k}"] = r[k] if ran else math.nan
                sd = (r.get("seed_sd") or {}).get(k) if ran else None
                cv = (r.get("seed_cv") or {}).get(k) if ran else None  # None: one seed (NaN)
                row[f"{which}_{k}_sd"] = math.nan if sd is None else float(sd)
                row[f"{which}_{k}_cv_pct"] = math.nan if cv is None else 100 * float(cv)
                row[f"{which}_{k}_err_pct"] = r["errors_pct"][k] if ran else math.nan
        for k in P.TARGETS:
            row[f"lab_{k}"] = c["targets"][k]
        row["n_seeds"] = v.get("n_seeds", 1)
        row["rounds"] = v["rounds"]
        row["status"] = v["status"]
        row["calibration_status"] = c.get("status")
        row["note"] = v["message"] if not ran else outside_items(v.get("outside_design") or {})
        for resp in tensile:
            has = resp in c["targets"]
            for which in ("single_pass", "closed_loop"):
                row[f"{which}_{resp}"] = v[which][resp] if ran and has else math.nan
                row[f"{which}_{resp}_err_pct"] = (v[which]["errors_pct"][resp] if ran and has
                                                  else math.nan)
                cv = (v[which].get("seed_cv") or {}).get(resp) if ran and has else None
                row[f"{which}_{resp}_cv_pct"] = math.nan if cv is None else 100 * float(cv)
            row[f"lab_{resp}"] = c["targets"][resp] if has else math.nan
        if tensile:
            row["missed"] = "; ".join(f"{m['target']} {m['error_pct']:+.2f} %"
                                      for m in v.get("missed") or [])
            row["tensile_specimens"] = int(v.get("tensile_specimens", 1))
            row["tensile_note"] = tensile_note(v)
        t5.append(row)
        up_lab = c["lab"].get("u_pre_MJm3")
        up_sim = v["closed_loop"]["u_pre_MJm3"] if ran else math.nan
        t6.append({"specimen": spec, "sim_Up_MJm3": up_sim, "lab_Up_MJm3": up_lab,
                   "rel_error_pct": (100 * abs(up_sim - up_lab) / up_lab
                                     if up_lab and ran else math.nan),
                   "sim_peak_strain": v["closed_loop"]["peak_strain"] if ran else math.nan})
        curves[spec] = read_series(run) if ran else f"not run: {c.get('status')} calibration"
    t5 = pd.DataFrame(t5).set_index("specimen")
    t6 = pd.DataFrame(t6).set_index("specimen")
    write_table(t5, table5)
    write_table(t6, table6)
    save_figure(fig_stress_strain(curves, lab_df), figure)
    return {"table5": t5, "table6": t6}
