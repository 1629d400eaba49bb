"""Temporary files of atomic writes: unique, O_EXCL, never through a planted symlink,
stale ones from killed runs removed on the next write."""
import os
import signal
import subprocess
import sys
import textwrap
import time

from support.repo import REPO

from bpmcal.io import atomic
from bpmcal.io.atomic import atomic_path, clean_stale_temps, write_text


def _dead_pid():
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid  # reaped: no such process (PIDs are not reused this fast)


def test_temp_names_are_unique_and_hidden(tmp_path):
    names = set()
    for _ in range(20):
        with atomic_path(tmp_path / "a.csv") as tmp:
            assert tmp.exists() and tmp.stat().st_size == 0  # created, empty, ours
            assert tmp.name.startswith(".a.csv.") and tmp.name.endswith(".tmp")
            assert atomic._TMP_RE.match(tmp.name)
            names.add(tmp.name)
            tmp.write_text("x")
    assert len(names) == 20
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv"]


def test_a_planted_symlink_is_never_followed(tmp_path, monkeypatch):
    """An attacker who guesses the temporary name and plants a symlink there cannot make
    the writer write through it: O_EXCL refuses the name and another one is drawn."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    tokens = iter(["0" * 16, "1" * 16])
    monkeypatch.setattr(atomic.secrets, "token_hex", lambda n: next(tokens))
    guessed = tmp_path / f".out.txt.{atomic._host()}.{os.getpid()}.{'0' * 16}.tmp"
    guessed.symlink_to(victim)
    write_text(tmp_path / "out.txt", "new content")
    assert victim.read_text() == "precious"
    assert (tmp_path / "out.txt").read_text() == "new content"
    assert guessed.is_symlink()  # left alone (it is not ours: the pid is alive)


def test_stale_temps_of_killed_runs_are_removed_on_the_next_write(tmp_path):
    dead = _dead_pid()
    host = atomic._host()
    stale = [tmp_path / f".s001.h5.{host}.{dead}.{'a' * 16}.tmp",  # killed run, this host
             tmp_path / f".s002.h5.{dead}.tmp"]  # the old naming (bpmcal 0.1.0)
    alive = [tmp_path / f".s003.h5.{host}.{os.getppid()}.{'b' * 16}.tmp",  # a live writer
             tmp_path / f".s004.h5.otherhost.{dead}.{'c' * 16}.tmp",  # another node, recent
             tmp_path / "notes.tmp", tmp_path / ".hidden.tmp"]  # not ours
    old_foreign = tmp_path / f".s005.h5.otherhost.{dead}.{'d' * 16}.tmp"  # > 1 day old
    for f in [*stale, *alive, old_foreign]:
        f.write_text("partial")
    t = time.time() - 2 * atomic.STALE_AFTER_S
    os.utime(old_foreign, (t, t))
    write_text(tmp_path / "dataset.csv", "a,b\n")
    left = {p.name for p in tmp_path.iterdir()}
    assert not any(f.name in left for f in stale + [old_foreign])
    assert all(f.name in left for f in alive)


def test_clean_stale_temps_leaves_directories_and_returns_what_it_removed(tmp_path):
    dead = _dead_pid()
    d = tmp_path / f".x.{atomic._host()}.{dead}.{'e' * 16}.tmp"
    d.mkdir()
    f = tmp_path / f".y.{atomic._host()}.{dead}.{'f' * 16}.tmp"
    f.write_text("")
    assert clean_stale_temps(tmp_path) == [f]
    assert d.is_dir()


def test_a_killed_writer_leaves_a_temp_that_the_next_run_removes(tmp_path):
    out = tmp_path / "k.csv"
    code = textwrap.dedent(f"""
        import time
        from bpmcal.io import atomic
        with atomic.atomic_path({str(out)!r}) as tmp:
            tmp.write_text("partial")
            time.sleep(60)
    """)
    p = subprocess.Popen([sys.executable, "-c", code])
    t0 = time.time()
    while not any(f.name.endswith(".tmp") for f in tmp_path.iterdir()):
        assert time.time() - t0 < 60 and p.poll() is None
        time.sleep(0.05)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert not out.exists() and len(list(tmp_path.iterdir())) == 1  # the orphan
    write_text(out, "complete\n")
    assert [f.name for f in tmp_path.iterdir()] == ["k.csv"]


def test_gitignore_matches_the_temporary_files():
    r = subprocess.run(["git", "check-ignore", "-q", "--no-index",
                        "results/ucs/.s001.h5.host.123.0123456789abcdef.tmp"], cwd=REPO)
    assert r.returncode == 0
    r = subprocess.run(["git", "check-ignore", "-q", "--no-index", "config/.s001.h5.99.tmp"],
                       cwd=REPO)
    assert r.returncode == 0
