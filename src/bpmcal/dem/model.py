"""``Model``: the Python side of the engine. It owns the structure-of-arrays state, runs
chunks of steps through the numba runner, grows capacities on overflow, installs bonds,
manages walls, and reports energies, breakage events and diagnostics. No I/O here.

Typical use::

    m = Model(positions, radii, density=2294.0, material=mat, damping=0.7)
    m.add_plane_wall(point=(0, 0, 0), normal=(0, 0, 1))
    m.bond(gap=0.0)
    m.set_timestep(m.critical_timestep() * 0.8)
    m.cycle(1000)
    print(m.energies())
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from . import bondblock as bb
from . import diagnostics as D
from . import kernels as K
from . import neighbors as NB
from ._jit import numba, set_threads
from .errors import InputError, InstabilityError
from .layout import (
    BOND_INTACT,
    E_DASH,
    E_REMOVED,
    E_SLIP,
    E_WDASH,
    E_WSLIP,
    FIX_ALL,
    I_BAD,
    I_FORCES,
    I_NB,
    I_NBROKEN,
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
    WALL_CYLINDER,
    WALL_PLANE,
)
from .material import Material

Balls = namedtuple("Balls", "pos vel angvel force moment radius mass inertia fix pos_ref "
                   "edamp egrav efix fbuf pmask")
Pairs = namedtuple("Pairs", "pi pj fs df act slip dash estr vptr pi2 pj2 fs2 vptr2 cand part")
Bonds = namedtuple("Bonds", "blk state step pos nrm energy estr sig ptr part")
Slots = namedtuple("Slots", "b w fs df rg f m rad slip dash estr ptr b2 w2 fs2 ptr2")
Walls = namedtuple("Walls", "type pos nrm rad disk vel radv fric mass force radsum work "
                   "grav disp")

#: Energy terms reported by :meth:`Model.energies` (J).
ENERGY_TERMS = ("kinetic", "kinetic_walls", "strain_linear", "strain_bond", "slip",
                "dashpot", "damping", "released", "removed", "work_walls", "work_gravity",
                "work_constraints")


#: type of the ball indices in the pair and wall-slot lists: unsigned, so that numba
#: emits no negative-index wraparound code where the kernels index ball arrays with them
#: (the public methods return int32 copies)
IDX = np.uint32


def aligned_zeros(shape, align=64):
    """Zeroed float64 array whose data start on an ``align``-byte boundary (so that the
    8-float rows of the force buffers each fill exactly one cache line)."""
    n = int(np.prod(shape))
    raw = np.zeros(n + align // 8)
    off = (-raw.ctypes.data % align) // 8
    return raw[off:off + n].reshape(shape)


def _readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of an engine array (no copy; reflects later steps)."""
    v = a.view()
    v.flags.writeable = False
    return v


def _vec3(name, v):
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name}={v!r}: expected three finite numbers")
    return a


class Model:
    """Bonded-sphere DEM model with PFC linear + linear-parallel-bond contacts.

    Parameters
    ----------
    positions : (N, 3) array [m]
    radii : (N,) array [m], > 0
    density : float or (N,) array [kg/m^3], > 0
    material : Material
    damping : local damping coefficient alpha in [0, 1) (0.7 quasi-static, 0 dynamic)
    gravity : (3,) [m/s^2]
    skin : Verlet skin [m]; default 0.125 x the smallest radius
    max_speed : blow-up guard [m/s]; a ball faster than this stops the run
    threads : numba threads (None: leave numba's setting)
    partitions : number of fixed pair partitions (>= threads to use all threads). Forces
        are summed per partition in a fixed order, so results are bitwise identical for
        any number of threads at a given ``partitions``.
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
        if not isinstance(material, Material):
            raise InputError(f"material: expected a bpmcal.dem.Material, got {type(material).__name__}")
        if skin is None:
            skin = 0.125 * float(rad.min())
        if not (float(skin) > 0 and math.isfinite(float(skin))):
            raise InputError(f"skin={skin!r}: expected a positive length in m")
        if not (float(max_speed) > 0):
            raise InputError(f"max_speed={max_speed!r}: expected a positive speed in m/s")
        set_threads(threads)
        npart = int(partitions)
        if not 1 <= npart <= 63:
            raise InputError(f"partitions={partitions!r}: expected an integer in [1, 63]")
        self._npart = npart

        # r^3 through the C library's pow, element by element: numpy's vectorised power
        # (SVML kernels on AVX-512 hosts) rounds ~5 % of the cubes differently, and one
        # last-bit change in a mass changes the whole trajectory (bpmcal.portable)
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
        self.set_material(material)
        self._alloc_pairs(int(pair_capacity) if pair_capacity else max(64, 8 * n))
        self.Bd = self._empty_bonds(0)
        self._alloc_slots(int(slot_capacity) if slot_capacity else max(64, n // 2))
        self.W = self._empty_walls(0)
        self.iprm[I_REBUILD] = 1
        self.iprm[I_FORCES] = 1
        self._recorded = False
        self._removed_work = 0.0
        self._removed_grav = 0.0

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

    def _empty_bonds(self, nb):
        return Bonds(blk=bb.new_state(nb), state=np.zeros(nb, np.int8),
                     step=np.full(nb, -1, np.int64), pos=np.zeros((nb, 3)),
                     nrm=np.zeros((nb, 3)), energy=np.zeros(nb), estr=np.zeros(nb),
                     sig=np.zeros((nb, 3)), ptr=np.zeros(self.n + 1, np.int64),
                     part=np.zeros(nb, np.int64))

    @staticmethod
    def _empty_walls(nw):
        return Walls(type=np.zeros(nw, np.int64), pos=np.zeros((nw, 3)), nrm=np.zeros((nw, 3)),
                     rad=np.zeros(nw), disk=np.zeros(nw), vel=np.zeros((nw, 3)),
                     radv=np.zeros(nw), fric=np.zeros(nw), mass=np.zeros(nw),
                     force=np.zeros((nw, 3)), radsum=np.zeros(nw), work=np.zeros(nw),
                     grav=np.zeros(nw), disp=np.zeros(nw))

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
    def set_material(self, material: Material):
        """Install material properties (takes effect at the next step)."""
        if not isinstance(material, Material):
            raise InputError(f"material: expected a bpmcal.dem.Material, got {type(material).__name__}")
        self.material = material
        p = self.prm
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
        self.prm[P_GX:P_GX + 3] = _vec3("gravity", g)

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

    def critical_timestep(self) -> tuple[float, int]:
        """(dt_crit, limiting ball): min over balls of sqrt(m/k_tran), sqrt(I/k_rot)."""
        self._ensure_lists()
        dtc, arg = D.stiffness_timestep(self.B.radius, self.B.mass, self.B.inertia, self.B.fix,
                                        self.P.pi, self.P.pj, int(self.iprm[I_NPAIRS]),
                                        int(self.iprm[I_NB]), self.Bd.state, self.S.b,
                                        int(self.iprm[I_NSLOTS]), self.prm)
        if not math.isfinite(dtc):  # no contacts at all: use a lone ball on a wall
            i = int(np.argmin(self.B.mass / self.B.radius))
            kn = math.pi * self.B.radius[i] * self.material.emod
            dtc = math.sqrt(self.B.mass[i] / kn)
            arg = i
        return float(dtc), int(arg)

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
        return _readonly(self.B.pos)

    @property
    def velocities(self) -> np.ndarray:
        """Ball velocities v_{n-1/2} (N, 3) [m/s] (half-step values of the leapfrog)."""
        return _readonly(self.B.vel)

    @property
    def angular_velocities(self) -> np.ndarray:
        """Ball spins (N, 3) [rad/s] (half-step values)."""
        return _readonly(self.B.angvel)

    @property
    def radii(self) -> np.ndarray:
        """Ball radii (N,) [m]."""
        return _readonly(self.B.radius)

    @property
    def masses(self) -> np.ndarray:
        """Ball masses (N,) [kg]."""
        return _readonly(self.B.mass)

    @property
    def fix_flags(self) -> np.ndarray:
        """Fixed degrees of freedom of every ball (N,) (bits of layout.FIX_*; 0 = free)."""
        return _readonly(self.B.fix)

    def fix(self, idx, flags=FIX_ALL):
        """Fix degrees of freedom of balls ``idx`` (bits of layout.FIX_*); their current
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

    # ------------------------------------------------------------------ walls
    def _add_wall(self, kind, point, normal, radius, disk, velocity, radial_velocity, fric, mass):
        W = self.W
        nw = W.type.shape[0]
        new = self._empty_walls(nw + 1)
        for name, arr in W._asdict().items():
            getattr(new, name)[:nw] = arr
        new.type[nw] = kind
        new.pos[nw] = _vec3("point", point)
        nrm = _vec3("normal", normal)
        ln = np.linalg.norm(nrm)
        if ln == 0:
            raise InputError(f"normal={normal!r}: expected a non-zero vector")
        new.nrm[nw] = nrm / ln
        new.rad[nw] = radius
        new.disk[nw] = disk
        new.vel[nw] = _vec3("velocity", velocity)
        new.radv[nw] = radial_velocity
        f = float(fric)
        if not (f >= 0 and math.isfinite(f)):
            raise InputError(f"wall fric={fric!r}: expected a friction coefficient >= 0")
        new.fric[nw] = f
        mval = float(mass)
        if not (mval >= 0 and math.isfinite(mval)):
            raise InputError(f"wall mass={mass!r}: expected >= 0 kg (0 = prescribed motion)")
        new.mass[nw] = mval
        self.W = new
        self.iprm[I_REBUILD] = 1
        self._touch()
        return nw

    def add_plane_wall(self, point, normal, velocity=(0.0, 0.0, 0.0), fric=0.0,
                       disk_radius=0.0, mass=0.0) -> int:
        """Planar wall through ``point``; balls live on the side ``normal`` points to.

        ``disk_radius`` > 0 makes it a finite disk centred at ``point``; ``mass`` > 0 makes
        it a rigid body (drop hammer) whose velocity follows the contact forces and gravity;
        otherwise ``velocity`` is prescribed. Returns the wall id.
        """
        d = float(disk_radius)
        if not (d >= 0):
            raise InputError(f"disk_radius={disk_radius!r}: expected >= 0 m (0 = infinite plane)")
        return self._add_wall(WALL_PLANE, point, normal, 0.0, d, velocity, 0.0, fric, mass)

    def add_cylinder_wall(self, center, axis, radius, radial_velocity=0.0, fric=0.0) -> int:
        """Inside of an infinite cylinder (vessel); balls live inside."""
        r = float(radius)
        if not (r > 0 and math.isfinite(r)):
            raise InputError(f"cylinder radius={radius!r}: expected a positive length in m")
        return self._add_wall(WALL_CYLINDER, center, axis, r, 0.0, (0, 0, 0),
                              float(radial_velocity), fric, 0.0)

    def set_wall_velocity(self, w, velocity=None, radial_velocity=None):
        """Prescribe the velocity of wall ``w`` [m/s] and/or, for a cylinder, the rate of
        change of its radius [m/s] (positive = expanding); they take effect at the next
        step."""
        if velocity is not None:
            self.W.vel[w] = _vec3("velocity", velocity)
        if radial_velocity is not None:
            self.W.radv[w] = float(radial_velocity)

    def remove_wall(self, w: int):
        """Delete wall ``w`` (ids of later walls shift down by one). Its boundary work and
        the slip/dashpot energy of its contacts stay in the energy totals."""
        W = self.W
        nw = W.type.shape[0]
        if not (0 <= w < nw):
            raise InputError(f"wall id {w}: expected 0..{nw - 1}")
        self.energies()  # make the slot strain energies current
        ns = int(self.iprm[I_NSLOTS])
        S = self.S
        self.eacc[E_REMOVED] += S.estr[:ns][S.w[:ns] == w].sum()
        self._touch()
        self.eacc[E_WSLIP] += S.slip[:ns].sum()
        self.eacc[E_WDASH] += S.dash[:ns].sum()
        S.slip[:ns] = 0.0
        S.dash[:ns] = 0.0
        wout = np.zeros((nw, 3))
        D.measure_walls(W.vel, W.radv, W.mass, W.force, W.radsum, self.prm, wout)
        if W.mass[w] == 0.0:  # a rigid wall's work is internal to the system
            self._removed_work += float(W.work[w] + wout[w, 1])
        self._removed_grav += float(W.grav[w] + wout[w, 2])
        # the first half of the current step's work was counted: drop the wall's force so
        # the next step adds nothing for it (the slots are removed below)
        keep = np.arange(nw) != w
        self.W = Walls(**{k: np.ascontiguousarray(v[keep]) for k, v in W._asdict().items()})
        # drop the slots (forces) of that wall; the rest are rebuilt with history
        sel = S.w[:ns] != w
        m = int(sel.sum())
        nb_, nw_ = S.b[:ns][sel].copy(), S.w[:ns][sel].copy()
        nw_[nw_ > w] -= 1
        fs = S.fs[:ns][sel].copy()
        df = S.df[:ns][sel].copy()
        rgs = S.rg[:ns][sel].copy()
        S.b[:m], S.w[:m], S.fs[:m], S.df[:m], S.rg[:m] = nb_, nw_, fs, df, rgs
        S.f[:m] = S.f[:ns][sel]
        S.m[:m] = S.m[:ns][sel]
        counts = np.bincount(nb_, minlength=self.n)
        S.ptr[0] = 0
        S.ptr[1:] = np.cumsum(counts)
        self.iprm[I_NSLOTS] = m
        self.iprm[I_REBUILD] = 1

    @property
    def n_walls(self) -> int:
        return int(self.W.type.shape[0])

    def wall_type(self, w) -> int:
        """Kind of wall ``w``: layout.WALL_PLANE or layout.WALL_CYLINDER."""
        return int(self.W.type[w])

    def wall_normal(self, w) -> np.ndarray:
        """Unit normal of plane ``w`` (pointing to the balls), or axis of cylinder ``w``."""
        return self.W.nrm[w].copy()

    def wall_radius(self, w) -> float:
        """Current radius of cylinder ``w`` [m] (it changes with its radial velocity);
        0 for planes."""
        return float(self.W.rad[w])

    def wall_force(self, w) -> np.ndarray:
        """Force the balls exert on wall ``w`` at the last step [N]."""
        return self.W.force[w].copy()

    def wall_radial_force(self, w) -> float:
        """Sum over the contacts of wall ``w`` of the outward radial component of the force
        the balls exert on it [N] (cylinders: the lateral pressure times the wall area;
        0 for planes), at the last step."""
        return -float(self.W.radsum[w])

    def wall_position(self, w) -> np.ndarray:
        """Reference point of wall ``w`` [m] (walls move with their velocity)."""
        return self.W.pos[w].copy()

    def wall_velocity(self, w) -> np.ndarray:
        """Velocity of wall ``w`` [m/s] (prescribed, or of a rigid wall: v_{n+1/2})."""
        return self.W.vel[w].copy()

    def set_wall_friction(self, w, fric: float):
        """Friction coefficient of the contacts of wall(s) ``w`` (takes effect at the next
        force evaluation, like a velocity change; the current forces stay)."""
        f = float(fric)
        if not (f >= 0 and math.isfinite(f)):
            raise InputError(f"wall fric={fric!r}: expected a friction coefficient >= 0")
        idx = np.atleast_1d(np.asarray(w))
        if idx.size and not ((idx >= 0) & (idx < self.n_walls)).all():
            raise InputError(f"wall id {w!r}: expected 0..{self.n_walls - 1}")
        self.W.fric[idx] = f

    def wall_contact_balls(self, w) -> np.ndarray:
        """Balls (sorted, unique) that touch wall ``w`` with a non-zero force now."""
        ns = int(self.iprm[I_NSLOTS])
        S = self.S
        on = (S.w[:ns] == w) & np.any(S.f[:ns] != 0.0, axis=1)
        return np.unique(S.b[:ns][on]).astype(np.int32)

    # ------------------------------------------------------------------ contacts & bonds
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
        rg = np.zeros(i.shape[0])
        rg[:nb] = bb.get_field(self.Bd.blk, bb.S_RG, nb)
        intact = np.zeros(i.shape[0], bool)
        intact[:nb] = self.Bd.state == BOND_INTACT
        sel = (self.pair_gaps(i, j) < rg) | intact
        return i[sel], j[sel]

    @property
    def n_bonds(self) -> int:
        return int(self.iprm[I_NB])

    @property
    def n_broken(self) -> int:
        return int(self.iprm[I_NBROKEN])

    @property
    def bond_states(self) -> np.ndarray:
        """State of every bond pair (read-only view): 0 intact, 1 broken in tension,
        2 broken in shear (``BOND_*``), in the order of :meth:`bond_pairs`."""
        return _readonly(self.Bd.state)

    @property
    def bond_break_steps(self) -> np.ndarray:
        """Step at which each bond broke, -1 if intact (read-only view)."""
        return _readonly(self.Bd.step)

    @property
    def n_rebuilds(self) -> int:
        """Neighbour-list rebuilds so far (diagnostics)."""
        return int(self.iprm[I_NREBUILDS])

    @property
    def n_wall_slots(self) -> int:
        """Ball-wall pairs in the wall-contact list now (touching or within the skin)."""
        return int(self.iprm[I_NSLOTS])

    def bond(self, gap: float = 0.0, rgap=None) -> int:
        """Install parallel bonds on every unbonded pair with surface gap <= ``gap`` (PFC
        ``contact method bond gap``). Bonds are created with zero force and moment; the
        linear shear force of the pair is kept. ``rgap`` optionally gives, per new bond (in
        the order of :meth:`bond_pairs` after the call), the reference gap of its linear
        component (default 0). Returns the number of new bonds."""
        g = float(gap)
        if not math.isfinite(g):
            raise InputError(f"gap={gap!r}: expected a finite installation gap in m")
        self._touch()
        self._ensure_lists()
        P, Bd = self.P, self.Bd
        nb = int(self.iprm[I_NB])
        m = int(self.iprm[I_NPAIRS])
        vi, vj = P.pi[nb:m].copy(), P.pj[nb:m].copy()
        sel = self.pair_gaps(vi, vj) <= g
        if not sel.any():
            return 0
        # fold the energy of Verlet pairs that become bonds (their pair slots move)
        self.eacc[E_SLIP] += P.slip[nb:m].sum()
        self.eacc[E_DASH] += P.dash[nb:m].sum()
        ni, nj, nfs = vi[sel], vj[sel], P.fs[nb:m][sel].copy()
        ndf = P.df[nb:m][sel].copy()
        nnew = ni.shape[0]
        nbt = nb + nnew
        new = self._empty_bonds(nbt)
        for name in ("state", "step", "pos", "nrm", "energy", "estr", "sig"):
            getattr(new, name)[:nb] = getattr(Bd, name)
        for f in range(bb.NSF):  # blocked state: old bonds keep theirs
            bb.set_field(new.blk, f, nb, bb.get_field(Bd.blk, f, nb))
        newk = np.arange(nb, nbt)
        for c in range(3):
            new.blk[bb.field_index(bb.S_LX + c, nbt)[newk]] = nfs[:, c]
            new.blk[bb.field_index(bb.S_DFX + c, nbt)[newk]] = ndf[:, c]
        if rgap is not None:
            rg = np.asarray(rgap, float).reshape(-1)
            if rg.shape != (nnew,) or not np.all(np.isfinite(rg)):
                raise InputError(f"rgap: expected {nnew} finite reference gaps, "
                                 f"got shape {rg.shape}")
            new.blk[bb.field_index(bb.S_RG, nbt)[newk]] = rg
        oi, oj = P.pi[:nb].copy(), P.pj[:nb].copy()
        ai = np.concatenate([oi, ni]).astype(IDX)
        aj = np.concatenate([oj, nj]).astype(IDX)
        if nbt > P.pi.shape[0]:
            self._alloc_pairs(int(nbt * 1.5) + 8 * self.n)
            P = self.P
        P.pi[:nbt], P.pj[:nbt] = ai, aj
        P.fs[:nbt] = 0.0  # bond pairs keep their linear shear force in the blocked state
        P.df[:nbt] = 0.0
        P.act[:nbt] = 1
        P.slip[:nbt] = np.concatenate([P.slip[:nb], np.zeros(nnew)])
        P.dash[:nbt] = np.concatenate([P.dash[:nb], np.zeros(nnew)])
        # partner CSR (j > i of each bond (i, j), i < j by construction)
        order = np.lexsort((aj, ai))
        counts = np.bincount(ai, minlength=self.n)
        new.ptr[1:] = np.cumsum(counts)
        new.part[:] = aj[order]
        self.Bd = new
        self.iprm[I_NB] = nbt
        self.iprm[I_NPAIRS] = nbt
        P.vptr[:] = 0  # no Verlet history left to carry (all contacting pairs are bonds)
        self.iprm[I_REBUILD] = 1
        self._ensure_lists()
        return nnew

    def bond_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        nb = self.n_bonds
        return self.P.pi[:nb].astype(np.int32), self.P.pj[:nb].astype(np.int32)

    def set_bond_rgap(self, rgap):
        """Reference gaps [m] of the linear component of the bond pairs (PFC ``rgap``).
        Once a bond has broken and its surfaces are apart (gap >= 0), a negative reference
        gap is set to 0: a broken pair that comes back into contact is repelled from the
        first touch, as in PFC."""
        rg = np.asarray(rgap, float).reshape(-1)
        if rg.shape != (self.n_bonds,) or not np.all(np.isfinite(rg)):
            raise InputError(f"rgap: expected {self.n_bonds} finite values, got shape {rg.shape}")
        bb.set_field(self.Bd.blk, bb.S_RG, self.n_bonds, rg)
        self._touch()

    def set_bond_strength_factors(self, factors):
        """Per-bond strength factors: bond k (in the order of :meth:`bond_pairs`) fails at
        the material's tensile strength ``pb_ten`` and cohesion ``pb_coh`` times
        ``factors[k]`` (its friction angle and stiffnesses are unchanged). PFC gives every
        contact its own ``pb_ten`` / ``pb_coh``; here the material holds the common value
        and this factor the per-bond deviation. New bonds get factor 1. A scalar applies to
        every bond."""
        nb = self.n_bonds
        f = np.broadcast_to(np.asarray(factors, float), (nb,)) if np.ndim(factors) == 0 \
            else np.asarray(factors, float).reshape(-1)
        if f.shape != (nb,) or not np.all(np.isfinite(f)) or np.any(f < 0):
            raise InputError(f"strength factors: expected {nb} finite values >= 0, got "
                             f"shape {f.shape}")
        bb.set_field(self.Bd.blk, bb.S_SF, nb, f)
        self._touch()

    @property
    def bond_strength_factors(self) -> np.ndarray:
        """Strength factor of every bond pair (a copy; :meth:`set_bond_strength_factors`)."""
        return bb.get_field(self.Bd.blk, bb.S_SF, self.n_bonds)

    def scale_wall_overlaps(self, w: int, factor: float) -> int:
        """Give every current contact of wall ``w`` a reference gap (PFC ``rgap``) so that
        its overlap force is multiplied by ``factor`` (in [0, 1]); the geometry does not
        change. Contacts formed later have a zero reference gap. Returns how many."""
        f = float(factor)
        if not (0.0 <= f <= 1.0):
            raise InputError(f"factor={factor!r}: expected a force scale in [0, 1]")
        if not (0 <= w < self.n_walls):
            raise InputError(f"wall id {w}: expected 0..{self.n_walls - 1}")
        self._ensure_lists()
        ns = int(self.iprm[I_NSLOTS])
        S, B, W = self.S, self.B, self.W
        sel = np.flatnonzero(S.w[:ns] == w)
        p = B.pos[S.b[sel]] - W.pos[w]
        h = p @ W.nrm[w]
        if W.type[w] == WALL_CYLINDER:
            q = p - h[:, None] * W.nrm[w]
            gap = W.rad[w] - np.linalg.norm(q, axis=1) - B.radius[S.b[sel]]
        else:
            gap = h - B.radius[S.b[sel]]
        touching = gap < 0
        S.rg[sel[touching]] = gap[touching] * (1.0 - f)
        self._touch()
        return int(touching.sum())

    def breaks(self) -> dict:
        """Broken bonds as events sorted by (step, bond index): step, time, bond, i, j,
        mode (1 tension, 2 shear), position, normal, bond radius, released energy."""
        st = self.Bd.state
        k = np.flatnonzero(st != BOND_INTACT)
        k = k[np.lexsort((k, self.Bd.step[k]))]
        i, j = self.P.pi[k].astype(np.int32), self.P.pj[k].astype(np.int32)
        r = self.material.pb_rmul * np.minimum(self.B.radius[i], self.B.radius[j])
        return {"step": self.Bd.step[k].copy(), "bond": k, "i": i.copy(), "j": j.copy(),
                "mode": st[k].astype(np.int64), "pos": self.Bd.pos[k].copy(),
                "normal": self.Bd.nrm[k].copy(), "radius": r,
                "energy": self.Bd.energy[k].copy(), "sigma": self.Bd.sig[k, 0].copy(),
                "tau": self.Bd.sig[k, 1].copy(), "sigma_n": self.Bd.sig[k, 2].copy()}

    def bond_state(self) -> dict:
        """Current parallel-bond state of every bond pair (copies): normal force (tension
        positive) [N], shear force vector [N], twisting moment [N m], bending moment vector
        [N m], state (0 intact, 1 tension, 2 shear), reference gap of the linear part [m]."""
        Bd = self.Bd
        nb = self.n_bonds
        g = lambda f: bb.get_field(Bd.blk, f, nb)  # noqa: E731
        vec = lambda f: np.column_stack([g(f), g(f + 1), g(f + 2)]) if nb else np.zeros((0, 3))  # noqa: E731
        return {"fn": g(bb.S_FN), "fs": vec(bb.S_SX), "mt": g(bb.S_MT), "mb": vec(bb.S_BX),
                "state": Bd.state.copy(), "rgap": g(bb.S_RG)}

    def linear_shear_forces(self) -> np.ndarray:
        """Shear force vector of the linear component of every listed pair [N]."""
        self._ensure_lists()
        out = self.P.fs[: int(self.iprm[I_NPAIRS])].copy()
        nb = self.n_bonds
        for c in range(3):
            out[:nb, c] = bb.get_field(self.Bd.blk, bb.S_LX + c, nb)
        return out

    # ------------------------------------------------------------------ running
    def _touch(self):
        """Something changed from Python: forces must be re-evaluated (no increments)."""
        if self.iprm[I_FORCES] == 0:
            self.iprm[I_FORCES] = 1
        self._recorded = False

    def cycle(self, nsteps: int, record: bool = True):
        """Run ``nsteps`` steps (numba runs them; this loop only handles overflow and
        instability). With ``record`` the last step stores the state energies."""
        nsteps = int(nsteps)
        if nsteps < 0:
            raise InputError(f"nsteps={nsteps}: expected >= 0")
        if self.prm[P_DT] <= 0:
            raise InputError("timestep not set: call set_timestep() first")
        self._check_spin()
        pass  # forces are kept current by run_steps
        done = 0
        while True:
            st, k = K.run_steps(self.B, self.P, self.Bd, self.S, self.W, self.prm, self.iprm,
                                self.eacc, nsteps - done, record, numba.get_num_threads() == 1)
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

    # ------------------------------------------------------------------ measurements
    def energies(self) -> dict:
        """Energy terms [J] of the current state (step n), consistent with the integrator.

        Inputs: ``work_walls`` (walls with prescribed motion; every wall's work on the balls
        is in ``work_walls_each``), ``work_gravity``,
        ``work_constraints`` (of prescribed velocities). Stored: ``kinetic`` (balls,
        1/2 m v_{n-1/2}.v_{n+1/2} + rotation), ``kinetic_walls`` (rigid walls),
        ``strain_linear``, ``strain_bond``. Dissipated or released: ``slip``, ``dashpot``,
        ``damping``, ``released`` (strain energy of bonds at breakage).
        """
        if not self._recorded:
            if self.iprm[I_FORCES] == 0:
                self.iprm[I_FORCES] = 1
            self.cycle(0, record=True)
        B, P, Bd, S, W = self.B, self.P, self.Bd, self.S, self.W
        lin, bond, slip, dash, damp, grav, fixw, rel = D.sum_energies(
            B.edamp, B.egrav, B.efix, P.estr, P.slip, P.dash, int(self.iprm[I_NPAIRS]),
            Bd.estr, Bd.energy, Bd.state, int(self.iprm[I_NB]), S.estr, S.slip, S.dash,
            int(self.iprm[I_NSLOTS]), self.eacc)
        kin, dmp2, grv2, cst2 = D.measure_balls(B.vel, B.angvel, B.force, B.moment, B.mass,
                                                B.inertia, B.fix, B.fbuf, B.pmask, S.ptr,
                                                S.f, S.m, self.prm)
        wout = np.zeros((self.n_walls, 3))
        D.measure_walls(W.vel, W.radv, W.mass, W.force, W.radsum, self.prm, wout)
        ww = W.work + wout[:, 1]
        e = {"kinetic": kin, "kinetic_walls": float(wout[:, 0].sum()), "strain_linear": lin,
             "strain_bond": bond, "slip": slip, "dashpot": dash, "damping": damp + dmp2,
             "released": rel, "removed": float(self.eacc[E_REMOVED]),
             # rigid-body walls are part of the system (their kinetic energy is stored
             # energy), so only walls with prescribed motion do external work
             "work_walls": float(ww[W.mass == 0.0].sum()) + self._removed_work,
             "work_gravity": grav + grv2 + float((W.grav + wout[:, 2]).sum())
             + self._removed_grav,
             "work_constraints": fixw + cst2, "work_walls_each": ww.tolist(),
             "work_gravity_walls": float((W.grav + wout[:, 2]).sum()) + self._removed_grav}
        return e

    @staticmethod
    def energy_balance(e: dict, e0: dict | None = None) -> dict:
        """Inputs, stored, dissipated between two :meth:`energies` snapshots and the
        relative closure error |input - (d stored + d dissipated)| / max(|input|, stored)."""
        def parts(x):
            inp = x["work_walls"] + x["work_gravity"] + x["work_constraints"]
            sto = x["kinetic"] + x["kinetic_walls"] + x["strain_linear"] + x["strain_bond"]
            dis = x["slip"] + x["dashpot"] + x["damping"] + x["released"] + x["removed"]
            return inp, sto, dis
        i1, s1, d1 = parts(e)
        i0, s0, d0 = parts(e0) if e0 is not None else (0.0, 0.0, 0.0)
        inp, sto, dis = i1 - i0, s1 - s0, d1 - d0
        scale = max(abs(inp), abs(s1), abs(s0), 1e-300)
        return {"input": inp, "stored": sto, "dissipated": dis,
                "error": inp - sto - dis, "rel_error": abs(inp - sto - dis) / scale}

    def unbalanced_ratio(self) -> float:
        """Mean unbalanced force of free balls / mean contact force (PFC ratio-average)."""
        free = self.B.fix == 0
        if not free.any():
            return 0.0
        self.energies()  # current resultant forces (measure pass)
        fu = np.linalg.norm(self.B.force[free], axis=1).mean()
        fc, cnt = D.contact_force_mean(self.B.pos, self.B.radius, self.P.pi, self.P.pj,
                                       self.P.fs, int(self.iprm[I_NPAIRS]), int(self.iprm[I_NB]),
                                       self.Bd.state, self.Bd.blk, self.prm)
        if cnt == 0 or fc == 0.0:
            return math.inf if fu > 0 else 0.0
        return float(fu / fc)

    def coordination_numbers(self) -> np.ndarray:
        """Contacts per ball now (bonded or touching)."""
        self._ensure_lists()
        return D.coordination(self.B.pos, self.B.radius, self.P.pi, self.P.pj,
                              int(self.iprm[I_NPAIRS]), int(self.iprm[I_NB]), self.Bd.state,
                              self.Bd.blk)

    def ball_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """Resultant force (contacts + gravity) [N] and moment [N m] on every ball at the
        current positions (copies)."""
        self.energies()
        return self.B.force.copy(), self.B.moment.copy()

    def set_positions(self, idx, pos):
        """Move balls (e.g. to build a test configuration); lists are rebuilt."""
        p = np.asarray(pos, float)
        if not np.all(np.isfinite(p)):
            raise InputError("positions: expected finite coordinates")
        self.B.pos[np.asarray(idx)] = p
        self.iprm[I_REBUILD] = 1
        self._touch()

    def momentum(self) -> tuple[np.ndarray, np.ndarray]:
        """Linear momentum and angular momentum about the origin (Sum m x_n x v_{n+1/2}
        + I w, the leapfrog-conserved form, using x before the last position update)."""
        B = self.B
        p = (B.mass[:, None] * B.vel).sum(axis=0)
        x_prev = B.pos - B.vel * self.dt
        L = (B.mass[:, None] * np.cross(x_prev, B.vel)).sum(axis=0) + (
            B.inertia[:, None] * B.angvel).sum(axis=0)
        return p, L
