"""Servo-controlled walls (PFC ``wall servo``): a proportional controller with adaptive gain.

A wall whose motion is servo-controlled moves, along its normal (a plane) or radially (a
cylinder), at

    v = G (F_measured - F_target),   G = alpha / (K dt),   |v| <= v_max

(sign: the wall moves away from the specimen when it pushes harder than the target;
with ``feedforward`` the mean velocity of the wall's contacting balls is added, see
below), where
F is the compressive normal force the balls exert on the wall, K the sum of the normal
stiffnesses k_n = pi R E* of the ball-wall contacts of that wall, dt the timestep and
alpha the relaxation factor (PFC's ``gain-factor``, default 0.8 as in PFC). With the
balls held still, one step changes the wall force by alpha (F_target - F): alpha < 1
cannot overshoot, and the compliance of the specimen behind the contacts only makes the
loop slower, never less stable. A wall without contacts moves toward the specimen at
the ``approach`` speed (when the target is positive). For a stress target the target
force follows the current loaded area (``Servo.target``).

Feed-forward (an addition to PFC's servo, used for the triaxial confinement): a
proportional controller lags a wall that must keep moving (the specimen dilates during
axial loading) by v / G, i.e. a constant force error. Adding the stiffness-weighted mean
velocity of the balls in contact (the wall velocity that keeps their overlaps constant)
removes that lag: the overlap rate is then -G x error, so the error decays by (1 - alpha)
per step whatever the balls do.

The controller runs in Python between engine steps (``ServoLoop``): the velocity is set
every ``interval`` steps (default every step; the gain is divided by ``interval``, since
the velocity is then held that many steps) and the gain every ``gain_update`` steps; the
engine itself is unchanged.
"""
from __future__ import annotations

import math

import numpy as np

from ..dem.errors import InputError
from ..dem.slots import WALL_CYLINDER
from .stepping import cycle


class ServoError(RuntimeError):
    """A servo-controlled stage (seating, consolidation) did not reach its target within
    its step limit: the run is recorded as failed with this message."""


def wall_contacts(m, w) -> np.ndarray:
    """Indices of the balls in contact with wall ``w`` now (non-zero contact force)."""
    return m.wall_contact_balls(w)


def wall_stiffness(m, w) -> float:
    """Sum of the normal stiffnesses k_n = pi R E* of the ball-wall contacts of wall ``w``
    (PFC's K^c of the wall servo) [N/m]."""
    return math.pi * float(m.material.emod) * float(m.radii[wall_contacts(m, w)].sum())


def wall_normal_force(m, w, direction=None) -> float:
    """Compressive force the balls exert on wall ``w`` along its normal [N] (for a
    cylinder: the sum of the radial components, outward = compressive); with
    ``direction`` (a unit vector pointing from the wall toward the specimen, for a wall
    that translates, such as a Brazilian loading jaw) the force component against it."""
    if direction is None and m.wall_type(w) == WALL_CYLINDER:
        return m.wall_radial_force(w)
    f = m.wall_force(w)
    n = m.wall_normal(w) if direction is None else direction
    return -float(f[0] * n[0] + f[1] * n[1] + f[2] * n[2])


class Servo:
    """Servo control of one wall toward a target compressive force.

    ``target`` is a callable returning the target force [N] now (so a stress target can
    follow the loaded area). Planes move along their normal (positive = toward the balls);
    cylinders change their radius (positive = expanding), or, given a ``direction`` (unit
    vector from the wall toward the specimen), translate along it like a plane (a curved
    loading jaw)."""

    def __init__(self, m, w, target, alpha: float = 0.8, vmax: float = 1.0,
                 approach: float | None = None, feedforward: bool = False,
                 direction=None):
        if not (0.0 < alpha <= 1.0):
            raise InputError(f"servo gain factor alpha={alpha!r}: expected 0 < alpha <= 1")
        if not (vmax > 0 and math.isfinite(vmax)):
            raise InputError(f"servo velocity cap {vmax!r}: expected a positive speed in m/s")
        self.m = m
        self.w = int(w)
        self.target = target
        self.alpha = float(alpha)
        self.vmax = float(vmax)
        self.approach = self.vmax if approach is None else min(float(approach), self.vmax)
        self.dir = None
        if direction is not None:
            d = np.asarray(direction, float).reshape(3)
            ln = float(np.linalg.norm(d))
            if not (ln > 0 and math.isfinite(ln)):
                raise InputError(f"servo direction={direction!r}: expected a non-zero vector")
            self.dir = d / ln
        self.cyl = m.wall_type(w) == WALL_CYLINDER and self.dir is None
        self.feedforward = bool(feedforward)
        self.K = 0.0
        self.v = 0.0
        self.interval = 1  # steps the velocity is held (set by ServoLoop)
        self._balls = np.zeros(0, np.int64)
        self._wgt = np.zeros(0)

    def update_gain(self):
        m = self.m
        b = wall_contacts(m, self.w)
        r = m.radii[b]
        self.K = math.pi * float(m.material.emod) * float(r.sum())
        self._balls = b
        self._wgt = r / r.sum() if b.size else r

    def contact_velocity(self) -> float:
        """Stiffness-weighted mean velocity of the wall's contacting balls along the wall's
        direction of motion (outward radial for a cylinder, against the normal for a
        plane, i.e. the wall velocity that keeps their overlaps constant)."""
        b = self._balls
        if b.size == 0:
            return 0.0
        m = self.m
        v = m.velocities[b]
        if self.cyl:
            p = m.positions[b] - m.wall_position(self.w)
            n = m.wall_normal(self.w)
            q = p - np.outer(p @ n, n)
            rho = np.sqrt((q * q).sum(axis=1))
            vr = (v * q).sum(axis=1) / np.where(rho > 0, rho, 1.0)
        else:
            vr = -(v @ self._direction())
        return float(self._wgt @ vr)

    def _direction(self) -> np.ndarray:
        """Unit vector along which a translating wall moves toward the specimen."""
        return self.m.wall_normal(self.w) if self.dir is None else self.dir

    def force(self) -> float:
        return wall_normal_force(self.m, self.w, self.dir)

    def error(self) -> float:
        """Measured minus target force [N]."""
        return self.force() - self.target()

    def apply(self):
        """Set the wall velocity from the current force (call after a step)."""
        m = self.m
        err = self.error()
        if self.K > 0.0:
            v = self.alpha * err / (self.K * m.dt * self.interval)
            if self.feedforward:
                v += self.contact_velocity()
        else:  # no contact: approach the specimen (if it should be loaded)
            v = -self.approach if self.target() > 0.0 else 0.0
        v = min(self.vmax, max(-self.vmax, v))
        self.v = v
        if self.cyl:
            m.set_wall_velocity(self.w, radial_velocity=v)  # expand when pushed harder
        else:  # retreat when pushed harder than the target
            m.set_wall_velocity(self.w, velocity=-v * self._direction())
        return v

    def stop(self):
        self.v = 0.0
        if self.cyl:
            self.m.set_wall_velocity(self.w, radial_velocity=0.0)
        else:
            self.m.set_wall_velocity(self.w, velocity=(0.0, 0.0, 0.0))


class ServoLoop:
    """Cycle a model while servo-controlling some walls: ``run(n)`` takes ``n`` steps,
    setting the servo velocities every ``interval`` steps and the gains every
    ``gain_update`` steps."""

    def __init__(self, m, servos, interval: int = 1, gain_update: int = 10):
        if int(interval) < 1 or int(gain_update) < 1:
            raise InputError(f"servo interval={interval!r}, gain_update={gain_update!r}: "
                             "expected integers >= 1")
        self.m = m
        self.servos = list(servos)
        self.interval = int(interval)
        for s in self.servos:  # the velocity is held for `interval` steps: G / interval
            s.interval = self.interval
        self.gain_update = int(gain_update)
        self._since_gain = self.gain_update  # update the gain at the first call

    def control(self):
        if self._since_gain >= self.gain_update:
            for s in self.servos:
                s.update_gain()
            self._since_gain = 0
        for s in self.servos:
            s.apply()

    def run(self, nsteps: int, record: bool = True):
        """Take ``nsteps`` steps under servo control (the last one records energies when
        ``record``)."""
        m = self.m
        done = 0
        nsteps = int(nsteps)
        while done < nsteps:
            k = min(self.interval, nsteps - done)
            self.control()
            cycle(m, k, record=record and done + k >= nsteps)
            done += k
            self._since_gain += k
