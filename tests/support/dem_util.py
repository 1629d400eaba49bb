"""Helpers of the engine tests: the test material, two bonded balls, a relaxed box pack."""
import math

import numpy as np

from bpmcal.dem import FIX_ALL, Material, Model

R = 1.0e-3  # ball radius [m]
RHO = 2294.0


def material(**kw):
    base = dict(emod=10e9, kratio=2.0, fric=0.5, pb_emod=12e9, pb_kratio=2.5, pb_ten=20e6,
                pb_coh=30e6, pb_fa=30.0)
    base.update(kw)
    return Material(**base)


def bond_constants(mat, r1=R, r2=R):
    """Closed-form stiffnesses of docs/contact_laws.md, evaluated in the same operation order as the
    kernel (so that step-by-step increments can be replayed exactly in Python)."""
    sr = r1 + r2
    inv_l = 1.0 / sr
    r = min(r1, r2)
    kn = math.pi * r * r * mat.emod * inv_l
    ks = kn * (1.0 / mat.kratio)
    rb = mat.pb_rmul * r
    area = math.pi * rb * rb
    inertia = 0.25 * area * rb * rb
    knb = mat.pb_emod * inv_l
    ksb = knb * (1.0 / mat.pb_kratio)
    return dict(kn=kn, ks=ks, rb=rb, area=area, I=inertia, J=2 * inertia, knA=knb * area,
                ksA=ksb * area, ksJ=ksb * 2 * inertia, knI=knb * inertia)


def two_balls(mat, overlap=0.0, damping=0.0, r1=R, r2=R):
    """Two balls on the x axis, ball 0 at the origin, both fully fixed (prescribed
    velocities), bonded in their initial position."""
    d = r1 + r2 - overlap
    m = Model([[0.0, 0.0, 0.0], [d, 0.0, 0.0]], [r1, r2], RHO, mat, damping=damping)
    m.fix([0, 1], FIX_ALL)
    assert m.bond(gap=max(0.0, -overlap) + 1e-12) == 1
    m.set_timestep(None)
    return m


def rel(a, b):
    return abs(a - b) / max(abs(b), 1e-300)


def rng(seed=0):
    return np.random.default_rng(seed)


def box_pack(n, seed=0, rmin=0.8e-3, ratio=1.66, solid=0.60, mat=None, damping=0.7,
             walls=True, **model_kw):
    """A small relaxed random pack in a cube of frictionless planar walls."""
    g = np.random.default_rng(seed)
    r = g.uniform(rmin, ratio * rmin, n)
    L = ((4 / 3 * np.pi * r ** 3).sum() / solid) ** (1 / 3)
    pos = g.uniform(ratio * rmin, L - ratio * rmin, (n, 3))
    m = Model(pos, r, RHO, mat or material(fric=0.0), damping=damping, **model_kw)
    for ax in range(3):
        nrm = np.zeros(3)
        nrm[ax] = 1.0
        m.add_plane_wall(np.zeros(3), nrm)
        p = np.zeros(3)
        p[ax] = L
        m.add_plane_wall(p, -nrm)
    m.set_timestep(None)
    m.set_speed_cap(0.02 * rmin / m.dt)
    for _ in range(20):
        m.cycle(200)
        m.set_timestep(None)
    m.set_speed_cap(0)
    m.cycle(1000)
    return m, L


def total(e):
    """Stored energy plus what friction slip took out (no other sink in a free cluster)."""
    return e["kinetic"] + e["strain_linear"] + e["strain_bond"] + e["slip"]


def approach(m, set_vel, remaining, k_eff, fast=1e-3):
    """Drive a load that grows by k_eff*v*dt per step until ``remaining(m)`` (strength
    minus load, from the current bond state) is used up, slowing down by 100x each time it
    gets within two increments, so the last increment is below 1e-10 of the load: the bond
    breaks within a relative 1e-9 of its strength, at the first step that reaches it."""
    v = fast
    scale = remaining(m)
    while True:
        inc = k_eff * v * m.dt
        n = int(0.5 * remaining(m) / inc)  # half the way: the strength may move too
        if n >= 1:
            set_vel(v)
            m.cycle(n)
            assert m.n_broken == 0, "broke below the strength"
        elif inc < 1e-10 * scale:
            break
        else:
            v *= 0.1
    set_vel(v)
    for _ in range(1000):
        m.cycle(1)
        if m.n_broken:
            return
    raise AssertionError("bond did not break")
