"""Stepwise regression against planted models and independent computations."""
import json

import numpy as np
import pytest
import statsmodels.api as sm
from scipy import stats
from statsmodels.stats.outliers_influence import variance_inflation_factor

from bpmcal.analysis.stepwise import (
    RegressionModel,
    StepwiseRegression,
    StepwiseResults,
    design_matrix,
    fit_terms,
    term_name,
    vif,
)
from bpmcal.params import ParameterError

A, B = "pb_coh_MPa", "pb_ten_MPa"  # the planted variables (10-50 MPa)
NOISE = ("pb_kratio", "porosity")  # candidates without effect
TRUTH = {(A,): 2.0, (B,): 1.5, (A, A): -0.07, (A, B): 0.05}
INTERCEPT = 10.0


@pytest.fixture(scope="module")
def planted(design):
    """y = 10 + 2 a + 1.5 b - 0.07 a² + 0.05 a·b + N(0, 2²); 3 failed rows."""
    df = design(150, seed=11)
    rng = np.random.default_rng(12)
    a, b = df[A], df[B]
    df["ucs_MPa"] = INTERCEPT + 2 * a + 1.5 * b - 0.07 * a**2 + 0.05 * a * b + rng.normal(0, 2.0, len(df))
    df["E_GPa"] = 1.3 * df["pb_emod_GPa"] + rng.normal(0, 0.5, len(df))
    df.loc[[0, 1, 2], "status"] = "failed"
    df.loc[[0, 1, 2], "ucs_MPa"] = -999.0  # garbage that must not be used
    return df


@pytest.fixture(scope="module")
def result(planted):
    cands = {"ucs_MPa": (A, B) + NOISE, "E_GPa": ("pb_emod_GPa",)}
    return StepwiseRegression(cv_repeats=3).fit(planted, cands)


def test_recovers_planted_terms_and_drops_noise(result):
    stages = result.models["ucs_MPa"]
    assert set(stages["main"].terms) == {(A,), (B,)}
    assert set(stages["quadratic"].terms) == {(A,), (B,), (A, A)}
    assert set(stages["interaction"].terms) == set(TRUTH)
    assert result.final_models["E_GPa"].terms == (("pb_emod_GPa",),)
    adj = [m.adj_r2 for m in stages.values()]
    assert adj[0] < adj[1] < adj[2]
    assert result.rows["n_dropped"] == 3 and result.final_models["ucs_MPa"].n_obs == 147


def test_coefficients_within_confidence_intervals(result):
    tab = result.final_models["ucs_MPa"].table
    for term, true in TRUTH.items():
        name = term_name(term)
        assert tab.loc[name, "ci_low"] < true < tab.loc[name, "ci_high"], name
    assert tab.loc["Intercept", "ci_low"] < INTERCEPT < tab.loc["Intercept", "ci_high"]


def test_ols_statistics_match_independent_computation(result, planted):
    m = result.final_models["ucs_MPa"]
    ok = planted[planted["status"] == "ok"]
    cols = [np.prod([ok[f].to_numpy() for f in t], axis=0) for t in m.terms]
    X = np.column_stack([np.ones(len(ok))] + cols)
    y = ok["ucs_MPa"].to_numpy()
    beta = np.linalg.solve(X.T @ X, X.T @ y)
    resid = y - X @ beta
    dof = len(y) - X.shape[1]
    se = np.sqrt(resid @ resid / dof * np.diag(np.linalg.inv(X.T @ X)))
    half = stats.t.ppf(0.975, dof) * se
    np.testing.assert_allclose(m.table["coef"], beta, rtol=1e-8)
    np.testing.assert_allclose(m.table["std_err"], se, rtol=1e-8)
    np.testing.assert_allclose(m.table["ci_high"] - m.table["coef"], half, rtol=1e-8)
    r2 = 1 - resid @ resid / np.sum((y - y.mean()) ** 2)
    np.testing.assert_allclose(m.r2, r2, rtol=1e-10)
    np.testing.assert_allclose(m.adj_r2, 1 - (1 - r2) * (len(y) - 1) / dof, rtol=1e-10)
    assert 0.9 * m.r2 < m.cv_r2_mean < m.r2


def test_vif_is_on_centred_terms(planted):
    terms = [(A,), (B,), (A, A), (A, B)]
    Z = design_matrix(planted, terms, center={A: planted[A].mean(), B: planted[B].mean()})
    Zc = sm.add_constant(Z)
    expected = [variance_inflation_factor(Zc, j) for j in range(1, Zc.shape[1])]
    np.testing.assert_allclose(vif(planted, terms), expected, rtol=1e-8)
    assert max(expected) < 2  # centred: nearly orthogonal
    raw = sm.add_constant(design_matrix(planted, terms))
    assert variance_inflation_factor(raw, 1) > 10  # uncentred a vs a²: spuriously collinear


def test_collinear_candidate_is_blocked_by_vif(design):
    df = design(120, seed=21)
    rng = np.random.default_rng(22)
    df[B] = df[A] + rng.normal(0, 2.0, len(df))  # VIF(a, b) ≈ 35
    df["ucs_MPa"] = -3 * df[A] + 5 * df[B] + rng.normal(0, 1.0, len(df))
    strict = StepwiseRegression(stages=("main",), cv_folds=0).fit(df, {"ucs_MPa": (A, B)})
    assert len(strict.final_models["ucs_MPa"].terms) == 1
    assert (strict.steps["action"] == "blocked").any()
    loose = StepwiseRegression(stages=("main",), cv_folds=0, vif_max=100).fit(df, {"ucs_MPa": (A, B)})
    assert set(loose.final_models["ucs_MPa"].terms) == {(A,), (B,)}


def test_hierarchy_policy(design):
    """y = 0.05 a²: the raw slope of a is 0 once a² is in. Strong heredity keeps a (parent of
    a²) whatever its p-value; without heredity it is removed."""
    df = design(150, seed=31)
    rng = np.random.default_rng(32)
    df["ucs_MPa"] = 0.05 * df[A] ** 2 + rng.normal(0, 1.0, len(df))
    kw = dict(stages=("main", "quadratic"), cv_folds=0)
    strong = StepwiseRegression(hierarchy="strong", **kw).fit(df, {"ucs_MPa": (A,)})
    free = StepwiseRegression(hierarchy="none", **kw).fit(df, {"ucs_MPa": (A,)})
    assert strong.final_models["ucs_MPa"].terms == ((A,), (A, A))
    assert strong.final_models["ucs_MPa"].table.loc[A, "p_value"] > 0.05
    assert free.final_models["ucs_MPa"].terms == ((A, A),)
    assert (free.steps["action"] == "remove").any()
    assert strong.settings["hierarchy"] == "strong"


def test_pure_interaction_needs_no_heredity(design):
    """y = 0.05 (a-30)(b-30): no marginal main effects, so heredity blocks a·b."""
    df = design(150, seed=41)
    rng = np.random.default_rng(42)
    df["ucs_MPa"] = 0.05 * (df[A] - 30) * (df[B] - 30) + rng.normal(0, 1.0, len(df))
    for policy, expect in (("strong", False), ("weak", False), ("none", True)):
        res = StepwiseRegression(hierarchy=policy, cv_folds=0).fit(df, {"ucs_MPa": (A, B)})
        assert ((A, B) in res.final_models["ucs_MPa"].terms) is expect, policy


def test_partial_derivatives_match_finite_differences(result, planted):
    m = result.final_models["ucs_MPa"]
    rows = planted.iloc[10:15]
    grad = m.gradient(rows)
    for p in (A, B):
        h = 1e-4
        up, dn = rows.copy(), rows.copy()
        up[p] += h
        dn[p] -= h
        np.testing.assert_allclose(grad[p], (m.predict(up) - m.predict(dn)) / (2 * h), rtol=1e-6)
    point = {A: 20.0, B: 30.0}
    g = m.gradient(point)
    c = dict(zip(m.terms, m.coef))
    np.testing.assert_allclose(g[A], c[(A,)] + 2 * c[(A, A)] * 20 + c[(A, B)] * 30)
    assert isinstance(m.predict(point), float)


def test_equation_reads_like_the_paper():
    m = RegressionModel("ucs_MPa", [("pb_coh_MPa",), ("pb_ten_MPa",), ("porosity",), ("pb_kratio",)],
                        [2.20, 1.51, -428.14, -11.53], 115.54)
    assert m.equation() == ("ucs_MPa = 2.20·pb_coh_MPa + 1.51·pb_ten_MPa − 428.14·porosity "
                            "− 11.53·pb_kratio + 115.54")
    assert m.equation(symbols=True) == "σc = 2.20·τcp + 1.51·σcp − 428.14·n − 11.53·kp* + 115.54"
    nu = RegressionModel("nu", [("pb_kratio",), ("pb_kratio", "pb_kratio")], [0.118, -0.013], 0.002)
    assert nu.equation(symbols=True) == "ν = 0.118·kp* − 0.013·kp*² + 0.002"
    assert nu.equation(ascii=True) == "nu = 0.118*pb_kratio - 0.013*pb_kratio^2 + 0.002"


def test_table4_and_long_table(result):
    t4 = result.table4_terms(symbols=True)
    assert t4.loc["σc", "Interaction term"] == "τcp·σcp"
    assert t4.loc["σc", "Quadratic term"] == "τcp²"
    assert t4.loc["E", "Interaction term"] == "-" and t4.loc["E", "Quadratic term"] == "-"
    cand = result.table4_terms("candidates")
    assert cand.loc["ucs_MPa", "Interaction term"].count("·") == 6  # 4 candidates -> 6 pairs
    assert cand.loc["E_GPa", "Quadratic term"] == "pb_emod_GPa²"
    long = result.to_frame()
    final = long[(long["response"] == "ucs_MPa") & (long["stage"] == "interaction")]
    assert list(final["term"]) == ["Intercept", A, B, f"{A}*{B}", f"{A}^2"]


def test_json_round_trip(result, planted):
    back = StepwiseResults.from_dict(json.loads(json.dumps(result.to_dict())))
    for r, m in result.final_models.items():
        m2 = back.final_models[r]
        np.testing.assert_allclose(m2.predict(planted), m.predict(planted), rtol=1e-12)
        assert m2.equation() == m.equation() and m2.summary() == m.summary()
        np.testing.assert_allclose(m2.table.to_numpy(float), m.table.to_numpy(float), rtol=1e-12)
    assert back.rows == result.rows and back.settings == result.settings


def test_fit_terms_accepts_names_and_rejects_unknown(planted):
    ok = planted[planted["status"] == "ok"]
    m = fit_terms(ok, "ucs_MPa", [A, f"{A}^2", f"{A}*{B}", B], cv_folds=0)
    assert m.terms == ((A,), (A, A), (A, B), (B,))
    with pytest.raises(ParameterError, match="pb_coh"):
        fit_terms(ok, "ucs_MPa", ["pb_coh"])
    with pytest.raises(ParameterError, match="'tau'"):
        StepwiseRegression().fit(planted, {"ucs_MPa": ("tau",)})
    with pytest.raises(ValueError, match="alpha_out=0.01"):
        StepwiseRegression(alpha_out=0.01)


def test_a_models_summary_holds_no_wall_clock_time():
    """The statsmodels summary stamps the date and time of the fit; a model file keeps
    the summary without them, so a rerun on the same data writes the same bytes."""
    import pandas as pd

    rng = np.random.default_rng(1)
    df = pd.DataFrame({"pb_ten_MPa": rng.uniform(10, 50, 30)})
    df["ucs_MPa"] = 2.0 * df["pb_ten_MPa"] + rng.normal(0, 1, 30)
    df["status"] = "ok"
    text = fit_terms(df, "ucs_MPa", ["pb_ten_MPa"]).summary_text
    date = next(ln for ln in text.splitlines() if ln.startswith("Date:"))
    time_ = next(ln for ln in text.splitlines() if ln.startswith("Time:"))
    assert not any(ch.isdigit() for ch in date.split("Prob")[0] + time_.split("Log")[0])
    assert "R-squared" in text and "pb_ten_MPa" in text  # the rest of the summary is kept
