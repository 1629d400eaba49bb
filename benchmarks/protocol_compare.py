"""Two loading protocols paired on the same design samples: what one saves against the
other, and whether the answers move (``benchmarks/protocol_screen.py``'s rows).

    python benchmarks/protocol_compare.py ROWS.jsonl [ROWS.jsonl ...] --ref ref --new fast \
        [--json out.json]

Per test, on the samples both protocols ran:

- cost: the loading's steps and particle-steps (deterministic), the CPU seconds of the
  tests' loading (the ledger's test phases, retests' included: they depend on the load of
  the machine), the discs tested;
- UCS: σc, E, ν (and the strain at the peak), each sample's change new / ref - 1: median,
  median of its size, mean (the bias), standard deviation, 5th and 95th percentiles,
  largest size;
- Brazilian: σt's change on the samples valid under both with the same disc (a change of
  disc is another specimen, reported apart), the valid first discs and valid samples under
  each.

The acceptance rule of a protocol change (issue 53): every response's median change and
bias under 1 % and 0.5 % in size, and no fewer valid Brazilian samples (nor first discs).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

UCS_RESPONSES = ("ucs_MPa", "E_GPa", "nu")
#: acceptance limits [%]: the median change and the bias (mean change), in size
MEDIAN_LIMIT, BIAS_LIMIT = 1.0, 0.5


def load(paths) -> dict:
    rows = {}
    for p in paths:
        for line in Path(p).read_text().splitlines():
            r = json.loads(line)
            rows[(r["sample"], r["protocol"], r["test"])] = r
    return rows


def stats(d) -> dict | None:
    d = np.asarray([x for x in d if np.isfinite(x)], float)
    if d.size == 0:
        return None
    return {"n": int(d.size), "median": float(np.median(d)),
            "median_abs": float(np.median(np.abs(d))), "mean": float(d.mean()),
            "sd": float(d.std(ddof=1)) if d.size > 1 else 0.0,
            "p5": float(np.percentile(d, 5)), "p95": float(np.percentile(d, 95)),
            "max_abs": float(np.abs(d).max())}


def test_cpu(r: dict) -> float:
    ph = r.get("cpu_phases") or {}
    return float(ph.get("test", 0.0) + ph.get("retest_test", 0.0))


def cost(pairs) -> dict:
    out = {}
    for key, f in (("loading_steps", lambda r: r["loading_steps"]),
                   ("particle_steps", lambda r: r["particle_steps"]),
                   ("test_cpu_s", test_cpu)):
        a = sum(f(r) for r, _ in pairs)
        b = sum(f(n) for _, n in pairs)
        out[key] = {"ref": a, "new": b, "ratio": b / a if a else float("nan")}
    return out


def compare(rows: dict, ref: str, new: str) -> dict:
    out = {"ref": ref, "new": new}
    samples = sorted({s for s, p, t in rows})
    for test in ("ucs", "bts"):
        pairs = [(rows[(s, ref, test)], rows[(s, new, test)]) for s in samples
                 if (s, ref, test) in rows and (s, new, test) in rows]
        if not pairs:
            continue
        res = {"samples": len(pairs), "cost": cost(pairs)}
        if test == "ucs":
            for k in (*UCS_RESPONSES, "peak_strain", "u_pre_MJm3"):
                res[k] = stats([100 * (n[k] / r[k] - 1) for r, n in pairs])
            # the tensile share of the cracks at the end of the test (the posterior's
            # untargeted prediction), in points
            share = [100 * (n["cracks_tension"] / (n["cracks_tension"] + n["cracks_shear"])
                            - r["cracks_tension"] / (r["cracks_tension"] + r["cracks_shear"]))
                     for r, n in pairs]
            res["tensile_share_points"] = stats(share)
        else:
            same = [(r, n) for r, n in pairs if r["bts_valid"] and n["bts_valid"]
                    and r["disc_seed"] == n["disc_seed"]]
            res["bts_MPa"] = stats([100 * (n["bts_MPa"] / r["bts_MPa"] - 1) for r, n in same])
            other = [(r, n) for r, n in pairs if r["bts_valid"] and n["bts_valid"]
                     and r["disc_seed"] != n["disc_seed"]]
            res["bts_other_disc"] = [
                {"sample": r["sample"], "change_pct": 100 * (n["bts_MPa"] / r["bts_MPa"] - 1)}
                for r, n in other]
            res["bts_all_valid"] = stats([100 * (n["bts_MPa"] / r["bts_MPa"] - 1)
                                          for r, n in pairs if r["bts_valid"] and n["bts_valid"]])
            for side, i in (("ref", 0), ("new", 1)):
                res[f"invalid_reasons_{side}"] = reasons(pairs, i)
                res[f"valid_{side}"] = sum(p[i]["bts_valid"] for p in pairs)
                res[f"first_valid_{side}"] = sum(p[i]["disc_runs"][0]["valid"] for p in pairs)
                res[f"discs_{side}"] = sum(len(p[i]["disc_runs"]) for p in pairs)
        out[test] = res
    return out


def reasons(pairs, i: int) -> dict:
    """Why the Brazilian discs of one side of ``pairs`` were invalid: the first words of
    each reason (``lab.validity``), counted over every disc tested."""
    out = {}
    for p in pairs:
        for d in p[i]["disc_runs"]:
            if not d["valid"]:
                key = d["reason"].split(":")[0]
                key = key.replace("the bottom ", "a ").replace("the top ", "a ")
                out[key] = out.get(key, 0) + 1
    return out


def verdict(c: dict) -> list[str]:
    """The acceptance rule's failures (none: accepted)."""
    bad = []
    for test, keys in (("ucs", UCS_RESPONSES), ("bts", ("bts_MPa",))):
        if test not in c:
            continue
        for k in keys:
            s = c[test][k]
            if s is None:
                continue
            if abs(s["median"]) >= MEDIAN_LIMIT or s["median_abs"] >= MEDIAN_LIMIT:
                bad.append(f"{k}: median change {s['median']:+.2f} % (size {s['median_abs']:.2f} %)")
            if abs(s["mean"]) >= BIAS_LIMIT:
                bad.append(f"{k}: bias {s['mean']:+.2f} %")
    if "bts" in c and c["bts"]["valid_new"] < c["bts"]["valid_ref"]:
        bad.append(f"valid Brazilian samples {c['bts']['valid_ref']} -> {c['bts']['valid_new']}")
    return bad


def _row(name: str, s: dict | None, unit: str = "%") -> str:
    if not s:
        return f"| {name} | 0 | – | – | – | – | – | – |"
    return (f"| {name} | {s['n']} | {s['median']:+.2f} {unit} | {s['median_abs']:.2f} {unit} | "
            f"{s['mean']:+.2f} {unit} | {s['sd']:.2f} {unit} | {s['p5']:+.2f} … {s['p95']:+.2f} "
            f"{unit} | {s['max_abs']:.2f} {unit} |")


def markdown(c: dict) -> str:
    """The record's tables of one comparison (``compare``'s result)."""
    lines = []
    for test in ("ucs", "bts"):
        if test not in c:
            continue
        t, cs = c[test], c[test]["cost"]
        name = "UCS test" if test == "ucs" else "Brazilian test (every disc tested)"
        lines += [f"**{name}**, {t['samples']} samples:", "",
                  "| | " + c["ref"] + " | " + c["new"] + " | new / ref |", "|---|---|---|---|"]
        for key, label, f in (("loading_steps", "loading steps" + (
                " (seating included)" if test == "bts" else ""), "{:,.0f}"),
                ("particle_steps", "particle-steps", "{:,.0f}"),
                ("test_cpu_s", "CPU s of the loading (machine under load)", "{:.1f}")):
            lines.append(f"| {label} | {f.format(cs[key]['ref'])} | {f.format(cs[key]['new'])} "
                         f"| {cs[key]['ratio']:.3f} |")
            if key != "particle_steps":  # per test (a Brazilian test: every disc of a sample)
                n = t["samples"]
                lines.append(f"| {label}, per test | {cs[key]['ref'] / n:,.1f} | "
                             f"{cs[key]['new'] / n:,.1f} | – |")
        if test == "bts":
            for key, label in (("valid", "samples with a valid σt"),
                               ("first_valid", "first discs valid"), ("discs", "discs tested")):
                lines.append(f"| {label} | {t[key + '_ref']} | {t[key + '_new']} | – |")
            lines.append(f"| discs per sample | {t['discs_ref'] / t['samples']:.3f} | "
                         f"{t['discs_new'] / t['samples']:.3f} | – |")
        lines += ["", "| change new / ref − 1 | n | median | median size | mean (bias) | SD | "
                      "5th … 95th percentile | largest size |", "|---|---|---|---|---|---|---|---|"]
        if test == "ucs":
            for k, label in (("ucs_MPa", "σc"), ("E_GPa", "E"), ("nu", "ν"),
                             ("peak_strain", "strain at the peak"),
                             ("u_pre_MJm3", "pre-peak energy U_p")):
                lines.append(_row(label, t[k]))
            lines.append(_row("tensile share of the cracks at the end (points)",
                              t["tensile_share_points"], "pt"))
        else:
            lines.append(_row("σt, valid under both on the same disc", t["bts_MPa"]))
            lines.append(_row("σt, every sample valid under both", t["bts_all_valid"]))
            if t["bts_other_disc"]:
                lines += ["", "Samples whose valid disc changed (another specimen): " + ", ".join(
                    f"{o['sample']} {o['change_pct']:+.1f} %" for o in t["bts_other_disc"]) + "."]
            for side in ("ref", "new"):
                r = t[f"invalid_reasons_{side}"]
                lines += ["", f"Invalid discs under {c[side]}: " + (", ".join(
                    f"{v} × {k}" for k, v in sorted(r.items(), key=lambda kv: -kv[1]))
                    or "none") + "."]
        lines.append("")
    bad = verdict(c)
    lines.append("Acceptance (median change and bias of σc, E, ν and σt under 1 % and 0.5 % in "
                 "size, no fewer valid Brazilian samples): "
                 + ("**passed**." if not bad else "**failed**: " + "; ".join(bad) + "."))
    return "\n".join(lines) + "\n"


def show(c: dict) -> str:
    lines = [f"{c['new']} against {c['ref']}"]
    for test in ("ucs", "bts"):
        if test not in c:
            continue
        t = c[test]
        cs = t["cost"]
        lines.append(f"  {test}: {t['samples']} samples; steps x{cs['loading_steps']['ratio']:.3f}"
                     f", particle-steps x{cs['particle_steps']['ratio']:.3f}, test CPU "
                     f"x{cs['test_cpu_s']['ratio']:.3f}")
        keys = (*UCS_RESPONSES, "peak_strain") if test == "ucs" else ("bts_MPa", "bts_all_valid")
        for k in keys:
            s = t[k]
            if s:
                lines.append(f"    {k}: n {s['n']}, median {s['median']:+.2f} %, |median| "
                             f"{s['median_abs']:.2f} %, mean {s['mean']:+.2f} %, sd "
                             f"{s['sd']:.2f} %, p5..p95 {s['p5']:+.2f}..{s['p95']:+.2f} %, "
                             f"max {s['max_abs']:.2f} %")
        if test == "bts":
            lines.append(f"    valid samples {t['valid_ref']} -> {t['valid_new']}, first discs "
                         f"valid {t['first_valid_ref']} -> {t['first_valid_new']}, discs "
                         f"{t['discs_ref']} -> {t['discs_new']}; σt on another disc: "
                         + ", ".join(f"{o['change_pct']:+.1f} %" for o in t["bts_other_disc"]))
    bad = verdict(c)
    lines.append("  acceptance: " + ("passed" if not bad else "FAILED: " + "; ".join(bad)))
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", nargs="+")
    ap.add_argument("--ref", default="ref")
    ap.add_argument("--new", nargs="+", required=True)
    ap.add_argument("--json")
    ap.add_argument("--markdown", action="store_true", help="print the record's tables")
    a = ap.parse_args(argv)
    rows = load(a.rows)
    res = [compare(rows, a.ref, n) for n in a.new]
    for c in res:
        print(markdown(c) if a.markdown else show(c))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
