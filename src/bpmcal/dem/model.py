"""``Model``: the Python side of the engine. It owns the structure-of-arrays state, runs
chunks of steps through the numba runner, grows capacities on overflow, installs bonds,
manages walls, and reports energies, breakage events and diagnostics. No I/O here.

Typical use::

    m = Model(positions, radii, density=2294.0, material=mat, damping=0.7)
    m.add_plane_wall(point=(0, 0, 0), normal=(0, 0, 1))
    m.bond(gap=0.0)
    m.set_timestep(safety=0.8)  # 0.8 x the critical timestep
    m.cycle(1000)
    print(m.energies())

This module holds the state (allocation and growth of the records of ``model_arrays``),
the global parameters, the timestep, the ball accessors, the neighbour lists and
``cycle``. The rest of the public API comes from three mixins, one concept each:
``model_walls.WallsMixin`` (walls), ``model_bonds.BondsMixin`` (parallel bonds: the
contact-model-specific part) and ``model_measure.MeasureMixin`` (energies and other
measurements). They share the model's state; a call is ``m.add_plane_wall(...)`` whichever
module defines it.
"""
from __future__ import annotations

import math

import numpy as np

from . import bondblock as bb
from . import diagnostics as D
from . import flatjoint as FJ
from . import kernels as K
from . import neighbors as NB
from . import servo_kernel as SK
from ._jit import compiled, set_threads
from .errors import InputError, InstabilityError
from .material import MATERIALS, FlatJointMaterial, Material
from .model_arrays import IDX, Balls, Pairs, Slots, aligned_zeros, readonly, vec3
from .model_bonds import BondsMixin
from .model_flatjoints import FlatJointsMixin, empty_flatjoints, flatjoint_params
from .model_measure import ENERGY_TERMS, MeasureMixin
from .model_walls import WallsMixin
from .slots import (
    BOND_INTACT,
    FIX_ALL,
    I_BAD,
    I_FORCES,
    I_NB,
    I_NEED_C,
    I_NEED_P,
    I_NEED_W,
    I_NPAIRS,
    I_NREBUILDS,
    I_NSLOTS,
    I_REBUILD,
    I_STEP,
    N_EACC,
    N_IPRM,
    N_PRM,
    P_ALPHA,
    P_DP_N,
    P_DP_S,
    P_DT,
    P_EMOD,
    P_FRIC,
    P_GX,
    P_KRATIO,
    P_MAXSPEED,
    P_MODEL,
    P_NOSPIN,
    P_PB_COH,
    P_PB_EMOD,
    P_PB_KRATIO,
    P_PB_MCF,
    P_PB_RMUL,
    P_PB_TANFA,
    P_PB_TEN,
    P_SKIN,
    P_TIME,
    P_VCAP,
)
from .threads import AutoThreads

__all__ = ["Model", "ENERGY_TERMS"]


class Model(WallsMixin, BondsMixin, FlatJointsMixin, MeasureMixin):
    """Bonded-sphere DEM model with PFC linear + linear-parallel-bond contacts, or flat
    joints (PFC ``flatjoint``) when ``material`` is a :class:`FlatJointMaterial`.

    Parameters
    ----------
    positions : (N, 3) array [m]
    radii : (N,) array [m], > 0
    density : float or (N,) array [kg/m^3], > 0
    material : Material or FlatJointMaterial (the contact model of the installed pairs)
    damping : local damping coefficient alpha in [0, 1) (0.7 quasi-static, 0 dynamic)
    gravity : (3,) [m/s^2]
    skin : Verlet skin [m]; default 0.125 x the smallest radius
    max_speed : blow-up guard [m/s]; a ball faster than this stops the run
    threads : numba threads, forced for the process (None: unless a caller forced a count
        with ``set_threads``, the model chooses its own between chunks of steps:
        :mod:`bpmcal.dem.threads`)
    partitions : number of fixed pair partitions (>= threads to use all threads). Forces
        are summed per partition in a fixed order, so results are bitwise identical for
        any number of threads at a given ``partitions``.

    The walls, bonds and measurements are in the mixins (module doc).
    """

    def __init__(self, positions, radii, density, material: Material, *, damping=0.7,
                 gravity=(0.0, 0.0, 0.0), skin=None, max_speed=500.0, threads=None,
                 partitions=2, pair_capacity=None, slot_capacity=None):
        pos = np.array(positions, dtype=np.float64, order="C")
        rad = np.array(radii, dtype=np.float64).reshape(-1)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise InputError(f"positions: expected an (N, 3) array, got shape {pos.shape}")
        n = pos.shape[0]
        if n < 1:
            raise InputError("positions: expected at least one ball, got 0")
        if rad.shape != (n,):
            raise InputError(f"radii: expected shape ({n},), got {rad.shape}")
        bad = np.flatnonzero(~np.isfinite(pos).all(axis=1))
        if bad.size:
            raise InputError(f"positions: ball {bad[0]} has non-finite coordinates {pos[bad[0]]}")
        bad = np.flatnonzero(~(rad > 0) | ~np.isfinite(rad))
        if bad.size:
            raise InputError(f"radii: ball {bad[0]} has radius {float(rad[bad[0]])!r}; expected > 0")
        dens = np.broadcast_to(np.asarray(density, dtype=float), (n,)).copy()
        bad = np.flatnonzero(~(dens > 0) | ~np.isfinite(dens))
        if bad.size:
            raise InputError(f"density: ball {bad[0]} has density {float(dens[bad[0]])!r}; "
                             "expected > 0 kg/m^3")
        if not isinstance(material, MATERIALS):
            raise InputError("material: expected a bpmcal.dem.Material or FlatJointMaterial, "
                             f"got {type(material).__name__}")
        if skin is None:
            skin = 0.125 * float(rad.min())
        if not (float(skin) > 0 and math.isfinite(float(skin))):
            raise InputError(f"skin={skin!r}: expected a positive length in m")
        if not (float(max_speed) > 0):
            raise InputError(f"max_speed={max_speed!r}: expected a positive speed in m/s")
        set_threads(threads)
        self._threads = AutoThreads()
        npart = int(partitions)
        if not 1 <= npart <= 63:
            raise InputError(f"partitions={partitions!r}: expected an integer in [1, 63]")
        self._npart = npart

        # r^3 through the C library's pow, element by element: numpy's vectorised power
        # (SVML kernels on AVX-512 hosts) rounds ~5 % of the cubes differently, and one
        # last-bit change in a mass changes the whole trajectory (bpmcal.exact_math)
        rad3 = np.array([math.pow(r, 3.0) for r in rad.tolist()])
        mass = dens * (4.0 / 3.0) * math.pi * rad3
        inertia = 0.4 * mass * rad ** 2
        z3 = lambda: np.zeros((n, 3))  # noqa: E731
        self.B = Balls(pos=pos, vel=z3(), angvel=z3(), force=z3(), moment=z3(), radius=rad,
                       mass=mass, inertia=inertia, fix=np.zeros(n, np.uint8),
                       pos_ref=pos.copy(), edamp=np.zeros(n), egrav=np.zeros(n),
                       efix=np.zeros(n), fbuf=aligned_zeros((npart, n, 8)),
                       pmask=np.full(n, (1 << npart) - 1, np.int64))
        self.prm = np.zeros(N_PRM)
        self.iprm = np.zeros(N_IPRM, np.int64)
        self.eacc = np.zeros(N_EACC)
        self.prm[P_SKIN] = float(skin)
        self.prm[P_MAXSPEED] = float(max_speed)
        self.set_damping(damping)
        self.set_gravity(gravity)
        self.Fj = empty_flatjoints(0)
        self.set_material(material)
        self._alloc_pairs(int(pair_capacity) if pair_capacity else max(64, 8 * n))
        self.Bd = self._empty_bonds(0)
        self._alloc_slots(int(slot_capacity) if slot_capacity else max(64, n // 2))
        self.W = self._empty_walls(0)
        self.iprm[I_REBUILD] = 1
        self.iprm[I_FORCES] = 1
        self._recorded = False
        self._measured = False  # the measure pass (energies) is of the current state
        self._removed_work = 0.0
        self._removed_grav = 0.0
        self._kernels = {}  # kernel -> (the state's arrays, its entry point): _run_steps

    # ------------------------------------------------------------------ allocation
    @property
    def n(self) -> int:
        return self.B.pos.shape[0]

    def _alloc_pairs(self, cap, old: Pairs | None = None):
        n = self.n
        ccap = cap if old is None else max(cap, old.cand.shape[0])  # unbonded pairs found
        P = Pairs(pi=np.zeros(cap, IDX), pj=np.zeros(cap, IDX),
                  fs=np.zeros((cap, 3)), df=np.zeros((cap, 3)), act=np.zeros(cap, np.uint8),
                  slip=np.zeros(cap), dash=np.zeros(cap), estr=np.zeros(cap),
                  vptr=np.zeros(n + 1, np.int64), pi2=np.zeros(cap, IDX),
                  pj2=np.zeros(cap, IDX), fs2=np.zeros((cap, 6)),
                  vptr2=np.zeros(n + 1, np.int64),
                  cand=np.zeros(ccap, np.int64), part=np.zeros(self._npart + 1, np.int64))
        if old is not None:
            m = int(self.iprm[I_NPAIRS])
            for name in ("pi", "pj", "fs", "df", "act", "slip", "dash", "estr"):
                getattr(P, name)[:m] = getattr(old, name)[:m]
            P.vptr[:] = old.vptr
            P.part[:] = old.part
        self.P = P

    def _alloc_slots(self, cap, old: Slots | None = None):
        n = self.n
        S = Slots(b=np.zeros(cap, IDX), w=np.zeros(cap, IDX), fs=np.zeros((cap, 3)),
                  df=np.zeros((cap, 3)), rg=np.zeros(cap), f=np.zeros((cap, 3)),
                  m=np.zeros((cap, 3)), rad=np.zeros(cap), slip=np.zeros(cap),
                  dash=np.zeros(cap), estr=np.zeros(cap), ptr=np.zeros(n + 1, np.int64),
                  b2=np.zeros(cap, IDX), w2=np.zeros(cap, IDX),
                  fs2=np.zeros((cap, 7)), ptr2=np.zeros(n + 1, np.int64))
        if old is not None:
            m = int(self.iprm[I_NSLOTS])
            for name in ("b", "w", "fs", "df", "rg", "f", "m", "rad", "slip", "dash", "estr"):
                getattr(S, name)[:m] = getattr(old, name)[:m]
            S.ptr[:] = old.ptr
        self.S = S

    def _grow(self):
        need_p = int(self.iprm[I_NEED_P])
        need_w = int(self.iprm[I_NEED_W])
        need_c = int(self.iprm[I_NEED_C])
        if need_p > self.P.pi.shape[0]:
            self._alloc_pairs(int(need_p * 1.5) + 16, old=self.P)
        if need_c > self.P.cand.shape[0]:
            self.P = self.P._replace(cand=np.zeros(2 * need_c, np.int64))
        if need_w > self.S.b.shape[0]:
            self._alloc_slots(int(need_w * 1.5) + 16, old=self.S)

    # ------------------------------------------------------------------ parameters
    def set_material(self, material: Material | FlatJointMaterial):
        """Install material properties (takes effect at the next step). The contact model
        cannot change once bonds or flat joints are installed. A material whose mean
        tensile strength or cohesion differs from the current one's also sets every
        installed contact's own strengths to the new means (PFC ``contact property``; a
        strength scatter drawn for the old means is gone: draw it again with
        :meth:`set_bond_strengths`)."""
        if not isinstance(material, MATERIALS):
            raise InputError("material: expected a bpmcal.dem.Material or FlatJointMaterial, "
                             f"got {type(material).__name__}")
        old = getattr(self, "material", None)
        if old is not None and self.n_bonds and old.contact_model != material.contact_model:
            raise InputError(f"material: contact model {material.contact_model!r}, but the "
                             f"model has {self.n_bonds} {old.contact_model} contacts installed")
        new_means = old is None or old.strengths()[::2] != material.strengths()[::2]
        if isinstance(material, FlatJointMaterial):
            if self.n_bonds and (material.fj_nr, material.fj_nal) != (old.fj_nr, old.fj_nal):
                raise InputError(f"material: fj_nr x fj_nal = {material.fj_nr} x "
                                 f"{material.fj_nal}, but the installed flat joints have "
                                 f"{old.fj_nr} x {old.fj_nal} elements")
            self.material = material
            p = self.prm
            p[P_MODEL] = 1.0
            p[P_EMOD] = material.emod
            p[P_KRATIO] = material.kratio
            p[P_FRIC] = material.fric
            for k in (P_PB_EMOD, P_PB_KRATIO, P_PB_RMUL):
                p[k] = 1.0  # unused; finite so that nothing divides by zero
            for k in (P_PB_TEN, P_PB_COH, P_PB_TANFA, P_PB_MCF):
                p[k] = 0.0
            p[P_DP_N] = material.dp_nratio
            p[P_DP_S] = material.dp_sratio
            self.Fj.prm[:] = flatjoint_params(material)
            if hasattr(self, 'iprm'):
                if new_means and self.n_bonds:
                    self._reset_bond_strengths()
                self._touch()
            return
        self.material = material
        p = self.prm
        p[P_MODEL] = 0.0
        p[P_EMOD] = material.emod
        p[P_KRATIO] = material.kratio
        p[P_FRIC] = material.fric
        p[P_PB_EMOD] = material.pb_emod
        p[P_PB_KRATIO] = material.pb_kratio
        p[P_PB_TEN] = material.pb_ten
        p[P_PB_COH] = material.pb_coh
        p[P_PB_TANFA] = math.tan(math.radians(material.pb_fa))
        p[P_PB_RMUL] = material.pb_rmul
        p[P_PB_MCF] = material.pb_mcf
        p[P_DP_N] = material.dp_nratio
        p[P_DP_S] = material.dp_sratio
        if hasattr(self, 'iprm'):
            if new_means and self.n_bonds:
                self._reset_bond_strengths()
            self._touch()

    def set_damping(self, alpha: float):
        a = float(alpha)
        if not (0.0 <= a < 1.0):
            raise InputError(f"damping={alpha!r}: local damping coefficient must be in [0, 1)")
        self.prm[P_ALPHA] = a

    def set_speed_cap(self, vmax: float | None):
        """Clip ball speeds to ``vmax`` m/s (None/0: off). For removing the large initial
        overlaps of a genesis only: the clipped kinetic energy is not booked."""
        v = 0.0 if vmax is None else float(vmax)
        if not (v >= 0 and math.isfinite(v)):
            raise InputError(f"speed cap {vmax!r}: expected a speed >= 0 m/s")
        self.prm[P_VCAP] = v

    def set_spin(self, enabled: bool):
        """Rotational dynamics on (the default) or off. Off ("translation only"): no
        torques are summed and the spins stay as they are. Only for a pack whose forces
        are all central and blind to spins - frictionless balls and walls, no dashpots,
        no bonds (a genesis relaxation): there the moments are round-off and no spin
        ever acts back on a force, so the positions are bitwise those of a run with
        rotation, for less work. Refused (InputError) for anything else, also when the
        material, walls or bonds change later (checked by :meth:`cycle`)."""
        if enabled:
            self.prm[P_NOSPIN] = 0.0
            return
        self.prm[P_NOSPIN] = 1.0
        try:
            self._check_spin()
        except InputError:
            self.prm[P_NOSPIN] = 0.0
            raise

    def _check_spin(self):
        """With rotation off: every force is still central and blind to spins."""
        if self.prm[P_NOSPIN] == 0.0:
            return
        m = self.material
        why = []
        if m.fric != 0.0:
            why.append(f"ball friction {m.fric:g}")
        if m.dp_nratio != 0.0 or m.dp_sratio != 0.0:
            why.append("dashpots")
        if self.n_bonds > 0:
            why.append(f"{self.n_bonds} bonds")
        if np.any(self.W.fric != 0.0):
            why.append("wall friction")
        if why:
            raise InputError("rotation is off (set_spin(False)), which needs central, "
                             f"spin-blind forces, but the model has {', '.join(why)}: "
                             "call set_spin(True) first")

    def set_gravity(self, g):
        self.prm[P_GX:P_GX + 3] = vec3("gravity", g)

    @property
    def dt(self) -> float:
        return float(self.prm[P_DT])

    @property
    def time(self) -> float:
        return float(self.prm[P_TIME])

    @property
    def step(self) -> int:
        return int(self.iprm[I_STEP])

    @property
    def skin(self) -> float:
        """Verlet skin [m]: pairs closer than this are in the neighbour list."""
        return float(self.prm[P_SKIN])

    def _contacts(self) -> tuple:
        """The contact state the stiffness estimate reads (``diagnostics.ball_stiffness``
        after the radii): pairs, bonds, wall slots, the parameters and the flat joints'."""
        self._ensure_lists()
        F = self.Fj
        return (self.P.pi, self.P.pj, int(self.iprm[I_NPAIRS]), int(self.iprm[I_NB]),
                self.Bd.state, self.S.b, int(self.iprm[I_NSLOTS]), self.prm, F.prm,
                F.flag[:, FJ.K_LIVE], FJ.twist_factor(F.geo))

    def critical_timestep(self) -> tuple[float, int]:
        """(dt_crit, limiting ball): min over balls of sqrt(m/k_tran), sqrt(I/k_rot)."""
        dtc, arg = D.stiffness_timestep(self.B.radius, self.B.mass, self.B.inertia, self.B.fix,
                                        *self._contacts())
        if not math.isfinite(dtc):  # no contacts at all: use a lone ball on a wall
            i = int(np.argmin(self.B.mass / self.B.radius))
            kn = math.pi * self.B.radius[i] * self.material.emod
            dtc = math.sqrt(self.B.mass[i] / kn)
            arg = i
        return float(dtc), int(arg)

    def scale_density(self, quantile: float | None) -> dict:
        """PFC's density scaling for quasi-static runs, ball by ball: raise each ball's
        inertial mass and moment of inertia so that its own critical timestep (sqrt(m /
        k_tran), sqrt(I / k_rot), the stiffnesses of :meth:`critical_timestep`) is at least
        the ``quantile`` of all the free balls' (0: the smallest, no change; 0.5: the median
        ball's). The critical timestep, and so the timestep :meth:`set_timestep` then sets,
        grows by that factor; the balls that limited it get heavier, the others keep their
        mass. Masses are always scaled from the balls' true masses (a second call replaces
        the first; ``None`` restores them). Inertia only: a run with gravity is refused
        (the weight would change). Returns ``dt_gain`` (the critical timestep's factor)
        and ``mass_added`` (the fraction of the total mass added)."""
        if not hasattr(self, "_true_mass"):
            self._true_mass = (self.B.mass.copy(), self.B.inertia.copy())
        m0, i0 = self._true_mass
        self.B.mass[:], self.B.inertia[:] = m0, i0
        if quantile is None or quantile == 0:
            return {"dt_gain": 1.0, "mass_added": 0.0}
        if isinstance(quantile, bool) or not (isinstance(quantile, (int, float))
                                              and 0.0 <= quantile <= 1.0):
            raise InputError(f"density scaling quantile={quantile!r}: expected a fraction "
                             "in [0, 1] (or None: no scaling)")
        if np.any(self.prm[P_GX:P_GX + 3] != 0.0):
            raise InputError("density scaling with gravity on: the scaled masses would "
                             "change the weight; expected a run without gravity")
        kt, kr = D.ball_stiffness(self.B.radius, *self._contacts())
        with np.errstate(divide="ignore"):
            t = np.minimum(np.sqrt(m0 / kt), np.sqrt(i0 / kr))
        t = t[(self.B.fix != FIX_ALL) & np.isfinite(t)]
        if not t.size:  # no contacts: nothing limits the timestep through them
            return {"dt_gain": 1.0, "mass_added": 0.0}
        target = float(np.quantile(t, float(quantile)))
        self.B.mass[:] = np.maximum(m0, target * target * kt)
        self.B.inertia[:] = np.maximum(i0, target * target * kr)
        return {"dt_gain": target / float(t.min()),
                "mass_added": float(self.B.mass.sum() / m0.sum() - 1.0)}

    def set_timestep(self, dt: float | None = None, safety: float = 0.8):
        """Set dt; ``None`` uses ``safety`` x the critical estimate. A dt above the
        critical estimate is refused."""
        dtc, arg = self.critical_timestep()
        if dt is None:
            if not (0 < safety <= 1):
                raise InputError(f"safety={safety!r}: expected a factor in (0, 1]")
            dt = safety * dtc
        dt = float(dt)
        if not (dt > 0 and math.isfinite(dt)):
            raise InputError(f"timestep dt={dt!r} s: expected a positive time")
        if dt > dtc:
            raise InputError(f"timestep dt={dt:.4g} s is above the stable limit {dtc:.4g} s "
                             f"(limited by ball {arg}); use dt <= {dtc:.4g} s")
        self.prm[P_DT] = dt
        return dt

    # ------------------------------------------------------------------ balls
    # Read-only views of the ball state (no copies: they follow the model as it steps;
    # take ``.copy()`` for a snapshot). Change the state with the methods below.
    @property
    def positions(self) -> np.ndarray:
        """Ball centres x_n (N, 3) [m]."""
        return readonly(self.B.pos)

    @property
    def velocities(self) -> np.ndarray:
        """Ball velocities v_{n-1/2} (N, 3) [m/s] (half-step values of the leapfrog)."""
        return readonly(self.B.vel)

    @property
    def angular_velocities(self) -> np.ndarray:
        """Ball spins (N, 3) [rad/s] (half-step values)."""
        return readonly(self.B.angvel)

    @property
    def radii(self) -> np.ndarray:
        """Ball radii (N,) [m]."""
        return readonly(self.B.radius)

    @property
    def masses(self) -> np.ndarray:
        """Ball masses (N,) [kg]."""
        return readonly(self.B.mass)

    @property
    def fix_flags(self) -> np.ndarray:
        """Fixed degrees of freedom of every ball (N,) (bits of slots.FIX_*; 0 = free)."""
        return readonly(self.B.fix)

    def fix(self, idx, flags=FIX_ALL):
        """Fix degrees of freedom of balls ``idx`` (bits of slots.FIX_*); their current
        velocities are then prescribed."""
        self.B.fix[np.asarray(idx)] = np.uint8(flags)
        self._touch()

    def set_velocity(self, idx, vel=None, angvel=None):
        idx = np.asarray(idx)
        if vel is not None:
            self.B.vel[idx] = np.asarray(vel, float)
        if angvel is not None:
            self.B.angvel[idx] = np.asarray(angvel, float)
        self._touch()

    def set_positions(self, idx, pos):
        """Move balls (e.g. to build a test configuration); lists are rebuilt."""
        p = np.asarray(pos, float)
        if not np.all(np.isfinite(p)):
            raise InputError("positions: expected finite coordinates")
        self.B.pos[np.asarray(idx)] = p
        self.iprm[I_REBUILD] = 1
        self._touch()

    # ------------------------------------------------------------------ neighbour lists
    def _ensure_lists(self):
        if self.iprm[I_REBUILD]:
            while True:
                st = NB.rebuild_lists(self.B, self.P, self.Bd, self.S, self.W, self.prm, self.iprm,
                                self.eacc)
                if st == 0:
                    break
                self._grow()

    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """(i, j) of all pairs in the neighbour list (bond pairs first)."""
        self._ensure_lists()
        m = int(self.iprm[I_NPAIRS])
        return self.P.pi[:m].astype(np.int32), self.P.pj[:m].astype(np.int32)

    def pair_gaps(self, i=None, j=None) -> np.ndarray:
        """Surface gaps |xj - xi| - Ri - Rj [m] of the pairs (default: all listed pairs)."""
        if i is None:
            i, j = self.pairs()
        d = np.linalg.norm(self.B.pos[j] - self.B.pos[i], axis=1)
        return d - self.B.radius[i] - self.B.radius[j]

    def contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """(i, j) of the pairs in contact now (gap below reference gap, or intact bond)."""
        i, j = self.pairs()
        nb = self.n_bonds
        sel = np.zeros(i.shape[0], bool)
        sel[nb:] = self.pair_gaps(i[nb:], j[nb:]) < 0.0
        sel[:nb] = self._installed_in_contact()
        return i[sel], j[sel]

    def _installed_in_contact(self) -> np.ndarray:
        """Which installed pairs (bonds or flat joints) are in contact now: an intact
        bond or a linear part within its reference gap; a flat joint with a bonded element
        or a closed point of its interface (a deleted one: its balls overlap)."""
        nb = self.n_bonds
        i, j = self.P.pi[:nb], self.P.pj[:nb]
        g = self.pair_gaps(i, j)
        if self.material.contact_model == "flatjoint":
            F = self.Fj
            rad = self.material.fj_rmul * np.minimum(self.B.radius[i], self.B.radius[j])
            gs = g - F.c[:, FJ.C_GREF]
            live = F.flag[:, FJ.K_LIVE] == 1
            tb = np.hypot(F.c[:, FJ.C_TBS], F.c[:, FJ.C_TBT])
            closed = gs - tb * rad < 0.0
            bonded = (F.es == FJ.E_BONDED).any(axis=1)
            return np.where(live, bonded | closed, g < 0.0)
        rg = bb.get_field(self.Bd.blk, bb.S_RG, nb)
        return (g < rg) | (self.Bd.state == BOND_INTACT)

    @property
    def threads_used(self) -> list[int]:
        """The numba thread counts this model has run with (sorted; one value unless it
        chose its own and the machine's load changed during the run)."""
        return sorted(self._threads.used)

    @property
    def n_rebuilds(self) -> int:
        """Neighbour-list rebuilds so far (diagnostics)."""
        return int(self.iprm[I_NREBUILDS])

    # ------------------------------------------------------------------ running
    def _touch(self):
        """Something changed from Python: forces must be re-evaluated (no increments)."""
        if self.iprm[I_FORCES] == 0:
            self.iprm[I_FORCES] = 1
        self._recorded = False
        self._measured = False

    def __getstate__(self):
        """A pickled model keeps its state, not the kernel's entry point (``_run_steps``
        looks it up again)."""
        d = self.__dict__.copy()
        d["_kernels"] = {}
        return d

    def _run_steps(self, nsteps: int, record: bool, serial: bool, kernel=None,
                   extra: tuple = ()):
        """``kernels.run_steps`` (or ``kernel``, a stepping kernel taking the same state
        and arguments followed by ``extra``: ``servo_kernel.servo_steps``) on this model's
        state. The compiled version's entry point (``_jit.compiled``) is kept while the
        state's records are the same objects (``_grow``, a new wall or new bonds replace
        one: its types are then looked up again): the same machine code, without numba's
        per-call matching of the types of the ~70 arrays (12-17 us a call; a
        servo-controlled seating calls the engine every step)."""
        kernel = K.run_steps if kernel is None else kernel
        state = (self.B, self.P, self.Bd, self.S, self.W, self.Fj, self.prm, self.iprm,
                 self.eacc)
        args = (*state, int(nsteps), bool(record), bool(serial), *extra)
        cache = self._kernels
        kern = cache.get(kernel)
        if kern is None or any(a is not b for a, b in zip(state, kern[0])):
            run = compiled(kernel, args)
            if run is None:  # not loaded yet: numba's dispatcher loads it (or numba is off)
                out = kernel(*args)
                cache[kernel] = (state, compiled(kernel, args) or kernel)
                return out
            kern = cache[kernel] = (state, run)
        return kern[1](*args)

    def cycle(self, nsteps: int, record: bool = True):
        """Run ``nsteps`` steps (numba runs them; this loop only handles overflow and
        instability). With ``record`` the last step stores the state energies."""
        self._cycle(nsteps, record)

    def cycle_servo(self, nsteps: int, servo: tuple, record: bool = True):
        """Run ``nsteps`` steps with walls under servo control inside the engine
        (``servo_kernel.servo_steps``; ``servo`` its arrays ``svi, svf, sdir, sballs,
        swgt, lp``, which it updates): as :meth:`cycle`, the servo law applied between
        the steps. ``bpmcal.lab.servo.ServoLoop`` builds and reads the arrays."""
        self._cycle(nsteps, record, SK.servo_steps, tuple(servo))

    def _cycle(self, nsteps: int, record: bool, kernel=None, extra: tuple = ()):
        nsteps = int(nsteps)
        if nsteps < 0:
            raise InputError(f"nsteps={nsteps}: expected >= 0")
        if self.prm[P_DT] <= 0:
            raise InputError("timestep not set: call set_timestep() first")
        self._check_spin()
        serial = self._threads.apply(self.n) == 1  # numba's thread count for these steps
        self._measured = False
        done = 0
        while True:
            st, k = self._run_steps(nsteps - done, bool(record), serial, kernel, extra)
            done += int(k)
            if st == 0 and done >= nsteps:
                break
            if st == 1:
                self._grow()
            elif st == 2:
                b = int(self.iprm[I_BAD]) - 1
                self.iprm[I_BAD] = 0
                v = self.B.vel[b]
                raise InstabilityError(
                    f"run blew up at step {self.step}: ball {b} has velocity "
                    f"({v[0]:.3g}, {v[1]:.3g}, {v[2]:.3g}) m/s (non-finite or above the "
                    f"{self.prm[P_MAXSPEED]:g} m/s guard); dt={self.dt:.3g} s - check the "
                    "timestep, stiffnesses and overlaps", self.step, b)
        self._recorded = bool(record)
