"""Figures of the calibration: screening importances, regression fit, stress-strain curves
of the calibrated specimens (Fig. 6)."""
from __future__ import annotations

import numpy as np
import pandas as pd

from .. import params as P
from .style import C_ALT, C_LAB, C_SIM, COLUMN, DOUBLE, figure


def _label(name):
    if name in P.ALL_PARAMS:
        return P.ALL_PARAMS[name].latex
    r = P.RESPONSES[name]
    return f"{r.latex} ({r.unit})" if r.unit else r.latex


def fig_importance(importance: pd.DataFrame, shadow: pd.DataFrame | None = None,
                   kind: str = "gain", threshold: float = 10.0):
    """Bar chart of the importance shares (%), one panel per response, fold-to-fold std as
    error bars; the largest shadow (permuted) share as a dashed noise line and the
    selection threshold as a dotted line. ``importance``: ``ScreeningResults.to_frame()``
    (index response, parameter; columns ``<kind>_mean``, ``<kind>_std``)."""
    resp = list(dict.fromkeys(importance.index.get_level_values("response")))
    fig, axes = figure(DOUBLE, 2.2, ncols=len(resp), sharey=True)
    axes = np.atleast_1d(axes)
    for ax, r in zip(axes, resp):
        sub = importance.xs(r, level="response")
        sub = sub.reindex([p for p in P.ALL_PARAMS if p in sub.index])  # the model's order
        y = np.arange(len(sub))
        ax.barh(y, sub[f"{kind}_mean"], xerr=sub[f"{kind}_std"], color=C_SIM, height=0.65,
                error_kw={"elinewidth": 0.6, "capsize": 1.5})
        ax.set_yticks(y, [P.ALL_PARAMS[p].latex for p in sub.index])
        ax.invert_yaxis()
        ax.axvline(threshold, color="k", ls=":", lw=0.7)
        if shadow is not None and r in shadow.index and kind in shadow.columns:
            ax.axvline(shadow.loc[r, kind], color=C_ALT, ls="--", lw=0.8)
        ax.set_xlabel(f"share of {kind} importance (%)")
        ax.set_title(P.RESPONSES[r].latex)
    axes[0].plot([], [], color=C_ALT, ls="--", label="largest shadow share")
    axes[0].plot([], [], color="k", ls=":", label="selection threshold")
    axes[0].legend(loc="lower right", frameon=False)
    fig.tight_layout()
    return fig


def fig_pred_vs_sim(df: pd.DataFrame, predicted: pd.DataFrame, fit_table: pd.DataFrame):
    """Predicted (final stepwise model) vs simulated response, one panel per response,
    with the 1:1 line and adjusted/cross-validated R^2."""
    resp = list(predicted.columns)
    fig, axes = figure(DOUBLE, 2.4, ncols=len(resp))
    axes = np.atleast_1d(axes)
    for ax, r in zip(axes, resp):
        y = df[r].to_numpy(float)
        yh = predicted[r].to_numpy(float)
        ax.plot(y, yh, "o", ms=2.5, color=C_SIM, alpha=0.7, mec="none")
        lo, hi = np.nanmin([y.min(), yh.min()]), np.nanmax([y.max(), yh.max()])
        ax.plot([lo, hi], [lo, hi], "k-", lw=0.6)
        row = fit_table.xs(r, level="response").iloc[-1]
        ax.text(0.04, 0.96, f"adj. $R^2$ = {row['adj_r2']:.3f}\nCV $R^2$ = {row['cv_r2_mean']:.3f}",
                transform=ax.transAxes, va="top", fontsize=7)
        ax.set_xlabel("simulated " + _label(r))
        ax.set_ylabel("predicted " + _label(r))
    fig.tight_layout()
    return fig


def fig_stress_strain(curves: dict, lab: pd.DataFrame):
    """Fig. 6: simulated stress-strain curves of the calibrated specimens, the lab peak
    strength (dashed) and the lab modulus (slope line through the origin) marked.
    ``curves``: specimen -> DataFrame with axial_strain, axial_stress (SI), or a text saying
    why the specimen has no simulated curve (e.g. its closed loop did not run): the panel
    then shows the lab values and that text."""
    fig, axes = figure(DOUBLE, 2.4, ncols=len(curves), sharey=True)
    axes = np.atleast_1d(axes)
    for ax, (spec, ser) in zip(axes, curves.items()):
        if isinstance(ser, str):  # the reason the closed loop did not run
            ax.text(0.5, 0.5, ser, transform=ax.transAxes, ha="center", va="center", wrap=True)
        elif "axial_strain" in ser:  # a failed run has no series
            eps = ser["axial_strain"].to_numpy() * 100
            sig = ser["axial_stress"].to_numpy() / 1e6
            ax.plot(eps, sig, color=C_SIM, label="simulated")
        else:
            ax.text(0.5, 0.5, "DEM run failed", ha="center", transform=ax.transAxes)
        row = lab.set_index("specimen").loc[spec]
        ax.axhline(row["ucs_MPa"], color=C_LAB, ls="--", lw=0.7, label=r"lab $\sigma_c$")
        e_lab = row["E_GPa"] * 1e3 / 100  # MPa per % strain
        x = np.linspace(0, row["ucs_MPa"] / e_lab, 20)
        ax.plot(x, e_lab * x, color=C_LAB, ls=":", lw=0.9, label=r"lab $E$")
        ax.set_xlabel(r"axial strain $\varepsilon_a$ (%)")
        ax.set_title(spec)
    axes[0].set_ylabel(r"axial stress $\sigma$ (MPa)")
    axes[0].legend(frameon=False, loc="lower right")
    fig.tight_layout()
    return fig


__all__ = ["fig_importance", "fig_pred_vs_sim", "fig_stress_strain", "COLUMN"]
