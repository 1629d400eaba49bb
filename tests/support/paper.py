"""The paper's calibrated specimen A1 (``bpmcal.study.paper.A1``) and the small specimens the
tests build from it."""
from bpmcal.lab.runner import Geometry
from bpmcal.lab.ucs import UCSSettings
from bpmcal.study.paper import A1  # noqa: F401  (the paper's card: bpmcal.study.paper)

#: small specimens for tests: 12 x 24 mm, Rmin 0.8 mm (~300 balls)
SMALL = Geometry(scale=0.24)
#: a fast UCS loading for them (platen 0.1 m/s, a record every 4e-5 of strain)
FAST = UCSSettings(platen_velocity=0.1, record_strain=4e-5)

#: a flat-jointed card for tests (PFC ``flatjoint``; granite-like strengths, 20 % slits)
FJ1 = dict(contact_model="flatjoint", rmin_mm=0.8, porosity=0.30, fj_emod_GPa=60.0,
           fj_kratio=2.0, fj_ten_MPa=10.0, fj_coh_MPa=100.0, fj_fa_deg=30.0, fj_fric=0.6,
           fj_gi_ratio=0.2, fj_slit_frac=0.2)
