"""The stages that run many seeds give the same outputs on two CPUs (their seeds side by
side in worker processes, bpmcal.stages.pool) as on one (one seed after the other in the
stage's own process): the real DEM, a small parallel-bond card."""
import json

import pandas as pd
import pytest

from bpmcal.analysis.calibration import LoopSettings
from bpmcal.analysis.stepwise import FORMAT, RegressionModel
from bpmcal.io.card import read_card, write_card
from bpmcal.lab.run_context import RunContext
from bpmcal.lab.runner import Geometry, bts_geometry
from bpmcal.lab.ucs import UCSSettings
from bpmcal.params import table2_ranges
from bpmcal.stages.fresh_seeds import fresh_seeds
from bpmcal.stages.measure import SeedTests
from bpmcal.stages.seed_scatter import seed_scatter
from bpmcal.stages.verification import verify

pytestmark = pytest.mark.slow

MODELS = {
    "ucs_MPa": RegressionModel("ucs_MPa", [("pb_coh_MPa",)], [1.2], 10.0),
    "E_GPa": RegressionModel("E_GPa", [("pb_emod_GPa",)], [1.0], 1.0),
    "nu": RegressionModel("nu", [("pb_kratio",)], [0.05], 0.1),
}
PARAMS = {"rmin_mm": 1.0, "porosity": 0.36, "pb_fa_deg": 35.0, "fric": 0.35,
          "pb_emod_GPa": 10.0, "pb_kratio": 2.0, "pb_coh_MPa": 20.0, "pb_ten_MPa": 28.0}
GEO = Geometry(scale=0.2)
DISC = bts_geometry(scale=0.5)  # 25 x 12.5 mm: the Brazilian test beside every fresh seed


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("pool_dem")
    models = d / "models.json"
    models.write_text(json.dumps({
        "format": FORMAT, "settings": {}, "rows": {}, "candidates": {},
        "models": {r: {"main": m.to_dict()} for r, m in MODELS.items()}, "steps": []}))
    roles = {k: "fixed" for k in PARAMS}
    roles.update(pb_emod_GPa="free", pb_kratio="free", pb_coh_MPa="free", pb_ten_MPa="derived")
    targets = {"ucs_MPa": 30.0, "E_GPa": 8.0, "nu": 0.2}
    card = d / "B1.yaml"
    write_card(card, {"specimen": "B1", "status": "ok", "message": "", "ratio_ten_coh": 1.4,
                      "parameters": PARAMS, "roles": roles,
                      "ranges": {k: list(v) for k, v in table2_ranges().items()},
                      "targets": targets, "lab": dict(targets)})
    return d, card, models


def _run_all(d, card, models, threads):
    out = d / f"t{threads}"
    ctx = RunContext(threads=threads)
    verify(card, models, out_card=out / "card.yaml", rounds=out / "rounds.csv",
           run=out / "best.h5", tests=SeedTests(GEO, UCSSettings()),
           loop=LoopSettings(seed=1, seeds_per_round=2, max_seeds=2, max_rounds=2), ctx=ctx)
    fresh_seeds(out / "card.yaml", seeds=[101, 102],
                runs=[out / f"fresh{s}.h5" for s in (101, 102)],
                bts_runs=[out / f"fresh{s}.bts.h5" for s in (101, 102)],
                seed_runs=out / "fresh.csv",
                tests=SeedTests(GEO, UCSSettings(), bts_geometry=DISC), ctx=ctx)
    seed_scatter(out / "card.yaml", runs=[out / f"sc{s}.h5" for s in (201, 202)],
                 seeds=[201, 202], seed_runs=out / "sc_runs.csv", table=out / "sc.csv",
                 geometry=GEO, settings=UCSSettings(), ctx=ctx)
    return out


def test_two_cpus_give_the_outputs_of_one(study):
    d, card, models = study
    one, two = (_run_all(d, card, models, t) for t in (1, 2))
    pd.testing.assert_frame_equal(pd.read_csv(two / "rounds.csv"), pd.read_csv(one / "rounds.csv"))
    v1, v2 = (read_card(o / "card.yaml")["verification"] for o in (one, two))
    assert v1["rounds"] >= 1 and v1["n_seeds"] == 2
    for k in ("parameters", "closed_loop", "single_pass", "status", "seeds"):
        assert v2[k] == v1[k], k
    for f in ("fresh.csv", "sc_runs.csv", "sc.csv"):
        pd.testing.assert_frame_equal(pd.read_csv(two / f), pd.read_csv(one / f))
    fresh = pd.read_csv(one / "fresh.csv")
    assert list(fresh["seed"]) == [101, 102] and (fresh["status"] == "ok").all()
    assert fresh["ucs_MPa"].nunique() == 2  # two packings, two answers: really run
    assert fresh["bts_MPa"].notna().any()  # the Brazilian tests ran in the workers too
