"""``WallsMixin``: the walls of ``Model`` (planes, disks, rigid hammers, cylinders):
adding, moving and removing them, reading their forces, and their ball contacts.

A mixin of :class:`bpmcal.dem.model.Model`, not usable alone: it works on the model's
``W`` (``Walls``) and ``S`` (``Slots``, the ball-wall contacts), ``B``, ``prm``, ``iprm``,
``eacc`` and calls ``_touch``, ``_ensure_lists`` and ``energies``. The wall contact laws
run in the numba kernels.
"""
from __future__ import annotations

import math

import numpy as np

from . import diagnostics as D
from .errors import InputError
from .model_arrays import Walls, vec3
from .slots import (
    E_REMOVED,
    E_WDASH,
    E_WSLIP,
    I_NSLOTS,
    I_REBUILD,
    WALL_CYLINDER,
    WALL_PLANE,
)


class WallsMixin:
    """Walls of :class:`~bpmcal.dem.model.Model` (ids 0, 1, ... in the order added)."""

    @staticmethod
    def _empty_walls(nw):
        return Walls(type=np.zeros(nw, np.int64), pos=np.zeros((nw, 3)), nrm=np.zeros((nw, 3)),
                     rad=np.zeros(nw), disk=np.zeros(nw), vel=np.zeros((nw, 3)),
                     radv=np.zeros(nw), fric=np.zeros(nw), mass=np.zeros(nw),
                     force=np.zeros((nw, 3)), radsum=np.zeros(nw), work=np.zeros(nw),
                     grav=np.zeros(nw), disp=np.zeros(nw))

    def _add_wall(self, kind, point, normal, radius, disk, velocity, radial_velocity, fric, mass):
        W = self.W
        nw = W.type.shape[0]
        new = self._empty_walls(nw + 1)
        for name, arr in W._asdict().items():
            getattr(new, name)[:nw] = arr
        new.type[nw] = kind
        new.pos[nw] = vec3("point", point)
        nrm = vec3("normal", normal)
        ln = np.linalg.norm(nrm)
        if ln == 0:
            raise InputError(f"normal={normal!r}: expected a non-zero vector")
        new.nrm[nw] = nrm / ln
        new.rad[nw] = radius
        new.disk[nw] = disk
        new.vel[nw] = vec3("velocity", velocity)
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
            self.W.vel[w] = vec3("velocity", velocity)
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
        """Kind of wall ``w``: slots.WALL_PLANE or slots.WALL_CYLINDER."""
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
        S = self.S
        return D.wall_contact_balls(S.w, S.b, S.f, int(self.iprm[I_NSLOTS]), int(w), self.n)

    @property
    def n_wall_slots(self) -> int:
        """Ball-wall pairs in the wall-contact list now (touching or within the skin)."""
        return int(self.iprm[I_NSLOTS])

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
