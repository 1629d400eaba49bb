"""The verify and transfer stages (stages/analysis.py) around a planted simulator: the DEM
run is replaced by a known function of the parameters, the packing seed and the specimen
scale, so the seed means, seed CVs, the kept run file and the full-size correction can be
checked against values computed by hand. (The stages with the real DEM run in the smoke
study, tests/workflow/test_smoke.py.)"""
import json
import math
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from support.planted_loop import (
    FULL,
    SMALL,
    TARGETS,
    PlantedDEM,
    run_verify,
    start_params,
)

import bpmcal.stages.measure as M
import bpmcal.stages.seed_scatter as S
import bpmcal.stages.transfer as TR
import bpmcal.stages.verification as V
import bpmcal.stages.verification_tables as VT
from bpmcal.analysis.calibration import LoopSettings
from bpmcal.io.card import card_parameters, read_card, write_card
from bpmcal.io.checks import BadInput
from bpmcal.lab.run_context import RunContext
from bpmcal.lab.runner import Geometry
from bpmcal.lab.ucs import UCSSettings


def test_verify_runs_k_seeds_per_round_and_records_mean_cv_and_n(study, monkeypatch):
    tmp_path, card, models = study
    dem = PlantedDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    v = run_verify(tmp_path, card, models, 3)["verification"]
    n_rounds = v["rounds"]
    assert len(dem.calls) == 3 * n_rounds == v["runs"]
    # every round runs seeds 1, 2, 3 with one parameter set
    for r in range(n_rounds):
        chunk = dem.calls[3 * r: 3 * r + 3]
        assert [c[1] for c in chunk] == [1, 2, 3]
        assert chunk[0][0] == chunk[1][0] == chunk[2][0]
    assert v["n_seeds"] == 3 and v["seeds"] == [1, 2, 3]
    best = v["best_round"] - 1
    truth = dem.truth(dem.calls[3 * best][0], 0.25)
    for r, t in truth.items():  # the seed mean is the planted truth (deviations cancel) ...
        assert v["closed_loop"][r] == pytest.approx(t, rel=1e-12)
        assert v["closed_loop"]["seed_cv"][r] == pytest.approx(0.02, rel=1e-9)  # ... CV planted
        assert v["closed_loop"]["seed_sd"][r] == pytest.approx(0.02 * t, rel=1e-9)
        assert v["closed_loop"]["errors_pct"][r] == pytest.approx(100 * (t / TARGETS[r] - 1))
    assert v["parameters"] == pytest.approx(dem.calls[3 * best][0])
    # single pass = round 1 at the regression's answer: 5 % bias removed by the loop
    assert v["single_pass"]["errors_pct"]["E_GPa"] != pytest.approx(0, abs=1.0)
    assert v["status"] == "converged"
    assert max(abs(e) for e in v["closed_loop"]["errors_pct"].values()) <= 100 * max(
        0.01, 2 * 0.02 / math.sqrt(3))
    # the kept run file is the best round's first seed
    kept = json.loads((tmp_path / "v" / "best.h5").read_text())
    assert kept == {"call": 3 * best + 1, "seed": 1}
    assert not list((tmp_path / "v").glob(".best.rounds*"))  # the loop's journal removed
    h = pd.read_csv(tmp_path / "v" / "rounds.csv")
    assert (h["n_seeds"] == 3).all() and h["cv_ucs_MPa"].to_numpy() == pytest.approx(0.02)
    assert read_card(tmp_path / "v" / "card.yaml")["calibrated_at_scale"] == 0.25


def test_one_seed_per_round_has_no_spread(study, monkeypatch):
    tmp_path, card, models = study
    dem = PlantedDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    v = run_verify(tmp_path, card, models, 1)["verification"]
    assert {c[1] for c in dem.calls} == {1} and v["n_seeds"] == 1
    assert math.isnan(v["closed_loop"]["seed_cv"]["ucs_MPa"])
    # seed 1 sits 2 % low: the one-seed loop fits that packing, not the planted truth
    truth = dem.truth(v["parameters"], 0.25)
    assert v["closed_loop"]["ucs_MPa"] == pytest.approx(0.98 * truth["ucs_MPa"])


def test_table5_carries_the_seed_spread(study, monkeypatch):
    tmp_path, card, models = study
    monkeypatch.setitem(M.RUNNERS, "ucs", PlantedDEM())
    run_verify(tmp_path, card, models, 3)
    monkeypatch.setattr(VT, "read_series", lambda run: pd.DataFrame(
        {"strain": [0.0, 0.01], "stress_MPa": [0.0, 60.0]}))
    monkeypatch.setattr(VT, "save_figure", lambda fig, path: None)
    lab = tmp_path / "lab.csv"
    lab.write_text("specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3\nB1,60.0,14.0,0.25,0.1\n")
    t5 = VT.verification_tables([tmp_path / "v" / "card.yaml"], [tmp_path / "v" / "best.h5"],
                               lab, table5=tmp_path / "t5.csv", table6=tmp_path / "t6.csv",
                               figure=tmp_path / "f6.png")["table5"]
    assert t5.loc["B1", "n_seeds"] == 3
    assert t5.loc["B1", "closed_loop_E_GPa_cv_pct"] == pytest.approx(2.0)
    assert t5.loc["B1", "closed_loop_E_GPa_sd"] == pytest.approx(
        0.02 * t5.loc["B1", "closed_loop_E_GPa"])


@pytest.mark.parametrize("e_full, rtol, corrected", [(1.0, 0.05, False), (1.10, 0.05, True),
                                                     (1.10, 0.001, True)])
def test_transfer_corrects_only_a_miss_beyond_the_seed_scatter(study, monkeypatch, e_full,
                                                               rtol, corrected):
    tmp_path, card, models = study
    dem = PlantedDEM(e_full=e_full)
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    run_verify(tmp_path, card, models, 3)
    verified = read_card(tmp_path / "v" / "card.yaml")
    n_verify = len(dem.calls)
    t = TR.transfer(tmp_path / "v" / "card.yaml", models, out_card=tmp_path / "t" / "card.yaml",
                   rounds=tmp_path / "t" / "rounds.csv", run=tmp_path / "t" / "best.h5",
                   tests=FULL, loop=LoopSettings(seed=4, rtol=rtol), max_rounds=2)
    full = dem.calls[n_verify:]
    assert all(c[1] == 4 and c[2] == 1.0 for c in full)  # one seed, full size
    assert full[0][0] == pytest.approx(card_parameters(verified))  # starts from the card
    tr = t["transfer"]
    # tolerance: max(rtol, 2 x the seed CV of one run measured by the verification, shrunk
    # to one full-size run: sqrt(0.25^3) for 64 x the balls)
    assert tr["scatter_factor"] == pytest.approx(0.125)
    assert tr["tolerance_pct"]["E_GPa"] == pytest.approx(100 * max(rtol, 2 * 0.02 * 0.125))
    e0 = tr["at_transfer"]["errors_pct"]["E_GPa"]
    card_out = read_card(tmp_path / "t" / "card.yaml")
    assert card_out["calibrated_at_scale"] == 1.0
    if not corrected:
        assert tr["status"] == "within-scatter" and len(full) == 1 and tr["corrections"] == 0
        assert tr["parameters"] == pytest.approx(card_parameters(verified))
    else:
        assert abs(e0) > 4.0  # the planted 10 % full-size offset in E is beyond the scatter
        assert 2 <= len(full) <= 3 and tr["rounds"] == len(full)
        assert abs(tr["final"]["errors_pct"]["E_GPa"]) < abs(e0)
        assert tr["status"] in ("corrected", "max_rounds")
        # readers of the card take the full-size parameters
        assert card_parameters(card_out) == pytest.approx(tr["parameters"])
        assert tr["parameters"]["pb_emod_GPa"] < verified["verification"]["parameters"][
            "pb_emod_GPa"]
    table = TR.transfer_table([tmp_path / "t" / "card.yaml"], table=tmp_path / "tt.csv")
    row = table[table["response"] == "E_GPa"].iloc[0]
    assert row["scale"] == 1.0 and row["verified_scale"] == 0.25
    assert row["at_transfer_err_pct"] == pytest.approx(e0)
    assert np.isfinite(row["final_err_pct"])


def test_scatter_factor_follows_the_ball_count():
    g = Geometry(scale=0.4).to_dict()
    assert TR.scatter_factor(g, Geometry(scale=1.0)) == pytest.approx(0.4 ** 1.5)
    assert TR.scatter_factor(g, Geometry(scale=0.4)) == pytest.approx(1.0)
    # a shorter specimen at the same scale holds half the balls: it scatters more
    assert TR.scatter_factor(g, Geometry(scale=0.4, height_mm=50.0)) == pytest.approx(2 ** 0.5)
    assert TR.scatter_factor(None, Geometry(scale=1.0)) == 1.0  # a card without its geometry
    assert TR.scatter_factor({"scale": 0.4, "diameter_mm": 20.0}, Geometry(scale=1.0)) == 1.0


def test_transfer_of_a_card_whose_loop_did_not_run(study, tmp_path):
    _, card, models = study
    c = read_card(card)
    c["verification"] = {"status": "not-run", "message": "unreachable", "closed_loop": None}
    write_card(tmp_path / "nr.yaml", c)
    t = TR.transfer(tmp_path / "nr.yaml", models, out_card=tmp_path / "o" / "card.yaml",
                   rounds=tmp_path / "o" / "r.csv", run=tmp_path / "o" / "b.h5", tests=FULL)
    assert t["transfer"]["status"] == "not-run" and "calibrated_at_scale" not in t
    assert (tmp_path / "o" / "b.h5").exists()


def test_verify_grows_the_seed_set_and_records_it(study, monkeypatch):
    """Seeds 1-3 sit 2 % high on average, seeds 1-6 average zero: the loop that may grow
    to 6 seeds ends on the planted truth, the card records the six seeds it was judged on
    and the Jacobian the loop learned."""
    tmp_path, card, models = study
    dev = {1: 0.0, 2: 0.04, 3: 0.02, 4: -0.03, 5: -0.02, 6: -0.01}
    dem = PlantedDEM(dev=dev)
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    v = run_verify(tmp_path, card, models, 3, max_seeds=6)["verification"]
    assert v["seeds_per_round"] == 3 and v["max_seeds"] == 6
    assert v["n_seeds"] == 6 and v["seeds"] == [1, 2, 3, 4, 5, 6]
    h = pd.read_csv(tmp_path / "v" / "rounds.csv")
    assert h["grown"].sum() == 3 and v["runs"] == len(dem.calls) == int(h["n_seeds"].sum())
    best = dem.calls[-1][0]  # converged: the last point is the card's
    assert v["parameters"] == pytest.approx(best)
    truth = dem.truth(best, 0.25)
    for r, t in truth.items():  # six seeds average to the truth
        assert v["closed_loop"][r] == pytest.approx(t, rel=1e-12)
    # the loop's Jacobian in the card: responses x free parameters, physical units
    jac = v["jacobian"]
    assert set(jac) == set(TARGETS) and set(jac["E_GPa"]) == {"pb_emod_GPa", "pb_kratio",
                                                               "pb_coh_MPa"}
    assert jac["E_GPa"]["pb_emod_GPa"] > 0


def test_transfer_starts_from_the_jacobian_the_verification_learned(study, monkeypatch):
    """A verified card whose recorded Jacobian says E falls with pb_emod_GPa (planted, the
    opposite of the models'): the transfer's first correction of a too-high E raises
    pb_emod_GPa, so it followed the card's Jacobian, not the regression's."""
    tmp_path, card, models = study
    dem = PlantedDEM(e_full=1.10)
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    run_verify(tmp_path, card, models, 3)
    c = read_card(tmp_path / "v" / "card.yaml")
    jac = {r: dict(row) for r, row in c["verification"]["jacobian"].items()}
    jac["E_GPa"]["pb_emod_GPa"] = -abs(jac["E_GPa"]["pb_emod_GPa"])
    c["verification"]["jacobian"] = jac
    write_card(tmp_path / "planted.yaml", c)
    n = len(dem.calls)
    TR.transfer(tmp_path / "planted.yaml", models, out_card=tmp_path / "t" / "card.yaml",
               rounds=tmp_path / "t" / "rounds.csv", run=tmp_path / "t" / "best.h5",
               tests=FULL, loop=LoopSettings(seed=4), max_rounds=1)
    full = [p for p, _, _ in dem.calls[n:]]
    assert len(full) == 2
    assert full[1]["pb_emod_GPa"] > full[0]["pb_emod_GPa"]


def test_scatter_of_a_verified_card_runs_its_verified_parameters(study, monkeypatch):
    """bpmcal scatter on a verified card scatters the closed loop's parameters (the ones
    the card stands for), not the regression's starting point it also records."""
    tmp_path, card, models = study
    dem = PlantedDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    v = run_verify(tmp_path, card, models, 3)["verification"]
    assert v["parameters"]["pb_emod_GPa"] != pytest.approx(start_params()["pb_emod_GPa"])
    n = len(dem.calls)
    monkeypatch.setitem(M.RUNNERS, "ucs", lambda out, params, seed, *a, **k: (
        dem(out, params, seed, Geometry(scale=0.25), None)))
    S.seed_scatter(tmp_path / "v" / "card.yaml", runs=[tmp_path / "s1.h5", tmp_path / "s2.h5"],
                   seeds=[1, 2], seed_runs=tmp_path / "sr.csv", table=tmp_path / "sc.csv",
                   geometry=Geometry(scale=0.25), settings=UCSSettings())
    ran = [p for p, _, _ in dem.calls[n:]]
    assert len(ran) == 2
    assert all(p == pytest.approx(v["parameters"]) for p in ran)


def test_transfer_of_a_card_whose_jacobian_does_not_fit_starts_from_the_models(study,
                                                                                monkeypatch):
    """A recorded Jacobian without a free parameter's column (learned for other free
    parameters) is not used: the transfer starts from the regression's, as for an older
    card without one."""
    tmp_path, card, models = study
    dem = PlantedDEM(e_full=1.10)
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    run_verify(tmp_path, card, models, 3)
    c = read_card(tmp_path / "v" / "card.yaml")
    jac = {r: {p: x for p, x in row.items() if p != "pb_coh_MPa"}
           for r, row in c["verification"]["jacobian"].items()}
    for name, v in (("partial", jac), ("none", None)):
        c["verification"]["jacobian"] = v
        write_card(tmp_path / f"{name}.yaml", c)
        n = len(dem.calls)
        TR.transfer(tmp_path / f"{name}.yaml", models, out_card=tmp_path / name / "card.yaml",
                   rounds=tmp_path / name / "rounds.csv", run=tmp_path / name / "best.h5",
                   tests=FULL, loop=LoopSettings(seed=4), max_rounds=1)
        if name == "partial":
            partial = [p for p, _, _ in dem.calls[n:]]
    full = [p for p, _, _ in dem.calls[n:]]
    assert len(partial) == len(full) == 2 and partial[1] == pytest.approx(full[1])


def test_verify_follows_a_target_past_a_design_range_and_says_so(study, monkeypatch):
    """ν = 0.336 needs pb_kratio = (0.336 / 1.05 - 0.1) / 0.04 = 5.5, past Table 2's 5:
    with the default margin (a quarter of the width, up to 6) the loop converges there and
    the card lists pb_kratio as outside the design space; with margin 0 it stays at 5 and
    misses ν. The transfer of the card starts outside the ranges, so it gets the margin too."""
    tmp_path, card, models = study
    c = read_card(card)
    c["targets"] = {**TARGETS, "nu": 0.336}
    write_card(tmp_path / "far.yaml", c)
    monkeypatch.setitem(M.RUNNERS, "ucs", PlantedDEM(dev={s: 0.0 for s in range(1, 12)}))
    kw = dict(rounds=tmp_path / "v" / "rounds.csv", run=tmp_path / "v" / "best.h5",
              tests=SMALL)
    loop = LoopSettings(seed=1, seeds_per_round=1, max_rounds=6, max_seeds=1)
    v = V.verify(tmp_path / "far.yaml", models, out_card=tmp_path / "v" / "card.yaml",
                 loop=loop, **kw)["verification"]
    assert v["status"] == "converged" and v["range_margin"] == 0.25
    assert v["parameters"]["pb_kratio"] == pytest.approx(5.5, rel=0.01)
    assert v["loop_bounds"]["pb_kratio"][1] == pytest.approx(6.0)
    assert v["outside_design"]["pb_kratio"]["range"] == [1.0, 5.0]
    assert "outside the design space" in v["message"] and "pb_kratio" in v["message"]
    inside = V.verify(tmp_path / "far.yaml", models, out_card=tmp_path / "v0" / "card.yaml",
                      loop=replace(loop, range_margin=0.0), **kw)["verification"]
    assert inside["status"] != "converged" and inside["outside_design"] == {}
    assert inside["parameters"]["pb_kratio"] == pytest.approx(5.0)
    assert [m["target"] for m in inside["missed"]] == ["nu"]
    t = dict(tests=FULL, max_rounds=1)
    out = TR.transfer(tmp_path / "v" / "card.yaml", models, out_card=tmp_path / "t" / "c.yaml",
                     rounds=tmp_path / "t" / "r.csv", run=tmp_path / "t" / "b.h5",
                     loop=LoopSettings(seed=4), **t)
    assert out["transfer"]["status"] == "within-scatter"
    assert set(out["transfer"]["outside_design"]) == {"pb_kratio"}
    with pytest.raises(ValueError, match=r"pb_kratio=5.4\d* outside \[1, 5\].*margin.*now 0\)"):
        TR.transfer(tmp_path / "v" / "card.yaml", models, out_card=tmp_path / "t0" / "c.yaml",
                   rounds=tmp_path / "t0" / "r.csv", run=tmp_path / "t0" / "b.h5",
                   loop=LoopSettings(seed=4, range_margin=0.0), **t)
    monkeypatch.setattr(VT, "read_series", lambda run: pd.DataFrame(
        {"strain": [0.0, 0.01], "stress_MPa": [0.0, 60.0]}))
    monkeypatch.setattr(VT, "save_figure", lambda fig, path: None)
    lab = tmp_path / "lab.csv"
    lab.write_text("specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3\nB1,60.0,14.0,0.336,0.1\n")
    from bpmcal.io import study_files as L
    from bpmcal.report.verification import section

    lay = L.StudyFiles(tmp_path / "study")
    t5 = VT.verification_tables([tmp_path / "v" / "card.yaml", tmp_path / "v0" / "card.yaml"],
                               [tmp_path / "v" / "best.h5"] * 2, lab,
                               table5=lay.table(L.TABLE5), table6=lay.table(L.TABLE6),
                               figure=tmp_path / "f6.png")["table5"]
    notes = list(t5["note"])
    assert "pb_kratio 5.4" in notes[0] and "outside its range 1-5" in notes[0]
    assert notes[1] == ""
    text = section(lay, [])  # the report says it under Table 5, once
    assert text.count("outside the design space") == 1 and "B1: outside the design space" in text
    with pytest.raises(BadInput, match=r"range_margin=1.5: expected a number in \[0, 1\]"):
        replace(loop, range_margin=1.5)  # refused where the settings are built


def test_verify_polishes_a_converged_card_and_records_it(study, monkeypatch):
    """Packings 0.1 % apart: the loop converges inside 1 % but more than one standard error
    off; the polishing round (one more, full Newton step) is the card's."""
    tmp_path, card, models = study
    dev = {1: -0.001, 2: 0.001, 3: 0.0}
    out = {}
    for polish in (False, True):
        dem = PlantedDEM(dev=dev)
        monkeypatch.setitem(M.RUNNERS, "ucs", dem)
        v = V.verify(card, models, out_card=tmp_path / f"p{polish}" / "card.yaml",
                     rounds=tmp_path / f"p{polish}" / "rounds.csv",
                     run=tmp_path / f"p{polish}" / "best.h5", tests=SMALL,
                     loop=LoopSettings(seed=1, seeds_per_round=3, max_rounds=6, max_seeds=3,
                                       polish=polish))["verification"]
        truth = dem.truth(v["parameters"], 0.25)
        out[polish] = (v, max(abs(truth[r] / t - 1) for r, t in TARGETS.items()))
    (plain, e0), (pol, e1) = out[False], out[True]
    assert plain["polish"] is False and pol["polish"] is True
    assert plain["status"] == pol["status"] == "converged"
    assert pol["rounds"] == plain["rounds"] + 1 and pol["best_round"] == pol["rounds"]
    assert e1 < 0.2 * e0 and e0 < 0.01
    h = pd.read_csv(tmp_path / "pTrue" / "rounds.csv")
    assert bool(h["polish"].iloc[-2]) and "polishing step" in pol["message"]


def test_verify_reports_every_round_and_records_its_update_rule(study, monkeypatch):
    """The history rule reaches the loop and the card; every judged round is a progress
    note (a loop of many rounds runs for an hour); a rule it does not know is refused."""
    tmp_path, card, models = study
    monkeypatch.setitem(M.RUNNERS, "ucs", PlantedDEM())
    seen = []
    v = V.verify(card, models, out_card=tmp_path / "h" / "card.yaml",
                 rounds=tmp_path / "h" / "rounds.csv", run=tmp_path / "h" / "best.h5",
                 tests=SMALL, loop=LoopSettings(seed=1, seeds_per_round=3, max_rounds=4,
                                                max_seeds=3, jacobian_update="history"),
                 ctx=RunContext(progress=seen.append))["verification"]
    assert v["jacobian_update"] == "history" and v["status"] == "converged"
    notes = [d["note"] for d in seen if "note" in d and d["note"].startswith("closed loop")]
    assert len(notes) == v["rounds"]
    assert notes[0].startswith("closed loop round 1 (3 seeds): ucs_MPa ")
    with pytest.raises(BadInput, match="jacobian_update='newton': expected one of broyden, "
                                         "history"):
        LoopSettings(jacobian_update="newton")  # refused where the settings are built


class StoppedDEM(PlantedDEM):
    """The planted DEM, stopped (as by a kill or a Slurm time limit) at its ``stop``-th run."""

    def __init__(self, stop):
        super().__init__()
        self.stop = stop

    def __call__(self, out, params, seed, geometry, settings, **kw):
        if len(self.calls) + 1 == self.stop:
            raise KeyboardInterrupt("planted stop")
        return super().__call__(out, params, seed, geometry, settings, **kw)


def _verify_into(d, card, models, **kw):
    return V.verify(card, models, out_card=d / "card.yaml", rounds=d / "rounds.csv",
                    run=d / "best.h5", tests=SMALL,
                    loop=LoopSettings(seed=1, seeds_per_round=3, max_seeds=3, max_rounds=4),
                    ctx=RunContext(**kw))


def test_a_loop_stopped_part_way_resumes_from_its_journal(study, monkeypatch):
    tmp_path, card, models = study
    whole = PlantedDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", whole)
    ref = _verify_into(tmp_path / "ref", card, models)["verification"]
    n = len(whole.calls)
    assert n >= 6  # at least two rounds of three seeds: the stop falls inside the loop
    d = tmp_path / "v"
    monkeypatch.setitem(M.RUNNERS, "ucs", StoppedDEM(stop=5))  # round 2, its second seed
    with pytest.raises(KeyboardInterrupt):
        _verify_into(d, card, models)
    journal = d / ".best.rounds" / "journal.jsonl"
    assert len(journal.read_text().splitlines()) == 4  # the four finished runs, on disk
    assert not (d / "card.yaml").exists() and not (d / "rounds.csv").exists()
    with open(journal, "a") as fh:
        fh.write('{"key": "cut short by the ki')  # a line a kill cut short is skipped
    again = PlantedDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", again)
    notes = []
    v = _verify_into(d, card, models, progress=lambda e: notes.append(e.get("note", "")))
    assert len(again.calls) == n - 4  # only the runs the stopped attempt had not finished
    assert again.calls == whole.calls[4:]
    assert any("4 finished run(s) of an earlier attempt" in x for x in notes)
    assert any("4 run(s) read from the journal" in x for x in notes)
    for k in ("parameters", "closed_loop", "single_pass", "status", "rounds", "best_round"):
        assert v["verification"][k] == ref[k], k
    pd.testing.assert_frame_equal(pd.read_csv(d / "rounds.csv"),
                                  pd.read_csv(tmp_path / "ref" / "rounds.csv"))
    assert not (d / ".best.rounds").exists()  # written: the journal is gone


def test_a_journal_of_other_inputs_is_not_read(study, monkeypatch):
    tmp_path, card, models = study
    d = tmp_path / "v"
    monkeypatch.setitem(M.RUNNERS, "ucs", StoppedDEM(stop=5))
    with pytest.raises(KeyboardInterrupt):
        _verify_into(d, card, models)
    again = PlantedDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", again)
    _verify_into(d, card, models, genesis_max_steps=40_000)  # another setting: every run anew
    whole = PlantedDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", whole)
    _verify_into(tmp_path / "ref", card, models, genesis_max_steps=40_000)
    assert len(again.calls) == len(whole.calls)  # nothing read from the other inputs' journal
