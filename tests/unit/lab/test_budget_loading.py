"""Runs that are bounded and visible: each lab test estimates its loading's steps before it
starts, refuses a loading above ``max_steps`` naming the property that sets the timestep,
and reports progress (with its step bound) while one record interval takes long."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support.paper import A1, FAST, FJ1, SMALL

from bpmcal.dem.material import (
    FlatJointMaterial,
    Material,
    expected_failure_strain,
    stiffest_spring,
)
from bpmcal.lab import budget as B
from bpmcal.lab import stepping
from bpmcal.lab.runner import ucs_test

PB = dict(emod=10e9, kratio=2.0, fric=0.5, pb_emod=12e9, pb_kratio=2.5, pb_ten=20e6,
          pb_coh=30e6, pb_fa=30.0)


def test_loading_steps_runs_to_the_smaller_of_max_strain_and_the_failure_scale():
    # 10 x 1e-3 = 0.01 < 0.03: to 0.01 at 1e-7 per step
    assert B.loading_steps(1e-7, 0.03, 1e-3) == pytest.approx(0.01 / 1e-7)
    assert B.loading_steps(1e-7, 0.005, 1e-3) == pytest.approx(0.005 / 1e-7)
    assert B.loading_steps(1e-7, 0.03) == pytest.approx(0.03 / 1e-7)


#: a loading of 1e-9 strain per step: platens at 10 m/s on a 20 mm body at dt 1e-12 s
SLOW = B.Loading("UCS", 10.0, 0.02, "platen_velocity", 10.0)


def test_check_refuses_a_loading_cut_off_long_before_it_is_done(monkeypatch):
    monkeypatch.delenv("BPMCAL_LOADING_BUDGET_S", raising=False)
    kw = dict(dt=1e-12, max_strain=0.03, spring="pb_kratio = 1e-09 (...)",
              failure_strain=1e-3, n_balls=1000, ball_steps_per_s=1e6)
    # done within max_steps: runs, whatever it costs
    assert B.check_loading_steps(SLOW, max_steps=10_000_001, **kw) == pytest.approx(1e7, abs=1)
    # cut off after 9,999,999 steps x 1000 balls / 1e6 per s = 10,000 s > 600 s: refused
    with pytest.raises(B.StepBudgetError) as e:
        B.check_loading_steps(SLOW, max_steps=9_999_999, **kw)
    msg = str(e.value)
    assert "1e+07 steps" in msg and "max_steps = 9999999" in msg and "167 min" in msg
    assert "pb_kratio = 1e-09" in msg  # the default velocity would not fit either
    # cut off after 500 s <= 600 s at 0.5 x the failure strain: runs to its cut-off
    assert B.check_loading_steps(SLOW, max_steps=500_000, **kw) == pytest.approx(1e7, abs=1)
    monkeypatch.setenv("BPMCAL_LOADING_BUDGET_S", "0")
    with pytest.raises(B.StepBudgetError):
        B.check_loading_steps(SLOW, max_steps=500_000, **kw)


def test_check_refuses_a_hopeless_loading_after_ten_seconds(monkeypatch):
    """A cut-off before REACH_FRACTION of the failure strain cannot give a peak: refused
    once its steps take longer than HOPELESS_S (not only the loading budget)."""
    monkeypatch.delenv("BPMCAL_LOADING_BUDGET_S", raising=False)
    kw = dict(dt=1e-12, max_strain=0.03, spring="pb_emod = 1e10 Pa", failure_strain=1e-3,
              ball_steps_per_s=1e6)
    hopeless = int(B.REACH_FRACTION * 1e-3 / 1e-9) - 1  # reaches just below the fraction
    # 100 balls: the cut-off takes ~25 s (> 10 s, < 600 s): refused, the reach named
    with pytest.raises(B.StepBudgetError, match=r"would reach 0\.00025, before the card"):
        B.check_loading_steps(SLOW, max_steps=hopeless, n_balls=100, **kw)
    # 10 balls: ~2.5 s, a short cut on purpose: runs
    assert B.check_loading_steps(SLOW, max_steps=hopeless, n_balls=10, **kw) > hopeless
    # just reaching the fraction: not hopeless, the 600 s budget applies
    assert B.check_loading_steps(SLOW, max_steps=hopeless + 2, n_balls=100, **kw)


def test_a_slow_velocity_is_named_as_the_cause():
    """With the default velocity the loading would fit max_steps: the message names the
    velocity setting, not the spring."""
    slow = B.Loading("UCS", 1e-6, 0.04, "platen_velocity", 0.05)
    with pytest.raises(B.StepBudgetError) as e:
        B.check_loading_steps(slow, dt=1.3e-7, max_strain=0.03, max_steps=3_000_000,
                              spring="pb_emod = 1e10 Pa", n_balls=1500,
                              ball_steps_per_s=1e7, failure_strain=2.7e-3)
    msg = str(e.value)
    assert "platen_velocity gives 1e-06 m/s, against the default 0.05 m/s" in msg
    assert "pb_emod" not in msg


def test_platen_loading_follows_the_strain_rate_setting():
    from bpmcal.lab.brazilian import BTSSettings
    from bpmcal.lab.direct_tension import DTTSettings
    from bpmcal.lab.ucs import UCSSettings

    lo = UCSSettings(strain_rate=2.0).loading_at(0.1)
    assert lo.velocity == pytest.approx(0.1) and lo.setting.startswith("strain_rate")
    assert lo.default == UCSSettings().platen_velocity
    d = DTTSettings(grip_velocity=0.002).loading_at(0.05)
    assert (d.velocity, d.setting, d.loaders, d.default, d.tension) == (
        0.002, "grip_velocity", "grips", DTTSettings().grip_velocity, True)
    assert not lo.tension
    assert BTSSettings().loading_at(0.02).body == "disc"


def test_budget_seconds_from_the_environment(monkeypatch):
    monkeypatch.delenv("BPMCAL_LOADING_BUDGET_S", raising=False)
    assert B.budget_seconds() == B.LOADING_BUDGET_S
    monkeypatch.setenv("BPMCAL_LOADING_BUDGET_S", "60")
    assert B.budget_seconds() == 60.0
    for bad in ("an hour", "-1", "nan"):
        monkeypatch.setenv("BPMCAL_LOADING_BUDGET_S", bad)
        with pytest.raises(ValueError, match="BPMCAL_LOADING_BUDGET_S="):
            B.budget_seconds()


def test_a_cut_off_loading_runs_or_is_refused_by_the_budget(cache, monkeypatch):
    """The same short-cut loading (max_steps far below its estimate) runs to its cut-off
    under the default budget and is refused under a budget of 0 s."""
    st = dataclasses.replace(FAST, max_steps=200)
    run = ucs_test(A1, 1, SMALL, st, cache=cache)
    assert run.summary["stop_reason"] == "max_steps"
    assert 200 <= run.summary["steps"] <= 200 + run.series["step"][1]  # a record's steps
    monkeypatch.setenv("BPMCAL_LOADING_BUDGET_S", "0")
    with pytest.raises(B.StepBudgetError, match="UCS: the loading would need"):
        ucs_test(A1, 1, SMALL, st, cache=cache)


@pytest.mark.parametrize("card", [A1, {**A1, "pb_kratio": 0.05}, {**A1, "rmin_mm": 1.2}, FJ1,
                                  {**FJ1, "fj_kratio": 0.1}],
                         ids=["A1", "pb_kratio", "rmin", "FJ1", "fj_kratio"])
def test_the_timestep_bound_is_above_the_built_specimens_timestep(cache, card):
    """budget.timestep_bound, known before genesis, is above the timestep the built
    specimen gets (so the screen never refuses a loading that could finish), and within
    a factor 10 of it (so it screens at all)."""
    from bpmcal.lab.runner import make_specimen
    from bpmcal.lab.specimen import card_material
    from bpmcal.params import to_si, validate_params

    p = validate_params(card)
    sp = make_specimen(p, 1, SMALL, cache=cache)
    dt = sp.model.set_timestep(None)
    bound = B.timestep_bound(card_material(p)[0], to_si("rmin_mm", p["rmin_mm"]))
    assert dt < bound < 10 * dt


def test_stiffest_spring_names_the_property():
    assert stiffest_spring(Material(**PB)).startswith("pb_emod = 1.2e+10")
    assert stiffest_spring(Material(**{**PB, "pb_kratio": 1e-9})).startswith("pb_kratio = 1e-09")
    assert stiffest_spring(Material(**{**PB, "kratio": 0.1})).startswith("kratio = 0.1")
    # a tie between the linear part and the bond names the bond's property (the card's)
    assert stiffest_spring(Material(**{**PB, "emod": 12e9})).startswith("pb_emod")
    fj = FlatJointMaterial(fj_emod=60e9, fj_kratio=1e-6, fj_ten=10e6, fj_coh=100e6, fj_fa=30.0,
                           fj_fric=0.6)
    assert stiffest_spring(fj).startswith("fj_kratio = 1e-06")
    assert expected_failure_strain(fj) == pytest.approx(100e6 / 60e9)
    assert expected_failure_strain(Material(**PB)) == pytest.approx(30e6 / 12e9)
    # a direct-tension test fails by the tensile strength
    assert expected_failure_strain(fj, tension=True) == pytest.approx(10e6 / 60e9)
    assert expected_failure_strain(Material(**PB), tension=True) == pytest.approx(20e6 / 12e9)


def test_a_collapsed_timestep_is_refused_before_loading(cache, monkeypatch):
    """pb_kratio = 1e-5: the bond's shear spring is 1e5 x its normal one, the timestep
    ~300 x shorter; the UCS refuses at once naming pb_kratio instead of stepping to its
    max_steps (the budget set to 0 s: how long those steps take depends on the host).
    The API runs no screen before genesis (the CLI does: tests/integration/test_extreme_inputs.py)."""
    monkeypatch.setenv("BPMCAL_LOADING_BUDGET_S", "0")
    with pytest.raises(B.StepBudgetError) as e:
        ucs_test({**A1, "pb_kratio": 1e-5}, 1, SMALL, FAST, cache=cache)
    assert "UCS:" in str(e.value) and "pb_kratio = 1e-05" in str(e.value)


def test_progress_reports_the_bound_and_heartbeats_within_a_long_interval(cache,
                                                                        monkeypatch):
    """One record interval of many steps: the heartbeat still reports (here every call
    of the stepping loop), with the steps so far and the loading's step bound."""
    monkeypatch.setattr(stepping, "HEARTBEAT_S", 0.0)
    monkeypatch.setattr(stepping, "CALL_S", 1e-6)  # many short numba calls per record
    monkeypatch.setattr(stepping, "_rate", 1e6)
    seen = []
    st = dataclasses.replace(FAST, record_strain=2e-3, max_strain=4e-3)
    run = ucs_test(A1, 1, SMALL, st, cache=cache, progress=seen.append)
    loading = [d for d in seen if "bound_steps" in d]
    assert loading, "no loading progress"
    bound = loading[0]["bound_steps"]
    assert all(d["bound_steps"] == bound for d in loading)
    # the bound is the steps to max_strain here; the test stops at the first record at or
    # past it, so at most one record interval beyond (the interval's steps are rounded:
    # two of them may fall just short of max_strain)
    interval = int(np.diff(run.series["step"]).max())
    assert run.summary["steps"] <= bound + interval
    # more reports than records: the heartbeat fired between records
    assert len(loading) > run.series["step"].size - 1
    steps = [d["steps"] for d in loading]
    assert steps == sorted(steps)


def test_flat_jointed_card_has_a_bound_too(cache):
    seen = []
    ucs_test(FJ1, 1, SMALL, dataclasses.replace(FAST, max_strain=2e-3), cache=cache,
             progress=seen.append)
    assert any(d.get("bound_steps") for d in seen)


def test_progress_line_past_the_step_estimate_counts_against_the_max_strain():
    """A confined card fails later than its bonds' strength over modulus says: once the
    steps pass the estimate, the line no longer claims 100 % of an 'at most' that was
    exceeded, but gives the share of the max strain (where the loading stops at the
    latest) and the time to it at the measured rate."""
    import io

    from bpmcal.stages.progress import Progress

    out = io.StringIO()
    p = Progress("tri", stream=out, every=0.0)
    base = {"stress_MPa": 300.0, "peak_MPa": 320.0, "cracks": 10, "max_strain": 0.03}
    p({**base, "strain": 0.005, "steps": 50_000, "wall_s": 50.0, "bound_steps": 100_000})
    p({**base, "strain": 0.02, "steps": 150_000, "wall_s": 150.0, "bound_steps": 100_000})
    first, second = out.getvalue().splitlines()
    assert "50.0 % of at most 100000 steps, ETA <= 50 s" in first
    # 2 % of 3 %; the last 1 % at 7,500 steps per 0.1 %: 75,000 steps at 1,000 steps/s
    assert "past the estimate of 100000 steps;  66.7 % of the max strain 3 %" in second
    assert "ETA <= 75 s" in second and "of at most" not in second
