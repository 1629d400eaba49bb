"""Peer comparison: bpmcal vs YADE (CohFrictMat) on the dem_throughput.py reference case.

    python benchmarks/peer_yade.py --n 10000 --threads 1 --steps 1000 [--json]

The driver (run with the project's python) takes the relaxed pack from
``dem_throughput.make_pack(n, seed)`` (cached in ~/.cache/bpmcal), writes it to a
temporary .npz, generates a YADE script next to it and runs
``yade -n -x -j<threads> <script>`` (YADE's own python, Debian's /usr/bin/python3) with
``OMP_NUM_THREADS=<threads>``. Then it runs ``benchmarks/dem_throughput.py --json`` with
the same N / threads / steps in a subprocess with ``NUMBA_THREADING_LAYER=omp`` (installing
yade pulls in TBB, which numba would otherwise pick; see benchmarks/README.md). The two runs
are sequential, never concurrent. It prints one JSON object::

    {"n", "threads", "steps", "bpmcal": {...}, "yade": {...},
     "ratio_particle_steps": bpmcal / yade}

If ``yade`` is not on PATH it says how to install it (``apt-get install -y yade``) and
exits 0: this is a benchmark, not a test.

What is the same in both runs
-----------------------------
* Geometry: the same N spheres (positions and radii from make_pack, radii uniform in
  [0.8, 1.328] mm, density 2294 kg/m^3), the same cube of side L bounded by six infinite,
  one-sided, frictionless planes at 0 and L (YADE ``Wall`` bodies with ``sense=+-1``).
* Bonds: every initially overlapping sphere pair (surface gap <= 0) is bonded, nothing
  else (same count in both codes); contacts made later are frictional only. Strengths are
  1e12 Pa, so no bond breaks in either code (both report ``broken``).
* Bond stiffnesses, per bond, exactly bpmcal's (E* = E-bar = 10 GPa, kappa* = kappa-bar = 2,
  lambda-bar = 1; rmin = min(R1, R2), L = R1 + R2): YADE's CohFrictPhys of each bond is
  overwritten after creation with kn = linear + bond = 2 pi rmin^2 E/L, ks = kn/2,
  kr = kn_bar I = pi E rmin^4/(4L), ktw = ks_bar J = pi E rmin^4/(4L)
  (momentRotationLaw, incremental form, elastic moments: etaRoll = etaTwist = -1).
* Initial bond force: bpmcal installs bonds with zero force while the linear part keeps
  the pack's overlap force pi rmin^2 E/L * overlap; in YADE each bond gets
  ``unp = overlap/2``, which gives the same initial force (and the same force increments).
* Walls: kn = pi r E, ks = kn/2, frictionless, in both (YADE: FrictMat walls with a
  1000x larger ``young`` so the harmonic mean gives pi r E within 0.1 %; sphere-wall
  contacts use Ig2_Wall_Sphere_ScGeom + FrictPhys + Law2_ScGeom_FrictPhys_CundallStrack).
* Friction 0.5 (frictionAngle = atan 0.5) on sphere-sphere contacts, local (Cundall,
  non-viscous) damping 0.7, no gravity, no viscous dashpots.
* Loading: walls z = 0 and z = L approach at 0.02 m/s each.
* Neighbour search skin: bpmcal's Verlet skin is 0.125 r_min with a rebuild when a ball
  has moved more than half of it; YADE's InsertionSortCollider gets
  ``verletDist = 0.0625 r_min`` (each bound grown by that, so pairs are found within about
  the same 0.125 r_min gap, and the collider reruns when a body leaves its grown bound).
  Rebuild counts are reported (bpmcal ``rebuilds``, including warm-up; YADE
  ``collider_runs``, timed part only).
* Time step: 0.8 x the critical step computed with bpmcal's formula
  (``bpmcal.dem.kernels.stiffness_timestep``: min over balls of sqrt(m/k_tran),
  sqrt(I/k_rot), over pairs within the skin, bonds adding their stiffnesses) evaluated on
  YADE's interactions; on the n=500 pack it equals bpmcal's dt to all printed digits.
* Timing: 200 warm-up steps, then the wall-clock time of ``steps`` steps (YADE
  ``O.run(steps, True)``; bpmcal ``Model.cycle``). particle-steps/s = N * steps / time
  (walls are not counted as particles).
* Cross-check (n = 500, same dt, 3200 steps, done once by hand): the force on the top
  wall was 34 273 N in bpmcal and 34 271 N in YADE (start: 31 633 N), no bond broken in
  either; so the two runs really compute the same mechanical system.

What is not the same
--------------------
* Contact law. bpmcal implements PFC's linear + linear parallel bond: two components in
  parallel, the linear one takes no tension and slips with Coulomb friction, the bond
  (own force/moment increments, stress-based tension and Mohr-Coulomb shear failure with
  beta-bar) carries tension, shear, twisting and bending. YADE's
  Law2_ScGeom6D_CohFrictPhys_CohesionMoment has one spring per direction on the total
  overlap: kn * (overlap - unp) also in tension (bpmcal: only the bond's half in tension),
  one shear spring limited by shear adhesion + Fn tan(phi) (bpmcal: the bond's shear force
  is not limited by friction, only the linear part's), and rolling/twisting springs.
  Failure criteria differ too (YADE: adhesion = cohesion * rmin^2 on forces, not the bond
  stress with its moment term) and so does the law after breakage. None of that changes
  the state here (compression, no slip of bonds, nothing breaks), but the per-contact
  arithmetic differs: bpmcal updates two components (linear + bond) per bonded pair,
  YADE one CohFrictPhys with moments.
* New (unbonded) contacts: YADE's Ip2 gives kn = pi E R1 R2/(R1+R2) (``young = pi E/2``),
  bpmcal pi rmin^2 E/(R1+R2); equal for equal radii, up to 1.66x apart otherwise. Few such
  contacts form in this small-strain run.
* Code structure: YADE runs its engine loop (ForceResetter, InsertionSortCollider,
  InteractionLoop with functor dispatch per interaction, NewtonIntegrator) over
  shared-pointer interactions and also visits potential (not yet touching) pairs found
  by the collider every step; bpmcal keeps bonds in a fixed list and searches only
  unbonded pairs. Those are the differences being measured.
* Numerics: both are explicit central-difference schemes but integrate rotations and
  rotate stored shear forces/moments differently; trajectories agree closely (see the
  cross-check) but not bit-for-bit.
* Startup: ``bpmcal.compile_s`` is numba compile/cache-load time; ``yade.setup_s`` is the
  time to build the scene in YADE's python (plus one step). Neither is in the throughput.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _peer
import numpy as np

HERE = Path(__file__).resolve().parent
E_PFC = 10e9  # E* = E-bar of dem_throughput._material
KRATIO = 2.0
FRIC = 0.5
DAMPING = 0.7
WALL_SPEED = 0.02
STRENGTH = 1e12
SKIN_FACTOR = 0.125  # bpmcal's default Verlet skin / r_min
WARMUP = 200  # as dem_throughput.py
INSTALL_MSG = _peer.install_msg("YADE", "yade", "yade", "peer_yade.py")

# --------------------------------------------------------------------------------------
# The script YADE runs (its own python). It reads the parameters from the JSON file named
# by $PEER_YADE_PARAMS and writes its result to params["out"].
YADE_SCRIPT = r'''
import json, math, os, resource, sys, time
import numpy as np
from yade import O, utils, config
from yade.wrapper import *
from yade import Vector3

t_setup = time.perf_counter()
P = json.load(open(os.environ["PEER_YADE_PARAMS"]))
d = np.load(P["pack"])
pos, rad, L = d["pos"], d["r"], float(d["L"])
n = int(rad.shape[0])
E = P["young"]

O.reset()
ball = O.materials.append(CohFrictMat(
    young=E, poisson=1.0 / P["kratio"], density=P["rho"], frictionAngle=math.atan(P["fric"]),
    isCohesive=True, normalCohesion=P["strength"], shearCohesion=P["strength"],
    momentRotationLaw=True, alphaKr=0.25, alphaKtw=0.25,
    etaRoll=-1.0, etaTwist=-1.0, fragile=True, label="balls"))
wmat = O.materials.append(FrictMat(young=P["wall_young"], poisson=1.0 / P["kratio"], density=P["rho"],
                                   frictionAngle=0.0, label="walls"))

# six one-sided infinite planes, in dem_throughput's order: (0, +n), (L, -n) per axis
walls = []
for ax in range(3):
    walls.append(O.bodies.append(utils.wall(0.0, axis=ax, sense=1, material=wmat)))
    walls.append(O.bodies.append(utils.wall(L, axis=ax, sense=-1, material=wmat)))
ids = O.bodies.append([utils.sphere((float(p[0]), float(p[1]), float(p[2])), float(r),
                                    material=ball) for p, r in zip(pos, rad)])
O.bodies[walls[4]].state.vel = Vector3(0, 0, P["wall_speed"])
O.bodies[walls[5]].state.vel = Vector3(0, 0, -P["wall_speed"])

O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Wall_Aabb()], verletDist=P["verlet_dist"],
                          label="collider"),
    InteractionLoop(
        [Ig2_Sphere_Sphere_ScGeom6D(), Ig2_Wall_Sphere_ScGeom()],
        [Ip2_CohFrictMat_CohFrictMat_CohFrictPhys(setCohesionNow=True,
                                                  setCohesionOnNewContacts=False,
                                                  label="ip2"),
         Ip2_FrictMat_FrictMat_FrictPhys()],
        [Law2_ScGeom6D_CohFrictPhys_CohesionMoment(useIncrementalForm=True, label="law"),
         Law2_ScGeom_FrictPhys_CundallStrack()]),
    NewtonIntegrator(damping=P["damping"], gravity=(0, 0, 0), label="newton"),
]
# step 0 (at a negligible dt): collider, then bonds on every overlapping pair
# (setCohesionNow); the time step is set after it, once the interactions exist
O.dt = 1e-12
O.run(1, True)
# Per bond, bpmcal's stiffnesses (linear + parallel bond, lambda = 1, kappa = kappa-bar):
#   kn = 2 pi rmin^2 E/L, ks = kn/kappa, kr = kn_bar I = pi E rmin^4/(4 L),
#   ktw = ks_bar J = pi E rmin^4/(2 kappa L), with rmin = min(R1, R2), L = R1 + R2.
# bpmcal installs the bond with zero force while the linear part keeps the overlap force
# pi rmin^2 E/L * overlap; the same initial normal force here is kn * (overlap - unp)
# with unp = overlap/2.
Epfc, kap = P["e_pfc"], P["kratio"]
nb = 0
for i in O.interactions:
    if i.isReal and isinstance(i.phys, CohFrictPhys) and not i.phys.cohesionBroken:
        r1, r2 = O.bodies[i.id1].shape.radius, O.bodies[i.id2].shape.radius
        rm, lc = min(r1, r2), r1 + r2
        ph = i.phys
        ph.kn = 2.0 * math.pi * rm * rm * Epfc / lc
        ph.ks = ph.kn / kap
        ph.kr = math.pi * Epfc * rm ** 4 / (4.0 * lc)
        ph.ktw = math.pi * Epfc * rm ** 4 / (2.0 * kap * lc)
        ph.unp = 0.5 * i.geom.penetrationDepth
        nb += 1

def critical_dt():
    """bpmcal's (PFC's) estimate: min over balls of sqrt(m/k_tran), sqrt(I/k_rot), k summed
    over every pair the collider has (touching or within the skin) and the wall contacts,
    bonded pairs adding the bond's stiffnesses (cf. bpmcal.dem.kernels.stiffness_timestep)."""
    nbod = len(O.bodies)
    skin = 2.0 * P["verlet_dist"]
    kt, kr = np.zeros(nbod), np.zeros(nbod)
    for i in O.interactions.all():
        a, b = i.id1, i.id2
        if a < 6 and b < 6:  # wall-wall (walls' bounds are infinite): not a contact
            continue
        if a < 6 or b < 6:  # wall: kn = pi r E
            s = max(a, b)
            rs = O.bodies[s].shape.radius
            kn = math.pi * rs * Epfc
            kt[s] += max(kn, kn / kap)
            kr[s] += kn / kap * rs * rs
            continue
        r1, r2 = O.bodies[a].shape.radius, O.bodies[b].shape.radius
        rm, lc = min(r1, r2), r1 + r2
        if not i.isReal and (O.bodies[a].state.pos - O.bodies[b].state.pos).norm() - lc > skin:
            continue  # bounds overlap but farther apart than bpmcal's Verlet skin
        kn = math.pi * rm * rm * Epfc / lc
        ks = kn / kap
        ktr, ksh, krb = max(kn, ks), ks, 0.0
        if i.isReal and isinstance(i.phys, CohFrictPhys) and not i.phys.cohesionBroken:
            ktr += max(kn, ks)  # bond: kn_bar A = kn here (lambda = 1, E-bar = E*)
            ksh += ks
            krb = max(math.pi * Epfc * rm ** 4 / (4 * lc), math.pi * Epfc * rm ** 4 / (2 * kap * lc))
        kt[a] += ktr
        kt[b] += ktr
        kr[a] += ksh * r1 * r1 + krb
        kr[b] += ksh * r2 * r2 + krb
    best = np.inf
    for b in O.bodies:
        if b.id < 6:
            continue
        if kt[b.id] > 0:
            best = min(best, math.sqrt(b.state.mass / kt[b.id]))
        if kr[b.id] > 0:
            best = min(best, math.sqrt(b.state.inertia[0] / kr[b.id]))
    return best


dt_crit = critical_dt()
O.dt = P["dt"] if P.get("dt") else 0.8 * dt_crit
wkn = [i.phys.kn / (math.pi * Epfc * O.bodies[max(i.id1, i.id2)].shape.radius)
       for i in O.interactions if i.isReal and min(i.id1, i.id2) < 6]
setup_s = time.perf_counter() - t_setup

O.run(P["warmup"] - 1, True)  # warm-up (page faults, first collider runs)
dt = O.dt
runs0 = collider.numAction
it0 = O.iter
c1 = time.process_time()
t1 = time.perf_counter()
O.run(P["steps"], True)
wall = time.perf_counter() - t1
cpu = time.process_time() - c1
steps = O.iter - it0

real = bonds = 0
for i in O.interactions:
    if i.isReal and i.id1 >= 6 and i.id2 >= 6:
        real += 1
        if isinstance(i.phys, CohFrictPhys) and not i.phys.cohesionBroken:
            bonds += 1
nint = len(O.interactions)
fz = [O.forces.f(walls[4])[2], O.forces.f(walls[5])[2]]  # bottom/top wall, last step
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
res = {"n": n, "threads": P["threads"], "steps": steps, "wall_s": wall,
       "particle_steps_per_s": n * steps / wall,
       "cpu_s": cpu, "particle_steps_per_cpu_s": n * steps / cpu,
       "contact_steps_per_s": real * steps / wall,
       "bonds": nb, "bonds_intact": bonds, "broken": nb - bonds,
       "contacts_and_bonds": real, "bonds_per_ball": 2.0 * nb / n,
       "interactions_incl_potential": nint, "dt": dt, "dt_crit": dt_crit,
       "sim_time_s": O.time, "wall_force_z": fz,
       "wall_kn_over_pi_r_E": [min(wkn), max(wkn)] if wkn else None,
       "collider_runs": collider.numAction - runs0, "setup_s": setup_s,
       "peak_rss_mb": peak, "omp_threads": O.numThreads, "yade_version": config.version}
with open(P["out"], "w") as f:
    json.dump(res, f)
print("PEER_YADE_JSON " + json.dumps(res))
sys.stdout.flush()
'''


def _yade_version(exe: str) -> str:
    try:
        out = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=120)
        return (out.stdout.strip().splitlines() or ["?"])[-1]
    except Exception:  # noqa: BLE001 - informative only
        return "?"


def run_yade(n: int, threads: int, steps: int, seed: int = 1, exe: str = "yade",
             timeout: float = 3600.0, dt: float | None = None) -> dict:
    """Run the case in YADE; ``dt`` fixes the time step (default: 0.8 x the critical step
    computed with bpmcal's formula on YADE's interactions)."""
    sys.path.insert(0, str(HERE))
    from dem_throughput import RHO, make_pack
    pos, r, L = make_pack(n, seed)
    with tempfile.TemporaryDirectory(prefix="peer_yade_") as tmp:
        tmp = Path(tmp)
        np.savez(tmp / "pack.npz", pos=np.asarray(pos), r=np.asarray(r), L=float(L))
        params = {
            "pack": str(tmp / "pack.npz"), "out": str(tmp / "result.json"),
            "threads": threads, "steps": steps, "warmup": WARMUP,
            "rho": RHO, "young": 0.5 * math.pi * E_PFC,
            "wall_young": 0.5e3 * math.pi * E_PFC, "kratio": KRATIO, "fric": FRIC,
            "e_pfc": E_PFC, "strength": STRENGTH,
            "damping": DAMPING, "wall_speed": WALL_SPEED,
            "verlet_dist": 0.5 * SKIN_FACTOR * float(np.min(r)), "dt": dt,
        }
        (tmp / "params.json").write_text(json.dumps(params))
        script = tmp / "peer_yade_case.py"
        script.write_text(YADE_SCRIPT)
        env = dict(os.environ, PEER_YADE_PARAMS=str(tmp / "params.json"),
                   OMP_NUM_THREADS=str(threads))
        env.pop("DISPLAY", None)
        t0 = time.perf_counter()
        proc = subprocess.run([exe, "-n", "-x", f"-j{threads}", str(script)], cwd=tmp, env=env,
                              capture_output=True, text=True, timeout=timeout)
        total = time.perf_counter() - t0
        out = tmp / "result.json"
        if not out.exists():
            tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-30:])
            raise RuntimeError(f"yade run failed (exit {proc.returncode}):\n{tail}")
        res = json.loads(out.read_text())
    res["process_s"] = total
    return res


def main(argv=None):
    a = _peer.parser(__doc__, "--yade", "yade executable (default: yade on PATH)",
                     bpmcal_steps=True).parse_args(argv)
    return _peer.side_by_side(a, "yade", "YADE", shutil.which(a.yade),
                              _yade_version, run_yade, INSTALL_MSG)


if __name__ == "__main__":
    sys.exit(main())
