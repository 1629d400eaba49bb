"""XGBoost screening on data with a planted dominant parameter."""
import numpy as np
import pytest
import xgboost as xgb

from bpmcal.analysis.screening import (
    IMPORTANCE_TYPES,
    XGBScreening,
    _normalise,
    table3,
    table3_markdown,
)
from bpmcal.params import PARAM_NAMES

FAST = {"n_estimators": 80}


@pytest.fixture(scope="module")
def planted(design):
    """ucs depends strongly on pb_coh_MPa, weakly on porosity; nu is pure noise."""
    df = design(120, seed=3)
    rng = np.random.default_rng(4)
    df["ucs_MPa"] = 3.0 * df["pb_coh_MPa"] - 60.0 * df["porosity"] + rng.normal(0, 2.0, len(df))
    df["nu"] = rng.normal(0.25, 0.01, len(df))
    df.loc[[5, 17], "status"] = "failed"
    df.loc[[5, 17], "ucs_MPa"] = np.nan
    return df


@pytest.fixture(scope="module")
def result(planted):
    return XGBScreening(responses=("ucs_MPa", "nu"), xgb_params=FAST, n_repeats=5, seed=1).fit(planted)


def test_dominant_parameter_ranks_first_and_beats_shadows(result):
    for kind in IMPORTANCE_TYPES:
        share = result.share(kind)["ucs_MPa"]
        assert share.idxmax() == "pb_coh_MPa", kind
        assert share["pb_coh_MPa"] > 60.0, kind
        assert result.shadow_max.loc["ucs_MPa", kind] < share["pb_coh_MPa"] / 5, kind
    assert result.selected["ucs_MPa"][0] == "pb_coh_MPa"
    inert = ["rmin_mm", "pb_emod_GPa", "pb_kratio", "pb_ten_MPa", "pb_fa_deg", "fric"]
    assert not set(inert) & set(result.selected["ucs_MPa"])


def test_shares_are_percent_and_cv_r2_separates_signal_from_noise(result):
    for kind in IMPORTANCE_TYPES:
        np.testing.assert_allclose(result.share(kind)["ucs_MPa"].sum(), 100.0, rtol=1e-9)
    cv = result.cv_r2
    assert cv.loc["ucs_MPa", "mean"] > 0.9
    assert cv.loc["nu", "mean"] < 0.2  # nothing to learn
    assert {f"fold{k}" for k in range(5)} <= set(cv.columns)
    # for the pure-noise response no parameter stands out from the shadow copies
    assert result.share("permutation")["nu"].max() < 60


def test_failed_rows_are_dropped_and_counted(result):
    assert result.rows["n_dropped"] == 2 and result.rows["n_used"] == 118
    assert result.cv["n_train"].add(result.cv["n_val"]).eq(118).all()


def test_gain_equals_xgbregressor_feature_importances(planted):
    """'gain' share of one model = 100 × XGBRegressor.feature_importances_ (independent API)."""
    pytest.importorskip("sklearn")  # XGBRegressor needs scikit-learn
    data = planted[planted["status"] == "ok"]
    X, y = data[list(PARAM_NAMES)].to_numpy(), data["ucs_MPa"].to_numpy()
    scr = XGBScreening(responses=("ucs_MPa",), xgb_params=FAST)
    booster = scr._train(X, y, list(PARAM_NAMES), seed=7)
    score = booster.get_score(importance_type="gain")
    ours = _normalise(np.array([score.get(p, 0.0) for p in PARAM_NAMES]))
    reg = xgb.XGBRegressor(n_estimators=80, max_depth=3, learning_rate=0.05, subsample=0.8, n_jobs=1,
                           random_state=7, min_child_weight=1.0, reg_lambda=1.0, colsample_bytree=1.0)
    reg.fit(X, y)
    np.testing.assert_allclose(ours, 100 * reg.feature_importances_, rtol=1e-5, atol=1e-6)


def test_table3_layout(result):
    tab = table3(result)
    assert list(tab.index) == list(PARAM_NAMES)
    assert list(tab.columns) == ["ucs_MPa", "nu"]
    md = table3_markdown(result)
    lines = md.splitlines()
    assert lines[0] == "| Meso-parameters | σc (%) | ν (%) |"
    assert len(lines) == 2 + 8 and lines[7].startswith("| τcp |")


def test_selection_rule_is_configurable(result):
    assert result.selected_by("gain", threshold=99.9)["ucs_MPa"] == ()
    assert "porosity" in result.selected_by("shap", threshold=1.0)["ucs_MPa"]
    frame = result.to_frame()
    assert frame.loc[("ucs_MPa", "pb_coh_MPa"), "selected"]
    assert not frame.loc[("ucs_MPa", "fric"), "selected"]


def test_deterministic_given_seed(planted):
    a = XGBScreening(responses=("ucs_MPa",), xgb_params=FAST, n_repeats=2, shadow=False, seed=5).fit(planted)
    b = XGBScreening(responses=("ucs_MPa",), xgb_params=FAST, n_repeats=2, shadow=False, seed=5).fit(planted)
    np.testing.assert_array_equal(a.importances["share"], b.importances["share"])


def test_bad_settings_name_the_value():
    with pytest.raises(ValueError, match="importance='weight'"):
        XGBScreening(importance="weight")
    with pytest.raises(ValueError, match="unknown parameter"):
        XGBScreening(params=["pb_coh"])
    with pytest.raises(ValueError, match="seed"):
        XGBScreening(xgb_params={"random_state": 3})


@pytest.fixture(scope="module")
def spread(design):
    """sigma_t-like: two strong parameters and two weak but real ones (a few % of the
    importance each, below the paper's 10 %), four inert."""
    df = design(150, seed=8)
    rng = np.random.default_rng(9)
    z = {p: (df[p] - df[p].mean()) / df[p].std() for p in PARAM_NAMES}
    df["bts_MPa"] = (10 + 3.0 * z["pb_ten_MPa"] + 3.0 * z["pb_coh_MPa"] + 0.9 * z["pb_kratio"]
                     + 0.9 * z["pb_fa_deg"] + rng.normal(0, 0.1, len(df)))
    return df


def test_rules_threshold_above_noise_and_all(spread):
    kw = dict(responses=("bts_MPa",), xgb_params=FAST, n_repeats=2, seed=2)
    paper = XGBScreening(**kw).fit(spread)
    share = paper.share("gain")["bts_MPa"]
    assert share["pb_kratio"] < 10 and share["pb_fa_deg"] < 10  # the planted weak ones
    assert set(paper.selected["bts_MPa"]) == {"pb_ten_MPa", "pb_coh_MPa"}
    noise = XGBScreening(rule="above_noise", **kw).fit(spread)
    assert {"pb_kratio", "pb_fa_deg"} <= set(noise.selected["bts_MPa"])
    assert noise.selected["bts_MPa"][:2] in {("pb_ten_MPa", "pb_coh_MPa"),
                                             ("pb_coh_MPa", "pb_ten_MPa")}
    every = XGBScreening(rule="all", **kw).fit(spread)
    assert set(every.selected["bts_MPa"]) == set(PARAM_NAMES)
    assert every.selected["bts_MPa"][0] in {"pb_ten_MPa", "pb_coh_MPa"}  # largest share first
    assert "(all)" in every.summary() and "(above noise)" in noise.summary()


def test_combined_screenings_keep_each_responses_rule(planted, spread):
    from bpmcal.analysis.screening import combine

    a = XGBScreening(responses=("ucs_MPa",), xgb_params=FAST, n_repeats=2, seed=1).fit(planted)
    b = XGBScreening(responses=("bts_MPa",), xgb_params=FAST, n_repeats=2, seed=1,
                     rule="all").fit(spread)
    both = combine(a, b)
    assert both.rule_of("ucs_MPa") == "threshold" and both.rule_of("bts_MPa") == "all"
    assert both.selected["ucs_MPa"] == a.selected["ucs_MPa"]
    assert set(both.selected["bts_MPa"]) == set(PARAM_NAMES)


def test_bad_rule_names_the_value():
    with pytest.raises(ValueError, match="rule='boruta'"):
        XGBScreening(rule="boruta")
    with pytest.raises(ValueError, match="shadow=True"):
        XGBScreening(rule="above_noise", shadow=False)
