"""Model.cycle calls the stepping kernel's compiled entry point (``_jit.compiled``)
instead of numba's dispatcher: the same machine code, so the same state bit for bit,
also across the events that replace the state's records (growth of the pair list, a new
wall, new bonds); the entry point is never used with arguments of other types."""
from __future__ import annotations

import numpy as np
import pytest
from support.dem_util import RHO, box_pack, material

from bpmcal.dem import Model
from bpmcal.dem import kernels as K
from bpmcal.dem._jit import JIT_DISABLED, compiled


def _state(m) -> dict:
    out = {"prm": m.prm.copy(), "iprm": m.iprm.copy(), "eacc": m.eacc.copy()}
    for rec in ("B", "P", "Bd", "S", "W"):
        for k, v in getattr(m, rec)._asdict().items():
            out[f"{rec}.{k}"] = np.array(v, copy=True)
    return out


def _dispatched(m):
    """Make ``m`` step through numba's dispatcher (the path before the entry point)."""
    def run(nsteps, record, serial, kernel=None, extra=()):
        assert kernel is None and extra == ()  # plain stepping only
        return K.run_steps(m.B, m.P, m.Bd, m.S, m.W, m.Fj, m.prm, m.iprm, m.eacc, nsteps,
                           record, serial)
    m._run_steps = run


def _model(fast: bool, serial: bool):
    """80 overlapping balls in a box, relaxed (the pair list grows from a capacity of 64),
    bonded, with friction; steps in calls of several lengths; a wall added and moving."""
    g = np.random.default_rng(3)
    r = g.uniform(0.8e-3, 1.3e-3, 80)
    L = ((4 / 3 * np.pi * r ** 3).sum() / 0.6) ** (1 / 3)
    m = Model(g.uniform(1.3e-3, L - 1.3e-3, (80, 3)), r, RHO, material(fric=0.0),
              damping=0.7, pair_capacity=64)
    m._threads.apply = (lambda n: 1) if serial else (lambda n: 2)
    if not fast:
        _dispatched(m)
    for ax in range(3):
        nrm = np.zeros(3)
        nrm[ax] = 1.0
        m.add_plane_wall(np.zeros(3), nrm)
        m.add_plane_wall(L * nrm, -nrm)
    m.set_timestep(None)
    m.set_speed_cap(0.02 * 0.8e-3 / m.dt)
    for k in (1, 1, 7, 300, 300):
        m.cycle(k)
    m.set_speed_cap(0)
    m.bond(gap=0.0)
    m.set_material(material(fric=0.5))
    m.set_timestep(None)
    w = m.add_plane_wall((0.0, 0.0, 0.2e-3), (0.0, 0.0, 1.0), velocity=(0.0, 0.0, 0.5))
    for k in (1, 3, 120):
        m.cycle(k, record=k > 1)
    m.set_wall_velocity(w, velocity=(0.0, 0.0, -0.5))
    m.cycle(60)
    return m


@pytest.mark.parametrize("serial", [True, False], ids=["one-thread", "partitions"])
def test_entry_point_gives_the_dispatchers_state_bit_for_bit(serial):
    models = [_model(fast, serial) for fast in (True, False)]
    assert models[0].P.pi.shape[0] > 64  # the pair list grew
    a, b = (_state(m) for m in models)
    assert a.keys() == b.keys()
    differ = [k for k in a if not np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f")]
    assert differ == []
    assert models[0].step == models[1].step and models[0].n_bonds > 0


@pytest.mark.skipif(JIT_DISABLED, reason="numba is off: the kernel is plain Python")
def test_the_kept_entry_point_follows_the_states_records():
    m, _ = box_pack(40, seed=1)
    m.cycle(2)
    state, run = m._kernels[K.run_steps]
    assert run is not K.run_steps  # the compiled entry point, not the dispatcher
    assert all(a is b for a, b in zip(state, (m.B, m.P, m.Bd, m.S, m.W, m.Fj)))
    m.bond(gap=0.0)  # new bond records
    m.cycle(1)
    kept = m._kernels[K.run_steps]
    assert kept[0][2] is m.Bd and kept[1] is not K.run_steps


@pytest.mark.skipif(JIT_DISABLED, reason="numba is off: nothing is compiled")
def test_compiled_refuses_arguments_of_types_never_compiled():
    m, _ = box_pack(20, seed=2)
    m.cycle(1)
    args = (m.B, m.P, m.Bd, m.S, m.W, m.Fj, m.prm, m.iprm, m.eacc)
    assert compiled(K.run_steps, (*args, 3, True, True)) is not None
    assert compiled(K.run_steps, (*args, 3.0, True, True)) is None  # a float step count
    assert compiled(K.run_steps, (*args[:-1], m.eacc.astype(np.float32), 3, True,
                                  True)) is None


def test_unbalanced_ratio_is_pfcs_mean_force_ratio_with_and_without_fixed_balls():
    """Mean |resultant| of the free balls over the mean contact force, the norm as numpy's
    ``linalg.norm`` gives it (bit for bit), with every ball free and with some fixed."""
    from bpmcal.dem import diagnostics as D
    from bpmcal.dem.slots import I_NB, I_NPAIRS

    m, _ = box_pack(60, seed=5)
    m.set_gravity((0.0, 0.0, -9.81e3))
    for fixed in (False, True):
        if fixed:
            m.fix([0, 5, 9])
        m.cycle(3)
        r = m.unbalanced_ratio()
        free = m.B.fix == 0
        fc, _ = D.contact_force_mean(m.B.pos, m.B.radius, m.P.pi, m.P.pj, m.P.fs,
                                     int(m.iprm[I_NPAIRS]), int(m.iprm[I_NB]), m.Bd.state,
                                     m.Bd.blk, m.prm, m.Fj.c)
        assert r == float(np.linalg.norm(m.B.force[free], axis=1).mean() / fc)
        assert 0.0 < r < np.inf


def test_a_pickled_model_steps_on_as_the_original():
    import pickle

    a, _ = box_pack(30, seed=6)
    a.cycle(5)
    b = pickle.loads(pickle.dumps(a))
    a.cycle(40)
    b.cycle(40)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.velocities,
                                                                       b.velocities)
