"""A real, private, single-node Slurm cluster for tests (Debian's slurm-wlm + munge).

``local_slurm_cluster(workdir)`` is a context manager that

1. checks the prerequisites (asked for with ``BPMCAL_TEST_SLURM=1``; root; the daemons
   installed, else ``apt-get`` to install them),
2. starts ``munged`` as the ``munge`` user on the default socket (or reuses a working one),
3. writes a ``slurm.conf`` into a private directory (this host, its real CPUs and
   RealMemory from ``slurmd -C``, no accounting, private state/spool/pid/log paths, free
   ports) and makes it reachable at ``/etc/slurm/slurm.conf`` through a symlink (the
   jobstep plugin strips ``SLURM_CONF`` before its inner ``srun``, so the job steps find
   the configuration only at the default path),
4. starts ``slurmctld`` and ``slurmd`` in the foreground as our own child processes, waits
   for ``scontrol ping`` and for the node to be idle,
5. and on exit, also on exceptions, KeyboardInterrupt and SIGTERM, cancels the jobs,
   stops the daemons it started by their pids, restores whatever ``/etc/slurm/slurm.conf``
   was before and removes its private directories.

It changes the machine (system packages, daemons, ``/etc/slurm``), so it runs only when
asked: ``BPMCAL_TEST_SLURM=1`` in the environment (``.ci/run`` sets it; a plain
``python -m pytest`` skips the Slurm tests and changes nothing outside the repository).
Prerequisites that are not met raise :class:`SlurmUnavailable` before anything is
changed; a test fixture turns that into a skip.  Anything that goes wrong later raises
:class:`SlurmClusterError` with the daemons' log tails in the message.
"""

from __future__ import annotations

import atexit
import contextlib
import dataclasses
import errno
import fcntl
import os
import pwd
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Iterator

PACKAGES = ("slurmctld", "slurmd", "slurm-client", "munge")
REQUIRED_BINARIES = (
    "slurmctld",
    "slurmd",
    "sbatch",
    "squeue",
    "scontrol",
    "sinfo",
    "srun",
    "munged",
    "munge",
)
#: the environment variable that asks for the Slurm tests (they install and start services)
ASK = "BPMCAL_TEST_SLURM"
ETC_SLURM_CONF = Path("/etc/slurm/slurm.conf")
SAVED_ETC_CONF = Path("/etc/slurm/slurm.conf.bpmcal-saved")
MUNGE_SOCKET_DIR = Path("/run/munge")
LOCK_FILE = (
    Path("/run/lock/bpmcal-slurm-test.lock")
    if Path("/run/lock").is_dir()
    else Path("/tmp/bpmcal-slurm-test.lock")
)
#: Every path of ours contains this string: it identifies stale daemons of an earlier,
#: killed run (their command lines name our config) and stale /etc symlinks.
MARKER = "bpmcal-slurm"
DAEMON_NAMES = ("slurmctld", "slurmd", "slurmstepd", "munged")


class SlurmUnavailable(RuntimeError):
    """The machine cannot host the private cluster (not root, no apt-get, ...): skip."""


class SlurmClusterError(RuntimeError):
    """Bring-up or tear-down failed; the message carries the daemons' log tails."""


@dataclasses.dataclass
class SlurmCluster:
    """What a test needs to know about the running cluster."""

    root: Path  # private directory with slurm.conf and the daemons' logs
    conf: Path
    node: str
    partition: str
    cpus: int
    real_memory_mb: int
    slurmctld_port: int
    slurmd_port: int
    env: dict  # os.environ plus SLURM_CONF, for subprocesses that talk to the cluster
    pids: dict  # name -> pid of every daemon this context started
    started_munged: bool
    bringup_seconds: float = 0.0  # from entering the context to an idle node, apt-get included
    install_seconds: float = 0.0  # apt-get part of that (0 when the packages were there)
    logs: dict = dataclasses.field(default_factory=dict)  # name -> log path
    _stop: object = dataclasses.field(default=None, repr=False)

    def run(self, *cmd: str, timeout: float = 30, check: bool = True) -> subprocess.CompletedProcess:
        """Run a Slurm client command against this cluster."""
        return _run(list(cmd), env=self.env, timeout=timeout, check=check)

    def log_tails(self, lines: int = 40) -> str:
        return _format_tails(self.logs, lines)

    def stop(self) -> None:
        """Shut the cluster down now (idempotent; leaving the ``with`` block does the same)."""
        if self._stop is not None:
            self._stop()

    def daemons_alive(self) -> dict:
        """name -> pid of the daemons this cluster started that are still alive."""
        return {name: pid for name, pid in self.pids.items() if _pid_alive(pid)}


# --------------------------------------------------------------------------- helpers


def _run(cmd, *, env=None, timeout=30, check=True, input=None) -> subprocess.CompletedProcess:
    try:
        res = subprocess.run(cmd, env=env, timeout=timeout, input=input, capture_output=True, text=True)
    except subprocess.TimeoutExpired as e:
        raise SlurmClusterError(f"command timed out after {timeout} s: {' '.join(cmd)}") from e
    if check and res.returncode != 0:
        raise SlurmClusterError(
            f"command failed ({res.returncode}): {' '.join(cmd)}\n"
            f"stdout: {res.stdout[-2000:]}\nstderr: {res.stderr[-2000:]}"
        )
    return res


def _tail(path: Path, lines: int) -> str:
    try:
        text = Path(path).read_text(errors="replace")
    except OSError as e:
        return f"<cannot read: {e}>"
    return "\n".join(text.splitlines()[-lines:]) or "<empty>"


def _format_tails(logs: dict, lines: int = 40) -> str:
    return "\n".join(
        f"----- {name}: last {lines} lines of {path} -----\n{_tail(path, lines)}"
        for name, path in logs.items()
    )


def missing_binaries() -> list[str]:
    return [b for b in REQUIRED_BINARIES if shutil.which(b) is None and not Path("/usr/sbin", b).exists()]


def unavailable_reason() -> str | None:
    """Why the private cluster cannot be brought up here, or None if it can."""
    if os.environ.get(ASK, "") in ("", "0"):
        return (f"Slurm test not asked for: set {ASK}=1 to run it (as root it installs "
                f"{' '.join(PACKAGES)} with apt-get and starts their daemons)")
    if os.name != "posix" or not Path("/proc/self").exists():
        return "Slurm test needs Linux"
    if os.geteuid() != 0:
        return "Slurm test needs root and apt-get (not root)"
    if missing_binaries() and shutil.which("apt-get") is None:
        return (
            f"Slurm test needs root and apt-get (apt-get not found; missing: {', '.join(missing_binaries())})"
        )
    return None


def ensure_installed(log: Path | None = None, timeout: float = 600) -> float:
    """Install the Debian packages if any daemon/client is missing; returns seconds spent."""
    missing = missing_binaries()
    if not missing:
        return 0.0
    t0 = time.monotonic()
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    install = ["apt-get", "install", "-y", "-q", "--no-install-recommends", *PACKAGES]
    out = []
    res = subprocess.run(install, env=env, capture_output=True, text=True, timeout=timeout)
    out.append(res.stdout + res.stderr)
    if res.returncode != 0:  # stale or empty package lists on a fresh machine: update, retry
        upd = subprocess.run(
            ["apt-get", "update", "-q"], env=env, capture_output=True, text=True, timeout=timeout
        )
        out.append(upd.stdout + upd.stderr)
        res = subprocess.run(install, env=env, capture_output=True, text=True, timeout=timeout)
        out.append(res.stdout + res.stderr)
    if log is not None:
        log.write_text("\n".join(out))
    if res.returncode != 0 or missing_binaries():
        raise SlurmClusterError(
            f"could not install {' '.join(PACKAGES)} (missing: {', '.join(missing_binaries())}):\n"
            + "\n".join(out)[-3000:]
        )
    return time.monotonic() - t0


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _proc_table() -> list[tuple[int, str, str, float]]:
    """(pid, comm, cmdline, start time in clock ticks) of every process."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            comm = (d / "comm").read_text().strip()
            cmdline = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
            stat = (d / "stat").read_text()
            start = float(stat[stat.rindex(")") + 2 :].split()[19])
        except (OSError, ValueError, IndexError):
            continue
        out.append((int(d.name), comm, cmdline, start))
    return out


def slurm_processes() -> list[tuple[int, str, str, float]]:
    """Every slurmctld/slurmd/slurmstepd/munged process on the machine (zombies excluded)."""
    procs = []
    for pid, comm, cmdline, start in _proc_table():
        if comm in DAEMON_NAMES or comm.startswith("slurmstepd"):
            try:
                state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except (OSError, IndexError):
                continue
            if state != "Z":
                procs.append((pid, comm, cmdline, start))
    return procs


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # a zombie is dead for our purposes
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def _stop_pid(pid: int, proc: subprocess.Popen | None = None, grace: float = 10.0) -> None:
    """SIGTERM, wait up to ``grace`` s, then SIGKILL; reaps our own children."""
    for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, 5.0)):
        try:
            os.kill(pid, sig)
        except ProcessLookupError:
            break
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline:
            if proc is not None:
                if proc.poll() is not None:
                    return
            elif not _pid_alive(pid):
                return
            time.sleep(0.05)
    if proc is not None:
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=5)


RUNNER_MARK = "BPMCAL_SLURM_RUNNER"


def _has_runner_mark(pid: int) -> bool:
    try:
        return f"{RUNNER_MARK}=".encode() in Path(f"/proc/{pid}/environ").read_bytes()
    except OSError:
        return False


def _with_descendants(pids: list[int]) -> list[int]:
    children: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            with contextlib.suppress(OSError, ValueError, IndexError):
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
                children.setdefault(ppid, []).append(int(d.name))
    out, todo = [], list(pids)
    while todo:
        pid = todo.pop()
        if pid not in out:
            out.append(pid)
            todo.extend(children.get(pid, []))
    return out


def _kill_stale_daemons() -> list[int]:
    """Stop daemons left behind by an earlier run of ours that was killed (SIGKILL).

    Only processes whose command line names one of our private paths (MARKER) are
    touched; a foreign slurmctld/slurmd makes the bring-up refuse instead.
    """
    killed = []
    for pid, comm, cmdline, _ in slurm_processes():
        if MARKER in cmdline and comm in ("slurmctld", "slurmd", "munged"):
            _stop_pid(pid, grace=5.0)
            killed.append(pid)
    # Job steps of a cluster that is gone: with no slurmd left on the machine (a foreign
    # one makes the bring-up refuse), every slurmstepd is an orphan of a killed run.
    procs = slurm_processes()
    if not any(comm == "slurmd" for _, comm, _, _ in procs):
        steps = [pid for pid, comm, _, _ in procs if comm.startswith("slurmstepd")]
        for pid in _with_descendants(steps):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            killed.append(pid)
    # Snakemake runs of a killed test (run_snakemake_on_slurm marks them in the environment)
    runners = [pid for pid, _, _, _ in _proc_table() if pid != os.getpid() and _has_runner_mark(pid)]
    for pid in _with_descendants(runners):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
        killed.append(pid)
    # their private directories in /tmp (we hold the lock, so none is in use)
    for d in Path("/tmp").glob(f"{MARKER}-*"):
        shutil.rmtree(d, ignore_errors=True)
    return killed


def _restore_etc_conf() -> None:
    """Put back whatever /etc/slurm/slurm.conf was before we replaced it."""
    if ETC_SLURM_CONF.is_symlink() and MARKER in os.readlink(ETC_SLURM_CONF):
        ETC_SLURM_CONF.unlink()
    if SAVED_ETC_CONF.exists() or SAVED_ETC_CONF.is_symlink():
        if not (ETC_SLURM_CONF.exists() or ETC_SLURM_CONF.is_symlink()):
            os.rename(SAVED_ETC_CONF, ETC_SLURM_CONF)


def _install_etc_conf(conf: Path) -> None:
    _restore_etc_conf()  # a stale symlink of a killed run first
    ETC_SLURM_CONF.parent.mkdir(parents=True, exist_ok=True)
    if ETC_SLURM_CONF.exists() or ETC_SLURM_CONF.is_symlink():
        os.rename(ETC_SLURM_CONF, SAVED_ETC_CONF)
    os.symlink(conf, ETC_SLURM_CONF)


@contextlib.contextmanager
def _exclusive_lock(timeout: float = 300.0) -> Iterator[None]:
    """One private cluster per machine at a time (it owns /etc/slurm/slurm.conf)."""
    LOCK_FILE.parent.mkdir(parents=True, exist_ok=True)
    with open(LOCK_FILE, "w") as fh:
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except OSError as e:
                if e.errno not in (errno.EAGAIN, errno.EACCES) or time.monotonic() > deadline:
                    raise SlurmClusterError(
                        f"another private Slurm cluster holds {LOCK_FILE} (waited {timeout:.0f} s)"
                    ) from e
                time.sleep(0.5)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into KeyboardInterrupt while the cluster is up, so `finally` runs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise KeyboardInterrupt(f"signal {signum} while a private Slurm cluster was up")

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _munge_works(timeout: float = 10) -> bool:
    try:
        enc = subprocess.run(["munge", "-n"], capture_output=True, timeout=timeout)
        if enc.returncode != 0:
            return False
        dec = subprocess.run(["unmunge"], input=enc.stdout, capture_output=True, timeout=timeout)
        return dec.returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def _wait_for(predicate, timeout: float, interval: float = 0.25) -> bool:
    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return True
        if time.monotonic() > deadline:
            return False
        time.sleep(interval)


def node_config_line() -> tuple[str, dict]:
    """``slurmd -C``'s NodeName line (UpTime dropped) and its fields."""
    out = _run(["slurmd", "-C"], timeout=30).stdout
    line = next((ln for ln in out.splitlines() if ln.startswith("NodeName=")), None)
    if line is None:
        raise SlurmClusterError(f"unexpected `slurmd -C` output:\n{out}")
    fields = dict(kv.split("=", 1) for kv in line.split() if "=" in kv)
    fields.pop("UpTime", None)
    return " ".join(f"{k}={v}" for k, v in fields.items()), fields


def write_slurm_conf(
    root: Path,
    spool: Path,
    node: str,
    node_fields: dict,
    ctld_port: int,
    slurmd_port: int,
    partition: str = "debug",
) -> Path:
    state = root / "state"
    state.mkdir(parents=True, exist_ok=True)
    node_line = " ".join(
        f"{k}={v}"
        for k, v in {**node_fields, "NodeName": node, "NodeAddr": "127.0.0.1", "State": "UNKNOWN"}.items()
    )
    conf = root / "slurm.conf"
    conf.write_text(
        f"""# private single-node test cluster written by tests/support/slurm_cluster.py
ClusterName=bpmcaltest
SlurmctldHost={node}(127.0.0.1)
SlurmctldPort={ctld_port}
SlurmdPort={slurmd_port}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CryptoType=crypto/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
DefMemPerCPU=256
ReturnToService=2
# keep finished jobs visible to squeue long enough for the plugin's status checks
# (MinJobAge >= 3 x slurm-init-seconds-before-status-checks)
MinJobAge=300
MailProg=/bin/true
SchedulerType=sched/backfill
SchedulerParameters=sched_interval=1
InactiveLimit=0
KillWait=5
Waittime=0
SlurmctldTimeout=60
SlurmdTimeout=60
# no slurmdbd: no accounting (the plugin must use squeue for status checks)
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
StateSaveLocation={state}
SlurmdSpoolDir={spool}
SlurmctldPidFile={root}/slurmctld.pid
SlurmdPidFile={root}/slurmd.pid
SlurmctldLogFile={root}/slurmctld.log
SlurmdLogFile={root}/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
{node_line}
PartitionName={partition} Nodes={node} Default=YES MaxTime=INFINITE State=UP
"""
    )
    conf.chmod(0o644)
    return conf


# --------------------------------------------------------------------------- the context manager


@contextlib.contextmanager
def local_slurm_cluster(
    workdir: os.PathLike | str,
    *,
    install: bool = True,
    ping_timeout: float = 60.0,
    idle_timeout: float = 90.0,
) -> Iterator[SlurmCluster]:
    """Bring up a private single-node Slurm cluster for the duration of the ``with`` block.

    ``workdir`` receives the configuration and the daemons' logs (``<workdir>/bpmcal-slurm``).
    Raises :class:`SlurmUnavailable` (nothing changed) when the machine cannot host it.
    """
    reason = unavailable_reason()
    if reason:
        raise SlurmUnavailable(reason)

    t0 = time.monotonic()
    root = Path(workdir).resolve() / MARKER
    root.mkdir(parents=True, exist_ok=True)
    install_seconds = 0.0
    if install:
        install_seconds = ensure_installed(log=root / "apt-get.log")
    elif missing_binaries():
        raise SlurmUnavailable(f"Slurm binaries missing: {', '.join(missing_binaries())}")

    procs: dict[str, subprocess.Popen] = {}
    logs: dict[str, Path] = {}
    cleanups: list = []  # callables run in reverse order on exit
    done = False

    def teardown():
        nonlocal done
        if done:
            return
        done = True
        errors = []
        for fn in reversed(cleanups):
            try:
                fn()
            except Exception as e:  # keep tearing down; report at the end
                errors.append(f"{getattr(fn, '__name__', fn)}: {e!r}")
        cleanups.clear()
        if errors:
            raise SlurmClusterError("tear-down problems: " + "; ".join(errors))

    def _logfile(path: Path):
        fh = open(path, "w")
        cleanups.append(fh.close)
        return fh

    atexit.register(teardown)  # last resort if the interpreter exits inside the block
    try:
        with _exclusive_lock(), _sigterm_as_interrupt():
            try:
                _kill_stale_daemons()
                foreign = [(p, c) for p, c, cmd, _ in slurm_processes() if c in ("slurmctld", "slurmd")]
                if foreign:
                    raise SlurmUnavailable(
                        f"Slurm daemons not started by this test are running ({foreign}); "
                        "refusing to bring up a private cluster beside them"
                    )

                # -- munge ----------------------------------------------------------------
                started_munged = False
                if not _munge_works():
                    munge_pw = pwd.getpwnam("munge")
                    key = Path("/etc/munge/munge.key")
                    if not key.exists():
                        _run(["mungekey", "--create", f"--keyfile={key}"], timeout=30)
                        os.chown(key, munge_pw.pw_uid, munge_pw.pw_gid)
                        key.chmod(0o600)
                    MUNGE_SOCKET_DIR.mkdir(mode=0o755, parents=True, exist_ok=True)
                    os.chown(MUNGE_SOCKET_DIR, munge_pw.pw_uid, munge_pw.pw_gid)
                    MUNGE_SOCKET_DIR.chmod(0o755)
                    # munge can't traverse root's 0700 pytest tmp dirs: private dir in /tmp
                    mdir = Path(tempfile.mkdtemp(prefix=f"{MARKER}-munge-", dir="/tmp"))

                    def remove_mdir():
                        with contextlib.suppress(OSError):  # keep munged's log beside the others
                            shutil.copy(mdir / "munged.log", root / "munged.log")
                        shutil.rmtree(mdir, ignore_errors=True)

                    cleanups.append(remove_mdir)
                    os.chown(mdir, munge_pw.pw_uid, munge_pw.pw_gid)
                    mdir.chmod(0o700)
                    logs["munged"] = mdir / "munged.log"

                    def as_munge():
                        os.setgid(munge_pw.pw_gid)
                        os.setgroups([])
                        os.setuid(munge_pw.pw_uid)

                    # (the 'force' flag lets munged replace a stale socket of a killed run)
                    munged = subprocess.Popen(
                        [
                            "munged",
                            "--foreground",
                            "--force",
                            f"--pid-file={mdir}/munged.pid",
                            f"--log-file={mdir}/munged.log",
                            f"--seed-file={mdir}/munged.seed",
                        ],
                        stdout=_logfile(root / "munged.out"),
                        stderr=subprocess.STDOUT,
                        preexec_fn=as_munge,
                        cwd="/",
                        close_fds=True,
                    )
                    procs["munged"] = munged
                    cleanups.append(lambda: _stop_pid(munged.pid, munged))
                    started_munged = True
                    if not _wait_for(lambda: munged.poll() is None and _munge_works(), 20):
                        raise SlurmClusterError(
                            f"munged did not come up (exit code {munged.poll()}):\n"
                            + _format_tails({**logs, "munged.out": root / "munged.out"})
                        )

                # -- configuration --------------------------------------------------------------
                node = socket.gethostname().split(".")[0]
                _, node_fields = node_config_line()
                spool = Path(tempfile.mkdtemp(prefix=f"{MARKER}-spool-", dir="/tmp"))  # short: unix sockets
                cleanups.append(lambda: shutil.rmtree(spool, ignore_errors=True))
                ctld_port = _free_port()
                slurmd_port = _free_port()
                while slurmd_port == ctld_port:
                    slurmd_port = _free_port()
                partition = "debug"
                conf = write_slurm_conf(root, spool, node, node_fields, ctld_port, slurmd_port, partition)
                shutil.rmtree(root / "state", ignore_errors=True)  # no state from an earlier run
                (root / "state").mkdir()
                for name in ("slurmctld", "slurmd"):
                    logs[name] = root / f"{name}.log"
                    with contextlib.suppress(FileNotFoundError):
                        logs[name].unlink()
                _install_etc_conf(conf)
                cleanups.append(_restore_etc_conf)

                env = {
                    k: v for k, v in os.environ.items() if not k.startswith(("SLURM_", "SBATCH_", "SRUN_"))
                }
                env["SLURM_CONF"] = str(conf)
                cluster = SlurmCluster(
                    root=root,
                    conf=conf,
                    node=node,
                    partition=partition,
                    cpus=int(node_fields.get("CPUs", 1)),
                    real_memory_mb=int(node_fields.get("RealMemory", 1)),
                    slurmctld_port=ctld_port,
                    slurmd_port=slurmd_port,
                    env=env,
                    pids={},
                    started_munged=started_munged,
                    logs=logs,
                    _stop=teardown,
                    install_seconds=install_seconds,
                )
                if started_munged:
                    cluster.pids["munged"] = procs["munged"].pid

                def start(name: str, cmd: list[str]) -> subprocess.Popen:
                    out = root / f"{name}.out"
                    logs[f"{name}.out"] = out
                    p = subprocess.Popen(
                        cmd,
                        stdout=_logfile(out),
                        stderr=subprocess.STDOUT,
                        env=env,
                        cwd=root,
                        close_fds=True,
                    )
                    procs[name] = p
                    cluster.pids[name] = p.pid
                    return p

                def fail(msg: str):
                    raise SlurmClusterError(f"{msg}\nconfig: {conf}\n" + _format_tails(logs))

                # -- slurmctld ---------------------------------------------------------------
                ctld = start("slurmctld", ["slurmctld", "-D", "-i", "-f", str(conf)])

                def stop_ctld():
                    _stop_pid(ctld.pid, ctld)

                cleanups.append(stop_ctld)

                def ctld_up():
                    if ctld.poll() is not None:
                        fail(f"slurmctld exited with code {ctld.returncode} during start-up")
                    r = _run(["scontrol", "ping"], env=env, timeout=10, check=False)
                    return r.returncode == 0 and "UP" in r.stdout

                if not _wait_for(ctld_up, ping_timeout, 0.5):
                    fail(f"`scontrol ping` did not report slurmctld UP within {ping_timeout:.0f} s")

                # -- slurmd ------------------------------------------------------------------
                slurmd_start_ticks = None
                sd = start("slurmd", ["slurmd", "-D", "-N", node, "-f", str(conf)])
                with contextlib.suppress(OSError, ValueError, IndexError):
                    st = Path(f"/proc/{sd.pid}/stat").read_text()
                    slurmd_start_ticks = float(st[st.rindex(")") + 2 :].split()[19])

                def stop_slurmd():
                    _stop_pid(sd.pid, sd)
                    # job steps of our jobs (slurmstepd daemonizes away from slurmd)
                    if slurmd_start_ticks is not None:
                        for pid, comm, _, start_ticks in slurm_processes():
                            if comm.startswith("slurmstepd") and start_ticks >= slurmd_start_ticks:
                                _stop_pid(pid, grace=3.0)

                cleanups.append(stop_slurmd)

                def cancel_jobs():  # first, while both daemons still run
                    if ctld.poll() is not None or sd.poll() is not None:
                        return
                    _run(["scancel", "--quiet", "--full", "-u", "root"], env=env, timeout=15, check=False)
                    _wait_for(
                        lambda: (
                            not _run(
                                ["squeue", "-h", "-o", "%i"], env=env, timeout=10, check=False
                            ).stdout.strip()
                        ),
                        20,
                    )

                cleanups.append(cancel_jobs)

                state = {"t": ""}

                def node_idle():
                    if sd.poll() is not None:
                        fail(f"slurmd exited with code {sd.returncode} during start-up")
                    r = _run(["sinfo", "-h", "-N", "-n", node, "-o", "%t"], env=env, timeout=10, check=False)
                    state["t"] = r.stdout.strip()
                    if state["t"].startswith(("drain", "drng", "inval", "down")) and "*" not in state["t"]:
                        _run(["scontrol", "update", f"nodename={node}", "state=resume"], env=env, check=False)
                    return r.returncode == 0 and state["t"] == "idle"

                if not _wait_for(node_idle, idle_timeout, 0.5):
                    reason_out = _run(["scontrol", "show", "node", node], env=env, check=False).stdout
                    fail(
                        f"node {node} not idle within {idle_timeout:.0f} s (state {state['t']!r})\n"
                        f"{reason_out}"
                    )

                cluster.bringup_seconds = time.monotonic() - t0
                yield cluster
            except BaseException:
                with contextlib.suppress(SlurmClusterError):  # the original error matters more
                    teardown()
                raise
            else:
                teardown()
    finally:
        atexit.unregister(teardown)


@contextlib.contextmanager
def cluster_or_skip(workdir: os.PathLike | str, **kwargs) -> Iterator[SlurmCluster]:
    """``local_slurm_cluster`` for pytest: an unusable machine skips the test instead."""
    import pytest

    reason = unavailable_reason()
    if reason:
        pytest.skip(reason)
    entered = False
    try:
        with local_slurm_cluster(workdir, **kwargs) as cluster:
            entered = True
            yield cluster
    except SlurmUnavailable as e:
        if entered:
            raise
        pytest.skip(str(e))


# --------------------------------------------------------------------------- running Snakemake

SUBMITTED_RE = re.compile(r"Job (\S+) has been submitted with SLURM jobid (\d+)")


@dataclasses.dataclass
class SnakemakeRun:
    cmd: list
    returncode: int
    output: str  # stdout and stderr, interleaved
    seconds: float
    log: Path  # where `output` was written as well

    @property
    def timed_out(self) -> bool:  # `timeout` exits 124 (or 128+9 after -k)
        return self.returncode in (124, 137)

    @property
    def submissions(self) -> list[tuple[str, str]]:
        """(Snakemake job id, Slurm job id) of every sbatch submission, in order."""
        return SUBMITTED_RE.findall(self.output)

    @property
    def slurm_job_ids(self) -> list[str]:
        return [sid for _, sid in self.submissions]


def run_snakemake_on_slurm(
    workflow_dir: os.PathLike | str,
    profile_dir: os.PathLike | str,
    extra_args=(),
    timeout_s: float = 600,
    *,
    env: dict | None = None,
    log_name: str = "snakemake-slurm.log",
) -> SnakemakeRun:
    """Run ``snakemake --executor slurm --workflow-profile <profile_dir>`` in ``workflow_dir``.

    The run is wrapped in ``timeout -s INT`` (a run that lost track of its jobs waits
    forever and ignores SIGTERM; SIGINT makes Snakemake cancel its Slurm jobs and stop),
    with a SIGKILL 60 s later if even that does not help.
    Pass the cluster's ``env`` (it carries SLURM_CONF). Output goes to
    ``<workflow_dir>/<log_name>`` and into the returned :class:`SnakemakeRun`.
    """
    workflow_dir = Path(workflow_dir).resolve()
    profile_dir = Path(profile_dir).resolve()
    if not (profile_dir / "config.yaml").is_file():
        raise FileNotFoundError(f"no config.yaml in workflow profile {profile_dir}")
    cmd = [
        "timeout", "-s", "INT", "-k", "60", str(int(timeout_s)),
        sys.executable, "-m", "snakemake",
        "--executor", "slurm",
        "--workflow-profile", str(profile_dir),
        *map(str, extra_args),
    ]  # fmt: skip
    run_env = dict(os.environ if env is None else env)
    # Snakemake inside the Slurm job is started as `<this python> -m snakemake`; keep its
    # scripts (and `snakemake` itself) on PATH there as well.
    bindir = str(Path(sys.executable).parent)
    if bindir not in run_env.get("PATH", "").split(os.pathsep):
        run_env["PATH"] = bindir + os.pathsep + run_env.get("PATH", "")
    run_env[RUNNER_MARK] = str(os.getpid())  # lets a later bring-up find orphans of a killed test
    log = workflow_dir / log_name
    t0 = time.monotonic()
    with open(log, "w") as fh:
        # own session: on an exception (KeyboardInterrupt, SIGTERM) we stop it ourselves
        proc = subprocess.Popen(
            cmd, cwd=workflow_dir, env=run_env, stdout=fh, stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL, start_new_session=True,
        )  # fmt: skip
        try:
            returncode = proc.wait()
        except BaseException:
            # `timeout` forwards the SIGINT: Snakemake cancels its Slurm jobs and exits
            # (it ignores SIGTERM while waiting for its jobs)
            with contextlib.suppress(ProcessLookupError):
                proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                pass
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(proc.pid, signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=5)
            raise
    seconds = time.monotonic() - t0
    return SnakemakeRun(cmd=cmd, returncode=returncode, output=log.read_text(errors="replace"),
                        seconds=seconds, log=log)  # fmt: skip
