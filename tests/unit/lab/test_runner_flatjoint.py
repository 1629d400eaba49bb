"""Flat-jointed specimens in the virtual lab: genesis (microstructure as asked, installed
force-free), determinism and thread-count invariance of a UCS run, the scaling law of
sigma_c and sigma_t, every test running a flat-jointed card, and bad cards refused."""
import h5py
import numpy as np
import pytest
from support.lab_util import SMALL, ucs
from support.paper import A1, FJ1

from bpmcal import params as P
from bpmcal.cli import main
from bpmcal.dem import flatjoint as fj
from bpmcal.dem._jit import set_threads
from bpmcal.io.vtk import export_run
from bpmcal.lab.direct_tension import DTTSettings, run_dtt
from bpmcal.lab.runner import make_specimen
from bpmcal.lab.ucs import UCSSettings

SHORT = UCSSettings(platen_velocity=0.1, record_strain=4e-5, max_steps=1500)


def scaled(p, k):
    return dict(p, fj_emod_GPa=p["fj_emod_GPa"] * k, fj_ten_MPa=p["fj_ten_MPa"] * k,
                fj_coh_MPa=p["fj_coh_MPa"] * k)


@pytest.fixture(autouse=True)
def one_thread():
    set_threads(1)
    yield
    set_threads(1)


@pytest.fixture(scope="module")
def base(cache):
    set_threads(1)
    return ucs(FJ1, cache)


def test_genesis_installs_the_microstructure_asked_for(cache):
    card = dict(FJ1, fj_slit_frac=0.3, fj_gap_frac=0.1, fj_gap0_ratio=0.01)
    sp = make_specimen(card, 3, SMALL, cache=cache)
    m, g = sp.model, sp.report
    n = m.n_bonds
    t = m.flatjoint_types
    for mt, want, key in ((fj.MT_SLIT, 0.3, "fj_slit_frac_installed"),
                          (fj.MT_GAPPED, 0.1, "fj_gapped_frac"),
                          (fj.MT_BONDED, 0.6, "fj_bonded_frac")):
        got = np.count_nonzero(t == mt) / n
        assert abs(got - want) <= 1.0 / n, (mt, got)  # exact counts, as fistPkg
        assert g[key] == pytest.approx(got)
    assert g["contact_model"] == "flatjoint"
    assert g["flatjoints_per_ball"] == pytest.approx(2 * n / m.n)
    rmean = float(np.mean(m.radii))
    assert g["fj_gi_mm"] == pytest.approx(0.2 * rmean * 1e3, rel=1e-9)
    assert g["fj_gap0_mm"] == pytest.approx(0.01 * rmean * 1e3, rel=1e-9)
    # a wider installation gap gives more flat joints per ball (PFC: more faces per grain)
    g0 = make_specimen(dict(FJ1, fj_gi_ratio=0.0), 3, SMALL, cache=cache).report
    assert g0["flatjoints_per_ball"] < g["flatjoints_per_ball"]
    # gapped joints: surfaces g_0 apart; the others touch; no element state but theirs
    st = m.flatjoint_state()
    assert np.all(st["gap0"][t == fj.MT_GAPPED] == pytest.approx(0.01 * rmean))
    assert np.all(m.bond_states[t != fj.MT_BONDED] == 3)
    assert np.all(m.element_states[t == fj.MT_BONDED] == fj.E_BONDED)
    # not clustered along the contact order (which follows the balls' space-filling order)
    half = n // 2
    assert abs(np.mean(t[:half] == fj.MT_SLIT) - np.mean(t[half:] == fj.MT_SLIT)) < 0.1


def test_installation_is_force_free(cache):
    """Right after installation every flat joint carries no force (docs/flatjoint-spec.md T9)."""
    from bpmcal.dem import Model
    from bpmcal.lab.packing_cache import get_packing
    from bpmcal.lab.runner import specimen_spec
    from bpmcal.lab.specimen import card_material
    p = P.validate_params(FJ1)
    pk = get_packing(specimen_spec(p, 3, SMALL), cache=cache)
    mat, _ = card_material(p)
    m = Model(pk.pos, pk.radius, 2294.0, mat)
    assert m.bond(gap=0.2 * float(np.mean(pk.radius))) > m.n
    m.set_timestep(None)
    m.energies()
    f = np.linalg.norm(m.Fj.c[:, fj.C_FX:fj.C_FZ + 1], axis=1)
    # most are exactly 0; the rest are the gap's last bit (the kernel fuses multiply-adds
    # where numpy does not): ~1e-19 m x k_n A ~ 1e-11 N, against ~100 N per um of overlap
    assert np.count_nonzero(f == 0.0) > 0.5 * f.size
    assert f.max() < 1e-9


def test_flat_jointed_ucs_is_deterministic_and_thread_count_invariant(cache):
    runs = []
    for th in (1, 1, 2):
        set_threads(th)
        r, sp = ucs(FJ1, cache, settings=SHORT)
        runs.append((r.series["axial_stress"], sp.model.positions.copy(),
                     sp.model.element_states.copy(), r.cracks["step"]))
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            assert np.array_equal(a, b)
    assert runs[0][3].size > 0  # elements broke on the way


def test_flat_jointed_ucs_fails_with_element_cracks_of_both_modes(base):
    r, sp = base
    s = r.summary
    assert r.series["axial_stress"].max() > 0
    assert s["stop_reason"] == "post_peak_drop"
    assert s["cracks_tension"] > 0 and s["cracks_shear"] > 0
    assert len(r.cracks["step"]) == s["cracks_tension"] + s["cracks_shear"]
    assert set(np.unique(r.cracks["element"])) <= set(range(3))
    assert np.all(r.cracks["area"] > 0)


@pytest.mark.slow
def test_scaling_moduli_and_strengths_by_1_5_scales_sigma_c_and_sigma_t(base, cache):
    r0 = base[0].summary
    r1 = ucs(scaled(FJ1, 1.5), cache)[0].summary
    assert r1["ucs_MPa"] / r0["ucs_MPa"] == pytest.approx(1.5, rel=0.03)
    assert r1["E_GPa"] / r0["E_GPa"] == pytest.approx(1.5, rel=0.03)
    st = DTTSettings()
    t = [run_dtt(make_specimen(c, 3, SMALL, cache=cache, boundary="free"), st).summary
         for c in (FJ1, scaled(FJ1, 1.5))]
    # the mechanics scale whether or not the run is a valid measurement: the peaks
    assert t[1]["dtt_peak_MPa"] / t[0]["dtt_peak_MPa"] == pytest.approx(1.5, rel=0.03)


def test_flat_joints_raise_sigma_c_over_sigma_t_above_the_parallel_bond(base, cache):
    """The reason for the model (Potyondy 2012, docs/flatjoint-spec.md §9): the same kind of specimen
    gives a far higher sigma_c / sigma_t with flat joints than A1 with parallel bonds."""
    st = DTTSettings()
    fjt = run_dtt(make_specimen(FJ1, 3, SMALL, cache=cache, boundary="free"), st).summary
    pbt = run_dtt(make_specimen(A1, 3, SMALL, cache=cache, boundary="free"), st).summary
    pbc = ucs(A1, cache)[0].summary
    # the peaks (a 12 mm cylinder's fracture may fall outside the gauge: invalid as a
    # measurement, but the strength ratio of the two models is what is compared)
    r_fj = base[0].summary["ucs_MPa"] / fjt["dtt_peak_MPa"]
    r_pb = pbc["ucs_MPa"] / pbt["dtt_peak_MPa"]
    assert r_fj > 2 * r_pb, (r_fj, r_pb)


@pytest.mark.slow
@pytest.mark.parametrize("test,extra", [
    # one disc: whether it is valid, or split before its max_strain (else it is written
    # whole as incomplete: --failed-ok), does not matter here (a retest would run another)
    # the disc as sized (--min-balls-across 0: not enlarged to a flat joint's 19 across)
    ("bts", ["--scale", "0.4", "--max-strain", "0.002", "--retests", "0", "--failed-ok",
             "--min-balls-across", "0"]),
    ("dtt", ["--scale", "0.24"]),
    ("triaxial", ["--scale", "0.24", "--sigma3", "5"]),
    ("impact", ["--scale", "0.24", "--duration-ms", "0.3"])])
def test_every_lab_test_runs_a_flat_jointed_card_from_the_cli(tmp_path, test, extra):
    pf = tmp_path / "fj.yaml"
    pf.write_text("\n".join(f"{k}: {v}" for k, v in FJ1.items()) + "\n")
    out = tmp_path / f"{test}.h5"
    rc = main([test, "--params", str(pf), "--out", str(out), "--quiet", "--threads", "1",
               *extra])
    assert rc == 0 and out.exists()
    with h5py.File(out) as f:
        assert f["inputs"].attrs["contact_model"] == "flatjoint"
        assert f["inputs"].attrs["fj_nal"] == 3.0
        assert f["genesis"].attrs["contact_model"] == "flatjoint"
        s = f["summary"].attrs
        assert s["cracks_tension"] + s["cracks_shear"] == f["cracks/step"].shape[0] > 0
        assert set(np.unique(f["cracks/element"][()])) <= {0, 1, 2}
    # ParaView: one crack per broken element, with its mode and element index
    files = export_run(out, tmp_path / "vtk")
    txt = (tmp_path / "vtk" / "cracks.vtp").read_text()
    assert any(p.name == "cracks.vtp" for p in files)
    assert '"element"' in txt and '"mode"' in txt


def test_set_built_card_needs_no_other_flag_than_contact_model(tmp_path, cache):
    sets = [x for k, v in FJ1.items() if k != "contact_model"
            for x in ("--set", f"{k}={v}")]
    out = tmp_path / "u.h5"
    rc = main(["ucs", "--contact-model", "flatjoint", *sets, "--out", str(out), "--quiet",
               "--scale", "0.24", "--threads", "1", "--specimen-cache", str(cache),
               "--platen-velocity", "0.1", "--record-strain", "4e-5", "--max-strain", "2e-3"])
    # max_strain 2e-3 cuts the loading before the peak (for speed): the run is written whole
    # but recorded incomplete (exit 3), no sigma_c
    assert rc == 3
    with h5py.File(out) as f:
        assert f["inputs"].attrs["contact_model"] == "flatjoint"
        assert f.attrs["status"] == "incomplete"


@pytest.mark.parametrize("change,needle", [
    (dict(fj_nr=0), "fj_nr=0"), (dict(fj_nr=1.5), "fj_nr=1.5"),
    (dict(fj_slit_frac=1.2), "fj_slit_frac=1.2"),
    (dict(fj_slit_frac=0.7, fj_gap_frac=0.5), "fj_slit_frac + fj_gap_frac"),
    (dict(pb_ten_MPa=20.0), "mixed card"),
    (dict(contact_model="linearpbond"), "but the card has flatjoint keys"),
    (dict(contact_model="flatjoints"), "contact_model='flatjoints'"),
])
def test_bad_flat_joint_cards_exit_2_with_one_line_and_no_file(tmp_path, capsys, change,
                                                               needle):
    pf = tmp_path / "fj.yaml"
    pf.write_text("\n".join(f"{k}: {v}" for k, v in {**FJ1, **change}.items()) + "\n")
    out = tmp_path / "x.h5"
    rc = main(["ucs", "--params", str(pf), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert needle in err and len(err.splitlines()) == 1


def test_a_flat_joint_key_on_a_parallel_bond_card_is_refused():
    with pytest.raises(P.ParameterError, match="mixed card"):
        P.validate_params(dict(A1, fj_nr=2))
    # a parallel-bond card validates exactly as before flat joints existed
    assert P.validate_params(A1) == {k: float(v) for k, v in A1.items()}
