"""The fresh-seed check of the verified cards (stages/fresh_seeds.py): statistics against
values computed by hand, the verdicts, failed runs kept as rows, and the stage around a
planted simulator (the DEM replaced by a known function of the parameters and the seed,
as in test_verify_transfer_stages.py). The real DEM runs it in the smoke study."""
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from support.planted_loop import (
    PlantedDEM,
    run_verify,
    start_params,
)

import bpmcal.stages.fresh_seeds as H
import bpmcal.stages.measure as M
from bpmcal.io.card import read_card, write_card
from bpmcal.io.checks import BadInput
from bpmcal.lab.runner import Geometry
from bpmcal.lab.ucs import UCSSettings
from bpmcal.stages.runs import RunOutcome


def test_statistics_are_those_of_the_fresh_seeds():
    v = [1.0, 2.0, 3.0, 4.0, 5.0]
    sd, se = math.sqrt(2.5), math.sqrt(2.5) / math.sqrt(5)
    s = H.fresh_seed_stats(v, 3.0, rtol=0.01)
    assert (s["n"], s["mean"]) == (5, 3.0)
    assert s["sd"] == pytest.approx(sd) and s["se"] == pytest.approx(se)
    assert s["z_score"] == 0.0 and s["within_z_se"] and s["met"]
    # a lab value 1.5 away: z = -1.5 / 0.7071 = -2.12, outside 2 standard errors
    s = H.fresh_seed_stats(v, 4.5, rtol=0.01)
    assert s["z_score"] == pytest.approx(-1.5 / se)
    assert s["err_pct"] == pytest.approx(100 * (3.0 / 4.5 - 1))
    assert not s["within_z_se"] and not s["met"]
    # ... inside 3 standard errors; and "met" when the loop's rtol is wider than the miss
    assert H.fresh_seed_stats(v, 4.5, rtol=0.01, z=3.0)["within_z_se"]
    assert H.fresh_seed_stats(v, 4.5, rtol=0.5)["met"]
    assert not H.fresh_seed_stats(v, 4.5, rtol=0.5)["within_z_se"]


def test_a_lab_value_with_its_own_standard_error_is_a_difference_of_two_means():
    """lab_se: the z-score and both verdicts use sqrt(se^2 + lab_se^2)."""
    v = [1.0, 2.0, 3.0, 4.0, 5.0]
    se = math.sqrt(2.5) / math.sqrt(5)
    s = H.fresh_seed_stats(v, 4.5, rtol=0.01, lab_se=0.5)
    both = math.hypot(se, 0.5)
    assert s["z_score"] == pytest.approx(-1.5 / both) and s["within_z_se"]  # -1.73
    assert s["tol_pct"] == pytest.approx(200 * both / 4.5) and s["met"]
    assert s["se"] == pytest.approx(se)  # the fresh seeds' own standard error is unchanged
    assert H.fresh_seed_stats(v, 4.5, rtol=0.01, lab_se=0.0) == H.fresh_seed_stats(v, 4.5, rtol=0.01)


def test_failed_runs_do_not_count_and_one_seed_gives_no_verdict():
    s = H.fresh_seed_stats([10.0, math.nan, 12.0], 11.0, rtol=0.01)
    assert s["n"] == 2 and s["mean"] == 11.0 and s["sd"] == pytest.approx(math.sqrt(2))
    one = H.fresh_seed_stats([11.0, math.nan], 11.0, rtol=0.01)
    assert one["n"] == 1 and math.isnan(one["se"])
    assert not one["within_z_se"] and not one["met"]


def _card(path, spec, targets):
    write_card(path, {"specimen": spec, "status": "ok", "parameters": start_params(),
                      "targets": targets})
    return path


def test_table_per_card_and_target_keeps_failed_seeds(tmp_path):
    c1 = _card(tmp_path / "B1.yaml", "B1", {"ucs_MPa": 60.0, "E_GPa": 14.0, "nu": 0.25})
    c2 = _card(tmp_path / "B2.yaml", "B2", {"ucs_MPa": 70.0, "E_GPa": 15.0, "nu": 0.24,
                                            "bts_MPa": 8.0})
    s1 = tmp_path / "B1.csv"
    pd.DataFrame({"seed": [101, 102, 103], "status": ["ok", "ok", "failed"],
                  "ucs_MPa": [59.0, 61.0, np.nan], "E_GPa": [14.1, 13.9, np.nan],
                  "nu": [0.25, 0.25, np.nan]}).to_csv(s1, index=False)
    s2 = tmp_path / "B2.csv"  # sigma_c planted 10 % high on every seed: a clear miss
    pd.DataFrame({"seed": [101, 102, 103], "status": ["ok"] * 3,
                  "ucs_MPa": [76.0, 77.0, 78.0], "E_GPa": [15.0, 15.2, 14.8],
                  "nu": [0.24, 0.23, 0.25], "bts_MPa": [7.5, 8.5, 8.0]}).to_csv(s2, index=False)
    t = H.fresh_seeds_table([c1, c2], [s1, s2], table=tmp_path / "out" / "fresh_seeds.csv")
    assert len(t) == 3 + 4 and (tmp_path / "out" / "fresh_seeds.md").is_file()
    r = t[(t.specimen == "B1") & (t.response == "ucs_MPa")].iloc[0]
    assert (r["n"], r["n_failed"], r["seeds"]) == (2, 1, "101,102,103")
    assert r["mean"] == 60.0 and r["within_z_se"]
    r = t[(t.specimen == "B2") & (t.response == "ucs_MPa")].iloc[0]
    assert r["mean"] == 77.0 and r["se"] == pytest.approx(1 / math.sqrt(3))
    assert r["z_score"] == pytest.approx(7.0 * math.sqrt(3)) and not r["within_z_se"]
    assert not r["met"]
    assert t[(t.specimen == "B2") & (t.response == "bts_MPa")].iloc[0]["within_z_se"]


def test_sigma_t_without_a_target_is_the_cards_prediction_with_its_scatter(tmp_path):
    """A card without a σt target whose fresh seeds ran the Brazilian test: σt is a row of
    its own, role "prediction", with its mean, standard error and seed CV over the valid
    discs (an invalid disc, NaN, does not count) and no verdict."""
    c = _card(tmp_path / "B1.yaml", "B1", {"ucs_MPa": 60.0, "E_GPa": 14.0, "nu": 0.25})
    s = tmp_path / "B1.csv"
    pd.DataFrame({"seed": [101, 102, 103, 104], "status": ["ok"] * 4,
                  "ucs_MPa": [59.0, 61.0, 60.0, 60.0], "E_GPa": [14.0] * 4,
                  "nu": [0.25] * 4, "bts_MPa": [9.0, 10.0, np.nan, 11.0]}).to_csv(s, index=False)
    t = H.fresh_seeds_table([c], [s], table=tmp_path / "t.csv")
    assert list(t["role"]) == ["target"] * 3 + ["prediction"]
    r = t.iloc[-1]
    assert r["response"] == "bts_MPa" and math.isnan(r["lab"]) and r["n"] == 3
    assert r["mean"] == 10.0 and r["cv_pct"] == pytest.approx(10.0)
    assert not r["within_z_se"] and not r["met"]


def test_table_refuses_a_seed_table_without_a_target_column(tmp_path):
    c = _card(tmp_path / "B2.yaml", "B2", {"ucs_MPa": 70.0, "E_GPa": 15.0, "nu": 0.24,
                                           "bts_MPa": 8.0})
    s = tmp_path / "B2.csv"
    pd.DataFrame({"seed": [1, 2], "status": ["ok", "ok"], "ucs_MPa": [1, 2], "E_GPa": [1, 2],
                  "nu": [0.2, 0.2]}).to_csv(s, index=False)
    with pytest.raises(BadInput, match=r"missing column\(s\) \['bts_MPa'\]"):
        H.fresh_seeds_table([c], [s], table=tmp_path / "t.csv")
    assert not (tmp_path / "t.csv").exists()


@pytest.fixture
def verified(study, monkeypatch):  # noqa: F811
    tmp_path, card, models = study
    dem = PlantedDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    run_verify(tmp_path, card, models, 3)  # seeds 1, 2, 3
    return tmp_path, tmp_path / "v" / "card.yaml", dem


class FreshDEM(PlantedDEM):
    """The planted truth on fresh seeds: seed s deviates by DEV[s]; seed 9 fails."""

    DEV = {101: -0.01, 102: 0.01, 103: 0.0, 104: 0.03}

    def __call__(self, out, params, seed, geometry, settings, **kw):
        self.calls.append((dict(params), seed, geometry.scale))
        if seed == 9:
            out.write_text("failed")
            return RunOutcome("failed", {}, error="NumericalInstability: planted", path=out)
        y = {r: v * (1 + self.DEV[seed]) for r, v in self.truth(params, geometry.scale).items()}
        out.write_text(json.dumps({"seed": seed}))
        return RunOutcome("ok", {**y, "u_pre_MJm3": 0.1, "peak_strain": 0.005}, path=out)


def run_fresh_seeds(tmp_path, card, seeds, **kw):
    d = tmp_path / "h"
    return H.fresh_seeds(card, seeds=seeds, runs=[d / f"seed{s}.h5" for s in seeds],
                         seed_runs=d / "seeds.csv",
                         tests=M.SeedTests(Geometry(scale=0.25), UCSSettings()), **kw)


def test_the_stage_runs_the_verified_parameters_on_every_fresh_seed(verified, monkeypatch):
    tmp_path, card, _ = verified
    dem = FreshDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    df = run_fresh_seeds(tmp_path, card, [101, 102, 103, 9])
    params = read_card(card)["verification"]["parameters"]
    assert [c[1] for c in dem.calls] == [101, 102, 103, 9]
    assert all(c[0] == pytest.approx(params) for c in dem.calls)
    assert list(df["status"]) == ["ok", "ok", "ok", "failed"]
    assert "planted" in df["error"].iloc[3]  # the failed seed is a row with its reason
    t = H.fresh_seeds_table([card], [tmp_path / "h" / "seeds.csv"], table=tmp_path / "t.csv")
    truth = dem.truth(params, 0.25)
    for _, r in t.iterrows():  # deviations of 101-103 cancel: the mean is the truth
        assert r["mean"] == pytest.approx(truth[r["response"]], rel=1e-12)
        assert r["n"] == 3 and r["n_failed"] == 1
        assert r["sd"] == pytest.approx(0.01 * truth[r["response"]], rel=1e-9)


def test_seeds_of_the_closed_loop_are_refused(verified, monkeypatch):
    tmp_path, card, _ = verified
    monkeypatch.setitem(M.RUNNERS, "ucs", FreshDEM())
    with pytest.raises(BadInput, match=r"--seeds: 2, 3 already used"):
        run_fresh_seeds(tmp_path, card, [2, 3, 101])
    assert not (tmp_path / "h").exists()


def test_a_card_whose_loop_did_not_run_leaves_records_not_gaps(study, tmp_path,  # noqa: F811
                                                               monkeypatch):
    from bpmcal.io.h5 import check_run_file

    _, card, _ = study
    dem = FreshDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    c = read_card(card)
    c["verification"] = {"status": "not-run", "message": "unreachable: widen E",
                         "parameters": None, "seeds": [1, 2, 3]}
    write_card(tmp_path / "nr.yaml", c)
    df = run_fresh_seeds(tmp_path, tmp_path / "nr.yaml", [101, 102])
    assert not dem.calls and list(df["status"]) == ["not-run"] * 2
    for s in (101, 102):
        rec = check_run_file(tmp_path / "h" / f"seed{s}.h5")
        assert rec["status"] == "failed" and "widen E" in rec["error"]
    t = H.fresh_seeds_table([tmp_path / "nr.yaml"], [tmp_path / "h" / "seeds.csv"],
                            table=tmp_path / "t.csv")
    assert (t["n"] == 0).all() and (t["n_failed"] == 2).all()
    assert not t["within_z_se"].any() and t["note"].str.contains("widen E").all()


def test_a_sigma_t_target_needs_brazilian_run_files(verified):
    tmp_path, card, _ = verified
    c = read_card(card)
    c["targets"] = dict(c["targets"], bts_MPa=8.0)
    write_card(tmp_path / "bts.yaml", c)
    with pytest.raises(BadInput, match="give --bts-runs"):
        run_fresh_seeds(tmp_path, tmp_path / "bts.yaml", [101, 102])


def test_config_refuses_fresh_seeds_of_the_loop_or_the_transfer():
    from bpmcal.study.config import _fresh_seed_checks

    cfg = {"verification": {"seed": 1, "seeds_per_round": 3, "fresh_seeds": [3, 9]},
           "transfer": {"enabled": False}}
    assert "[3]" in _fresh_seed_checks(cfg)[0]
    cfg["verification"]["fresh_seeds"] = [4, 9]
    assert _fresh_seed_checks(cfg) == []
    cfg["transfer"]["enabled"] = True  # the transfer runs seed 1 + 3
    assert "[4]" in _fresh_seed_checks(cfg)[0]
    # a seed set that may grow to 8 seeds uses 1-8, the transfer then 9
    cfg["verification"].update(max_seeds=8, fresh_seeds=[8, 20])
    assert "[8]" in _fresh_seed_checks(cfg)[0]
    cfg["verification"]["fresh_seeds"] = [9, 20]
    assert "[9]" in _fresh_seed_checks(cfg)[0]
    cfg["transfer"]["enabled"] = False
    assert _fresh_seed_checks(cfg) == []
    cfg["verification"]["fresh_seeds"] = [9]
    assert "at least 2" in _fresh_seed_checks(cfg)[0]
    cfg["verification"]["fresh_seeds"] = []
    assert _fresh_seed_checks(cfg) == []


def test_false_alarm_rate_of_a_card_exactly_on_target():
    """Fresh seeds drawn around the lab value itself: the share of checks that fail is the
    Student-t tail false_alarm(n) (4000 draws; binomial standard error ~0.5 %), well above
    the normal tail of 4.6 %, and it shrinks towards that with more seeds."""
    from bpmcal.stages.fresh_seeds import false_alarm, fresh_seed_stats

    rng = np.random.default_rng(7)
    for n in (3, 5, 12):
        fails = [not fresh_seed_stats(60.0 * (1 + 0.02 * rng.standard_normal(n)), 60.0,
                                      rtol=1e-9)["within_z_se"] for _ in range(4000)]
        p = false_alarm(n)
        assert abs(np.mean(fails) - p) < 4 * np.sqrt(p * (1 - p) / 4000)
    assert false_alarm(5) == pytest.approx(0.1161, abs=1e-4)
    assert false_alarm(3) > false_alarm(5) > false_alarm(12) > 0.0455
    assert false_alarm(5, targets=9) == pytest.approx(1 - (1 - false_alarm(5)) ** 9)
    assert np.isnan(false_alarm(1))


def test_false_alarm_of_a_card_fitted_to_its_loop_seeds():
    """A card exactly on its targets over its closed loop's k packings (the lab value is
    the mean of k seeds, the rock's mean another): the fresh check fails more often than
    Student's t alone says, as false_alarm(n, loop_seeds=k) computes (4000 draws)."""
    from bpmcal.stages.fresh_seeds import false_alarm, fresh_seed_stats

    rng = np.random.default_rng(11)
    for n, k in ((5, 10), (5, 3), (10, 10)):
        fails = []
        for _ in range(4000):
            lab = float((60.0 * (1 + 0.02 * rng.standard_normal(k))).mean())  # the loop's fit
            fresh = 60.0 * (1 + 0.02 * rng.standard_normal(n))
            fails.append(not fresh_seed_stats(fresh, lab, rtol=1e-9)["within_z_se"])
        p = false_alarm(n, loop_seeds=k)
        assert abs(np.mean(fails) - p) < 4 * np.sqrt(p * (1 - p) / 4000), (n, k, np.mean(fails), p)
    assert false_alarm(5, loop_seeds=10) == pytest.approx(0.1778, abs=1e-4)
    assert false_alarm(5, loop_seeds=3) > false_alarm(5, loop_seeds=10) > false_alarm(5)
    assert false_alarm(5, loop_seeds=10 ** 9) == pytest.approx(false_alarm(5), abs=1e-9)


def test_the_report_counts_the_triaxial_targets_own_loop_seeds(tmp_path):
    """A loop of 20 seeds whose triaxial test ran on its first 10 (the card's
    verification.triaxial_seeds): the report's false-alarm odds take k = 10 for σ1 and
    k = 20 for the other targets; without the cap every target takes k = 20."""
    from pathlib import Path

    import yaml
    from support.synthetic import FIXED, TRUTH

    from bpmcal.io import study_files as L
    from bpmcal.io.card import CARD_FORMAT
    from bpmcal.report.verification import fresh_seeds_section
    from bpmcal.stages.fresh_seeds import false_alarm

    lay = L.StudyFiles(tmp_path)
    targets = ["ucs_MPa", "E_GPa", "nu", "dtt_MPa", "tri_MPa"]
    Path(lay.table(L.FRESH_SEEDS)).parent.mkdir(parents=True)
    pd.DataFrame([{"specimen": "LdB", "response": r, "role": "target", "lab": 1.0, "n": 5,
                   "mean": 1.0, "sd": 0.01, "se": 0.005, "err_pct": 0.0, "se_pct": 0.5,
                   "z_score": 0.0, "z": 2.0, "within_z_se": True, "tol_pct": 1.0,
                   "met": True, "cv_pct": 1.0, "n_failed": 0, "seeds": "101,102,103,104,105",
                   "note": ""} for r in targets]).to_csv(lay.table(L.FRESH_SEEDS), index=False)
    pd.DataFrame([{"specimen": "LdB", "n_seeds": 20}]).to_csv(lay.table(L.TABLE5), index=False)
    card = Path(lay.verified_card("LdB"))
    card.parent.mkdir(parents=True)

    def text(verification):
        card.write_text(yaml.safe_dump({"card_format": CARD_FORMAT, "specimen": "LdB",
                                        "parameters": {**FIXED, **TRUTH,
                                                       "pb_ten_MPa": 1.4 * TRUTH["pb_coh_MPa"]},
                                        "verification": verification}))
        return fresh_seeds_section(lay)

    p20, p10 = false_alarm(5, loop_seeds=20), false_alarm(5, loop_seeds=10)
    capped = text({"n_seeds": 20, "triaxial_seeds": 10})
    assert f"on the first 10 of them: {100 * p10:.1f} %" in capped
    both = 1 - (1 - p20) ** 4 * (1 - p10)
    assert f"{100 * p20:.1f} % per target (" in capped and f"{100 * both:.0f} % for one" in capped
    plain = text({"n_seeds": 20})
    assert "first 10" not in plain
    assert f"{100 * false_alarm(5, targets=5, loop_seeds=20):.0f} % for one" in plain
    assert not math.isclose(both, false_alarm(5, targets=5, loop_seeds=20))


def test_loop_reference_is_students_two_sample_t_of_the_fresh_and_the_loop_means():
    """t_loop and its degrees of freedom are the pooled two-sample t-test's (scipy's on
    the same numbers, from the loop's mean, SD and n alone); t_crit is the Student-t
    quantile of the two-sided level of z = 2 normal standard errors (4.55 %), shared among
    the targets by Šidák."""
    from scipy import stats

    fresh = np.array([10.3, 9.7, 11.0, 10.2, 9.5])
    loop = np.array([10.8, 11.1, 10.2, 10.9, 11.4, 10.6, 10.3, 11.0, 10.7, 11.2])
    r = H.loop_reference_stats(fresh, loop_mean=loop.mean(), loop_sd=loop.std(ddof=1),
                               loop_n=len(loop), lab=10.5, z=2.0, targets=1)
    w = stats.ttest_ind(fresh, loop, equal_var=True)
    assert r["t_loop"] == pytest.approx(w.statistic, rel=1e-12)
    assert r["dof"] == pytest.approx(w.df, rel=1e-12)
    assert r["loop_se"] == pytest.approx(loop.std(ddof=1) / math.sqrt(10))
    assert r["diff_pct"] == pytest.approx(100 * (fresh.mean() - loop.mean()) / 10.5)
    alpha = 2 * stats.norm.sf(2.0)
    assert r["t_crit"] == pytest.approx(stats.t.isf(alpha / 2, w.df))
    assert r["reproduces_loop"] == (abs(w.statistic) <= r["t_crit"])
    four = H.loop_reference_stats(fresh, loop_mean=loop.mean(), loop_sd=loop.std(ddof=1),
                                  loop_n=10, lab=10.5, targets=4)
    each = 1 - (1 - alpha) ** 0.25
    assert four["t_crit"] == pytest.approx(stats.t.isf(each / 2, w.df))
    assert four["t_crit"] > r["t_crit"]
    # these numbers: t = -2.73, outside t_crit 2.21 of one target, inside 2.94 of four
    assert not r["reproduces_loop"] and four["reproduces_loop"]
    # failed runs do not count; one fresh or one loop seed: no verdict
    assert H.loop_reference_stats([*fresh, math.nan], loop_mean=loop.mean(),
                                  loop_sd=loop.std(ddof=1), loop_n=10, lab=10.5)["t_loop"] == \
        pytest.approx(w.statistic)
    for kw in (dict(values=[10.0]), dict(values=fresh, loop_n=1)):
        x = H.loop_reference_stats(**{"values": fresh, "loop_mean": 10.5, "loop_sd": 0.4,
                                      "loop_n": 10, "lab": 10.5, **kw})
        assert math.isnan(x["t_loop"]) and not x["reproduces_loop"]


def _loop_and_fresh(rng, k, n, m, cv, accepted):
    """One simulated calibration with m independent targets, each with seed CV ``cv``: the
    loop's card reads the lab value on its own k seeds up to a residual uniform in
    +-``accepted`` of the lab (what its tolerance let through); its rock mean is then off
    by the loop seeds' sampling error; n fresh seeds are drawn around that rock mean."""
    lab = 100.0
    out = []
    for _ in range(m):
        loop_mean = lab * (1 + accepted * rng.uniform(-1, 1))
        e_loop = cv * lab * rng.standard_normal(k)
        mu = loop_mean - e_loop.mean()  # the card's mean over every packing
        loop_sd = float((mu + e_loop).std(ddof=1))
        out.append((lab, loop_mean, loop_sd, mu + cv * lab * rng.standard_normal(n)))
    return out


def test_a_card_that_generalises_fails_the_check_at_the_stated_rate():
    """A card whose fresh seeds are another draw of the packings its loop saw fails the
    check with probability alpha (4.55 % for z = 2) on one or more of its 4 targets,
    whatever residual the loop accepted (here up to 4 %, more than the 2 % seed CV); the
    lab-referenced verdict within_z_se fails the same cards far more often (3000 cards;
    binomial standard error ~0.4 %)."""
    from scipy import stats

    rng = np.random.default_rng(5)
    alpha = 2 * stats.norm.sf(2.0)
    for k, n in ((10, 5), (20, 5), (3, 3)):
        fails, lab_fails = [], []
        for _ in range(3000):
            rows = _loop_and_fresh(rng, k, n, 4, 0.02, 0.04)
            fails.append(not all(H.loop_reference_stats(
                f, loop_mean=lm, loop_sd=sd, loop_n=k, lab=lab, targets=4)["reproduces_loop"]
                for lab, lm, sd, f in rows))
            lab_fails.append(not all(H.fresh_seed_stats(f, lab, rtol=1e-9)["within_z_se"]
                                     for lab, lm, sd, f in rows))
        p = float(np.mean(fails))
        assert abs(p - alpha) < 4 * math.sqrt(alpha * (1 - alpha) / 3000), (k, n, p)
        assert np.mean(lab_fails) > 0.4, (k, n, np.mean(lab_fails))


def test_the_check_finds_a_card_that_does_not_generalise():
    """Fresh seeds whose mean lies mdd_pct off the loop's (a card whose loop seeds read
    differently from the rock) fail about half the time, and twice that offset nearly
    always: the check has the power it reports (2000 draws)."""
    rng = np.random.default_rng(9)
    k, n, cv, lab = 10, 5, 0.03, 100.0
    base = H.loop_reference_stats(lab * (1 + cv * rng.standard_normal(n)), loop_mean=lab,
                                  loop_sd=cv * lab, loop_n=k, lab=lab, targets=4)
    mdd = base["mdd_pct"]
    assert 4.0 < mdd < 6.0  # t_crit 2.94 x 3 % x sqrt(1/5 + 1/10) = 4.8 %, the SD as drawn
    for shift, lo, hi in ((mdd, 0.35, 0.65), (2 * mdd, 0.95, 1.0)):
        found = []
        for _ in range(2000):
            e = cv * lab * rng.standard_normal(k)
            loop = lab + e - e.mean()  # the loop's seeds read exactly the lab's mean
            fresh = lab * (1 + shift / 100) + cv * lab * rng.standard_normal(n)
            found.append(not H.loop_reference_stats(
                fresh, loop_mean=float(loop.mean()), loop_sd=float(loop.std(ddof=1)),
                loop_n=k, lab=lab, targets=4)["reproduces_loop"])
        assert lo <= np.mean(found) <= hi, (shift, np.mean(found))


def test_the_table_judges_against_the_closed_loop_only_when_the_runs_repeat_it(
        verified, monkeypatch):
    """Fresh seeds on the loop's cylinder: every target is judged against the card's
    closed-loop mean (judged_by "closed loop", the loop's seeds and SD from the card); on
    another cylinder the loop's mean is no reference and the lab-referenced verdict
    decides."""
    tmp_path, card, _ = verified
    monkeypatch.setitem(M.RUNNERS, "ucs", FreshDEM())
    run_fresh_seeds(tmp_path, card, [101, 102, 103])
    seeds = pd.read_csv(tmp_path / "h" / "seeds.csv")
    assert seeds["loop_reference"].all()
    t = H.fresh_seeds_table([card], [tmp_path / "h" / "seeds.csv"], table=tmp_path / "t.csv")
    loop = read_card(card)["verification"]["closed_loop"]
    for _, r in t.iterrows():
        assert r["judged_by"] == "closed loop" and r["loop_n"] == 3
        assert r["loop_mean"] == pytest.approx(loop[r["response"]])
        assert r["loop_se"] == pytest.approx(loop["seed_sd"][r["response"]] / math.sqrt(3))
        assert r["passed"] == r["reproduces_loop"]
    d = tmp_path / "h2"
    H.fresh_seeds(card, seeds=[101, 102, 103], runs=[d / f"s{s}.h5" for s in (101, 102, 103)],
                  seed_runs=d / "seeds.csv", tests=M.SeedTests(Geometry(scale=0.3), UCSSettings()))
    other = pd.read_csv(d / "seeds.csv")
    assert not other["loop_reference"].any()
    assert (other["loop_reference_note"] == "the fresh seeds run another UCS specimen than "
            "the loop's").all()
    t = H.fresh_seeds_table([card], [d / "seeds.csv"], table=tmp_path / "t2.csv")
    assert (t["judged_by"] == "lab").all() and (t["passed"] == t["within_z_se"]).all()
    assert t["t_loop"].isna().all()
    assert (t["lab_because"] == other["loop_reference_note"].iloc[0]).all()
    assert (H.fresh_seeds_table([card], [tmp_path / "h" / "seeds.csv"],
                                table=tmp_path / "t3.csv")["lab_because"] == "").all()
    # a seed table of an older bpmcal (no loop_reference column): the lab, saying why
    old = seeds.drop(columns=["loop_reference", "loop_reference_note"])
    old.to_csv(tmp_path / "old.csv", index=False)
    t = H.fresh_seeds_table([card], [tmp_path / "old.csv"], table=tmp_path / "t4.csv")
    assert (t["judged_by"] == "lab").all() and (t["lab_because"] == H.OLD_SEED_TABLE).all()


def test_why_fresh_seeds_do_not_repeat_the_loop(verified):
    """The loop's mean is a reference only for the loop's own parameters on its own
    specimens: a transferred card, a card without a closed-loop mean, another cylinder or
    another disc each say so."""
    _, card, _ = verified
    c = read_card(card)
    g = Geometry(scale=0.25)  # the loop's cylinder (run_verify)
    assert H._loop_reference(c, g) == ""
    assert "full-size transfer" in H._loop_reference({**c, "transfer": {"parameters": {"x": 1}}}, g)
    assert "no closed-loop mean" in H._loop_reference(
        {**c, "verification": {**c["verification"], "closed_loop": {}}}, g)
    assert "another UCS specimen" in H._loop_reference(c, Geometry(scale=0.3))
    assert "another Brazilian disc" in H._loop_reference(c, g, disc=Geometry(scale=0.3))


def test_the_report_judges_the_cards_against_their_closed_loops(verified, monkeypatch):
    """The report's fresh-seed section: the check against the closed loop (its verdict,
    the loop's and the fresh means, the detectable difference), then the same seeds
    against the lab as a measurement; a card whose fresh seeds read 30 % above its loop is
    named as not reproduced."""
    from bpmcal.io import study_files as L
    from bpmcal.report.verification import fresh_seeds_section

    tmp_path, card, _ = verified
    lay = L.StudyFiles(tmp_path / "study")
    table = Path(lay.table(L.FRESH_SEEDS))
    monkeypatch.setitem(M.RUNNERS, "ucs", FreshDEM())
    run_fresh_seeds(tmp_path, card, [101, 102, 103])
    H.fresh_seeds_table([card], [tmp_path / "h" / "seeds.csv"], table=table)
    text = fresh_seeds_section(lay)
    assert "Every card reproduces its closed loop." in text
    assert "tell a difference of" in text and "A measurement, not the check" in text
    high = pd.read_csv(tmp_path / "h" / "seeds.csv")
    high["E_GPa"] *= 1.3
    high.to_csv(tmp_path / "h" / "high.csv", index=False)
    H.fresh_seeds_table([card], [tmp_path / "h" / "high.csv"], table=table)
    text = fresh_seeds_section(lay)
    assert "**Not reproduced**: B1 E (+" in text and "off the loop's mean" in text
    assert "did not converge" not in text
    # a card whose loop ended without meeting the lab: named, not verified by the check
    c = read_card(card)
    c["verification"]["status"] = "max_rounds"
    write_card(tmp_path / "mr.yaml", c)
    H.fresh_seeds_table([tmp_path / "mr.yaml"], [tmp_path / "h" / "seeds.csv"], table=table)
    assert "The closed loops of B1 (max_rounds) did not converge" in fresh_seeds_section(lay)
    # judged against the lab: the report says why
    old = pd.read_csv(tmp_path / "h" / "seeds.csv").drop(columns=["loop_reference"])
    old.to_csv(tmp_path / "h" / "old.csv", index=False)
    H.fresh_seeds_table([card], [tmp_path / "h" / "old.csv"], table=table)
    assert (f"Judged against the lab instead (no closed-loop mean of the same runs): "
            f"B1 ({H.OLD_SEED_TABLE})") in fresh_seeds_section(lay)


class TensileDEM:
    """Brazilian and direct-tension 'runs' of fresh seeds: σt 10 MPa and σt,d 7.5 MPa on
    every seed but 102, where each is 2 % high."""

    def __init__(self):
        self.calls = []

    def _run(self, test, value, out, seed):
        from bpmcal.io.h5 import RunRecord, write_run
        from bpmcal.lab.seeds import REPLICATE_STRIDE

        self.calls.append((test, seed))
        v = value * (1.02 if seed % REPLICATE_STRIDE == 102 else 1.0)  # its every specimen
        s = {f"{test}_peak_MPa": v, f"{test}_MPa": v, f"{test}_valid": True,
             f"{test}_invalid_reason": ""}
        write_run(out, RunRecord(test=test, inputs={"seed": seed}, summary=s))
        return RunOutcome(status="ok", summary=s, path=out)

    def bts(self, out, params, seed, geometry, settings, **kw):
        return self._run("bts", 10.0, out, seed)

    def dtt(self, out, params, seed, geometry, settings, **kw):
        return self._run("dtt", 7.5, out, seed)


def test_direct_tension_without_a_target_is_measured_as_the_cards_prediction(
        verified, monkeypatch):
    """A card with neither tensile target whose fresh seeds are given direct-tension run
    files (a study running both tensile tests): every seed runs the direct-tension test
    beside its Brazilian one, σt,d is a "prediction" row of the table, and the report
    gives the card's direct/Brazilian ratio (the ratio of the means, its standard error
    from theirs)."""
    from bpmcal.io.h5 import check_run_file
    from bpmcal.report.verification import direct_over_brazilian

    tmp_path, card, _ = verified
    dem, tens = FreshDEM(), TensileDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", dem)
    monkeypatch.setitem(M.RUNNERS, "bts", tens.bts)
    monkeypatch.setitem(M.RUNNERS, "dtt", tens.dtt)
    seeds, d = [101, 102, 103], tmp_path / "h"
    df = run_fresh_seeds(tmp_path, card, seeds, bts_runs=[d / f"s{s}.bts.h5" for s in seeds],
                         dtt_runs=[d / f"s{s}.dtt.h5" for s in seeds])
    from bpmcal.lab.seeds import REPLICATE_STRIDE

    for test in ("bts", "dtt"):  # every seed's first specimen (more: its replicates)
        assert {s for t, s in tens.calls if t == test and s < REPLICATE_STRIDE} == set(seeds)
    assert df["dtt_MPa"].tolist() == pytest.approx([7.5, 7.65, 7.5])
    assert check_run_file(d / "s102.dtt.h5")["status"] == "ok"
    t = H.fresh_seeds_table([card], [d / "seeds.csv"], table=tmp_path / "t.csv")
    pred = t[t["role"] == "prediction"].set_index("response")
    assert set(pred.index) == {"bts_MPa", "dtt_MPa"}
    direct, brazil = np.array([7.5, 7.65, 7.5]), np.array([10.0, 10.2, 10.0])
    assert pred.loc["dtt_MPa", "mean"] == pytest.approx(direct.mean())
    r = direct.mean() / brazil.mean()
    se = r * math.hypot(direct.std(ddof=1) / math.sqrt(3) / direct.mean(),
                        brazil.std(ddof=1) / math.sqrt(3) / brazil.mean())
    text = direct_over_brazilian(t)
    assert f"| {r:.2f} ± {se:.2f} |" in text and "| 3, 3 |" in text, text


def test_without_direct_tension_run_files_the_card_has_no_ratio(verified, monkeypatch):
    """The same card with Brazilian run files only (the default study): no direct-tension
    run, no σt,d row, no ratio."""
    from bpmcal.report.verification import direct_over_brazilian

    tmp_path, card, _ = verified
    tens = TensileDEM()
    monkeypatch.setitem(M.RUNNERS, "ucs", FreshDEM())
    monkeypatch.setitem(M.RUNNERS, "bts", tens.bts)
    monkeypatch.setitem(M.RUNNERS, "dtt", tens.dtt)
    d = tmp_path / "h"
    run_fresh_seeds(tmp_path, card, [101, 102], bts_runs=[d / "a.h5", d / "b.h5"])
    assert {t for t, _ in tens.calls} == {"bts"}
    t = H.fresh_seeds_table([card], [d / "seeds.csv"], table=tmp_path / "t.csv")
    assert "dtt_MPa" not in set(t["response"]) and direct_over_brazilian(t) == ""
