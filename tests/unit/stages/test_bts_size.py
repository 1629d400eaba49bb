"""σt at the lab's disc size (:mod:`bpmcal.stages.bts_size`): the power-law fit against
closed forms, σt at a size measured or read from the curve, and the stage with its DEM
runs replaced by a closed form σt(D) (``measure.RUNNERS``, the seam every per-seed test
goes through): the exponent recovered, the contact cap scaled with D from the study's disc
and the study's disc left as it is, the seeds grown until the mean is precise enough, the
tables and run files written."""
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from bpmcal.cli import main
from bpmcal.dem.errors import InputError
from bpmcal.io.checks import BadInput
from bpmcal.io.study_files import StudyFiles
from bpmcal.lab.brazilian import BTSSettings, similar_contact_cap
from bpmcal.lab.budget import BudgetError
from bpmcal.lab.run_context import RunContext
from bpmcal.lab.runner import bts_geometry
from bpmcal.report.bts_size import section
from bpmcal.stages import bts_size as bs
from bpmcal.stages import measure
from bpmcal.stages.runs import RunOutcome


# ------------------------------------------------------------------ the fit, closed forms
@pytest.mark.parametrize("k", [0.0, 0.35, 1.2])
def test_points_on_an_exact_power_law_give_its_exponent_back(k):
    d = np.array([20.0, 27.5, 38.0, 50.0])
    ref = 27.5
    m = 9.7 * (d / ref) ** -k
    se = np.array([0.02, 0.05, 0.01, 0.3]) * m  # any weights: the points lie on the curve
    f = bs.fit_power_law(d, m, se, ref)
    assert f["k"] == pytest.approx(k, abs=1e-10)
    assert f["sigma_ref_MPa"] == pytest.approx(9.7, rel=1e-12)
    assert f["chi2"] == pytest.approx(0.0, abs=1e-18)
    assert f["n_sizes"] == 4


def test_two_sizes_give_the_exact_interpolation():
    d1, d2, s1, s2 = 27.5, 50.0, 9.73, 8.47
    f = bs.fit_power_law([d1, d2], [s1, s2], [0.1, 0.2], d1)
    k = math.log(s1 / s2) / math.log(d2 / d1)
    assert f["k"] == pytest.approx(k, rel=1e-12)
    for d in (d1, d2, 37.08, 60.0):
        v, _ = bs.curve_at(f, d)
        assert v == pytest.approx(s1 * (d / d1) ** -k, rel=1e-12)
    # the SE at a measured size is that size's own (the curve passes through both points)
    assert bs.curve_at(f, d1)[1] == pytest.approx(0.1, rel=1e-9)
    assert bs.curve_at(f, d2)[1] == pytest.approx(0.2, rel=1e-9)
    # k's SE: the two log-SEs through the log-distance, var k = (s1² + s2²) / ln²(d2/d1)
    assert f["k_se"] == pytest.approx(math.hypot(0.1 / s1, 0.2 / s2) / math.log(d2 / d1),
                                      rel=1e-9)


def test_scattered_points_widen_k_by_their_reduced_chi2():
    d = np.array([27.5, 37.0, 50.0])
    m = np.array([9.7, 8.0, 8.5])  # not on any power law within SEs of 1 %
    se = 0.01 * m
    f = bs.fit_power_law(d, m, se, 27.5)
    x = np.log(d / 27.5)
    X = np.column_stack([np.ones(3), -x])
    w = 1 / 0.01 ** 2
    base = math.sqrt(np.linalg.inv(w * X.T @ X)[1, 1])
    assert f["chi2"] > 1
    assert f["k_se"] == pytest.approx(base * math.sqrt(f["chi2"] / 1), rel=1e-9)


def test_sizes_without_an_se_are_left_out_and_one_size_is_no_curve():
    f = bs.fit_power_law([27.5, 50.0], [9.7, 8.4], [0.1, math.nan], 27.5)
    assert f["n_sizes"] == 1 and math.isnan(f["k"])
    assert all(math.isnan(v) for v in bs.curve_at(f, 40.0))


def _sizes(rows):
    return pd.DataFrame(rows, columns=["diameter_mm", "valid", "mean_MPa", "se_MPa"])


def test_sigma_at_a_size_measured_or_read_from_the_curve():
    sizes = _sizes([(27.5, 5, 9.7, 0.1), (37.08, 5, 9.0, 0.1), (50.0, 4, 8.4, 0.15)])
    f = bs.fit_power_law(sizes["diameter_mm"], sizes["mean_MPa"], sizes["se_MPa"], 27.5)
    assert bs.sigma_at(sizes, f, 50.0) == {"value": 8.4, "se": 0.15, "method": "measured"}
    inside = bs.sigma_at(sizes, f, 45.0)
    assert inside["method"] == "interpolated"
    assert inside["value"] == pytest.approx(bs.curve_at(f, 45.0)[0])
    assert bs.sigma_at(sizes, f, 54.0)["method"] == "extrapolated"
    # the lab's size with one valid disc: from the curve of the others
    one = _sizes([(27.5, 5, 9.7, 0.1), (37.08, 5, 9.0, 0.1), (50.0, 1, 6.0, math.nan)])
    f1 = bs.fit_power_law(one["diameter_mm"], one["mean_MPa"], one["se_MPa"], 27.5)
    assert bs.sigma_at(one, f1, 50.0)["method"] == "extrapolated"
    none = _sizes([(27.5, 1, 9.7, math.nan), (50.0, 0, math.nan, math.nan)])
    f0 = bs.fit_power_law(none["diameter_mm"], none["mean_MPa"], none["se_MPa"], 27.5)
    assert bs.sigma_at(none, f0, 50.0)["method"] == "not measured"


def test_the_sizes_measured():
    assert bs.sizes_of(27.5, 50.0) == [27.5, pytest.approx(math.sqrt(27.5 * 50)), 50.0]
    assert bs.sizes_of(27.5, 50.0, middle=False) == [27.5, 50.0]
    assert bs.sizes_of(27.5, 20.0, middle=False) == [20.0, 27.5]
    assert bs.sizes_of(27.5, 27.5) == [27.5]
    with pytest.raises(BadInput, match="lab's disc"):
        bs.sizes_of(27.5, 0.0)


def test_the_contact_cap_scaled_with_the_disc():
    assert similar_contact_cap(1.5, 50.0, 27.5) == pytest.approx(1.5 * 50 / 27.5)
    assert similar_contact_cap(1.5, 27.5, 27.5) == 1.5  # the study's disc: as it is
    for bad in (0.0, -1.0, math.nan, "50"):
        with pytest.raises(InputError, match="positive disc diameter"):
            similar_contact_cap(1.5, bad, 27.5)


@pytest.mark.parametrize("kw, match", [({"seeds": 1}, "seeds=1"),
                                       ({"seeds": 5, "max_seeds": 4}, "max_seeds=4"),
                                       ({"target_se": 0.0}, "target_se=0.0"),
                                       ({"first_seed": -1}, "first_seed=-1")])
def test_bad_size_settings_are_refused(kw, match):
    with pytest.raises(BadInput, match=match):
        bs.SizeSettings(**kw)


# ------------------------------------------------------------------ the stage, closed-form runs
K, SIGMA_REF = 0.3, 9.7  # the closed form: σt = SIGMA_REF (D / 27.5)^-K x (1 + noise)


class FakeDiscs:
    """Brazilian runs as a closed form of the disc's diameter, with a deterministic
    packing-seed scatter of ``cv``; ``invalid`` packing seeds are invalid discs. Each
    writes a small file where the stage asks and records the disc and settings."""

    def __init__(self, cv=0.04, invalid=()):
        self.cv, self.invalid, self.calls = cv, set(invalid), []

    def __call__(self, out, params, seed, geometry, settings, **kw):
        d = geometry.scale * geometry.diameter_mm
        self.calls.append((d, seed, settings))
        noise = self.cv * math.sqrt(3) * (2 * ((seed * 0.6180339887) % 1.0) - 1)
        v = SIGMA_REF * (d / 27.5) ** -K * (1 + noise)
        valid = seed not in self.invalid
        with open(out, "w") as fh:
            fh.write(f"{d} {seed}")
        return RunOutcome(status="ok", path=out, summary={
            "bts_valid": valid, "bts_MPa": v if valid else math.nan, "bts_peak_MPa": v,
            "discs": 1, "balls_across": d / 1.6, "n_balls": 10.0,
            "bts_invalid_reason": "" if valid else "fracture initiated next to the top platen"})


@pytest.fixture
def card(tmp_path):
    f = tmp_path / "card.yaml"
    f.write_text(yaml.safe_dump({
        "card_format": 1, "specimen": "B1",
        "parameters": {"rmin_mm": 0.8, "porosity": 0.34, "pb_emod_GPa": 10.4,
                       "pb_kratio": 3.47, "pb_ten_MPa": 27.7, "pb_coh_MPa": 19.7,
                       "pb_fa_deg": 35.0, "fric": 0.35},
        "targets": {"ucs_MPa": 60.0, "E_GPa": 13.7, "nu": 0.25, "bts_MPa": 8.0},
        "lab": {"ucs_MPa": 60.0, "E_GPa": 13.7, "nu": 0.25, "bts_MPa": 8.0},
        "target_se": {"bts_MPa": 0.3}}))
    return f


def _stage(tmp_path, card, fake, monkeypatch, **size):
    monkeypatch.setitem(measure.RUNNERS, "bts", fake)
    out = tmp_path / "out"
    st = BTSSettings(contact_cap=1.5)
    r = bs.bts_size(card, lab_diameter_mm=50.0, disc=bts_geometry(scale=0.55), settings=st,
                    run_dir=out / "runs", runs_table=out / "runs.csv",
                    sizes_table=out / "sizes.csv", fit_table=out / "fit.csv",
                    size_settings=bs.SizeSettings(**size), ctx=RunContext(max_balls=None))
    return r, out, st


def test_the_stage_recovers_the_curve_and_compares_at_the_labs_size(tmp_path, card,
                                                                    monkeypatch):
    fake = FakeDiscs()
    r, out, st = _stage(tmp_path, card, fake, monkeypatch, seeds=6, max_seeds=6)
    sizes, f = r["sizes"], r["fit"].iloc[0]
    assert list(sizes["diameter_mm"]) == pytest.approx([27.5, math.sqrt(27.5 * 50), 50.0])
    assert list(sizes["role"]) == ["the study's disc", "between", "the lab's disc"]
    assert list(sizes["seeds"]) == [6, 6, 6] and list(sizes["valid"]) == [6, 6, 6]
    # the same seeds at every size: the scatter cancels in the ratios, k comes back exactly
    assert f["k"] == pytest.approx(K, abs=1e-9)
    assert f["method"] == "measured"
    lab50 = sizes.set_index("role").loc["the lab's disc"]
    assert f["sigma_lab_size_MPa"] == pytest.approx(lab50["mean_MPa"])
    assert f["err_pct"] == pytest.approx(100 * (lab50["mean_MPa"] / 8.0 - 1))
    assert f["z"] == pytest.approx((lab50["mean_MPa"] - 8.0) / math.hypot(lab50["se_MPa"], 0.3))
    # the study's disc runs with the study's settings object; the others with the cap x D
    # and at their own size (not enlarged to a contact model's fewest balls across)
    for d, _, s in fake.calls:
        if d == pytest.approx(27.5):
            assert s is st
        else:
            assert s.contact_cap == pytest.approx(1.5 * d / 27.5)
            assert s == BTSSettings(contact_cap=s.contact_cap, min_balls_across=0.0)
    for name in ("runs", "sizes", "fit"):
        assert (out / f"{name}.csv").is_file() and (out / f"{name}.md").is_file()
    assert pd.read_csv(out / "fit.csv")["method"].iloc[0] == "measured"
    assert len(list((out / "runs").glob("*.h5"))) == 18


def test_seeds_grow_until_the_mean_is_precise_enough(tmp_path, card, monkeypatch):
    fake = FakeDiscs(cv=0.06, invalid={302})
    r, _, _ = _stage(tmp_path, card, fake, monkeypatch, seeds=3, max_seeds=9,
                     target_se=0.02, middle=False)
    runs = r["runs"]
    for d, g in runs.groupby("diameter_mm"):
        v = g.loc[g["valid"], "bts_MPa"].to_numpy()
        n = len(g)
        assert 3 <= n <= 9
        # stopped at the first seed count whose SE met the target, or at max_seeds
        if n < 9:
            assert v.std(ddof=1) / math.sqrt(v.size) <= 0.02 * v.mean()
            w = g.iloc[:-1].loc[g.iloc[:-1]["valid"], "bts_MPa"].to_numpy()
            assert n == 3 or w.std(ddof=1) / math.sqrt(w.size) > 0.02 * w.mean()
    sizes = r["sizes"].set_index("diameter_mm")
    assert (sizes["seeds"] - sizes["valid"]).tolist() == [1, 1]  # seed 302 invalid at both


def test_a_card_without_a_brazilian_target_is_refused(tmp_path, card, monkeypatch):
    c = yaml.safe_load(card.read_text())
    c["targets"].pop("bts_MPa")
    card.write_text(yaml.safe_dump(c))
    with pytest.raises(BadInput, match="no Brazilian σt target"):
        _stage(tmp_path, card, FakeDiscs(), monkeypatch)
    assert not (tmp_path / "out" / "fit.csv").exists()


# ------------------------------------------------------------------ the command and the report
def _argv(files, card, lab="50"):
    return ["bts-size", "--card", str(card), "--lab-diameter", lab, "--run-dir",
            files.bts_size_dir("B1"), "--runs", files.bts_size_runs("B1"), "--sizes",
            files.bts_size_sizes("B1"), "--fit", files.bts_size_fit("B1"), "--seeds", "4",
            "--max-seeds", "4", "--scale", "0.4", "--bts-scale", "0.55",
            "--bts-contact-cap", "1.5", "--max-balls", "100000000", "--quiet"]


@pytest.mark.parametrize("lab, needle", [("0", "lab-diameter"), ("-50", "lab-diameter"),
                                         ("fifty", "lab-diameter"), ("nan", "lab-diameter")])
def test_a_bad_lab_diameter_is_one_line_exit_2_nothing_written(tmp_path, card, capsys, lab,
                                                                needle, monkeypatch):
    monkeypatch.setitem(measure.RUNNERS, "bts", FakeDiscs())
    files = StudyFiles(tmp_path / "results")
    rc = main(_argv(files, card, lab))
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and needle in err[0], err
    assert err[0].startswith("bpmcal bts-size: error: ") and f"={lab!r}" in err[0]
    assert not (tmp_path / "results").exists()


def test_the_command_and_the_reports_table(tmp_path, card, monkeypatch, capsys):
    monkeypatch.setitem(measure.RUNNERS, "bts", FakeDiscs())
    files = StudyFiles(tmp_path / "results")
    assert main(_argv(files, card)) == 0
    text = section(files, ["B1", "B2"])  # B2 has no size curve: left out
    assert text.startswith("\n## σt at the lab's disc size")
    assert "**B1** (lab discs 50 mm, the study's 27.5 mm)" in text and "B2" not in text
    sizes = pd.read_csv(files.bts_size_sizes("B1"))
    f = pd.read_csv(files.bts_size_fit("B1")).iloc[0]
    for _, r in sizes.iterrows():  # a row per size: D, seeds, valid discs, mean, SE
        assert (f"| {r['diameter_mm']:.1f} | {r['role']} | {r['balls_across']:.1f} | "
                f"{r['contact_cap']:.2f} | 4 | 4 (4 discs tested) | {r['mean_MPa']:.3f} | "
                f"{r['se_MPa']:.3f} |") in text
    assert f"k = {f['k']:.3f} ± {f['k_se']:.3f}" in text
    assert (f"σt at the lab's 50 mm: {f['sigma_lab_size_MPa']:.3f} ± "
            f"{f['sigma_lab_size_se']:.3f} MPa, measured on discs of the lab's size") in text
    assert f"error {f['err_pct']:+.1f} %" in text
    assert section(StudyFiles(tmp_path / "none"), ["B1"]) == ""


@pytest.mark.parametrize("raw", ["0", "-27.5", "fifty", "nan", "inf", "-0", "1e400", "2001"])
def test_the_lab_csv_refuses_a_bad_disc_diameter(raw):
    """The lab CSV's ``bts_diameter_mm`` (what the rule passes as --lab-diameter) is checked
    when the config is validated: one problem naming the specimen and the value."""
    from bpmcal.study.lab_data import lab_problems

    df = pd.DataFrame({"specimen": ["B1"], "ucs_MPa": ["60"], "E_GPa": ["13"], "nu": ["0.25"],
                       "bts_MPa": ["8"], "bts_diameter_mm": [raw]})
    msgs = lab_problems(df, "lab.csv")
    assert len(msgs) == 1 and "specimen B1 bts_diameter_mm=" in msgs[0], msgs
    assert "expected a positive number" in msgs[0] or "expected a value in (0, 2000]" in msgs[0]


def test_the_report_says_at_which_size_it_compared(tmp_path, card, monkeypatch):
    """The whole report of a study whose lab row gave a disc diameter: Table 5's σt note
    names the study's disc and points to the section, which has the table and the fit."""
    import copy

    from support.repo import REPO

    from bpmcal import params as P
    from bpmcal.io import study_files as L
    from bpmcal.report.build import build

    monkeypatch.setitem(measure.RUNNERS, "bts", FakeDiscs())
    files = StudyFiles(tmp_path / "results")
    assert main(_argv(files, card)) == 0
    pd.DataFrame({"sample_id": ["s000"], "status": ["ok"], "error": [""],
                  "wall_s": [1.0]}).to_csv(files.dataset, index=False)
    ks = (*P.TARGETS, P.BTS)
    t5 = {"status": "converged", "note": "", "tensile_note": "", "missed": "", "n_seeds": 3,
          **{f"{c}{k}{e}": 1.0 for k in ks for c in ("single_pass_", "closed_loop_")
             for e in ("", "_err_pct")}, **{f"lab_{k}": 2.0 for k in ks}}
    Path(files.table(L.TABLE5)).parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame([t5], index=pd.Index(["B1"], name="specimen")).to_csv(files.table(L.TABLE5))
    pd.DataFrame({"specimen": ["B1"]}).to_csv(files.table(L.CALIBRATION), index=False)
    cfg = copy.deepcopy(yaml.safe_load((REPO / "config" / "config.yaml").read_text()))
    cfg["study"].update(name="my_rock", reference="none")
    text = open(build(files.outdir, cfg)).read()
    f = pd.read_csv(files.bts_size_fit("B1")).iloc[0]
    assert (f"- **B1: σt** is compared here on the study's 27.5 mm disc; the lab's discs are "
            f"50 mm: σt there {f['sigma_lab_size_MPa']:.3f} ± {f['sigma_lab_size_se']:.3f} MPa "
            "(measured)") in text
    assert "## σt at the lab's disc size" in text and "**B1** (lab discs 50 mm" in text


def test_which_specimens_get_a_size_curve(tmp_path):
    """Only a lab row whose disc diameter differs from the study's disc (rule bts_size):
    none in the shipped lab CSVs, so no study's DAG gains the job unless its CSV asks."""
    from support.repo import REPO

    from bpmcal.study.lab_data import lab_disc_diameters, load_lab

    for f in sorted((REPO / "config" / "lab").glob("*.csv")):
        if "triaxial" not in f.name:
            assert lab_disc_diameters(load_lab(f), 27.5) == {}, f.name
    f = tmp_path / "lab.csv"
    f.write_text("specimen,ucs_MPa,E_GPa,nu,bts_MPa,bts_diameter_mm\n"
                 "A,60,13,0.25,8,50\nB,60,13,0.25,8,\nC,60,13,0.25,8,27.5\nD,60,13,0.25,,\n"
                 "E,60,13,0.25,8,20\n")
    assert lab_disc_diameters(load_lab(f), 27.5) == {"A": 50.0, "E": 20.0}


def test_a_lab_disc_too_large_is_refused_before_any_run(tmp_path, card, monkeypatch):
    """A 200 mm lab disc needs a cap of 10.9 mean ball diameters (over BTSSettings' 10) and,
    within the ball budget, is refused before the first disc runs."""
    fake = FakeDiscs()
    monkeypatch.setitem(measure.RUNNERS, "bts", fake)
    with pytest.raises(BadInput, match="--lab-diameter 200 mm: .*contact_cap=10.9"):
        bs.bts_size(card, lab_diameter_mm=200.0, disc=bts_geometry(scale=0.55),
                    settings=BTSSettings(contact_cap=1.5), run_dir=tmp_path / "runs",
                    runs_table=tmp_path / "r.csv", sizes_table=tmp_path / "s.csv",
                    fit_table=tmp_path / "f.csv", ctx=RunContext(max_balls=None))
    assert fake.calls == [] and not (tmp_path / "runs").exists()
    with pytest.raises(BudgetError, match="more than the budget of 20,000"):  # exit 2 too
        bs.bts_size(card, lab_diameter_mm=150.0, disc=bts_geometry(scale=0.55),
                    settings=BTSSettings(contact_cap=1.5), run_dir=tmp_path / "runs",
                    runs_table=tmp_path / "r.csv", sizes_table=tmp_path / "s.csv",
                    fit_table=tmp_path / "f.csv", ctx=RunContext(max_balls=20_000))
    assert fake.calls == [] and not (tmp_path / "runs").exists()


def test_a_flat_jointed_cards_study_disc_is_its_enlarged_disc(tmp_path, monkeypatch):
    """A flat-jointed card is tested on the study's disc enlarged to 25 balls across
    (``lab.brazilian.resolved_disc``: 27.5 mm -> 53.2 mm at Rmin 0.8 mm): that disc is the
    curve's reference and runs with the study's settings; the other sizes run at their
    size with the cap scaled from it."""
    f = tmp_path / "fj.yaml"
    f.write_text(yaml.safe_dump({
        "card_format": 1, "specimen": "LdB",
        "parameters": {"contact_model": "flatjoint", "rmin_mm": 0.8, "porosity": 0.3,
                       "fj_emod_GPa": 86.72, "fj_kratio": 1.7, "fj_ten_MPa": 11.63,
                       "fj_coh_MPa": 115.0, "fj_fa_deg": 30.0, "fj_fric": 0.6},
        "targets": {"ucs_MPa": 200.0, "bts_MPa": 9.0},
        "lab": {"ucs_MPa": 200.0, "bts_MPa": 9.0}, "target_se": {"bts_MPa": 0.3}}))
    fake = FakeDiscs()
    r, _, st = _stage(tmp_path, f, fake, monkeypatch)
    study = 25 * 0.8 * 2.66
    sizes = r["sizes"]
    # (the sizes in order: the lab's 50 mm disc is now the smaller)
    assert list(sizes["diameter_mm"]) == pytest.approx([50.0, math.sqrt(study * 50), study])
    assert list(sizes["role"]) == ["the lab's disc", "between", "the study's disc"]
    assert r["fit"]["reference_mm"].iloc[0] == pytest.approx(study)
    for d, _, s in fake.calls:
        if d == pytest.approx(study):
            assert s is st
        else:
            assert s.contact_cap == pytest.approx(1.5 * d / study)
            assert s.min_balls_across == 0.0
