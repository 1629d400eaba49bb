"""Calibration against the tensile strength (issue 13 item 5): σt sets the bond-strength
ratio; a σc/σt the parallel-bond models cannot reach is a no-exact-fit with every missed
target named. Synthetic regression models with known answers (no DEM)."""
import numpy as np
import pytest
from support.synthetic import FIXED, TRUTH, dem_response, models, predict

from bpmcal.analysis.calibration import ClosedLoop, LoopSteps, Multistart, SearchSpace, bts_strengths, invert
from bpmcal.params import BTS, table2_ranges

T2 = table2_ranges()  # pb_ten_MPa, pb_coh_MPa in [10, 50]


def test_bts_strengths_frees_the_ratio_only_with_a_tensile_target():
    assert bts_strengths({"ucs_MPa": 60.0}, None, FIXED, 1.4) == (None, 1.4, "ratio")
    free, ratio, by = bts_strengths({"ucs_MPa": 60.0, BTS: 8.0}, None, FIXED, 1.4)
    assert ratio is None and by == BTS
    assert free == ("pb_emod_GPa", "pb_kratio", "pb_coh_MPa", "pb_ten_MPa")
    # pb_ten fixed by the user: σt stays a plain target, the ratio is not touched
    assert bts_strengths({BTS: 8.0}, None, {**FIXED, "pb_ten_MPa": 30.0}, None)[2] == "ratio"


@pytest.mark.parametrize("planted", [1.1, 1.6, 1.9])
def test_inversion_recovers_a_planted_ratio_from_a_planted_sigma_t(planted):
    ms = models()
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": planted * TRUTH["pb_coh_MPa"]}
    targets = predict(ms, truth)
    free, ratio, _ = bts_strengths(targets, None, FIXED, 1.4)  # configured 1.4 is overridden
    res = invert(ms,
                 targets,
                 FIXED,
                 SearchSpace(ranges=T2, free=free, ratio=ratio),
                 search=Multistart(seed=3))
    assert res.status == "ok" and res.missed == [] and res.reach == {}
    got = res.solution["pb_ten_MPa"] / res.solution["pb_coh_MPa"]
    assert got == pytest.approx(planted, rel=1e-6)
    for p, v in truth.items():
        assert res.solution[p] == pytest.approx(v, rel=1e-6), p
    # without σt the configured ratio would have been used and σt missed
    ucs_only = {k: v for k, v in targets.items() if k != BTS}
    r14 = invert(ms, ucs_only, FIXED, SearchSpace(ranges=T2, ratio=1.4), search=Multistart(seed=3))
    assert r14.solution["pb_ten_MPa"] / r14.solution["pb_coh_MPa"] == pytest.approx(1.4)
    assert abs(ms[BTS].predict(r14.solution) / targets[BTS] - 1) > 0.01


def _sigma_t_span(ms, targets):
    """Independent check of the reported span: with E and ν met, kratio and emod are
    fixed by the (linear) models; walk pb_ten over its range, solve σc(coh, ten) = target
    for coh (linear in coh), keep the points inside the range of coh, and take the
    extremes of σt."""
    kr = (targets["nu"] - 0.1) / 0.04
    out = []
    for ten in np.linspace(10, 50, 40001):
        # σc = 120 + 1.2 coh + 0.8 ten - 300 por - 6 kr + 0.02 coh ten
        coh = (targets["ucs_MPa"] - 120 - 0.8 * ten + 300 * 0.34 + 6 * kr) / (1.2 + 0.02 * ten)
        if 10 <= coh <= 50:
            out.append(0.3 * ten + 0.1 * coh)
    return min(out), max(out)


def test_unreachable_ucs_over_bts_is_a_no_exact_fit_with_the_missed_targets():
    ms = models()
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 35.0}
    targets = predict(ms, truth)
    targets[BTS] = targets["ucs_MPa"] / 15.0  # σc/σt = 15: beyond what these models give
    free, ratio, _ = bts_strengths(targets, None, FIXED, 1.4)
    res = invert(ms,
                 targets,
                 FIXED,
                 SearchSpace(ranges=T2, free=free, ratio=ratio),
                 search=Multistart(seed=3))
    assert res.status == "no-exact-fit" and not res.ok
    missed = {m["target"]: m for m in res.missed}
    assert BTS in missed  # the model's σt is too high for a σc/σt of 15
    m = missed[BTS]
    assert m["error_pct"] > 1.0
    assert m["error_pct"] == pytest.approx(100 * (m["predicted"] / targets[BTS] - 1))
    assert m["predicted"] == pytest.approx(ms[BTS].predict(res.solution))
    # every target is in the objective and reported: none dropped
    assert set(res.residuals) == set(targets)
    assert all(abs(res.residuals[r]) > res.tol for r in missed)
    # what the models reach while meeting σc, E, ν, checked independently
    lo, hi = _sigma_t_span(ms, targets)
    assert res.reach["bts_MPa"] == pytest.approx([lo, hi], rel=2e-3)
    q_lo, q_hi = res.reach["ucs_over_bts"]
    assert q_hi < 15 and q_hi == pytest.approx(targets["ucs_MPa"] / lo, rel=2e-3)
    assert "σc/σt = 15" in res.message and f"bts_MPa {m['error_pct']:+.2f} %" in res.message
    # the target σc/σt is above the parallel bond's reach: the registry's advice names
    # the other model
    assert "linear parallel bond models reach" in res.message
    assert "try `contact_model: flatjoint`" in res.message
    # the compromise is the least-squares one: no start does better
    best = sum(v ** 2 for v in res.residuals.values())
    assert best <= res.starts["sum_sq"].min() * (1 + 1e-9)


def test_a_sigma_c_out_of_range_stays_unreachable_with_sigma_t():
    """No-exact-fit is only for a target set whose other targets are met: a σc beyond the
    ranges is still 'unreachable' (widen the ranges), σt or not."""
    ms = models()
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 35.0}
    targets = predict(ms, truth)
    top = {**FIXED, **TRUTH, "pb_coh_MPa": 50.0, "pb_ten_MPa": 50.0, "pb_kratio": 1.0}
    targets["ucs_MPa"] = 1.3 * ms["ucs_MPa"].predict(top)
    free, ratio, _ = bts_strengths(targets, None, FIXED, 1.4)
    res = invert(ms,
                 targets,
                 FIXED,
                 SearchSpace(ranges=T2, free=free, ratio=ratio),
                 search=Multistart(seed=3, diagnose=False))
    assert res.status == "unreachable"
    assert "ucs_MPa" in {m["target"] for m in res.missed}


def _dem(ms, offset=0.03):
    """A 'DEM' that differs from the regression: every response off by a few %, σt more."""
    def simulate(p):
        return dem_response(predict(ms, p), offset)
    return simulate


def test_closed_loop_steers_sigma_t_with_the_ratio_free():
    ms = models()
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 1.6 * TRUTH["pb_coh_MPa"]}
    sim = _dem(ms)
    targets = sim(truth)  # the planted truth, as the 'DEM' sees it
    free, ratio, _ = bts_strengths(targets, None, FIXED, 1.4)
    start = invert(ms,
                   targets,
                   FIXED,
                   SearchSpace(ranges=T2, free=free, ratio=ratio),
                   search=Multistart(seed=3)).solution
    loop = ClosedLoop(sim,
                      targets,
                      space=SearchSpace(ranges=T2, free=free, ratio=ratio),
                      steps=LoopSteps(rtol=1e-3, max_rounds=8),
                      models=ms)
    res = loop.run(start)
    assert res.converged, res.summary()
    assert f"err_{BTS}" in res.history and abs(res.history[f"err_{BTS}"].iloc[0]) > 1e-3
    assert res.params["pb_ten_MPa"] / res.params["pb_coh_MPa"] == pytest.approx(1.6, rel=1e-2)


def test_closed_loop_with_an_unreachable_sigma_t_records_the_miss():
    ms = models()
    sim = _dem(ms)
    targets = sim({**FIXED, **TRUTH, "pb_ten_MPa": 35.0})
    targets[BTS] = targets["ucs_MPa"] / 15.0
    free, ratio, _ = bts_strengths(targets, None, FIXED, 1.4)
    start = invert(ms,
                   targets,
                   FIXED,
                   SearchSpace(ranges=T2, free=free, ratio=ratio),
                   search=Multistart(seed=3, diagnose=False)).solution
    res = ClosedLoop(sim,
                     targets,
                     space=SearchSpace(ranges=T2, free=free, ratio=ratio),
                     steps=LoopSteps(max_rounds=4),
                     models=ms).run(start)
    assert not res.converged
    assert res.responses[BTS] / targets[BTS] - 1 > 0.05  # σt stays too high, and it is recorded
    assert (res.history[f"err_{BTS}"].abs() > 0.05).all()


def test_a_sigma_c_over_sigma_t_below_the_reach_advises_a_wider_tensile_range():
    ms = models()
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 35.0}
    targets = predict(ms, truth)
    targets[BTS] = targets["ucs_MPa"] / 3.0  # σc/σt = 3: below what these models give
    free, ratio, _ = bts_strengths(targets, None, FIXED, 1.4)
    res = invert(ms,
                 targets,
                 FIXED,
                 SearchSpace(ranges=T2, free=free, ratio=ratio),
                 search=Multistart(seed=3))
    assert res.status == "no-exact-fit"
    assert targets["ucs_MPa"] / targets[BTS] < res.reach["ucs_over_bts"][0]
    assert "widen the range of pb_ten_MPa upwards" in res.message
    assert "contact_model: flatjoint" not in res.message
