"""Wall servos inside the engine: PFC's ``wall servo`` control law applied between steps in
numba, so a servo-controlled stage (a triaxial cell, a Brazilian disc's seating) costs what
its steps cost, not a Python round trip per step.

The law and its arithmetic are those of ``bpmcal.lab.servo`` (its module docstring), which
calls the helpers below for every quantity it computes, so a stage run here and one run by
the Python loop give the same state bit for bit (tested). A servo is one row of three
arrays:

- ``svi`` (int64): the wall, whether it moves radially (a cylinder without a direction),
  the kind of target (:data:`TARGET_FORCE`, :data:`TARGET_LATERAL`, :data:`TARGET_DISC`),
  the walls that give the target's area (the cylinder whose radius, the bottom and top
  platens whose gap), feed-forward (0/1) and the number of balls in contact at the last
  gain update;
- ``svf`` (float64): the gain factor alpha, the velocity cap, the approach speed, the
  target (a force [N] or a stress [Pa]), the contact stiffness K [N/m], the last
  velocity [m/s] and the balls' modulus E* [Pa] for K;
- ``sdir`` (3 floats): the direction a translating wall moves toward the specimen (the
  wall's normal when zero).

``sballs`` / ``swgt`` (one row per servo, as long as the model has balls) hold the balls in
contact and their stiffness weights from the last gain update; ``lp`` is the loop: the
steps a velocity is held, the steps between gain updates, the steps since the last one,
and the steps still due of a chunk the engine broke off (-1: none).
"""
from __future__ import annotations

import math

import numpy as np

from ._jit import jit
from .diagnostics import wall_contact_balls
from .kernels import run_steps
from .slots import I_NSLOTS, P_DT

# svi columns
SV_WALL, SV_RADIAL, SV_TARGET, SV_RWALL, SV_BOTTOM, SV_TOP, SV_FF, SV_NB = range(8)
SVI_COLS = 8
# svf columns
SV_ALPHA, SV_VMAX, SV_APPROACH, SV_GOAL, SV_K, SV_V, SV_EMOD = range(7)
SVF_COLS = 7
# lp entries
LP_INTERVAL, LP_GAIN_UPDATE, LP_SINCE, LP_PENDING = range(4)
LP_LEN = 4

#: the target is a force [N]
TARGET_FORCE = 0
#: a stress [Pa] on a cylinder's lateral area, 2 pi R H (R the cylinder's radius, H the
#: gap between the bottom and top platens)
TARGET_LATERAL = 1
#: a stress [Pa] on the cylinder's cross-section pi R^2
TARGET_DISC = 2


@jit
def servo_target(wpos, wrad, svi, svf, s):
    """Servo ``s``'s target force now [N]."""
    kind = svi[s, SV_TARGET]
    if kind == TARGET_FORCE:
        return svf[s, SV_GOAL]
    r = wrad[svi[s, SV_RWALL]]
    if kind == TARGET_LATERAL:
        h = wpos[svi[s, SV_TOP], 2] - wpos[svi[s, SV_BOTTOM], 2]
        return svf[s, SV_GOAL] * (2.0 * math.pi * r * h)
    return svf[s, SV_GOAL] * (math.pi * r * r)


@jit
def servo_force(wforce, wradsum, wnrm, svi, sdir, s):
    """The compressive force the balls exert on servo ``s``'s wall [N]: the radial sum for
    a radially moving cylinder, else the component against its direction of motion."""
    w = svi[s, SV_WALL]
    if svi[s, SV_RADIAL] != 0:
        return -wradsum[w]
    d0, d1, d2 = sdir[s, 0], sdir[s, 1], sdir[s, 2]
    if d0 == 0.0 and d1 == 0.0 and d2 == 0.0:
        d0, d1, d2 = wnrm[w, 0], wnrm[w, 1], wnrm[w, 2]
    return -(wforce[w, 0] * d0 + wforce[w, 1] * d1 + wforce[w, 2] * d2)


@jit
def servo_gain(sw, sb, sf, nslots, radius, svi, svf, sballs, swgt, s):
    """Gain update of servo ``s``: the balls touching its wall, K = pi E* sum(R) and each
    ball's weight R / sum(R) (PFC's K^c of the wall servo)."""
    b = wall_contact_balls(sw, sb, sf, nslots, svi[s, SV_WALL], radius.shape[0])
    rs = 0.0
    for k in range(b.shape[0]):
        rs += radius[b[k]]
    for k in range(b.shape[0]):
        sballs[s, k] = b[k]
        swgt[s, k] = radius[b[k]] / rs
    svi[s, SV_NB] = b.shape[0]
    svf[s, SV_K] = math.pi * svf[s, SV_EMOD] * rs


@jit
def servo_contact_velocity(pos, vel, wpos, wnrm, svi, sdir, sballs, swgt, s):
    """Stiffness-weighted mean velocity of servo ``s``'s contacting balls along its wall's
    direction of motion (outward radial for a cylinder, toward the specimen reversed for
    a translating wall): the wall velocity that keeps their overlaps constant."""
    w = svi[s, SV_WALL]
    out = 0.0
    if svi[s, SV_RADIAL] != 0:
        n0, n1, n2 = wnrm[w, 0], wnrm[w, 1], wnrm[w, 2]
        for k in range(svi[s, SV_NB]):
            i = sballs[s, k]
            p0 = pos[i, 0] - wpos[w, 0]
            p1 = pos[i, 1] - wpos[w, 1]
            p2 = pos[i, 2] - wpos[w, 2]
            a = p0 * n0 + p1 * n1 + p2 * n2
            q0, q1, q2 = p0 - a * n0, p1 - a * n1, p2 - a * n2
            rho = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
            vr = (vel[i, 0] * q0 + vel[i, 1] * q1 + vel[i, 2] * q2) / (rho if rho > 0 else 1.0)
            out += swgt[s, k] * vr
        return out
    d0, d1, d2 = sdir[s, 0], sdir[s, 1], sdir[s, 2]
    if d0 == 0.0 and d1 == 0.0 and d2 == 0.0:
        d0, d1, d2 = wnrm[w, 0], wnrm[w, 1], wnrm[w, 2]
    for k in range(svi[s, SV_NB]):
        i = sballs[s, k]
        out += swgt[s, k] * -(vel[i, 0] * d0 + vel[i, 1] * d1 + vel[i, 2] * d2)
    return out


@jit
def servo_velocity(err, target, contact_v, svi, svf, s, dt, interval):
    """The wall speed the law gives servo ``s`` for the force error ``err`` [N] (measured
    minus target), clamped to its cap; the approach speed toward the specimen when no ball
    touches the wall and the target is positive."""
    if svf[s, SV_K] > 0.0:
        v = svf[s, SV_ALPHA] * err / (svf[s, SV_K] * dt * interval)
        if svi[s, SV_FF] != 0:
            v += contact_v
    elif target > 0.0:
        v = -svf[s, SV_APPROACH]
    else:
        v = 0.0
    vmax = svf[s, SV_VMAX]
    return min(vmax, max(-vmax, v))


@jit
def servo_set(wvel, wradv, wnrm, svi, sdir, s, v):
    """Give servo ``s``'s wall the speed ``v``: a cylinder's radius grows at v, a
    translating wall retreats from the specimen at v (moves by -v along its direction)."""
    w = svi[s, SV_WALL]
    if svi[s, SV_RADIAL] != 0:
        wradv[w] = v
        return
    d0, d1, d2 = sdir[s, 0], sdir[s, 1], sdir[s, 2]
    if d0 == 0.0 and d1 == 0.0 and d2 == 0.0:
        d0, d1, d2 = wnrm[w, 0], wnrm[w, 1], wnrm[w, 2]
    wvel[w, 0] = -v * d0
    wvel[w, 1] = -v * d1
    wvel[w, 2] = -v * d2


@jit
def servo_apply_to(B, W, svi, svf, sdir, sballs, swgt, s, dt, interval, target):
    """One velocity update of servo ``s`` toward ``target`` [N] from the forces of the
    last step."""
    err = servo_force(W.force, W.radsum, W.nrm, svi, sdir, s) - target
    cv = 0.0
    if svf[s, SV_K] > 0.0 and svi[s, SV_FF] != 0:
        cv = servo_contact_velocity(B.pos, B.vel, W.pos, W.nrm, svi, sdir, sballs, swgt, s)
    v = servo_velocity(err, target, cv, svi, svf, s, dt, interval)
    svf[s, SV_V] = v
    servo_set(W.vel, W.radv, W.nrm, svi, sdir, s, v)


@jit
def servo_apply(B, W, svi, svf, sdir, sballs, swgt, s, dt, interval):
    """One velocity update of servo ``s`` toward its own target (``svi``'s kind)."""
    servo_apply_to(B, W, svi, svf, sdir, sballs, swgt, s, dt, interval,
                   servo_target(W.pos, W.rad, svi, svf, s))


@jit
def servo_steps(B, P, Bd, S, W, Fj, prm, iprm, eacc, nsteps, record_last, serial,
                svi, svf, sdir, sballs, swgt, lp):
    """``nsteps`` steps under servo control (``kernels.run_steps`` in chunks of
    ``lp[LP_INTERVAL]`` steps; before each chunk the gains are updated when due and every
    servo's velocity is set). Returns (status, steps_done) as ``run_steps`` does; on status
    1 (a capacity overflowed: grow and call again with the steps left) the chunk's steps
    still due are kept in ``lp[LP_PENDING]`` and run first at the next call, without a
    velocity update, as the Python loop's ``Model.cycle`` would run them."""
    done = 0
    interval = lp[LP_INTERVAL]
    dt = prm[P_DT]
    while True:
        rest = lp[LP_PENDING]  # steps still due of a chunk the engine broke off, or -1
        if rest < 0:
            if done >= nsteps:
                return 0, done
            rest = min(interval, nsteps - done)
            if lp[LP_SINCE] >= lp[LP_GAIN_UPDATE]:
                for s in range(svi.shape[0]):
                    servo_gain(S.w, S.b, S.f, iprm[I_NSLOTS], B.radius, svi, svf, sballs,
                               swgt, s)
                lp[LP_SINCE] = 0
            for s in range(svi.shape[0]):
                servo_apply(B, W, svi, svf, sdir, sballs, swgt, s, dt, interval)
        st, kk = run_steps(B, P, Bd, S, W, Fj, prm, iprm, eacc, rest,
                           record_last and done + rest >= nsteps, serial)
        done += kk
        lp[LP_SINCE] += kk
        if st != 0:  # 1: grow and call again (the chunk's rest first); 2: blown up
            lp[LP_PENDING] = rest - kk
            return st, done
        lp[LP_PENDING] = -1


class ServoRows:
    """The arrays of :func:`servo_steps` for ``n`` servos of a model of ``n_balls`` balls
    (module docstring), and the Python side of the law for one row: the same numba
    helpers, so a loop run from Python (a target given as a Python function) computes
    what the engine's loop computes."""

    def __init__(self, n: int, n_balls: int):
        self.svi = np.zeros((n, SVI_COLS), np.int64)
        self.svf = np.zeros((n, SVF_COLS))
        self.sdir = np.zeros((n, 3))
        self.sballs = np.zeros((n, max(1, int(n_balls))), np.int64)
        self.swgt = np.zeros((n, max(1, int(n_balls))))

    @classmethod
    def stack(cls, rows: list) -> "ServoRows":
        """One set holding the rows of the one-row sets ``rows`` (copies)."""
        out = cls.__new__(cls)
        for k in ("svi", "svf", "sdir", "sballs", "swgt"):
            setattr(out, k, np.ascontiguousarray(np.concatenate([getattr(r, k) for r in rows])))
        return out

    def unstack(self, rows: list) -> None:
        """Copy row ``i`` back into the one-row set ``rows[i]``."""
        for i, r in enumerate(rows):
            for k in ("svi", "svf", "sdir", "sballs", "swgt"):
                getattr(r, k)[0] = getattr(self, k)[i]

    def fit(self, n_balls: int) -> None:
        """Room for ``n_balls`` balls in contact (a model that gained balls)."""
        extra = int(n_balls) - self.sballs.shape[1]
        if extra > 0:
            self.sballs = np.ascontiguousarray(np.pad(self.sballs, ((0, 0), (0, extra))))
            self.swgt = np.ascontiguousarray(np.pad(self.swgt, ((0, 0), (0, extra))))

    def arrays(self) -> tuple:
        return self.svi, self.svf, self.sdir, self.sballs, self.swgt

    def target(self, m, s: int = 0) -> float:
        """Row ``s``'s target force now [N] (its own kind of target)."""
        return float(servo_target(m.W.pos, m.W.rad, self.svi, self.svf, s))

    def force(self, m, s: int = 0) -> float:
        """The compressive force on row ``s``'s wall [N]."""
        return float(servo_force(m.W.force, m.W.radsum, m.W.nrm, self.svi, self.sdir, s))

    def gain(self, m, s: int = 0) -> None:
        """Gain update of row ``s`` (the balls in contact, K, the weights)."""
        self.svf[s, SV_EMOD] = float(m.material.emod)
        self.fit(m.n)
        servo_gain(m.S.w, m.S.b, m.S.f, int(m.iprm[I_NSLOTS]), m.B.radius, self.svi,
                   self.svf, self.sballs, self.swgt, s)

    def contact_velocity(self, m, s: int = 0) -> float:
        return float(servo_contact_velocity(m.B.pos, m.B.vel, m.W.pos, m.W.nrm, self.svi,
                                            self.sdir, self.sballs, self.swgt, s))

    def apply(self, m, s: int, interval: int, target: float) -> float:
        """One velocity update of row ``s`` toward ``target`` [N]; returns the speed."""
        servo_apply_to(m.B, m.W, self.svi, self.svf, self.sdir, self.sballs, self.swgt, s,
                       float(m.prm[P_DT]), int(interval), float(target))
        return float(self.svf[s, SV_V])

    def set_speed(self, m, s: int, v: float) -> None:
        self.svf[s, SV_V] = float(v)
        servo_set(m.W.vel, m.W.radv, m.W.nrm, self.svi, self.sdir, s, float(v))
