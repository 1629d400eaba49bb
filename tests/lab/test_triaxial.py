"""Triaxial test on small specimens: the unconfined limit, the confinement effect, the servo."""
import numpy as np
import pytest
from lab_util import A1, FAST, SMALL

from bpmcal.dem.errors import InputError
from bpmcal.lab.runner import make_specimen
from bpmcal.lab.triaxial import TriaxialSettings, run_triaxial
from bpmcal.lab.ucs import run_ucs

SEED = 3
TX = dict(platen_velocity=FAST.platen_velocity, record_strain=FAST.record_strain)


def triaxial(cache, sigma3_MPa, seed=SEED, **kw):
    sp = make_specimen(A1, seed, SMALL, cache=cache, boundary="vessel")
    return run_triaxial(sp, TriaxialSettings(sigma3=sigma3_MPa * 1e6, **TX, **kw))


@pytest.fixture(scope="module")
def runs(cache):
    return {s3: triaxial(cache, s3) for s3 in (0.0, 5.0, 10.0)}


def test_unconfined_triaxial_reproduces_the_ucs_test(runs, cache):
    """sigma3 = 0 (servo-controlled cylinder, consolidation to zero stress) against the UCS
    test (no cylinder) on the same packing: well inside the packing scatter (3.3 % CV of
    sigma_c, 0.9 % of E, 1.2 % of nu, README)."""
    u = run_ucs(make_specimen(A1, SEED, SMALL, cache=cache), FAST).summary
    t = runs[0.0].summary
    assert t["sigma1_MPa"] == pytest.approx(u["ucs_MPa"], rel=0.03)
    assert t["E_GPa"] == pytest.approx(u["E_GPa"], rel=0.01)
    assert abs(t["nu"] - u["nu"]) < 0.01
    # the wall retreats from the bulging surface: the lateral stress stays negligible
    assert t["sigma3_maxdev_MPa"] < 0.005 * t["sigma1_MPa"]


def test_peak_axial_stress_rises_with_confinement(runs):
    s1 = [runs[s3].summary["sigma1_MPa"] for s3 in (0.0, 5.0, 10.0)]
    assert s1[0] < s1[1] < s1[2], s1
    # a frictional material: sigma1 grows faster than sigma3 (q > 1)
    assert (s1[2] - s1[0]) / 10.0 > 1.5
    for s3 in (0.0, 5.0, 10.0):
        s = runs[s3].summary
        assert s["stop_reason"] == "post_peak_drop"
        assert s["sigma1_MPa"] == pytest.approx(s3 + s["deviator_MPa"])


@pytest.mark.parametrize("s3", [5.0, 10.0])
def test_servo_holds_sigma3_within_one_percent_up_to_the_peak(runs, s3):
    r = runs[s3]
    ser = r.series
    ip = int(np.argmax(ser["deviator"]))
    dev = np.abs(ser["confining_stress"][: ip + 1] / (s3 * 1e6) - 1.0)
    assert ip > 20 and dev.max() < 0.01, dev.max()
    assert r.summary["sigma3_maxdev_rel"] == pytest.approx(dev.max())
    # the lateral stress is the radial wall force over the current wall area
    assert ser["wall_radius"][ip] > ser["wall_radius"][0]  # the specimen dilates
    # consolidation reached sigma3 on all walls before loading
    assert abs(ser["confining_stress"][0] / (s3 * 1e6) - 1) < 0.005
    assert abs(ser["axial_stress"][0] / (s3 * 1e6) - 1) < 0.005


def test_confined_moduli_and_strain_definitions(runs):
    """E from the deviator is nearly independent of sigma3 for bonded particles (the bonds
    carry tension and compression alike); nu from the surface balls agrees with the wall's
    radius change under confinement, where the rigid wall holds the surface."""
    e0 = runs[0.0].summary["E_GPa"]
    for s3 in (5.0, 10.0):
        s = runs[s3].summary
        assert s["E_GPa"] == pytest.approx(e0, rel=0.05)
        assert abs(s["nu"] - s["nu_wall"]) < 0.02
        ser = runs[s3].series
        assert np.allclose(ser["volumetric_strain"],
                           ser["axial_strain"] + 2 * ser["lateral_strain"])


def test_triaxial_settings_refuse_bad_values():
    for kw, needle in [(dict(sigma3=-1e6), "sigma3=-1000000.0"),
                       (dict(sigma3=float("nan")), "sigma3=nan"),
                       (dict(servo_alpha=1.5), "servo_alpha=1.5"),
                       (dict(servo_interval=0), "servo_interval=0")]:
        with pytest.raises(InputError, match=needle):
            TriaxialSettings(**kw)
