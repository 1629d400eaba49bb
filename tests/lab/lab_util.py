import pytest

from bpmcal.lab.runner import Geometry, make_specimen
from bpmcal.lab.ucs import UCSSettings, run_ucs

#: the paper's calibrated specimen A1; phi_p and mu at the Table 2 midpoints (our choice)
A1 = dict(rmin_mm=0.8, porosity=0.34, pb_emod_GPa=10.396, pb_kratio=3.467, pb_ten_MPa=27.670,
          pb_coh_MPa=19.689, pb_fa_deg=35.0, fric=0.35)

#: small specimens for tests: 12 x 24 mm, Rmin 0.8 mm (~300 balls)
SMALL = Geometry(scale=0.24)
FAST = UCSSettings(platen_velocity=0.1, record_strain=4e-5)


@pytest.fixture(scope="session")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("packings")


def ucs(params, cache, seed=3, geometry=SMALL, settings=FAST):
    sp = make_specimen(params, seed, geometry, cache=cache)
    return run_ucs(sp, settings), sp
