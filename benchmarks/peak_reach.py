"""Where a study's lab tests peak, relative to their card's failure-strain scale.

    python benchmarks/peak_reach.py RESULTS_DIR [RESULTS_DIR ...] [--json out.json]

Reads every ``ok`` run file of ``RESULTS_DIR/{ucs,bts,dtt}/*.h5`` (a study's sample jobs)
and prints, per results folder and test, the strain at the peak (the UCS and direct-tension
tests' axial strain, the Brazilian test's diametral strain: the platens' approach over D)
over the
card's failure-strain scale ``dem.material.expected_failure_strain`` (its bonds' larger
strength over their modulus; for the direct-tension test their tensile strength over it):
min, 5th percentile, median and max over the runs.

``lab.budget.REACH_FRACTION`` is chosen below the minimum: a loading cut off before that
fraction of the scale cannot give a peak, and is refused (``check_loading_steps``,
``screen_loading``).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bpmcal import params as P
from bpmcal.dem.material import expected_failure_strain
from bpmcal.io import h5
from bpmcal.lab.specimen import card_material

#: (strain series, stress or load series, tension) of each test's folder; a direct-tension
#: test is compared with the card's tensile scale (``Loading.tension``)
TESTS = {"ucs": ("axial_strain", "axial_stress", False),
         "bts": ("diametral_strain", "load", False),
         "dtt": ("axial_strain", "axial_stress", True)}


def reach(path: Path, strain: str, load: str, tension: bool) -> float | None:
    if h5.read_summary(path).get("status") != "ok":
        return None
    inp = h5.read_inputs(path)
    card = P.validate_params({k: v for k, v in inp.items()
                              if k in P.ALL_PARAMS or k == "contact_model"})
    scale = expected_failure_strain(card_material(card)[0], tension)
    s = h5.read_series(path)
    i = int(np.argmax(np.asarray(s[load])))
    return float(np.asarray(s[strain])[i]) / scale


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path, nargs="+")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    out = {}
    for results in a.results:
        out[str(results)] = res = {}
        for test, (strain, load, tension) in TESTS.items():
            vals = [r for f in sorted((results / test).glob("*.h5"))
                    if (r := reach(f, strain, load, tension)) is not None]
            if not vals:
                continue
            v = np.asarray(vals)
            res[test] = row = {"runs": int(v.size), "min": float(v.min()),
                               "p5": float(np.percentile(v, 5)),
                               "median": float(np.median(v)), "max": float(v.max())}
            print(f"{results} {test}: {row['runs']} runs; peak strain / failure-strain "
                  f"scale: min {row['min']:.3g}, 5th percentile {row['p5']:.3g}, median "
                  f"{row['median']:.3g}, max {row['max']:.3g}")
    if a.json:
        a.json.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
