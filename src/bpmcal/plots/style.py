"""One figure style for every plot: readable at journal column width (3.5 in), symbols and
units as in the paper. Functions in this package return matplotlib Figures and write no
file; the stages save them (``bpmcal.io.figures.save_figure``: PNG and PDF)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLUMN = 3.5  # in, single column
DOUBLE = 7.2  # in, double column

RC = {
    "font.size": 8,
    "axes.labelsize": 8,
    "axes.titlesize": 8,
    "legend.fontsize": 7,
    "xtick.labelsize": 7,
    "ytick.labelsize": 7,
    "lines.linewidth": 1.0,
    "lines.markersize": 3.5,
    "axes.linewidth": 0.6,
    "xtick.major.width": 0.6,
    "ytick.major.width": 0.6,
    "savefig.dpi": 300,
    "figure.dpi": 150,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "mathtext.fontset": "dejavusans",
}

#: colours: tensile / shear cracks, simulation / lab
C_TENSION = "#1f77b4"
C_SHEAR = "#d62728"
C_SIM = "#1f77b4"
C_LAB = "#222222"
C_ALT = "#ff7f0e"


def figure(width=COLUMN, height=2.6, **kw):
    plt.rcParams.update(RC)
    return plt.subplots(figsize=(width, height), **kw)


def fig_note(title: str, text: str):
    """A figure that says why the real one is missing (e.g. its run failed), so that the
    report shows the reason in place of the figure."""
    import textwrap

    fig, ax = figure(COLUMN, 1.6)
    ax.set_axis_off()
    ax.set_title(title)
    ax.text(0.5, 0.5, "\n".join(textwrap.wrap(text, 60)), ha="center", va="center",
            transform=ax.transAxes, fontsize=7)
    return fig
