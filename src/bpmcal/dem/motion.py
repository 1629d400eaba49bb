"""Law of motion of ONE ball (and the power of one wall), as small numba functions.

``kernels.integrate`` applies them to every ball each step; ``diagnostics.measure_balls``
applies the same functions to *predict* the next half-step velocities (kinetic energy and
the first half of the step's damping, gravity and constraint work), so the prediction is
exactly what the integrator will compute.

Central differences (PFC's law of motion): v_{n+1/2} = v_{n-1/2} + (F_n + F_d) / m * dt
per degree of freedom, with PFC's local (non-viscous) damping force
F_d = -alpha |F_n| sign(v_{n-1/2}); a fixed degree of freedom keeps its prescribed
velocity (fixity bits ``slots.FIX_*``).
"""
from __future__ import annotations

from ._jit import jit, numba
from .slots import FIX_VX, FIX_VY, FIX_VZ, FIX_WX, FIX_WY, FIX_WZ

_inl = numba.njit(cache=True, inline="always")


@_inl
def gather(i, fbuf, pmask, sptr, sf, sm, clear):
    """Resultant contact force and moment on ball i: the partition buffers in partition
    order, then the ball's wall slots. ``clear`` zeroes the buffers for the next step.

    Bit ``p`` of ``pmask[i]`` is set when partition p has a pair with ball i; the other
    partitions' rows of ball i are zero and are skipped (adding +0.0 to a sum that
    starts at +0.0 changes nothing, so the result is the same bit for bit)."""
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    m0 = 0.0
    m1 = 0.0
    m2 = 0.0
    mk = pmask[i]
    for p in range(fbuf.shape[0]):
        if not (mk >> p) & 1:
            continue
        f0 += fbuf[p, i, 0]
        f1 += fbuf[p, i, 1]
        f2 += fbuf[p, i, 2]
        m0 += fbuf[p, i, 3]
        m1 += fbuf[p, i, 4]
        m2 += fbuf[p, i, 5]
        if clear:
            for c in range(6):
                fbuf[p, i, c] = 0.0
    for s in range(sptr[i], sptr[i + 1]):
        f0 += sf[s, 0]
        f1 += sf[s, 1]
        f2 += sf[s, 2]
        m0 += sm[s, 0]
        m1 += sm[s, 1]
        m2 += sm[s, 2]
    return f0, f1, f2, m0, m1, m2


@_inl
def local_damping(f, v, alpha):
    """PFC local damping force of one degree of freedom: -alpha |F| sign(v), sign(0) = 0.
    Written with selects: the sign of a velocity is a coin toss for the branch predictor."""
    sgn = (1.0 if v > 0.0 else 0.0) - (1.0 if v < 0.0 else 0.0)
    return -alpha * abs(f) * sgn


@_inl
def dof(v, f, im, alpha, dt, fixed):
    """New half-step velocity of one degree of freedom and its damping force."""
    if fixed:
        return v, 0.0
    fd = local_damping(f, v, alpha)
    return v + (f + fd) * im * dt, fd


@_inl
def ball_state(i, mi, inertia, fix, vel, angvel):
    """Ball i (mass ``mi``) as ``ball_update`` takes it: fixity bits, 1/mass, 1/inertia,
    half-step velocity ``u`` (3) and spin ``w`` (3). Read the same way, in the same order,
    by the integrator and by the energy measurement that predicts its step."""
    fl = fix[i]
    im = 1.0 / mi
    ii = 1.0 / inertia[i]
    return fl, im, ii, vel[i, 0], vel[i, 1], vel[i, 2], angvel[i, 0], angvel[i, 1], angvel[i, 2]


@_inl
def ball_update(u0, u1, u2, w0, w1, w2, f0, f1, f2, m0, m1, m2, im, ii, alpha, dt, fl,
                spin=True):
    """The six degrees of freedom of one ball: velocity ``u``, spin ``w``, resultant force
    ``f`` and moment ``m`` (gravity included), 1/mass ``im``, 1/inertia ``ii``, fixity
    bits ``fl``. Returns the new half-step velocity (3), spin (3), and the damping forces
    (3) and moments (3) that were applied. Without ``spin`` (translation only,
    ``Model.set_spin``) the spins are kept and no damping moment is applied."""
    n0, d0 = dof(u0, f0, im, alpha, dt, fl & FIX_VX)
    n1, d1 = dof(u1, f1, im, alpha, dt, fl & FIX_VY)
    n2, d2 = dof(u2, f2, im, alpha, dt, fl & FIX_VZ)
    if spin:
        r0, e0 = dof(w0, m0, ii, alpha, dt, fl & FIX_WX)
        r1, e1 = dof(w1, m1, ii, alpha, dt, fl & FIX_WY)
        r2, e2 = dof(w2, m2, ii, alpha, dt, fl & FIX_WZ)
    else:
        r0, r1, r2, e0, e1, e2 = w0, w1, w2, 0.0, 0.0, 0.0
    return n0, n1, n2, r0, r1, r2, d0, d1, d2, e0, e1, e2


@_inl
def constraint_power(fl, f0, f1, f2, m0, m1, m2, u0, u1, u2, w0, w1, w2):
    """Sum of F . u over the fixed degrees of freedom of a ball (fixity bits ``fl``), with
    ``u`` the per-degree-of-freedom displacements (or velocities) the caller passes: the
    work (or power) of the constraint forces that hold prescribed velocities is minus
    this sum."""
    cw = 0.0
    if fl & FIX_VX:
        cw += f0 * u0
    if fl & FIX_VY:
        cw += f1 * u1
    if fl & FIX_VZ:
        cw += f2 * u2
    if fl & FIX_WX:
        cw += m0 * w0
    if fl & FIX_WY:
        cw += m1 * w1
    if fl & FIX_WZ:
        cw += m2 * w2
    return cw


@jit
def wall_power(wforce, wradsum, w, v0, v1, v2, rv):
    """Power the wall delivers to the balls at wall velocity v (and radial velocity rv)."""
    return -(wforce[w, 0] * v0 + wforce[w, 1] * v1 + wforce[w, 2] * v2) + wradsum[w] * rv
