"""The posterior predictive stage (:mod:`bpmcal.stages.predictive`) with its DEM runs
replaced by closed forms: each draw's envelope recovers the Mohr-Coulomb line its σ1(σ3)
was built on, and a stage stopped part way reads its finished runs back from the journal
instead of running them again (a flat-jointed impact can take a quarter of an hour)."""
import math

import pandas as pd
import pytest

from bpmcal.lab.impact import ImpactSettings
from bpmcal.lab.run_context import RunContext
from bpmcal.lab.runner import Geometry
from bpmcal.lab.triaxial import TriaxialSettings
from bpmcal.stages import predictive as pred
from bpmcal.stages.runs import RunOutcome

SIGMA3 = [0.0, 5.0, 10.0]
PHI = 30.0  # the Mohr-Coulomb line the fake triaxial tests follow


def _sigma1(c_MPa: float, sigma3_MPa: float) -> float:
    """σ1 at failure on the Mohr-Coulomb line of cohesion c and friction angle PHI."""
    s = math.sin(math.radians(PHI))
    q = (1 + s) / (1 - s)
    return 2 * c_MPa * math.sqrt(q) + q * sigma3_MPa


class Stopped(Exception):
    """The stage stopped part way (a kill, a time limit)."""


class FakeRuns:
    """Triaxial and impact runs as closed forms of a draw's parameters, each writing a
    small file where the stage asks; ``fail_after`` raises (a kill) after that many runs."""

    def __init__(self, fail_after=None):
        self.calls = []
        self.fail_after = fail_after

    def _run(self, out, kind, summary):
        if self.fail_after is not None and len(self.calls) >= self.fail_after:
            raise Stopped("stopped")
        self.calls.append(kind)
        with open(out, "w") as fh:
            fh.write(kind)
        return RunOutcome(status="ok", summary=summary, path=out)

    def triaxial(self, out, params, seed, geometry, settings, **kw):
        s3 = settings.sigma3 / 1e6
        return self._run(out, f"tri {s3:g}",
                         {"sigma1_MPa": _sigma1(params["pb_coh_MPa"] / 2, s3)})

    def impact(self, out, params, seed, geometry, settings, **kw):
        return self._run(out, "impact", {"eta_f": params["pb_ten_MPa"] / 100})


@pytest.fixture
def draws(tmp_path):
    f = tmp_path / "draws.csv"
    pd.DataFrame({"draw": [1, 2], "pb_emod_GPa": [13.0, 14.0], "pb_kratio": [2.0, 2.5],
                  "pb_ten_MPa": [20.0, 30.0], "pb_coh_MPa": [24.0, 32.0],
                  "pb_fa_deg": [30.0, 30.0], "fric": [0.5, 0.5],
                  "porosity": [0.3, 0.3], "rmin_mm": [0.8, 0.8]}).to_csv(f, index=False)
    return f


def _call(tmp_path, draws, fake, monkeypatch):
    monkeypatch.setattr(pred, "run_triaxial_file", fake.triaxial)
    monkeypatch.setattr(pred, "run_impact_file", fake.impact)
    out = tmp_path / "out"
    tri = [out / f"draw{d}.s3_{s:g}.h5" for d in (1, 2) for s in SIGMA3]
    imp = [out / f"draw{d}.impact.h5" for d in (1, 2)]
    table = out / "predictive.csv"
    settings = pred.PredictiveSettings(sigma3_MPa=SIGMA3, geometry=Geometry(),
                                       tri_settings=TriaxialSettings(),
                                       impact_geometry=Geometry(),
                                       impact_settings=ImpactSettings())
    t = pred.predictive(draws, specimen="B1", tri_runs=tri, table=table, settings=settings,
                        impact_runs=imp, ctx=RunContext(threads=1))
    return t, tri, imp, table


def test_each_draw_recovers_its_envelope_and_eta_f(tmp_path, draws, monkeypatch):
    fake = FakeRuns()
    t, tri, imp, table = _call(tmp_path, draws, fake, monkeypatch)
    rows = t[t["draw"] != "card"].set_index("draw")
    assert rows.loc["1", "c_MPa"] == pytest.approx(12.0, rel=1e-6)
    assert rows.loc["2", "c_MPa"] == pytest.approx(16.0, rel=1e-6)
    assert rows["phi_deg"].to_numpy() == pytest.approx([PHI, PHI], rel=1e-6)
    assert rows["eta_f"].to_numpy() == pytest.approx([0.2, 0.3])
    assert len(fake.calls) == 8 and all(f.exists() for f in tri + imp) and table.exists()
    assert not (table.parent / ".predictive.runs").exists()  # the journal goes at the end


def test_a_stopped_stage_reads_its_finished_runs_back(tmp_path, draws, monkeypatch):
    first = FakeRuns(fail_after=3)
    with pytest.raises(Stopped):
        _call(tmp_path, draws, first, monkeypatch)
    folder = tmp_path / "out" / ".predictive.runs"
    assert folder.is_dir() and len(first.calls) == 3
    assert not (tmp_path / "out" / "predictive.csv").exists()
    again = FakeRuns()
    t, tri, imp, table = _call(tmp_path, draws, again, monkeypatch)
    assert len(again.calls) == 8 - 3  # the three finished runs were not run again
    expected = ["impact"] * 2 + [f"tri {s:g}" for s in SIGMA3] * 2
    assert sorted(first.calls + again.calls) == sorted(expected)
    assert all(f.exists() for f in tri + imp) and not folder.exists()
    (tmp_path / "b").mkdir()
    t2, *_ = _call(tmp_path / "b", draws, FakeRuns(), monkeypatch)
    pd.testing.assert_frame_equal(t, t2)  # read-back runs give the same table
