"""Guards on extreme but valid inputs: interruptible stepping (exact), the genesis step
budget and progress, the ball-count estimate, failure records that never replace a good
run."""
import math
from dataclasses import replace

import numpy as np
import pytest
from support.lab_util import A1, FAST, SMALL

from bpmcal.dem.errors import InstabilityError
from bpmcal.io import h5
from bpmcal.lab import runner, stepping
from bpmcal.lab.budget import BudgetError, check_budget, estimate_balls
from bpmcal.lab.runner import Geometry, make_specimen
from bpmcal.stages.runs import run_ucs_file


def _loaded(cache):
    sp = make_specimen(A1, 3, SMALL, cache=cache)
    m = sp.model
    m.set_wall_velocity(0, velocity=(0.0, 0.0, 0.5))
    m.set_wall_velocity(1, velocity=(0.0, 0.0, -0.5))
    m.set_timestep(None)
    return m


def test_stepping_in_pieces_is_bitwise_the_same(cache, monkeypatch):
    """cycle(m, n) in many short numba calls == m.cycle(n) in one, bit for bit, through
    bond breakage (the loaded specimen cracks)."""
    a = _loaded(cache)
    a.cycle(3000)
    b = _loaded(cache)
    monkeypatch.setattr(stepping, "FIRST_BALL_STEPS", 7 * b.n)  # 7 steps per call ...
    monkeypatch.setattr(stepping, "_rate", None)
    monkeypatch.setattr(stepping.time, "perf_counter", lambda: 0.0)  # ... and no speed-up
    calls = []
    real = type(b).cycle
    monkeypatch.setattr(type(b), "cycle", lambda m, n, record=True: (calls.append(n),
                                                                      real(m, n, record)))
    stepping.cycle(b, 3000)
    assert len(calls) == 429 and sum(calls) == 3000
    assert a.n_broken > 0 and a.step == b.step
    for k in ("pos", "vel", "angvel", "force"):
        assert np.array_equal(getattr(a.B, k), getattr(b.B, k)), k
    assert np.array_equal(a.Bd.state, b.Bd.state)
    ea, eb = a.energies(), b.energies()
    assert all(np.array_equal(np.asarray(ea[k]), np.asarray(eb[k])) for k in ea)


def test_pieces_of_a_chunked_run_end_on_its_chunks(cache, monkeypatch):
    """With ``quantum`` (a servo loop's chunk) every piece but the last is a multiple of
    it, also when the piece the speed allows is shorter than one chunk."""
    m = _loaded(cache)
    monkeypatch.setattr(stepping.time, "perf_counter", lambda: 0.0)  # no speed-up
    for per_call, quantum, n in ((7, 3, 100), (2, 5, 23), (9, 1, 40)):
        monkeypatch.setattr(stepping, "FIRST_BALL_STEPS", per_call * m.n)
        monkeypatch.setattr(stepping, "_rate", None)
        calls = []
        stepping.cycle(m, n, run=lambda k, rec: calls.append((k, rec)), quantum=quantum)
        assert sum(k for k, _ in calls) == n
        assert all(k % quantum == 0 and k >= quantum for k, _ in calls[:-1])
        assert [rec for _, rec in calls] == [False] * (len(calls) - 1) + [True]


def test_a_specimen_that_does_not_settle_is_a_failure_record(cache, tmp_path):
    """pb_kratio = 1e-9 collapses the timestep: under the bpmcal genesis (a locked-in
    stress to settle) the settling never converges (the pfc genesis starts force-free and
    settles at once). With a step budget the run ends as a failure record naming the phase
    and the budget."""
    out = tmp_path / "k.h5"
    res = run_ucs_file(out, {**A1, "pb_kratio": 1e-9}, 3, replace(SMALL, genesis="bpmcal"),
                       FAST, cache=cache, genesis_max_steps=2000)
    assert res.status == "failed"
    s = h5.read_summary(out)
    assert s["status"] == "failed"
    assert "genesis step budget of 2,000 steps" in s["error"]
    assert "unbalanced-force ratio" in s["error"]


def test_the_budget_does_not_change_a_specimen_that_settles(cache):
    a = make_specimen(A1, 3, SMALL, cache=cache).model
    b = make_specimen(A1, 3, SMALL, cache=cache, genesis_max_steps=50_000).model
    assert np.array_equal(a.B.pos, b.B.pos) and a.step == b.step


def test_genesis_reports_its_phases(tmp_path):
    seen = []
    # a cold cache and a dense packing: the relaxation runs past its first 2,000 steps
    make_specimen({**A1, "porosity": 0.2}, 5, SMALL, cache=tmp_path, progress=seen.append)
    phases = [d["phase"] for d in seen]
    assert "relax packing" in phases
    relax = [d for d in seen if d["phase"] == "relax packing"]
    assert [d["steps"] for d in relax] == sorted(d["steps"] for d in relax)
    assert all(math.isfinite(d["ratio"]) and d["target"] > 0 and d["wall_s"] >= 0
               for d in seen)
    assert relax[-1]["ratio"] <= relax[-1]["target"]  # it ended converged


def test_ball_count_estimate_matches_the_genesis(cache):
    """The estimate is distribute()'s volume balance: within a few balls of the count."""
    sp = make_specimen(A1, 3, SMALL, cache=cache)
    est = estimate_balls(A1["rmin_mm"], A1["porosity"], scale=SMALL.scale)
    assert abs(sp.report["n_balls"] / est - 1) < 0.05


def test_budget_refuses_before_any_work():
    with pytest.raises(BudgetError, match="rmin_mm=0.01"):
        check_budget({**A1, "rmin_mm": 0.01}, Geometry(), mem_budget_mb=1e9)
    with pytest.raises(BudgetError, match="budget of 300 MB"):
        check_budget(A1, Geometry(), mem_budget_mb=300)
    check_budget(A1, Geometry(), mem_budget_mb=2000)  # the full-size A1 specimen fits


def test_a_failure_never_replaces_a_good_run(cache, tmp_path, monkeypatch):
    out = tmp_path / "a1.h5"
    assert run_ucs_file(out, A1, 3, SMALL, FAST, cache=cache).status == "ok"
    good = out.read_bytes()

    def unstable(*a, **k):
        raise InstabilityError("run blew up at step 12: ball 3 ...", 12, 3)
    monkeypatch.setattr(runner, "run_test", unstable)  # the driver, as the runner calls it
    res = run_ucs_file(out, A1, 3, SMALL, FAST, cache=cache)
    assert res.status == "failed" and res.kept == out
    assert out.read_bytes() == good
    rec = tmp_path / "a1.failed.h5"
    assert res.path == rec and h5.read_summary(rec)["status"] == "failed"
    # a failure record itself is replaced by the next failure (nothing good to keep)
    res2 = run_ucs_file(rec, A1, 3, SMALL, FAST, cache=cache)
    assert res2.kept is None and res2.path == rec
