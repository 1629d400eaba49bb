"""Saving figures: every figure as PNG and PDF (same stem), atomically.

``bpmcal.plots`` builds matplotlib Figures and writes nothing; the stages save them here
(the figure convention of ``bpmcal.io.study_files``)."""
from __future__ import annotations

from pathlib import Path

from .atomic import atomic_path


def save_figure(fig, path_png) -> list[Path]:
    """Save ``fig`` as ``path_png`` and the PDF beside it, atomically, and close it."""
    import matplotlib.pyplot as plt  # matplotlib only where figures are saved

    p = Path(path_png)
    out = []
    for ext in (".png", ".pdf"):
        f = p.with_suffix(ext)
        with atomic_path(f) as tmp:
            fig.savefig(tmp, format=ext[1:], bbox_inches="tight")
        out.append(f)
    plt.close(fig)
    return out
