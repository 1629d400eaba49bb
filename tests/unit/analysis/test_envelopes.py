"""Mohr-Coulomb and Hoek-Brown envelope fits: planted parameters recovered, errors."""
import math

import numpy as np
import pytest

from bpmcal.analysis.envelopes import (
    EnvelopeError,
    fit_hoek_brown,
    fit_mohr_coulomb,
    hoek_brown_sigma1,
    mohr_coulomb_q,
    mohr_coulomb_sigma_c,
)

S3 = np.array([0.0, 5.0, 10.0, 20.0, 30.0])


def test_mohr_coulomb_recovers_planted_c_and_phi_exactly():
    c, phi = 12.5, 37.0
    s1 = mohr_coulomb_sigma_c(c, phi) + mohr_coulomb_q(phi) * S3
    mc = fit_mohr_coulomb(S3, s1)
    assert mc.c == pytest.approx(c, rel=1e-10)
    assert mc.phi_deg == pytest.approx(phi, rel=1e-10)
    assert mc.sigma_c == pytest.approx(2 * c * math.cos(math.radians(phi))
                                       / (1 - math.sin(math.radians(phi))), rel=1e-10)
    assert mc.c_se == pytest.approx(0.0, abs=1e-9) and mc.rms == pytest.approx(0, abs=1e-9)


def test_mohr_coulomb_standard_errors_cover_the_planted_values():
    """Noisy points from a planted envelope: the fitted values lie within 3 standard errors
    in (nearly) every draw, and the standard errors match the spread over draws."""
    c, phi = 8.0, 32.0
    s3 = np.repeat([0.0, 5.0, 10.0, 20.0], 3)
    truth = mohr_coulomb_sigma_c(c, phi) + mohr_coulomb_q(phi) * s3
    rng = np.random.default_rng(7)
    fits = [fit_mohr_coulomb(s3, truth + rng.normal(0, 1.0, s3.size)) for _ in range(400)]
    cs = np.array([f.c for f in fits])
    ph = np.array([f.phi_deg for f in fits])
    cover_c = np.mean([abs(f.c - c) <= 3 * f.c_se for f in fits])
    cover_p = np.mean([abs(f.phi_deg - phi) <= 3 * f.phi_se_deg for f in fits])
    assert cover_c > 0.97 and cover_p > 0.97
    assert np.median([f.c_se for f in fits]) == pytest.approx(cs.std(), rel=0.2)
    assert np.median([f.phi_se_deg for f in fits]) == pytest.approx(ph.std(), rel=0.2)
    assert abs(cs.mean() - c) < 0.1 * c and abs(ph.mean() - phi) < 1.0


def test_hoek_brown_recovers_planted_mi_with_and_without_sigma_ci():
    sci, mi = 45.0, 11.0
    s1 = hoek_brown_sigma1(S3, sci, mi)
    hb = fit_hoek_brown(S3, s1, sigma_ci=sci)
    assert hb.mi == pytest.approx(mi, rel=1e-10) and hb.sigma_ci_fixed
    both = fit_hoek_brown(S3, s1)
    assert both.mi == pytest.approx(mi, rel=1e-10)
    assert both.sigma_ci == pytest.approx(sci, rel=1e-10)
    assert not both.sigma_ci_fixed and both.r2 == pytest.approx(1.0)


def test_hoek_brown_with_noise_is_unbiased_within_its_standard_error():
    sci, mi = 60.0, 15.0
    s3 = np.repeat([0.0, 5.0, 10.0, 20.0], 3)
    rng = np.random.default_rng(11)
    fits = [fit_hoek_brown(s3, hoek_brown_sigma1(s3, sci, mi) + rng.normal(0, 1.5, s3.size))
            for _ in range(300)]
    m = np.array([f.mi for f in fits])
    assert abs(m.mean() - mi) < 0.5
    assert np.median([f.mi_se for f in fits]) == pytest.approx(m.std(), rel=0.25)
    assert np.mean([abs(f.mi - mi) <= 3 * f.mi_se for f in fits]) > 0.97


def test_hoek_brown_curvature_is_not_a_straight_line():
    """A Mohr-Coulomb line has constant slope q; a Hoek-Brown envelope flattens. The MC
    fit to HB points misfits; the HB fit does not."""
    s1 = hoek_brown_sigma1(S3, 50.0, 20.0)
    assert fit_mohr_coulomb(S3, s1).rms > 0.5
    assert fit_hoek_brown(S3, s1).rms < 1e-9


@pytest.mark.parametrize("s3, s1, needle", [
    ([5.0], [60.0], "at least 2"),
    ([10.0, 10.0, 10.0], [60.0, 61.0, 62.0], "all sigma3 are equal"),
    ([0.0, 5.0], [40.0, 4.0], "sigma1 = 4 <= sigma3 = 5"),
    ([0.0, -5.0], [40.0, 30.0], "sigma3 = -5"),
    ([0.0, 5.0], [40.0, float("nan")], "finite"),
    ([0.0, 5.0, 10.0], [40.0, 40.0, 40.0], "<= 1: sigma1 does not rise faster"),
    ([0.0, 5.0], [40.0, 50.0, 60.0], "differ in length"),
])
def test_mohr_coulomb_refuses_points_that_define_no_envelope(s3, s1, needle):
    with pytest.raises(EnvelopeError, match=needle.replace("(", r"\(")):
        fit_mohr_coulomb(s3, s1)


def test_hoek_brown_errors():
    with pytest.raises(EnvelopeError, match="at least 2"):
        fit_hoek_brown([5.0], [60.0])
    with pytest.raises(EnvelopeError, match="all sigma3 are equal"):
        fit_hoek_brown([5.0, 5.0], [60.0, 61.0])
    with pytest.raises(EnvelopeError, match="sigma3 > 0"):
        fit_hoek_brown([0.0, 0.0], [45.0, 46.0], sigma_ci=45.0)
    with pytest.raises(EnvelopeError, match="sigma_ci"):
        fit_hoek_brown([0.0, 5.0], [45.0, 60.0], sigma_ci=-1.0)
    with pytest.raises(EnvelopeError, match="m_i"):
        fit_hoek_brown([0.0, 10.0], [45.0, 50.0], sigma_ci=45.0)  # q < 1: mi < 0
    # one confined point with a given sigma_ci determines m_i (no standard error)
    hb = fit_hoek_brown([10.0], [hoek_brown_sigma1(10.0, 45.0, 9.0)], sigma_ci=45.0)
    assert hb.mi == pytest.approx(9.0) and math.isnan(hb.mi_se)
