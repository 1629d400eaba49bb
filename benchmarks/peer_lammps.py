"""Peer comparison: bpmcal (bonded) vs LAMMPS (frictional granular) on the dem_throughput.py case.

    python benchmarks/peer_lammps.py --n 10000 --threads 1 --steps 1000 [--json]

LAMMPS has no bonded-particle model in Debian's build, so it runs the same pack as a
frictional granular material (``pair_style gran/hooke/history``): that is the speed bar
for a contact loop (one spring-dashpot-friction law per touching pair, history kept per
pair, Verlet lists with a skin), not the same physics as bpmcal's linear + parallel-bond
pairs. The driver (run with the project's python):

1. takes the relaxed pack from ``dem_throughput.make_pack(n, seed)`` and builds bpmcal's
   model of it (``dem_throughput.bench_model``) to get the time step, the Verlet skin and
   the bonded pairs' normal stiffnesses;
2. writes a LAMMPS data file and input script to a temporary folder and runs
   ``lmp -in in.case`` (``mpirun -np <threads> lmp`` for more than one thread: Debian's
   LAMMPS has no OPENMP package, so its parallel runs use MPI ranks);
3. after LAMMPS has finished (never at the same time), runs
   ``benchmarks/dem_throughput.py --json`` with the same N, threads and steps.

It prints one JSON object, like ``peer_yade.py``::

    {"n", "threads", "steps", "bpmcal": {...}, "lammps": {...},
     "ratio_particle_steps": bpmcal / lammps, "date", "loadavg_1_5_15_before", ..._after}

If ``lmp`` is not on PATH it says how to install it (``apt-get install -y lammps``) and
exits 0: this is a benchmark, not a test.

What is the same in both runs
-----------------------------
* The N spheres (positions and radii of make_pack, radii uniform in [0.8, 1.328] mm,
  density 2294 kg/m^3) in the cube [0, L]^3 bounded by six planar walls (LAMMPS:
  ``fix wall/gran`` planes for x and y, ``fix wall/gran/region`` planes for z, so that
  the two z walls can move); the z walls approach each other at 0.02 m/s each.
* Time step: bpmcal's dt (0.8 x the critical step of the bonded pack), passed to LAMMPS.
* Neighbour skin: bpmcal's Verlet skin (0.125 r_min = 1.0e-4 m for this pack), LAMMPS
  ``neighbor <skin> bin`` with ``neigh_modify delay 0 every 1 check yes``, i.e. a rebuild
  when some atom has moved more than half the skin, as in bpmcal.
* Friction 0.5 (``xmu``); no gravity; 200 warm-up steps, then ``steps`` timed steps.
* Normal stiffness: gran/hooke/history has one constant kn for every pair; it is set to
  the mean over the bonded pairs of bpmcal's normal stiffness of a bonded pair (linear
  part + bond, 2 pi r_min^2 E / (R1 + R2) with E* = E-bar = 10 GPa), so the pack is about
  as stiff in both codes and the same dt is as safe; kt = kn / 2 (bpmcal's kappa = 2).
  Walls use the same kn and kt.

What is not the same
--------------------
* Physics: LAMMPS computes one frictional contact per *touching* pair, bpmcal one
  linear contact + one parallel bond (force, shear force, twisting and bending moment,
  failure test) per bonded pair, plus the linear contact of touching unbonded pairs.
  bpmcal therefore does more arithmetic per pair; the comparison says how fast bpmcal's
  bonded loop is against a mature contact loop on the same machine.
* Damping: bpmcal uses local (Cundall) damping 0.7; LAMMPS uses the viscous damping of
  gran/hooke/history (``gamman`` for a critical-damping ratio of 0.5 of a pair of mean
  mass, ``gammat`` = gamman / 2, ``dampflag 1``). Neither changes the cost much.
* Settling: the pack was relaxed by bpmcal with radius-dependent stiffnesses, so LAMMPS
  first lets it settle under its own law for 1000 untimed steps (the z walls start
  moving after that), then runs the 200 warm-up steps and the timed steps. The pack
  keeps about as many touching pairs as bpmcal has bonds (``contacts`` in the output).
* LAMMPS sorts atoms spatially every 1000 steps (its default); bpmcal's balls are in
  Morton order from the start.
* Timing: LAMMPS's own ``Loop time`` of the timed ``run``; bpmcal's timer around
  ``Model.cycle``. Both exclude setup. particle-steps/s = N * steps / loop time.
"""
from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _peer
import numpy as np

HERE = Path(__file__).resolve().parent
WARMUP = 200  # as dem_throughput.py
RELAX = 1000  # untimed settling of the pack under LAMMPS's law, before the warm-up
FRIC = 0.5
KRATIO = 2.0
DAMP_RATIO = 0.5  # normal viscous damping of the LAMMPS pairs (critical-damping ratio)
INSTALL_MSG = _peer.install_msg("LAMMPS", "lmp", "lammps", "peer_lammps.py")


def lammps_inputs(n: int, seed: int = 1) -> dict:
    """Pack, time step, skin and stiffness for LAMMPS, from bpmcal's model of the case."""
    sys.path.insert(0, str(HERE))
    from dem_throughput import E_MOD, RHO, WALL_SPEED, bench_model, make_pack
    pos, r, L = make_pack(n, seed)
    m, nb = bench_model(n, seed)
    bi, bj = m.bond_pairs()
    rmin = np.minimum(r[bi], r[bj])
    kn = float(np.mean(2.0 * math.pi * rmin ** 2 * E_MOD / (r[bi] + r[bj])))
    mass = RHO * 4.0 / 3.0 * math.pi * r ** 3
    meff = 0.5 * float(mass.mean())  # reduced mass of two balls of mean mass
    # gran/hooke/history: F_damp = -meff * gamman * v_n; critical damping 2 sqrt(kn meff)
    gamman = DAMP_RATIO * 2.0 * math.sqrt(kn / meff)
    return {"pos": np.asarray(pos), "r": np.asarray(r), "L": float(L), "dt": m.dt,
            "skin": m.skin, "kn": kn, "kt": kn / KRATIO, "gamman": gamman, "rho": RHO,
            "wall_speed": WALL_SPEED, "bonds": nb}


def _f(x) -> str:
    """A float as LAMMPS reads it (shortest round-trip repr)."""
    return repr(float(x))


def write_case(tmp: Path, inp: dict, steps: int):
    pos, r, L = inp["pos"], inp["r"], _f(inp["L"])
    n = r.shape[0]
    pad = 4.0 * float(r.max())
    lo, hi = _f(-pad), _f(inp["L"] + pad)
    lines = ["bpmcal benchmark pack (peer_lammps.py)", "", f"{n} atoms", "1 atom types", "",
             f"{lo} {hi} xlo xhi", f"{lo} {hi} ylo yhi", f"{lo} {hi} zlo zhi", "",
             "Atoms # sphere", ""]
    for k in range(n):
        lines.append(f"{k + 1} 1 {_f(2.0 * r[k])} {_f(inp['rho'])} {_f(pos[k, 0])} "
                     f"{_f(pos[k, 1])} {_f(pos[k, 2])}")
    (tmp / "pack.data").write_text("\n".join(lines) + "\n")
    # Kn Kt gamma_n gamma_t xmu dampflag; gamma_t NULL = gamma_n / 2
    g = f"{_f(inp['kn'])} {_f(inp['kt'])} {_f(inp['gamman'])} NULL {_f(FRIC)} 1"
    v = _f(inp["wall_speed"])
    script = f"""# generated by benchmarks/peer_lammps.py
units si
atom_style sphere
atom_modify map array
boundary f f f
newton off
comm_modify vel yes
read_data pack.data
pair_style gran/hooke/history {g}
pair_coeff * *
neighbor {_f(inp['skin'])} bin
neigh_modify delay 0 every 1 check yes
timestep {_f(inp['dt'])}
fix integ all nve/sphere
fix wx all wall/gran hooke/history {g} xplane 0.0 {L}
fix wy all wall/gran hooke/history {g} yplane 0.0 {L}
variable go equal (step>{RELAX})*(step-{RELAX})*dt
variable zlo equal {v}*v_go
variable zhi equal -{v}*v_go
region rzlo plane 0.0 0.0 0.0 0.0 0.0 1.0 side in move NULL NULL v_zlo units box
region rzhi plane 0.0 0.0 {L} 0.0 0.0 -1.0 side in move NULL NULL v_zhi units box
fix wzlo all wall/gran/region hooke/history {g} region rzlo
fix wzhi all wall/gran/region hooke/history {g} region rzhi
compute cn all contact/atom
compute ncn all reduce sum c_cn
thermo_style custom step atoms c_ncn
thermo {RELAX + WARMUP + steps}
# let the pack settle under LAMMPS's own contact law (untimed; it was relaxed in bpmcal
# with radius-dependent stiffnesses); the z walls start moving after this
run {RELAX}
run {WARMUP}
run {steps}
"""
    (tmp / "in.case").write_text(script)


def _lmp_version(exe: str) -> str:
    try:
        out = subprocess.run([exe, "-h"], capture_output=True, text=True, timeout=120).stdout
        m = re.search(r"Massively Parallel Simulator - (.+)", out)
        return m.group(1).strip() if m else "?"
    except Exception:  # noqa: BLE001 - informative only
        return "?"


def run_lammps(n: int, threads: int, steps: int, seed: int = 1, exe: str = "lmp",
               timeout: float = 3600.0) -> dict:
    inp = lammps_inputs(n, seed)
    with tempfile.TemporaryDirectory(prefix="peer_lammps_") as tmp:
        tmp = Path(tmp)
        write_case(tmp, inp, steps)
        cmd = [exe, "-in", "in.case", "-log", "log.lammps", "-nocite"]
        if threads > 1:
            mpirun = shutil.which("mpirun")
            if mpirun is None:
                raise RuntimeError("mpirun not found: LAMMPS runs on several cores with MPI "
                                   "(apt-get install -y openmpi-bin)")
            cmd = [mpirun, "--allow-run-as-root", "--oversubscribe", "--bind-to", "none",
                   "-np", str(threads)] + cmd
        env = dict(os.environ, OMP_NUM_THREADS="1")
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True,
                              timeout=timeout)
        total = time.perf_counter() - t0
        log = (tmp / "log.lammps").read_text() if (tmp / "log.lammps").exists() else ""
    loops = re.findall(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with "
                       r"(\d+) atoms", log)
    if proc.returncode != 0 or len(loops) < 3:
        tail = "\n".join((proc.stdout + proc.stderr + log).splitlines()[-30:])
        raise RuntimeError(f"lammps run failed (exit {proc.returncode}):\n{tail}")
    wall, procs, nsteps, natoms = float(loops[-1][0]), int(loops[-1][1]), int(loops[-1][2]), \
        int(loops[-1][3])
    cpu_use = re.findall(r"([0-9.]+)% CPU use with", log)
    cpu = wall * float(cpu_use[-1]) / 100.0 if cpu_use else None
    thermo = re.findall(r"^\s*(\d+)\s+(\d+)\s+([0-9.eE+-]+)\s*$", log, flags=re.M)
    touching = int(round(float(thermo[-1][2]) / 2)) if thermo else None  # pairs
    nbuilds = re.findall(r"Neighbor list builds = (\d+)", log)
    return {"n": natoms, "threads": procs, "steps": nsteps, "wall_s": wall,
            "particle_steps_per_s": natoms * nsteps / wall,
            # LAMMPS's "% CPU use" of the timed loop (per MPI task): on a shared machine,
            # with one task, N * steps / cpu_s is less sensitive to other processes
            "cpu_s": cpu, "particle_steps_per_cpu_s": natoms * nsteps / cpu if cpu else None,
            "contacts": touching,
            "contact_steps_per_s": touching * nsteps / wall if touching else None,
            "lost_atoms": n - natoms, "neighbor_builds": int(nbuilds[-1]) if nbuilds else None,
            "dt": inp["dt"], "skin": inp["skin"], "kn": inp["kn"], "kt": inp["kt"],
            "gamman": inp["gamman"], "process_s": total, "lammps_version": _lmp_version(exe)}


def main(argv=None):
    a = _peer.parser(__doc__, "--lmp", "LAMMPS executable (default: lmp on PATH)").parse_args(argv)
    return _peer.side_by_side(a, "lammps", "LAMMPS", shutil.which(a.lmp),
                              lambda e: f"LAMMPS {_lmp_version(e)}", run_lammps, INSTALL_MSG)


if __name__ == "__main__":
    sys.exit(main())
