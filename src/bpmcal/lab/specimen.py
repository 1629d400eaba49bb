"""Specimen genesis: a bonded cylinder of balls, PFC style, with a small locked-in stress.

Procedure (after Potyondy & Cundall 2004 and PFC's ``ball distribute``):

1. **Distribute** (``distribute``): radii uniform in [Rmin, ratio x Rmin] are drawn until
   the summed ball volume reaches (1 - n) V of the vessel (a cylinder D x H); centres are
   placed uniformly so that every ball lies inside the vessel. Overlaps are allowed: this
   is PFC's *nominal* porosity n, and n = 0.20 means heavily overlapped placement.
2. **Relax** (``relax_packing``): frictionless balls in frictionless vessel walls (a
   cylinder and two planes; translation only, as every force is central), local damping
   0.5, speeds clipped during the first steps while the initial overlaps are pushed apart,
   until the mean unbalanced-force ratio (mean |unbalanced force| / mean |contact force|,
   PFC's ``ratio-average``) falls below ``relax_ratio`` (1e-2). That is looser than PFC's
   default for a final equilibrium, on purpose: the contact forces of this state are
   scaled down by ~1e-3 in step 4, and so is any residual imbalance; a tighter ratio costs
   2-10x the steps while the overcompressed pack keeps rearranging. The relaxed geometry
   does not depend on the contact modulus (the same number of steps at dt ~ sqrt(m/k)), so
   it is computed once at a reference modulus and cached (``lab.packing_cache``:
   ``get_packing``): a packing depends only on geometry, Rmin, ratio, density, n, seed.
3. **Floaters**: balls with fewer than 3 contacts are enlarged until they touch three
   neighbours (if that needs less than +25 % radius; the rest are reported).
4. **Install the material** (``build_specimen``): the linear contacts get E* = Ecp and
   kappa* = kp* (the paper's assumption), the packing re-equilibrates in the vessel, and
   the isotropic stress on the vessel walls is measured. At a nominal porosity below the
   random-close-packing limit (~0.36 for this size ratio) that stress is large (tens to
   hundreds of MPa), because the overlaps that realise the requested porosity remain.
   It is reduced to ``sigma0`` (0.1 MPa, as P&C) without moving a ball: every contacting
   pair gets a linear reference gap (PFC ``rgap``) that scales its overlap force by
   sigma0/sigma. P&C instead shrink all radii, which would raise every n below ~0.36 to
   ~0.36 and erase the porosity the study varies; the reference gap keeps the geometry,
   the coordination number and the nominal porosity.
5. **Bond** every pair with surface gap <= ``install_gap`` (0: touching/overlapping),
   relieve the ball-wall contacts the same way, set the friction, remove the lateral
   wall and let the specimen settle (same ratio criterion) between the end walls, which
   stay in place as the loading platens (PFC practice: the end faces are flat because
   they were packed against them). Other tests keep other parts of the vessel
   (``boundary``): the triaxial test keeps all of it (the cylinder becomes the
   servo-controlled confining wall), the Brazilian test none of it (the disc settles
   free and gets its own platens across a diameter).

Two ways to do steps 4-5 (``build_specimen(genesis=...)``; both start from the same cached
packing, so they can be compared on one packing):

- ``"bpmcal"``: as above; the pairs are bonded at ``install_gap`` (default 0:
  touching/overlapping pairs only) and the locked-in stress is relieved to ``sigma0``.
- ``"pfc"`` (the default, ``DEFAULT_GENESIS``): the relief and bonding of Itasca's
  tutorial scripts (``contact method bond gap``, then the linear part in incremental
  mode, ``lin_mode 1``, with its forces reset, ``lin_force 0``): every pair within a
  *positive* installation gap (default
  ``PFC_GAP_RATIO`` x Rmin = 0.0625 Rmin, the tutorials' 0.5e-4 m at Rmin = 0.8 mm) is
  bonded, and every existing overlap - ball-ball and ball-wall - carries no force from
  then on: the linear reference gap of an overlapping pair is set to its current gap
  (the equivalent of PFC's incremental mode after ``lin_force 0`` while the pair stays in
  contact), that of a bonded pair with a positive gap stays 0 (its linear part, as in
  PFC, starts when the surfaces touch). ``sigma0`` does not apply: the locked-in stress
  is zero. No dashpot is added: the tutorials' normal dashpot (dp_nratio 0.5) changed
  sigma_c by -2.4 and +3.0 % and E by < 0.3 % on two packings (A1, scale 0.4),
  within the packing scatter, and the paper does not mention one; give the material a
  ``dp_nratio`` to use it.

Everything is seeded; the same inputs give bitwise-identical specimens.

Bounds and feedback: the relaxation stops after ``SpecimenSpec.max_relax_steps``
(200,000; a GenesisError), the settling of steps 4-5 after ``max_steps`` in total when
given (the genesis step budget, ``bpmcal ucs --genesis-max-steps``; a GenesisError
naming the phase and its unbalanced-force ratio); ``progress`` receives
``{"phase", "steps", "ratio", "target", "wall_s"}`` after every 500 steps; steps run
through ``stepping.cycle`` so that Ctrl-C is honoured within a fraction of a second.
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from .. import params as P
from ..dem import FlatJointMaterial, Material, Model
from ..dem.errors import InputError
from ..dem.material import stiffest_modulus
from ..dem.order import morton_order
from ..exact_math import libm_pow
from .microstructure import Microstructure, install_microstructure, install_strength_scatter
from .stepping import cycle

#: modulus used while relaxing the packing (the relaxed geometry does not depend on it)
E_REF = 1.0e9
#: local damping while the overlapped packing relaxes: with 0.5 the frictionless pack
#: finds its jammed state in about half the steps it needs at 0.7 (measured, 6 packs)
RELAX_DAMPING = 0.5
#: unbalanced-force ratio of the bonded specimen's final settling (bonded packs
#: equilibrate quickly, and a drifting specimen would corrupt the lateral strain)
SETTLE_RATIO = 1e-3
#: genesis version: part of the cache key; bump when the procedure changes (5: ball masses
#: from the C library's pow, so packings no longer depend on the host's numpy kernels)
GENESIS_VERSION = 5
#: genesis procedures of steps 4-5 (``build_specimen(genesis=...)``)
GENESES = ("bpmcal", "pfc")
#: the genesis when none is given: the one closer to PFC3D on the paper's A1 set
#: (docs/measurements/2026-11-26-a1-geneses.md: 8-13 % more sigma_c and 5-8 % more E than
#: "bpmcal" on the same packings, both still below PFC3D)
DEFAULT_GENESIS = "pfc"
#: installation gap of the PFC-style genesis / Rmin: Itasca's tutorial scripts bond pairs
#: within 0.5e-4 m at Rmin = 0.8 mm (0.0625 Rmin), scaled here with Rmin
PFC_GAP_RATIO = 0.0625


def default_install_gap(genesis: str, rmin: float) -> float:
    """Installation gap [m] of a genesis when none is given: 0 for ``"bpmcal"``,
    ``PFC_GAP_RATIO`` x ``rmin`` for ``"pfc"``."""
    if genesis not in GENESES:
        raise InputError(f"genesis={genesis!r}: expected one of {', '.join(GENESES)}")
    return PFC_GAP_RATIO * float(rmin) if genesis == "pfc" else 0.0


class GenesisError(RuntimeError):
    """The specimen could not be built for this parameter combination (the packing did not
    reach equilibrium within the step limit)."""


@dataclass(frozen=True)
class SpecimenSpec:
    """Geometry and packing inputs of a cylindrical specimen (SI units)."""

    diameter: float  # m
    height: float  # m
    rmin: float  # m
    porosity: float  # nominal, as PFC's ball distribute
    seed: int
    ratio: float = P.RADIUS_RATIO
    density: float = P.DENSITY
    relax_ratio: float = 1e-2  # mean unbalanced-force ratio for equilibrium
    max_relax_steps: int = 200_000

    def __post_init__(self):
        for name in ("diameter", "height", "rmin", "density"):
            v = getattr(self, name)
            if not (float(v) > 0 and math.isfinite(float(v))):
                raise InputError(f"{name}={v!r}: expected a positive number (SI units)")
        if not (0.0 < float(self.porosity) < 0.9):
            raise InputError(f"porosity={self.porosity!r}: expected 0 < n < 0.9 (nominal, "
                             "as PFC's ball distribute)")
        if not (float(self.ratio) >= 1.0):
            raise InputError(f"ratio={self.ratio!r}: expected Rmax/Rmin >= 1")
        rmax = self.ratio * self.rmin
        if self.diameter < 6 * rmax or self.height < 6 * rmax:
            raise InputError(
                f"specimen {self.diameter * 1e3:g} x {self.height * 1e3:g} mm is too small for "
                f"Rmax = {rmax * 1e3:g} mm: need at least 3 ball diameters across")

    @classmethod
    def from_paper_units(cls, rmin_mm, porosity, seed, scale=1.0, diameter_mm=50.0,
                         height_mm=100.0, **kw):
        """The paper's 50 x 100 mm cylinder shrunk by ``scale`` (Rmin is not scaled)."""
        s = float(scale)
        if not (0 < s <= 10):
            raise InputError(f"scale={scale!r}: expected a factor in (0, 10]")
        return cls(diameter=diameter_mm * 1e-3 * s, height=height_mm * 1e-3 * s,
                   rmin=rmin_mm * 1e-3, porosity=float(porosity), seed=int(seed), **kw)

    def key(self) -> str:
        d = asdict(self)
        d["genesis_version"] = GENESIS_VERSION
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]

    @property
    def volume(self) -> float:
        return math.pi * (0.5 * self.diameter) ** 2 * self.height


@dataclass
class Packing:
    """A relaxed, unbonded packing (output of steps 1-3)."""

    spec: SpecimenSpec
    pos: np.ndarray
    radius: np.ndarray
    report: dict = field(default_factory=dict)


def distribute(spec: SpecimenSpec) -> tuple[np.ndarray, np.ndarray]:
    """Step 1: radii and centres, summed volume (1 - n) V (overlaps allowed)."""
    rng = np.random.default_rng(spec.seed)
    target = (1.0 - spec.porosity) * spec.volume
    rmin, rmax = spec.rmin, spec.ratio * spec.rmin
    mean_v = 4.0 / 3.0 * math.pi * (rmax ** 4 - rmin ** 4) / (4 * (rmax - rmin)) if rmax > rmin \
        else 4.0 / 3.0 * math.pi * rmin ** 3
    radii = []
    vol = 0.0
    while vol < target:
        batch = rng.uniform(rmin, rmax, max(16, int(1.2 * (target - vol) / mean_v) + 1))
        for r in batch:
            radii.append(r)
            vol += 4.0 / 3.0 * math.pi * r ** 3
            if vol >= target:
                break
    r = np.array(radii)
    n = r.shape[0]
    R = 0.5 * spec.diameter
    rho = np.sqrt(rng.uniform(0.0, 1.0, n)) * (R - r)
    phi = rng.uniform(0.0, 2.0 * math.pi, n)
    z = r + rng.uniform(0.0, 1.0, n) * (spec.height - 2 * r)
    pos = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])
    order = morton_order(pos)
    return pos[order], r[order]


def _vessel(m: Model, spec: SpecimenSpec):
    """Frictionless vessel: cylinder (id 0), bottom (1) and top (2) planes."""
    m.add_cylinder_wall((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.5 * spec.diameter)
    m.add_plane_wall((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    m.add_plane_wall((0.0, 0.0, spec.height), (0.0, 0.0, -1.0))


def _genesis_material(emod=E_REF, kratio=1.0) -> Material:
    return Material(emod=emod, kratio=kratio, fric=0.0, pb_emod=emod, pb_kratio=kratio,
                    pb_ten=1.0, pb_coh=1.0, pb_fa=0.0)


class _StepBudget:
    """Total steps allowed for the settling phases of ``build_specimen``."""

    def __init__(self, total):
        self.total = None if total is None else int(total)
        self.used = 0

    def limit(self, max_steps: int) -> int:
        return max_steps if self.total is None else min(max_steps, max(0, self.total - self.used))

    def spend(self, steps: int, phase: str, ratio: float, tol: float):
        self.used += int(steps)
        if self.total is not None and ratio > tol and self.used >= self.total:
            raise GenesisError(
                f"the specimen did not settle within the genesis step budget of "
                f"{self.total:,} steps (--genesis-max-steps): phase '{phase}' stopped at "
                f"unbalanced-force ratio {ratio:.3g} > {tol:g}")


def _solve(m: Model, tol: float, max_steps: int, chunk: int = 500, progress=None,
           phase: str = "", budget: _StepBudget | None = None) -> dict:
    """Cycle until the mean unbalanced-force ratio is <= tol (or max_steps, or the budget
    is used up: GenesisError)."""
    s0, t0 = m.step, time.perf_counter()
    ratio = m.unbalanced_ratio()
    limit = max_steps if budget is None else budget.limit(max_steps)
    while ratio > tol and m.step - s0 < limit:
        cycle(m, chunk)
        ratio = m.unbalanced_ratio()
        if progress is not None:
            progress({"phase": phase, "steps": m.step - s0, "ratio": float(ratio),
                      "target": tol, "wall_s": time.perf_counter() - t0})
    if budget is not None:
        budget.spend(m.step - s0, phase, ratio, tol)
    return {"steps": m.step - s0, "ratio": float(ratio), "converged": bool(ratio <= tol)}


#: reference stress of the pfc genesis's settling criterion [Pa] (P&C's locked-in 0.1 MPa)
PFC_SETTLE_STRESS = 0.1e6


def _settle_force_free(m: Model, spec: SpecimenSpec, chunk: int = 500, progress=None,
                       budget: _StepBudget | None = None) -> dict:
    """Settling of the pfc genesis, whose specimen starts with no force at all (every
    overlap relieved): cycle until the mean unbalanced force of the balls is at most
    ``SETTLE_RATIO`` x ``PFC_SETTLE_STRESS`` x pi Rmin^2 (the unbalanced-force ratio of
    ``_solve`` would divide round-off by round-off). ``ratio`` in the result is that mean
    force over the reference force."""
    fref = PFC_SETTLE_STRESS * math.pi * spec.rmin ** 2
    s0, t0 = m.step, time.perf_counter()
    limit = spec.max_relax_steps if budget is None else budget.limit(spec.max_relax_steps)

    def mean_force():
        f, _ = m.ball_forces()
        free = m.fix_flags == 0
        return float(np.linalg.norm(f[free], axis=1).mean()) / fref if free.any() else 0.0

    ratio = mean_force()
    while ratio > SETTLE_RATIO and m.step - s0 < limit:
        cycle(m, chunk)
        ratio = mean_force()
        if progress is not None:
            progress({"phase": "settle bonded", "steps": m.step - s0, "ratio": ratio,
                      "target": SETTLE_RATIO, "wall_s": time.perf_counter() - t0})
    if budget is not None:
        budget.spend(m.step - s0, "settle bonded", ratio, SETTLE_RATIO)
    return {"steps": m.step - s0, "ratio": ratio, "converged": bool(ratio <= SETTLE_RATIO)}


def _close_pairs(pos, reach):
    """Every pair (i, j), i < j, of centres within ``reach`` [m] of each other (plus,
    possibly, a few slightly farther: callers filter by their own distance test), found by
    a sweep along the longest extent of the packing: numpy only, no tree (importing
    scipy.spatial alone cost ~0.07 s of every sample job)."""
    n = pos.shape[0]
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    ax = int(np.argmax(pos.max(axis=0) - pos.min(axis=0)))
    order = np.argsort(pos[:, ax], kind="stable")
    x = pos[order, ax]
    r2 = float(reach) * float(reach)
    out_i, out_j = [], []
    for k in range(1, n):
        # the k-th next ball along the axis: once no pair at offset k is within reach
        # along the axis, no pair at a larger offset is
        near = np.flatnonzero(x[k:] - x[:-k] <= reach)
        if near.size == 0:
            break
        a, b = order[near], order[near + k]
        d = pos[b] - pos[a]
        keep = np.einsum("ij,ij->i", d, d) <= r2 * (1.0 + 1e-9)
        out_i.append(np.minimum(a[keep], b[keep]))
        out_j.append(np.maximum(a[keep], b[keep]))
    if not out_i:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_i), np.concatenate(out_j)


def _fix_floaters(pos, radius, ncontacts, max_overlap, rmax_factor=1.25):
    """Enlarge balls with fewer than 3 contacts until they touch three neighbours, when
    that costs at most +25 % radius and overlaps no neighbour by more than
    ``max_overlap`` [m] (the packing's median contact overlap): a larger overlap would be
    a loaded spring that throws its neighbours about. The rest stay floaters."""
    floaters = np.flatnonzero(ncontacts < 3)
    if floaters.size == 0:
        return radius, 0, 0
    r = radius.copy()
    reach = 2.0 * float(radius.max()) * rmax_factor
    fixed = 0
    for i in floaters:
        # the balls whose centres lie within reach (brute force: floaters are few)
        sep = pos - pos[i]
        near = np.einsum("ij,ij->i", sep, sep) <= reach * reach
        near[i] = False
        nb = np.flatnonzero(near)
        if len(nb) < 3:
            continue
        d = np.sort(np.linalg.norm(pos[nb] - pos[i], axis=1) - r[nb])
        need = d[2] * (1.0 + 1e-9)
        if r[i] < need <= rmax_factor * radius[i] and need - d[0] <= max_overlap:
            r[i] = need
            fixed += 1
    return r, int(floaters.size), fixed


def _count_touching(pos, radius, gap):
    """Pairs with surface gap <= ``gap``, counted independently of the engine's lists
    (``_close_pairs``, not the engine's cell grid)."""
    i, j = _close_pairs(pos, 2.0 * float(radius.max()) + max(gap, 0.0))
    if i.size == 0:
        return 0
    d = np.linalg.norm(pos[j] - pos[i], axis=1)
    return int(np.count_nonzero(d - radius[i] - radius[j] <= gap))


def _touching_per_ball(m) -> float:
    """Listed pairs whose balls overlap (surface gap < 0), twice, per ball."""
    i, j = m.pairs()
    return float(2.0 * np.count_nonzero(m.pair_gaps(i, j) < 0.0) / m.n)


def relax_packing(spec: SpecimenSpec, progress=None, threads=None) -> Packing:
    """Steps 1-3 at the reference modulus (frictionless balls and vessel); ``threads``:
    numba threads (None: leave numba's setting; the packing is the same for any number)."""
    pos, r = distribute(spec)
    m = Model(pos, r, spec.density, _genesis_material(), damping=RELAX_DAMPING,
              skin=0.25 * spec.rmin, threads=threads)
    _vessel(m, spec)
    # frictionless balls in a frictionless vessel: central forces only, so the spins
    # never act back on the positions; translation only is the same packing, bit for
    # bit, for less work per step (Model.set_spin)
    m.set_spin(False)
    m.set_timestep(None)
    # clear the initial overlaps: speeds clipped to 2 % of Rmin per step
    m.set_speed_cap(0.02 * spec.rmin / m.dt)
    for _ in range(10):
        cycle(m, 200)
        m.set_timestep(None)
        m.set_speed_cap(0.02 * spec.rmin / m.dt)
    m.set_speed_cap(0.0)
    m.set_timestep(None)
    info = _solve(m, spec.relax_ratio, spec.max_relax_steps, progress=progress,
                  phase="relax packing")
    if not info["converged"]:
        raise GenesisError(f"packing did not reach equilibrium: unbalanced-force ratio "
                           f"{info['ratio']:.3g} > {spec.relax_ratio:g} after {info['steps']} "
                           f"steps (n={spec.porosity:g}, Rmin={spec.rmin * 1e3:g} mm)")
    z = m.coordination_numbers()
    g = m.pair_gaps()
    typical = float(np.median(-g[g < 0])) if np.any(g < 0) else 0.0
    r2, nfloat, nfixed = _fix_floaters(m.positions, r, z, typical)
    report = {
        "n_balls": int(m.n),
        "relax_steps": int(m.step),
        "relax_ratio": info["ratio"],
        "relax_converged": info["converged"],
        "floaters": nfloat,
        "floaters_enlarged": nfixed,
        "porosity_nominal_distributed": float(1.0 - (4 / 3 * np.pi * libm_pow(r, 3)).sum()
                                               / spec.volume),
    }
    return Packing(spec=spec, pos=m.positions.copy(), radius=r2, report=report)


@dataclass
class Specimen:
    """A bonded specimen ready for testing."""

    model: Model
    spec: SpecimenSpec
    material: Material
    report: dict
    surface: np.ndarray  # balls that touched the lateral vessel wall (lateral strain)
    z_bottom: float  # bottom face (platen position) [m]
    z_top: float  # top face [m]
    radius0: float  # specimen radius at the start of testing [m]
    platens: tuple = (0, 1)  # wall ids of the bottom and top platens (the vessel's ends)
    lateral_wall: int | None = None  # wall id of the vessel's cylinder when it was kept
    boundary: str = "platens"  # which vessel walls were kept (see build_specimen)


def wall_stresses(m: Model, spec: SpecimenSpec) -> tuple[float, float]:
    """(axial, lateral) compressive stress on the vessel walls [Pa] at the last step."""
    m.energies()  # forces of the current state
    area = math.pi * (0.5 * spec.diameter) ** 2
    s_ax = 0.5 * (abs(m.wall_force(1)[2]) + abs(m.wall_force(2)[2])) / area
    s_lat = m.wall_radial_force(0) / (2 * math.pi * 0.5 * spec.diameter * spec.height)
    return float(s_ax), float(s_lat)


#: which walls of the vessel stay after bonding (``build_specimen(boundary=...)``)
BOUNDARIES = ("platens", "vessel", "free")


def speed_guard(material: Material, density: float) -> float:
    """Blow-up guard [m/s] of a specimen's model: twice the P-wave speed of the stiffer
    spring, sqrt(max(E*, Ebar) / rho), but at least 500 m/s. While the overlapped packing
    settles under the real moduli, ball speeds scale with that wave speed (~200-500 m/s
    at 100 GPa), so a fixed 500 m/s would stop a stiff rock's genesis although nothing
    blew up; a real blow-up grows without bound and is still caught."""
    e = stiffest_modulus(material)
    return max(500.0, 2.0 * math.sqrt(e / float(density)))


def build_specimen(packing: Packing, material: Material | FlatJointMaterial, *,
                   sigma0: float = 0.1e6, install_gap: float | None = None,
                   damping: float = 0.7, threads=None, progress=None,
                   max_steps: int | None = None, boundary: str = "platens",
                   genesis: str = DEFAULT_GENESIS,
                   microstructure: Microstructure | None = None) -> Specimen:
    """Steps 4-5: install the material, relieve the locked-in stress (to ``sigma0`` with
    ``genesis="bpmcal"``, to zero with ``"pfc"``: see the module docstring), bond the
    pairs within ``install_gap`` [m] (None: the genesis's default, ``default_install_gap``),
    remove (part of) the vessel, settle (at most ``max_steps`` steps in total, else
    GenesisError).

    ``boundary`` says which vessel walls stay for the test: ``"platens"`` (UCS, impact)
    removes the cylinder and keeps the end walls as platens (wall ids 0, 1);
    ``"vessel"`` (triaxial) keeps the cylinder (wall 0) and the end walls (1, 2), and the
    specimen settles inside the closed vessel at the locked-in stress; ``"free"``
    (Brazilian) removes all three walls and the specimen settles free.

    With a :class:`FlatJointMaterial` the pairs get flat joints instead of parallel
    bonds (force-free), on every pair within ``microstructure.gi_ratio`` x the mean ball
    radius (``install_gap`` does not apply), with the microstructure's types drawn from
    the packing seed (``lab.microstructure.install_microstructure``). A material with a
    strength scatter gives every contact its own strengths, drawn from the packing seed
    (``lab.microstructure.install_strength_scatter``)."""
    spec = packing.spec
    flat = isinstance(material, FlatJointMaterial)
    rmean = float(np.mean(packing.radius))
    if flat:
        microstructure = microstructure or Microstructure()
        install_gap = microstructure.gi_ratio * rmean
    elif microstructure is not None:
        raise InputError("microstructure: a flat-jointed material's; the material is "
                         f"{material.contact_model}")
    if not (sigma0 >= 0 and math.isfinite(sigma0)):
        raise InputError(f"sigma0={sigma0!r}: expected an isotropic stress >= 0 Pa")
    if genesis not in GENESES:
        raise InputError(f"genesis={genesis!r}: expected one of {', '.join(GENESES)}")
    if install_gap is None:
        install_gap = default_install_gap(genesis, spec.rmin)
    if not (install_gap >= 0 and math.isfinite(install_gap)):
        raise InputError(f"install_gap={install_gap!r}: expected a surface gap >= 0 m")
    if max_steps is not None and int(max_steps) < 1:
        raise InputError(f"max_steps={max_steps!r}: expected a step budget >= 1")
    if boundary not in BOUNDARIES:
        raise InputError(f"boundary={boundary!r}: expected one of {', '.join(BOUNDARIES)}")
    budget = _StepBudget(max_steps)
    frictionless = material.replace(fric=0.0)
    # the Verlet skin must reach beyond the installation gap (bonds come from the list)
    m = Model(packing.pos, packing.radius, spec.density, frictionless, damping=damping,
              skin=max(0.25 * spec.rmin, 1.5 * install_gap), threads=threads,
              max_speed=speed_guard(material, spec.density))
    _vessel(m, spec)
    m.set_timestep(None)
    # enlarged floaters overlap their nearest neighbours: clip speeds while they settle
    m.set_speed_cap(0.02 * spec.rmin / m.dt)
    cycle(m, 500)
    budget.used += 500
    m.set_speed_cap(0.0)
    settle_walls = _solve(m, spec.relax_ratio, spec.max_relax_steps, progress=progress,
                          phase="settle in vessel", budget=budget)
    s_ax, s_lat = wall_stresses(m, spec)
    sigma_m = (s_ax + 2 * s_lat) / 3.0
    if genesis == "pfc":
        f = 0.0  # lin_force 0: no overlap carries force after bonding
    else:
        f = 1.0 if sigma_m <= sigma0 or sigma_m <= 0 else sigma0 / sigma_m
    # surface balls: those touching the lateral wall now
    surface = m.wall_contact_balls(0)
    # bond every touching pair; the linear reference gap scales its overlap force by f,
    # and so do the reference gaps of the ball-wall contacts (the end walls stay as platens)
    # (with f = 0, the pfc genesis, rgap = the current gap of every overlapping pair: its
    # linear force is zero now and grows with any further overlap, PFC's incremental mode)
    if install_gap > 0.0:
        # a fresh neighbour list holds every pair within the skin; one built steps ago may
        # miss pairs with a positive gap
        m.set_positions(np.arange(m.n), m.positions.copy())
    i, j = m.pairs()
    gaps = m.pair_gaps(i, j)
    sel = gaps <= install_gap
    rg = np.where(gaps[sel] < 0.0, gaps[sel] * (1.0 - f), 0.0)
    n_touching = _count_touching(m.positions, m.radii, install_gap)
    n_overlapping = int(np.count_nonzero(gaps < 0.0))
    nb = m.bond(gap=install_gap, rgap=None if flat else rg)
    fj_report = install_microstructure(m, microstructure, spec.seed, rmean) if flat else {}
    scatter = install_strength_scatter(m, material, spec.seed)
    for w in range(3):
        m.scale_wall_overlaps(w, f)
    z = m.coordination_numbers()
    if boundary == "platens":
        m.remove_wall(0)  # the lateral wall; walls 0 and 1 are now the bottom and top platens
        platens, lateral = (0, 1), None
    elif boundary == "vessel":
        platens, lateral = (1, 2), 0
    else:
        for _ in range(3):
            m.remove_wall(0)
        platens, lateral = (), None
    m.set_material(material)
    m.set_timestep(None)
    # calm (PFC): the bonded specimen starts at rest, then settles to a tight equilibrium
    m.set_velocity(np.arange(m.n), vel=np.zeros((m.n, 3)), angvel=np.zeros((m.n, 3)))
    if genesis == "pfc":
        # force-free by construction: the ratio criterion is 0/0 here, so equilibrium is
        # judged by the mean unbalanced force against a reference contact force
        settle_free = _settle_force_free(m, spec, progress=progress, budget=budget)
    else:
        settle_free = _solve(m, min(spec.relax_ratio, SETTLE_RATIO), spec.max_relax_steps,
                             progress=progress, phase="settle bonded", budget=budget)
    pos, r = m.positions, m.radii
    z_bot = 0.0
    z_top = spec.height
    rho = np.hypot(pos[:, 0], pos[:, 1]) + r
    vol = float((4 / 3 * np.pi * libm_pow(r, 3)).sum())
    report = dict(packing.report)
    report.update({
        "genesis": genesis,
        "install_gap_mm": float(install_gap * 1e3),
        "install_gap_rmin": float(install_gap / spec.rmin),
        "n_balls": int(m.n),
        "n_bonds": int(nb),
        "contacts_at_bonding": int(n_touching),
        "overlapping_at_bonding": n_overlapping,
        "coordination": float(z.mean()),
        # balls touching (surface gap < 0) per ball: with every touching pair bonded at
        # genesis, the coordination (contacts incl. bonded ones, PFC's) equals the bonds
        # per ball; this count says how many of them the balls actually press on
        "contacts_per_ball": _touching_per_ball(m),
        "bonds_per_ball": float(2.0 * nb / m.n),
        "bonds_per_cm3": float(nb / (spec.volume * 1e6)),
        "porosity_requested": float(spec.porosity),
        "porosity_achieved": float(1.0 - vol / spec.volume),
        "relaxed_stress_MPa": float(sigma_m / 1e6),
        "relaxed_stress_axial_MPa": float(s_ax / 1e6),
        "relaxed_stress_lateral_MPa": float(s_lat / 1e6),
        "locked_in_stress_MPa": (float(min(sigma_m, sigma0) / 1e6)
                                 if sigma_m > 0 and genesis == "bpmcal" else 0.0),
        "overlap_force_scale": float(f),
        "settle_walls_steps": settle_walls["steps"],
        "settle_free_steps": settle_free["steps"],
        "settle_free_ratio": settle_free["ratio"],
        "surface_balls": int(surface.size),
        "diameter_after_settle_mm": 2e3 * float(np.percentile(rho, 99.5)),
    })
    report.update(scatter)  # (nothing without a scatter: the report is as before)
    if flat:  # a parallel-bond run file records exactly what it did before flat joints
        report.update({"contact_model": material.contact_model,
                       "flatjoints_per_ball": float(2.0 * nb / m.n), **fj_report})
    return Specimen(model=m, spec=spec, material=material, report=report, surface=surface,
                    z_bottom=z_bot, z_top=z_top, radius0=0.5 * spec.diameter,
                    platens=platens, lateral_wall=lateral, boundary=boundary)


def end_cap_bonds(sp: Specimen, height_d: float) -> np.ndarray:
    """Indices (in the order of ``Model.bond_pairs``) of the bonds whose contact point
    (the middle of the overlap or gap of the pair, now) lies within ``height_d`` mean ball
    diameters of an end face (``z_bottom``, ``z_top``): the end caps of ``apply_end_caps``."""
    if not (height_d >= 0 and math.isfinite(height_d)):
        raise InputError(f"end cap height {height_d!r}: expected >= 0 mean ball diameters")
    m = sp.model
    bi, bj = m.bond_pairs()
    pos, r = m.positions, m.radii
    d = pos[bj] - pos[bi]
    ln = np.sqrt((d * d).sum(axis=1))
    z = pos[bi, 2] + d[:, 2] / ln * (r[bi] + 0.5 * (ln - r[bi] - r[bj]))
    h = height_d * 2.0 * float(r.mean())
    return np.flatnonzero((z - sp.z_bottom <= h) | (sp.z_top - z <= h))


def apply_end_caps(sp: Specimen, height_d: float, factor: float) -> dict:
    """End caps (an end treatment of axial tests): the bonds within ``height_d`` mean ball
    diameters of an end face (``end_cap_bonds``) get ``factor`` x their tensile strength
    and cohesion (``Model.set_bond_strength_factors``); their stiffnesses are unchanged.
    Returns ``{"end_cap_bonds": their number, "end_cap_index": their indices}``."""
    if not (factor >= 1 and math.isfinite(factor)):
        raise InputError(f"end cap factor {factor!r}: expected a finite strength factor >= 1")
    idx = end_cap_bonds(sp, height_d)
    f = sp.model.bond_strength_factors
    f[idx] *= factor
    sp.model.set_bond_strength_factors(f)
    return {"end_cap_bonds": int(idx.size), "end_cap_index": idx}


#: the engine's material of each contact model (``params.ContactModel.material``)
_MATERIAL_CLASS = {"linearpbond": Material, "flatjoint": FlatJointMaterial}


def card_material(p: dict, dp_nratio=0.0, dp_sratio=0.0):
    """The material of a validated card (``params.validate_params``) of either contact
    model, and its flat-jointed microstructure (None for the parallel bond), as the
    model's registry entry declares them (``params.ContactModel``: ``material``,
    ``material_fixed``, ``microstructure``)."""
    model = P.contact_model(p.get("contact_model", P.DEFAULT_CONTACT_MODEL))
    fields = dict(model.material_fixed or {})
    p = {**(model.defaults or {}), **p}  # optional keys absent: their defaults
    for name, engine_fields in model.material.items():
        v = int(p[name]) if model.is_integer(name) else P.to_si(name, p[name])
        fields.update(dict.fromkeys(engine_fields, v))
    mat = _MATERIAL_CLASS[model.name](**fields, dp_nratio=dp_nratio, dp_sratio=dp_sratio)
    micro = (Microstructure(**{f: float(p[name]) for name, f in model.microstructure.items()})
             if model.microstructure else None)
    return mat, micro


def flatjoint_material(p: dict, dp_nratio=0.0, dp_sratio=0.0) -> FlatJointMaterial:
    """A validated flat-joint card (paper units, ``params.FJ_PARAMS``) as a material."""
    return card_material({**p, "contact_model": "flatjoint"}, dp_nratio, dp_sratio)[0]


def paper_material(pb_emod_GPa, pb_kratio, pb_ten_MPa, pb_coh_MPa, pb_fa_deg, fric,
                   dp_nratio=0.0, dp_sratio=0.0) -> Material:
    """The paper's parameter set as a Material (Ec = Ecp, k* = kp*, mu = mu_p, lambda = 1)."""
    card = dict(pb_emod_GPa=pb_emod_GPa, pb_kratio=pb_kratio, pb_ten_MPa=pb_ten_MPa,
                pb_coh_MPa=pb_coh_MPa, pb_fa_deg=pb_fa_deg, fric=fric)
    return card_material(card, dp_nratio, dp_sratio)[0]
