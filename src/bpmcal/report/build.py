"""Assemble ``results/report/``: every table (CSV + Markdown) and figure (PNG + PDF) of the
study, and ``index.md`` with the settings and seeds used, the failed samples, and every
result. For the paper's own study (``study.reference: yu2026``) each result stands next to
the value Yu et al. (2026) publish, with the difference (and ``tables/comparison.csv``); for
any other rock (``reference: none``) the paper's columns, shares and comparisons are left
out, not filled with dashes.

The report reads the files of the study's layout (``bpmcal.io.study_files``: the report rule
declares every one of them as its input) and writes the files ``StudyFiles.report_outputs``
names; a file that is not there (a partial study) leaves its section out."""
from __future__ import annotations

import json
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from .. import __version__
from .. import params as P
from ..io import study_files as L
from ..io.atomic import write_text
from ..io.card import read_card
from ..io.checks import BadInput, out_file, parse_json, read_json, read_yaml
from ..io.h5 import read_summary
from ..io.provenance import git_commit
from ..io.tables import markdown_table, write_table
from ..study import paper
from ..study.config import check_study_config
from .bts_size import section as bts_size_section
from .cells import compare, num, pct_diff, read_table
from .posterior import section as posterior_section
from .verification import section as verification_section

#: tables and figures of the report (stem -> caption)
TABLES = {
    L.TABLE3: "Table 3: XGBoost importance (%) of the meso-parameters",
    L.TABLE4: "Table 4: quadratic and interaction terms retained by the stepwise regression",
    L.REGRESSION_FIT: "Adjusted and cross-validated R² of every stage",
    L.CALIBRATION: "Calibrated meso-parameters of the lab specimens",
    L.TABLE5: "Table 5: verification - DEM vs lab (single pass and closed loop)",
    L.TABLE6: "Table 6: pre-peak energy density, DEM vs lab",
    L.FRESH_SEEDS: "The verified cards on fresh packing seeds against the lab targets",
    L.RATIO_SWEEP: "Bond-strength-ratio sweep: cracks and proportions",
    L.IMPACT_ENERGY: "Drop-hammer impact: energy budget over time",
    L.T10_ECS: "t10 against specific energy (impact-velocity sweep)",
    L.TRIAXIAL_ENVELOPES: "Triaxial envelopes per card: c, φ, mi, σc, σt, σc/σt, fit quality",
    L.TRIAXIAL_POINTS: "Triaxial runs of the cards (every run, ok or failed)",
    L.TRIAXIAL_LAB: "Lab triaxial points against the cards' envelopes",
}
FIGURES = {
    L.FIG_SCREENING: "XGBoost importance shares with fold spread and shadow reference",
    L.FIG_REGRESSION: "Stepwise regression: predicted vs simulated",
    L.FIG4: "Fig. 4: cracks and their proportions vs bond-strength ratio",
    L.FIG5: "Fig. 5: failure patterns (broken bonds) at selected ratios",
    L.FIG6: "Fig. 6: stress-strain curves of the calibrated specimens",
    L.FIG7: "Fig. 7: energy and crack evolution of the 6 m/s impact",
    L.FIG_T10: "t10 vs specific energy with the JK breakage model",
    L.FIG_ENVELOPES: "Triaxial strength envelopes (σ1 vs σ3) of the cards",
}


def _copy(lay: L.StudyFiles, src: str) -> bool:
    """Copy a table, figure or the equations into the report folder (if it exists)."""
    if not Path(src).exists():
        return False
    dst = Path(lay.report_copy(src))
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(src, dst)
    return True


def copy_outputs(lay: L.StudyFiles, sweep: bool = True, triaxial: bool = False,
                 triaxial_lab: bool = False, fresh_seeds: bool = False) -> dict:
    """Copy the tables, figures and equations into the report folder; returns the stems
    of the tables and figures found."""
    found = {"tables": [], "figures": []}
    for kind, files in (("tables", lay.report_tables(sweep, triaxial, triaxial_lab, fresh_seeds)),
                        ("figures", lay.report_figures(sweep, triaxial))):
        for f in files:
            copied = [_copy(lay, c) for c in L.companions(f)]
            if copied[0]:
                found[kind].append(Path(f).stem)
    _copy(lay, lay.equations)
    return found


def report(outdir=None, *, config=None, config_json=None, config_out=None) -> Path:
    """The job of ``bpmcal report``: the study config from ``config`` (a JSON or YAML file)
    or ``config_json`` (the text the workflow passes), checked; written to ``config_out``
    (JSON) when given; then :func:`build` for the study in ``outdir`` (default: the
    config's ``outdir``). Returns the index file."""
    if (config is None) == (config_json is None):
        raise BadInput("give the study config with exactly one of --config FILE and "
                       "--config-json TEXT")
    if config_json is not None:
        cfg = parse_json(config_json, "--config-json")
    elif str(config).endswith(".json"):
        cfg = read_json(config, "--config")
    else:
        cfg = read_yaml(config, "--config")
    if not isinstance(cfg, dict) or not isinstance(cfg.get("study"), dict):
        raise BadInput("--config: not a study config (no 'study' section)")
    check_study_config(cfg, "--config" if config is not None else "--config-json")
    if outdir is None:
        if not isinstance(cfg.get("outdir"), str):
            raise BadInput("--config: no 'outdir' (give --outdir)")
        outdir = cfg["outdir"]
    if not Path(outdir).is_dir():
        raise BadInput(f"--outdir {outdir}: not a directory (expected the study's output "
                       "folder)")
    if config_out is not None:
        out_file(config_out, "--config-out", suffixes=(".json",))
    out_file(L.StudyFiles(outdir).report_index, "--outdir", suffixes=(".md",))
    if config_out is not None:
        write_text(config_out, json.dumps(cfg, indent=1, sort_keys=True) + "\n")
    return build(outdir, cfg)


def build(outdir, config: dict) -> Path:
    """Write the report of the study in ``outdir`` (its layout) for ``config``."""
    lay = L.StudyFiles(outdir)
    cfg = config
    sweep = bool(cfg.get("ratio_sweep", {}).get("enabled", True))
    tx = cfg.get("triaxial") or {}
    triax, tlab = bool(tx.get("enabled", False)), bool(tx.get("lab_csv"))
    fresh = bool((cfg.get("verification") or {}).get("fresh_seeds"))
    Path(lay.report_dir).mkdir(parents=True, exist_ok=True)
    found = copy_outputs(lay, sweep, triax, tlab, fresh)
    S = []  # sections of index.md
    ref = is_paper_study(cfg)
    if ref:
        S.append(f"# {cfg['study']['name']}: the paper, regenerated\n")
        S.append(f"Reproduction of {paper.REFERENCE}\n")
    else:
        S.append(f"# {cfg['study']['name']}: calibration report\n")
        S.append(f"Lab data: `{cfg['lab']['csv']}`.\n")
    S.append(f"bpmcal {__version__}, commit `{git_commit()}`.\n")
    S.append(_settings(lay, cfg, ref))
    S.append(_not_found(lay, outdir, sweep, triax, tlab, fresh))
    comp: list[dict] = []  # every published value we compare against, one row each
    S.append(_table3(lay, comp, ref))
    S.append(_regression(lay, comp, ref))
    S.append(_calibration(lay, cfg, comp, ref))
    S.append(verification_section(lay, comp, ref))
    S.append(bts_size_section(lay, _specimens(lay)))
    S.append(_ratio(lay, comp, ref) if sweep else "")
    S.append(_impact(lay, cfg, comp, ref))
    S.append(_triaxial(lay, cfg, ref) if triax else "")
    S.append(posterior_section(lay, cfg, _specimens(lay)))
    if comp:
        write_table(pd.DataFrame(comp), lay.comparison, index=False)
        S.append("All of these comparisons, one row per published value: "
                 "[tables/comparison.md](tables/comparison.md) "
                 "([CSV](tables/comparison.csv)).\n")
    S.append("## Figures\n")
    for stem in found["figures"]:
        S.append(f"### {FIGURES[stem]}\n\n![{stem}](figures/{stem}.png)\n")
    missing = sorted(set(FIGURES) - set(found["figures"]) - (set() if triax else {L.FIG_ENVELOPES}))
    if missing:
        S.append(f"Figures not produced by this configuration: {', '.join(missing)}\n")
    S.append("## Tables\n")
    for stem in found["tables"]:
        S.append(f"- [{TABLES[stem]}](tables/{stem}.md) ([CSV](tables/{stem}.csv))")
    if ref:
        S.append("\n## Notes on the paper\n")
        S.extend(f"- {n}" for n in paper.NOTES)
    return write_text(lay.report_index, "\n".join(S) + "\n")


def _not_found(lay, outdir, sweep, triax, tlab, fresh) -> str:
    """The files this configuration's report shows that the study has not written (a
    partial run, or a stage that failed): named, so that a missing section is explained."""
    want = [lay.dataset, *lay.report_tables(sweep, triax, tlab, fresh),
            *lay.report_figures(sweep, triax)]
    gone = [os.path.relpath(p, outdir) for p in want if not Path(p).exists()]
    if not gone:
        return ""
    return ("**Not in this study yet** (their sections, tables and figures are left out of "
            "this report; rerun the study to make them): "
            + ", ".join(f"`{g}`" for g in gone) + ".\n")


def is_paper_study(cfg: dict) -> bool:
    """True when the study is the paper's (``study.reference: yu2026``): only then does the
    report show the paper's values, columns and comparisons."""
    return (cfg.get("study") or {}).get("reference") == "yu2026"


def _settings(lay, cfg, ref=False) -> str:
    ds_path = Path(lay.dataset)
    lines = ["## Settings\n"]
    sp, u = cfg["specimen"], cfg["compression"]
    lines.append(f"- Samples: {cfg['study']['n_samples']} (Latin hypercube, seed "
                 f"{cfg['study']['lhs_seed']}, packing seeds derived from it)")
    lines.append("- Sampled ranges (the design space; the calibration stays inside them): "
                 + ", ".join(f"{k} [{lo:g}, {hi:g}]" for k, (lo, hi) in cfg["ranges"].items()))
    lines.append(f"- Specimen scale {sp['scale']:g}: {sp['scale'] * sp['diameter_mm']:g} x "
                 f"{sp['scale'] * sp['height_mm']:g} mm" + (" (the paper: 50 x 100 mm)" if ref else "")
                 + "; radii uniform in [Rmin, 1.66 Rmin], ρ = 2294 kg/m³")
    lines.append(f"- UCS: platens at {u['platen_velocity']:g} m/s each, local damping "
                 f"{u['damping']:g}, E and ν fitted over 40-60 % of the peak")
    c = cfg["calibration"]
    lines.append(f"- Calibration: fixed {c['fixed']}, free {c['free']}"
                 + (f", bounds {c['bounds']}" if c.get("bounds") else "")
                 + f", verification seed {cfg['verification']['seed']}")
    lines.append(f"- Impact: scale {cfg['impact']['scale']:g}, hammer "
                 f"{cfg['impact']['hammer_mass_kg'] * cfg['impact']['scale'] ** 3:.3f} kg "
                 f"({cfg['impact']['hammer_mass_kg']:g} kg at full size), dashpot ratio "
                 f"{cfg['impact']['dp_ratio']:g}")
    if ds_path.exists():
        ds = pd.read_csv(ds_path)
        bad = ds[ds["status"] != "ok"]
        lines.append(f"- Dataset: {len(ds) - len(bad)} of {len(ds)} samples ok")
        if len(bad):
            lines.append("- Failed samples (left out of the analysis):")
            for r in bad.itertuples():
                lines.append(f"  - {r.sample_id}: {r.status}: {r.error}")
        else:
            lines.append("- Failed samples: none")
        w = ds.loc[ds["status"] == "ok", "wall_s"]
        if len(w):
            lines.append(f"- DEM time per sample: median {w.median():.1f} s "
                         f"(range {w.min():.1f}-{w.max():.1f} s)")
        for test, name, why in (("bts", "Brazilian", "ISRM: the fracture did not start in "
                                 "the disc's central zone or did not split it"),
                                ("dtt", "Direct-tension", "the specimen broke next to a grip")):
            if f"{test}_status" not in ds.columns:  # the tensile test of every sample
                continue
            st = ds[f"{test}_status"]
            bb = ds[st != "ok"]
            n_inv = int((st == "invalid").sum())
            lines.append(f"- {name} tests: {len(ds) - len(bb)} of {len(ds)} valid and ok"
                         + (f", {n_inv} invalid ({why})" if n_inv else "")
                         + (" (left out of the σt analysis):" if len(bb) else ""))
            for r in bb.itertuples():
                lines.append(f"  - {r.sample_id}: {name} {getattr(r, f'{test}_status')}: "
                             f"{getattr(r, f'{test}_error')}")
            w = ds.loc[st == "ok", f"{test}_wall_s"]
            if len(w):
                lines.append(f"- {name} time per sample: median {w.median():.1f} s "
                             f"(range {w.min():.1f}-{w.max():.1f} s)")
            if test == "bts":
                lines.append(_disc_note(cfg, ds))
        ratio = _direct_over_brazilian(ds)
        if ratio:
            lines.append(ratio)
    return "\n".join(lines) + "\n"


def _direct_over_brazilian(ds: pd.DataFrame) -> str:
    """The direct/Brazilian strength ratio σt,d/σt of the samples with both tensile
    strengths valid (rock: about 0.7-0.8), or "" without both tests."""
    if not {"bts_MPa", "dtt_MPa"} <= set(ds.columns):
        return ""
    r = (ds["dtt_MPa"] / ds["bts_MPa"]).replace([np.inf, -np.inf], np.nan).dropna()
    if not len(r):
        return ("- Direct/Brazilian ratio σt,d/σt: no sample has both tensile strengths "
                "valid")
    return (f"- Direct/Brazilian ratio σt,d/σt: median {r.median():.2f} (range "
            f"{r.min():.2f}-{r.max():.2f}) over the {len(r)} samples with both valid (rock: "
            "about 0.7-0.8; the two are measured on different specimens, the cylinder and "
            "the disc)")


def _disc_note(cfg: dict, ds: pd.DataFrame) -> str:
    """Which disc σt is measured on, that the closed loop fits it as measured, and where the
    comparison at the lab's disc size is."""
    b, sp = cfg.get("bts") or {}, cfg.get("specimen") or {}
    scale = b.get("scale") if b.get("scale") is not None else sp.get("scale", 1.0)
    d, t = b.get("diameter_mm", 50.0) * scale, b.get("thickness_mm", 25.0) * scale
    across = (f", {ds['bts_balls_across'].median():.1f} mean ball diameters across "
              "(median)" if "bts_balls_across" in ds.columns else "")
    from ..lab.brazilian import BTSSettings, across_mm, min_across

    need = min_across(cfg.get("contact_model", P.DEFAULT_CONTACT_MODEL),
                      BTSSettings(min_balls_across=b.get("min_balls_across")))
    if need > 0 and P.RMIN in ds.columns:  # the rule of lab.brazilian.resolved_disc
        big = int((d < across_mm(ds[P.RMIN], need)).sum())
        across += (f"; {big} of {len(ds)} samples' discs enlarged to {need:g} mean ball "
                   "diameters across (bts.min_balls_across: a coarser disc starts its "
                   "fracture at a platen)")
    return (f"- σt is measured on a {d:g} × {t:g} mm disc{across}, and the closed loop fits "
            "a lab σt on it as measured: σt falls with the disc's size (docs/measurements: "
            "the size curve), so a lab value from a larger disc asks for a stronger card "
            "than that fit shows; where the lab CSV gives its discs' diameter "
            "(`bts_diameter_mm`), \"σt at the lab's disc size\" compares at that size")


def _table3(lay, comp, ref=False) -> str:
    t3 = read_table(lay, L.TABLE3, index_col=0)
    if t3 is None:
        return ""
    rows = []
    for p in P.ALL_PARAMS:
        if p not in t3.index:
            continue
        r = [P.ALL_PARAMS[p].symbol]
        for resp in P.TARGETS:
            ours = t3.loc[p, resp] if resp in t3.columns else math.nan
            if ref:
                theirs = paper.TABLE3[p][resp]
                compare(comp, "Table 3", f"importance of {p} for {resp}", ours, theirs, "%")
                r.append(f"{num(ours, '.1f')} ({theirs:.1f})")
            else:
                r.append(num(ours, ".1f"))
        for resp in P.SAMPLE_TESTS:  # a tensile or triaxial test of every sample (none in the paper)
            if resp in t3.columns:
                r.append(num(t3.loc[p, resp], ".1f") + (" (–)" if ref else ""))
        rows.append(r)
    head = ("## Table 3: XGBoost screening (ours, paper in brackets, % of gain)\n\n" if ref
            else "## Table 3: XGBoost screening (% of gain)\n\n")
    tens = [resp for resp in P.SAMPLE_TESTS if resp in t3.columns]
    cols = ["parameter", "σc", "E", "ν", *(P.RESPONSES[resp].unicode for resp in tens)]
    note = ("\nσt: the Brazilian test of every sample (σt,d: the direct-tension test); the "
            "paper publishes no tensile data.\n" if ref and tens else "")
    if P.TRI in tens:
        note += ("\nσ1(σ3,d): σ1 at failure of one triaxial test of every sample at the "
                 "design confinement (triaxial.design_sigma3_MPa).\n")
    return head + markdown_table(rows, cols) + "\n" + note


def _regression(lay, comp, ref=False) -> str:
    fit = read_table(lay, L.REGRESSION_FIT)
    if fit is None:
        return ""
    rows = []
    for r in fit.itertuples():
        if not ref:
            rows.append([r.response, r.stage, num(r.adj_r2), num(r.cv_r2_mean)])
            continue
        theirs = paper.ADJ_R2.get(r.response, {}).get(r.stage)
        if theirs:
            compare(comp, "Regression", f"adjusted R² of {r.response}, {r.stage}", r.adj_r2, theirs)
        rows.append([r.response, r.stage, num(r.adj_r2), num(theirs) if theirs else "–",
                     (f"{r.adj_r2 - theirs:+.3f}" if theirs else "–"), num(r.cv_r2_mean)])
    eq = Path(lay.equations)
    header = (["response", "stage", "ours", "paper", "difference", "CV R² (ours)"] if ref
              else ["response", "stage", "adjusted R²", "CV R²"])
    s = "## Stepwise regression: adjusted R² per stage\n\n" + markdown_table(rows, header)
    if eq.exists():
        s += ("\n\nOur equations (all stages): " if ref else "\n\nThe equations (all stages): ")
        s += "[equations.md](equations.md)\n"
        if ref:
            s += "\nThe paper's main-effect equations: " + "; ".join(
                paper.EQUATIONS["main"].values()) + "\n"
    return s + "\n"


def _specimens(lay) -> list[str]:
    """The lab specimens in the lab CSV's order (the calibration table's)."""
    t = Path(lay.table(L.CALIBRATION))
    if not t.exists():
        return []
    return [str(x) for x in pd.read_csv(t, dtype={"specimen": str})["specimen"]]


def _calibration(lay, cfg, comp, ref=False) -> str:
    specs = [s for s in _specimens(lay) if Path(lay.card(s)).exists()]
    if not specs:
        return ""
    rows, notes = [], []
    model = P.contact_model(cfg.get("contact_model"))
    ratio_name = ("bond-strength ratio" if model.name == P.DEFAULT_CONTACT_MODEL
                  else f"strength ratio {model.ratio_symbol}")
    for spec in specs:
        card = read_card(lay.card(spec))
        p = card["parameters"]
        theirs = paper.CALIBRATED.get(spec) if ref else None
        bounds = card.get("bounds") or {}
        shown = [k for k, role in card["roles"].items() if role in ("free", "derived")]
        for k in shown:
            ci = next((i for i in card["bootstrap"]["intervals"] if i.get("quantity") == k),
                      None)
            ci_s = (f"[{num(ci.get('lower'))}, {num(ci.get('upper'))}] (n={ci.get('n')})"
                    if ci else "–")
            b = bounds.get(k)
            b_s = f"[{num(b['lower'], '.4g')}, {num(b['upper'], '.4g')}]" if b else "–"
            row = [spec, P.ALL_PARAMS[k].symbol, num(p[k]), ci_s, b_s]
            if ref:
                th = theirs.get(k) if theirs else None
                if th is not None:
                    compare(comp, "Calibration", f"{spec} {k}", p[k], th, P.ALL_PARAMS[k].unit)
                row += [num(th) if th is not None else "–",
                        pct_diff(p[k], th) if th is not None else "–"]
            rows.append(row + [card["status"]])
        if card["status"] != "ok":
            notes.append(f"- **{spec}: {card['status']}** — {card['message']}")
        sr = card.get("strength_ratio") or {}
        for resp in P.TENSILE_TESTS:
            if sr.get("set_by") == f"{resp} target":
                notes.append(f"- {spec}: the lab tensile strength "
                             f"{P.RESPONSES[resp].unicode} = {num(card['targets'][resp])} MPa "
                             f"sets the {ratio_name}: {num(sr['value'])} (not the ratio "
                             "in the title)")
        for m in card.get("missed") or []:
            notes.append(f"- {spec}: target {m['target']} missed by the calibration: lab "
                         f"{num(m['value'])}, regression {num(m['predicted'])} "
                         f"({num(m['error_pct'], '+.2f')} %)")
    chosen = Path(lay.sweep_chosen)
    sweep = bool(cfg.get("ratio_sweep", {}).get("enabled", True))
    ratio = (json.loads(chosen.read_text())["chosen_ratio"] if sweep and chosen.exists()
             else None)
    if ratio is None:  # no sweep, or it chose no ratio: the configured one was used
        ratio = cfg["calibration"]["strength_ratio"]
    header = ["specimen", "parameter", "calibrated", "95 % bootstrap interval", "bounds"]
    if ref:
        header += ["paper", "difference"]
    header += ["inversion status"]
    title = (f"## Calibrated meso-parameters ({ratio_name} {ratio:g}; paper 1.4)\n\n" if ref
             else f"## Calibrated meso-parameters ({ratio_name} {ratio:g})\n\n")
    out = title + markdown_table(rows, header) + "\n"
    coh_sym, ten = P.ALL_PARAMS[model.coh].unicode, model.ten
    out += ("\nBounds: the configured ranges (the design space), narrowed by calibration.bounds "
            f"and, for {coh_sym}, by ranges.{ten} / ratio; each card names where every bound "
            "comes from.\n")
    if notes:
        out += "\n" + "\n".join(notes) + "\n"
    return out


def _ratio(lay, comp, ref=False) -> str:
    f = Path(lay.sweep_chosen)
    if not f.exists():
        return ""
    ch = json.loads(f.read_text())
    failed = ""
    t = Path(lay.table(L.RATIO_SWEEP))
    if t.exists():
        sw = pd.read_csv(t)
        bad = sw[sw["status"] != "ok"] if "status" in sw.columns else sw.iloc[:0]
        if len(bad):
            failed = "\nRuns of the sweep left out (failed, unreadable or not run):\n\n" + "\n".join(
                f"- a = {r.ratio:g} ({r.sample_id}): {r.status}: "
                f"{getattr(r, 'reason', '') if isinstance(getattr(r, 'reason', ''), str) else ''}"
                for r in bad.itertuples()) + "\n"
    if ch.get("chosen_ratio") is None:
        s = (f"## Bond-strength ratio\n\nNo ratio chosen: {ch.get('reason', '')}. The "
             "calibration used the configured ratio (calibration.strength_ratio)")
        if not ref:
            return s + ".\n" + failed
        compare(comp, "Ratio sweep", "bond-strength ratio a", None, paper.RATIO)
        return s + f"; the paper chose {paper.RATIO:g}.\n" + failed
    s = (f"## Bond-strength ratio\n\nChosen a = σcp/τcp = {ch['chosen_ratio']:g} "
         f"({ch['criterion']} {num(ch['value'])} vs target {ch['target']:g})")
    if not ref:
        return s + ".\n" + failed
    compare(comp, "Ratio sweep", "bond-strength ratio a", ch["chosen_ratio"], paper.RATIO)
    return (s + f"; the paper chose {paper.RATIO:g} (difference "
            f"{ch['chosen_ratio'] - paper.RATIO:+.1f}).\n" + failed)


def _impact(lay, cfg, comp, ref=False) -> str:
    v = L.velocity_tag(cfg["impact"]["velocity"])
    f = Path(lay.impact_run(v))
    if not f.exists():
        return ""
    s = read_summary(f)
    if s.get("status") != "ok":
        if ref:
            compare(comp, "Impact", f"W_in at {v} m/s, full-size equivalent", None,
                    paper.IMPACT["W_in_J"], "J")
            compare(comp, "Impact", "eta_f = G_f / W_in", None, paper.IMPACT["eta_f"])
        return (f"## Drop-hammer impact at {v} m/s\n\nThe impact run failed: "
                f"{s.get('error', '')}\n")
    sc = float(cfg["impact"]["scale"]) ** 3
    w_full = s["W_in_J"] / sc
    if ref:
        compare(comp, "Impact", f"W_in at {v} m/s, full-size equivalent", w_full,
                paper.IMPACT["W_in_J"], "J")
        compare(comp, "Impact", "eta_f = G_f / W_in", s["eta_f"], paper.IMPACT["eta_f"])
        rows = [["W_in (J), scaled to full size", num(w_full, ".1f"),
                 num(paper.IMPACT["W_in_J"], ".1f"), pct_diff(w_full, paper.IMPACT["W_in_J"])],
                ["η_f = G_f / W_in", num(100 * s["eta_f"], ".1f") + " %",
                 num(100 * paper.IMPACT["eta_f"], ".1f") + " %",
                 pct_diff(s["eta_f"], paper.IMPACT["eta_f"])],
                ["energy closure (max over time)", num(100 * s["closure_rel_max"], ".3f") + " %",
                 "–", "–"]]
        header = ["quantity", "ours", "paper", "difference"]
    else:
        rows = [["W_in (J), scaled to full size", num(w_full, ".1f")],
                ["η_f = G_f / W_in", num(100 * s["eta_f"], ".1f") + " %"],
                ["energy closure (max over time)", num(100 * s["closure_rel_max"], ".3f") + " %"]]
        header = ["quantity", "value"]
    out = f"## Drop-hammer impact at {v} m/s\n\n" + markdown_table(rows, header) + "\n"
    out += _impact_card_note(lay)
    out += (f"\nStages: crack initiation {1e3 * s['t_initiation_s']:.3f} ms, peak crack rate "
            f"{1e3 * s['t_peak_rate_s']:.3f} ms, through-failure {1e3 * s['t_through_s']:.3f} ms"
            f" after first contact ({s.get('cracks_after_burst', 0)} of the "
            f"{s['cracks_tension'] + s['cracks_shear']} cracks came after the primary burst, "
            "while the hammer crushed the fragments); "
            f"t10 = {s['t10_pct']:.1f} % "
            f"(a t10-size fragment holds ~{s['balls_per_t10_fragment']:.1f} balls"
            + ("; below ~30 balls t10 reflects the ball size more than the rock)"
               if s["balls_per_t10_fragment"] < 30 else ")") + "\n")
    jk = Path(lay.jk_fit)
    if jk.exists():
        fit = json.loads(jk.read_text())
        if fit:
            out += (f"\nJK fit t10 = A (1 − exp(−b Ecs)): A = {fit['A']:.1f} %, b = "
                    f"{fit['b']:.3g} t/kWh, A·b = {fit['Ab']:.1f} ({fit['n']} velocities)\n")
    return out


def _impact_card_note(lay) -> str:
    """Say so when the impact's specimen has no verified calibration (the impact rule uses
    the first lab specimen's verified card; if its closed loop did not run, or did not
    converge from an unreachable start, the parameters are not a calibrated rock)."""
    specs = _specimens(lay)
    if not specs or not Path(lay.verified_card(specs[0])).exists():
        return ""
    first = specs[0]
    card = read_card(lay.verified_card(first))
    if card.get("status") == "unreachable":
        v = card.get("verification", {})
        return (f"\n**Not a calibrated rock:** the impact used specimen {first}'s card, whose "
                f"inversion is unreachable (closed loop: {v.get('status')}); its parameters are the "
                "closest point inside the sampled ranges, not a calibration.\n")
    return ""


def _triaxial(lay, cfg, ref=False) -> str:
    """σt, σc/σt, c, φ and mi of every tested card, the runs left out, the lab triaxial
    comparison, and (paper study) what the paper does not publish."""
    env = read_table(lay, L.TRIAXIAL_ENVELOPES, dtype={"specimen": str})
    if env is None:
        return ""
    tx = cfg.get("triaxial") or {}
    s3 = ", ".join(f"{x:g}" for x in tx.get("sigma3_MPa", []))
    out = ["## Tension and confinement: σt, σc/σt, Mohr–Coulomb and Hoek–Brown\n",
           f"Triaxial runs at σ3 = {s3} MPa of the {' and '.join(tx.get('cards', []))} "
           "card(s) (rigid servo-controlled lateral wall; loading as the UCS test), fitted "
           "by Mohr–Coulomb (c, φ) and Hoek–Brown (σci and mi both fitted) through the runs "
           "that are ok. σc and σt are the card's: the closed loop's DEM values when it ran, "
           "else the regression's predictions; a card without a Brazilian value shows –.\n"]
    rows = []

    def src(v, s):
        return f"{num(v, '.2f')} ({s})" if isinstance(s, str) and s else num(v, ".2f")

    for r in env.itertuples():
        rows.append([r.specimen, r.card, src(r.sigma_c_MPa, getattr(r, "sigma_c_source", "")),
                     src(getattr(r, "sigma_t_MPa", math.nan),
                         getattr(r, "sigma_t_source", ""))
                     + (f"; lab {num(r.lab_sigma_t_MPa, '.2f')}"
                        if num(getattr(r, "lab_sigma_t_MPa", math.nan)) != "–" else ""),
                     num(getattr(r, "sigma_c_over_sigma_t", math.nan), ".1f"),
                     f"{num(r.c_MPa, '.2f')} ± {num(r.c_se_MPa, '.2f')}",
                     f"{num(r.phi_deg, '.1f')} ± {num(r.phi_se_deg, '.1f')}",
                     f"{num(r.mi, '.2f')} ± {num(r.mi_se, '.2f')}",
                     num(r.mc_rms_MPa, ".2f"), num(r.hb_rms_MPa, ".2f"),
                     f"{r.runs_ok}/{r.runs}"])
    out.append(markdown_table(rows, ["specimen", "card", "σc (MPa)", "σt (MPa)", "σc/σt",
                                     "c (MPa)", "φ (°)", "mi", "MC rms (MPa)",
                                     "HB rms (MPa)", "runs ok"]) + "\n")
    out.append("± is one standard error of the fit (– with two points: an exact fit). "
               "Parallel-bond models tend to give σc/σt well below the 10–20 of most rocks.\n")
    notes = [f"- **{r.specimen} ({r.card})**: {r.note}" for r in env.itertuples()
             if isinstance(r.note, str) and r.note]
    if notes:
        out.append("\n".join(notes) + "\n")
    lt = Path(lay.table(L.TRIAXIAL_LAB))
    if tx.get("lab_csv") and lt.exists():
        comp = pd.read_csv(lt, dtype={"specimen": str})
        rows = [[r.specimen, r.card, num(r.sigma3_MPa, "g"), num(r.lab_sigma1_MPa, ".1f"),
                 num(r.mc_sigma1_MPa, ".1f"), num(r.mc_err_pct, "+.1f"),
                 num(r.hb_sigma1_MPa, ".1f"), num(r.hb_err_pct, "+.1f")]
                for r in comp.itertuples()]
        out.append(f"### Lab triaxial points (`{tx['lab_csv']}`) against the cards' "
                   "envelopes\n\n" + markdown_table(rows, [
                       "specimen", "card", "σ3 (MPa)", "lab σ1 (MPa)", "MC σ1 (MPa)",
                       "MC error %", "HB σ1 (MPa)", "HB error %"]) + "\n")
        out.append("The lab triaxial points are compared with the cards, not calibrated "
                   "against: the inversion does not use them.\n")
    if ref:
        out.append("**What the paper does not publish:** Yu et al. (2026) give only uniaxial "
                   "data for the green sandstone (σc, E, ν and the pre-peak energy of B1–B3): "
                   "no Brazilian tensile strength and no triaxial tests. The σt, σc/σt, c, φ "
                   "and mi above are therefore the cards' predictions, compared with no "
                   "measurement.\n")
    return "\n".join(out)
