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

The controller acts between engine steps (``ServoLoop``): the velocity is set every
``interval`` steps (default every step; the gain is divided by ``interval``, since the
velocity is then held that many steps) and the gain every ``gain_update`` steps. A target
given as a :class:`WallTarget` (a force, a stress on a cylinder's lateral area or on its
cross-section: every target the lab tests use) lets the engine apply the law itself
(``dem.servo_kernel``: one numba call per piece of steps instead of a Python round trip
per step); a target given as a Python function runs the loop from Python. Both compute
with the same numba helpers, so they give the same state bit for bit (tested).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..dem import servo_kernel as SK
from ..dem.errors import InputError
from ..dem.slots import WALL_CYLINDER
from .stepping import cycle

#: False runs every servo loop from Python (the same law and state, slower): for comparison
#: (``benchmarks/servo_engine.py``) and debugging
IN_ENGINE = True


class ServoError(RuntimeError):
    """A servo-controlled stage (seating, consolidation) did not reach its target within
    its step limit: the run is recorded as failed with this message."""


@dataclass(frozen=True)
class WallTarget:
    """A servo target the engine evaluates itself: ``kind`` ``"force"`` (``value`` in N),
    ``"lateral"`` (a stress [Pa] on the lateral area 2 pi R H of the cylinder ``cylinder``,
    H the gap between the platens ``bottom`` and ``top``) or ``"section"`` (a stress [Pa]
    on the cylinder's cross-section pi R^2)."""
    kind: str
    value: float
    cylinder: int = 0
    bottom: int = 0
    top: int = 0

    def __post_init__(self):
        if self.kind not in _TARGET_KINDS:
            raise InputError(f"servo target kind {self.kind!r}: expected one of "
                             f"{sorted(_TARGET_KINDS)}")
        if not math.isfinite(self.value):
            raise InputError(f"servo target {self.value!r}: expected a finite number")

    @classmethod
    def force(cls, value: float) -> "WallTarget":
        return cls("force", float(value))

    @classmethod
    def lateral(cls, stress: float, cylinder: int, bottom: int, top: int) -> "WallTarget":
        return cls("lateral", float(stress), int(cylinder), int(bottom), int(top))

    @classmethod
    def section(cls, stress: float, cylinder: int) -> "WallTarget":
        return cls("section", float(stress), int(cylinder))


_TARGET_KINDS = {"force": SK.TARGET_FORCE, "lateral": SK.TARGET_LATERAL,
                 "section": SK.TARGET_DISC}


class Servo:
    """Servo control of one wall toward a target compressive force.

    ``target`` is a :class:`WallTarget` (evaluated by the engine) or a callable returning
    the target force [N] now (so a stress target can follow the loaded area). Planes move
    along their normal (positive = toward the balls); cylinders change their radius
    (positive = expanding), or, given a ``direction`` (unit vector from the wall toward
    the specimen), translate along it like a plane (a curved loading jaw)."""

    def __init__(self, m, w, target, alpha: float = 0.8, vmax: float = 1.0,
                 approach: float | None = None, feedforward: bool = False,
                 direction=None):
        if not (0.0 < alpha <= 1.0):
            raise InputError(f"servo gain factor alpha={alpha!r}: expected 0 < alpha <= 1")
        if not (vmax > 0 and math.isfinite(vmax)):
            raise InputError(f"servo velocity cap {vmax!r}: expected a positive speed in m/s")
        self.m = m
        self.w = int(w)
        self.spec = target if isinstance(target, WallTarget) else None
        self._target = target
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
        self.interval = 1  # steps the velocity is held (set by ServoLoop)
        r = self.row = SK.ServoRows(1, m.n)
        r.svi[0, SK.SV_WALL] = self.w
        r.svi[0, SK.SV_RADIAL] = int(self.cyl)
        r.svi[0, SK.SV_FF] = int(bool(feedforward))
        r.svf[0, SK.SV_ALPHA] = float(alpha)
        r.svf[0, SK.SV_VMAX] = self.vmax
        r.svf[0, SK.SV_APPROACH] = self.approach
        if self.dir is not None:
            r.sdir[0] = self.dir
        if self.spec is not None:
            t = self.spec
            r.svi[0, SK.SV_TARGET] = _TARGET_KINDS[t.kind]
            r.svi[0, SK.SV_RWALL], r.svi[0, SK.SV_BOTTOM], r.svi[0, SK.SV_TOP] = (
                t.cylinder, t.bottom, t.top)
            r.svf[0, SK.SV_GOAL] = t.value

    @property
    def alpha(self) -> float:
        return float(self.row.svf[0, SK.SV_ALPHA])

    @property
    def feedforward(self) -> bool:
        return bool(self.row.svi[0, SK.SV_FF])

    @property
    def K(self) -> float:
        """Sum of the normal stiffnesses of the wall's contacts at the last gain update."""
        return float(self.row.svf[0, SK.SV_K])

    @property
    def v(self) -> float:
        """The speed the last update gave the wall [m/s]."""
        return float(self.row.svf[0, SK.SV_V])

    def target(self) -> float:
        """The target force now [N]."""
        return self.row.target(self.m) if self.spec is not None else float(self._target())

    def update_gain(self):
        self.row.gain(self.m)

    def contact_velocity(self) -> float:
        """Stiffness-weighted mean velocity of the wall's contacting balls along the wall's
        direction of motion (outward radial for a cylinder, against the normal for a
        plane, i.e. the wall velocity that keeps their overlaps constant)."""
        return self.row.contact_velocity(self.m)

    def force(self) -> float:
        return self.row.force(self.m)

    def error(self) -> float:
        """Measured minus target force [N]."""
        return self.force() - self.target()

    def apply(self):
        """Set the wall velocity from the current force (call after a step)."""
        return self.row.apply(self.m, 0, self.interval, self.target())

    def stop(self):
        self.row.set_speed(self.m, 0, 0.0)


class ServoLoop:
    """Cycle a model while servo-controlling some walls: ``run(n)`` takes ``n`` steps,
    setting the servo velocities every ``interval`` steps and the gains every
    ``gain_update`` steps (in the engine when every target is a :class:`WallTarget`)."""

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
        self.in_engine = IN_ENGINE and all(s.spec is not None for s in self.servos)

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
        nsteps = int(nsteps)
        if nsteps <= 0:
            return
        if self.in_engine:
            self._run_in_engine(nsteps, record)
            return
        m = self.m
        done = 0
        while done < nsteps:
            k = min(self.interval, nsteps - done)
            self.control()
            cycle(m, k, record=record and done + k >= nsteps)
            done += k
            self._since_gain += k

    def _run_in_engine(self, nsteps: int, record: bool) -> None:
        rows = [s.row for s in self.servos]
        for s in self.servos:
            s.row.svf[0, SK.SV_EMOD] = float(self.m.material.emod)
            s.row.fit(self.m.n)
        st = SK.ServoRows.stack(rows)
        lp = np.array([self.interval, self.gain_update, self._since_gain, -1], np.int64)
        arrays = (*st.arrays(), lp)
        try:
            cycle(self.m, nsteps, record=record, quantum=self.interval,
                  run=lambda k, rec: self.m.cycle_servo(k, arrays, record=rec))
        finally:
            st.unstack(rows)
            self._since_gain = int(lp[SK.LP_SINCE])
