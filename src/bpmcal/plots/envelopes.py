"""The triaxial envelope figure: sigma1 against sigma3 per lab specimen, the DEM points of
each card (failed runs marked on the sigma3 axis), the fitted Mohr-Coulomb line and
Hoek-Brown curve, and the lab points when given."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..analysis.envelopes import hoek_brown_sigma1
from .style import C_ALT, C_LAB, C_SIM, DOUBLE, figure

_COLOURS = {"verified": C_SIM, "calibrated": C_ALT}
_MARKERS = {"verified": "o", "calibrated": "s"}


def _finite(*v) -> bool:
    try:
        return all(math.isfinite(float(x)) for x in v)
    except (TypeError, ValueError):
        return False


def fig_envelopes(points: pd.DataFrame, env: pd.DataFrame, lab: pd.DataFrame | None = None):
    """One panel per specimen. ``points``: one row per run (specimen, card, sigma3_MPa,
    status, sigma1_MPa); ``env``: one row per card (specimen, card, mc_sigma_c_MPa, mc_q,
    hb_sigma_ci_MPa, mi); ``lab``: specimen, sigma3_MPa, sigma1_MPa."""
    specs = list(dict.fromkeys(points["specimen"]))
    fig, axes = figure(DOUBLE, 2.6, ncols=max(1, len(specs)), sharey=False)
    axes = np.atleast_1d(axes)
    top = max([float(points["sigma3_MPa"].max())]
              + ([float(lab["sigma3_MPa"].max())] if lab is not None and len(lab) else []))
    x = np.linspace(0.0, max(top, 1.0) * 1.05, 60)
    for ax, spec in zip(axes, specs):
        for card, pts in points[points["specimen"] == spec].groupby("card", sort=False):
            col, mk = _COLOURS.get(card, "k"), _MARKERS.get(card, "^")
            ok = pts[pts["status"] == "ok"]
            ax.plot(ok["sigma3_MPa"], ok["sigma1_MPa"], mk, color=col, ms=4, clip_on=False,
                    label=f"DEM, {card} card")
            bad = pts[pts["status"] != "ok"]
            if len(bad):
                ax.plot(bad["sigma3_MPa"], np.zeros(len(bad)), "x", color=col, ms=6,
                        clip_on=False, label=f"failed run ({card})")
            e = env[(env["specimen"] == spec) & (env["card"] == card)]
            if len(e):
                e = e.iloc[0]
                if _finite(e["mc_sigma_c_MPa"], e["mc_q"]):
                    ax.plot(x, e["mc_sigma_c_MPa"] + e["mc_q"] * x, "-", color=col, lw=0.9,
                            label=f"Mohr-Coulomb ({card})")
                if _finite(e["hb_sigma_ci_MPa"], e["mi"]):
                    ax.plot(x, hoek_brown_sigma1(x, e["hb_sigma_ci_MPa"], e["mi"]), "--",
                            color=col, lw=0.9, label=f"Hoek-Brown ({card})")
        if lab is not None and len(lab):
            lp = lab[lab["specimen"] == spec]
            if len(lp):
                ax.plot(lp["sigma3_MPa"], lp["sigma1_MPa"], "D", mfc="none", color=C_LAB, clip_on=False,
                        ms=5, label="lab")
        ax.set_xlabel(r"confining stress $\sigma_3$ (MPa)")
        ax.set_title(spec)
        ax.set_xlim(0, x[-1])
        ax.set_ylim(bottom=0)
    axes[0].set_ylabel(r"axial stress at peak $\sigma_1$ (MPa)")
    axes[0].legend(frameon=False, loc="upper left", fontsize="x-small")
    fig.tight_layout()
    return fig


__all__ = ["fig_envelopes"]
