"""bpmcal.plots: each figure built from a small synthetic table draws what its docstring
says, read back from the matplotlib objects: one panel per response or specimen, the data
as given (in the figure's units), the reference lines at their values, the labels."""
import math

import matplotlib
import numpy as np
import pandas as pd
import pytest

from bpmcal import params as P
from bpmcal.analysis.envelopes import hoek_brown_sigma1
from bpmcal.lab.fragments import jk_model
from bpmcal.plots import calibration as C
from bpmcal.plots import envelopes as EN
from bpmcal.plots import fracture as FR
from bpmcal.plots.style import C_LAB, C_SIM, fig_note

PARAMS = ["porosity", "pb_emod_GPa", "pb_kratio", "pb_coh_MPa"]


@pytest.fixture(autouse=True)
def _close():
    yield
    matplotlib.pyplot.close("all")


def _line(ax, label):
    return next(ln for ln in ax.get_lines() if ln.get_label() == label)


def _vlines_x(ax):
    """x of every vertical line of ``ax`` (axvline: two equal x in data units)."""
    out = []
    for ln in ax.get_lines():
        x = np.asarray(ln.get_xdata(), float)
        if x.size == 2 and x[0] == x[1] and ln.get_transform() != ax.transData:
            out.append(float(x[0]))
    return out


# ------------------------------------------------------------------------ calibration
def test_importance_has_a_panel_per_response_the_shares_and_the_two_reference_lines():
    idx = pd.MultiIndex.from_product([["ucs_MPa", "E_GPa"], PARAMS],
                                     names=["response", "parameter"])
    shares = {"ucs_MPa": [40.0, 30.0, 20.0, 10.0], "E_GPa": [5.0, 80.0, 10.0, 5.0]}
    imp = pd.DataFrame({"gain_mean": shares["ucs_MPa"] + shares["E_GPa"],
                        "gain_std": [1.0] * 8}, index=idx)
    shadow = pd.DataFrame({"gain": [3.0, 4.5]}, index=["ucs_MPa", "E_GPa"])
    fig = C.fig_importance(imp, shadow, threshold=12.0)
    fig.canvas.draw()  # the tick labels exist once drawn
    axes = fig.axes
    assert [ax.get_title() for ax in axes] == [P.RESPONSES["ucs_MPa"].latex, P.RESPONSES["E_GPa"].latex]
    for ax, r in zip(axes, ("ucs_MPa", "E_GPa")):
        widths = [b.get_width() for b in ax.patches]
        order = [p for p in P.ALL_PARAMS if p in PARAMS]  # the model's order
        assert widths == [dict(zip(PARAMS, shares[r]))[p] for p in order]
        assert sorted(_vlines_x(ax)) == sorted([12.0, float(shadow.loc[r, "gain"])])
        assert ax.get_xlabel() == "share of gain importance (%)"
    order = [p for p in P.ALL_PARAMS if p in PARAMS]  # shared y: labelled on the first panel
    assert [t.get_text() for t in axes[0].get_yticklabels()] == [P.ALL_PARAMS[p].latex for p in order]
    labels = [t.get_text() for t in axes[0].get_legend().get_texts()]
    assert labels == ["largest shadow share", "selection threshold"]


def test_predicted_against_simulated_draws_the_points_the_one_to_one_line_and_the_r2():
    df = pd.DataFrame({"ucs_MPa": [10.0, 20.0, 30.0], "nu": [0.1, 0.2, 0.3]})
    pred = pd.DataFrame({"ucs_MPa": [11.0, 19.0, 31.0], "nu": [0.12, 0.21, 0.28]})
    fit = pd.DataFrame({"adj_r2": [0.5, 0.912, 0.7, 0.8765], "cv_r2_mean": [0.4, 0.875, 0.6, 0.7]},
                       index=pd.MultiIndex.from_tuples(
                           [("ucs_MPa", "main"), ("ucs_MPa", "interaction"), ("nu", "main"),
                            ("nu", "quadratic")], names=["response", "stage"]))
    fig = C.fig_pred_vs_sim(df, pred, fit)
    assert len(fig.axes) == 2
    for ax, r, adj, cv in zip(fig.axes, ("ucs_MPa", "nu"), (0.912, 0.8765), (0.875, 0.7)):
        pts, one = ax.get_lines()
        assert list(pts.get_xdata()) == list(df[r]) and list(pts.get_ydata()) == list(pred[r])
        lo, hi = min(df[r].min(), pred[r].min()), max(df[r].max(), pred[r].max())
        assert list(one.get_xdata()) == list(one.get_ydata()) == [lo, hi]  # the 1:1 line
        text = ax.texts[0].get_text()
        assert f"adj. $R^2$ = {adj:.3f}" in text and f"CV $R^2$ = {cv:.3f}" in text  # last stage
        assert ax.get_xlabel().startswith("simulated ") and ax.get_ylabel().startswith("predicted ")
    assert fig.axes[0].get_xlabel() == "simulated $\\sigma_c$ (MPa)"


def test_stress_strain_draws_the_curve_in_percent_and_mpa_and_the_lab_values():
    lab = pd.DataFrame({"specimen": ["B1", "B2", "B3"], "ucs_MPa": [60.0, 62.0, 64.0],
                        "E_GPa": [14.0, 13.0, 12.0], "nu": [0.25] * 3})
    eps = np.linspace(0.0, 0.006, 7)
    curves = {"B1": pd.DataFrame({"axial_strain": eps, "axial_stress": 1.2e10 * eps}),
              "B2": "the closed loop did not run: unreachable",
              "B3": pd.DataFrame({"summary": [1]})}  # a failed run: no series
    fig = C.fig_stress_strain(curves, lab)
    a1, a2, a3 = fig.axes
    sim = _line(a1, "simulated")
    assert np.allclose(sim.get_xdata(), 100 * eps) and np.allclose(sim.get_ydata(), 1.2e4 * eps)
    assert [t.get_text() for t in a2.texts] == ["the closed loop did not run: unreachable"]
    assert [t.get_text() for t in a3.texts] == ["DEM run failed"]
    for ax, row in zip(fig.axes, lab.itertuples()):
        assert ax.get_title() == row.specimen
        peak = _line(ax, r"lab $\sigma_c$")
        assert list(peak.get_ydata()) == [row.ucs_MPa] * 2
        slope = _line(ax, r"lab $E$")  # E in MPa per % strain, up to the lab peak
        x, y = np.asarray(slope.get_xdata()), np.asarray(slope.get_ydata())
        assert np.allclose(y[1:] / x[1:], row.E_GPa * 10) and y[-1] == pytest.approx(row.ucs_MPa)
    assert a1.get_ylabel() == r"axial stress $\sigma$ (MPa)"


# ------------------------------------------------------------------------ envelopes
def test_envelopes_draw_points_fits_failed_runs_and_lab_points_per_specimen():
    pts = pd.DataFrame({"specimen": ["B1"] * 4 + ["B2"] * 2, "card": "verified",
                        "sigma3_MPa": [0.0, 5.0, 10.0, 20.0, 0.0, 10.0],
                        "status": ["ok", "ok", "ok", "failed", "ok", "ok"],
                        "sigma1_MPa": [60.0, 80.0, 100.0, math.nan, 70.0, 110.0]})
    env = pd.DataFrame({"specimen": ["B1", "B2"], "card": "verified",
                        "mc_sigma_c_MPa": [60.0, 70.0], "mc_q": [4.0, 4.0],
                        "hb_sigma_ci_MPa": [58.0, math.nan], "mi": [12.0, math.nan]})
    lab = pd.DataFrame({"specimen": ["B1"], "sigma3_MPa": [15.0], "sigma1_MPa": [120.0]})
    fig = EN.fig_envelopes(pts, env, lab)
    b1, b2 = fig.axes
    assert [b1.get_title(), b2.get_title()] == ["B1", "B2"]
    ok = _line(b1, "DEM, verified card")
    assert list(ok.get_xdata()) == [0.0, 5.0, 10.0] and list(ok.get_ydata()) == [60.0, 80.0, 100.0]
    bad = _line(b1, "failed run (verified)")  # marked on the sigma3 axis
    assert list(bad.get_xdata()) == [20.0] and list(bad.get_ydata()) == [0.0]
    mc = _line(b1, "Mohr-Coulomb (verified)")
    x = np.asarray(mc.get_xdata())
    assert x[-1] == pytest.approx(20.0 * 1.05) and np.allclose(mc.get_ydata(), 60.0 + 4.0 * x)
    hb = _line(b1, "Hoek-Brown (verified)")
    assert np.allclose(hb.get_ydata(), hoek_brown_sigma1(x, 58.0, 12.0))
    lp = _line(b1, "lab")
    assert list(lp.get_xdata()) == [15.0] and list(lp.get_ydata()) == [120.0]
    assert lp.get_color() == C_LAB and ok.get_color() == C_SIM
    labels = {ln.get_label() for ln in b2.get_lines()}  # no Hoek-Brown fit: no curve, no lab
    assert "Hoek-Brown (verified)" not in labels and "lab" not in labels
    assert "Mohr-Coulomb (verified)" in labels
    assert b1.get_xlabel() == r"confining stress $\sigma_3$ (MPa)"
    assert b1.get_ylabel() == r"axial stress at peak $\sigma_1$ (MPa)"


# ------------------------------------------------------------------------ fracture
def _sweep(extrapolated):
    a = np.array([0.5, 1.0, 1.5, 2.0])
    nt, ns = np.array([10.0, 40.0, 70.0, 90.0]), np.array([90.0, 60.0, 30.0, 10.0])
    return pd.DataFrame({"ratio": a, "cracks_tension": nt, "cracks_shear": ns,
                         "cracks_total": nt + ns, "tensile_share": nt / (nt + ns),
                         "shear_share": ns / (nt + ns), "extrapolated": extrapolated})


def test_ratio_cracks_draws_counts_and_shares_and_marks_the_chosen_ratio():
    sw = _sweep([False, False, False, True])
    fig = FR.fig_ratio_cracks(sw, {"chosen_ratio": 1.5})
    ax, ax2 = fig.axes
    for label, col in (("total", "cracks_total"), ("tensile", "cracks_tension"),
                       ("shear", "cracks_shear")):
        ln = _line(ax, label)
        assert list(ln.get_xdata()) == list(sw["ratio"]) and list(ln.get_ydata()) == list(sw[col])
    shares = [list(ln.get_ydata()) for ln in ax2.get_lines()]
    assert shares == [list(100 * sw["tensile_share"]), list(100 * sw["shear_share"])]
    assert ax2.get_ylim() == (0, 100)
    assert _vlines_x(ax) == [1.5] and any("a = 1.5" in t.get_text() for t in ax.texts)
    out = _line(ax, "outside the sampled ranges")
    assert list(out.get_xdata()) == [2.0]
    fig = FR.fig_ratio_cracks(_sweep([False] * 4), {"chosen_ratio": None, "reason": "no target"})
    assert fig.axes[0].get_title() == "no ratio chosen: no target"
    assert "outside the sampled ranges" not in {ln.get_label() for ln in fig.axes[0].get_lines()}


def test_failure_patterns_plot_the_cracks_by_mode_in_mm_or_say_why_not():
    cr = pd.DataFrame({"x": [1e-3, 2e-3, 3e-3], "z": [4e-3, 5e-3, 6e-3], "mode": [1, 2, 1]})
    fig = FR.fig_failure_patterns({"a = 1.0": cr, "a = 2.0": cr.iloc[:0]})
    ax, empty = fig.axes
    tens, shear = ax.collections
    assert np.allclose(tens.get_offsets(), [[1.0, 4.0], [3.0, 6.0]])
    assert np.allclose(shear.get_offsets(), [[2.0, 5.0]])
    assert ax.get_title() == "a = 1.0" and ax.get_xlabel() == "x (mm)" and ax.get_ylabel() == "z (mm)"
    assert not empty.collections
    note = FR.fig_failure_patterns({})
    assert note.axes[0].get_title() == "Fig. 5 not available"
    assert "no run of the ratio sweep succeeded" in note.axes[0].texts[0].get_text()


def _impact_series():
    """A drop-hammer record: W_in ramps to 10 J over 2 ms, cracks burst around 1 ms (a
    logistic) to 400, the released energy follows the cracks (1 mJ per crack)."""
    t = np.linspace(0.0, 8e-3, 801)
    n = np.round(400 / (1 + np.exp(-(t - 1e-3) / 1e-4)))
    w_in = 10.0 * np.minimum(t / 2e-3, 1.0)
    return pd.DataFrame({"time": t, "W_in": w_in, "released": 1e-3 * n,
                         "kinetic": 0.1 * w_in, "cracks_tension": n - n // 4,
                         "cracks_shear": n // 4})


def test_the_impact_window_ends_at_three_times_the_primary_burst_s_95_percent_time():
    s = _impact_series()
    t = s["time"].to_numpy()
    n = (s["cracks_tension"] + s["cracks_shear"]).to_numpy(float)
    t95 = t[int(np.argmax(n >= 0.95 * FR.primary_burst(t, n)))]
    assert FR._fracture_window(t, n) == pytest.approx(3 * t95)
    assert 1.0e-3 < t95 < 1.5e-3  # the logistic's 95 % lies 3 of its widths past 1 ms
    assert FR._fracture_window(t, np.zeros_like(n)) == t[-1]  # no crack: the whole record


def test_impact_draws_the_energies_eta_f_and_the_stages_within_its_window():
    s = _impact_series()
    summary = {"W_in_J": 10.0, "G_f_J": 0.4, "eta_f": 0.04, "t_initiation_s": 0.6e-3,
               "t_peak_rate_s": 1.0e-3, "t_through_s": 7.0e-3}
    fig = FR.fig_impact(s, summary)
    ax, axe, ax2 = fig.axes  # (a), (b), the crack axis of (a)
    n = (s["cracks_tension"] + s["cracks_shear"]).to_numpy(float)
    t_win = FR._fracture_window(s["time"].to_numpy(), n)
    w = _line(ax, r"input energy $W_{in}$")
    x = np.asarray(w.get_xdata())
    assert x[0] == 0.0 and x[-2] <= 1e3 * t_win <= x[-1]  # ms, the window plus one sample
    k = len(x)
    assert np.allclose(w.get_ydata(), s["W_in"][:k])
    assert np.allclose(_line(ax, r"fracture-related energy $G_f$").get_ydata(), s["released"][:k])
    assert np.allclose(ax2.get_lines()[0].get_ydata(), n[:k])
    eta = np.asarray(axe.get_lines()[0].get_ydata())
    ok = s["W_in"][:k] >= 0.01 * 10.0
    assert np.allclose(eta[ok], 100 * s["released"][:k][ok] / s["W_in"][:k][ok])
    assert np.isnan(eta[~ok]).all()  # undefined while W_in ~ 0
    assert axe.get_xlim() == pytest.approx((0, 1e3 * t_win))
    # stages I and II inside the window (lines in both panels), III after it (in the note)
    assert sorted(_vlines_x(ax)) == pytest.approx([0.6, 1.0])
    assert [a.get_text() for a in ax.texts if a.get_text() in ("I", "II", "III")] == ["I", "II"]
    note = next(a.get_text() for a in axe.texts if "record continues" in a.get_text())
    assert "III (through-failure) at 7.00 ms" in note and r"$\eta_f$ = 4.0 %" in note
    assert axe.get_ylabel() == r"$\eta_f = G_f/W_{in}$ (%)" and axe.get_xlabel() == "time t (ms)"


def test_t10_draws_the_points_and_the_jk_fit():
    table = pd.DataFrame({"velocity": [2.0, 6.0, 10.0], "ecs_kWh_t": [0.1, 0.5, 1.2],
                          "t10_pct": [5.0, 18.0, 30.0]})
    fit = {"A": 40.0, "b": 1.3, "Ab": 52.0}
    fig = FR.fig_t10(table, fit)
    ax = fig.axes[0]
    pts, curve = ax.get_lines()
    assert list(pts.get_xdata()) == [0.1, 0.5, 1.2] and list(pts.get_ydata()) == [5.0, 18.0, 30.0]
    x = np.asarray(curve.get_xdata())
    assert x[-1] == pytest.approx(1.32) and np.allclose(curve.get_ydata(), jk_model(x, 40.0, 1.3))
    assert curve.get_label() == "A = 40.0 %, b = 1.3 t/kWh, A·b = 52.0"
    assert [a.get_text() for a in ax.texts] == ["2 m/s", "6 m/s", "10 m/s"]
    assert len(FR.fig_t10(table, None).axes[0].get_lines()) == 1  # no fit: the points only


def test_a_note_figure_says_why_the_real_one_is_missing():
    fig = fig_note("Fig. 7 not available", "the impact run failed: " + "x " * 40)
    ax = fig.axes[0]
    assert ax.get_title() == "Fig. 7 not available" and not ax.axison
    lines = ax.texts[0].get_text().split("\n")
    assert lines[0].startswith("the impact run failed") and max(map(len, lines)) <= 60
