"""Bad input, table-driven: every case ends the same way.

For each command line: exit code 2, exactly one line on stderr that starts with
``bpmcal <cmd>: error:`` and names the bad value, no traceback, and nothing written in
the output folder (nor anywhere else). Config values are checked the same way through the
study's validation (every problem by key, with the bad value). All in-process, no DEM run.
"""
import copy
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from support.paper import A1
from support.repo import REPO, SCHEMA

from bpmcal.cli import main
from bpmcal.io import h5
from bpmcal.study.config import ConfigError, validate_config

DESIGN_HEAD = "sample_id,rmin_mm,porosity,pb_emod_GPa,pb_kratio,pb_ten_MPa,pb_coh_MPa,pb_fa_deg,fric,seed\n"
ROW = "s000,0.8,0.34,10.4,3.5,27.7,19.7,35,0.35,7\n"
LAB_HEAD = "specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3\n"


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    """Input files, good and bad, shared by every case (read only)."""
    d = tmp_path_factory.mktemp("inputs")
    (d / "a1.yaml").write_text(yaml.safe_dump(A1))
    (d / "binary.yaml").write_bytes(bytes(range(128, 256)) * 3)
    (d / "garbled.yaml").write_text("rmin_mm: [0.8, 0.9\nporosity: 0.3\n")
    (d / "adir.yaml").mkdir()
    (d / "list.yaml").write_text("- 1\n- 2\n")
    (d / "empty.yaml").write_text("")
    (d / "bool.yaml").write_text(yaml.safe_dump({**A1, "fric": True}))
    (d / "string.yaml").write_text(yaml.safe_dump({**A1, "porosity": "0.3"}))
    (d / "fa90.yaml").write_text(yaml.safe_dump({**A1, "pb_fa_deg": 90.0}))
    (d / "nan.yaml").write_text(yaml.safe_dump(A1).replace("rmin_mm: 0.8", "rmin_mm: .nan"))
    (d / "badcard.yaml").write_text("card_format: 1\nspecimen: B1\nparameters: 5\n")
    (d / "design.csv").write_text(DESIGN_HEAD + ROW)
    (d / "plan.csv").write_text("sample_id,ratio,pb_ten_MPa,pb_coh_MPa,extrapolated\n"
                                "a100,1.0,20,20,False\n")
    (d / "design_missing_cols.csv").write_text("sample_id,rmin_mm\ns000,0.8\n")
    (d / "design_empty.csv").write_text("")
    (d / "design_header.csv").write_text(DESIGN_HEAD)
    (d / "design_negpor.csv").write_text(DESIGN_HEAD + ROW.replace(",0.34,", ",-0.34,"))
    (d / "design_nan.csv").write_text(DESIGN_HEAD + ROW.replace(",27.7,", ",,"))
    (d / "design_seed.csv").write_text(DESIGN_HEAD + ROW.replace(",7\n", ",-3\n"))
    (d / "design_escape.csv").write_text(DESIGN_HEAD + ROW.replace("s000", "../../x"))
    (d / "notahdf5.h5").write_text("this is not HDF5\n")
    with h5py.File(d / "foreign.h5", "w") as f:
        f.create_dataset("x", data=np.arange(3))
    h5.write_run(d / "good.h5",
                 h5.RunRecord(test="ucs",
                           inputs={"a": 1},
                           summary={"ucs_MPa": 50.0},
                           series={"step": np.arange(20000)}))
    raw = (d / "good.h5").read_bytes()
    (d / "truncated.h5").write_bytes(raw[: len(raw) // 2])
    h5.write_run(d / "failed.h5",
                 h5.RunRecord(test="ucs",
                           inputs={"a": 1},
                           status="failed",
                           error="GenesisError: did not settle"))
    (d / "runs").mkdir()
    (d / "lab_escape.csv").write_text(LAB_HEAD + "../../evil_card,60,13,0.25,\n")
    (d / "lab_upre.csv").write_text(LAB_HEAD + "B1,60,13,0.25,abc\n")
    (d / "lab_dup.csv").write_text(LAB_HEAD + "B1,60,13,0.25,\nB1,61,13,0.25,\n")
    (d / "lab_nu.csv").write_text(LAB_HEAD + "B1,60,13,0.6,\n")
    (d / "lab.csv").write_text(LAB_HEAD + "B1,60,13,0.25,0.1\n")
    (d / "dataset_cols.csv").write_text("sample_id,ucs_MPa\ns000,50\n")
    (d / "dataset_ok.csv").write_text(
        DESIGN_HEAD.strip() + ",status\n"
        + "".join(ROW.replace("s000", f"s00{i}").strip() + ",ok\n" for i in range(10)))
    (d / "card.yaml").write_text(yaml.safe_dump({"specimen": "B1", "parameters": A1,
                                                 "targets": {"ucs_MPa": 60.0}}))
    (d / "afile").write_text("x")
    return d


R = json.dumps({"rmin_mm": [0.6, 1.0], "porosity": [0.2, 0.36], "pb_emod_GPa": [10, 50],
                "pb_kratio": [1, 5], "pb_ten_MPa": [10, 50], "pb_coh_MPa": [10, 50],
                "pb_fa_deg": [15, 55], "fric": [0.15, 0.55]}, separators=(",", ":"))
UCS = "ucs --params {d}/a1.yaml --out {o}/r.h5"
CAL = ("calibrate --dataset {d}/design.csv --models {d}/card.yaml --lab {d}/lab.csv "
       "--cards {o}/cards/B1.yaml --ranges " + R + " --fixed {}")
SCREEN_OUT = (" --selected {o}/s.json --table3 {o}/t3.csv --figure {o}/f.png --importance-table "
              "{o}/i.csv --cv-table {o}/cv.csv --shadow-table {o}/sh.csv --summary {o}/s.txt")
REGRESS_OUT = (" --models {o}/m.json --equations {o}/eq.md --summaries {o}/s.txt --coefficients "
               "{o}/c.csv --candidates {o}/cand.csv --table4 {o}/t4.csv --fit-table {o}/fit.csv "
               "--figure {o}/f.png")

# (id, command line ({d}: inputs, {o}: output folder), text the message must contain)
CASES = [
    # --- ucs: parameter files
    ("params-binary", "ucs --params {d}/binary.yaml --out {o}/r.h5", "not a UTF-8 text file"),
    ("params-garbled", "ucs --params {d}/garbled.yaml --out {o}/r.h5", "not valid YAML at line"),
    ("params-directory", "ucs --params {d}/adir.yaml --out {o}/r.h5", "is a directory"),
    ("params-missing", "ucs --params {d}/nope.yaml --out {o}/r.h5", "nope.yaml: no such file"),
    ("params-list", "ucs --params {d}/list.yaml --out {o}/r.h5", "expected a YAML mapping"),
    ("params-empty", "ucs --params {d}/empty.yaml --out {o}/r.h5", "an empty file"),
    ("params-bool", "ucs --params {d}/bool.yaml --out {o}/r.h5", "fric=True"),
    ("params-string", "ucs --params {d}/string.yaml --out {o}/r.h5", "porosity='0.3'"),
    ("params-fa90", "ucs --params {d}/fa90.yaml --out {o}/r.h5", "pb_fa_deg=90 deg"),
    ("params-nan", "ucs --params {d}/nan.yaml --out {o}/r.h5", "rmin_mm=nan"),
    ("params-card-not-mapping", "ucs --params {d}/badcard.yaml --out {o}/r.h5",
     "'parameters' is not a mapping"),
    # --- ucs: --set and numbers
    ("set-tiny-rmin", UCS + " --set rmin_mm=1e-9", "rmin_mm=1e-09"),
    ("set-small-rmin", UCS + " --set rmin_mm=0.01", "budget of 2,000,000"),
    ("mem-budget", UCS + " --scale 0.3 --mem-budget-mb 50", "budget of 50 MB"),
    ("max-balls", UCS + " --scale 0.3 --max-balls 10", "more than the budget of 10"),
    ("set-nan", UCS + " --set fric=nan", "fric=nan"),
    ("set-unknown", UCS + " --set bogus=1", "bogus"),
    ("set-no-equals", UCS + " --set fric", "--set 'fric': expected NAME=VALUE"),
    ("set-bool", UCS + " --set fric=true", "fric='true'"),
    ("threads-0", UCS + " --threads 0", "threads='0'"),
    ("threads-neg", UCS + " --threads -1", "threads='-1'"),
    ("threads-text", UCS + " --threads two", "threads='two'"),
    ("seed-neg", UCS + " --seed -1", "seed='-1'"),
    ("seed-huge", UCS + " --seed 4294967296", "seed='4294967296'"),
    ("platen-fric-nan", UCS + " --platen-fric nan", "platen-fric='nan'"),
    ("platen-fric-neg", UCS + " --platen-fric -1", "platen-fric='-1'"),
    ("end-cap-neg", UCS + " --end-cap -1", "end-cap='-1'"),
    ("end-cap-factor-0.5", UCS + " --end-cap 1 --end-cap-factor 0.5", "end-cap-factor='0.5'"),
    ("install-gap-neg", UCS + " --install-gap -1", "install-gap='-1'"),
    ("damping-1", UCS + " --damping 1", "damping='1'"),
    ("scale-0", UCS + " --scale 0", "scale='0'"),
    ("scale-inf", UCS + " --scale inf", "scale='inf'"),
    ("stop-drop", UCS + " --stop-drop 1.5", "stop-drop='1.5'"),
    ("max-balls-0", UCS + " --max-balls 0", "max-balls='0'"),
    ("genesis-steps", UCS + " --genesis-max-steps 10", "genesis-max-steps='10'"),
    # --- ucs: design rows
    ("design-and-params", "ucs --params {d}/a1.yaml --design {d}/design.csv --sample s000 "
     "--out {o}/r.h5", "--design: not allowed with argument --params"),
    ("design-no-sample", "ucs --design {d}/design.csv --out {o}/r.h5", "--design needs --sample"),
    ("sample-no-design", UCS + " --sample s000", "--sample s000: needs --design"),
    ("design-missing-cols", "ucs --design {d}/design_missing_cols.csv --sample s000 "
     "--out {o}/r.h5", "missing column(s) ['porosity'"),
    ("design-empty", "ucs --design {d}/design_empty.csv --sample s000 --out {o}/r.h5",
     "design_empty.csv: empty file"),
    ("design-header-only", "ucs --design {d}/design_header.csv --sample s000 --out {o}/r.h5",
     "0 data row(s)"),
    ("design-unknown-sample", "ucs --design {d}/design.csv --sample s999 --out {o}/r.h5",
     "--sample 's999': not in"),
    ("design-neg-porosity", "ucs --design {d}/design_negpor.csv --sample s000 --out {o}/r.h5",
     "porosity=-0.34"),
    ("design-nan", "ucs --design {d}/design_nan.csv --sample s000 --out {o}/r.h5",
     "pb_ten_MPa=nan"),
    ("design-seed", "ucs --design {d}/design_seed.csv --sample s000 --out {o}/r.h5", "seed=-3"),
    # --- ucs: the output
    ("out-directory", "ucs --params {d}/a1.yaml --out {d}/runs", "is a directory"),
    ("out-suffix", "ucs --params {d}/a1.yaml --out {o}/r.txt", "ending in .h5 or .hdf5"),
    ("out-parent-file", "ucs --params {d}/a1.yaml --out {d}/afile/r.h5", "is not a directory"),
    ("out-uncreatable", "ucs --params {d}/a1.yaml --out /proc/bpmcal-x/r.h5",
     "cannot create directory"),
    ("out-empty", "ucs --params {d}/a1.yaml --out=", "expected a file name"),
    # --- summary, vtk
    ("summary-not-hdf5", "summary {d}/notahdf5.h5", "not a readable HDF5 file"),
    ("summary-missing", "summary {d}/nope.h5", "nope.h5: no such file"),
    ("summary-foreign", "summary {d}/foreign.h5", "not a bpmcal run file"),
    ("summary-truncated", "summary {d}/truncated.h5", "truncated.h5: not a readable HDF5"),
    ("summary-directory", "summary {d}/runs", "is a directory"),
    ("vtk-foreign", "vtk {d}/foreign.h5 --out {o}/vtk", "not a bpmcal run file"),
    ("vtk-truncated", "vtk {d}/truncated.h5 --out {o}/vtk", "truncated.h5"),
    ("vtk-failure-record", "vtk {d}/failed.h5 --out {o}/vtk", "a failure record"),
    # --- gather
    ("gather-design-missing", "gather --design {d}/nope.csv --runs {d}/runs/s000.h5 "
     "--out {o}/ds.csv", "nope.csv: no such file"),
    ("gather-runs-dir", "gather --design {d}/design.csv --runs {d}/runs --out {o}/ds.csv",
     "--runs {d}/runs: is a directory, expected a run file"),
    ("gather-runs-not-h5", "gather --design {d}/design.csv --runs {d}/afile --out {o}/ds.csv",
     "afile: expected a run file ending in .h5"),
    ("gather-runs-stranger", "gather --design {d}/design.csv --runs {d}/runs/s999.h5 "
     "--out {o}/ds.csv", "run file(s) ['s999'] match no id"),
    ("gather-runs-twice", "gather --design {d}/design.csv --runs {d}/runs/s000.h5 "
     "{d}/runs/s000.h5 --out {o}/ds.csv", "s000 given twice"),
    ("gather-sample-escape", "gather --design {d}/design_escape.csv --runs {d}/runs/s000.h5 "
     "--out {o}/ds.csv", "'../../x'"),
    ("gather-out-suffix", "gather --design {d}/design.csv --runs {d}/runs/s000.h5 "
     "--out {o}/ds.h5", "ending in .csv"),
    # --- design
    ("design-ranges-json", "design --ranges {rmin --n 8 --seed 1 --out {o}/s.csv",
     "--ranges: not valid JSON"),
    ("design-ranges-list", "design --ranges [1,2] --n 8 --seed 1 --out {o}/s.csv",
     "expected a JSON object"),
    ("design-ranges-nan", "design --ranges " + R.replace("[0.15,0.55]", "[NaN,0.55]")
     + " --n 8 --seed 1 --out {o}/s.csv", "ranges.fric[0]=nan"),
    ("design-ranges-bool", "design --ranges " + R.replace("[0.15,0.55]", "[true,0.55]")
     + " --n 8 --seed 1 --out {o}/s.csv", "ranges.fric[0]=True"),
    ("design-ranges-reversed", "design --ranges " + R.replace("[10,50]", "[50,10]", 1)
     + " --n 8 --seed 1 --out {o}/s.csv", "ranges.pb_emod_GPa=[50, 10]"),
    ("design-n-1", "design --ranges " + R + " --n 1 --seed 1 --out {o}/s.csv", "n='1'"),
    ("design-unknown", "design --ranges {\"rmin\":[1,2]} --n 8 --seed 1 --out {o}/s.csv",
     "unknown parameter(s) ['rmin']"),
    # --- calibrate
    ("calibrate-lab-escape", CAL.replace("lab.csv", "lab_escape.csv"), "'../../evil_card'"),
    ("calibrate-lab-upre", CAL.replace("lab.csv", "lab_upre.csv"), "u_pre_MJm3='abc'"),
    ("calibrate-lab-dup", CAL.replace("lab.csv", "lab_dup.csv"), "duplicate specimen names"),
    ("calibrate-lab-nu", CAL.replace("lab.csv", "lab_nu.csv"), "nu='0.6'"),
    ("calibrate-fixed-json", CAL.replace("--fixed {}", "--fixed {oops"), "--fixed: not valid JSON"),
    ("calibrate-fixed-bool", CAL.replace("--fixed {}", '--fixed {"fric":true}'), "fric=True"),
    ("calibrate-n-boot-1", CAL + " --n-boot 1", "--n-boot 1"),
    ("calibrate-free-unknown", CAL + " --free pb_emod_GPa,bogus", "['bogus']"),
    ("calibrate-ratio-nan", CAL + " --ratio nan", "ratio='nan'"),
    ("calibrate-dataset-cols", CAL.replace("design.csv", "dataset_cols.csv"),
     "missing column(s)"),
    # --- sweep-plan, impact, report, screen, regress
    ("sweep-reversed", "sweep-plan --card {d}/card.yaml --models {d}/card.yaml --ratios 2,1,0.1 "
     "--out {o}/plan.csv", "start <= stop"),
    ("sweep-text", "sweep-plan --card {d}/card.yaml --models {d}/card.yaml --ratios a,b,c "
     "--out {o}/plan.csv", "--ratios 'a,b,c'"),
    ("sweep-zero-step", "sweep-plan --card {d}/card.yaml --models {d}/card.yaml --ratios 1,2,0 "
     "--out {o}/plan.csv", "step > 0"),
    ("impact-dp-ratio", "impact --card {d}/card.yaml --out {o}/i.h5 --dp-ratio 2",
     "dp-ratio='2'"),
    ("impact-anvil-nan", "impact --card {d}/card.yaml --out {o}/i.h5 --anvil-fric nan",
     "anvil-fric='nan'"),
    ("impact-velocity-neg", "impact --card {d}/card.yaml --out {o}/i.h5 --velocity -6",
     "velocity='-6'"),
    ("impact-card-missing", "impact --card {d}/nope.yaml --out {o}/i.h5", "no such file"),
    ("report-no-config", "report --outdir {d}", "exactly one of --config"),
    ("report-config-json", "report --outdir {d} --config-json {x", "--config-json: not valid JSON"),
    ("screen-dataset-cols", "screen --dataset {d}/dataset_cols.csv" + SCREEN_OUT,
     "missing column(s)"),
    ("screen-threshold-nan", "screen --dataset {d}/design.csv --threshold nan" + SCREEN_OUT,
     "threshold='nan'"),
    ("screen-out-suffix", "screen --dataset {d}/dataset_ok.csv"
     + SCREEN_OUT.replace("t3.csv", "t3.md"),
     "--table3 {o}/t3.md: expected a file name ending in .csv"),
    ("regress-alpha-0", "regress --dataset {d}/design.csv --selected {d}/card.yaml --alpha-in 0"
     + REGRESS_OUT, "alpha-in='0'"),
    ("calibrate-cards-mismatch", CAL.replace("B1.yaml", "B2.yaml"),
     "expected one card per lab specimen, named <specimen>.yaml: ['B1']"),
    ("vtables-runs-count", "verification-tables --cards {d}/card.yaml --runs {d}/good.h5 "
     "{d}/good.h5 --lab {d}/lab.csv --table5 {o}/t5.csv --table6 {o}/t6.csv --figure {o}/f.png",
     "2 run file(s) for 1 card(s)"),
    ("sweep-analyse-stranger", "sweep-analyse --plan {d}/plan.csv --runs {d}/runs/a999.h5 "
     "--table {o}/t.csv --chosen {o}/c.json --fig4 {o}/4.png --fig5 {o}/5.png --vtk {o}/vtk",
     "run file(s) ['a999'] match no id"),
]


def _argv(template, d, o):
    return template.replace("{d}", str(d)).replace("{o}", str(o)).split(" ")


def _files(root: Path) -> set:
    return {p for p in root.rglob("*")} if root.exists() else set()


@pytest.mark.parametrize("case, template, needle", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_nothing_written(d, tmp_path, capsys, case, template,
                                                      needle):
    o = tmp_path / "out"
    before = _files(d)
    rc = main(_argv(template, d, o))
    err = capsys.readouterr().err
    cmd = template.split(" ")[0]
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"bpmcal {cmd}: error: "), err
    assert needle.replace("{d}", str(d)).replace("{o}", str(o)) in lines[0], err
    assert "Traceback" not in err
    assert not o.exists() or not any(o.rglob("*")), sorted(o.rglob("*"))
    assert _files(d) == before  # nothing written beside the inputs either
    assert set(tmp_path.iterdir()) <= {o}


def test_the_table_has_at_least_40_cases():
    assert len(CASES) >= 40 and len({c[0] for c in CASES}) == len(CASES)


def test_path_escape_in_lab_writes_nothing_outside(d, tmp_path, capsys):
    """The issue's attack: specimen ../../evil_card made calibrate write outside --out."""
    o = tmp_path / "a" / "b"
    assert main(_argv(CAL.replace("lab.csv", "lab_escape.csv"), d, o)) == 2
    assert not list(tmp_path.rglob("evil_card*"))
    assert not list(d.parent.rglob("evil_card*"))


# ------------------------------------------------------------------------ config values
def _cfg(**patch):
    base = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    cfg = copy.deepcopy(base)
    for dotted, v in patch.items():
        keys = dotted.split("__")
        node = cfg
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = v
    return cfg


def _lab(tmp_path, rows):
    f = tmp_path / "lab.csv"
    f.write_text(LAB_HEAD + rows)
    return str(f)


CONFIG_CASES = [
    ("outdir-semicolon", {"outdir": "results/a;touch X;b"}, "outdir: 'results/a;touch X;b'"),
    ("outdir-dollar", {"outdir": "results/$(touch X)"}, "character(s) '$()'"),
    ("outdir-backtick", {"outdir": "results/`touch X`"}, "'`'"),
    ("outdir-quote", {"outdir": "results/O'Brien"}, "\"'\""),
    ("outdir-newline", {"outdir": "results/a\nb"}, "outdir: 'results/a\\nb'"),
    ("outdir-dash", {"outdir": "-rf"}, "must not start with '-'"),
    ("outdir-braces", {"outdir": "results/{sample}"}, "'{}'"),
    ("lab-path-quote", {"lab__csv": "config/lab/x'y.csv"}, "lab.csv: \"config/lab/x'y.csv\""),
    ("ranges-bool", {"ranges__fric": [True, 0.5]}, "ranges.fric[0]: True is not of type"),
    ("ranges-nan", {"ranges__porosity": [float("nan"), 0.3]}, "ranges.porosity[0]: nan"),
    ("ranges-inf", {"ranges__pb_ten_MPa": [10.0, float("inf")]}, "ranges.pb_ten_MPa[1]"),
    ("ranges-reversed", {"ranges__pb_coh_MPa": [50.0, 10.0]}, "low 50 exceeds high 10"),
    ("ratios-reversed", {"ratio_sweep__ratios": [2.0, 0.5, 0.1]}, "start 2 exceeds stop 0.5"),
    ("ratios-fine", {"ratio_sweep__ratios": [0.5, 2.0, 0.001]}, "more than 200"),
    ("ratios-shared-id", {"ratio_sweep__ratios": [0.5, 0.6, 0.004]}, "finer than 0.01"),
    ("fixed-bool", {"calibration__fixed__fric": True}, "calibration.fixed.fric: True"),
    ("n-samples-bool", {"study__n_samples": True}, "study.n_samples: True"),
    ("scale-nan", {"specimen__scale": float("nan")}, "specimen.scale: nan"),
    ("end-cap-neg", {"compression__end_cap": -1.0}, "compression.end_cap: -1.0"),
    ("max-balls", {"resources__max_balls": 100}, "more than the budget of 100"),
    ("mem-budget", {"resources__dem_mem_mb": 100, "ranges__rmin_mm": [0.6, 1.0],
                    "specimen__scale": 1.0}, "budget of 100 MB"),
]


@pytest.mark.parametrize("case, patch, needle", CONFIG_CASES, ids=[c[0] for c in CONFIG_CASES])
def test_bad_config_value_is_named(case, patch, needle):
    with pytest.raises(ConfigError) as e:
        validate_config(_cfg(**patch), SCHEMA, base_dir=REPO)
    msg = str(e.value)
    assert needle in msg, msg
    problems = msg.splitlines()[1:]
    key = problems[0].split(":")[0]
    assert all(p.split(":")[0] == key for p in problems), msg  # one key, one line each


@pytest.mark.parametrize("rows, needle", [
    ("../../evil_card,60,13,0.25,\n", "specimen '../../evil_card'"),
    ("B1,60,13,0.25,abc\n", "B1 u_pre_MJm3='abc'"),
    ("B 1,60,13,0.25,\n", "specimen 'B 1'"),
    ("B1,60,13,nan,\n", "nu='nan'"),
    ("", "has no specimen rows"),
])
def test_bad_lab_table_is_named_at_validation(tmp_path, rows, needle):
    cfg = _cfg(lab__csv=_lab(tmp_path, rows))
    with pytest.raises(ConfigError, match="lab.csv") as e:
        validate_config(cfg, SCHEMA, base_dir=REPO)
    assert needle in str(e.value)


def test_allowed_outdir_and_title(tmp_path):
    """Spaces in outdir and any text in the title are fine (they are shell-quoted)."""
    cfg = _cfg(outdir="results/my study, 2026", study__name="O'Brien sandstone; $(x) `y`")
    validate_config(cfg, SCHEMA, base_dir=REPO)
