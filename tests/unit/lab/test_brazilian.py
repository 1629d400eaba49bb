"""Brazilian test: scaling law, loading rate, platen balance, sigma_t against sigma_c, the
split along the loaded diameter, validity (a planted weak zone under a platen), contact caps,
curved jaws, the run file and the command line."""
import json
import math
import time
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest
from support.lab_util import A1, FAST, SMALL
from support.repo import REPO

from bpmcal.cli import main
from bpmcal.dem.errors import InputError
from bpmcal.io import h5
from bpmcal.io.vtk import export_run
from bpmcal.lab.brazilian import (
    BTSSettings,
    analyse,
    cap_bridges,
    contact_cap_bonds,
    run_bts,
    tensile_strength,
)
from bpmcal.lab.runner import bts_geometry, make_specimen
from bpmcal.lab.ucs import run_ucs

#: a small ISRM disc: 20 x 10 mm (~390 balls, 9.4 balls across with Rmin 0.8 mm)
DISC = bts_geometry(scale=0.4)
SEED = 2
DEFAULT = BTSSettings()  # the default study's Brazilian loading (config/config.yaml bts)
#: a careful quasi-static loading (the defaults until the study's were made the library's):
#: a slow platen from the start, stopped well past the split
CAREFUL = dict(platen_velocity=0.00625, approach_velocity=0.0, stop_drop=0.7,
               post_peak_strain=0.002)


def scaled(p, k):
    return dict(p, pb_emod_GPa=p["pb_emod_GPa"] * k, pb_ten_MPa=p["pb_ten_MPa"] * k,
                pb_coh_MPa=p["pb_coh_MPa"] * k)


def bts(params, cache, seed=SEED, **kw):
    sp = make_specimen(params, seed, DISC, cache=cache, boundary="free")
    return run_bts(sp, BTSSettings(**kw)), sp


@pytest.fixture(scope="module")
def base(cache, tmp_path_factory):
    """The A1 disc at the default settings (the study's loading), through the command line
    (one HDF5 file): a run of seconds, so the tests that read it are in the slow tier (CI
    runs them; the fast tier keeps the Brazilian tests of tests/cli and the cheap ones
    below)."""
    d = tmp_path_factory.mktemp("bts")
    pf = d / "a1.yaml"
    pf.write_text("\n".join(f"{k}: {v}" for k, v in A1.items()))
    f = d / "a1.h5"
    assert main(["bts", "--params", str(pf), "--out", str(f), "--scale", str(DISC.scale),
                 "--seed", str(SEED), "--specimen-cache", str(cache), "--quiet"]) == 0
    ser = h5.read_series(f)
    return SimpleNamespace(summary=h5.read_summary(f), path=f,
                           series={k: ser[k].to_numpy() for k in ser})


@pytest.mark.slow
def test_disc_geometry_is_the_isrm_disc_scaled_like_the_cylinder(base):
    inp = h5.read_inputs(base.path)
    assert inp["diameter_mm"] == pytest.approx(50 * 0.4)
    assert inp["thickness_mm"] == pytest.approx(25 * 0.4) == inp["height_mm"]
    s = base.summary
    assert s["test"] == "bts" and s["status"] == "ok"
    assert s["diameter_mm"] == pytest.approx(20.0) and s["thickness_mm"] == pytest.approx(10.0)
    assert s["platen_velocity"] == DEFAULT.platen_velocity
    # the resolution of the measurement: the diameter in mean ball diameters
    ini = h5.read_particles(base.path, "initial")
    dbar = 2 * ini["radius"].mean()
    assert s["balls_across"] == pytest.approx(20e-3 / dbar, rel=1e-9)
    assert 9 < s["balls_across"] < 10


@pytest.mark.slow
def test_sigma_t_is_2P_over_pi_D_t_of_the_peak_mean_platen_load(base):
    s, ser = base.summary, base.series
    P = 0.5 * (ser["load_bottom"] + ser["load_top"])
    assert np.allclose(ser["load"], P)
    ip = int(np.argmax(P))
    assert s["contact_events"] == 0  # no seating event: the peak is the largest load
    assert int(ser["step"][ip]) == s["peak_step"]
    D, t = 20e-3, 10e-3
    assert s["bts_valid"] and s["bts_invalid_reason"] == ""
    assert s["bts_MPa"] == s["bts_peak_MPa"]
    assert s["bts_MPa"] == pytest.approx(2 * P[ip] / (math.pi * D * t) / 1e6, rel=1e-12)
    assert s["stop_reason"] == "post_peak_drop"
    # the split: the load collapses after the peak
    assert ser["load"][-1] < DEFAULT.stop_drop * P[ip]


@pytest.fixture(scope="module")
def careful(cache):
    """The A1 disc of ``base`` under the CAREFUL loading."""
    return bts(A1, cache, **CAREFUL)[0]


def _mismatch(ser, first: int = 0):
    """The two platens' relative load difference from record ``first`` to the peak, where
    the load is established (above a fifth of the peak)."""
    ip = int(np.argmax(ser["load"]))
    up = slice(first, ip + 1)
    loaded = ser["load"][up] > 0.2 * ser["load"][ip]
    return np.abs(ser["load_bottom"][up] - ser["load_top"][up])[loaded] / ser["load"][up][loaded]


@pytest.mark.slow
def test_the_two_platen_forces_agree(base, careful):
    """Quasi-static loading: the two platens carry the same load (no net force on the
    disc) at the peak and along the pre-peak curve once the load is established; only
    the stress waves of single bond breaks near one platen separate them for a moment.
    So under the careful loading from the start, and under the default (the study's) from
    where its platens slow from the fast approach (``approach_strain``) to the peak. The
    study's approach lasts until a few per mille of the bonds have broken, which on A1 is
    a few records before the peak (at 99.98 % of its load): during it the platens differ
    by up to about 5 % (the dynamic approach the loading-protocol record paid for its
    steps with; sigma_t on the same discs moved by a median 0.01 %), so the pre-peak
    balance is the careful loading's, and the study's is held at and just before the
    peak."""
    for s in (base.summary, careful.summary):
        assert s["platen_mismatch"] < 0.005
    switch = int(np.flatnonzero(base.series["diametral_strain"]
                                == base.summary["approach_strain"])[0])
    for ser, first in ((careful.series, 0), (base.series, switch)):
        rel = _mismatch(ser, first)
        assert rel.size > (100 if first == 0 else 2)
        assert rel.mean() < 0.005 and np.percentile(rel, 95) < 0.01, (rel.mean(), rel.max())


@pytest.mark.slow
def test_the_disc_splits_along_the_loaded_diameter(base):
    """The cracks of a Brazilian test line up with the loading axis (y): most lie in the
    strip |x| < D/6 around the loaded diameter."""
    cr = h5.read_cracks(base.path)
    ini = h5.read_particles(base.path, "initial")
    xc = ini["position"][:, 0].mean()
    assert len(cr) >= 20
    assert np.mean(np.abs(cr["x"] - xc) < 20e-3 / 6) > 0.6


@pytest.mark.slow
def test_sigma_t_is_positive_and_below_sigma_c_for_the_a1_set(base, cache):
    u = run_ucs(make_specimen(A1, SEED, SMALL, cache=cache), FAST).summary
    st = base.summary["bts_MPa"]
    assert 0 < st < u["ucs_MPa"]
    # the parallel-bond model's known weakness (Potyondy & Cundall 2004): sigma_c/sigma_t
    # far below the 10-20 of rocks
    assert 2 < u["ucs_MPa"] / st < 15


@pytest.mark.slow
def test_scaling_moduli_and_strengths_by_1_5_scales_sigma_t_by_1_5(base, cache):
    """The scaling law on the median of three packings (seeds 1-3): a ~200-ball disc can
    take one of two failure paths when its loading changes slightly in time units (a
    stiffer disc has a shorter timestep), and one disc then moves by several % (seed 2
    under the pfc genesis: x 1.567; seeds 1, 3, 4, 5: x 1.4988-1.5005)."""
    sig, eps = [], []
    for seed in (1, 2, 3):
        if seed == SEED:
            r0 = SimpleNamespace(summary=base.summary)
        else:
            r0, _ = bts(A1, cache, seed=seed)
        r, _ = bts(scaled(A1, 1.5), cache, seed=seed)
        # the mechanics scale whether or not the run is a valid test: the peak stress
        sig.append(r.summary["bts_peak_MPa"] / r0.summary["bts_peak_MPa"])
        eps.append(r.summary["peak_strain"] / r0.summary["peak_strain"])
    assert float(np.median(sig)) == pytest.approx(1.5, rel=0.03), sig
    # strains do not change: the same diametral strain at the peak
    assert float(np.median(eps)) == pytest.approx(1.0, rel=0.03), eps


@pytest.mark.slow
def test_halving_the_default_platen_speed_changes_sigma_t_by_less_than_2_percent(base, cache):
    r, _ = bts(A1, cache, platen_velocity=0.5 * DEFAULT.platen_velocity)
    assert r.summary["bts_MPa"] == pytest.approx(base.summary["bts_MPa"], rel=0.02)


@pytest.mark.slow
def test_the_study_settings_give_the_sigma_t_of_a_careful_loading(base, careful):
    """The default Brazilian test, which is the study's (config/config.yaml ``bts``: a fast
    approach until the first crack, a faster platen, a stop once the disc has split),
    against the CAREFUL loading on the A1 disc: the same sigma_t within 2 %, in fewer
    steps; the platens switch to the loading speed at the first crack."""
    import yaml

    b = yaml.safe_load((REPO / "config" / "config.yaml").read_text())["bts"]
    keys = ("platen_velocity", "approach_velocity", "post_peak_strain", "stop_drop", "loading",
            "contact_cap")
    assert {k: getattr(DEFAULT, k) for k in keys} == {k: b[k] for k in keys}
    s = base.summary
    assert s["bts_valid"] and careful.summary["bts_valid"]
    assert s["bts_MPa"] == pytest.approx(careful.summary["bts_MPa"], rel=0.02)
    assert s["steps"] < 0.7 * careful.summary["steps"]
    ser = base.series
    cracks = ser["cracks_tension"] + ser["cracks_shear"]
    # the switch: the record where the approach's share of the bonds had broken (its count
    # checked in test_the_approach_ends_once_its_share_of_the_bonds_has_broken)
    k = int(np.flatnonzero(ser["diametral_strain"] == s["approach_strain"])[0])
    assert s["approach_strain"] > 0 and cracks[k] >= 1 and cracks[k - 1] < cracks[k]
    dstep = np.diff(ser["step"])
    fast, slow = dstep[: k - 1], dstep[k + 1:]
    ratio = b["approach_velocity"] / b["platen_velocity"]
    assert (fast == fast[0]).all() and (slow == slow[0]).all()
    assert slow[0] / fast[0] == pytest.approx(ratio, rel=0.05)


@pytest.mark.slow
def test_the_approach_ends_once_its_share_of_the_bonds_has_broken(cache):
    """approach_damage f: the platens close fast until ceil(f x the disc's bonds) cracks
    (at least one), then at the platen velocity; f = 0 is the first crack."""
    from bpmcal.lab.brazilian import approach_cracks

    sp = make_specimen(A1, SEED, DISC, cache=cache, boundary="free")
    n = sp.model.bond_pairs()[0].size
    assert approach_cracks(sp.model, 0.0) == 1 and approach_cracks(sp.model, 1e-9) == 1
    assert approach_cracks(sp.model, 0.01) == math.ceil(0.01 * n) > 5
    res = run_bts(sp, BTSSettings(approach_damage=0.01))
    s, ser = res.summary, res.series
    cracks = ser["cracks_tension"] + ser["cracks_shear"]
    k = int(np.argmax(cracks >= math.ceil(0.01 * n)))  # the switch's record
    assert 0 < k and s["approach_strain"] == ser["diametral_strain"][k] > 0
    assert cracks[k - 1] < math.ceil(0.01 * n) and cracks[k - 1] > 1  # past the first crack
    dstep = np.diff(ser["step"])
    ratio = DEFAULT.approach_velocity / DEFAULT.platen_velocity
    assert dstep[-1] / dstep[0] == pytest.approx(ratio, rel=0.05)


def test_analyse_against_a_closed_form_load_curve():
    """A parabolic load-displacement curve with a known peak and platen loads that differ
    by a known 1 %: sigma_t = 2 P / (pi D t), the peak position and the mismatch."""
    D, t, Pp, dp = 0.05, 0.025, 20e3, 2e-4
    d = np.linspace(0, 1.5 * dp, 301)
    P = np.where(d <= dp, Pp * (1 - (1 - d / dp) ** 2), Pp * (1 - 2 * (d / dp - 1)))
    ser = {"load": P, "load_bottom": 1.005 * P, "load_top": 0.995 * P, "displacement": d,
           "diametral_strain": d / D, "cracks_tension": np.arange(d.size),
           "cracks_shear": np.zeros(d.size, int)}
    r = analyse(ser, D, t)
    assert r["bts_peak_MPa"] == pytest.approx(2 * Pp / (math.pi * D * t) / 1e6, rel=1e-12)
    assert r["peak_displacement_mm"] == pytest.approx(dp * 1e3, rel=1e-9)
    assert r["platen_mismatch"] == pytest.approx(0.01, rel=1e-9)
    assert float(tensile_strength(1.0, 2.0, 1.0 / math.pi)) == pytest.approx(1.0)


@pytest.mark.slow
def test_summary_json_and_vtk_of_a_run_file(base, tmp_path, capsys):
    assert main(["summary", str(base.path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["bts_MPa"] == pytest.approx(base.summary["bts_MPa"]) and d["bts_MPa"] > 0
    files = {f.name for f in export_run(base.path, tmp_path / "vtk")}
    assert {"particles_initial.vtp", "particles_final.vtp", "cracks.vtp", "run.pvd"} <= files
    root = ET.parse(tmp_path / "vtk" / "cracks.vtp").getroot().find("PolyData/Piece")
    assert int(root.get("NumberOfPoints")) == d["cracks_tension"] + d["cracks_shear"]


def test_settings_refuse_bad_values():
    for kw, needle in [(dict(platen_velocity=-1.0), "platen_velocity=-1.0"),
                       (dict(platen_fric=float("nan")), "platen_fric=nan"),
                       (dict(stop_drop=1.5), "stop_drop=1.5"),
                       (dict(seat_stress=0.0), "seat_stress=0.0"),
                       (dict(approach_velocity=-1.0), "approach_velocity=-1.0"),
                       (dict(approach_damage=1.0), "approach_damage=1.0"),
                       (dict(approach_damage=float("nan")), "approach_damage=nan"),
                       (dict(loading="curved"), "loading='curved'"),
                       (dict(jaw_ratio=0.8), "jaw_ratio=0.8: expected a jaw radius larger"),
                       (dict(contact_cap=-1.0), "contact_cap=-1.0"),
                       (dict(contact_cap_bridge="yes"), "contact_cap_bridge=.yes."),
                       (dict(central_zone=0.0), "central_zone=0.0"),
                       (dict(retests=-1), "retests=-1"), (dict(retests=1.5), "retests=1.5"),
                       (dict(retests=11), "retests=11")]:
        with pytest.raises(InputError, match=needle):
            BTSSettings(**kw)


@pytest.mark.parametrize("args, needle", [
    (["--platen-velocity", "abc"], "platen-velocity"),
    (["--platen-fric", "-1"], "platen-fric='-1'"),
    (["--set", "pb_ten_MPa=abc"], "pb_ten_MPa"),
    (["--set", "porosity=0.95"], "porosity=0.95"),
    (["--diameter", "-5"], "diameter='-5'"),
    (["--jaw-ratio", "0.8"], "jaw-ratio='0.8'"),
    (["--loading", "curved"], "loading='curved': expected one of flat, jaws"),
])
def test_cli_rejects_bad_input_and_writes_no_file(tmp_path, capsys, args, needle):
    pf = tmp_path / "p.yaml"
    pf.write_text("\n".join(f"{k}: {v}" for k, v in A1.items()))
    out = tmp_path / "o.h5"
    t0 = time.perf_counter()
    try:
        rc = main(["bts", "--params", str(pf), "--out", str(out), *args])
    except SystemExit as e:  # argparse's own type errors (usage line + error line)
        rc = e.code
    assert rc == 2 and time.perf_counter() - t0 < 5
    assert needle in capsys.readouterr().err
    assert not out.exists()


def test_cli_defaults_are_the_settings_defaults():
    """One source of truth: the command line's defaults are the dataclasses' defaults."""
    from bpmcal.cli import build_parser
    from bpmcal.lab.triaxial import TriaxialSettings

    ap = build_parser()
    sub = ap._subparsers._group_actions[0].choices
    b = {a.dest: a.default for a in sub["bts"]._actions}
    for k in ("platen_velocity", "platen_fric", "damping", "stop_drop", "max_strain",
              "record_strain", "loading", "jaw_ratio", "contact_cap", "contact_cap_factor",
              "central_zone"):
        assert b[k] == getattr(DEFAULT, k), k
    t = {a.dest: a.default for a in sub["triaxial"]._actions}
    tx = TriaxialSettings()
    assert t["servo_alpha"] == tx.servo_alpha and t["servo_interval"] == tx.servo_interval
    for k in ("platen_velocity", "damping", "stop_drop", "max_strain", "platen_fric",
              "record_strain"):
        assert t[k] == getattr(tx, k), k


@pytest.mark.slow
def test_a_weak_zone_under_a_platen_makes_the_run_invalid(base, cache):
    """Bonds at 0.45-0.7 R above the centre along the loaded diameter (below the top
    platen's contact cap) at a fifth of their strength: the fracture starts there, and the
    run is recorded as invalid with that reason - no sigma_t. (The same disc without the
    weak zone is valid: ``base``.)"""
    sp = make_specimen(A1, SEED, DISC, cache=cache, boundary="free")
    m = sp.model
    bi, bj = m.bond_pairs()
    mid = 0.5 * (m.positions[bi] + m.positions[bj])
    c = m.positions[:, :2].mean(axis=0)
    R = 0.5 * sp.spec.diameter
    weak = (np.abs(mid[:, 0] - c[0]) < 0.3 * R) & (mid[:, 1] - c[1] > 0.45 * R) & (
        mid[:, 1] - c[1] < 0.7 * R)
    assert weak.sum() >= 10
    f = m.bond_strength_factors
    f[weak] *= 0.2
    m.set_bond_strength_factors(f)
    s = run_bts(sp, DEFAULT).summary
    assert s["stop_reason"] == "post_peak_drop"
    assert not s["bts_valid"] and math.isnan(s["bts_MPa"])
    # the crack grew down the diameter from the weak zone before the peak (its burst, the
    # unstable rest of the split, starts nearer the centre)
    assert s["bts_invalid_reason"].startswith("a fracture grew from the top platen before "
                                              "the peak"), s["bts_invalid_reason"]
    assert s["pre_contact_fraction"] > 0.15
    assert s["bts_peak_MPa"] < base.summary["bts_MPa"]  # the weak zone failed first


@pytest.mark.slow
def test_contact_caps_change_strength_not_stiffness(cache):
    """The caps' bonds cannot break (strength x 1000), but until the first crack the
    capped and the uncapped disc are the same elastic body: the same loads, step by step."""
    runs = {}
    for cap in (0.0, 1.5):
        sp = make_specimen(A1, SEED, DISC, cache=cache, boundary="free")
        runs[cap] = run_bts(sp, BTSSettings(contact_cap=cap, platen_velocity=0.025,
                                            approach_velocity=0.05, stop_drop=0.5,
                                            post_peak_strain=3e-4))
    a, b = runs[0.0], runs[1.5]
    assert a.summary["contact_cap_bonds"] == 0 < b.summary["contact_cap_bonds"]
    assert b.summary["contact_cap_broken"] == 0
    ca = a.series["cracks_tension"] + a.series["cracks_shear"]
    cb = b.series["cracks_tension"] + b.series["cracks_shear"]
    k = min(int(np.argmax(ca > 0)), int(np.argmax(cb > 0)))
    assert k > 10
    np.testing.assert_array_equal(a.series["load"][:k], b.series["load"][:k])


@pytest.mark.slow
def test_curved_jaws_touch_the_disc_without_overlap_and_split_it(cache):
    from bpmcal.lab.brazilian import add_jaws

    sp = make_specimen(A1, SEED, DISC, cache=cache, boundary="free")
    m = sp.model
    wb, wt = add_jaws(sp, ratio=1.5)
    rj = 1.5 * 0.5 * sp.spec.diameter
    for w, sign in ((wb, -1), (wt, 1)):
        assert m.wall_radius(w) == pytest.approx(rj)
        c = m.wall_position(w)
        dist = np.hypot(m.positions[:, 0] - c[0], m.positions[:, 1] - c[1]) + m.radii
        assert dist.max() <= rj and dist.max() == pytest.approx(rj, abs=1e-9)
        assert sign * (c[1] - m.positions[:, 1].mean()) < 0  # the axis on the far side
    sp = make_specimen(A1, SEED, DISC, cache=cache, boundary="free")
    s = run_bts(sp, BTSSettings(loading="jaws", platen_velocity=0.025,
                                approach_velocity=0.05, stop_drop=0.5,
                                post_peak_strain=3e-4)).summary
    assert s["loading"] == "jaws"
    assert s["stop_reason"] == "post_peak_drop" and s["bts_peak_MPa"] > 0
    assert 0 < s["arc_deg_peak"] < 30  # the jaw bears on an arc around the loaded diameter


@pytest.mark.slow
def test_the_run_of_a_valid_first_disc_records_one_disc(base):
    s = base.summary
    assert s["bts_valid"] and s["discs"] == 1 and s["disc_seed"] == SEED
    assert s["discarded"] == ""


def _fake_disc(valid_from: int, seed0: int):
    """A stand-in for one disc's test (``runner._lab_test``): discs packed with the seeds
    of retests below ``valid_from`` are invalid, the others valid."""
    from bpmcal.lab.runner import LabRun
    from bpmcal.lab.seeds import retest_seed

    seeds = [retest_seed(seed0, k) for k in range(11)]

    def fake(test, params, seed, geometry, inputs, boundary, run, how):
        k = seeds.index(seed)
        ok = k >= valid_from
        summ = {"bts_valid": ok, "bts_MPa": 7.0 + k if ok else math.nan,
                "bts_peak_MPa": 7.0 + k, "wall_s": 1.5,
                "bts_invalid_reason": "" if ok else f"planted: disc {k}"}
        return LabRun(test=test, inputs=inputs, summary=summ, genesis={}, series={},
                      cracks={})
    return fake


@pytest.mark.parametrize("valid_from, retests, discs, valid", [
    (0, 2, 1, True), (1, 2, 2, True), (2, 2, 3, True), (3, 2, 3, False), (1, 0, 1, False)])
def test_an_invalid_disc_is_discarded_and_another_tested(monkeypatch, valid_from, retests,
                                                         discs, valid):
    """ISRM practice: an invalid disc gives no sigma_t and another disc of the card is
    tested (packed with the next retest seed), up to ``retests`` more; the first valid one
    is the test, and the run names every discarded disc and its reason."""
    from bpmcal.lab import runner
    from bpmcal.lab.seeds import retest_seed

    monkeypatch.setattr(runner, "_lab_test", _fake_disc(valid_from, SEED))
    notes = []
    r = runner.bts_test(A1, SEED, DISC, BTSSettings(retests=retests),
                        progress=lambda d: notes.append(d.get("note")))
    s = r.summary
    assert s["discs"] == discs and s["bts_valid"] is valid
    assert s["disc_seed"] == retest_seed(SEED, discs - 1)
    assert s["wall_s"] == pytest.approx(1.5 * discs)  # the time of every disc tested
    gone = [x for x in s["discarded"].split("; ") if x]
    assert gone == [f"seed {retest_seed(SEED, k)}: planted: disc {k}" for k in range(discs - 1)]
    assert len([n for n in notes if n]) == discs - 1
    assert r.inputs["seed"] == SEED and r.inputs["bts_retests"] == retests
    if valid:
        assert s["bts_MPa"] == 7.0 + discs - 1


def test_retest_seeds_are_deterministic_distinct_and_in_range():
    from bpmcal.lab.seeds import retest_seed

    assert retest_seed(5, 0) == 5
    seeds = [retest_seed(2 ** 32 - 3, k) for k in range(4)]
    assert len(set(seeds)) == 4 and all(0 <= x < 2 ** 32 for x in seeds)


def test_caps_that_do_not_bridge_leave_the_split_free(cache):
    """``contact_cap_bridge`` False caps the same zones less the bonds whose balls lie on
    opposite sides of the loaded diameter, which would staple the two halves together
    (issue 56: a flat-jointed disc's peak fell from 19.8 to 9.0 MPa without them,
    docs/measurements/2026-12-02b-flatjoint-brazilian-split.md); by default the caps bridge
    for parallel bonds (the study's measured practice) and not for flat joints."""
    sp = make_specimen(A1, SEED, DISC, cache=cache, boundary="free")
    m = sp.model
    bi, bj = m.bond_pairs()
    x = m.positions[:, 0] - m.positions[:, 0].mean()
    every = contact_cap_bonds(sp, 1.5)
    split = contact_cap_bonds(sp, 1.5, bridge=False)
    across = every[x[bi[every]] * x[bj[every]] < 0]
    assert across.size > 0 and set(split) == set(every) - set(across)
    assert not np.any(x[bi[split]] * x[bj[split]] < 0)
    assert cap_bridges(sp, None) and not cap_bridges(sp, False)


# --------------------------------------------------- the fewest balls across (issue 56 item 2)
LDB_FJ = {"contact_model": "flatjoint", "rmin_mm": 0.8, "porosity": 0.3,
          "fj_emod_GPa": 86.72, "fj_kratio": 1.7, "fj_ten_MPa": 11.63, "fj_coh_MPa": 115.0,
          "fj_fa_deg": 30.0, "fj_fric": 0.6}


def test_a_flat_jointed_disc_is_enlarged_to_its_fewest_balls_across_a_bonded_one_is_not():
    """``resolved_disc``: a flat-jointed card's 27.5 mm disc (12.9 mean ball diameters
    across at Rmin 0.8 mm, the diameter Rmin (1 + 1.66)) becomes a disc of exactly 25
    across, its thickness with it (the scale); a parallel-bonded card's stays as sized; a
    disc already fine enough, and min_balls_across 0, stay the same object."""
    from bpmcal.lab.brazilian import FLATJOINT_MIN_ACROSS, min_across, resolved_disc
    from bpmcal.params import validate_params

    disc = bts_geometry(scale=0.55)
    fj, pb = validate_params(LDB_FJ), validate_params(A1)
    dbar = 0.8 * 2.66
    big = resolved_disc(disc, fj, DEFAULT)
    assert min_across("flatjoint", DEFAULT) == FLATJOINT_MIN_ACROSS == 25.0
    assert big.scale * big.diameter_mm == pytest.approx(25.0 * dbar, rel=1e-12)
    assert big.scale * big.height_mm == pytest.approx(12.5 * dbar, rel=1e-12)  # t = D / 2
    assert (big.diameter_mm, big.height_mm, big.genesis) == (disc.diameter_mm,
                                                               disc.height_mm, disc.genesis)
    assert resolved_disc(disc, pb, DEFAULT) is disc
    assert resolved_disc(big, fj, DEFAULT) is big  # already 25 across
    assert resolved_disc(disc, fj, BTSSettings(min_balls_across=0.0)) is disc
    # an explicit count applies to either model
    pb_big = resolved_disc(disc, pb, BTSSettings(min_balls_across=20.0))
    assert pb_big.scale * pb_big.diameter_mm == pytest.approx(20.0 * dbar, rel=1e-12)
    wide = bts_geometry(scale=1.2)  # 60 mm: 28.2 across, kept
    assert resolved_disc(wide, fj, DEFAULT) is wide


@pytest.mark.parametrize("bad", [-1.0, 61.0, math.nan, True, "19"])
def test_a_bad_fewest_balls_across_is_refused(bad):
    with pytest.raises(InputError, match="min_balls_across"):
        BTSSettings(min_balls_across=bad)


def test_the_enlarged_disc_is_the_one_tested_and_recorded(cache):
    """Through ``runner.bts_test``: A1 on a 17.5 mm disc (8.2 across) with min_balls_across
    11 is tested on a disc of 11 across (the packing's own mean diameter within 3 % of the
    nominal), and its inputs say it was enlarged from the scale asked for."""
    from bpmcal.lab.runner import bts_test

    st = BTSSettings(min_balls_across=11.0, retests=0, max_strain=0.004)
    run = bts_test(A1, SEED, bts_geometry(scale=0.35), st, cache=cache, threads=1,
                   keep_particles=False)
    s = run.summary
    assert s["diameter_mm"] == pytest.approx(11.0 * 0.8 * 2.66, rel=1e-9)
    assert s["balls_across"] == pytest.approx(11.0, rel=0.03)
    assert run.inputs["disc_enlarged"] is True and run.inputs["disc_scale_requested"] == 0.35
    asis = bts_test(A1, SEED, bts_geometry(scale=0.35), BTSSettings(retests=0,
                    max_strain=0.004), cache=cache, threads=1, keep_particles=False)
    assert asis.inputs["disc_enlarged"] is False
    assert asis.summary["diameter_mm"] == pytest.approx(17.5, rel=1e-9)
