"""Runs that are bounded and visible: each lab test estimates its loading's steps before it
starts, refuses a loading above ``max_steps`` naming the property that sets the timestep,
and reports progress (with its step bound) while one record interval takes long."""
from __future__ import annotations

import dataclasses

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


def test_check_refuses_above_max_steps_and_names_the_cause():
    kw = dict(strain_per_step=1e-9, max_strain=0.03, dt=1e-12, loading="platens",
              spring="pb_kratio = 1e-09 (...)", failure_strain=1e-3)
    assert B.check_loading_steps("UCS", max_steps=10_000_000, **kw) == 10_000_000
    with pytest.raises(B.StepBudgetError) as e:
        B.check_loading_steps("UCS", max_steps=9_999_999, **kw)
    msg = str(e.value)
    assert "1e+07 steps" in msg and "1e+07 steps of its budget" in msg
    assert "pb_kratio = 1e-09" in msg


def test_budget_is_a_day_at_the_measured_speed(monkeypatch):
    monkeypatch.delenv("BPMCAL_LOADING_BUDGET_S", raising=False)
    assert B.budget_steps(1000, 5e6) == pytest.approx(86400 * 5e6 / 1000)
    assert B.budget_steps(1000, None) == pytest.approx(86400 * B.DEFAULT_BALL_STEPS_PER_S / 1000)
    monkeypatch.setenv("BPMCAL_LOADING_BUDGET_S", "60")
    assert B.budget_steps(1000, 5e6) == pytest.approx(60 * 5e6 / 1000)
    monkeypatch.setenv("BPMCAL_LOADING_BUDGET_S", "an hour")
    with pytest.raises(ValueError, match="BPMCAL_LOADING_BUDGET_S='an hour'"):
        B.budget_steps(1000, 5e6)


def test_a_small_budget_refuses_an_ordinary_card(cache, monkeypatch):
    """The same card runs under the default budget (test_progress_... below) and is
    refused when the budget is one second."""
    monkeypatch.setenv("BPMCAL_LOADING_BUDGET_S", "1e-3")
    with pytest.raises(B.StepBudgetError, match="UCS: the loading would need"):
        ucs_test(A1, 1, SMALL, FAST, cache=cache)


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


def test_a_collapsed_timestep_is_refused_before_loading(cache):
    """pb_kratio = 1e-9: the bond's shear spring is 1e9 x its normal one, the timestep
    collapses; the UCS refuses at once (a failure record naming pb_kratio), it does not
    run for hours."""
    with pytest.raises(B.StepBudgetError) as e:
        ucs_test({**A1, "pb_kratio": 1e-9}, 1, SMALL, FAST, cache=cache)
    assert "UCS:" in str(e.value) and "pb_kratio = 1e-09" in str(e.value)


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
    # the bound is the steps to max_strain here; the test stops at the record that reaches
    # it, so at most one record's rounding beyond
    assert run.summary["steps"] <= bound + run.series["step"].size
    # more reports than records: the heartbeat fired between records
    assert len(loading) > run.series["step"].size - 1
    steps = [d["steps"] for d in loading]
    assert steps == sorted(steps)


def test_flat_jointed_card_has_a_bound_too(cache):
    seen = []
    ucs_test(FJ1, 1, SMALL, dataclasses.replace(FAST, max_strain=2e-3), cache=cache,
             progress=seen.append)
    assert any(d.get("bound_steps") for d in seen)
