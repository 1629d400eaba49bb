"""RunJournal (bpmcal.stages.journal): the finished runs of a closed loop, read again by
a later attempt with the same inputs and the same bpmcal. (The loop stopped and resumed:
tests/unit/stages/test_verification_transfer.py.)"""
import math

import bpmcal.stages.journal as J
from bpmcal.lab.runner import Geometry
from bpmcal.lab.ucs import UCSSettings


def _inputs(**kw):
    return dict(dict(params={"pb_emod_GPa": 10.0}, seed=3, geometry=Geometry(scale=0.3),
                     settings=UCSSettings()), **kw)


def test_the_key_is_the_inputs_and_the_bpmcal(monkeypatch):
    k = J.RunJournal.key(**_inputs())
    assert k == J.RunJournal.key(**_inputs())  # the same run: the same key
    for other in (_inputs(seed=4), _inputs(params={"pb_emod_GPa": 10.000000001}),
                  _inputs(geometry=Geometry(scale=0.31)),
                  _inputs(settings=UCSSettings(platen_velocity=0.051))):
        assert J.RunJournal.key(**other) != k
    monkeypatch.setattr(J, "source_hash", lambda: "an edited checkout")
    assert J.RunJournal.key(**_inputs()) != k  # another bpmcal: the runs are made anew


def test_a_finished_run_is_read_back_once_its_files_are_there(tmp_path):
    j = J.RunJournal(tmp_path / ".best.rounds")
    f = j.stem("a" * 64).with_suffix(".h5")
    f.write_text("run")
    j.add("a" * 64, {"row": {"ucs_MPa": math.nan, "seed": 3}, "out": {"ucs_MPa": 61.5}},
          [f])
    j.add("b" * 64, {"row": {}, "out": {}}, [tmp_path / ".best.rounds" / "gone.h5"])
    with open(j.path, "a") as fh:
        fh.write('{"key": "cccc", "files": [], "rec')  # a line a kill cut short
    j.release()  # the first attempt ended
    again = J.RunJournal(tmp_path / ".best.rounds")
    assert again.resumable == 1  # b's file is missing, c's line is cut: neither counts
    rec = again.get("a" * 64)
    assert rec["out"] == {"ucs_MPa": 61.5} and math.isnan(rec["row"]["ucs_MPa"])
    assert again.get("b" * 64) is None and again.reused == 1
    again.keep_or_remove()  # after a failure: kept, it holds a finished run
    assert again.path.exists()
    again.remove()
    assert not (tmp_path / ".best.rounds").exists()
    empty = J.RunJournal(tmp_path / ".x.rounds")
    empty.keep_or_remove()  # nothing finished: nothing kept
    assert not (tmp_path / ".x.rounds").exists()


def test_a_second_stage_in_the_same_folder_stops_before_touching_it(tmp_path):
    """Two runs sharing one working folder (an orphaned child of a killed run did this):
    the second stops with the folder and the holder's pid, and the first's runs stay."""
    import os
    import subprocess
    import sys

    import pytest

    from bpmcal.io.checks import BadInput

    j = J.RunJournal(tmp_path / ".best.rounds")
    f = j.stem("a" * 64).with_suffix(".h5")
    f.write_text("run")
    j.add("a" * 64, {"row": {}, "out": {}}, [f])
    with pytest.raises(BadInput, match=rf"\.best\.rounds: another bpmcal process \(pid "
                                       rf"{os.getpid()}\) is working in this folder"):
        J.RunJournal(tmp_path / ".best.rounds")
    # another process, as two CLI runs are: refused too, nothing removed
    code = ("import sys; import bpmcal.stages.journal as J\n"
            "try:\n J.RunJournal(sys.argv[1]).remove()\n"
            "except Exception as e:\n print(type(e).__name__, e); sys.exit(2)")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / ".best.rounds")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "BadInput" in r.stdout and str(os.getpid()) in r.stdout
    assert f.exists() and j.path.exists()
    j.keep_or_remove()  # the first ends (failed, runs kept): the folder is free again
    again = J.RunJournal(tmp_path / ".best.rounds")
    assert again.resumable == 1
    again.remove()
    assert not (tmp_path / ".best.rounds").exists()
