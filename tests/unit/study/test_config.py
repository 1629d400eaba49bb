"""The study config (bpmcal.study.config): the shipped configs validate and the overlays
change what they say they change; the example of another rock (Lac du Bonnet) validates and
is not the paper; lab CSVs with source comments; the rules for the calibration bounds."""
import math

import pandas as pd
import pytest
from support.repo import REPO, SCHEMA, merged_config, update_config

from bpmcal.study.config import ConfigError, load_lab, loop_rounds_bound, validate_config

EXAMPLE = ("config.yaml", "examples/lac_du_bonnet.yaml")
EXAMPLE_SMOKE = (*EXAMPLE, "examples/lac_du_bonnet_smoke.yaml")
LDB = {"ucs_MPa": 200.0, "E_GPa": 69.0, "nu": 0.26}  # config/lab/lac_du_bonnet.csv


@pytest.mark.parametrize("overlay", [None, "smoke.yaml", "paper.yaml"])
def test_shipped_configs_validate(overlay):
    cfg = merged_config("config.yaml", *([overlay] if overlay else []))
    validate_config(cfg, SCHEMA, base_dir=REPO)
    assert cfg["study"]["n_samples"] >= 4


def test_paper_config_is_the_full_size_study():
    cfg = validate_config(merged_config("config.yaml", "paper.yaml"), SCHEMA, base_dir=REPO)
    assert cfg["specimen"]["scale"] == 1.0 and cfg["impact"]["scale"] == 1.0
    assert cfg["study"]["n_samples"] == 150
    assert cfg["outdir"] != "results"  # never overwrites the default study


def test_a_typo_in_an_overlay_is_named():
    cfg = merged_config("config.yaml")
    cfg["impact"]["velocty"] = 6.0
    with pytest.raises(ConfigError, match="velocty"):
        validate_config(cfg, SCHEMA, base_dir=REPO)


# ------------------------------------------------------------ the example of another rock
def test_example_configs_validate_and_are_not_the_paper():
    for names in (EXAMPLE, EXAMPLE_SMOKE):
        cfg = validate_config(merged_config(*names), SCHEMA, base_dir=REPO)
        assert cfg["study"]["reference"] == "none" and cfg["outdir"] != "results"
        lab = load_lab(REPO / cfg["lab"]["csv"])
        for k, v in LDB.items():
            assert lab.loc[0, k] == v
    # the paper's configs inherit the reference from config/config.yaml
    for overlay in ((), ("smoke.yaml",), ("paper.yaml",)):
        assert validate_config(merged_config("config.yaml", *overlay), SCHEMA,
                               base_dir=REPO)["study"]["reference"] == "yu2026"


def test_lab_csv_comment_lines_are_skipped(tmp_path):
    f = tmp_path / "rock.csv"
    f.write_text("# source: somebody (2004), table 1\n"
                 "   # indented comment\n"
                 "specimen,ucs_MPa,E_GPa,nu,u_pre_MJm3\n"
                 "# a comment between rows\n"
                 "R1,150.5,50.0,0.22,\n")
    lab = load_lab(f)
    assert list(lab.columns) == ["specimen", "ucs_MPa", "E_GPa", "nu", "u_pre_MJm3"]
    assert lab["specimen"].tolist() == ["R1"] and lab.loc[0, "ucs_MPa"] == 150.5
    cfg = merged_config(*EXAMPLE)
    cfg["lab"]["csv"] = str(f)
    cfg["triaxial"]["lab_csv"] = None  # the example's triaxial points are LdB's, not R1's
    validate_config(cfg, SCHEMA, base_dir=REPO)  # accepted by the config validation
    assert "# Lac du Bonnet" in (REPO / "config/lab/lac_du_bonnet.csv").read_text()


@pytest.mark.parametrize("patch, needle", [
    ({"calibration": {"bounds": {"pb_emod_GPa": [20.0, 100.0]}}},
     "calibration.bounds.pb_emod_GPa: [20, 100] reaches beyond ranges.pb_emod_GPa [30, 120], the "
     "sampled space"),
    ({"calibration": {"bounds": {"porosity": [0.3, 0.35]}}},
     "calibration.bounds.porosity: porosity is not calibrated"),
    ({"calibration": {"bounds": {"pb_coh_MPa": [90.0, 80.0]}}},
     "calibration.bounds.pb_coh_MPa: low 90 must be below high 80"),
    ({"calibration": {"fixed": {"porosity": 0.4}}},
     "calibration.fixed.porosity: 0.4 is outside ranges.porosity [0.2, 0.36]"),
    ({"ranges": {"pb_ten_MPa": [10.0, 50.0]}},
     "calibration.strength_ratio: 1.4 x pb_coh_MPa in [50, 300] never falls inside pb_ten_MPa [10, 50]"),
    ({"study": {"reference": "yu2026"}},
     "study.reference: yu2026 compares the results with the paper's green sandstone specimens"),
    ({"study": {"reference": "yu2025"}}, "study.reference: 'yu2025' is not one of"),
    ({"verification": {"from_unreachable": "no"}}, "verification.from_unreachable: 'no' is not of type"),
    ({"verification": {"max_rounds": "Auto"}}, "verification.max_rounds: 'Auto' does not match '^auto$'"),
    ({"verification": {"max_rounds": 0}}, "verification.max_rounds: 0 is less than the minimum of 1"),
    ({"verification": {"grow_within": 0.5}},
     "verification.grow_within: 0.5 is less than the minimum of 1"),
])
def test_calibration_space_config_errors_name_the_key(patch, needle):
    cfg = update_config(merged_config(*EXAMPLE), patch, keep=("bounds",))
    with pytest.raises(ConfigError) as e:
        validate_config(cfg, SCHEMA, base_dir=REPO)
    assert needle in str(e.value)


def test_a_cluster_loop_job_is_given_the_rounds_its_loop_may_take():
    """verification.max_rounds auto: 2 per free parameter, the tensile strength counted
    when a σt target frees it (the verify job's runtime on a cluster)."""
    cfg = validate_config(merged_config("config.yaml"), SCHEMA, base_dir=REPO)
    assert cfg["verification"]["max_rounds"] == "auto"
    assert loop_rounds_bound(cfg, tensile=False) == 6 and loop_rounds_bound(cfg, tensile=True) == 8
    cfg["calibration"]["free"] = [*cfg["calibration"]["free"], "pb_ten_MPa"]
    assert loop_rounds_bound(cfg, tensile=True) == 8  # freed already: not counted twice
    fj = validate_config(merged_config("config.yaml", "examples/lac_du_bonnet_fj.yaml"), SCHEMA,
                         base_dir=REPO)
    assert loop_rounds_bound(fj, tensile=True) == 8  # the model's default free + fj_ten_MPa
    fj["verification"]["max_rounds"] = 5
    assert loop_rounds_bound(fj, tensile=True) == 5


def test_narrowing_bounds_are_accepted():
    cfg = merged_config(*EXAMPLE)
    cfg["calibration"]["bounds"] = {"pb_emod_GPa": [40.0, 100.0], "pb_ten_MPa": [60.0, 250.0]}
    validate_config(cfg, SCHEMA, base_dir=REPO)


# ------------------------------------------------------------ the contact model
FJ_RANGES = {"fj_emod_GPa": [40.0, 100.0], "fj_kratio": [1.5, 3.0], "fj_ten_MPa": [5.0, 20.0],
             "fj_coh_MPa": [50.0, 200.0], "fj_fa_deg": [0.0, 40.0], "fj_fric": [0.4, 0.8]}


def _fj_config():
    cfg = merged_config("config.yaml")
    cfg["contact_model"] = "flatjoint"
    cfg["ranges"].update(FJ_RANGES)
    cfg["calibration"]["fixed"] = {"rmin_mm": 0.8, "porosity": 0.34, "fj_fa_deg": 20.0,
                                   "fj_fric": 0.6}
    cfg["calibration"]["strength_ratio"] = 0.1  # free: config.yaml's parallel-bond default
    return cfg


def test_a_flat_joint_config_takes_the_models_names_and_defaults():
    notes = []
    cfg = validate_config(_fj_config(), SCHEMA, base_dir=REPO, note=notes.append)
    assert cfg["calibration"]["free"] == ["fj_emod_GPa", "fj_kratio", "fj_coh_MPa"]
    # the parallel-bond keys inherited from config.yaml are left out, with one line
    assert not [k for k in cfg["ranges"] if k.startswith("pb_") or k == "fric"]
    assert len(notes) == 1 and "pb_emod_GPa" in notes[0] and "ranges.fric" in notes[0]
    assert "calibration.free" in notes[0]
    pb = validate_config(merged_config("config.yaml"), SCHEMA, base_dir=REPO)
    assert pb["contact_model"] == "linearpbond"
    assert pb["calibration"]["free"] == ["pb_emod_GPa", "pb_kratio", "pb_coh_MPa"]


def test_contact_model_mistakes_are_named():
    cfg = merged_config("config.yaml")
    cfg["ranges"]["fj_ten_MPa"] = [5.0, 20.0]  # a flat-joint name, parallel-bond study
    with pytest.raises(ConfigError, match=r"ranges: \['fj_ten_MPa'\] are flatjoint parameters.*"
                                          r"set contact_model: flatjoint"):
        validate_config(cfg, SCHEMA, base_dir=REPO)
    cfg = _fj_config()
    del cfg["ranges"]["fj_coh_MPa"]
    with pytest.raises(ConfigError, match=r"ranges: no range for \['fj_coh_MPa'\]"):
        validate_config(cfg, SCHEMA, base_dir=REPO)
    cfg = _fj_config()
    cfg["calibration"]["free"] = ["pb_emod_GPa"]
    with pytest.raises(ConfigError, match="calibration.free.*linearpbond parameters"):
        validate_config(cfg, SCHEMA, base_dir=REPO)
    cfg = _fj_config()
    cfg["contact_model"] = "hertz"
    with pytest.raises(ConfigError, match="contact_model.*hertz"):
        validate_config(cfg, SCHEMA, base_dir=REPO)
    cfg = _fj_config()
    cfg["calibration"]["strength_ratio"] = 1.4  # 1.4 x cb (50..200) never in sigma_b 5..20
    with pytest.raises(ConfigError, match="strength_ratio: 1.4 x fj_coh_MPa"):
        validate_config(cfg, SCHEMA, base_dir=REPO)


def test_the_schema_holds_every_registered_parameter():
    from bpmcal import params as P
    from bpmcal.study.config import load_schema

    sch = load_schema(SCHEMA)["properties"]
    assert sch["contact_model"]["enum"] == list(P.MODELS)
    cal = sch["calibration"]["properties"]
    for name, p in P.ALL_PARAMS.items():
        assert name in sch["ranges"]["properties"] and name in cal["fixed"]["properties"]
        assert name in cal["free"]["items"]["enum"] and name in cal["bounds"]["properties"]
    assert cal["fixed"]["properties"]["fj_slit_frac"] == {"type": "number", "minimum": 0.0,
                                                          "maximum": 1.0}


def test_lab_standard_errors_are_checked(tmp_path):
    f = tmp_path / "rock.csv"
    f.write_text("specimen,ucs_MPa,E_GPa,nu,bts_MPa,ucs_MPa_se,bts_MPa_se\n"
                 "R1,150.5,50.0,0.22,9.0,3.0,\nR2,140.0,48.0,0.21,,0.0,\n")
    lab = load_lab(f)
    assert lab.loc[0, "ucs_MPa_se"] == 3.0 and lab.loc[1, "ucs_MPa_se"] == 0.0
    f.write_text("specimen,ucs_MPa,E_GPa,nu,bts_MPa,ucs_MPa_se,bts_MPa_se\n"
                 "R1,150.5,50.0,0.22,,-1.0,0.5\n")
    with pytest.raises(ConfigError) as e:
        load_lab(f)
    assert "R1 ucs_MPa_se='-1.0': expected a standard error >= 0" in str(e.value)
    assert "R1 bts_MPa_se='0.5': a standard error without its value bts_MPa" in str(e.value)


def test_null_in_an_overlay_unsets_an_inherited_fixed_value_or_bound():
    cfg = _fj_config()
    cfg["calibration"]["free"] = ["fj_emod_GPa", "fj_kratio", "fj_coh_MPa", "fj_fa_deg"]
    with pytest.raises(ConfigError, match=r"calibration.free and calibration.fixed both name fj_fa_deg.*"
                                          r"calibration.fixed.fj_fa_deg: null"):
        validate_config(cfg, SCHEMA, base_dir=REPO, note=lambda _: None)
    cfg = update_config(cfg, {"calibration": {"fixed": {"fj_fa_deg": None},
                                              "bounds": {"fj_kratio": None}}})
    notes = []
    out = validate_config(cfg, SCHEMA, base_dir=REPO, note=notes.append)
    assert "fj_fa_deg" not in out["calibration"]["fixed"] and out["calibration"]["fixed"]["fj_fric"]
    assert "fj_fa_deg" in out["calibration"]["free"] and "fj_kratio" not in out["calibration"]["bounds"]
    assert notes[0] == ("config: calibration.fixed.fj_fa_deg, calibration.bounds.fj_kratio unset "
                        "(null: the base config's value removed)")
    # null stays an error where it unsets nothing the schema allows
    cfg = update_config(_fj_config(), {"ranges": {"fj_fa_deg": None}})
    with pytest.raises(ConfigError, match="ranges.fj_fa_deg: None is not of type 'array'"):
        validate_config(cfg, SCHEMA, base_dir=REPO, note=lambda _: None)


def test_the_triaxial_overlay_adds_sigma1_on_the_lab_envelope_and_frees_the_friction_angle():
    """The overlay's target is the lab envelope's sigma1 at the design confinement (the
    same point as the triaxial stage's lab CSV), and its stated tolerance (2 x tri_MPa_se)
    is the sigma1 band in which the two-point Hoek-Brown mi stays within +-25 % of the
    envelope's 28.9, as the lab CSV says."""
    cfg = validate_config(merged_config("config.yaml", "examples/lac_du_bonnet_fj.yaml",
                                        "examples/lac_du_bonnet_fj_triaxial.yaml"),
                          SCHEMA, base_dir=REPO)
    s3 = cfg["triaxial"]["design_sigma3_MPa"]
    assert "fj_fa_deg" in cfg["calibration"]["free"] and "fj_fa_deg" not in cfg["calibration"]["fixed"]
    lo_fa, hi_fa = cfg["ranges"]["fj_fa_deg"]
    assert lo_fa < 30.0 < 50.0 < hi_fa  # the probed 30-50 deg (record 27l) inside the design
    lab = load_lab(REPO / cfg["lab"]["csv"])
    env = pd.read_csv(REPO / cfg["triaxial"]["lab_csv"], comment="#")
    assert s3 in env["sigma3_MPa"].tolist()
    assert lab.loc[0, "tri_MPa"] == env.loc[env["sigma3_MPa"] == s3, "sigma1_MPa"].item()
    assert lab.loc[0, "dtt_MPa"] == 9.3
    sc, mi = lab.loc[0, "ucs_MPa"], 28.9

    def two_point_mi(s1):
        return ((s1 - s3) ** 2 / sc ** 2 - 1) * sc / s3

    assert two_point_mi(lab.loc[0, "tri_MPa"]) == pytest.approx(mi, rel=2e-3)
    # sigma1 where the two-point mi is 0.75 and 1.25 x 28.9: 2 SE is that band's half-width
    lo, hi = (s3 + sc * math.sqrt(f * mi * s3 / sc + 1) for f in (0.75, 1.25))
    assert two_point_mi(lo) == pytest.approx(0.75 * mi) and two_point_mi(hi) == pytest.approx(
        1.25 * mi)
    assert 2 * lab.loc[0, "tri_MPa_se"] == pytest.approx((hi - lo) / 2, rel=0.02)
    assert cfg["outdir"] not in ("results", "results/lac_du_bonnet_fj")
    # the four-target example itself has no triaxial target
    base = validate_config(merged_config("config.yaml", "examples/lac_du_bonnet_fj.yaml"),
                           SCHEMA, base_dir=REPO)
    assert base["triaxial"]["design_sigma3_MPa"] is None
    assert base["calibration"]["fixed"]["fj_fa_deg"] == 30.0
    assert "tri_MPa" not in load_lab(REPO / base["lab"]["csv"]).columns


def test_a_flat_jointed_study_that_scales_densities_is_told_once():
    """Density scaling is validated on parallel-bond cards: a flat-jointed study with it on
    gets one line naming the keys and the record; with it null, or a parallel-bond
    study with it on, none."""
    def lines(*names, **sections):
        cfg = merged_config(*names)
        for sec, v in sections.items():
            cfg.setdefault(sec, {})["density_scaling"] = v
        seen = []
        validate_config(cfg, SCHEMA, base_dir=REPO, note=seen.append)
        return [s for s in seen if "density scaling" in s]

    fj = ("config.yaml", "examples/lac_du_bonnet_fj.yaml")
    got = lines(*fj, compression=0.5, dtt=0.25, bts=None)
    assert len(got) == 1 and "compression.density_scaling, dtt.density_scaling set" in got[0]
    assert "2026-12-02j-density-scaling.md" in got[0]
    assert lines(*fj, compression=None, bts=None, dtt=None) == []
    assert lines("config.yaml", compression=0.5, bts=0.5) == []
