"""bpmcal.report: the report builds from a minimal set of a study's files and says what is
missing; each file added brings its section; the paper's values appear only for the
paper's study; bad input is one clear error. (The whole report of a finished study:
tests/workflow/test_smoke.py.)"""
import copy
import json
import math
from pathlib import Path

import pandas as pd
import pytest
import yaml
from support.repo import REPO

from bpmcal import params as P
from bpmcal.io import study_files as L
from bpmcal.io.checks import BadInput
from bpmcal.report.build import build, report
from bpmcal.study import paper

CONFIG = yaml.safe_load((REPO / "config" / "config.yaml").read_text())


def _config(**study):
    cfg = copy.deepcopy(CONFIG)
    cfg["study"].update(study)
    return cfg


def _dataset(lay):
    """Four samples, one failed: what gather writes, cut to the columns the report reads."""
    pd.DataFrame({"sample_id": ["s000", "s001", "s002", "s003"],
                  "status": ["ok", "ok", "failed", "ok"],
                  "error": ["", "", "genesis did not settle", ""],
                  "wall_s": [10.0, 12.0, math.nan, 14.0]}).to_csv(lay.dataset, index=False)


def _table3(lay):
    """Table 3 of the paper's shares plus one percentage point each (ours)."""
    t3 = pd.DataFrame({r: {p: paper.TABLE3[p][r] + 1.0 for p in P.PARAM_NAMES}
                       for r in P.TARGETS})
    Path(lay.table(L.TABLE3)).parent.mkdir(parents=True, exist_ok=True)
    t3.to_csv(lay.table(L.TABLE3))
    return t3


@pytest.fixture
def study(tmp_path):
    lay = L.StudyFiles(tmp_path / "results")
    (tmp_path / "results").mkdir()
    _dataset(lay)
    return lay


def test_a_study_with_only_its_dataset_gets_a_report_that_names_what_is_missing(study):
    index = build(study.outdir, _config())
    text = open(index).read()
    assert text.startswith("# green_sandstone: the paper, regenerated\n")
    assert "- Dataset: 3 of 4 samples ok" in text
    assert "  - s002: failed: genesis did not settle" in text  # the failed sample, named
    assert "- DEM time per sample: median 12.0 s (range 10.0-14.0 s)" in text
    missing = next(ln for ln in text.splitlines() if ln.startswith("**Not in this study yet**"))
    for f in (L.TABLE3, L.TABLE5, L.CALIBRATION):  # every table the report shows, by path
        assert f"`tables/{f}.csv`" in missing
    assert f"`figures/{L.FIG6}.png`" in missing and "`dataset.csv`" not in missing
    assert "## Table 3" not in text and "## Settings" in text
    assert not Path(study.comparison).exists()


def test_a_file_added_brings_its_section_and_the_comparison_with_the_paper(study):
    t3 = _table3(study)
    text = open(build(study.outdir, _config())).read()
    assert "## Table 3: XGBoost screening (ours, paper in brackets, % of gain)" in text
    p = P.PARAM_NAMES[0]
    assert f"{t3.loc[p, 'ucs_MPa']:.1f} ({paper.TABLE3[p]['ucs_MPa']:.1f})" in text
    missing = next(ln for ln in text.splitlines() if ln.startswith("**Not in this study yet**"))
    assert L.TABLE3 not in missing
    comp = pd.read_csv(study.comparison)
    rows = comp[comp["section"] == "Table 3"]
    assert len(rows) == len(P.PARAM_NAMES) * len(P.TARGETS)
    assert rows["difference"].to_numpy() == pytest.approx(1.0)  # ours = the paper's + 1
    assert Path(study.report_copy(study.table(L.TABLE3))).exists()  # copied into the report


def test_another_rocks_report_leaves_the_paper_out(study):
    _table3(study)
    text = open(build(study.outdir, _config(name="my_rock", reference="none"))).read()
    assert text.startswith("# my_rock: calibration report\n")
    assert "## Table 3: XGBoost screening (% of gain)" in text
    assert paper.REFERENCE not in text and "Notes on the paper" not in text
    assert "(ours, paper in brackets" not in text
    assert not Path(study.comparison).exists()


def test_the_missing_list_names_exactly_the_files_that_are_not_there(study):
    """The figures present (the report only copies them): listed under Figures, no longer
    named missing; the tables still absent still named, and nothing of another
    configuration (the sweep off: no Fig. 4, 5 or sweep table)."""
    cfg = _config()
    cfg["ratio_sweep"]["enabled"] = False
    for f in study.report_figures(sweep=False, triaxial=True):  # the config's triaxial stage
        Path(f).parent.mkdir(parents=True, exist_ok=True)
        Path(f).write_bytes(b"\x89PNG")
    text = open(build(study.outdir, cfg)).read()
    missing = next(ln for ln in text.splitlines() if ln.startswith("**Not in this study yet**"))
    named = set(missing.split("`")[1::2])
    tables = {Path(f).relative_to(study.outdir).as_posix()
              for f in study.report_tables(sweep=False, triaxial=True, fresh_seeds=True)}
    assert named == tables
    for stem in (L.FIG_SCREENING, L.FIG6, L.FIG7, L.FIG_ENVELOPES):
        assert f"![{stem}](figures/{stem}.png)" in text
    assert L.RATIO_SWEEP not in missing and L.FIG4 not in missing


@pytest.mark.parametrize("kw, needle", [
    ({"config_json": "{}"}, "not a study config (no 'study' section)"),
    ({"config_json": "[1,"}, "--config-json"),
    ({}, "exactly one of --config FILE and --config-json TEXT"),
])
def test_bad_input_is_one_clear_error_and_writes_nothing(study, kw, needle):
    with pytest.raises(BadInput, match=needle.replace("(", r"\(").replace(")", r"\)")
                       .replace("[", r"\[")):
        report(study.outdir, **kw)
    assert not Path(study.report_dir).exists()


def test_an_outdir_that_is_not_a_folder_is_named(tmp_path):
    with pytest.raises(BadInput, match=r"--outdir .*nowhere: not a directory"):
        report(tmp_path / "nowhere", config_json=json.dumps(CONFIG))


def test_the_direct_over_brazilian_ratio_is_of_the_samples_with_both_valid():
    from bpmcal.report.build import _direct_over_brazilian

    ds = pd.DataFrame({"bts_MPa": [10.0, 8.0, math.nan, 5.0],
                       "dtt_MPa": [8.0, 6.0, 7.0, math.nan]})
    line = _direct_over_brazilian(ds)
    assert "median 0.78" in line and "0.75-0.80" in line and "2 samples" in line
    assert _direct_over_brazilian(ds[["bts_MPa"]]) == ""
    none = _direct_over_brazilian(pd.DataFrame({"bts_MPa": [math.nan], "dtt_MPa": [7.0]}))
    assert "no sample has both" in none


def test_the_disc_note_counts_the_discs_enlarged_to_the_fewest_balls_across():
    """27.5 mm discs: a flat-jointed study's samples with Rmin 0.6 mm (17.2 mean ball
    diameters across) and 0.4 mm (25.8): the first enlarged to 25, the second not; a
    parallel-bonded study's, none (bts.min_balls_across null)."""
    from bpmcal.report.build import _disc_note

    ds = pd.DataFrame({"rmin_mm": [0.6, 0.4], "bts_balls_across": [17.2, 25.8]})
    cfg = {"bts": {"scale": 0.55, "min_balls_across": None}, "specimen": {"scale": 0.4}}
    fj = _disc_note({**cfg, "contact_model": "flatjoint"}, ds)
    assert "1 of 2 samples' discs enlarged to 25 mean ball diameters" in fj
    assert "27.5 × 13.75 mm" in fj
    assert "enlarged" not in _disc_note(cfg, ds)
    pb20 = _disc_note({**cfg, "bts": {"scale": 0.55, "min_balls_across": 20.0}}, ds)
    assert "1 of 2 samples' discs enlarged to 20" in pb20
