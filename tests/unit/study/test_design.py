"""The Latin-hypercube design for either contact model (the registry's names and ranges)."""
import numpy as np
import pytest

from bpmcal import params as P
from bpmcal.study.design import lhs_design, validate_ranges


def test_a_flat_joint_design_has_the_models_columns_and_defaults():
    ranges = {"rmin_mm": [0.6, 1.0], "porosity": [0.2, 0.36], "fj_emod_GPa": [40, 100],
              "fj_kratio": [1.5, 3], "fj_ten_MPa": [5, 20], "fj_coh_MPa": [50, 200],
              "fj_fa_deg": [0, 40], "fj_fric": [0.4, 0.8]}
    d = lhs_design(ranges, 20, 7)
    # the quiet keys (no strength scatter) are left out at their defaults
    loud = [k for k in P.FLATJOINT.names if k not in P.FLATJOINT.quiet]
    assert list(d.columns) == ["sample_id", *loud, "seed"]
    for k, v in P.FJ_DEFAULTS.items():  # no range, no fixed value: the model's default
        assert k in P.FLATJOINT.quiet or (d[k] == v).all()
    for k, (lo, hi) in ranges.items():
        assert d[k].between(lo, hi).all() and d[k].nunique() == 20


def test_an_integer_parameter_is_designed_on_its_levels():
    ranges = {**{k: list(v) for k, v in P.FLATJOINT.design_ranges().items()},
              "fj_nal": [2, 5]}
    d = lhs_design(ranges, 40, 3)
    levels = d["fj_nal"].value_counts().sort_index()
    assert list(levels.index) == [2.0, 3.0, 4.0, 5.0]  # every level, integers only
    assert (levels == 10).all()  # a Latin hypercube: each level's stratum equally often
    assert (d["fj_kratio"] != np.floor(d["fj_kratio"])).all()  # real ones stay real


def test_names_of_the_other_model_or_unknown_names_are_refused():
    with pytest.raises(P.ParameterError, match="mixed card"):
        lhs_design({"pb_emod_GPa": [10, 50], "fj_ten_MPa": [5, 20]}, 10, 1)
    with pytest.raises(P.ParameterError, match=r"unknown parameter\(s\) \['pb_emod_GPa'\].*flatjoint"):
        validate_ranges({"pb_emod_GPa": [10, 50]}, P.FLATJOINT)
    with pytest.raises(P.ParameterError, match="fj_slit_frac"):
        validate_ranges({"fj_slit_frac": [0.0, 1.5]})  # outside its physical domain
    with pytest.raises(P.ParameterError, match="contact_model='hertz'"):
        lhs_design(P.table2_ranges(), 10, 1, contact_model="hertz")


def test_the_parallel_bond_design_keeps_table_2_order():
    d = lhs_design({k: list(v) for k, v in P.table2_ranges().items()}, 10, 1)
    assert list(d.columns) == ["sample_id", *P.PARAM_NAMES, "seed"]


def test_a_flat_joint_design_row_is_a_flat_joint_card(tmp_path):
    from bpmcal.stages.runs import BadInput, params_from_design, run_source
    from bpmcal.study.gather import gather

    ranges = {"rmin_mm": [0.8, 0.8], "porosity": [0.3, 0.3], "fj_emod_GPa": [40, 100],
              "fj_kratio": [1.5, 3], "fj_ten_MPa": [5, 20], "fj_coh_MPa": [50, 200],
              "fj_fa_deg": [0, 40], "fj_fric": [0.4, 0.8]}
    d = lhs_design(ranges, 4, 7)
    f = tmp_path / "design.csv"
    d.to_csv(f, index=False)
    params, seed, skip = params_from_design(f, "s002")
    assert params["contact_model"] == "flatjoint" and skip == "" and seed == d["seed"][2]
    assert params["fj_coh_MPa"] == pytest.approx(d["fj_coh_MPa"][2])
    with pytest.raises(BadInput, match="--contact-model linearpbond: .* flatjoint cards"):
        run_source(design=f, sample="s002", contact_model="linearpbond")
    df = gather(d, {})  # no run files: every sample missing, the card's columns kept
    loud = [k for k in P.FLATJOINT.names if k not in P.FLATJOINT.quiet]
    assert list(df.columns[:len(loud) + 1]) == ["sample_id", *loud]
    assert (df["status"] == "missing").all()
