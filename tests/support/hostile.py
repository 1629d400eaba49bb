"""Hostile and unlucky inputs (issue 55), as data: the cases, the files they need, how to
run one ``bpmcal`` command in a fresh process, and how its ending is judged.

Used by ``tests/integration/test_hostile.py`` (every case, as a test) and by
``benchmarks/hostile_inputs.py`` (every case in a fresh process against any checkout of
bpmcal, counted by class: the record of how many end cleanly, before and after a change).

A case is a command line (``{d}``: the folder of the inputs, ``{o}``: an output folder
that does not exist yet) or a config overlay (validated as the workflow validates its
config, before any job), with what a clean ending is: the exit code, one line on stderr
that names the bad value (``needle``), no traceback, nothing left under ``{o}`` but what
the case expects there, nothing written beside the inputs, and an ending within
``max_s`` seconds (a timeout is a hang). The classes are the issue's.
"""
from __future__ import annotations

import copy
import json
import os
import resource
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from .paper import A1

#: the classes of the issue: what went wrong before, in its words
CLASSES = {
    "wrong-result": "wrong data accepted as a result",
    "system": "a full disk, a limit or a signal called a bug",
    "cache": "a damaged cache stops every run",
    "traceback": "a traceback for an input mistake",
    "hang": "a hang (or minutes) on hostile input",
    "late": "a failure the config validation could have caught",
    "hygiene": "output hygiene (escapes, folders, paths)",
}

#: the small, fast cylinder of the DEM cases (the tests' SMALL and FAST: ~300 balls)
DEM = ("--scale 0.24 --platen-velocity 0.1 --record-strain 4e-5 --threads 1 --quiet "
       "--specimen-cache {cache}")


@dataclass
class Case:
    id: str
    cls: str
    argv: str | None = None  # a bpmcal command line ({d}, {o}, {cache}); or
    config: dict | None = None  # a config overlay, merged over config/config.yaml
    exit: int = 2
    needle: str = ""  # in the one line on stderr
    lines: int | None = 1  # lines on stderr (None: any)
    max_s: float = 20.0
    dem: bool = False  # runs a (small) DEM test: seconds, not milliseconds
    slow: bool = False  # minutes: the slow tier only
    outputs: tuple = ()  # files under {o} the case leaves on purpose
    check: str = ""  # a named extra check (:data:`CHECKS`)
    fsize: int | None = None  # RLIMIT_FSIZE [bytes] of the process (ulimit -f)
    sigterm_after: float | None = None  # send SIGTERM after this many seconds
    shell: str | None = None  # run through bash with this redirection (e.g. "2>&-")
    env: dict = field(default_factory=dict)
    root: bool = False  # needs root (mounts a file system)
    setup: str = ""  # a named preparation of {o} (:data:`SETUPS`)


def _card(**kw) -> dict:
    return {**A1, **kw}


DESIGN_HEAD = ("sample_id,rmin_mm,porosity,pb_emod_GPa,pb_kratio,pb_ten_MPa,pb_coh_MPa,"
               "pb_fa_deg,fric,seed\n")
ROW = "s000,0.8,0.34,10.4,3.5,27.7,19.7,35,0.35,7\n"
LAB_HEAD = "specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3"
RANGES = json.dumps({"rmin_mm": [0.6, 1.0], "porosity": [0.2, 0.36], "pb_emod_GPa": [10, 50],
                     "pb_kratio": [1, 5], "pb_ten_MPa": [10, 50], "pb_coh_MPa": [10, 50],
                     "pb_fa_deg": [15, 55], "fric": [0.15, 0.55]}, separators=(",", ":"))


def _bomb() -> str:
    """A "billion laughs" YAML of a few hundred bytes: 9^9 values behind 8 anchors."""
    levels = ["&a [1,1,1,1,1,1,1,1,1]"]
    for prev, name in zip("abcdefg", "bcdefgh"):
        levels.append(f"&{name} [" + ",".join([f"*{prev}"] * 9) + "]")
    levels.append("[" + ",".join(["*h"] * 9) + "]")
    rest = "".join(f"{k}: {v}\n" for k, v in A1.items() if k != "rmin_mm")
    return "rmin_mm: [" + ", ".join(levels) + "]\n" + rest


def _run_files(d: Path) -> None:
    """Run files for gather, summary and vtk: good, crafted, of another test or seed."""
    import h5py
    import numpy as np

    from bpmcal.io import h5

    row = {**_card(), "seed": 7}
    ok = {"ucs_MPa": 50.0, "E_GPa": 12.0, "nu": 0.2, "stop_reason": "post_peak_drop"}
    runs = d / "runs"
    runs.mkdir()
    h5.write_run(runs / "s000.h5", h5.RunRecord(test="ucs", inputs=row, summary=ok))
    (d / "other_test").mkdir()
    h5.write_run(d / "other_test" / "s000.h5",
                 h5.RunRecord(test="bts",
                           inputs=row,
                           summary={"bts_MPa": 3.0, "stop_reason": "post_peak_drop"}))
    (d / "other_seed").mkdir()
    h5.write_run(d / "other_seed" / "s000.h5",
                 h5.RunRecord(test="ucs", inputs={**row, "seed": 8}, summary=ok))
    (d / "other_params").mkdir()
    h5.write_run(d / "other_params" / "s000.h5",
                 h5.RunRecord(test="ucs",
                           inputs={**row, "pb_emod_GPa": 30.0},
                           summary=ok))
    (d / "incomplete").mkdir()
    h5.write_run(d / "incomplete" / "s000.h5",
                 h5.RunRecord(test="ucs",
                           inputs=row,
                           status="incomplete",
                           error="incomplete: the loading stopped at its max_strain",
                           summary={**ok, "ucs_MPa": 6.1, "stop_reason": "max_strain"}))
    (d / "text_value").mkdir()
    h5.write_run(d / "text_value" / "s000.h5",
                 h5.RunRecord(test="ucs",
                           inputs=row,
                           summary={**ok, "ucs_MPa": "fifty"}))
    (d / "escape").mkdir()
    forged = "boom\x1b[2J\x1b]0;owned\x07\nstatus                   ok"
    h5.write_run(d / "escape" / "s000.h5",
                 h5.RunRecord(test="ucs", inputs=row, status="failed", error=forged))
    h5.write_run(d / "escape.h5", h5.RunRecord(test="ucs", inputs=row, summary={**ok, "note": forged}))
    # a few kB that declare 6e9 values (a chunked dataset of fill values: 44 GiB as floats)
    with h5py.File(d / "huge.h5", "w") as f:
        f.attrs.update({"schema_version": 1, "test": "ucs", "status": "ok", "error": ""})
        f.create_group("summary").attrs["ucs_MPa"] = 1.0
        g = f.create_group("particles/initial")
        g.create_dataset("position", shape=(2_000_000_000, 3), dtype="f8", chunks=(1024, 3),
                         compression="gzip")
        g.create_dataset("radius", shape=(2_000_000_000,), dtype="f8", chunks=(1024,),
                         compression="gzip")
    with h5py.File(d / "shapes.h5", "w") as f:
        f.attrs.update({"schema_version": 1, "test": "ucs", "status": "ok", "error": ""})
        f.create_group("summary")
        g = f.create_group("particles/initial")
        g.create_dataset("position", data=np.zeros((10, 2)))
        g.create_dataset("radius", data=np.ones(7))
    with h5py.File(d / "oddattrs.h5", "w") as f:
        f.attrs.update({"schema_version": 1, "test": "ucs", "status": 5, "error": ""})
    with h5py.File(d / "arrayattr.h5", "w") as f:
        f.attrs.update({"schema_version": 1, "test": "ucs", "status": "ok", "error": ""})
        f.create_group("summary").attrs["ucs_MPa"] = np.arange(3.0)


def make_inputs(d: Path) -> Path:
    """Every input file of :data:`CASES` in folder ``d`` (read only by the cases)."""
    d.mkdir(parents=True, exist_ok=True)
    (d / "a1.yaml").write_text(yaml.safe_dump(_card()))
    (d / "bomb.yaml").write_text(_bomb())
    (d / "deep.yaml").write_text("rmin_mm: " + "[" * 50_000 + "]" * 50_000 + "\n")
    os.mkfifo(d / "fifo.yaml")
    os.mkfifo(d / "fifo.h5")
    os.mkfifo(d / "fifo.csv")
    with open(d / "sparse.yaml", "wb") as f:  # 300 MB that occupy no disk
        f.truncate(300 * 2 ** 20)
    (d / "verif_str.yaml").write_text(yaml.safe_dump(
        {"card_format": 1, "specimen": "B1", "parameters": _card(), "verification": "done"}))
    (d / "transfer_list.yaml").write_text(yaml.safe_dump(
        {"card_format": 1, "specimen": "B1", "parameters": _card(), "transfer": [1, 2]}))
    (d / "longstr.yaml").write_text(yaml.safe_dump(_card(porosity="x" * 100_000)))
    (d / "design.csv").write_text(DESIGN_HEAD + ROW.replace(",7\n", ",7\n"))
    (d / "design_a1.csv").write_text(
        DESIGN_HEAD + "s000," + ",".join(str(_card()[k]) for k in
                                         ("rmin_mm", "porosity", "pb_emod_GPa", "pb_kratio",
                                          "pb_ten_MPa", "pb_coh_MPa", "pb_fa_deg",
                                          "fric")) + ",7\n")
    (d / "card.yaml").write_text(yaml.safe_dump({"card_format": 1, "specimen": "B1",
                                                 "parameters": _card(),
                                                 "targets": {"ucs_MPa": 60.0}}))
    (d / "lab_typo.csv").write_text(f"{LAB_HEAD},bts_Mpa\nB1,60,13,0.25,,5\n")
    (d / "lab_tiny_E.csv").write_text(f"{LAB_HEAD}\nB1,60,1e-300,0.25,\n")
    (d / "lab_huge.csv").write_text(f"{LAB_HEAD}\nB1,6e30,13,0.25,\n")
    (d / "lab.csv").write_text(f"{LAB_HEAD}\nB1,60,13,0.25,0.1\n")
    (d / "dataset.csv").write_text(DESIGN_HEAD.strip() + ",status\n" + "".join(
        ROW.replace("s000", f"s00{i}").strip() + ",ok\n" for i in range(10)))
    (d / "loop").symlink_to(d / "loop")
    _run_files(d)
    return d


def _gather(runs: str) -> str:
    return f"gather --design {{d}}/design_a1.csv --runs {runs} --out {{o}}/ds.csv"


CAL = ("calibrate --dataset {d}/dataset.csv --models {d}/card.yaml --lab {d}/LAB "
       "--cards {o}/B1.yaml --ranges " + RANGES + " --fixed {}")
UCS = "ucs --params {d}/a1.yaml --out {o}/r.h5"

CASES = [
    # --- a result is a result
    Case("ucs-cut-by-max-strain", "wrong-result", f"{UCS} --max-strain 0.001 {DEM}", exit=3,
         needle="INCOMPLETE", outputs=("r.h5",), check="incomplete", dem=True, max_s=120),
    Case("ucs-cut-by-max-steps", "wrong-result", f"{UCS} --max-steps 1500 {DEM}", exit=3,
         needle="max_steps", outputs=("r.h5",), check="incomplete", dem=True, slow=True,
         max_s=120),
    Case("ucs-failed-ok-incomplete", "wrong-result",
         f"{UCS} --max-strain 0.001 --failed-ok {DEM}", exit=0, needle="INCOMPLETE",
         outputs=("r.h5",), check="incomplete", dem=True, slow=True, max_s=120),
    Case("triaxial-high-sigma3-cut", "wrong-result",
         f"triaxial --params {{d}}/a1.yaml --sigma3 300 --max-strain 0.004 --out {{o}}/r.h5 "
         f"{DEM}", exit=3, needle="sigma_1 at failure", outputs=("r.h5",),
         check="incomplete", dem=True, slow=True, max_s=600),
    Case("ucs-max-strain-hopeless", "wrong-result", f"{UCS} --max-strain 1e-6 {DEM}",
         exit=2, needle="max_strain = 1e-06 stops the loading", dem=True, max_s=120),
    Case("config-max-strain-tiny", "wrong-result", config={"compression": {"max_strain": 1e-5}},
         needle="compression.max_strain: no card of the design space"),
    Case("config-bts-max-strain-tiny", "wrong-result",
         config={"bts": {"max_strain": 1e-5}}, needle="bts.max_strain"),
    Case("lab-column-typo", "wrong-result", CAL.replace("LAB", "lab_typo.csv"),
         needle="did you mean 'bts_MPa'"),
    Case("config-lab-column-typo", "wrong-result",
         config={"lab": {"csv": "{d}/lab_typo.csv"}, "study": {"reference": "none"}},
         needle="did you mean 'bts_MPa'"),
    Case("gather-other-test", "wrong-result", _gather("{d}/other_test/s000.h5"),
         needle="a run file of test 'bts', expected 'ucs'"),
    Case("gather-other-seed", "wrong-result", _gather("{d}/other_seed/s000.h5"),
         needle="its seed=8, the design row's 7"),
    Case("gather-other-params", "wrong-result", _gather("{d}/other_params/s000.h5"),
         needle="its pb_emod_GPa=30.0"),
    Case("gather-incomplete", "wrong-result", _gather("{d}/incomplete/s000.h5"), exit=0,
         lines=0, outputs=("ds.csv",), check="gathered_incomplete"),
    # --- the system: a full disk, limits, signals
    Case("write-file-size-limit", "system", f"{UCS} {DEM}", exit=4,
         needle="file too large", fsize=64 * 1024, dem=True, max_s=120),
    Case("gather-file-size-limit", "system", _gather("{d}/runs/s000.h5"), exit=4,
         needle="ds.csv: file too large", fsize=200, env={}),
    Case("write-full-disk", "system", "ucs --params {d}/a1.yaml --out {tiny}/r.h5 " + DEM,
         exit=4, needle="no space left on the device", dem=True, root=True, max_s=120),
    Case("sigterm-during-run", "system",
         "ucs --params {d}/a1.yaml --out {o}/r.h5 --scale 0.5 --threads 1 --quiet "
         "--specimen-cache {o}/cache", exit=4, needle="terminated (SIGTERM",
         sigterm_after=4.0, lines=None, dem=True, max_s=60, outputs=("cache",)),
    Case("stderr-closed", "system", "ucs --params {d}/nope.yaml --out {o}/r.h5", exit=2,
         lines=0, shell="2>&-"),
    # --- caches that heal
    Case("packing-cache-damaged", "cache",
         f"{UCS} {DEM}".replace("{cache}", "{o}/cache"), exit=0, lines=1,
         needle="is damaged", outputs=("r.h5", "cache"), setup="damaged_cache",
         check="healed_cache", dem=True, max_s=120),
    Case("numba-cache-damaged", "cache", f"{UCS} {DEM}", exit=0, lines=1,
         needle="kernel cache in", outputs=("r.h5", "nb"), setup="damaged_numba",
         env={"BPMCAL_CACHE": "{o}/nb", "NUMBA_CACHE_DIR": None}, dem=True, slow=True,
         max_s=900),
    # --- tracebacks for input mistakes
    Case("rmin-1e-100", "traceback", UCS + " --set rmin_mm=1e-100", needle="rmin_mm=1e-100"),
    Case("rmin-1e300", "traceback", UCS + " --set rmin_mm=1e300", needle="Rmax = 1.66e+300"),
    Case("emod-1e300", "traceback", UCS + " --set pb_emod_GPa=1e300",
         needle="pb_emod_GPa=1e+300 GPa"),
    Case("card-verification-not-mapping", "traceback",
         "ucs --params {d}/verif_str.yaml --out {o}/r.h5", needle="'verification' is not a mapping"),
    Case("card-transfer-not-mapping", "traceback",
         "impact --card {d}/transfer_list.yaml --out {o}/i.h5", needle="'transfer' is not a mapping"),
    Case("report-overlay-config", "traceback", "report --config CONFIG/smoke.yaml --outdir {d}",
         needle="--config"),
    Case("summary-status-not-text", "traceback", "summary {d}/oddattrs.h5", needle="status=5"),
    Case("summary-json-array-attr", "traceback", "summary {d}/arrayattr.h5 --json", exit=0,
         lines=0),
    Case("vtk-44-gib", "traceback", "vtk {d}/huge.h5 --out {o}/vtk",
         needle="declares 6,000,000,000 values"),
    Case("vtk-shapes", "traceback", "vtk {d}/shapes.h5 --out {o}/vtk", needle="not (n, 3)"),
    Case("gather-text-value", "traceback", _gather("{d}/text_value/s000.h5"), exit=0, lines=0,
         outputs=("ds.csv",), check="gathered_unreadable"),
    Case("ranges-deep-json", "traceback",
         "design --ranges " + "[" * 5000 + "]" * 5000 + " --n 8 --seed 1 --out {o}/s.csv",
         needle="JSON nested 5000 levels deep"),
    Case("ratios-denormal-step", "traceback",
         "sweep-plan --card {d}/card.yaml --models {d}/card.yaml --ratios 0.01,1e300,5e-324 "
         "--out {o}/p.csv", needle="more than 200"),
    Case("out-symlink-loop", "traceback", "ucs --params {d}/a1.yaml --out {d}/loop/r.h5",
         needle="loop"),
    Case("summary-symlink-loop", "traceback", "summary {d}/loop", needle="cannot be opened"),
    Case("set-long-value", "traceback", UCS + " --set fric=" + "x" * 100_000,
         needle="more characters", check="short_line"),
    Case("report-deep-json", "traceback",
         "report --outdir {d} --config-json " + '{"study":' * 3000 + "1" + "}" * 3000,
         needle="JSON nested 3000 levels deep"),
    Case("lab-modulus-1e-300", "traceback", CAL.replace("LAB", "lab_tiny_E.csv"),
         needle="E_GPa='1e-300'"),
    Case("config-lab-modulus-1e-300", "traceback",
         config={"lab": {"csv": "{d}/lab_tiny_E.csv"}, "study": {"reference": "none"}},
         needle="E_GPa='1e-300'"),
    Case("config-lab-ucs-6e30", "traceback",
         config={"lab": {"csv": "{d}/lab_huge.csv"}, "study": {"reference": "none"}},
         needle="ucs_MPa='6e30'"),
    Case("long-value-cut", "traceback", "ucs --params {d}/longstr.yaml --out {o}/r.h5",
         needle="more characters", check="short_line"),
    # --- hangs
    Case("yaml-alias-bomb", "hang", "ucs --params {d}/bomb.yaml --out {o}/r.h5",
         needle="aliases stand for more than", max_s=10),
    Case("yaml-deep", "traceback", "ucs --params {d}/deep.yaml --out {o}/r.h5",
         needle="nested deeper than", max_s=10),
    Case("params-fifo", "hang", "ucs --params {d}/fifo.yaml --out {o}/r.h5",
         needle="not a regular file", max_s=10),
    Case("params-dev-zero", "hang", "ucs --params /dev/zero --out {o}/r.h5",
         needle="not a regular file", max_s=10),
    Case("params-300-mb", "hang", "ucs --params {d}/sparse.yaml --out {o}/r.h5",
         needle="larger than", max_s=10),
    Case("summary-fifo", "hang", "summary {d}/fifo.h5", needle="not a regular file", max_s=10),
    Case("gather-design-fifo", "hang", "gather --design {d}/fifo.csv --runs {d}/runs/s000.h5 "
         "--out {o}/ds.csv", needle="not a regular file", max_s=10),
    Case("lab-dev-zero", "hang", CAL.replace("{d}/LAB", "/dev/zero"),
         needle="not a regular file", max_s=10),
    Case("design-20000-random-cd", "hang", "design --ranges " + RANGES
         + " --n 20000 --seed 1 --out {o}/s.csv", needle="takes minutes above 5,000", max_s=10),
    Case("design-20000-plain", "hang", "design --ranges " + RANGES
         + " --n 20000 --seed 1 --optimization none --out {o}/s.csv", exit=0, lines=0,
         outputs=("s.csv",), max_s=15),
    Case("sweep-2e10-ratios", "hang", "sweep-plan --card {d}/card.yaml --models {d}/card.yaml "
         "--ratios 0.01,200,1e-8 --out {o}/p.csv", needle="more than 200", max_s=10),
    # --- late failures: caught by the config's validation
    Case("config-lhs-seed-2^32", "late", config={"study": {"lhs_seed": 2 ** 32}},
         needle="study.lhs_seed"),
    Case("config-screen-seed-2^40", "late", config={"screening": {"seed": 2 ** 40}},
         needle="screening.seed"),
    Case("config-loop-seed-near-2^32", "late", config={"verification": {"seed": 2 ** 32 - 3}},
         needle="verification.seed"),
    Case("config-fresh-seed-2^32", "late",
         config={"verification": {"fresh_seeds": [2 ** 32, 2 ** 32 + 1]}},
         needle="verification.fresh_seeds"),
    Case("config-name-10k", "late", config={"study": {"name": "x" * 10_000}},
         needle="study.name", check="short_line"),
    Case("config-hopeless-loading", "late", config={"compression": {"platen_velocity": 1e-7}},
         needle="compression: no card of the design space"),
    Case("config-n-20000-random-cd", "late", config={"study": {"n_samples": 20_000}},
         needle="study.n_samples"),
    # --- output hygiene
    Case("summary-escapes", "hygiene", "summary {d}/escape.h5", exit=0, lines=0,
         check="no_escapes"),
    Case("gather-escapes", "hygiene", _gather("{d}/escape/s000.h5"), exit=0, lines=0,
         outputs=("ds.csv",), check="no_escapes"),
    Case("config-outdir-root", "hygiene", config={"outdir": "/"}, needle="outdir: '/'"),
    Case("config-outdir-escape", "hygiene", config={"outdir": "../../x"},
         needle="leaves the working folder"),
    Case("vtk-failed-no-folder", "hygiene", "vtk {d}/shapes.h5 --out {o}/a/b/vtk",
         needle="not (n, 3)"),
    Case("ucs-failed-no-folder", "hygiene",
         "ucs --params {d}/a1.yaml --out {o}/runs/r.h5 --end-cap 10 " + DEM,
         needle="caps would meet", dem=True, slow=True, max_s=120),
    Case("report-failed-no-folder", "hygiene",
         "report --config CONFIG/smoke.yaml --outdir {o}", needle="--config", setup="empty_o",
         outputs=(".",)),
]


# ------------------------------------------------------------------------ running a case
@dataclass
class Ending:
    code: int | None  # None: timed out (a hang)
    stdout: str
    stderr: str
    wall_s: float
    cpu_s: float = 0.0  # CPU seconds of the case's processes


def _fill(text: str, d: Path, o: Path, cache: Path, tiny: Path | None, repo: Path) -> str:
    return (text.replace("{d}", str(d)).replace("{o}", str(o)).replace("{cache}", str(cache))
            .replace("{tiny}", str(tiny)).replace("CONFIG/", f"{repo}/config/"))


#: the address space of a case's process without a DEM run [bytes]: a command that reads
#: /dev/zero to its end or expands an alias bomb fails with MemoryError instead of taking
#: the machine's memory (a DEM run, numba's and LLVM's reservations, is not limited)
CASE_ADDRESS_SPACE = 4 * 2 ** 30


def _limits(fsize, address_space=None):
    def pre():
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
        if address_space is not None:
            resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))
    return pre


def timeout_of(case: Case) -> float:
    """How long a case may run before it counts as a hang [s]."""
    return max(120.0, 3 * case.max_s) if case.dem else max(30.0, 3 * case.max_s)


CONFIG_PROBE = """
import json, sys
import yaml
from bpmcal.study.config import ConfigError, validate_config
cfg = json.loads(sys.argv[1])
try:
    validate_config(cfg, sys.argv[2], base_dir=sys.argv[3], note=lambda line: None)
except ConfigError as e:
    print(" ".join(str(e).split()), file=sys.stderr)
    sys.exit(2)
"""


def merged_config(repo: Path, overlay: dict, d: Path) -> dict:
    """``config/config.yaml`` with ``overlay`` merged over it (as ``--configfile``)."""
    base = yaml.safe_load((repo / "config" / "config.yaml").read_text())

    def merge(a, b):
        for k, v in b.items():
            if isinstance(v, dict) and isinstance(a.get(k), dict):
                merge(a[k], v)
            else:
                a[k] = copy.deepcopy(v)
    merge(base, json.loads(json.dumps(overlay).replace("{d}", str(d))))
    return base


def run(case: Case, d: Path, o: Path, cache: Path, *, repo: Path, env: dict | None = None,
        tiny: Path | None = None, timeout: float | None = None) -> Ending:
    """Run ``case`` in a fresh process (``env``: its environment, e.g. the PYTHONPATH of
    the bpmcal under test)."""
    env = {**(env or os.environ)}
    for k, v in case.env.items():
        if v is None:
            env.pop(k, None)
        else:
            env[k] = _fill(v, d, o, cache, tiny, repo)
    if case.config is not None:
        cfg = merged_config(repo, case.config, d)
        argv = [sys.executable, "-c", CONFIG_PROBE, json.dumps(cfg),
                str(repo / "workflow" / "schemas" / "config.schema.yaml"), str(repo)]
    else:
        args = _fill(case.argv, d, o, cache, tiny, repo).split(" ")
        argv = [sys.executable, "-m", "bpmcal.cli", *args]
    if case.shell:
        argv = ["bash", "-c", " ".join(f"'{a}'" for a in argv) + " " + case.shell]
    timeout = timeout_of(case) if timeout is None else timeout
    t0 = time.perf_counter()
    c0 = _children_cpu()
    p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=env, cwd=str(d), preexec_fn=_limits(
                             case.fsize, None if case.dem else CASE_ADDRESS_SPACE))
    try:
        if case.sigterm_after is not None:
            _wait_started(p, o, timeout)  # SIGTERM a run, not an interpreter still importing
            try:
                out, err = p.communicate(timeout=case.sigterm_after)
            except subprocess.TimeoutExpired:
                p.send_signal(signal.SIGTERM)
                out, err = p.communicate(timeout=timeout)
        else:
            out, err = p.communicate(timeout=timeout)
        code = p.returncode
    except subprocess.TimeoutExpired:
        p.kill()
        out, err = p.communicate()
        code = None
    return Ending(code, out, err, time.perf_counter() - t0, _children_cpu() - c0)


def _wait_started(p, o: Path, timeout: float) -> None:
    """Until the case's process has begun its run (something appeared in its output folder
    ``o``, e.g. the packing cache), it has ended, or ``timeout`` passed: on a loaded machine
    a signal sent after a fixed delay can reach it while it still imports."""
    t = time.perf_counter()
    while p.poll() is None and time.perf_counter() - t < timeout:
        if o.exists() and any(o.iterdir()):
            return
        time.sleep(0.1)


def _children_cpu() -> float:
    """CPU seconds of this process's finished children (the case's process and its own)."""
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


# ------------------------------------------------------------------------ judging it
def _check_incomplete(o: Path, ending: Ending) -> str:
    import h5py

    with h5py.File(o / "r.h5", "r") as f:
        status = f.attrs["status"]
    status = status.decode() if isinstance(status, bytes) else status
    return "" if status == "incomplete" else f"run file status {status!r}, not 'incomplete'"


def _check_gathered(status: str):
    def check(o: Path, ending: Ending) -> str:
        import pandas as pd

        row = pd.read_csv(o / "ds.csv").iloc[0]
        if row["status"] != status or pd.notna(row["ucs_MPa"]):
            return (f"gathered as status {row['status']!r}, ucs_MPa {row['ucs_MPa']!r} "
                    f"(expected {status!r}, no value)")
        return ""
    return check


def _check_no_escapes(o: Path, ending: Ending) -> str:
    text = ending.stdout
    if "\x1b" in text or "\x07" in text:
        return "a terminal escape printed raw"
    if sum(ln.split()[:1] == ["status"] for ln in text.splitlines()) > 1:
        return "a forged 'status' line"
    return ""


def _check_short_line(o: Path, ending: Ending) -> str:
    longest = max((len(ln) for ln in ending.stderr.splitlines()), default=0)
    return "" if longest <= 2000 else f"a message line of {longest:,} characters"


def _check_healed_cache(o: Path, ending: Ending) -> str:
    import numpy as np

    (f,) = (o / "cache").glob("packing_*.npz")
    with np.load(f) as z:
        return "" if z["pos"].shape[1] == 3 else "the damaged packing was not replaced"


#: the damaged packing: the cache file of the DEM cases' specimen (A1, seed 1, scale 0.24)
def _damaged_cache(o: Path, env: dict) -> None:
    from bpmcal.lab.runner import Geometry, specimen_spec

    key = specimen_spec(_card(), 1, Geometry(scale=0.24)).key()
    (o / "cache").mkdir(parents=True)
    (o / "cache" / f"packing_{key}.npz").write_bytes(b"PK\x03\x04 cut short by a full disk")


def _damaged_numba(o: Path, env: dict) -> None:
    """A copy of the bpmcal-under-test's warm numba cache in ``{o}/nb`` (its
    ``BPMCAL_CACHE``) with every compiled kernel cut to garbage (a disk that filled while
    numba wrote them)."""
    import shutil

    env = {k: v for k, v in env.items() if k != "NUMBA_CACHE_DIR"}
    h = subprocess.run([sys.executable, "-c", "from bpmcal.dem._jit import _source_hash as h; "
                                              "print(h())"],
                       env=env, capture_output=True, text=True, check=True).stdout.strip()
    root = Path(env.get("BPMCAL_CACHE") or Path.home() / ".cache" / "bpmcal")
    src = root / "numba" / h
    if not any(src.glob("*/*.nbc")):
        raise RuntimeError(f"no warm numba cache in {src}: run a DEM case first")
    dst = o / "nb" / "numba" / h
    shutil.copytree(src, dst)
    for f in dst.glob("*/*.nbc"):
        f.write_bytes(f.read_bytes()[:40])


SETUPS = {"damaged_cache": _damaged_cache, "damaged_numba": _damaged_numba,
          "empty_o": lambda o, env: o.mkdir(parents=True)}


CHECKS = {"incomplete": _check_incomplete,
          "gathered_incomplete": _check_gathered("incomplete"),
          "gathered_unreadable": _check_gathered("unreadable"),
          "no_escapes": _check_no_escapes, "short_line": _check_short_line,
          "healed_cache": _check_healed_cache}


def judge(case: Case, ending: Ending, o: Path, before: set, after: set) -> list[str]:
    """What is wrong with how ``case`` ended (empty: a clean ending). ``before`` and
    ``after``: the files beside the inputs before and after it ran."""
    bad = []
    if ending.code is None:
        return [f"hang: no end within the timeout ({ending.wall_s:.0f} s)"]
    err = ending.stderr
    if ending.code < 0 or ending.code > 128:
        bad.append(f"crash: exit {ending.code}")
    elif ending.code != case.exit:
        bad.append(f"exit {ending.code}, expected {case.exit}")
    if "Traceback" in err:
        bad.append("traceback")
    lines = err.strip().splitlines()
    if case.lines is not None and len(lines) != case.lines:
        bad.append(f"{len(lines)} line(s) on stderr, expected {case.lines}")
    if case.needle and case.needle not in err:
        bad.append(f"stderr does not say {case.needle!r}")
    if case.exit in (2, 4) and case.lines == 1 and lines and not (
            lines[0].startswith("bpmcal ") and ": error: " in lines[0]) and case.config is None:
        bad.append("the line is not 'bpmcal CMD: error: ...'")
    # the work a case does, in CPU seconds (a loaded machine stretches its wall time; a
    # process blocked forever uses none and is caught by the timeout, a hang)
    if ending.cpu_s > case.max_s:
        bad.append(f"took {ending.cpu_s:.1f} CPU s, more than {case.max_s:g} s")
    left = sorted(str(p.relative_to(o)) for p in o.rglob("*")) if o.exists() else []
    allowed = set(case.outputs)
    extra = [p for p in left if not any(p == a or p.startswith(a + "/") for a in allowed)]
    if extra:
        bad.append(f"left under the output folder: {extra[:5]}")
    if o.exists() and not case.outputs and case.config is None:
        bad.append("left the output folder (empty)")
    if after != before:
        bad.append(f"wrote beside the inputs: {sorted(map(str, after - before))[:5]}")
    if case.check and not bad:
        try:
            m = CHECKS[case.check](o, ending)
        except Exception as e:  # noqa: BLE001 - an output that cannot be read is a finding
            m = f"its output cannot be checked ({type(e).__name__}: {e})"
        if m:
            bad.append(m)
    return bad


def files_beside(d: Path) -> set:
    """Every file and folder under ``d`` (the inputs), to see that nothing was added."""
    return {p for p in d.rglob("*") if not p.is_symlink() or p.exists()} if d.exists() else set()
