"""The paper's calibrated specimen A1 and the small specimens the tests build from it."""
from bpmcal.lab.runner import Geometry
from bpmcal.lab.ucs import UCSSettings
from bpmcal.study.paper import CALIBRATED

#: the paper's calibrated specimen A1 (section 4.2's set for B1, at n = 0.34 and
#: Rmin = 0.8 mm); phi_p and mu at the Table 2 midpoints (our choice)
A1 = dict(rmin_mm=0.8, porosity=0.34, **CALIBRATED["B1"], pb_fa_deg=35.0, fric=0.35)

#: small specimens for tests: 12 x 24 mm, Rmin 0.8 mm (~300 balls)
SMALL = Geometry(scale=0.24)
#: a fast UCS loading for them (platen 0.1 m/s, a record every 4e-5 of strain)
FAST = UCSSettings(platen_velocity=0.1, record_strain=4e-5)

#: a flat-jointed card for tests (PFC ``flatjoint``; granite-like strengths, 20 % slits)
FJ1 = dict(contact_model="flatjoint", rmin_mm=0.8, porosity=0.30, fj_emod_GPa=60.0,
           fj_kratio=2.0, fj_ten_MPa=10.0, fj_coh_MPa=100.0, fj_fa_deg=30.0, fj_fric=0.6,
           fj_gi_ratio=0.2, fj_slit_frac=0.2)
