"""Figures of failure and fragmentation: crack counts vs bond-strength ratio (Fig. 4),
failure patterns (Fig. 5), impact energy and crack evolution (Fig. 7), t10 vs specific
energy with the JK fit."""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..lab.fragments import jk_model
from .style import C_ALT, C_SHEAR, C_SIM, C_TENSION, COLUMN, DOUBLE, figure


def fig_ratio_cracks(sweep: pd.DataFrame, chosen: dict):
    """Fig. 4: crack numbers (tensile, shear, total) and proportions vs a = sigma_cp/tau_cp."""
    fig, ax = figure(COLUMN, 2.6)
    a = sweep["ratio"]
    ax.plot(a, sweep["cracks_total"], "k-o", label="total")
    ax.plot(a, sweep["cracks_tension"], "-s", color=C_TENSION, label="tensile")
    ax.plot(a, sweep["cracks_shear"], "-^", color=C_SHEAR, label="shear")
    ax.set_xlabel(r"bond strength ratio $a = \sigma_c^p/\tau_c^p$")
    ax.set_ylabel("number of cracks")
    ax2 = ax.twinx()
    ax2.plot(a, 100 * sweep["tensile_share"], "--", color=C_TENSION, lw=0.8)
    ax2.plot(a, 100 * sweep["shear_share"], "--", color=C_SHEAR, lw=0.8)
    ax2.set_ylabel("proportion of cracks (%) (dashed)")
    ax2.set_ylim(0, 100)
    ax2.spines["right"].set_visible(True)
    ax.axvline(chosen["chosen_ratio"], color=C_ALT, lw=0.8, ls=":")
    ax.text(chosen["chosen_ratio"], ax.get_ylim()[1], f" a = {chosen['chosen_ratio']:.1f}",
            color=C_ALT, va="top", fontsize=7)
    ext = sweep["extrapolated"].astype(bool)
    if ext.any():
        ax.plot(a[ext], sweep["cracks_total"][ext], "o", mfc="none", mec="0.5", ms=6,
                label="outside Table 2 range")
    ax.legend(frameon=False, loc="upper left", fontsize=6)
    fig.tight_layout()
    return fig


def fig_failure_patterns(panels: dict):
    """Fig. 5: broken bonds of selected runs, seen from the side (x-z), coloured by mode;
    the intact specimen is hidden. ``panels``: title -> crack table (x, z, mode)."""
    fig, axes = figure(DOUBLE, 2.9, ncols=len(panels), sharey=True)
    axes = np.atleast_1d(axes)
    for ax, (title, cr) in zip(axes, panels.items()):
        for mode, c, lab in ((1, C_TENSION, "tensile"), (2, C_SHEAR, "shear")):
            sel = cr["mode"] == mode
            ax.scatter(cr.loc[sel, "x"] * 1e3, cr.loc[sel, "z"] * 1e3, s=1.2, c=c,
                       linewidths=0, label=lab)
        ax.set_aspect("equal")
        ax.set_title(title)
        ax.set_xlabel("x (mm)")
    axes[0].set_ylabel("z (mm)")
    axes[0].legend(frameon=False, markerscale=4, loc="lower left", fontsize=6)
    fig.tight_layout()
    return fig


def fig_impact(series: pd.DataFrame, summary: dict):
    """Fig. 7: input energy, fracture-related energy, eta_f and crack numbers vs time, with
    the crack-initiation, peak-rate and through-failure times marked."""
    fig, ax = figure(COLUMN, 2.8)
    t = series["time"] * 1e3
    ax.plot(t, series["W_in"], color="k", label=r"$W_{in}$")
    ax.plot(t, series["released"], color=C_SIM, label=r"$G_f$")
    ax.plot(t, series["kinetic"], color="0.6", lw=0.8, label="rock kinetic")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("energy (J)")
    ax2 = ax.twinx()
    ax2.spines["right"].set_visible(True)
    ax2.plot(t, series["cracks_tension"] + series["cracks_shear"], color=C_SHEAR, lw=0.9,
             label="cracks")
    ax2.set_ylabel("number of cracks", color=C_SHEAR)
    for key, lab in (("t_initiation_s", "I"), ("t_peak_rate_s", "II"),
                     ("t_through_s", "III")):
        v = summary.get(key)
        if v is not None and np.isfinite(v):
            ax.axvline(v * 1e3, color=C_ALT, ls=":", lw=0.7)
            ax.text(v * 1e3, ax.get_ylim()[1], lab, color=C_ALT, fontsize=6, va="top")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, frameon=False, loc="center right", fontsize=6)
    ax.text(0.02, 0.97, rf"$\eta_f$ = {summary['eta_f'] * 100:.1f} %", transform=ax.transAxes,
            va="top", fontsize=7)
    fig.tight_layout()
    return fig


def fig_t10(table: pd.DataFrame, fit: dict | None):
    """t10 vs specific energy with the JK fit t10 = A (1 - exp(-b Ecs))."""
    fig, ax = figure(COLUMN, 2.5)
    ax.plot(table["ecs_kWh_t"], table["t10_pct"], "o", color=C_SIM)
    for r in table.itertuples():
        ax.annotate(f"{r.velocity:g} m/s", (r.ecs_kWh_t, r.t10_pct), fontsize=6,
                    xytext=(3, -8), textcoords="offset points")
    if fit:
        x = np.linspace(0, table["ecs_kWh_t"].max() * 1.1, 100)
        ax.plot(x, jk_model(x, fit["A"], fit["b"]), "k-", lw=0.8,
                label=f"A = {fit['A']:.1f} %, b = {fit['b']:.3g} t/kWh, A·b = {fit['Ab']:.1f}")
        ax.legend(frameon=False, fontsize=6, loc="lower right")
    ax.set_xlabel(r"specific energy $E_{cs}$ (kWh/t)")
    ax.set_ylabel(r"$t_{10}$ (%)")
    fig.tight_layout()
    return fig
