"""Direct-tension test: the scaling law, the grips, a failure next to a grip, the run file
and the command line."""
import math
import time

import numpy as np
import pytest
from support.lab_util import A1

from bpmcal.cli import main
from bpmcal.dem.errors import InputError
from bpmcal.dem.slots import FIX_VZ
from bpmcal.io import h5
from bpmcal.lab.direct_tension import DTTSettings, grips, run_dtt
from bpmcal.lab.runner import Geometry, make_specimen

#: 12 x 24 mm, ~330 balls: the cheapest cylinder with grips of two ball layers
CYL = Geometry(scale=0.24)
FAST = DTTSettings(grip_velocity=0.02, record_strain=4e-6)
SEED = 2  # fails in its gauge section (seed 3 of this small cylinder breaks at a grip)


def scaled(p, k):
    return dict(p, pb_emod_GPa=p["pb_emod_GPa"] * k, pb_ten_MPa=p["pb_ten_MPa"] * k,
                pb_coh_MPa=p["pb_coh_MPa"] * k)


def dtt(params, cache, seed=SEED, settings=FAST, weaken=None):
    sp = make_specimen(params, seed, CYL, cache=cache, boundary="free")
    if weaken is not None:
        weaken(sp)
    return run_dtt(sp, settings), sp


@pytest.fixture(scope="module")
def base(cache):
    return dtt(A1, cache)


def test_the_grips_pull_the_ends_apart_and_sigma_t_is_the_peak_stress(base):
    r, sp = base
    s, ser = r.summary, r.series
    m = sp.model
    bot, top = r.grip_balls
    assert (m.fix_flags[bot] & FIX_VZ).all() and (m.fix_flags[top] & FIX_VZ).all()
    free = np.setdiff1d(np.arange(m.n), np.concatenate([bot, top]))
    assert not (m.fix_flags[free] & FIX_VZ).any()
    assert np.allclose(m.velocities[top, 2], FAST.grip_velocity)
    assert np.allclose(m.velocities[bot, 2], -FAST.grip_velocity)
    assert s["grip_balls_bottom"] == bot.size and s["grip_balls_top"] == top.size
    ip = int(np.argmax(ser["axial_stress"]))
    assert s["dtt_peak_MPa"] == pytest.approx(ser["axial_stress"][ip] / 1e6, rel=1e-12)
    assert s["dtt_valid"] and s["dtt_MPa"] == s["dtt_peak_MPa"] > 0
    assert s["stop_reason"] == "post_peak_drop"
    # quasi-static: the two grips carry the same load along the pre-peak curve
    up = slice(ip // 4, ip + 1)
    rel = np.abs(ser["stress_top"][up] - ser["stress_bottom"][up]) / ser["axial_stress"][up]
    assert np.median(rel) < 0.01
    # the fracture lies in the gauge section
    assert 0 < s["fracture_height"] < 1 and s["fracture_grip_distance_mm"] > 0


def test_the_tensile_modulus_is_the_compressive_one(base, cache):
    """Below the peak the bonded body is linear: E in tension (grips) matches E in
    compression (platens, UCS) on the same specimen size within 10 %."""
    from support.lab_util import FAST as UCS_FAST

    from bpmcal.lab.ucs import run_ucs

    u = run_ucs(make_specimen(A1, SEED, CYL, cache=cache), UCS_FAST).summary
    assert base[0].summary["E_t_GPa"] == pytest.approx(u["E_GPa"], rel=0.10)


def test_sigma_t_is_below_the_bond_tensile_strength_and_sigma_c(base, cache):
    s = base[0].summary
    assert 0.2 * A1["pb_ten_MPa"] < s["dtt_MPa"] < A1["pb_ten_MPa"]


def test_scaling_moduli_and_strengths_by_1_5_scales_sigma_t_by_1_5(base, cache):
    r, _ = dtt(scaled(A1, 1.5), cache)
    s0, s1 = base[0].summary, r.summary
    assert s1["dtt_peak_MPa"] / s0["dtt_peak_MPa"] == pytest.approx(1.5, rel=0.03)
    assert s1["peak_strain"] / s0["peak_strain"] == pytest.approx(1.0, rel=0.03)
    assert s1["dtt_valid"] == s0["dtt_valid"]


def test_a_failure_next_to_a_grip_is_flagged(cache):
    """The bonds within one mean ball diameter above the bottom grip's face at a tenth of
    their strength: the specimen breaks there, and the run says so (no sigma_t)."""
    def weaken(sp):
        m = sp.model
        _, _, zb, _ = grips(sp, FAST.grip_length)
        bi, bj = m.bond_pairs()
        zmid = 0.5 * (m.positions[bi, 2] + m.positions[bj, 2])
        dbar = 2 * m.radii.mean()
        weak = (zmid > zb) & (zmid < zb + dbar)
        f = m.bond_strength_factors
        f[weak] *= 0.1
        m.set_bond_strength_factors(f)

    r, _ = dtt(A1, cache, weaken=weaken)
    s = r.summary
    assert s["stop_reason"] == "post_peak_drop"
    assert not s["dtt_valid"] and math.isnan(s["dtt_MPa"])
    assert s["dtt_invalid_reason"].startswith("failure next to the bottom grip")
    assert s["fracture_height"] < 0.1


def test_settings_refuse_bad_values():
    for kw, needle in [(dict(grip_velocity=-1.0), "grip_velocity=-1.0"),
                       (dict(grip_length=0.5), "grip_length=0.5"),
                       (dict(stop_drop=1.5), "stop_drop=1.5"),
                       (dict(grip_clearance=float("nan")), "grip_clearance=nan")]:
        with pytest.raises(InputError, match=needle):
            DTTSettings(**kw)


def test_the_command_writes_one_run_file(tmp_path, cache, capsys):
    pf = tmp_path / "a1.yaml"
    pf.write_text("\n".join(f"{k}: {v}" for k, v in A1.items()))
    out = tmp_path / "a1.h5"
    assert main(["dtt", "--params", str(pf), "--out", str(out), "--scale", "0.24",
                 "--seed", str(SEED), "--grip-velocity", "0.02", "--record-strain", "4e-6",
                 "--specimen-cache", str(cache), "--quiet"]) == 0
    s = h5.read_summary(out)
    assert s["test"] == "dtt" and s["status"] == "ok" and s["dtt_valid"]
    inp = h5.read_inputs(out)
    assert inp["dtt_grip_velocity"] == 0.02 and inp["diameter_mm"] == pytest.approx(12.0)


@pytest.mark.parametrize("args, needle", [
    (["--grip-velocity", "-1"], "grip-velocity='-1'"),
    (["--grip-length", "0.6"], "grip-length='0.6'"),
    (["--diameter", "-5"], "diameter='-5'"),
])
def test_cli_rejects_bad_input_and_writes_no_file(tmp_path, capsys, args, needle):
    pf = tmp_path / "p.yaml"
    pf.write_text("\n".join(f"{k}: {v}" for k, v in A1.items()))
    out = tmp_path / "o.h5"
    t0 = time.perf_counter()
    try:
        rc = main(["dtt", "--params", str(pf), "--out", str(out), *args])
    except SystemExit as e:
        rc = e.code
    assert rc == 2 and time.perf_counter() - t0 < 5
    assert needle in capsys.readouterr().err
    assert not out.exists()
