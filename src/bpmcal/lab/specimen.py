"""Specimen genesis: a bonded cylinder of balls, PFC style, with a small locked-in stress.

Procedure (after Potyondy & Cundall 2004 and PFC's ``ball distribute``):

1. **Distribute** (``distribute``): radii uniform in [Rmin, ratio x Rmin] are drawn until
   the summed ball volume reaches (1 - n) V of the vessel (a cylinder D x H); centres are
   placed uniformly so that every ball lies inside the vessel. Overlaps are allowed: this
   is PFC's *nominal* porosity n, and n = 0.20 means heavily overlapped placement.
2. **Relax** (``relax_packing``): frictionless balls in frictionless vessel walls (a
   cylinder and two planes), local damping 0.5, speeds clipped during the first steps
   while the initial overlaps are pushed apart, until the mean unbalanced-force ratio
   (mean |unbalanced force| / mean |contact force|, PFC's ``ratio-average``) falls below
   ``relax_ratio`` (1e-2). That is looser than PFC's default for a final equilibrium,
   on purpose: the contact forces of this state are scaled down by ~1e-3 in step 4, and
   so is any residual imbalance; a tighter ratio costs 2-10x the steps while the
   overcompressed pack keeps rearranging. The relaxed geometry does not depend on the contact modulus
   (the same number of steps at dt ~ sqrt(m/k)), so it is computed once at a reference
   modulus and cached: a packing depends only on geometry, Rmin, ratio, density, n, seed.
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
   they were packed against them).

Everything is seeded; the same inputs give bitwise-identical specimens.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .. import params as P
from ..dem import Material, Model
from ..dem.errors import InputError
from ..dem.order import morton_order
from ..io.atomic import atomic_path

#: modulus used while relaxing the packing (the relaxed geometry does not depend on it)
E_REF = 1.0e9
#: local damping while the overlapped packing relaxes: with 0.5 the frictionless pack
#: finds its jammed state in about half the steps it needs at 0.7 (measured, 6 packs)
RELAX_DAMPING = 0.5
#: unbalanced-force ratio of the bonded specimen's final settling (bonded packs
#: equilibrate quickly, and a drifting specimen would corrupt the lateral strain)
SETTLE_RATIO = 1e-3
#: genesis version: part of the cache key; bump when the procedure changes
GENESIS_VERSION = 4


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


def _solve(m: Model, tol: float, max_steps: int, chunk: int = 500, progress=None) -> dict:
    """Cycle until the mean unbalanced-force ratio is <= tol (or max_steps)."""
    s0 = m.step
    ratio = m.unbalanced_ratio()
    while ratio > tol and m.step - s0 < max_steps:
        m.cycle(chunk)
        ratio = m.unbalanced_ratio()
        if progress is not None:
            progress(m.step - s0, ratio)
    return {"steps": m.step - s0, "ratio": float(ratio), "converged": bool(ratio <= tol)}


def _fix_floaters(pos, radius, ncontacts, max_overlap, rmax_factor=1.25):
    """Enlarge balls with fewer than 3 contacts until they touch three neighbours, when
    that costs at most +25 % radius and overlaps no neighbour by more than
    ``max_overlap`` [m] (the packing's median contact overlap): a larger overlap would be
    a loaded spring that throws its neighbours about. The rest stay floaters."""
    from scipy.spatial import cKDTree

    floaters = np.flatnonzero(ncontacts < 3)
    if floaters.size == 0:
        return radius, 0, 0
    r = radius.copy()
    tree = cKDTree(pos)
    reach = 2.0 * float(radius.max()) * rmax_factor
    fixed = 0
    for i in floaters:
        nb = [k for k in tree.query_ball_point(pos[i], reach) if k != i]
        if len(nb) < 3:
            continue
        d = np.sort(np.linalg.norm(pos[nb] - pos[i], axis=1) - r[nb])
        need = d[2] * (1.0 + 1e-9)
        if r[i] < need <= rmax_factor * radius[i] and need - d[0] <= max_overlap:
            r[i] = need
            fixed += 1
    return r, int(floaters.size), fixed


def _count_touching(pos, radius, gap):
    """Pairs with surface gap <= ``gap``, counted independently of the engine's lists."""
    from scipy.spatial import cKDTree

    tree = cKDTree(pos)
    pairs = tree.query_pairs(2.0 * float(radius.max()) + max(gap, 0.0), output_type="ndarray")
    if pairs.size == 0:
        return 0
    d = np.linalg.norm(pos[pairs[:, 1]] - pos[pairs[:, 0]], axis=1)
    return int(np.count_nonzero(d - radius[pairs[:, 0]] - radius[pairs[:, 1]] <= gap))


def relax_packing(spec: SpecimenSpec, progress=None) -> Packing:
    """Steps 1-3 at the reference modulus (frictionless balls and vessel)."""
    pos, r = distribute(spec)
    m = Model(pos, r, spec.density, _genesis_material(), damping=RELAX_DAMPING,
              skin=0.25 * spec.rmin, threads=None)
    _vessel(m, spec)
    m.set_timestep(None)
    # clear the initial overlaps: speeds clipped to 2 % of Rmin per step
    m.set_speed_cap(0.02 * spec.rmin / m.dt)
    for _ in range(10):
        m.cycle(200)
        m.set_timestep(None)
        m.set_speed_cap(0.02 * spec.rmin / m.dt)
    m.set_speed_cap(0.0)
    m.set_timestep(None)
    info = _solve(m, spec.relax_ratio, spec.max_relax_steps, progress=progress)
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
        "porosity_nominal_distributed": float(1.0 - (4 / 3 * np.pi * r ** 3).sum() / spec.volume),
    }
    return Packing(spec=spec, pos=m.positions.copy(), radius=r2, report=report)


def cache_dir() -> Path:
    return Path(os.environ.get("BPMCAL_SPECIMEN_CACHE",
                               Path.home() / ".cache" / "bpmcal" / "packings"))


def get_packing(spec: SpecimenSpec, cache: str | os.PathLike | None = None,
                progress=None) -> Packing:
    """The relaxed packing for ``spec``, from the cache directory when it is there
    (written atomically: temporary name, then rename)."""
    d = Path(cache) if cache is not None else cache_dir()
    f = d / f"packing_{spec.key()}.npz"
    if f.exists():
        z = np.load(f, allow_pickle=False)
        return Packing(spec=spec, pos=z["pos"], radius=z["radius"],
                       report=json.loads(str(z["report"])))
    pk = relax_packing(spec, progress=progress)
    with atomic_path(f) as tmp, open(tmp, "wb") as fh:  # a file object: no ".npz" appended
        np.savez(fh, pos=pk.pos, radius=pk.radius, report=json.dumps(pk.report),
                 spec=json.dumps(asdict(spec)))
    return pk


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


def wall_stresses(m: Model, spec: SpecimenSpec) -> tuple[float, float]:
    """(axial, lateral) compressive stress on the vessel walls [Pa] at the last step."""
    m.energies()  # forces of the current state
    area = math.pi * (0.5 * spec.diameter) ** 2
    s_ax = 0.5 * (abs(m.wall_force(1)[2]) + abs(m.wall_force(2)[2])) / area
    s_lat = m.wall_radial_force(0) / (2 * math.pi * 0.5 * spec.diameter * spec.height)
    return float(s_ax), float(s_lat)


def build_specimen(packing: Packing, material: Material, *, sigma0: float = 0.1e6,
                   install_gap: float = 0.0, damping: float = 0.7, threads=None,
                   progress=None) -> Specimen:
    """Steps 4-5: install the material, relieve the locked-in stress to ``sigma0``, bond,
    remove the vessel, settle."""
    spec = packing.spec
    if not (sigma0 >= 0 and math.isfinite(sigma0)):
        raise InputError(f"sigma0={sigma0!r}: expected an isotropic stress >= 0 Pa")
    frictionless = material.replace(fric=0.0)
    m = Model(packing.pos, packing.radius, spec.density, frictionless, damping=damping,
              skin=0.25 * spec.rmin, threads=threads)
    _vessel(m, spec)
    m.set_timestep(None)
    # enlarged floaters overlap their nearest neighbours: clip speeds while they settle
    m.set_speed_cap(0.02 * spec.rmin / m.dt)
    m.cycle(500)
    m.set_speed_cap(0.0)
    settle_walls = _solve(m, spec.relax_ratio, spec.max_relax_steps, progress=progress)
    s_ax, s_lat = wall_stresses(m, spec)
    sigma_m = (s_ax + 2 * s_lat) / 3.0
    f = 1.0 if sigma_m <= sigma0 or sigma_m <= 0 else sigma0 / sigma_m
    # surface balls: those touching the lateral wall now
    surface = m.wall_contact_balls(0)
    # bond every touching pair; the linear reference gap scales its overlap force by f,
    # and so do the reference gaps of the ball-wall contacts (the end walls stay as platens)
    i, j = m.pairs()
    gaps = m.pair_gaps(i, j)
    sel = gaps <= install_gap
    rg = np.where(gaps[sel] < 0.0, gaps[sel] * (1.0 - f), 0.0)
    n_touching = _count_touching(m.positions, m.radii, install_gap)
    nb = m.bond(gap=install_gap, rgap=rg)
    for w in range(3):
        m.scale_wall_overlaps(w, f)
    z = m.coordination_numbers()
    m.remove_wall(0)  # the lateral wall; walls 0 and 1 are now the bottom and top platens
    m.set_material(material)
    m.set_timestep(None)
    # calm (PFC): the bonded specimen starts at rest, then settles to a tight equilibrium
    m.set_velocity(np.arange(m.n), vel=np.zeros((m.n, 3)), angvel=np.zeros((m.n, 3)))
    settle_free = _solve(m, min(spec.relax_ratio, SETTLE_RATIO), spec.max_relax_steps,
                         progress=progress)
    pos, r = m.positions, m.radii
    z_bot = 0.0
    z_top = spec.height
    rho = np.hypot(pos[:, 0], pos[:, 1]) + r
    vol = float((4 / 3 * np.pi * r ** 3).sum())
    report = dict(packing.report)
    report.update({
        "n_balls": int(m.n),
        "n_bonds": int(nb),
        "contacts_at_bonding": int(n_touching),
        "coordination": float(z.mean()),
        "porosity_requested": float(spec.porosity),
        "porosity_achieved": float(1.0 - vol / spec.volume),
        "relaxed_stress_MPa": float(sigma_m / 1e6),
        "relaxed_stress_axial_MPa": float(s_ax / 1e6),
        "relaxed_stress_lateral_MPa": float(s_lat / 1e6),
        "locked_in_stress_MPa": float(min(sigma_m, sigma0) / 1e6) if sigma_m > 0 else 0.0,
        "overlap_force_scale": float(f),
        "settle_walls_steps": settle_walls["steps"],
        "settle_free_steps": settle_free["steps"],
        "settle_free_ratio": settle_free["ratio"],
        "surface_balls": int(surface.size),
        "diameter_after_settle_mm": 2e3 * float(np.percentile(rho, 99.5)),
    })
    return Specimen(model=m, spec=spec, material=material, report=report, surface=surface,
                    z_bottom=z_bot, z_top=z_top, radius0=0.5 * spec.diameter)


def paper_material(pb_emod_GPa, pb_kratio, pb_ten_MPa, pb_coh_MPa, pb_fa_deg, fric,
                   dp_nratio=0.0, dp_sratio=0.0) -> Material:
    """The paper's parameter set as a Material (Ec = Ecp, k* = kp*, mu = mu_p, lambda = 1)."""
    E = P.to_si("pb_emod_GPa", pb_emod_GPa)
    return Material(emod=E, kratio=float(pb_kratio), fric=float(fric), pb_emod=E,
                    pb_kratio=float(pb_kratio), pb_ten=P.to_si("pb_ten_MPa", pb_ten_MPa),
                    pb_coh=P.to_si("pb_coh_MPa", pb_coh_MPa), pb_fa=float(pb_fa_deg),
                    pb_rmul=P.PB_RMUL, dp_nratio=dp_nratio, dp_sratio=dp_sratio)
