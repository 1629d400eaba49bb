"""Validity of tensile tests (bpmcal.lab.validity) and the Brazilian peak (PeakTracker):
planted crack sets and load sequences with a known verdict."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from bpmcal.dem.errors import InputError
from bpmcal.lab.brazilian import (
    FLATJOINT_SPLIT_DROP,
    BTSSettings,
    cap_bridges,
    split_drop,
)
from bpmcal.lab.driver import PeakTracker
from bpmcal.lab.validity import INIT_MIN, bts_validity, burst_mask, dtt_validity, per_contact

R = 0.01  # disc radius [m]
D_BALL = 0.002  # mean ball diameter [m]
STEPS = np.arange(0, 2000, 100)  # record steps; the peak at record 10 (step 1000)
PEAK = 10


def cracks(points, steps):
    """Crack events at (x, y) positions (z = 0) formed at ``steps``."""
    p = np.zeros((len(points), 3))
    p[:, :2] = np.asarray(points, float)
    return {"step": np.asarray(steps), "pos": p}


def split(first_y, n=60, rng=None):
    """A split along the loaded diameter (|x| small): its first cracks at heights
    ``first_y`` (fractions of R), then cracks all along the diameter; a few pre-peak
    cracks under the top platen (step < the peak)."""
    rng = rng or np.random.default_rng(0)
    pre = [(0.0, 0.9 * R), (0.05 * R, -0.9 * R), (0.0, 0.85 * R)]
    first = [(0.02 * R * (-1) ** i, y * R) for i, y in enumerate(first_y)]
    rest = [(rng.uniform(-0.1, 0.1) * R, rng.uniform(-0.95, 0.95) * R) for _ in range(n)]
    pts = pre + first + rest
    steps = ([200, 500, 800] + list(range(951, 951 + len(first)))
             + list(range(1100, 1100 + n)))
    return cracks(pts, steps)


def test_burst_is_the_cracks_from_the_record_before_the_peak_on():
    ev = {"step": np.array([-5, 100, 899, 900, 901, 1500])}
    b = burst_mask(ev["step"], STEPS, PEAK)  # the record before the peak: step 900
    assert b.tolist() == [False, False, False, False, True, True]


def test_a_disc_that_splits_through_the_centre_is_valid():
    v = bts_validity(split([0.05, -0.1, 0.15, 0.0, -0.2, 0.1]), STEPS, PEAK, centre=(0, 0),
                     radius=R, mean_ball_diameter=D_BALL)
    assert v["bts_valid"] and v["bts_invalid_reason"] == ""
    assert v["init_offset"] < 0.25 and v["split_band_fraction"] > 0.9


def test_a_fracture_that_starts_under_a_platen_is_invalid_with_that_reason():
    v = bts_validity(split([0.8, 0.75, 0.7, 0.85, 0.65, 0.8, 0.7]), STEPS, PEAK,
                     centre=(0, 0), radius=R, mean_ball_diameter=D_BALL)
    assert not v["bts_valid"] and v["init_side"] == "top"
    assert v["bts_invalid_reason"].startswith("fracture initiated next to the top platen")
    assert "central zone is 0.5 R" in v["bts_invalid_reason"]
    # the same split mirrored: the bottom
    ev = split([-0.8, -0.75, -0.7, -0.85, -0.65, -0.8, -0.7])
    v = bts_validity(ev, STEPS, PEAK, centre=(0, 0), radius=R, mean_ball_diameter=D_BALL,
                     contact="jaw")
    assert not v["bts_valid"] and "next to the bottom jaw" in v["bts_invalid_reason"]
    # the pre-peak cracks under the platens do not count: only the failure's
    assert bts_validity(split([0.1] * 7), STEPS, PEAK, centre=(0, 0), radius=R,
                        mean_ball_diameter=D_BALL)["bts_valid"]


def test_the_initiation_zone_is_a_setting():
    ev = split([0.4, 0.45, 0.35, 0.4, 0.42, 0.38, 0.4])
    ok = bts_validity(ev, STEPS, PEAK, centre=(0, 0), radius=R, mean_ball_diameter=D_BALL)
    strict = bts_validity(ev, STEPS, PEAK, centre=(0, 0), radius=R,
                          mean_ball_diameter=D_BALL, central_zone=0.3)
    assert ok["bts_valid"] and not strict["bts_valid"]
    # the initiation is read from max(INIT_MIN, 10 % of the burst) first cracks
    assert ok["init_cracks"] == max(INIT_MIN, math.ceil(0.1 * ok["burst_cracks"]))


def test_a_fracture_off_the_loaded_diameter_is_invalid():
    rng = np.random.default_rng(1)
    pts = [(rng.uniform(-0.9, 0.9) * R, rng.uniform(-0.3, 0.3) * R) for _ in range(60)]
    ev = cracks(pts, range(1000, 1060))
    v = bts_validity(ev, STEPS, PEAK, centre=(0, 0), radius=R, mean_ball_diameter=D_BALL)
    assert not v["bts_valid"]
    assert v["bts_invalid_reason"].startswith("the fracture did not follow the loaded diameter")


def test_no_drop_or_no_crack_is_no_split():
    ev = split([0.0] * 6)
    v = bts_validity(ev, STEPS, PEAK, centre=(0, 0), radius=R, mean_ball_diameter=D_BALL,
                     ended=False)
    assert not v["bts_valid"] and "did not split" in v["bts_invalid_reason"]
    none = cracks([(0, 0.9 * R)], [100])  # only a pre-peak crack
    v = bts_validity(none, STEPS, PEAK, centre=(0, 0), radius=R, mean_ball_diameter=D_BALL)
    assert not v["bts_valid"] and "no crack formed at the peak" in v["bts_invalid_reason"]


def test_direct_tension_failure_next_to_a_grip_is_flagged():
    faces = (0.008, 0.032)  # grip faces of a 40 mm specimen with 8 mm grips
    mid = cracks([(0.001 * i, 0) for i in range(20)], range(1000, 1020))
    mid["pos"][:, 2] = 0.02
    v = dtt_validity(mid, STEPS, PEAK, grip_faces=faces, clearance=0.002)
    assert v["dtt_valid"] and v["fracture_height"] == pytest.approx(0.5)
    near = dict(mid, pos=mid["pos"].copy())
    near["pos"][:, 2] = 0.0085  # 0.5 mm above the bottom grip's face
    v = dtt_validity(near, STEPS, PEAK, grip_faces=faces, clearance=0.002)
    assert not v["dtt_valid"] and v["dtt_invalid_reason"].startswith(
        "failure next to the bottom grip")
    assert v["fracture_grip_distance_mm"] == pytest.approx(0.5)
    v = dtt_validity(mid, STEPS, PEAK, grip_faces=faces, clearance=0.002, ended=False)
    assert not v["dtt_valid"] and "did not break" in v["dtt_invalid_reason"]


def test_an_early_seating_drop_is_not_taken_as_the_peak():
    """The issue's seed 1: a seating event at 246 N with four cracks next to the bottom
    platen dropped the load to 20 N at 0.06 % strain and ended the test. The tracker
    records it as a contact event and the split that follows sets the peak."""
    tr = PeakTracker(stop_drop=0.2, post_peak_strain=0.0003)
    seating = [(50, 1e-4), (150, 3e-4), (246, 6e-4), (20, 8e-4), (18, 1.0e-3), (16, 1.2e-3)]
    loading = [(p, 1.2e-3 + 1e-4 * i) for i, p in enumerate(range(100, 3001, 100), 1)]
    after = [(400, 5e-3), (300, 5.1e-3)]
    judged = []
    for p, e in seating + loading + after:
        if tr.add(p, e):
            seating_drop = not judged  # the first drop has no crack in the central zone
            judged.append((p, e))
            if tr.judge(split=not seating_drop):
                break
    # the seating drop (below 0.2 x 246 N, 0.0003 past it) was judged no split, the test
    # loaded on, and the drop after 3000 N ended it
    assert judged[0] == (18, 1.0e-3) and judged[-1][0] == 400
    assert tr.events == [{"record": 3, "load_N": 246.0, "strain": 6e-4, "drop_to_N": 18.0}]
    assert tr.peak == 3000 and tr.peak_strain == pytest.approx(1.2e-3 + 30e-4)
    assert tr.peak_record == len(seating) + len(loading)


def test_the_tracker_waits_for_post_peak_strain():
    tr = PeakTracker(stop_drop=0.5, post_peak_strain=1e-3)
    assert not tr.add(100.0, 1e-3)
    assert not tr.add(10.0, 1.5e-3)  # dropped, but only 0.5e-3 past the peak
    assert tr.add(10.0, 2.0e-3)


def test_a_fracture_grown_from_a_platen_before_the_peak_is_invalid():
    """The burst starts near the centre, but before it a crack grew down the loaded
    diameter from under the top platen (a stable fracture from the contact)."""
    rng = np.random.default_rng(2)
    grown = [(rng.uniform(-0.1, 0.1) * R, rng.uniform(0.5, 0.9) * R) for _ in range(30)]
    ev = split([0.05, -0.1, 0.15, 0.0, -0.2, 0.1], n=60)
    pts = np.vstack([ev["pos"][:, :2], np.asarray(grown)])
    steps = np.concatenate([ev["step"], np.arange(300, 330)])  # before the peak
    v = bts_validity(cracks(pts, steps), STEPS, PEAK, centre=(0, 0), radius=R,
                     mean_ball_diameter=D_BALL)
    assert v["init_offset"] < 0.5  # the burst alone looks central ...
    assert not v["bts_valid"] and v["pre_contact_fraction"] > 0.15
    assert v["bts_invalid_reason"].startswith("a fracture grew from the top platen before "
                                              "the peak")
    # a few cracks under each platen before the peak (diffuse contact damage) are no fracture
    few = np.vstack([ev["pos"][:, :2], np.asarray(grown[:4])])
    v = bts_validity(cracks(few, np.concatenate([ev["step"], np.arange(300, 304)])), STEPS,
                     PEAK, centre=(0, 0), radius=R, mean_ball_diameter=D_BALL)
    assert v["bts_valid"], v["bts_invalid_reason"]


def fj_events(contacts):
    """Flat-joint element breaks: ``contacts`` = [(contact, (x, y), [steps of its broken
    elements])], one event per element (as ``Model.breaks`` gives them for flat joints)."""
    rows = [(s, k, e, p) for k, p, steps in contacts for e, s in enumerate(steps)]
    rows.sort(key=lambda r: (r[0], r[1], r[2]))
    pos = np.zeros((len(rows), 3))
    pos[:, :2] = [r[3] for r in rows]
    return {"step": np.array([r[0] for r in rows]), "bond": np.array([r[1] for r in rows]),
            "element": np.array([r[2] for r in rows]), "pos": pos,
            "mode": np.ones(len(rows), np.int64)}


def test_per_contact_keeps_each_flat_joints_first_element_break():
    ev = fj_events([(7, (0.0, 0.0), [1200, 1100, 1300]), (3, (0.0, 0.5 * R), [1150])])
    pc = per_contact(ev)
    assert pc["bond"].tolist() == [7, 3] and pc["step"].tolist() == [1100, 1150]
    assert pc["element"].tolist() == [1, 0]
    pb = cracks([(0, 0), (0, 0.1 * R)], [1000, 1001])  # parallel bonds: unchanged
    assert per_contact(pb) is pb


def _split_with_a_crushed_loader():
    """A split through the centre while four contacts under the top platen lose their
    three elements each, one after another, as the split starts (and a few more below):
    counted by element, the crushed contacts outnumber the split's first contacts."""
    rng = np.random.default_rng(3)
    loader = [(100 + i, (0.03 * R * (-1) ** i, (0.85 + 0.02 * i) * R),
               [951 + 6 * i, 952 + 6 * i, 953 + 6 * i]) for i in range(4)]
    first = [(200 + i, (0.02 * R * (-1) ** i, y * R), [s])
             for i, (y, s) in enumerate(zip([0.05, -0.1, 0.15, 0.0, -0.05, 0.1],
                                            [954, 955, 956, 960, 961, 962]))]
    rest = [(300 + i, (rng.uniform(-0.1, 0.1) * R, rng.uniform(-0.9, 0.9) * R),
             [1100 + 3 * i, 1101 + 3 * i, 1102 + 3 * i]) for i in range(20)]
    return fj_events(loader + first + rest)


def test_a_flat_jointed_disc_that_splits_through_the_centre_is_valid():
    ev = _split_with_a_crushed_loader()
    v = bts_validity(ev, STEPS, PEAK, centre=(0, 0), radius=R, mean_ball_diameter=D_BALL)
    assert v["bts_valid"], v["bts_invalid_reason"]
    assert v["burst_cracks"] == 30  # contacts, not the 78 element breaks
    assert v["init_offset"] < 0.5
    # counted by element, the same disc would have "started" at the crushed loader
    el = {k: a for k, a in ev.items() if k != "element"}
    assert not bts_validity(el, STEPS, PEAK, centre=(0, 0), radius=R,
                            mean_ball_diameter=D_BALL)["bts_valid"]


def test_a_flat_jointed_disc_that_shatters_from_a_loader_is_invalid_with_the_reason():
    rng = np.random.default_rng(4)
    # the failure starts under the top jaw: its first contacts there, element by element,
    # then the disc breaks up everywhere (cracks off the loaded diameter)
    start = [(i, (0.05 * R * (-1) ** i, (0.9 - 0.03 * i) * R), [951 + 3 * i, 952 + 3 * i])
             for i in range(8)]
    shatter = [(100 + i, (rng.uniform(-0.9, 0.9) * R, rng.uniform(-0.9, 0.9) * R),
                [1100 + 3 * i, 1101 + 3 * i, 1102 + 3 * i]) for i in range(60)]
    v = bts_validity(fj_events(start + shatter), STEPS, PEAK, centre=(0, 0), radius=R,
                     mean_ball_diameter=D_BALL, contact="jaw")
    assert not v["bts_valid"] and v["burst_cracks"] == 68
    assert v["bts_invalid_reason"].startswith("fracture initiated next to the top jaw")


def _split_then_reload():
    """A flat-jointed disc's load (nominal MPa) against diametral strain (per mil): up to
    the split at 8.2, a 7 % dip, then its halves load up to 9.5 (f08_s2 of
    docs/measurements/2026-12-02b-flatjoint-brazilian-split.md, rounded)."""
    up = [(0.4 * k, 0.1 * k) for k in range(1, 21)]  # 0.4 ... 8.0 at 2.0 per mil
    return up + [(8.2, 2.03), (7.6, 2.1), (7.6, 2.2), (7.7, 2.35), (7.9, 2.4), (8.5, 2.8), (9.1, 3.0),
                 (9.5, 3.3), (8.9, 3.4), (8.3, 3.8), (4.6, 6.0)]


def _first_stop(drop):
    tr = PeakTracker(stop_drop=drop, post_peak_strain=3e-4 * 1e3)  # strain in per mil
    for p, e in _split_then_reload():
        if tr.add(p, e) and tr.judge(split=True):
            return tr.peak
    return tr.peak


def test_a_flat_jointed_split_is_its_first_drop_not_the_halves_reloading():
    """The split of a flat-jointed disc drops the load by 5-15 %, not by half: with the
    flat joint's split_drop (0.95) the tracker stops at the split's 8.2; with the
    parallel bond's 0.5 it loads on to the halves' crushing at 9.5."""
    assert _first_stop(FLATJOINT_SPLIT_DROP) == 8.2
    assert _first_stop(0.5) == 9.5


def test_the_split_drop_and_the_caps_follow_the_contact_model():
    def disc(model):
        return SimpleNamespace(model=SimpleNamespace(material=SimpleNamespace(
            contact_model=model)))
    st = BTSSettings()
    assert split_drop(disc("linearpbond"), st) == st.stop_drop == 0.5
    assert split_drop(disc("flatjoint"), st) == FLATJOINT_SPLIT_DROP == 0.95
    assert split_drop(disc("flatjoint"), BTSSettings(split_drop=0.8)) == 0.8
    assert cap_bridges(disc("linearpbond"), None) and not cap_bridges(disc("flatjoint"), None)
    assert cap_bridges(disc("flatjoint"), True)
    with pytest.raises(InputError, match="split_drop=1.5"):
        BTSSettings(split_drop=1.5)
