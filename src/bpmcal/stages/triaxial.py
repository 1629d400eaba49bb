"""The triaxial stage (``workflow/rules/triaxial.smk``): strength envelopes of the
calibrated and verified cards.

The DEM runs themselves are ``bpmcal triaxial --params CARD --sigma3 S`` jobs (one per
card and confining stress, ``stages.runs``); :func:`envelopes` gathers them:

- every run is one row of the points table, ok or not: a failed run keeps its failure
  record's reason, a missing or unreadable file says so (never dropped);
- per card, a Mohr-Coulomb envelope (c, phi; ``analysis.envelopes.fit_mohr_coulomb``) and
  a Hoek-Brown envelope (sigma_ci and m_i both fitted, ``fit_hoek_brown``) through the
  runs that are ok, with the number of runs used and, when fewer than all, which were
  left out and why; a card with too few good runs keeps its row with the reason;
- the card's sigma_c and, where the card holds one, its tensile strength sigma_t and
  sigma_c/sigma_t (``card_strengths``: the closed loop's DEM values first, else the
  regression's predictions, else the lab's; each value names its source);
- with lab triaxial points (``triaxial.lab_csv``, ``study.lab_triaxial``): the lab's own
  envelopes (one more row, card "lab") and every lab point against each card's envelopes
  (sigma1 predicted at the lab sigma3, error in %).

Units: MPa and degrees (the paper's) in every table.
"""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from .. import params as P
from ..analysis.envelopes import EnvelopeError, fit_hoek_brown, fit_mohr_coulomb
from ..io.card import card_parameters, read_card
from ..io.checks import BadInput, in_file
from ..io.figures import save_figure
from ..io.h5 import RunFileError, read_inputs, read_summary
from ..io.tables import write_table
from ..plots.envelopes import fig_envelopes
from ..study.lab_data import load_lab_triaxial
from .inputs import CSV, PNG, outputs, read_lab

#: the confining stresses of the study's triaxial runs by default [MPa]
DEFAULT_SIGMA3_MPA = (0.0, 5.0, 10.0, 20.0)

#: columns of the points table
POINT_COLUMNS = ("specimen", "card", "sigma3_MPa", "status", "sigma1_MPa", "E_GPa", "nu",
                 "sigma3_maxdev_rel", "sigma3_maxdev_MPa", "cracks_tension", "cracks_shear",
                 "wall_s", "error")


def _num(v) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return math.nan
    return x if math.isfinite(x) else math.nan


def card_kind(card: dict) -> str:
    """"verified" for a card with a closed-loop section, else "calibrated"."""
    return "verified" if isinstance(card.get("verification"), dict) else "calibrated"


def _get(d, *keys):
    for k in keys:
        if not isinstance(d, dict):
            return None
        d = d.get(k)
    return d


def card_strengths(card: dict) -> dict:
    """The card's sigma_c and sigma_t [MPa] with their sources, read defensively (a card
    holds sigma_t only when the calibration or verification produced one):

    - verified cards whose closed loop ran: the closed loop's DEM responses;
    - else the regression's prediction at the card's parameters (``predicted``);
    - sigma_t also from the lab targets (``targets``/``lab``), as ``lab_sigma_t_MPa``."""
    out = {"sigma_c_MPa": math.nan, "sigma_c_source": "", "sigma_t_MPa": math.nan,
           "sigma_t_source": "", "lab_sigma_c_MPa": math.nan, "lab_sigma_t_MPa": math.nan}
    v = card.get("verification") if isinstance(card.get("verification"), dict) else {}
    ran = v.get("status") not in (None, "not-run")
    for key, name in (("ucs_MPa", "sigma_c"), ("bts_MPa", "sigma_t")):
        for src, val in (("DEM closed loop", _get(v, "closed_loop", key) if ran else None),
                         ("regression prediction", _get(card, "predicted", key)),
                         ("card", card.get(key))):
            x = _num(val)
            if math.isfinite(x):
                out[f"{name}_MPa"], out[f"{name}_source"] = x, src
                break
        for src in (_get(card, "targets", key), _get(card, "lab", key)):
            x = _num(src)
            if math.isfinite(x):
                out[f"lab_{name}_MPa"] = x
                break
    return out


def _read_run(path, sigma3: float, params: dict, where: str) -> dict:
    """One run as a points-table row (without specimen/card): status ok | failed |
    missing | unreadable. A run of another test, another sigma3 or other parameters than
    its card's is bad input (the wrong file was given)."""
    row = {"sigma3_MPa": float(sigma3), "status": "", "error": ""}
    if not Path(path).exists():
        return {**row, "status": "missing", "error": f"run file {path} not found"}
    try:
        s = read_summary(path)
        inp = read_inputs(path)
    except RunFileError as e:
        return {**row, "status": "unreadable", "error": str(e)}
    if s.get("test") != "triaxial":
        raise BadInput(f"{where} {path}: a {s.get('test')!r} run, expected a triaxial run")
    s3 = _num(inp.get("sigma3_MPa"))
    if not math.isclose(s3, sigma3, rel_tol=1e-9, abs_tol=1e-9):
        raise BadInput(f"{where} {path}: a run at sigma3 = {s3:g} MPa, expected {sigma3:g} MPa "
                       "(the runs follow --sigma3 for each card, in order)")
    bad = [k for k in P.ALL_PARAMS if k in params
           and not math.isclose(_num(inp.get(k)), float(params[k]), rel_tol=1e-9)]
    if bad:
        raise BadInput(f"{where} {path}: run with other parameters than its card ({bad[0]} = "
                       f"{inp.get(bad[0])!r}, card {params[bad[0]]!r})")
    row["status"] = str(s.get("status", ""))
    row["error"] = str(s.get("error", "") or "")
    for k in POINT_COLUMNS[4:-1]:
        row[k] = _num(s.get(k))
    return row


def fit_envelopes(sigma3, sigma1) -> dict:
    """Mohr-Coulomb and Hoek-Brown fits of the points, as table columns; a fit that cannot
    be made leaves NaN and its reason in ``fit_note``."""
    out = {k: math.nan for k in ("c_MPa", "c_se_MPa", "phi_deg", "phi_se_deg", "mc_sigma_c_MPa",
                                 "mc_q", "mc_r2", "mc_rms_MPa", "mi", "mi_se",
                                 "hb_sigma_ci_MPa", "hb_r2", "hb_rms_MPa")}
    notes = []
    try:
        mc = fit_mohr_coulomb(sigma3, sigma1)
        out.update(c_MPa=mc.c, c_se_MPa=mc.c_se, phi_deg=mc.phi_deg, phi_se_deg=mc.phi_se_deg,
                   mc_sigma_c_MPa=mc.sigma_c, mc_q=mc.q, mc_r2=mc.r2, mc_rms_MPa=mc.rms)
    except EnvelopeError as e:
        notes.append(f"no Mohr-Coulomb fit: {e}")
    try:
        hb = fit_hoek_brown(sigma3, sigma1)
        out.update(mi=hb.mi, mi_se=hb.mi_se, hb_sigma_ci_MPa=hb.sigma_ci, hb_r2=hb.r2,
                   hb_rms_MPa=hb.rms)
    except EnvelopeError as e:
        notes.append(f"no Hoek-Brown fit: {e}")
    out["fit_note"] = "; ".join(notes)
    return out


def envelopes(cards, runs, *, sigma3, table, points, figure, lab=None, lab_triaxial=None,
              lab_table=None) -> dict:
    """Envelope table, points table and figure of the triaxial runs of ``cards``:
    ``runs[i * len(sigma3) + j]`` is the run of ``cards[i]`` at ``sigma3[j]`` [MPa]. With
    ``lab_triaxial`` (a lab triaxial CSV, checked against the specimens of ``lab`` or of the
    cards), ``lab_table`` compares every lab point with the cards' envelopes."""
    s3 = [float(x) for x in sigma3]
    if not s3 or any(not (math.isfinite(x) and x >= 0) for x in s3):
        raise BadInput(f"--sigma3 {sigma3}: expected confining stresses >= 0 MPa")
    if len(set(s3)) != len(s3):
        raise BadInput(f"--sigma3 {sigma3}: a confining stress is repeated")
    if len(runs) != len(cards) * len(s3):
        raise BadInput(f"--runs: {len(runs)} run file(s) for {len(cards)} card(s) x {len(s3)} "
                       "confining stress(es); expected one per card and sigma3, card by card")
    loaded = [read_card(c, "--cards", need=("specimen", "parameters")) for c in cards]
    specimens = list(dict.fromkeys(str(c["specimen"]) for c in loaded))
    known = list(read_lab(lab)["specimen"]) if lab is not None else specimens
    lab_pts = None
    if lab_triaxial is not None:
        lab_pts = load_lab_triaxial(in_file(lab_triaxial, "--lab-triaxial"), known)
        if lab_table is None:
            raise BadInput("--lab-triaxial needs --lab-table (the comparison table to write)")
    elif lab_table is not None:
        raise BadInput("--lab-table needs --lab-triaxial (the lab points to compare with)")
    outputs((table, "--table", CSV), (points, "--points", CSV), (figure, "--figure", PNG),
            (lab_table, "--lab-table", CSV))

    prow, erow = [], []
    for i, (path, c) in enumerate(zip(cards, loaded)):
        spec, kind = str(c["specimen"]), card_kind(c)
        params = card_parameters(c)
        rows = [{"specimen": spec, "card": kind,
                 **_read_run(runs[i * len(s3) + j], x, params, "--runs")}
                for j, x in enumerate(s3)]
        prow.extend(rows)
        ok = [r for r in rows if r["status"] == "ok"]
        left = [f"sigma3 = {r['sigma3_MPa']:g} MPa {r['status']}"
                + (f" ({r['error']})" if r["error"] else "") for r in rows if r["status"] != "ok"]
        fit = fit_envelopes([r["sigma3_MPa"] for r in ok], [r["sigma1_MPa"] for r in ok])
        note = []
        if left:
            note.append(f"fitted on {len(ok)} of {len(rows)} runs; left out: "
                        + "; ".join(left))
        if fit["fit_note"]:
            note.append(fit["fit_note"])
        v = c.get("verification") if isinstance(c.get("verification"), dict) else None
        if v is not None and v.get("status") == "not-run":
            note.append("closed loop not run: the verified card holds the calibration's "
                        "parameters")
        st = card_strengths(c)
        if not math.isfinite(st["sigma_c_MPa"]):
            zero = [r for r in ok if r["sigma3_MPa"] == 0.0]
            if zero:
                st["sigma_c_MPa"], st["sigma_c_source"] = zero[0]["sigma1_MPa"], "triaxial sigma3 = 0"
        ratio = (st["sigma_c_MPa"] / st["sigma_t_MPa"]
                 if math.isfinite(st["sigma_c_MPa"]) and st["sigma_t_MPa"] > 0 else math.nan)
        erow.append({"specimen": spec, "card": kind,
                     "status": ("ok" if len(ok) == len(rows) and not fit["fit_note"]
                                else "partial" if math.isfinite(fit["c_MPa"])
                                or math.isfinite(fit["mi"]) else "failed"),
                     "runs_ok": len(ok), "runs": len(rows),
                     **{k: v for k, v in fit.items() if k != "fit_note"},
                     **st, "sigma_c_over_sigma_t": ratio,
                     "calibration_status": c.get("status", ""),
                     "note": "; ".join(note)})
    if lab_pts is not None:
        for spec, g in lab_pts.groupby("specimen", sort=False):
            fit = fit_envelopes(g["sigma3_MPa"], g["sigma1_MPa"])
            zero = g[g["sigma3_MPa"] == 0.0]
            erow.append({"specimen": spec, "card": "lab", "status": "ok" if not fit["fit_note"]
                         else "partial", "runs_ok": len(g), "runs": len(g),
                         **{k: v for k, v in fit.items() if k != "fit_note"},
                         "sigma_c_MPa": float(zero["sigma1_MPa"].mean()) if len(zero)
                         else math.nan, "sigma_c_source": "lab triaxial sigma3 = 0"
                         if len(zero) else "", "note": fit["fit_note"]})
    pts = pd.DataFrame(prow).reindex(columns=list(POINT_COLUMNS))
    env = pd.DataFrame(erow)
    comp = None
    if lab_pts is not None:
        comp = lab_comparison(env[env["card"] != "lab"], lab_pts)
        write_table(comp, lab_table, index=False)
    write_table(env, table, index=False)
    write_table(pts, points, index=False)
    save_figure(fig_envelopes(pts, env[env["card"] != "lab"], lab_pts), figure)
    return {"envelopes": env, "points": pts, "lab": comp}


def lab_comparison(env: pd.DataFrame, lab_pts: pd.DataFrame) -> pd.DataFrame:
    """Every lab point against the envelopes of every card of its specimen: sigma1 of the
    Mohr-Coulomb and Hoek-Brown fits at the lab sigma3, and the errors in % of the lab
    sigma1 (NaN where the card has no envelope)."""
    rows = []
    for r in lab_pts.itertuples():
        for e in env[env["specimen"] == r.specimen].itertuples():
            mc = (e.mc_sigma_c_MPa + e.mc_q * r.sigma3_MPa
                  if math.isfinite(e.mc_q) else math.nan)
            hb = (r.sigma3_MPa + e.hb_sigma_ci_MPa
                  * math.sqrt(e.mi * r.sigma3_MPa / e.hb_sigma_ci_MPa + 1.0)
                  if math.isfinite(e.mi) and math.isfinite(e.hb_sigma_ci_MPa) else math.nan)
            rows.append({"specimen": r.specimen, "card": e.card, "sigma3_MPa": r.sigma3_MPa,
                         "lab_sigma1_MPa": r.sigma1_MPa, "mc_sigma1_MPa": mc,
                         "mc_err_pct": 100 * (mc - r.sigma1_MPa) / r.sigma1_MPa,
                         "hb_sigma1_MPa": hb,
                         "hb_err_pct": 100 * (hb - r.sigma1_MPa) / r.sigma1_MPa})
    cols = ["specimen", "card", "sigma3_MPa", "lab_sigma1_MPa", "mc_sigma1_MPa", "mc_err_pct",
            "hb_sigma1_MPa", "hb_err_pct"]
    return pd.DataFrame(rows, columns=cols)


__all__ = ["DEFAULT_SIGMA3_MPA", "card_kind", "card_strengths", "envelopes", "fit_envelopes",
           "lab_comparison"]
