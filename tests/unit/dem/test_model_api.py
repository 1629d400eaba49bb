"""The Model accessors that lab/ and io/ use instead of the engine's internal arrays."""
import math

import numpy as np
import pytest
from support.dem_util import RHO, material

from bpmcal.dem import BOND_INTACT, InputError, Model
from bpmcal.dem.slots import FIX_ALL, WALL_CYLINDER, WALL_PLANE


def _ball_on_floor():
    """One ball resting 1 um deep on a floor (wall 0) inside a cylinder (wall 1)."""
    r = 1e-3
    m = Model([[0.0, 0.0, r - 1e-6]], [r], RHO, material(), damping=0.0)
    m.add_plane_wall((0, 0, 0), (0, 0, 1))
    m.add_cylinder_wall((0, 0, 0), (0, 0, 1), 2.5e-3)
    m.set_timestep(None)
    m.cycle(1)
    return m


def test_state_views_are_read_only_and_follow_the_model():
    m = _ball_on_floor()
    pos = m.positions
    assert pos.shape == (1, 3) and m.radii.shape == (1,)
    with pytest.raises(ValueError):
        pos[0, 0] = 1.0
    z0 = float(pos[0, 2])
    m.cycle(5)
    assert float(m.positions[0, 2]) != z0  # pushed up by the floor
    assert float(pos[0, 2]) == float(m.positions[0, 2])  # a view, not a snapshot
    assert m.masses[0] == pytest.approx(RHO * 4 / 3 * math.pi * 1e-9)
    assert m.velocities[0, 2] > 0 and m.angular_velocities.shape == (1, 3)


def test_wall_accessors():
    m = _ball_on_floor()
    assert m.wall_contact_balls(0).tolist() == [0]  # touching the floor
    assert m.wall_contact_balls(1).size == 0  # far from the cylinder
    f = m.wall_force(0)
    assert f[2] < 0  # the ball pushes the floor down
    assert m.wall_radial_force(1) == 0.0
    m.set_wall_friction([0, 1], 0.3)
    with pytest.raises(InputError, match="fric"):
        m.set_wall_friction(0, -0.1)
    with pytest.raises(InputError, match="wall id"):
        m.set_wall_friction(7, 0.1)
    m.add_plane_wall((0, 0, 5e-3), (0, 0, -1), velocity=(0, 0, -0.1))
    assert m.wall_velocity(2).tolist() == [0.0, 0.0, -0.1]
    z = m.wall_position(2)[2]
    m.cycle(10)
    assert m.wall_position(2)[2] == pytest.approx(z - 10 * m.dt * 0.1, rel=1e-12)


def test_cylinder_radial_force_is_the_lateral_push():
    r = 1e-3
    m = Model([[1.5e-3 - r + 2e-6, 0.0, 0.0]], [r], RHO, material(), damping=0.0)
    m.add_cylinder_wall((0, 0, 0), (0, 0, 1), 1.5e-3)
    m.set_timestep(None)
    m.cycle(0)
    m.energies()
    kn = math.pi * r * m.material.emod  # ball-wall stiffness
    assert m.wall_radial_force(0) == pytest.approx(kn * 2e-6, rel=1e-9)
    assert m.wall_contact_balls(0).tolist() == [0]


def test_bond_views_and_counters():
    m = Model([[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0]], [1e-3, 1e-3], RHO, material())
    assert m.bond(gap=1e-9) == 1
    m.set_timestep(None)
    st = m.bond_states
    assert st.tolist() == [BOND_INTACT] and m.bond_break_steps.tolist() == [-1]
    with pytest.raises(ValueError):
        st[0] = 2
    assert m.n_rebuilds >= 1 and m.n_wall_slots == 0
    assert m.skin == pytest.approx(0.125e-3)
    assert isinstance(m.positions, np.ndarray)


def test_wall_geometry_and_prescribed_motion():
    """Kind, normal and radius of the walls; a cylinder's radius follows its prescribed
    radial velocity (r = r0 + v_r t), a plane its velocity."""
    m = _ball_on_floor()
    assert m.wall_type(0) == WALL_PLANE and m.wall_type(1) == WALL_CYLINDER
    assert m.wall_normal(0).tolist() == [0.0, 0.0, 1.0]
    assert m.wall_normal(1).tolist() == [0.0, 0.0, 1.0]
    n = m.wall_normal(0)
    n[2] = 5.0  # a copy: the wall is unchanged
    assert m.wall_normal(0)[2] == 1.0
    assert m.wall_radius(0) == 0.0 and m.wall_radius(1) == 2.5e-3
    m.set_wall_velocity(1, radial_velocity=0.2)
    m.set_wall_velocity(0, velocity=(0.0, 0.0, -0.1))
    z0 = m.wall_position(0)[2]
    m.cycle(10)
    assert m.wall_radius(1) == pytest.approx(2.5e-3 + 10 * m.dt * 0.2, rel=1e-12)
    assert m.wall_position(0)[2] == pytest.approx(z0 - 10 * m.dt * 0.1, rel=1e-12)
    m.set_wall_velocity(1, radial_velocity=0.0)
    r = m.wall_radius(1)
    m.cycle(3)
    assert m.wall_radius(1) == r


def test_fix_flags_view():
    m = _ball_on_floor()
    flags = m.fix_flags
    assert flags.tolist() == [0]
    m.fix([0])
    assert flags.tolist() == [FIX_ALL]  # a view: follows the model
    with pytest.raises(ValueError):
        flags[0] = 0


def _defined_twice(classes) -> set:
    """Names (not dunders) that more than one of ``classes`` defines itself."""
    seen, twice = set(), set()
    for c in classes:
        own = {n for n in vars(c) if not n.startswith("__")}
        twice |= seen & own
        seen |= own
    return twice


def test_model_is_its_module_and_four_mixins_without_overlap():
    """``Model`` = model.py (state, parameters, balls, lists, cycle) + ``WallsMixin`` +
    ``BondsMixin`` + ``FlatJointsMixin`` + ``MeasureMixin``: every member is defined in
    exactly one of them (a name in two would be shadowed silently by the MRO), and each
    part holds its concept."""
    from bpmcal.dem.model_bonds import BondsMixin
    from bpmcal.dem.model_flatjoints import FlatJointsMixin
    from bpmcal.dem.model_measure import MeasureMixin
    from bpmcal.dem.model_walls import WallsMixin

    parts = (Model, WallsMixin, BondsMixin, FlatJointsMixin, MeasureMixin)
    assert Model.__mro__[1:5] == parts[1:]
    assert not _defined_twice(parts)
    public = {n for n in dir(Model) if not n.startswith("_")}
    assert public == {n for c in parts for n in vars(c) if not n.startswith("_")}
    assert {"add_plane_wall", "remove_wall", "wall_force"} <= set(vars(WallsMixin))
    assert {"bond", "breaks", "bond_state", "set_bond_strength_factors"} <= set(vars(BondsMixin))
    assert {"energies", "energy_balance", "momentum"} <= set(vars(MeasureMixin))
    assert {"set_flatjoint_types", "flatjoint_state", "crack_counts"} <= set(vars(FlatJointsMixin))
    assert {"cycle", "set_timestep", "positions"} <= set(vars(Model))
    # the check sees an overlap
    assert _defined_twice((type("A", (), {"f": 1}), type("B", (), {"f": 2, "g": 3}))) == {"f"}


def test_wall_contact_balls_of_a_pack_in_a_box_match_the_slots():
    """The balls touching each wall of a pack in a box of six walls: the sorted, unique
    balls of the slots on that wall with a non-zero force (the definition, in numpy)."""
    from support.dem_util import box_pack

    m, _ = box_pack(120, seed=3)
    S, ns = m.S, m.n_wall_slots
    for w in range(m.n_walls):
        on = (S.w[:ns] == w) & np.any(S.f[:ns] != 0.0, axis=1)
        want = np.unique(S.b[:ns][on])
        got = m.wall_contact_balls(w)
        assert got.dtype == np.int32 and got.tolist() == want.tolist()
    assert sum(m.wall_contact_balls(w).size for w in range(m.n_walls)) > 0


def test_unbalanced_ratio_follows_a_settings_change_between_measurements():
    """The unbalanced-force ratio reuses the measure pass of ``energies`` only while the
    state and the settings are those measured: after a gravity change without a step it
    equals that of a model measured afresh with that gravity."""
    from support.dem_util import box_pack

    a, _ = box_pack(60, seed=4)
    b, _ = box_pack(60, seed=4)
    a.energies()
    r0 = a.unbalanced_ratio()
    assert r0 == b.unbalanced_ratio()
    a.set_gravity((0.0, 0.0, -9.81e3))
    b.set_gravity((0.0, 0.0, -9.81e3))
    b.energies()
    r1 = a.unbalanced_ratio()
    assert r1 != r0 and r1 == b.unbalanced_ratio()
