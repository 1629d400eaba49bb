"""Synthetic regression models with known answers for the tensile-strength calibration
tests (no DEM): the inversion is checked against a planted σt. Shared by
tests/unit/analysis/calibration/test_fit_tensile.py and the targets' integration tests
(tests/integration/test_*_targets.py)."""
import json

from bpmcal.analysis.stepwise import FORMAT, RegressionModel
from bpmcal.params import BTS

#: the design space of the synthetic datasets: Table 2
RANGES = {"rmin_mm": [0.6, 1.0], "porosity": [0.2, 0.36], "pb_emod_GPa": [10, 50],
          "pb_kratio": [1, 5], "pb_ten_MPa": [10, 50], "pb_coh_MPa": [10, 50],
          "pb_fa_deg": [15, 55], "fric": [0.15, 0.55]}
FIXED = {"porosity": 0.34, "rmin_mm": 0.8, "pb_fa_deg": 30.0, "fric": 0.4}
TRUTH = {"pb_emod_GPa": 20.0, "pb_kratio": 2.5, "pb_coh_MPa": 25.0}


def models():
    """σc depends on both strengths (with an interaction), σt mostly on pb_ten: the
    parallel-bond picture; σc/σt spans about 5-10 over the Table 2 ranges."""
    ucs = RegressionModel("ucs_MPa", [("pb_coh_MPa",), ("pb_ten_MPa",), ("porosity",), ("pb_kratio",),
                                      ("pb_coh_MPa", "pb_ten_MPa")],
                          [1.2, 0.8, -300.0, -6.0, 0.02], 120.0)
    E = RegressionModel("E_GPa", [("pb_emod_GPa",), ("pb_kratio",)], [1.29, -0.3], 0.2)
    nu = RegressionModel("nu", [("pb_kratio",)], [0.04], 0.1)
    bts = RegressionModel(BTS, [("pb_ten_MPa",), ("pb_coh_MPa",)], [0.3, 0.1], 0.0)
    return {"ucs_MPa": ucs, "E_GPa": E, "nu": nu, BTS: bts}


def predict(ms, params):
    """Every model's response at ``params``."""
    return {r: m.predict(params) for r, m in ms.items()}


def dem_response(y, offset=0.03):
    """A synthetic 'DEM' that differs from the regression's responses ``y``: σc and E off by
    ``offset``, σt by twice that, ν as predicted."""
    return {"ucs_MPa": y["ucs_MPa"] * (1 + offset), "E_GPa": y["E_GPa"] * (1 - offset),
            "nu": y["nu"], BTS: y[BTS] * (1 + 2 * offset)}


def write_models(path, ms):
    """``ms`` (response -> RegressionModel) as a models.json of ``bpmcal regress`` (the
    interaction stage) at ``path``; returns ``path``."""
    path.write_text(json.dumps({"format": FORMAT, "settings": {}, "rows": {}, "steps": [],
                                "candidates": {r: [] for r in ms},
                                "models": {r: {"interaction": m.to_dict()}
                                           for r, m in ms.items()}}))
    return path


def calibrate_b1(d, out, *, lab="lab.csv", models="models.json", fixed=None, options=()):
    """``bpmcal calibrate`` of the one-specimen lab table ``d/lab`` against ``d``'s
    dataset.csv and ``models`` over :data:`RANGES`, no bootstrap: the card ``out/B1.yaml``;
    returns the exit code. ``options``: more command options (``--ratio``, ``--free``)."""
    from bpmcal.cli import main

    return main(["calibrate", "--dataset", str(d / "dataset.csv"), "--models",
                 str(d / models), "--lab", str(d / lab), "--cards", str(out / "B1.yaml"),
                 "--ranges", json.dumps(RANGES), "--fixed", json.dumps(fixed or FIXED),
                 *options, "--n-boot", "0", "--seed", "0"])
