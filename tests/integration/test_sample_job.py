"""The study's sample job: ``bpmcal sample --bts-out`` runs the sample's UCS test and then its
Brazilian test in one process (one start-up instead of two). Each file must be exactly
what the single-test commands write, every input of both tests is checked before the
first runs, and each test records its own failure."""
import h5py
import numpy as np
import pytest
import yaml
from support.paper import A1

from bpmcal.cli import main

#: the paper's A1 set at the smoke study's size: 15 x 30 mm cylinder, 21 x 10.5 mm disc
UCS = ["--scale", "0.3", "--platen-velocity", "0.2", "--record-strain", "2e-5", "--threads", "1"]
DISC = {"diameter": "70", "thickness": "35", "platen-velocity": "0.025",
        "approach-velocity": "0.1", "stop-drop": "0.2", "post-peak-strain": "0.0003"}


def _same_run(a, b):
    with h5py.File(a) as fa, h5py.File(b) as fb:
        sa, sb = dict(fa["summary"].attrs), dict(fb["summary"].attrs)
        timing = {"wall_s", "test_s", "genesis_s"}
        assert set(sa) == set(sb)
        for k in set(sa) - timing:  # NaN (a value that does not apply) equals NaN
            assert np.array_equal(sa[k], sb[k], equal_nan=np.asarray(sa[k]).dtype.kind == "f"), k
        for k in fa["series"]:
            assert np.array_equal(fa["series"][k][()], fb["series"][k][()]), k


@pytest.fixture(scope="module")
def runs(tmp_path_factory, packing_cache):
    d = tmp_path_factory.mktemp("sample")
    pf = d / "a1.yaml"
    pf.write_text(yaml.safe_dump(A1))
    cache = ["--specimen-cache", str(packing_cache)]
    both = [f"--bts-{k}={v}" for k, v in DISC.items()]
    one = [f"--{k}={v}" for k, v in DISC.items()]
    assert main(["sample", "--params", str(pf), "--out", str(d / "u.h5"), "--bts-out",
                 str(d / "b.h5"), *UCS, *both, *cache, "--quiet"]) == 0
    assert main(["ucs", "--params", str(pf), "--out", str(d / "u1.h5"), *UCS, *cache,
                 "--quiet"]) == 0
    assert main(["bts", "--params", str(pf), "--out", str(d / "b1.h5"), "--scale", "0.3",
                 "--threads", "1", *one, *cache, "--quiet"]) == 0
    return d


@pytest.mark.slow
def test_the_sample_job_writes_what_the_single_test_commands_write(runs):
    _same_run(runs / "u.h5", runs / "u1.h5")
    _same_run(runs / "b.h5", runs / "b1.h5")
    with h5py.File(runs / "b.h5") as f:
        s = f["summary"].attrs
        assert s["bts_MPa"] > 0 and s["approach_velocity"] == pytest.approx(0.1)
        assert f["inputs"].attrs["diameter_mm"] == pytest.approx(21.0)


@pytest.mark.parametrize("extra, needle", [
    (["--bts-out", "{d}/u.h5"], "the same file as --out"),
    (["--bts-out", "{d}/b.txt"], "--bts-out"),
    (["--bts-out", "{d}/b.h5", "--bts-diameter", "20"], "the Brazilian disc"),  # 6 x 10.5 mm
    (["--bts-out", "{d}/b.h5", "--bts-platen-velocity", "-1"], "bts-platen-velocity"),
])
def test_bad_input_of_either_test_is_refused_before_any_work(tmp_path, capsys, extra, needle):
    pf = tmp_path / "a1.yaml"
    pf.write_text(yaml.safe_dump(A1))
    disc = [f"--bts-{k}={v}" for k, v in DISC.items()]
    extra = [x.format(d=tmp_path) for x in extra]
    rc = main(["sample", "--params", str(pf), "--out", str(tmp_path / "u.h5"), *UCS, *disc,
               *extra])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
    assert not list(tmp_path.glob("*.h5"))  # nothing written, not even the UCS run


@pytest.mark.slow
def test_a_failed_ucs_test_does_not_stop_the_samples_brazilian_test(tmp_path, capsys):
    """A genesis step budget the cylinder (659 balls, bpmcal genesis) does not settle in
    but the disc (458 balls) does: the UCS test writes its failure record, the Brazilian
    test still runs and writes its run file, and --failed-ok lets the study go on."""
    pf = tmp_path / "a1.yaml"
    pf.write_text(yaml.safe_dump(A1))
    rc = main(["sample", "--params", str(pf), "--out", str(tmp_path / "u.h5"), "--bts-out",
               str(tmp_path / "b.h5"), *UCS, *[f"--bts-{k}={v}" for k, v in DISC.items()],
               "--genesis", "bpmcal", "--genesis-max-steps", "1000", "--quiet",
               "--failed-ok"])
    assert rc == 0  # --failed-ok: the study goes on
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bpmcal sample: FAILED: ") and "u.h5" in err[0]
    with h5py.File(tmp_path / "u.h5") as h:
        assert h.attrs["status"] == "failed" and h.attrs["test"] == "ucs"
        assert "GenesisError" in h.attrs["error"]
    with h5py.File(tmp_path / "b.h5") as h:
        assert h.attrs["status"] == "ok" and h.attrs["test"] == "bts"
        assert h["summary"].attrs["bts_MPa"] > 0
    # without --failed-ok the failure is the job's exit code
    assert main(["sample", "--params", str(pf), "--out", str(tmp_path / "u2.h5"), "--bts-out",
                 str(tmp_path / "b2.h5"), *UCS, *[f"--bts-{k}={v}" for k, v in DISC.items()],
                 "--genesis", "bpmcal", "--genesis-max-steps", "1000", "--quiet"]) == 3


@pytest.mark.parametrize("extra", [["--bts-out", "b.h5"], ["--dtt-out", "d.h5"],
                                   ["--tri-out", "t.h5", "--design-sigma3", "5"]])
def test_the_ucs_command_is_one_ucs_test_and_runs_no_other(tmp_path, capsys, extra):
    """``bpmcal ucs`` runs one UCS test; the sample job's other tests are ``bpmcal sample``'s:
    given to ``bpmcal ucs`` they are unknown options (one line, exit 2, nothing written)."""
    from bpmcal.cli import build_parser

    pf = tmp_path / "a1.yaml"
    pf.write_text(yaml.safe_dump(A1))
    argv = ["--params", str(pf), "--out", str(tmp_path / "u.h5"),
            *[str(tmp_path / x) if x.endswith(".h5") else x for x in extra]]
    assert main(["ucs", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unrecognized arguments" in err[0] and extra[0] in err[0], err
    assert not list(tmp_path.glob("*.h5"))
    args = build_parser(only="sample").parse_args(["sample", *argv])  # the sample job's option
    assert getattr(args, extra[0][2:].replace("-", "_")) == str(tmp_path / extra[1])
