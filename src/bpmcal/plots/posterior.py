"""Figures of a card's posterior: the pair plot of its draws (:func:`fig_pairs`) and the
learning curve, its width against the DEM runs near the card (:func:`fig_learning`)."""
from __future__ import annotations

import numpy as np
import pandas as pd

from .. import params as P
from .style import C_ALT, C_LAB, C_SIM, COLUMN, DOUBLE, figure


def _label(name: str) -> str:
    p = P.ALL_PARAMS.get(name)
    if p is None:
        return name
    return f"{p.latex} ({p.unit})" if p.unit else p.latex


def _limits(x, card: float, lo: float, hi: float) -> tuple[float, float]:
    """Axis limits that hold the draws' central 99 % and the card, padded by a fifth of
    that span, inside the prior box [lo, hi]."""
    a = min(float(np.quantile(x, 0.005)), card)
    b = max(float(np.quantile(x, 0.995)), card)
    pad = 0.2 * (b - a) if b > a else 0.05 * (hi - lo)
    return max(lo, a - pad), min(hi, b + pad)


def fig_pairs(res, max_points: int = 2000):
    """Pair plot of a :class:`~bpmcal.analysis.posterior.PosteriorResults`: each free
    parameter's marginal histogram with its highest-density interval (shaded) on the
    diagonal, the draws of every pair below it, the card marked (a cross and a line); the
    axes span the draws and the card (:func:`_limits`), inside the prior box."""
    prob = res.problem
    names = list(prob.free)
    d = len(names)
    X = res.draws[names].to_numpy(float)
    if len(X) > max_points:
        X = X[np.linspace(0, len(X) - 1, max_points).astype(int)]
    card = [res.card[p] for p in names]
    lims = [_limits(X[:, j], card[j], prob.lo[j], prob.hi[j]) for j in range(d)]
    size = DOUBLE if d > 2 else COLUMN
    fig, axes = figure(size, size * (0.9 if d > 1 else 0.6), nrows=d, ncols=d, squeeze=False)
    s = res.summary
    for i in range(d):
        for j in range(d):
            ax = axes[i, j]
            if j > i:
                ax.set_axis_off()
                continue
            if i == j:
                ax.hist(X[:, i], bins=40, color=C_SIM, alpha=0.8, range=lims[i])
                ax.axvspan(s.loc[names[i], "hdi_low"], s.loc[names[i], "hdi_high"],
                           color=C_SIM, alpha=0.15, lw=0)
                ax.axvline(card[i], color=C_ALT, lw=1.0)
                ax.set_yticks([])
                ax.set_xlim(*lims[i])
            else:
                ax.plot(X[:, j], X[:, i], ".", ms=1.0, color=C_SIM, alpha=0.35, rasterized=True)
                ax.plot(card[j], card[i], "x", color=C_ALT, ms=5, mew=1.2)
                ax.set_xlim(*lims[j])
                ax.set_ylim(*lims[i])
            if i == d - 1:
                ax.set_xlabel(_label(names[j]))
            else:
                ax.set_xticklabels([])
            if j == 0 and i > 0:
                ax.set_ylabel(_label(names[i]))
            elif j > 0 or i == 0:
                if i != j:
                    ax.set_yticklabels([])
    fig.suptitle(f"posterior ({100 * res.settings.hdi_prob:.0f} % HDI shaded; card: cross)",
                 fontsize=8)
    fig.tight_layout()
    return fig


def fig_learning(curve: pd.DataFrame):
    """The learning curve: the posterior's width (mean 90 % HDI width, % of the design
    range) against the DEM runs near the card, one point per data set."""
    fig, ax = figure(COLUMN, 2.4)
    x = curve["dem_runs_near_card"].to_numpy(float)
    y = curve["width_pct_of_range"].to_numpy(float)
    ax.plot(x, y, "o-", color=C_SIM)
    for xi, yi, lab in zip(x, y, curve["data"]):
        ax.annotate(str(lab), (xi, yi), fontsize=5, xytext=(3, 3), textcoords="offset points",
                    color=C_LAB)
    ax.set_xlabel("DEM runs near the card (beside the design)")
    ax.set_ylabel("posterior width (% of range)")
    ax.set_ylim(bottom=0)
    fig.tight_layout()
    return fig
