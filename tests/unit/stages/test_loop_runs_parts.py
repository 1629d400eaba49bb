"""A seed's tests as pool jobs of their own (``loop_runs.seed_parts``, issue 53): the
record a closed loop keeps of a seed put together from its runs run apart is the record of
the same runs one after the other (``loop_runs.loop_seed``), for valid, replaced,
never-valid and failed specimens. No DEM: a synthetic 'DEM' whose strengths depend on the
packing seed only, so any run that went to another packing, or a specimen counted twice,
or missed, changes the record."""
import json
import math

import pytest

from bpmcal.io.h5 import RunRecord, write_run
from bpmcal.lab import seeds as S
from bpmcal.lab.brazilian import BTSSettings
from bpmcal.lab.run_context import RunContext
from bpmcal.lab.runner import Geometry
from bpmcal.lab.ucs import UCSSettings
from bpmcal.params import BTS
from bpmcal.stages import loop_runs as LR
from bpmcal.stages import measure as M
from bpmcal.stages.journal import plain
from bpmcal.stages.runs import RunOutcome

PARAMS = {"rmin_mm": 0.8, "porosity": 0.3, "pb_emod_GPa": 20.0, "pb_kratio": 2.0,
          "pb_ten_MPa": 30.0, "pb_coh_MPa": 30.0, "pb_fa_deg": 35.0, "fric": 0.35}
STRIDE = S.REPLACEMENT_STRIDE


class SeedDEM:
    """UCS responses and a Brazilian σt that are functions of the packing seed; a disc is
    invalid when its packing seed is in ``invalid``, fails (a run failure) when it is in
    ``failed``."""

    def __init__(self, invalid=(), failed=()):
        self.invalid, self.failed = set(invalid), set(failed)
        self.calls = []

    def ucs(self, out, params, seed, geometry, settings, **kw):
        self.calls.append(("ucs", seed))
        s = {"ucs_MPa": 50.0 + seed % 7, "E_GPa": 20.0 + seed % 5, "nu": 0.2 + 0.01 * (seed % 3),
             "u_pre_MJm3": 0.1, "peak_strain": 0.01, "cracks_tension": 1, "cracks_shear": 2}
        write_run(out, RunRecord(test="ucs", inputs={"seed": seed}, summary=s))
        return RunOutcome(status="ok", summary=s, path=out)

    def bts(self, out, params, seed, geometry, settings, **kw):
        self.calls.append(("bts", seed))
        if seed in self.failed:
            write_run(out,
                      RunRecord(test="bts",
                                inputs={"seed": seed},
                                status="failed",
                                error="unstable",
                                summary={"wall_s": 0.0}))
            return RunOutcome(status="failed", error="InstabilityError: planted", path=out)
        valid = seed not in self.invalid
        v = 5.0 + (seed % 1009) / 1000.0
        s = {"bts_peak_MPa": v, BTS: v if valid else math.nan, "bts_valid": valid,
             "bts_invalid_reason": "" if valid else f"planted at {seed}"}
        write_run(out, RunRecord(test="bts", inputs={"seed": seed}, summary=s))
        return RunOutcome(status="ok", summary=s, path=out)


def _job(n):
    return dict(params=PARAMS, seed=7, targets=["ucs_MPa", "E_GPa", "nu", BTS],
                tests=M.SeedTests(Geometry(scale=0.3), UCSSettings(),
                                  bts_geometry=Geometry(scale=0.3), bts_settings=BTSSettings()),
                tensile_specimens=n)


def _apart(job, tmp_path):
    """The seed's parts run one by one (each with its own stem, as the journal gives
    them), in the pool's order, and the record put together from them."""
    parts = LR.seed_parts(job)
    ucs, sp = None, {}
    for i in LR.longest_first(parts):
        p = parts[i]
        rec, files = LR.run_part(**p, stem=tmp_path / f"part{i}", ctx=RunContext())
        rec = json.loads(json.dumps(rec, default=plain, allow_nan=True))  # the journal's
        assert files and all(f.exists() for f in files)
        if p["part"] == "ucs":
            ucs = rec
        else:
            sp.setdefault(p["part"], {})[p["j"]] = rec
    return LR.seed_record(job, ucs, {r: [v[j] for j in sorted(v)] for r, v in sp.items()})


def _whole(job, tmp_path):
    rec, _ = LR.loop_seed(**job, stem=tmp_path / "whole", ctx=RunContext())
    return json.loads(json.dumps(rec, default=plain, allow_nan=True))


def _same(a, b):
    """Records equal but for the run files' names (another stem), NaN equal to NaN."""
    assert set(a) == set(b)
    for k in ("row", "out"):
        assert list(a[k]) == list(b[k]), k  # the same columns, in the same order
        for key in a[k]:
            x, y = a[k][key], b[k][key]
            if isinstance(x, float) and math.isnan(x):
                assert isinstance(y, float) and math.isnan(y), key
            else:
                assert x == y, key
    assert (a["bts"] is None) == (b["bts"] is None)


R1 = S.REPLICATE_STRIDE


@pytest.mark.parametrize("n, invalid, failed", [
    (1, (), ()),                              # one valid disc
    (3, (7, 7 + R1), ()),                     # disc 0 and disc 1 invalid: replaced
    (3, (7 + 2 * R1 + k * STRIDE for k in range(S.MAX_REPLACEMENTS + 1)), ()),  # never valid
    (3, (), (7 + R1,)),                       # disc 1 fails: the seed has no σt
])
def test_a_seed_put_together_from_its_runs_is_the_seed_run_whole(tmp_path, monkeypatch, n,
                                                                 invalid, failed):
    invalid = tuple(invalid)
    dem = SeedDEM(invalid, failed)
    monkeypatch.setitem(M.RUNNERS, "ucs", dem.ucs)
    monkeypatch.setitem(M.RUNNERS, "bts", dem.bts)
    job = _job(n)
    whole = _whole(job, tmp_path)
    whole_calls, dem.calls = list(dem.calls), []
    apart = _apart(job, tmp_path)
    _same(whole, apart)
    # the same runs, but a specimen after a failed one, which runs apart and is not counted
    assert set(whole_calls) <= set(dem.calls)
    extra = set(dem.calls) - set(whole_calls)
    assert all(c[0] == "bts" and c[1] >= 7 + 2 * R1 for c in extra)
    assert bool(extra) == bool(failed)
    row = apart["row"]
    if failed:
        assert row["status"] == "failed" and math.isnan(row[BTS])
    elif n == 3 and len(invalid) > 2:
        assert row["status"] == "failed" and math.isnan(row[BTS])  # disc 2 never valid
        assert row["bts_invalid"] == S.MAX_REPLACEMENTS + 1
    else:
        assert row["status"] == "ok" and math.isfinite(row[BTS])
        assert row["bts_invalid"] == len(invalid)


def test_the_parts_run_the_ucs_tests_first_then_each_seeds_specimens_in_turn():
    jobs = [dict(_job(3), seed=s) for s in (1, 2)]
    parts = [p for job in jobs for p in LR.seed_parts(job)]
    order = [(parts[i]["part"], parts[i]["seed"], parts[i].get("j"))
             for i in LR.longest_first(parts)]
    assert order == [("ucs", 1, None), ("ucs", 2, None),
                     *[(BTS, s, j) for j in range(3) for s in (1, 2)]]
    # a top-up runs the raised specimens only, no UCS test
    top = LR.seed_parts(dict(_job(5), seed=1), first_specimen=3)
    assert [(p["part"], p["j"]) for p in top] == [(BTS, 3), (BTS, 4)]
