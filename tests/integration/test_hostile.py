"""Hostile and unlucky inputs (issue 55): every case of ``support.hostile.CASES`` ends
cleanly. A clean ending: the expected exit code (2 for the user's mistake, 4 for the
system, 3 or 0 with ``--failed-ok`` for a run that measured nothing), one line on stderr
that names the bad value, no traceback, no file left under its final name but what the
case writes on purpose, nothing written beside the inputs, and no hang.

Commands without a DEM run are run in this process (milliseconds each); those that need a
fresh process (a file-size limit, a closed stderr, SIGTERM, a mounted full disk) or run a
small DEM test run as ``bpmcal`` subprocesses. ``benchmarks/hostile_inputs.py`` runs the
same cases against any checkout and counts them by class.
"""
import os
import shutil
import subprocess
import sys
import time

import pytest
from support.hostile import CASES, SETUPS, Ending, files_beside, judge, make_inputs, run
from support.repo import REPO, SCHEMA

from bpmcal.cli import main
from bpmcal.study.config import ConfigError, validate_config

SRC = REPO / "src"


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    return make_inputs(tmp_path_factory.mktemp("hostile") / "in")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A 64 kB tmpfs, mounted for the full-disk case (root only; skipped otherwise)."""
    m = tmp_path_factory.mktemp("tiny")
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a small tmpfs needs root")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(m)],
                       capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {r.stderr.decode().strip()}")
    yield m
    subprocess.run(["umount", str(m)], capture_output=True)


def _in_process(case, d, o, cache, monkeypatch, capsys) -> Ending:
    monkeypatch.chdir(d)
    t0, c0 = time.perf_counter(), time.process_time()
    if case.config is not None:
        from support.hostile import merged_config

        cfg = merged_config(REPO, case.config, d)
        try:
            validate_config(cfg, SCHEMA, base_dir=REPO, note=lambda line: None)
            code, err = 0, ""
        except ConfigError as e:
            code, err = 2, " ".join(str(e).split()) + "\n"
        return Ending(code, "", err, time.perf_counter() - t0, time.process_time() - c0)
    argv = (case.argv.replace("{d}", str(d)).replace("{o}", str(o))
            .replace("{cache}", str(cache)).replace("CONFIG/", f"{REPO}/config/").split(" "))
    code = main(argv)
    c = capsys.readouterr()
    return Ending(code, c.out, c.err, time.perf_counter() - t0, time.process_time() - c0)


def _fresh(case) -> bool:
    """A case run as a subprocess: it needs a fresh process, runs a DEM test, or could
    hang or fill the memory if it regressed (a hang case: bounded by a timeout and an
    address-space limit)."""
    return (case.dem or case.fsize is not None or case.shell or case.sigterm_after
            or case.root or case.cls == "hang")


def _params():
    for c in CASES:
        marks = [pytest.mark.slow] if c.slow else []
        yield pytest.param(c, id=c.id, marks=marks)


@pytest.mark.parametrize("case", _params())
def test_a_hostile_case_ends_cleanly(case, d, tmp_path, packing_cache, monkeypatch, capsys,
                                     request):
    o = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    if case.setup:
        SETUPS[case.setup](o, env)
    tiny = request.getfixturevalue("tiny") if case.root else None
    before = files_beside(d)
    if _fresh(case):
        ending = run(case, d, o, packing_cache, repo=REPO, env=env, tiny=tiny)
    else:
        ending = _in_process(case, d, o, packing_cache, monkeypatch, capsys)
    after = files_beside(d)
    problems = judge(case, ending, o, before, after)
    if tiny is not None:
        left = list(tiny.iterdir())
        problems += [f"left on the full disk: {left}"] if left else []
    assert not problems, f"{problems}\nstderr: {ending.stderr[-2000:]}"


def test_every_class_has_cases_and_the_table_names_are_unique():
    from support.hostile import CLASSES

    assert {c.cls for c in CASES} == set(CLASSES)
    assert len({c.id for c in CASES}) == len(CASES) >= 60


# ------------------------------------------------------------------------ the system
@pytest.mark.parametrize("exc, needle", [
    (MemoryError(), "out of memory (system error)"),
    ("worker", "died (killed, or out of memory"),
    (OSError(13, "Permission denied", "/x/r.h5"), "/x/r.h5: permission denied (system error)"),
    (OSError(27, "File too large", "/x/r.h5"), "file too large"),
])
def test_a_system_failure_is_exit_4_with_what_to_do(monkeypatch, capsys, exc, needle):
    import bpmcal.io.h5 as h5mod
    from bpmcal.stages.pool import WorkerLost

    if exc == "worker":
        exc = WorkerLost("the worker process running run [3] died (killed, or out of memory:"
                         " each of the 2 runs at once needs its own memory)")

    def fail(path):
        raise exc
    monkeypatch.setattr(h5mod, "read_summary", fail)
    assert main(["summary", "x.h5"]) == 4
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and "bug" not in err[0], err


def test_sigterm_in_process_is_handled_like_ctrl_c(monkeypatch, capsys, tmp_path):
    """SIGTERM raised in a command: one line, exit 4, the temporary file removed."""
    import signal

    import bpmcal.io.h5 as h5mod

    out = tmp_path / "r.h5"

    def slow(path):
        from bpmcal.io.atomic import atomic_path

        with atomic_path(out) as t:
            t.write_bytes(b"partial")
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
    monkeypatch.setattr(h5mod, "read_summary", slow)
    assert main(["summary", "x.h5"]) == 4
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "terminated (SIGTERM" in err[0], err
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is not None  # the old handler is back


def test_a_full_disk_leaves_no_temporary_and_no_crash(tmp_path):
    """A run file written under a file-size limit: exit 4 and one line, no segfault at
    exit (h5py's errors on a failed write used to crash the interpreter)."""
    import resource

    code = ("import numpy as np\n"
            "from bpmcal.io import h5\n"
            f"h5.write_run({str(tmp_path / 'r.h5')!r}, h5.RunRecord(test='ucs', inputs={{}}, "
            "series={'x': np.random.default_rng(0).random(200000)}))\n")

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (50_000, 50_000))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       preexec_fn=limit, env={**os.environ, "PYTHONPATH": str(SRC)})
    assert p.returncode == 1 and "OSError: [Errno 27] File too large" in p.stderr, p.stderr
    assert "r.h5" in p.stderr.splitlines()[-1] and ".tmp" not in p.stderr.splitlines()[-1]
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------ small pieces
def test_shown_cuts_and_summarises():
    from bpmcal.io.safe_names import clip, printable, shown

    assert shown("x" * 1000).endswith("more characters)") and len(shown("x" * 1000)) < 100
    a = [1] * 9
    for _ in range(8):
        a = [a] * 9  # 9^9 values behind 9 references each
    assert shown(a) == "<a list of 9 item(s)>"
    assert shown(10 ** 5000) == "<a int>"
    assert clip("abc") == "abc"
    assert printable("ok\x1b[2J\nstatus ok\u202e") == "ok\\x1b[2J\\nstatus ok\\u202e"


@pytest.mark.parametrize("path, ok", [
    ("results", True), ("results/my rock", True), ("/tmp/me/study", True),
    ("/", False), ("//", False), (".", False), ("./", False), ("../x", False),
    ("a/../../x", False), ("a/../b", True),
])
def test_outdir_stays_in_the_working_folder_unless_absolute(path, ok):
    from bpmcal.io.safe_names import outdir_problem

    assert (outdir_problem(path) is None) == ok


@pytest.mark.parametrize("rmin, expect", [(1e-100, float("inf")), (1e300, 0.0),
                                          (1e-31, 1.3138274912972624e97)])
def test_the_ball_count_of_extreme_radii_is_a_number(rmin, expect):
    from bpmcal.lab.budget import estimate_balls

    assert estimate_balls(rmin, 0.3) == pytest.approx(expect, rel=1e-12)
    # the two formulas meet where they switch
    assert estimate_balls(1e-30 * 1.0000001, 0.3) == pytest.approx(
        estimate_balls(1e-30 / 1.0000001, 0.3), rel=1e-5)


def test_yaml_bounds(tmp_path):
    from bpmcal.io.checks import BadInput, read_yaml

    f = tmp_path / "x.yaml"
    f.write_text("a: &a [1, 2]\nb: [*a, *a]\n")  # a few aliases are fine
    assert read_yaml(f, "--x") == {"a": [1, 2], "b": [[1, 2], [1, 2]]}
    f.write_text("a: " + "[" * 65 + "]" * 65 + "\n")
    with pytest.raises(BadInput, match="nested deeper than 64"):
        read_yaml(f, "--x")
    f.write_text("a: &a [0]\n" + "".join(f"b{i}: *a\n" for i in range(1001)))
    with pytest.raises(BadInput, match="more than 1000 aliases"):
        read_yaml(f, "--x")


def test_json_bounds():
    from bpmcal.io.checks import BadInput, parse_json

    deep = "[" * 70
    assert parse_json('{"a": "' + deep + '"}', "--x") == {"a": deep}  # strings do not count
    with pytest.raises(BadInput, match="nested 65 levels deep"):
        parse_json("[" * 65 + "]" * 65, "--x")
    with pytest.raises(BadInput, match="more than 10"):
        parse_json("[1, 2, 3, 4, 5]", "--x", max_chars=10)


def test_an_input_must_be_a_regular_file_of_bounded_size(tmp_path):
    from bpmcal.io.checks import BadInput, in_file

    f = tmp_path / "big"
    with open(f, "wb") as fh:
        fh.truncate(2000)
    assert in_file(f, "--x", max_bytes=2000) == f
    with pytest.raises(BadInput, match="2,000 bytes, larger than the 1,999"):
        in_file(f, "--x", max_bytes=1999)
    os.mkfifo(tmp_path / "p")
    with pytest.raises(BadInput, match="not a regular file"):
        in_file(tmp_path / "p", "--x")


def test_failed_commands_remove_the_folders_they_created(tmp_path):
    from bpmcal.io.atomic import forget_created_dirs, make_dirs, remove_created_dirs

    (tmp_path / "kept").mkdir()
    forget_created_dirs()
    make_dirs(tmp_path / "kept" / "a" / "b")
    make_dirs(tmp_path / "full" / "c")
    (tmp_path / "full" / "c" / "file").write_text("x")
    removed = remove_created_dirs()
    assert sorted(p.name for p in removed) == ["a", "b"]
    assert (tmp_path / "kept").is_dir() and (tmp_path / "full" / "c" / "file").exists()


@pytest.mark.parametrize("stop, reason", [("post_peak_drop", ""),
                                          ("max_strain", "raise max_strain"),
                                          ("max_steps", "raise max_steps")])
@pytest.mark.parametrize("test", ["ucs", "triaxial", "dtt", "bts"])
def test_a_run_is_complete_only_after_its_peak_and_drop(test, stop, reason):
    from bpmcal.lab.registry import incomplete_reason

    got = incomplete_reason(test, {"stop_reason": stop, "steps": 100, "ucs_MPa": 6.1})
    assert (got == "") == (reason == "") and reason in got
    assert incomplete_reason("impact", {"stop_reason": "max_steps"}) == ""


def test_the_ratio_grid_is_bounded_before_it_is_built():
    from bpmcal.io.study_files import MAX_SWEEP_RATIOS, ratio_grid
    from bpmcal.params import ParameterError

    assert len(ratio_grid(0.01, 2.0, 0.01)) == MAX_SWEEP_RATIOS == 200
    t0 = time.perf_counter()
    for args in ((0.01, 1e300, 5e-324), (0.01, 200.0, 1e-8), (0.5, 0.6, 0.004)):
        with pytest.raises(ParameterError):
            ratio_grid(*args)
    assert time.perf_counter() - t0 < 1.0


def test_the_design_is_bounded_and_plain_lhs_is_fast():
    from bpmcal.study.design import MAX_OPTIMIZED, MAX_SAMPLES, design_size_problem, lhs_design

    assert design_size_problem(150, "random-cd") is None
    assert "takes minutes" in design_size_problem(MAX_OPTIMIZED["random-cd"] + 1, "random-cd")
    assert "takes minutes" in design_size_problem(101, "lloyd")
    assert design_size_problem(MAX_SAMPLES, None) is None
    assert design_size_problem(MAX_SAMPLES + 1, None)
    t0 = time.perf_counter()
    df = lhs_design({"rmin_mm": [0.6, 1.0], "porosity": [0.2, 0.36], "pb_emod_GPa": [10, 50],
                     "pb_kratio": [1, 5], "pb_ten_MPa": [10, 50], "pb_coh_MPa": [10, 50],
                     "pb_fa_deg": [15, 55], "fric": [0.15, 0.55]}, 20_000, 1,
                    optimization=None)
    assert len(df) == 20_000 and time.perf_counter() - t0 < 10.0


def test_config_and_cli_share_the_bounds():
    """The seeds, sample count and ratio count the config allows are the command's."""
    import yaml

    from bpmcal.cli.args import SEED
    from bpmcal.study.config import MAX_SEED
    from bpmcal.study.design import MAX_SAMPLES

    schema = yaml.safe_load(SCHEMA.read_text())
    study = schema["properties"]["study"]["properties"]
    assert study["lhs_seed"]["maximum"] == MAX_SEED == 2 ** 32 - 1
    assert study["n_samples"]["maximum"] == MAX_SAMPLES
    SEED(str(MAX_SEED))
    with pytest.raises(Exception, match="seed"):
        SEED(str(MAX_SEED + 1))
    seeds = []

    def walk(node, key=""):
        if isinstance(node, dict):
            name = key.split(".")[-1]
            if node.get("type") == "integer" and (name == "seed" or name.endswith("_seed")
                                                  or name in ("scatter_seeds", "fresh_seeds")):
                seeds.append((key, node.get("maximum")))
            for k, v in (node.get("properties") or {}).items():
                walk(v, f"{key}.{k}")
            if "items" in node:
                walk(node["items"], key)
    walk(schema)
    assert len(seeds) >= 9 and all(m == MAX_SEED for _, m in seeds), seeds


def test_summary_escapes_what_it_prints(tmp_path, capsys):
    from bpmcal.io import h5

    h5.write_run(tmp_path / "r.h5",
                 h5.RunRecord(test="ucs",
                           inputs={},
                           summary={"note": "a\x1b[31mred\x1b[0m\nstatus                   ok"}))
    assert main(["summary", str(tmp_path / "r.h5")]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "a\\x1b[31mred" in out
    assert [ln.split()[0] for ln in out.splitlines()].count("status") == 1


def test_closed_stdout_and_stderr_are_no_second_error(tmp_path):
    """``bpmcal ... 2>&-`` and ``>&-``: the exit code still tells, nothing crashes."""
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    for redirect in ("2>&-", ">&- 2>&-"):
        p = subprocess.run(["bash", "-c", f"'{sys.executable}' -m bpmcal.cli ucs --params "
                                          f"nope.yaml --out {tmp_path}/r.h5 {redirect}"],
                           capture_output=True, text=True, env=env, cwd=tmp_path)
        assert p.returncode == 2, p


def test_a_lab_table_is_a_schema(tmp_path):
    from bpmcal.study.lab_data import lab_problems, read_lab

    f = tmp_path / "lab.csv"
    f.write_text("specimen,ucs_MPa,E_GPa,nu,bts_Mpa,UCS_mpa_se,dtt_MPa\n"
                 "B1,60,13,0.25,5,1,1e3\n")
    msgs = lab_problems(read_lab(f), "lab.csv")
    text = "\n".join(msgs)
    assert "unknown column 'bts_Mpa'; did you mean 'bts_MPa'?" in text
    assert "unknown column 'UCS_mpa_se'; did you mean 'ucs_MPa_se'?" in text
    assert "dtt_MPa='1e3': expected a value in (0, 200] (rock)" in text
    f.write_text("specimen,ucs_MPa,E_GPa,nu\nB1,200,69,0.26\n")  # Lac du Bonnet: fine
    assert lab_problems(read_lab(f), "lab.csv") == []


def test_packing_cache_heals(tmp_path, capsys):
    """A damaged cached packing is removed with one line and relaxed again."""
    from bpmcal.lab.packing_cache import get_packing
    from bpmcal.lab.specimen import SpecimenSpec

    spec = SpecimenSpec.from_paper_units(0.8, 0.34, 1, scale=0.2)
    good = get_packing(spec, cache=tmp_path)
    (f,) = tmp_path.glob("packing_*.npz")
    raw = f.read_bytes()
    capsys.readouterr()
    for damaged in (raw[: len(raw) // 2], b"not a zip", b""):
        f.write_bytes(damaged)
        again = get_packing(spec, cache=tmp_path)
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "is damaged" in err[0] and "built again" in err[0], err
        assert (again.pos == good.pos).all() and f.read_bytes() == raw


def test_the_record_is_its_json_rendered():
    """docs/measurements/2026-12-02-hostile-inputs.md holds the tables of its two JSON
    results (``benchmarks/hostile_inputs.py --record``), of cases that are still cases."""
    import json

    sys.path.insert(0, str(REPO / "benchmarks"))
    import hostile_inputs

    raw = [json.loads((REPO / "benchmarks" / "results" / f"results_hostile_inputs_{w}_2026-12-02.json")
                      .read_text()) for w in ("before", "after")]
    page = (REPO / "docs" / "measurements" / "2026-12-02-hostile-inputs.md").read_text()
    assert hostile_inputs.markdown(*raw) in page
    ids = {c.id for c in CASES}
    assert all(r["case"] in ids for rec in raw for r in rec["cases"])
