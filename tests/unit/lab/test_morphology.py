"""Failure morphology (lab.morphology) on planted crack clouds."""
import math

import numpy as np
import pytest

from bpmcal.lab.morphology import (
    Frame,
    crack_heights,
    fit_plane,
    fragment_stats,
    height_distribution,
    plane_geometry,
    run_summary,
)

D, H = 0.05, 0.10  # the paper's cylinder [m]


def planted_band(n, dip_deg, h_axis, rng, sigma=0.6e-3, azimuth_deg=30.0):
    """n cracks on a plane of the given dip (from the horizontal), crossing the cylinder's
    axis at height h_axis * H, with normal scatter ``sigma`` across it, inside the
    cylinder D x H."""
    d, a = math.radians(dip_deg), math.radians(azimuth_deg)
    nrm = np.array([math.sin(d) * math.cos(a), math.sin(d) * math.sin(a), math.cos(d)])
    e1 = np.cross(nrm, [0.0, 0.0, 1.0]) if dip_deg > 1e-9 else np.array([1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(nrm, e1)
    c = np.array([0.0, 0.0, h_axis * H])
    out = []
    while sum(len(o) for o in out) < n:
        s, t = rng.uniform(-H, H, (2, 4 * n))
        p = c + s[:, None] * e1 + t[:, None] * e2 + rng.normal(0, sigma, 4 * n)[:, None] * nrm
        inside = (np.hypot(p[:, 0], p[:, 1]) < D / 2) & (p[:, 2] > 0) & (p[:, 2] < H)
        out.append(p[inside])
    return np.concatenate(out)[:n]


def background(n, rng):
    rho = D / 2 * np.sqrt(rng.uniform(0, 1, n))
    phi = rng.uniform(0, 2 * np.pi, n)
    return np.column_stack([rho * np.cos(phi), rho * np.sin(phi), rng.uniform(0, H, n)])


@pytest.mark.parametrize("dip, h_axis", [(60.0, 0.5), (70.0, 0.35), (30.0, 0.7), (85.0, 0.5)])
def test_planted_plane_is_recovered_among_background_cracks(dip, h_axis):
    rng = np.random.default_rng(int(dip))
    band = planted_band(1400, dip, h_axis, rng)
    pts = np.concatenate([band, background(600, rng)])  # 30 % diffuse cracks
    fit = fit_plane(pts, 2e-3, seed=1)
    g = plane_geometry(fit["normal"], fit["centre"], 2, 0.0, H, (0.0, 0.0, H / 2))
    assert g["plane_dip_deg"] == pytest.approx(dip, abs=1.5)
    assert g["plane_angle_to_axis_deg"] == pytest.approx(90 - dip, abs=1.5)
    assert g["plane_axis_height"] == pytest.approx(h_axis, abs=0.02)
    # the inliers are the band (all of it within 3 sigma) plus the background they cross
    assert 0.68 <= fit["fraction"] <= 0.85
    assert fit["inliers"][:1400].mean() > 0.99
    assert fit["rms"] < 1.2e-3


def test_plane_fit_is_deterministic_and_sign_fixed():
    rng = np.random.default_rng(5)
    pts = np.concatenate([planted_band(500, 60.0, 0.5, rng), background(200, rng)])
    a, b = fit_plane(pts, 2e-3, seed=3), fit_plane(pts, 2e-3, seed=3)
    assert np.array_equal(a["normal"], b["normal"]) and np.array_equal(a["inliers"], b["inliers"])
    assert a["normal"][2] >= 0
    c = fit_plane(-pts, 2e-3, seed=3)  # a mirrored cloud gives the same plane through 0
    assert np.allclose(c["normal"][2], a["normal"][2], atol=1e-9)


def test_plane_geometry_of_known_planes():
    o = (0.0, 0.0, H / 2)
    horiz = plane_geometry((0, 0, 1), (0.01, 0.0, 0.09), 2, 0.0, H, o)
    assert horiz["plane_dip_deg"] == pytest.approx(0.0) and horiz["plane_axis_height"] == pytest.approx(0.9)
    assert horiz["plane_offset"] == pytest.approx(0.4)
    vert = plane_geometry((1, 0, 0), (0.005, 0.0, 0.03), 2, 0.0, H, o)
    assert vert["plane_dip_deg"] == pytest.approx(90.0) and math.isnan(vert["plane_axis_height"])
    assert vert["plane_offset"] == pytest.approx(0.05)
    s = math.sqrt(0.5)  # 45 degrees through (0, 0, 0.03): crosses the axis at h 0.3
    d45 = plane_geometry((s, 0, s), (0.01, 0.0, 0.02), 2, 0.0, H, o)
    assert d45["plane_dip_deg"] == pytest.approx(45.0) and d45["plane_axis_height"] == pytest.approx(0.3)


def test_height_distribution_thirds_and_location():
    h = crack_heights(np.array([0.001, 0.01, 0.02, 0.03, 0.05, 0.09]), 0.0, H)
    d = height_distribution(h)
    assert d["height_median"] == pytest.approx(0.25)
    assert d["height_bottom_third"] == pytest.approx(4 / 6)
    assert d["height_top_third"] == pytest.approx(1 / 6)
    assert d["height_middle_third"] == pytest.approx(1 / 6)
    assert d["location"] == "bottom"
    assert height_distribution([0.45, 0.5, 0.55])["location"] == "middle"
    assert height_distribution([0.7, 0.9])["location"] == "top"
    assert height_distribution([])["location"] == "none"
    with pytest.raises(ValueError):
        crack_heights([0.0], 0.0, 0.0)


def test_fragments_of_planted_clusters():
    # balls 0-3 bonded in a chain, 4-5 bonded, 6 alone, 7-8 joined by a broken bond
    bi = np.array([0, 1, 2, 4, 7])
    bj = np.array([1, 2, 3, 5, 8])
    state = np.array([0, 0, 0, 0, 1])
    r = np.ones(9)
    f = fragment_stats(9, bi, bj, state == 0, r, min_fraction=0.2)
    assert f["fragments"] == 2  # 4/9 and 2/9 of the volume; the singles are 1/9 each
    assert f["largest_fragment"] == pytest.approx(4 / 9)
    assert f["detached_balls"] == 3


def test_run_summary_uses_post_peak_cracks_for_the_plane():
    rng = np.random.default_rng(2)
    pre = background(400, rng)  # diffuse damage before the peak
    post = planted_band(600, 65.0, 0.4, rng)  # the band after it
    pos = np.concatenate([pre, post])
    step = np.concatenate([rng.integers(0, 1000, 400), rng.integers(1000, 2000, 600)])
    frame = Frame(axis=2, low=0.0, length=H, centre_point=(0, 0, H / 2), width=D,
                  half_thickness=2e-3)
    s = run_summary({"pos": pos, "step": step}, 1000, frame, n_balls=3, bond_i=[0], bond_j=[1],
                    bond_state=[0], radius=[1.0, 1.0, 1.0])
    assert s["plane_cracks"] == "post-peak"
    assert s["plane_dip_deg"] == pytest.approx(65.0, abs=1.5)
    assert s["plane_axis_height"] == pytest.approx(0.4, abs=0.02)
    assert s["crack_height_median_peak"] == pytest.approx(0.5, abs=0.05)
    assert s["fragments"] == 2 and s["detached_balls"] == 1
    few = run_summary({"pos": pos[:10], "step": step[:10]}, 1000, frame, n_balls=3,
                      bond_i=[0], bond_j=[1], bond_state=[0], radius=[1.0, 1.0, 1.0])
    assert few["plane_cracks"] == "none" and math.isnan(few["plane_dip_deg"])


def test_ucs_run_file_carries_the_morphology(tmp_path, cache):
    from support.lab_util import A1, FAST, SMALL

    from bpmcal.io import h5
    from bpmcal.stages.runs import run_ucs_file

    out = tmp_path / "a1.h5"
    assert run_ucs_file(out, A1, 3, SMALL, FAST, cache=cache).status == "ok"
    s, cr, inp = h5.read_summary(out), h5.read_cracks(out), h5.read_inputs(out)
    h = cr.loc[cr["step"] >= 0, "z"].to_numpy() / (inp["height_mm"] * 1e-3)
    assert s["crack_height_median"] == pytest.approx(np.median(h), rel=1e-12)
    assert s["crack_height_bottom_third"] == pytest.approx(np.mean(h < 1 / 3), rel=1e-12)
    assert s["crack_location"] in ("bottom", "middle", "top")
    assert 0.0 <= s["plane_dip_deg"] <= 90.0 and 0 < s["plane_fraction"] <= 1
    assert s["fragments"] >= 1 and 0 < s["largest_fragment"] <= 1
