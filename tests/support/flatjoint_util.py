"""Two flat-jointed balls and their material (the common set-up of the flat joint's
single-contact tests, docs/flatjoint-spec.md section 8): used by the flat-joint law, energy
and per-contact strength tests."""
import math

from bpmcal.dem import FIX_ALL, FlatJointMaterial, Model

from .dem_util import RHO

R = 1.0e-3
KN = 50e9 / (2 * R)  # k_n [Pa/m]
KS = KN / 2.0
A = math.pi * R * R
INERTIA = math.pi * R ** 4 / 4
RHO_E = 0.55133 * R  # centroid distance, 1 x 3 (docs/flatjoint-spec.md §1 table; checked below)
TOL = 1e-9


def fj_material(**kw):
    base = dict(fj_emod=50e9, fj_kratio=2.0, fj_ten=10e6, fj_coh=20e6, fj_fa=30.0,
                fj_fric=0.5, fj_nr=1, fj_nal=3)
    base.update(kw)
    return FlatJointMaterial(**base)


def fj_two_balls(mat=None, gap=0.0):
    m = Model([[0.0, 0.0, 0.0], [2 * R + gap, 0.0, 0.0]], [R, R], RHO, mat or fj_material(),
              damping=0.0)
    m.fix([0, 1], FIX_ALL)
    assert m.bond(gap=max(gap, 0.0) + 1e-12) == 1
    m.set_timestep(None)
    return m
