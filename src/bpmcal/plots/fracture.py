"""Figures of failure and fragmentation: crack counts vs bond-strength ratio (Fig. 4),
failure patterns (Fig. 5), impact energy and crack evolution (Fig. 7), t10 vs specific
energy with the JK fit."""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..lab.fragments import jk_model
from ..lab.impact import primary_burst
from .style import C_ALT, C_SHEAR, C_SIM, C_TENSION, COLUMN, DOUBLE, fig_note, figure


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
    if chosen.get("chosen_ratio") is not None:
        ax.axvline(chosen["chosen_ratio"], color=C_ALT, lw=0.8, ls=":")
        ax.text(chosen["chosen_ratio"], ax.get_ylim()[1], f" a = {chosen['chosen_ratio']:.1f}",
                color=C_ALT, va="top", fontsize=7)
    else:
        ax.set_title(f"no ratio chosen: {chosen.get('reason', '')}"[:80], fontsize=6)
    ext = sweep["extrapolated"].astype(bool)
    if ext.any():
        ax.plot(a[ext], sweep["cracks_total"][ext], "o", mfc="none", mec="0.5", ms=6,
                label="outside the sampled ranges")
    ax.legend(frameon=False, loc="upper left", fontsize=6)
    fig.tight_layout()
    return fig


def fig_failure_patterns(panels: dict):
    """Fig. 5: broken bonds of selected runs, seen from the side (x-z), coloured by mode;
    the intact specimen is hidden. ``panels``: title -> crack table (x, z, mode); no panels
    (no successful run): a note instead."""
    if not panels:

        return fig_note("Fig. 5 not available", "no run of the ratio sweep succeeded")
    fig, axes = figure(DOUBLE, 2.9, ncols=len(panels), sharey=True)
    axes = np.atleast_1d(axes)
    for ax, (title, cr) in zip(axes, panels.items()):
        for mode, c, lab in ((1, C_TENSION, "tensile"), (2, C_SHEAR, "shear")):
            if not len(cr):
                continue
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


#: stage markers of Fig. 7: summary key, label, meaning (see ``lab.impact.crack_stages``)
_STAGES = (("t_initiation_s", "I", "crack initiation"),
           ("t_peak_rate_s", "II", "peak crack rate"),
           ("t_through_s", "III", "through-failure"))


def _fracture_window(t: np.ndarray, n: np.ndarray) -> float:
    """End (s) of the zoomed time window of Fig. 7: 3x the time at which the crack count
    reaches 95 % of the primary fracture burst, clamped to the record.

    The primary burst (``lab.impact.primary_burst``) ends when the crack rate first drops
    below 1 % of its peak; its crack count is the reference instead of the final count,
    so a slow late phase (e.g. crushing of the fragment bed) does not stretch the window
    over the whole record. Without a late phase both references coincide."""

    t_end = float(t[-1]) if t.size else 0.0
    if t.size < 3 or n[-1] <= 0:
        return t_end
    n_ref = primary_burst(t, n)
    t95 = float(t[int(np.argmax(n >= 0.95 * n_ref))])
    return float(min(max(3.0 * t95, 10 * (t[1] - t[0])), t_end))


def fig_impact(series: pd.DataFrame, summary: dict):
    """Fig. 7: (a) input energy W_in, fracture-related energy G_f (energy released by bond
    breakage), rock kinetic energy and crack number, (b) fracture-energy utilisation
    efficiency eta_f(t) = G_f(t)/W_in(t), vs time, zoomed on the fracture burst (see
    ``_fracture_window``), with the stages I (initiation), II (peak crack rate) and III
    (through-failure) marked; stages beyond the window and the values at the end of the
    record are given in the annotation."""
    fig, (ax, axe) = figure(COLUMN, 4.4, nrows=2, sharex=True,
                            gridspec_kw={"height_ratios": [1.25, 1.0]})
    t_s = series["time"].to_numpy(float)
    w_in = series["W_in"].to_numpy(float)
    g_f = series["released"].to_numpy(float)
    n = (series["cracks_tension"] + series["cracks_shear"]).to_numpy(float)
    t_win = _fracture_window(t_s, n)
    t_end = float(t_s[-1]) if t_s.size else 0.0
    # plot the window plus one sample so the curves reach the right edge
    sel = np.zeros(t_s.size, bool)
    sel[: int(np.searchsorted(t_s, t_win, side="right")) + 1] = True
    t = t_s[sel] * 1e3

    # (a) energies and crack number
    ax.plot(t, w_in[sel], color="k", label=r"input energy $W_{in}$")
    ax.plot(t, g_f[sel], color=C_SIM, label=r"fracture-related energy $G_f$")
    ax.plot(t, series["kinetic"].to_numpy(float)[sel], color="0.6", lw=0.8,
            label="rock kinetic energy")
    ax.set_ylabel("energy (J)")
    ax.set_ylim(bottom=0)
    ax2 = ax.twinx()
    ax2.spines["right"].set_visible(True)
    ax2.plot(t, n[sel], color=C_SHEAR, lw=0.9, ls="--", label="number of cracks (right)")
    ax2.set_ylabel("number of cracks", color=C_SHEAR)
    ax2.tick_params(axis="y", colors=C_SHEAR)
    ax2.spines["right"].set_color(C_SHEAR)
    # keep the crack plateau below the W_in plateau so the two curves stay distinguishable
    ax2.set_ylim(0, 1.25 * max(np.nanmax(n[sel], initial=0), 1.0))
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, frameon=False, loc="center right", fontsize=6)

    # (b) fracture-energy utilisation efficiency, undefined while W_in ~ 0
    w_fin = float(summary.get("W_in_J", w_in[-1] if w_in.size else np.nan))
    g_fin = float(summary.get("G_f_J", g_f[-1] if g_f.size else np.nan))
    eta_fin = float(summary.get("eta_f", g_fin / w_fin if w_fin > 0 else np.nan))
    with np.errstate(divide="ignore", invalid="ignore"):
        eta = np.where(w_in >= 0.01 * w_fin, 100 * g_f / w_in, np.nan)
    axe.plot(t, eta[sel], color=C_SIM)
    axe.axhline(100 * eta_fin, color="0.5", ls=":", lw=0.7)
    axe.text(t_win * 1e3, 100 * eta_fin, rf"$\eta_f$ at $t_{{end}}$ = {100 * eta_fin:.1f} %",
             ha="right", va="bottom", fontsize=6, color="0.35")
    axe.set_ylabel(r"$\eta_f = G_f/W_{in}$ (%)")
    axe.set_xlabel("time t (ms)")
    axe.set_ylim(0, 1.15 * max(np.nanmax(eta[sel], initial=0), 100 * eta_fin, 1.0))
    axe.set_xlim(0, t_win * 1e3)

    # stages: vertical lines in both panels, labels staggered at the top of (a)
    outside = []
    k = 0
    for key, lab, what in _STAGES:
        v = summary.get(key)
        if v is None or not np.isfinite(v):
            continue
        if v > t_win:
            outside.append(f"{lab} ({what}) at {1e3 * v:.2f} ms")
            continue
        for a in (ax, axe):
            a.axvline(v * 1e3, color=C_ALT, ls=":", lw=0.8, zorder=0)
        # left of the line (the curves rise to the right of it), staggered downwards
        ax.annotate(lab, (v * 1e3, 0.98 - 0.09 * k), xycoords=ax.get_xaxis_transform(),
                    xytext=(-1.5, 0), textcoords="offset points", color=C_ALT, fontsize=7,
                    va="top", ha="right")
        k += 1

    # what the zoom leaves out: end of record and final values
    dn = n[-1] - n[sel][-1] if n.size else 0
    note = [f"record continues to $t_{{end}}$ = {1e3 * t_end:.1f} ms;",
            f"at $t_{{end}}$: $W_{{in}}$ = {w_fin:.2f} J, $G_f$ = {g_fin:.2f} J,",
            rf"$\eta_f$ = {100 * eta_fin:.1f} %, {n[-1]:.0f} cracks"]
    if dn > 0:
        note.append(f"(+{dn:.0f} cracks after the window)")
    note += outside
    stages = [f"{lab}: {what}" for key, lab, what in _STAGES
              if np.isfinite(summary.get(key, np.nan)) and summary[key] <= t_win]
    for k in range(0, len(stages), 2):  # two per line: a full line would reach the axis
        note.append(", ".join(stages[k:k + 2]) + ("," if k + 2 < len(stages) else ""))
    axe.text(0.98, 0.04, "\n".join(note), transform=axe.transAxes, ha="right", va="bottom",
             fontsize=6, linespacing=1.35)
    for a, lab in ((ax, "(a)"), (axe, "(b)")):
        a.text(-0.2, 1.0, lab, transform=a.transAxes, fontsize=8, va="top", ha="left")
    fig.tight_layout()
    fig.align_ylabels([ax, axe])
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
