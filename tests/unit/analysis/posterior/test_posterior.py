"""The posterior machinery against closed forms and known structure: the Gaussian process
against scikit-learn's, the sampled posterior of a linear-Gaussian problem against its
closed form, the identifiability text on a toy with a known null direction, the reach
test, the surrogates' choice, determinism."""
import numpy as np
import pandas as pd
import pytest

from bpmcal.analysis.posterior import (
    PosteriorSettings,
    Problem,
    fit_basis_gp,
    fit_posterior,
    fit_surrogate,
    identifiability,
)
from bpmcal.analysis.posterior.surrogate import inflation, response_data

NAMES = ("pb_emod_GPa", "pb_kratio", "pb_coh_MPa")
RANGES = {"pb_emod_GPa": (10.0, 50.0), "pb_kratio": (1.0, 5.0), "pb_coh_MPa": (10.0, 50.0)}
LO = np.array([10.0, 1.0, 10.0])
W = np.array([40.0, 4.0, 40.0])


def _basis(P):
    return np.column_stack([np.asarray(P[q], float) for q in NAMES])


def _runs(f, n=60, seed=0, noise=0.0, names=("y1", "y2", "y3")):
    """Design runs of the responses f(U) (U: unit coordinates) with Gaussian noise."""
    rng = np.random.default_rng(seed)
    U = rng.uniform(0, 1, (n, 3))
    Y = f(U) + noise * rng.standard_normal((n, len(names)))
    df = pd.DataFrame(LO + U * W, columns=NAMES)
    for j, r in enumerate(names):
        df[r] = Y[:, j]
    df["source"] = "design"
    return df


def test_gp_prediction_equals_scikit_learns_with_a_vague_constant_mean():
    """With an intercept-only basis the explicit-basis GP (vague prior on the mean) is the
    GP whose kernel adds a constant of large variance: scikit-learn's, same
    hyperparameters, gives the same mean and latent sd."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    rng = np.random.default_rng(3)
    X = rng.uniform(0, 1, (40, 2))
    y = np.sin(3 * X[:, 0]) + X[:, 1] ** 2 + 0.05 * rng.standard_normal(40)
    gp = fit_basis_gp(X, np.zeros((40, 0)), y, seed=1)
    big = 1e6
    k = (ConstantKernel(big, "fixed") + ConstantKernel(gp.amp ** 2, "fixed")
         * RBF(gp.ls, "fixed") + WhiteKernel(gp.noise ** 2, "fixed"))
    sk = GaussianProcessRegressor(k, alpha=1e-10, optimizer=None).fit(X, y)
    Xs = rng.uniform(-0.2, 1.2, (25, 2))
    m, s = gp.predict(Xs, np.zeros((25, 0)))
    ms, ss = sk.predict(Xs, return_std=True)
    assert np.allclose(m, ms, rtol=0, atol=1e-5 * np.ptp(y))
    latent = np.sqrt(np.maximum(ss ** 2 - gp.noise ** 2, 0))
    assert np.allclose(s, latent, rtol=2e-3, atol=1e-6)


def test_linear_gaussian_posterior_matches_its_closed_form_within_two_percent():
    """Exact linear responses y = a + B u (the stepwise surrogate reproduces them exactly,
    its own error ~ 0), lab values with known sd, a prior box far wider than the
    posterior: the posterior is Gaussian with mean the truth and covariance
    (J' S^-1 J)^-1; the sampled mean is within 2 % of a posterior sd of it and the
    sampled covariance within 2 % (Frobenius) of it."""
    B = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.5], [0.3, 0.0, 1.0]])
    a = np.array([0.1, -0.2, 0.3])

    def f(U):
        return a + U @ B.T

    runs = _runs(f)
    surr = {r: fit_surrogate(runs, r, NAMES, RANGES, _basis, choice="stepwise")
            for r in ("y1", "y2", "y3")}
    u0 = np.array([0.5, 0.4, 0.6])
    sd = np.array([0.02, 0.03, 0.025])
    targets = dict(zip(("y1", "y2", "y3"), f(u0[None])[0]))
    prob = Problem(NAMES, LO - 0.5 * W, LO + 1.5 * W, {}, RANGES)
    card = dict(zip(NAMES, LO + u0 * W))
    res = fit_posterior(surr, prob, targets, card, target_se=dict(zip(targets, sd)),
                        settings=PosteriorSettings(seed=4, ess_min=20000, max_steps=200000,
                                                  draws=10 ** 6))
    assert res.converged
    J = B / W
    C = np.linalg.inv(J.T @ np.diag(sd ** -2) @ J)
    X = res.draws[list(NAMES)].to_numpy()
    err = (X.mean(0) - (LO + u0 * W)) / np.sqrt(np.diag(C))
    assert np.all(np.abs(err) < 0.02), err
    Cs = np.cov(X.T)
    assert np.linalg.norm(Cs - C) / np.linalg.norm(C) < 0.02


def test_identifiability_names_the_null_direction_of_a_toy():
    """Two targets for three parameters: y1 depends on Ecp + kp* (unit coordinates) only,
    y2 on τcp only. The posterior is a ridge along u_E - u_k: the text says the targets
    leave the balance of Ecp against kp* free and pin τcp and the common level."""
    def f(U):
        return np.column_stack([U[:, 0] + U[:, 1], 2 * U[:, 2]])

    runs = _runs(f, names=("y1", "y2"))
    surr = {r: fit_surrogate(runs, r, NAMES, RANGES, _basis, choice="stepwise")
            for r in ("y1", "y2")}
    u0 = np.array([0.5, 0.5, 0.5])
    targets = dict(zip(("y1", "y2"), f(u0[None])[0]))
    prob = Problem(NAMES, LO, LO + W, {}, RANGES)
    res = fit_posterior(surr, prob, targets, dict(zip(NAMES, LO + u0 * W)),
                        target_se={"y1": 0.01, "y2": 0.01}, settings=PosteriorSettings(seed=2))
    dirs = res.identifiability["directions"]
    free = dirs[-1]
    assert free["class"] == "free"
    w = np.array([free["weights"][n] for n in NAMES])
    assert abs(abs(w[0]) - abs(w[1])) < 0.1 and np.sign(w[0]) != np.sign(w[1]) and abs(w[2]) < 0.1
    text = res.identifiability["sentence"]
    assert "balance of Ecp against kp*" in text or "balance of kp* against Ecp" in text
    assert "leave free" in text
    assert [d["class"] for d in dirs[:2]] == ["pinned", "pinned"]


def test_identifiability_of_an_isotropic_posterior_is_all_pinned_or_all_free():
    rng = np.random.default_rng(0)
    tight = identifiability(0.5 + 0.01 * rng.standard_normal((4000, 3)), NAMES, [0] * 3, [1] * 3)
    assert {d["class"] for d in tight["directions"]} == {"pinned"}
    loose = identifiability(rng.uniform(0, 1, (4000, 3)), NAMES, [0] * 3, [1] * 3)
    assert {d["class"] for d in loose["directions"]} == {"free"}


def _fit_linear(targets, sd, seed=0):
    B = np.eye(3)

    def f(U):
        return U @ B.T

    runs = _runs(f, seed=seed)
    surr = {r: fit_surrogate(runs, r, NAMES, RANGES, _basis, choice="stepwise")
            for r in ("y1", "y2", "y3")}
    prob = Problem(NAMES, LO, LO + W, {}, RANGES)
    card = dict(zip(NAMES, LO + 0.5 * W))
    return fit_posterior(surr, prob, targets, card, target_se=dict(zip(targets, sd)),
                         settings=PosteriorSettings(seed=seed))


def test_reach_test_separates_reachable_from_unreachable_targets():
    inside = _fit_linear({"y1": 0.3, "y2": 0.5, "y3": 0.7}, [0.02] * 3)
    assert inside.reach["reachable"] and inside.reach["p_reach"] > 0.5
    outside = _fit_linear({"y1": 1.3, "y2": 0.5, "y3": 0.7}, [0.02] * 3)  # y1 <= 1 in the box
    assert not outside.reach["reachable"] and outside.reach["p_reach"] < 1e-6
    assert "Out of reach" in outside.reach["text"]


def test_posterior_width_shrinks_with_the_lab_standard_errors_and_is_deterministic():
    t = {"y1": 0.3, "y2": 0.5, "y3": 0.7}
    wide = _fit_linear(t, [0.04] * 3)
    narrow = _fit_linear(t, [0.01] * 3)
    ww = wide.summary["hdi_width_pct_of_range"]
    wn = narrow.summary["hdi_width_pct_of_range"]
    assert np.all(wn < 0.5 * ww)
    again = _fit_linear(t, [0.04] * 3)
    assert np.array_equal(again.draws.to_numpy(), wide.draws.to_numpy())


def test_surrogate_choice_prefers_the_gp_on_a_curved_response_and_replicates_give_the_noise():
    """A response the basis (linear) cannot follow: the GP predicts held-out points
    better and is chosen; replicated points' pooled scatter is the noise."""
    rng = np.random.default_rng(5)

    def f(U):
        return np.column_stack([np.sin(4 * U[:, 0]) + U[:, 1], U[:, 2], U[:, 0]])

    runs = _runs(f, n=80, noise=0.01)
    rep = runs.iloc[:6].copy()  # replicate the first 6 points 3 times each
    reps = []
    for _ in range(3):
        r = rep.copy()
        r["y1"] = f((r[list(NAMES)].to_numpy() - LO) / W)[:, 0] + 0.01 * rng.standard_normal(6)
        r["source"] = "loop"
        reps.append(r)
    runs = pd.concat([runs, *reps], ignore_index=True)
    s = fit_surrogate(runs, "y1", NAMES, RANGES, _basis)
    assert s.kind == "gp"
    assert s.scores["gp"]["rmse"] < 0.5 * s.scores["stepwise"]["rmse"]
    d = response_data(runs, "y1", NAMES, RANGES, _basis)
    # a point is one parameter set of one source: the design run and its loop replicates
    # are two points (the loop's three replicates give 2 degrees of freedom each)
    g = runs.assign(_k=runs[list(NAMES)].round(12).astype(str).agg("|".join, axis=1)
                    + "|" + runs["source"])
    dev = g["y1"] - g.groupby("_k")["y1"].transform("mean")
    dof = (g.groupby("_k").size() - 1).sum()
    assert d.pure_dof == dof and np.isclose(d.pure_sd, np.sqrt((dev ** 2).sum() / dof))
    assert np.isclose(s.noise_sd, d.pure_sd)


def test_inflation_makes_overconfident_errors_honest():
    e = np.array([0.3, -0.25, 0.35, -0.3])
    sig2 = np.full(4, 0.01)  # predicted sd 0.1: errors 3 sd
    noise2 = np.full(4, 0.0001)
    c = inflation(e, sig2, noise2)
    assert c > 2.5
    assert np.isclose(np.mean(e ** 2 / (c * c * sig2 + noise2)), 1.0)
    assert inflation(0.01 * e, sig2, noise2) == 1.0


@pytest.mark.parametrize("bad", [{"surrogate": "neural"}, {"hdi_prob": 1.0},
                                 {"rhat_max": 1.0}, {"ess_min": 0}])
def test_settings_refuse_bad_values(bad):
    with pytest.raises(ValueError):
        PosteriorSettings(**bad)


def test_a_card_outside_its_prior_box_is_refused():
    t = {"y1": 0.3, "y2": 0.5, "y3": 0.7}
    runs = _runs(lambda U: U)
    surr = {r: fit_surrogate(runs, r, NAMES, RANGES, _basis, choice="stepwise") for r in t}
    prob = Problem(NAMES, LO, LO + W, {}, RANGES)
    card = dict(zip(NAMES, LO + np.array([0.5, 0.5, 1.5]) * W))
    with pytest.raises(ValueError, match="outside its prior box"):
        fit_posterior(surr, prob, t, card, target_se={r: 0.02 for r in t})


def test_runs_on_shared_packings_do_not_average_away_their_offsets():
    """Six closed-loop rounds at one point, each on the same five packings: their mean is
    one observation of f there whose variance is s² (ρ / 5 + (1 - ρ) / 30) (the five
    packings' offsets stay), so the latent variance there is 1 / (1 / V_d + 1 / V_loop)
    with V_d the design's alone: the shared-packing term gives exactly that; without it
    the rounds count as 30 independent runs (s² / 30)."""
    from bpmcal.analysis.posterior.gp import BasisGP, shared_packings

    rng = np.random.default_rng(5)
    Xd = rng.uniform(0, 1, (40, 2))
    yd = Xd[:, 0] + 0.3 * np.sin(4 * Xd[:, 1]) + 0.05 * rng.standard_normal(40)
    x0 = np.array([[0.4, 0.6]])
    X = np.vstack([Xd, np.repeat(x0, 6, axis=0)])
    y = np.concatenate([yd, 0.4 + 0.3 * np.sin(2.4) + 0.02 * rng.standard_normal(6)])
    k = np.concatenate([np.ones(40), np.full(6, 5.0)])
    labels = [[f"d{i}"] for i in range(40)] + [[f"s{j}" for j in range(5)]] * 6
    C = shared_packings(labels)
    hyp = dict(amp=0.3, ls=np.array([0.5, 0.4]), noise=0.05, h_mean=np.zeros(0),
               h_sd=np.ones(0))
    H = np.ones((len(y), 1))
    design = BasisGP(Xd, H[:40], yd, np.ones(40), **hyp)
    v_d = design.predict(x0, np.zeros((1, 0)))[1][0] ** 2
    for rho, C_ in ((0.8, C), (0.0, None)):
        m = BasisGP(X, H, y, k, **hyp, C=C_, rho=rho)
        v = m.predict(x0, np.zeros((1, 0)))[1][0] ** 2
        v_loop = 0.05 ** 2 * (rho / 5 + (1 - rho) / 30)
        assert np.isclose(v, 1 / (1 / v_d + 1 / v_loop), rtol=1e-6), (rho, v)


def test_the_packing_share_is_fitted_where_points_share_packings():
    """Loop rounds at several points on the same packings with offsets of 80 % of the
    scatter's variance: the fitted share lies near 0.8; a design alone has none."""
    rng = np.random.default_rng(9)

    def f(U):
        return np.column_stack([U[:, 0] + 0.5 * U[:, 1], U[:, 2], U[:, 0]])

    sd = 0.05
    runs = _runs(f, n=80, noise=sd, seed=4)
    runs["packing"] = [f"d{i}" for i in range(len(runs))]
    offsets = np.sqrt(0.8) * sd * rng.standard_normal(10)
    rows = []
    for r in range(12):
        u = rng.uniform(0.3, 0.7, 3)
        for s in range(10):
            y = f(u[None])[0, 0] + offsets[s] + np.sqrt(0.2) * sd * rng.standard_normal()
            rows.append({**dict(zip(NAMES, LO + u * W)), "y1": y, "source": "loop",
                         "packing": f"s{s}"})
    both = pd.concat([runs, pd.DataFrame(rows)], ignore_index=True)
    s = fit_surrogate(both, "y1", NAMES, RANGES, _basis, choice="gp")
    assert 0.55 < s.model.rho < 0.95
    assert fit_surrogate(runs, "y1", NAMES, RANGES, _basis, choice="gp").model.rho == 0.0


def test_an_hdi_the_prior_box_cuts_is_flagged_and_named_in_the_note():
    """y1 = u1 at its target 1.0 sits on the box's upper bound: the posterior of
    pb_emod_GPa piles against it and its HDI ends there (cut by the prior, not the data);
    the interior parameters' HDIs are not flagged, and the note names the bound and the
    range to widen."""
    res = _fit_linear({"y1": 1.0, "y2": 0.5, "y3": 0.5}, [0.05] * 3)
    cut = res.summary["hdi_cut_by_prior"]
    assert cut["pb_emod_GPa"] == "high"
    assert cut["pb_kratio"] == "" and cut["pb_coh_MPa"] == ""
    note = " ".join(res.notes)
    assert "upper bound 50" in note and "widen ranges.pb_emod_GPa" in note
    inside = _fit_linear({"y1": 0.5, "y2": 0.5, "y3": 0.5}, [0.05] * 3)
    assert not inside.summary["hdi_cut_by_prior"].astype(bool).any()
    assert not any("prior cuts" in n for n in inside.notes)


def test_hdi_at_bound_reads_each_end():
    from bpmcal.analysis.posterior.posterior import hdi_at_bound
    assert hdi_at_bound(0.0, 0.5, 0.0, 1.0) == "low"
    assert hdi_at_bound(0.3, 0.995, 0.0, 1.0) == "high"
    assert hdi_at_bound(0.001, 0.999, 0.0, 1.0) == "both"
    assert hdi_at_bound(0.02, 0.98, 0.0, 1.0) == ""
    assert hdi_at_bound(float("nan"), 0.5, 0.0, 1.0) == ""
