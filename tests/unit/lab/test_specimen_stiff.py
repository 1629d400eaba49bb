"""A stiff rock's genesis is not stopped by the blow-up guard: ball speeds while the
overlapped packing settles scale with the P-wave speed sqrt(E / rho) (found with the Lac
du Bonnet example: a 106 GPa sample failed at 500 m/s although nothing blew up)."""
import math

import numpy as np
import pytest

from bpmcal.dem.errors import InstabilityError
from bpmcal.lab.packing_cache import get_packing
from bpmcal.lab.specimen import SpecimenSpec, build_specimen, paper_material, speed_guard

STIFF = dict(pb_emod_GPa=106.05817664944726, pb_kratio=5.695527088761074,
             pb_ten_MPa=61.107161474749645, pb_coh_MPa=129.1826816199465, pb_fa_deg=35.0,
             fric=0.35)


def test_guard_follows_the_wave_speed_of_the_stiffer_spring():
    soft = paper_material(10.0, 2.0, 20.0, 20.0, 35.0, 0.35)
    stiff = paper_material(**STIFF)
    assert speed_guard(soft, 2294.0) == pytest.approx(2 * math.sqrt(10e9 / 2294.0))
    assert speed_guard(stiff, 2294.0) == pytest.approx(2 * math.sqrt(STIFF["pb_emod_GPa"] * 1e9
                                                                     / 2294.0))
    assert speed_guard(paper_material(1e-3, 2.0, 20.0, 20.0, 35.0, 0.35), 2294.0) == 500.0


def test_stiff_specimen_settles_and_its_peak_speed_scales_with_the_wave_speed(tmp_path):
    spec = SpecimenSpec.from_paper_units(0.8, 0.34, 231078760, scale=0.25)
    pk = get_packing(spec, cache=tmp_path)
    sp = build_specimen(pk, paper_material(**STIFF))  # failed with the fixed 500 m/s guard
    assert sp.report["n_bonds"] > 3 * sp.report["n_balls"]
    v = np.linalg.norm(sp.model.B.vel, axis=1).max()
    assert np.isfinite(v) and v < speed_guard(paper_material(**STIFF), 2294.0)


def test_a_real_blow_up_is_still_caught(tmp_path):
    spec = SpecimenSpec.from_paper_units(0.8, 0.34, 5, scale=0.25)
    sp = build_specimen(get_packing(spec, cache=tmp_path), paper_material(**STIFF))
    m = sp.model
    # 400x stiffer springs at the old timestep: 20x above the critical step, the
    # central-difference scheme grows exponentially until the guard stops it
    m.set_material(paper_material(**dict(STIFF, pb_emod_GPa=400 * STIFF["pb_emod_GPa"])))
    with pytest.raises(InstabilityError, match="blew up"):
        m.cycle(5000)
