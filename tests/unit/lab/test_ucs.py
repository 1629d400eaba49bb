"""UCS test on small specimens: scaling laws and invariants of the bonded-particle model."""
import dataclasses
import math

import numpy as np
import pytest
from support.lab_util import A1, FAST, SMALL, ucs

from bpmcal.dem import InputError
from bpmcal.lab.runner import make_specimen, ucs_inputs
from bpmcal.lab.specimen import end_cap_bonds
from bpmcal.lab.triaxial import TriaxialSettings
from bpmcal.lab.ucs import UCSSettings, analyse, run_ucs


def scaled(p, k, moduli=True, strengths=False):
    q = dict(p)
    if moduli:
        q["pb_emod_GPa"] = p["pb_emod_GPa"] * k
    if strengths:
        q["pb_ten_MPa"] = p["pb_ten_MPa"] * k
        q["pb_coh_MPa"] = p["pb_coh_MPa"] * k
    return q


@pytest.fixture(scope="module")
def base(cache):
    res, sp = ucs(A1, cache)
    return res.summary


def test_ucs_produces_a_peak_and_stops_after_it(base):
    s = base
    assert s["stop_reason"] == "post_peak_drop"
    assert s["ucs_MPa"] > 5 and 2 < s["E_GPa"] < 40 and 0.05 < s["nu"] < 0.45
    assert s["fit_points"] >= 5
    assert 0 < s["crack_init_MPa"] < s["ucs_MPa"]
    assert s["cracks_tension"] + s["cracks_shear"] > 0
    # pre-peak energy density bracketed by the elastic triangle and the full rectangle
    up = s["u_pre_MJm3"]
    assert 0.3 * 0.5 * s["ucs_MPa"] * s["peak_strain"] < up < s["ucs_MPa"] * s["peak_strain"]


def test_E_doubles_when_both_moduli_double_and_nu_is_unchanged(base, cache):
    s2 = ucs(scaled(A1, 2.0), cache)[0].summary
    assert s2["E_GPa"] / base["E_GPa"] == pytest.approx(2.0, rel=0.03)
    assert abs(s2["nu"] - base["nu"]) <= 0.01


def test_scaling_moduli_and_strengths_scales_stress_not_strain(base, cache):
    k = 1.7
    s2 = ucs(scaled(A1, k, strengths=True), cache)[0].summary
    assert s2["ucs_MPa"] / base["ucs_MPa"] == pytest.approx(k, rel=0.03)
    assert s2["E_GPa"] / base["E_GPa"] == pytest.approx(k, rel=0.03)
    assert s2["peak_strain"] / base["peak_strain"] == pytest.approx(1.0, rel=0.03)


def test_more_porosity_never_gives_a_stiffer_specimen(cache):
    E = [ucs(dict(A1, porosity=n), cache)[0].summary["E_GPa"] for n in (0.22, 0.28, 0.34)]
    assert E[0] > E[1] > E[2], E


def test_stronger_bonds_give_higher_ucs(base, cache):
    s2 = ucs(scaled(A1, 1.5, moduli=False, strengths=True), cache)[0].summary
    assert s2["ucs_MPa"] > 1.2 * base["ucs_MPa"]


def test_analyse_against_a_closed_form_curve():
    """sigma = E eps (1 - eps/(2 eps_p)) up to the peak, then a linear drop: E from the
    40-60 % window, the peak, U_p = integral, nu from a linear lateral strain."""
    E, ep, nu = 12e9, 0.005, 0.23
    eps = np.linspace(0, 1.6 * ep, 2001)
    sig = np.where(eps <= ep, E * eps * (1 - eps / (2 * ep)),
                   E * ep / 2 * (1 - (eps - ep) / (0.6 * ep) * 0.5))
    ser = {"axial_stress": sig, "axial_strain": eps, "lateral_strain": -nu * eps,
           "cracks_tension": (eps > 0.5 * ep).astype(int) * 10,
           "cracks_shear": np.zeros_like(eps, dtype=int)}
    r = analyse(ser, UCSSettings())
    assert r["ucs_MPa"] == pytest.approx(E * ep / 2 / 1e6, rel=1e-6)
    assert r["peak_strain"] == pytest.approx(ep, rel=1e-3)
    # tangent slope averaged over the window: E (1 - eps/eps_p) for sigma in [0.4, 0.6] peak
    lo = ep * (1 - math.sqrt(1 - 0.4))
    hi = ep * (1 - math.sqrt(1 - 0.6))
    mid = 0.5 * (lo + hi)
    assert r["E_GPa"] == pytest.approx(E * (1 - mid / ep) / 1e9, rel=0.01)
    assert r["nu"] == pytest.approx(nu, rel=1e-9)
    assert (r["nu_window_lo"], r["nu_window_hi"]) == (0.4, 0.6)  # no dilation: E's window
    assert r["u_pre_MJm3"] == pytest.approx(E * ep ** 2 / 3 / 1e6, rel=1e-4)
    assert r["crack_init_MPa"] == pytest.approx(
        sig[np.argmax(eps > 0.5 * ep)] / 1e6, rel=1e-9)


def test_nu_before_crack_dilation_is_reported_beside_nu():
    """A specimen elastic (nu 0.17) up to 0.3 sigma_c whose lateral strain then grows with
    the cracks (tangent nu rising to 1.5, past 0.5 inside the 40-60 % window, as a
    flat-jointed card with slits does): ``nu_pre_dilation`` is fitted below the onset, over
    the window of E's proportions that ends there (0.2-0.3 sigma_c), and is the elastic
    one; nu and E keep their 40-60 % window (the lab's). Without the dilation both are
    the same nu over 40-60 %."""
    E, nu0, peak = 50e9, 0.17, 100e6
    sig = np.linspace(0.0, peak, 4001)
    eps = sig / E
    e_on = 0.3 * peak / E
    extra = np.where(eps > e_on, 4.0 * (eps - e_on) ** 2 / e_on, 0.0)  # dilation from 0.3
    ser = {"axial_stress": np.append(sig, 0.5 * peak),
           "axial_strain": np.append(eps, 1.1 * eps[-1]),
           "lateral_strain": np.append(-nu0 * eps - extra, -nu0 * eps[-1] - 2 * extra[-1]),
           "cracks_tension": np.zeros(4002, int), "cracks_shear": np.zeros(4002, int)}
    r = analyse(ser, UCSSettings())
    assert r["nu_window_hi"] == pytest.approx(0.3) and r["nu_window_lo"] == pytest.approx(0.2)
    assert r["nu_pre_dilation"] == pytest.approx(nu0, rel=1e-6)
    assert r["E_GPa"] == pytest.approx(E / 1e9, rel=1e-9)  # E: still 40-60 %
    old = -np.polyfit(eps[(sig >= 0.4 * peak) & (sig <= 0.6 * peak)],
                      ser["lateral_strain"][:4001][(sig >= 0.4 * peak) & (sig <= 0.6 * peak)],
                      1)[0]
    assert old > 0.5 and r["nu"] == pytest.approx(old, rel=1e-9)  # nu: the 40-60 % window
    flat = dict(ser, lateral_strain=np.append(-nu0 * eps, -nu0 * eps[-1]))
    r = analyse(flat, UCSSettings())
    assert (r["nu_window_lo"], r["nu_window_hi"]) == (0.4, 0.6)
    assert r["nu"] == r["nu_pre_dilation"] == pytest.approx(nu0, rel=1e-9)


def test_end_caps_strengthen_only_the_end_bonds_and_hold(base, cache):
    """End caps of one mean ball diameter: the bonds within it of a platen get
    1000 x their strength, the others keep theirs; none of the capped bonds breaks,
    although bonds among them break without the caps (end_cap=0, so the check can fail);
    E is unchanged (the stiffnesses are untouched) and, on this specimen, sigma_c is
    higher with the caps; the run file records the setting; the run is deterministic."""
    assert FAST.end_cap == 0.0 and FAST.end_cap_factor == 1000.0  # the defaults: no caps
    capped = dataclasses.replace(FAST, end_cap=1.0)
    sp = make_specimen(A1, 3, SMALL, cache=cache)
    idx = end_cap_bonds(sp, 1.0)
    assert 0 < idx.size < sp.model.n_bonds // 3
    res = run_ucs(sp, capped)
    s = res.summary
    f = sp.model.bond_strength_factors
    assert s["end_cap_bonds"] == idx.size
    assert np.all(f[idx] == 1000.0) and np.all(np.delete(f, idx) == 1.0)
    assert s["end_cap_broken"] == 0 and not np.any(sp.model.bond_states[idx])
    assert s["cracks_tension"] + s["cracks_shear"] > 0  # the specimen failed elsewhere
    off = FAST
    sp0 = make_specimen(A1, 3, SMALL, cache=cache)
    res0 = run_ucs(sp0, off)
    assert res0.summary["ucs_MPa"] == base["ucs_MPa"]  # the module's base run: no caps
    assert res0.summary["end_cap_bonds"] == 0 and res0.summary["end_cap_broken"] == 0
    assert np.all(sp0.model.bond_strength_factors == 1.0)
    assert np.count_nonzero(sp0.model.bond_states[idx]) > 0
    assert s["E_GPa"] == pytest.approx(res0.summary["E_GPa"], rel=2e-3)
    assert s["ucs_MPa"] > res0.summary["ucs_MPa"]
    assert ucs_inputs(A1, 3, SMALL, capped)["ucs_end_cap"] == 1.0
    assert ucs_inputs(A1, 3, SMALL, off)["ucs_end_cap"] == 0.0
    assert ucs_inputs(A1, 3, SMALL, capped)["ucs_end_cap_factor"] == 1000.0
    # deterministic: the same inputs give the same run, bit for bit
    res2 = run_ucs(make_specimen(A1, 3, SMALL, cache=cache), capped)
    for k, v in res.series.items():
        assert np.array_equal(v, res2.series[k]), k


@pytest.mark.parametrize("kw", [dict(end_cap=-1.0), dict(end_cap=math.nan),
                                dict(end_cap=11.0), dict(end_cap=True),
                                dict(end_cap_factor=0.5), dict(end_cap_factor=math.inf)])
def test_end_cap_settings_are_checked(kw):
    for cls in (UCSSettings, TriaxialSettings):
        with pytest.raises(InputError, match="end_cap"):
            cls(**kw)


def test_end_caps_that_would_meet_are_refused_before_the_test(cache):
    sp = make_specimen(A1, 3, SMALL, cache=cache)  # 24 mm high, mean ball diameter ~2.1 mm
    step = sp.model.step
    with pytest.raises(InputError, match="would meet"):
        run_ucs(sp, dataclasses.replace(FAST, end_cap=6.0))
    assert sp.model.step == step


@pytest.fixture(scope="module")
def approached(cache):
    """The base test with a fast approach (three times the platen velocity) until the first
    crack, slowed over 5 wave transits: its result and specimen."""
    return ucs(A1, cache, settings=dataclasses.replace(FAST, approach_velocity=0.3,
                                                       approach_ramp=5.0))


def test_the_approach_ends_at_the_first_crack_and_the_strain_is_the_platens_approach(
        approached):
    res, sp = approached
    s, ser = res.summary, res.series
    cracks = ser["cracks_tension"] + ser["cracks_shear"]
    k = int(np.argmax(cracks > cracks[0]))  # the first record with a crack of the loading
    assert 0 < k and s["approach_strain"] == ser["axial_strain"][k] > 0
    # the records come 3x as many steps apart after the ramp as before the switch
    dstep = np.diff(ser["step"])
    assert dstep[-1] / dstep[0] == pytest.approx(3.0, rel=0.05)
    assert (dstep[: k - 1] == dstep[0]).all()
    # the axial strain summed over the stretches at each speed (and the ramp's pieces) is
    # the platens' approach over the height, read from the walls themselves
    m = sp.model
    wb, wt = sp.platens
    H0 = sp.z_top - sp.z_bottom
    moved = (m.wall_position(wb)[2] - sp.z_bottom) + (sp.z_top - m.wall_position(wt)[2])
    assert ser["axial_strain"][-1] == pytest.approx(moved / H0, rel=1e-9)


def test_the_approach_keeps_the_responses_in_fewer_steps(base, approached):
    """A small A1 cylinder (24 mm high): E and nu are those of the constant-velocity test
    (they do not depend on the rate), sigma_c within its path scatter, in fewer steps."""
    s = approached[0].summary
    assert s["steps"] < 0.9 * base["steps"]
    assert s["E_GPa"] == pytest.approx(base["E_GPa"], rel=0.01)
    assert abs(s["nu"] - base["nu"]) <= 0.005
    assert s["ucs_MPa"] == pytest.approx(base["ucs_MPa"], rel=0.03)


def test_an_approach_not_faster_than_the_platens_is_the_constant_velocity_test(cache):
    """approach_velocity at or below platen_velocity (FAST's 0.1 m/s) is off: the run is
    bitwise that with approach_velocity 0."""
    a = ucs(A1, cache, settings=dataclasses.replace(FAST, approach_velocity=0.0))[0]
    b = ucs(A1, cache, settings=dataclasses.replace(FAST, approach_velocity=0.1,
                                                    approach_ramp=5.0))[0]
    for k, v in a.series.items():
        assert np.array_equal(v, b.series[k]), k
    assert b.summary["approach_strain"] == 0.0


@pytest.mark.parametrize("kw, needle", [
    (dict(approach_velocity=-0.1), "approach_velocity=-0.1"),
    (dict(approach_velocity=math.nan), "approach_velocity=nan"),
    (dict(approach_velocity=True), "approach_velocity=True"),
    (dict(approach_ramp=-1.0), "approach_ramp=-1.0"),
    (dict(approach_ramp=math.inf), "approach_ramp=inf")])
def test_approach_settings_are_checked(kw, needle):
    with pytest.raises(InputError, match=needle):
        UCSSettings(**kw)
