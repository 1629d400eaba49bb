"""The lab tests on the driver against closed forms: a simple-cubic lattice of equal,
touching, bonded balls (spacing 2 R) loaded along its columns.

Each column is a chain of springs in series (docs/contact_laws.md): between two balls the
linear contact kn = pi R E* / 2 in parallel with the parallel bond kn_b A = pi R E-bar / 2
(r = R, L = 2 R), at a platen the linear contact pi R E* (L = R). A column's cross-section
is (2 R)^2 and its height 2 R nz, so

- UCS (frictionless platens): E = 2 R nz / (4 R^2 ((nz - 1) / k_bb + 2 / k_bw)), and
  nu = 0 exactly (no lateral coupling in a simple-cubic lattice);
- direct tension (grips on the end layers, no walls; linear contacts carry no tension):
  E_t = 2 R nz / (4 R^2 (nz - 1) / k_b), the bonds between the two grip layers in series.

The loading is slow enough (2 mm/s) to be quasi-static to a few 1e-4 (at 10 mm/s the UCS
slope is 0.8 % low; at 0.5 mm/s both within 1e-4). A driver that broke a test's cycling,
records or stop would move these."""
import math

import numpy as np
import pytest

from bpmcal.dem import Material, Model
from bpmcal.lab.direct_tension import DTTSettings, run_dtt
from bpmcal.lab.specimen import Specimen
from bpmcal.lab.ucs import UCSSettings, run_ucs

R = 1e-3
NX, NY, NZ = 4, 4, 6


def lattice(emod, pb_emod, walls: bool):
    """The lattice (NX x NY columns of NZ balls, centred on the z axis) as a Specimen, with
    two frictionless platens touching its end faces (``walls``) or free."""
    idx = np.array([(i, j, k) for i in range(NX) for j in range(NY) for k in range(NZ)], float)
    pos = idx * 2 * R
    pos[:, :2] -= (np.array([NX, NY]) - 1) * R
    mat = Material(emod=emod, kratio=2.0, fric=0.5, pb_emod=pb_emod, pb_kratio=2.0,
                   pb_ten=1e9, pb_coh=1e9, pb_fa=30.0)  # bonds that do not break here
    m = Model(pos, np.full(len(pos), R), 2500.0, mat, damping=0.7)
    m.bond(gap=0.01 * R)
    zb, zt = -R, (NZ - 1) * 2 * R + R
    platens = ()
    if walls:
        platens = (m.add_plane_wall((0, 0, zb), (0, 0, 1.0)),
                   m.add_plane_wall((0, 0, zt), (0, 0, -1.0)))
    side = (np.abs(pos[:, 0]) > (NX - 2) * R) | (np.abs(pos[:, 1]) > (NY - 2) * R)
    r0 = math.sqrt(NX * NY * 4 * R * R / math.pi)  # pi r0^2: the columns' cross-section
    return Specimen(model=m, spec=None, material=mat, report={}, surface=np.flatnonzero(side),
                    z_bottom=zb, z_top=zt, radius0=r0, platens=platens)


@pytest.mark.parametrize("emod, pb_emod", [(10e9, 20e9), (30e9, 5e9)])
@pytest.mark.parametrize("scaling, nu_tol", [(0.0, 1e-9), (None, 1e-5)])
def test_ucs_of_a_simple_cubic_lattice_is_its_closed_form(emod, pb_emod, scaling, nu_tol):
    """With the true masses (0) the lattice keeps its symmetry: nu is 0 to round-off;
    with the default density scaling (None: the median ball's timestep for parallel
    bonds) the boundary balls, which have fewer contacts, keep their mass while the inner
    ones get heavier, and the small dynamic lag this leaves stays below 1e-5 in nu; E is
    the closed form's in both."""
    sp = lattice(emod, pb_emod, walls=True)
    res = run_ucs(sp, UCSSettings(platen_velocity=0.002, approach_velocity=0.0,
                                  max_strain=2e-4, record_strain=2e-6,
                                  density_scaling=scaling))
    s = res.summary
    k_bb, k_bw = math.pi * R * (emod + pb_emod) / 2, math.pi * R * emod
    E = 2 * R * NZ / (4 * R * R) / ((NZ - 1) / k_bb + 2 / k_bw)
    assert s["E_GPa"] * 1e9 == pytest.approx(E, rel=2e-3)
    assert abs(s["nu"]) < nu_tol
    assert s["stop_reason"] == "max_strain" and s["cracks_tension"] == s["cracks_shear"] == 0
    # the driver's steps: every record interval of 2e-6 axial strain, up to 2e-4
    n_rec = round(2e-6 * 2 * NZ * R / (2 * 0.002 * s["dt"]))
    assert s["steps"] == n_rec * (s["records"] - 1)
    assert res.series["axial_strain"][-1] >= 2e-4 > res.series["axial_strain"][-2]


def test_direct_tension_of_a_simple_cubic_lattice_is_its_closed_form():
    emod, pb_emod = 10e9, 20e9
    sp = lattice(emod, pb_emod, walls=False)
    res = run_dtt(sp, DTTSettings(grip_velocity=0.002, max_strain=2e-4, record_strain=2e-6))
    s = res.summary
    assert s["grip_balls_bottom"] == s["grip_balls_top"] == NX * NY  # one layer each
    k_b = math.pi * R * pb_emod / 2
    Et = 2 * R * NZ / (4 * R * R) / ((NZ - 1) / k_b)
    assert s["E_t_GPa"] * 1e9 == pytest.approx(Et, rel=2e-3)
    assert s["stop_reason"] == "max_strain"
