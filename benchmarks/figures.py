"""The one source of every measured figure the README and the docs quote:
``docs/measurements/figures.json``, generated from the benchmarks' JSON records
(``benchmarks/results/results_*.json``), never written by hand.

A page quotes a figure with an inline marker that renders on GitHub and in the docs site
as the bare value::

    the default study takes <!--fig:study.wall_min-->26.4<!--/fig--> min

A link to the record a figure comes from is marked the same way and refreshed with it
(the path relative to the page), so a newer record changes no page by hand::

    the <!--rec:study.wall_min-->[record](docs/measurements/DATE-default-study.md)<!--/rec-->

``tests/docs/test_figures.py`` checks that every marked value equals the generated one,
that ``figures.json`` is this script's output for the records in the repository, and that
the README and the docs (outside ``docs/measurements/``, but with its undated summary
pages) hold no unmarked measured figure.

    python benchmarks/figures.py            # write figures.json and refresh every marker
    python benchmarks/figures.py --check    # exit 1 if figures.json or a marker is stale

Each figure names the newest record of its kind (the file name's date decides), so a new
measurement written beside the old one (``results_default_study_<DATE>.json``) becomes
the quoted figure when this script is run again; the old record stays as it was. In a
default-study time record (``study_record.py``) the figure is the record's last run on 2
cores, the README's ``snakemake --cores 2`` (the newest code of a before/after pair).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: the benchmarks' JSON records (the scripts are in benchmarks/)
BENCH = REPO / "benchmarks" / "results"
OUT = REPO / "docs" / "measurements" / "figures.json"
#: a marked figure: <!--fig:KEY-->VALUE<!--/fig-->
MARK = re.compile(r"<!--fig:([a-z][a-z0-9_]*(?:\.[A-Za-z0-9_]+)+)-->(.*?)<!--/fig-->")
#: a link to the record a figure comes from: <!--rec:KEY-->[text](path)<!--/rec-->; the
#: path is refreshed like a figure (relative to the page), so a newer record needs no edit
REC = re.compile(r"<!--rec:([a-z][a-z0-9_]*(?:\.[A-Za-z0-9_]+)+)-->\[(.*?)\]\((.*?)\)<!--/rec-->",
                 re.S)

#: kind -> (file pattern of its JSON records, the Markdown record rendered from them)
SOURCES = {
    "default_study": ("results_default_study_*.json", "{tag}-default-study.md"),
    "study_outputs": ("results_study_outputs_*.json", "{tag}-default-study-results.md"),
    "bts_loadings": ("results_bts_loadings_*.json", "{tag}-tensile-strength.md"),
    # σt of a seed as the mean of k discs (bts_resolution.py cards --specimens)
    # (the newest dated one; its page pools the day's others, e.g. ..._a1-seeds31-90_DATE)
    "bts_specimens": ("results_bts_specimens_2*.json", "{tag}-tensile-strength.md"),
    "test_tiers": ("results_test_tiers_*.json", "{tag}-test-tiers.md"),
    # the Lac du Bonnet examples (example_record.py): parallel bond, flat joint, and the
    # flat joint's triaxial overlay
    "ldb_pb": ("results_example_lac_du_bonnet_pb_*.json", "{tag}-lac-du-bonnet-parallel-bond.md"),
    "ldb_fj": ("results_example_lac_du_bonnet_fj_2*.json", "{tag}-lac-du-bonnet-flatjoint.md"),
    "ldb_fj_tri": ("results_example_lac_du_bonnet_fj_tri_*.json",
                   "{tag}-lac-du-bonnet-flatjoint-triaxial.md"),
}

#: Table 3 columns: response -> (label, how many of the largest shares the pages quote)
TABLE3 = {"ucs_MPa": ("ucs", 4), "E_GPa": ("E", 3), "nu": ("nu", 1), "bts_MPa": ("bts", 5)}
SYMBOL = {"rmin_mm": "Rmin", "porosity": "n", "pb_emod_GPa": "Ecp", "pb_kratio": "kp*",
          "pb_ten_MPa": "σcp", "pb_coh_MPa": "τcp", "pb_fa_deg": "φp", "fric": "μ"}


def newest(kind: str) -> tuple[Path, dict]:
    pattern = SOURCES[kind][0]
    files = sorted(BENCH.glob(pattern))
    if not files:
        raise FileNotFoundError(f"no {BENCH.relative_to(REPO)}/{pattern}")
    return files[-1], json.loads(files[-1].read_text())


def _slash(values, fmt="{:.2f}") -> str:
    return " / ".join(fmt.format(v) for v in values)


def _default_study(rec: dict) -> dict:
    # the README's command is `snakemake --cores 2`: the last run on 2 cores (older
    # records did not record the cores; all of theirs were on 2)
    label, run = [(k, r) for k, r in rec["runs"].items() if r.get("cores", 2) == 2][-1]
    t = run["time"]
    # the record's first run is its baseline; the newest run on the same cores is the one
    # compared with it (side by side when the record says so)
    (_, base), *rest = rec["runs"].items()
    same = [r for _, r in rest if r.get("cores") == base.get("cores")]
    ratio = same[-1]["time"]["cpu_min"] / base["time"]["cpu_min"] if same else None
    return {
        **({"study.cpu_vs_baseline": (f"{ratio:.2f}", ratio, ""),
            "study.compared_commit": (same[-1]["commit"], same[-1]["commit"], "")}
           if ratio else {}),
        "study.baseline_commit": (base["commit"], base["commit"], ""),
        "study.wall_min": (f"{t['wall_s'] / 60:.1f}", t["wall_s"] / 60, "min"),
        "study.cpu_min": (f"{t['cpu_min']:.1f}", t["cpu_min"], "CPU-min"),
        "study.max_rss_mb": (f"{t['max_rss_mb']:.0f}", t["max_rss_mb"], "MB"),
        "study.commit": (run["commit"], run["commit"], ""),
        "study.date": (rec["date"], rec["date"], ""),
        "study.host": (f"{rec['cpu_model']}, {rec['cpus']} cores", rec["cpu_model"], ""),
    }


def _study_outputs(rec: dict) -> dict:
    o = rec["outputs"]
    spec = ("B1", "B2", "B3")
    f = {"results.commit": (rec["commit"], rec["commit"], ""),
         "results.date": (rec["date"], rec["date"], "")}
    for resp, (label, n) in TABLE3.items():
        shares = sorted(o["table3"][resp].items(), key=lambda kv: -kv[1])[:n]
        f[f"results.table3.{label}"] = (
            ", ".join(f"{SYMBOL[k]} {v:.1f} %" for k, v in shares), dict(shares), "%")
    for resp, label, stages in (("ucs_MPa", "ucs", ("main", "quadratic", "interaction")),
                                ("E_GPa", "E", ("main", "quadratic", "interaction")),
                                ("nu", "nu", ("main", "quadratic")),
                                ("bts_MPa", "bts", ("main", "quadratic", "interaction"))):
        v = [o["adj_r2"][f"{resp}/{s}"] for s in stages]
        f[f"results.adj_r2.{label}"] = (" → ".join(f"{x:.3f}" for x in v), v, "")
    for p, nd in (("pb_emod_GPa", 2), ("pb_kratio", 2), ("pb_ten_MPa", 1), ("pb_coh_MPa", 1)):
        v = [o["calibration"][s][p] for s in spec]
        f[f"results.card.{p}"] = (_slash(v, f"{{:.{nd}f}}"), v, p.rsplit("_", 1)[-1])
    f["results.card.status"] = (_slash([o["calibration"][s]["status"] for s in spec], "{}"),
                                [o["calibration"][s]["status"] for s in spec], "")
    f["results.table5.status"] = (_slash([o["table5"][s]["status"] for s in spec], "{}"),
                                  [o["table5"][s]["status"] for s in spec], "")
    notes = [f"{s}: {o['table5'][s]['note']}" for s in spec if o["table5"][s].get("note")]
    f["results.table5.notes"] = ("; ".join(notes) or "none", notes, "")
    r = o["ratio"]
    f["results.ratio"] = (f"{r['chosen']:g}", r["chosen"], "")
    f["results.ratio_tensile_share"] = (f"{100 * r['value']:.1f} %", 100 * r["value"], "%")
    for stage, nd in (("single_pass", 1), ("closed_loop", 2)):
        v = [o["table5"][s][stage]["largest_abs_err_pct"] for s in spec]
        f[f"results.table5.{stage}"] = (_slash(v, f"{{:.{nd}f}}") + " %", v, "%")
    v = [o["table6_up_err_pct"][s] for s in spec]
    f["results.table6.up_err"] = (_slash(v, "{:.1f}") + " %", v, "%")
    i = o["impact_6ms"]
    f["results.impact.w_in"] = (f"{i['W_in_full_size_J']:.1f} J", i["W_in_full_size_J"], "J")
    f["results.impact.eta_f"] = (f"{100 * i['eta_f']:.1f} %", 100 * i["eta_f"], "%")
    f["results.impact.closure"] = (f"{100 * i['closure_max_rel']:.2f} %",
                                   100 * i["closure_max_rel"], "%")
    sc = o["seed_scatter"]
    f["results.seed_scatter"] = (
        f"σc {sc['ucs_MPa']['cv_pct']:.1f} %, E {sc['E_GPa']['cv_pct']:.1f} %, "
        f"ν {sc['nu']['cv_pct']:.1f} %", {k: v["cv_pct"] for k, v in sc.items()}, "%")
    h = o["holdout"]
    f["results.holdout"] = (f"{h['within_2se']} of {h['targets']}", h["within_2se"], "")
    if "passed" in h:  # the check against the closed loop (records since 2026-11-28p)
        f["results.holdout_passed"] = (f"{h['passed']} of {h['judged']}", h["passed"], "")
    return f


def _bts_loadings(rec: dict) -> dict:
    a1 = rec["variants"]["flat, caps"]["a1"]
    return {"bts.cpu_s_per_test": (f"{a1['cpu_s_median']:.1f}", a1["cpu_s_median"], "CPU-s")}


def _bts_specimens(rec: dict) -> dict:
    """A1's seed CV of one disc and of a seed's σt at the default config's
    ``verification.tensile_specimens`` (k discs), and each card's at k."""
    import yaml
    from bts_resolution import disc_cv

    k = str(yaml.safe_load((REPO / "config" / "config.yaml").read_text())
            ["verification"]["tensile_specimens"])
    cards = rec["cards"]
    a1 = cards["A1"]["k"]
    others = {n.split(" ")[0]: c["k"][k]["seed_cv"] * 100 for n, c in cards.items() if n != "A1"}
    # one disc's CV from every disc of A1 in the day's specimens records (the page pools them)
    day = [json.loads(f.read_text())
           for f in sorted(BENCH.glob(f"results_bts_specimens_*{rec['date']}.json"))]
    one = 100 * disc_cv(day)["A1"][0]
    return {
        "bts.one_disc_cv": (f"{one:.1f} %", one, "%"),
        "bts.seeds": (str(cards["A1"]["n_seeds"]), cards["A1"]["n_seeds"], ""),
        "bts.specimens": (k, int(k), ""),
        "bts.seed_cv": (f"{100 * a1[k]['seed_cv']:.1f} %", 100 * a1[k]["seed_cv"], "%"),
        "bts.cards_seed_cv": (" / ".join(f"{v:.1f}" for v in others.values()) + " %",
                              others, "%"),
        "bts.cards": (" / ".join(others), list(others), ""),
    }


def _test_tiers(rec: dict) -> dict:
    f = {"tests.commit": (rec["commit"], rec["commit"], "")}
    for t in rec["tiers"]:
        f[f"tests.{t['tier']}_min"] = (f"{t['wall_s'] / 60:.1f}", t["wall_s"] / 60, "min")
        f[f"tests.{t['tier']}_passed"] = (str(t["counts"].get("passed", 0)),
                                          t["counts"].get("passed", 0), "")
    return f


def _example(prefix: str, spec: str = "LdB"):
    """The figures of an own-rock example record (``example_record.py``) under ``prefix``:
    the closed loop's status and rounds, the fresh seeds within 2 SE, the verified card's
    mi against the lab envelope's, and the study's time."""
    def extract(rec: dict) -> dict:
        s = rec["specimens"][spec]
        v, fresh = s["verified"], s.get("fresh_seeds") or []
        mi = {e["card"]: e["mi"] for e in s.get("envelopes") or []}
        n_ok = sum(bool(x["within_z_se"]) for x in fresh)
        passed = [bool(x["passed"]) for x in fresh if "passed" in x]  # since 2026-11-28p
        return {
            f"{prefix}.targets": (", ".join(v["targets"]), list(v["targets"]), ""),
            f"{prefix}.loop": (f"{v['status']} after {v['rounds']} rounds", v["status"], ""),
            f"{prefix}.fresh": (f"{n_ok} of {len(fresh)}", n_ok, ""),
            **({f"{prefix}.fresh_passed": (f"{sum(passed)} of {len(passed)}", sum(passed), "")}
               if passed else {}),
            f"{prefix}.mi": (f"{mi['verified']:.1f}", mi["verified"], ""),
            f"{prefix}.mi_lab": (f"{mi['lab']:.1f}", mi["lab"], ""),
            f"{prefix}.wall_min": (f"{rec['wall_s'] / 60:.1f}", rec["wall_s"] / 60, "min"),
            f"{prefix}.cpu_min": (f"{rec['cpu_min']:.1f}", rec["cpu_min"], "CPU-min"),
            **({f"{prefix}.sigma3": (f"{rec['design_sigma3_MPa']:g}", rec["design_sigma3_MPa"],
                                     "MPa")} if rec.get("design_sigma3_MPa") else {}),
        }
    return extract


EXTRACT = {"default_study": _default_study, "study_outputs": _study_outputs,
           "bts_loadings": _bts_loadings, "bts_specimens": _bts_specimens,
           "test_tiers": _test_tiers,
           "ldb_pb": _example("ldb_pb"), "ldb_fj": _example("ldb_fj"),
           "ldb_fj_tri": _example("ldb_fj_tri")}


def figures() -> dict:
    """Every figure: key -> {text, value, unit, source (the JSON), record (the page)}."""
    out = {}
    for kind, fn in EXTRACT.items():
        path, rec = newest(kind)
        # the file name's tag: the record's date, a letter for a second record that day
        page = SOURCES[kind][1].format(tag=path.stem.rsplit("_", 1)[-1])
        for key, (text, value, unit) in fn(rec).items():
            out[key] = {"text": text, "value": value, "unit": unit,
                        "source": str(path.relative_to(REPO)),
                        "record": f"docs/measurements/{page}"}
    return dict(sorted(out.items()))


def render() -> str:
    return json.dumps(figures(), indent=1, ensure_ascii=False) + "\n"


def pages() -> list[Path]:
    """The pages that quote figures: the README, every docs page outside the records, and
    the undated summaries among them (``docs/measurements/<name>.md`` not starting with a
    date, its two indexes, README and archive, aside), which quote several records side by
    side."""
    meas = REPO / "docs" / "measurements"
    docs = [p for p in sorted((REPO / "docs").rglob("*.md"))
            if "measurements" not in p.relative_to(REPO / "docs").parts]
    summaries = [p for p in sorted(meas.glob("*.md"))
                 if not p.name[:1].isdigit() and p.name not in ("README.md", "archive.md")]
    return [REPO / "README.md", REPO / "config" / "README.md", *docs, *summaries]


def record_link(key: str, figs: dict, page: Path) -> str:
    """The path of figure ``key``'s record, relative to ``page``'s folder."""
    if key not in figs:
        raise KeyError(f"unknown figure {key!r}")
    return os.path.relpath(REPO / figs[key]["record"], page.parent)


def refresh(text: str, figs: dict, page: Path = REPO / "README.md") -> str:
    def sub(m):
        key = m.group(1)
        if key not in figs:
            raise KeyError(f"unknown figure {key!r}")
        return f"<!--fig:{key}-->{figs[key]['text']}<!--/fig-->"

    def rec(m):
        key, label = m.group(1), m.group(2)
        return f"<!--rec:{key}-->[{label}]({record_link(key, figs, page)})<!--/rec-->"
    return REC.sub(rec, MARK.sub(sub, text))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help="write nothing; exit 1 if figures.json or a marked figure is stale")
    a = ap.parse_args(argv)
    text = render()
    figs = json.loads(text)
    stale = []
    if not OUT.is_file() or OUT.read_text() != text:
        stale.append(OUT)
        if not a.check:
            OUT.write_text(text)
    for page in pages():
        old = page.read_text()
        new = refresh(old, figs, page)
        if new != old:
            stale.append(page)
            if not a.check:
                page.write_text(new)
    for p in stale:
        print(f"{'stale' if a.check else 'updated'}: {p.relative_to(REPO)}")
    return 1 if a.check and stale else 0


if __name__ == "__main__":
    sys.exit(main())
