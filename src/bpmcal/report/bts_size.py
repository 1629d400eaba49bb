"""The report's "σt at the lab's disc size" (rule ``bts_size``, ``stages.bts_size``): for
each specimen whose lab row gives the diameter of its Brazilian discs, the verified card's
σt on each disc size measured (seeds, valid discs, mean and SE), the fitted size curve, and
σt at the lab's size against the lab's, saying whether that value was measured on the
lab's size or read from the curve. A specimen without the stage's tables is left out."""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from ..io.tables import markdown_table
from .cells import num


def _sizes_table(sizes: pd.DataFrame) -> str:
    rows = [[num(r["diameter_mm"], ".1f"), r["role"], num(r["balls_across"], ".1f"),
             num(r["contact_cap"], ".2f"), f"{int(r['seeds'])}",
             f"{int(r['valid'])} ({int(r['discs'])} discs tested)",
             num(r["mean_MPa"], ".3f"), num(r["se_MPa"], ".3f"), num(r["se_pct"], ".1f")]
            for _, r in sizes.iterrows()]
    return markdown_table(rows, ["disc D (mm)", "", "balls across", "contact cap (mean ball "
                                 "diameters)", "seeds", "valid seeds", "σt mean (MPa)",
                                 "SE (MPa)", "SE %"])


def _comparison(f: pd.Series) -> str:
    """The fit and σt at the lab's size against the lab, in words."""
    how = {"measured": "measured on discs of the lab's size",
           "interpolated": "read from the fitted curve between the measured sizes",
           "extrapolated": "read from the fitted curve beyond the measured sizes "
                           "(an extrapolation)",
           "not measured": "not measured (too few valid discs)"}[f["method"]]
    fit = (f"σt = {num(f['sigma_ref_MPa'])} MPa × (D / {num(f['reference_mm'], 'g')} mm)"
           f"^−k, k = {num(f['k'])} ± {num(f['k_se'])} (SE; {int(f['sizes_fitted'])} sizes, "
           "weighted by each mean's SE)" if math.isfinite(f["k"]) else
           "no curve (fewer than two sizes with two valid discs)")
    lab_se = f" ± {num(f['lab_bts_se'])}" if f["lab_bts_se"] > 0 else ""
    return (f"Fit: {fit}. σt at the lab's {num(f['lab_diameter_mm'], 'g')} mm: "
            f"{num(f['sigma_lab_size_MPa'])} ± {num(f['sigma_lab_size_se'])} MPa, {how}; "
            f"the lab's σt {num(f['lab_bts_MPa'], 'g')}{lab_se} MPa: error "
            f"{num(f['err_pct'], '+.1f')} %, z = {num(f['z'], '+.2f')}.")


def section(lay, specimens) -> str:
    """The section (module docstring) for ``specimens``; "" when none has its tables."""
    parts = []
    for spec in specimens:
        fs, ff = Path(lay.bts_size_sizes(spec)), Path(lay.bts_size_fit(spec))
        if not (fs.exists() and ff.exists()):
            continue
        sizes = pd.read_csv(fs)
        f = pd.read_csv(ff).iloc[0]
        parts.append(f"**{spec}** (lab discs {num(f['lab_diameter_mm'], 'g')} mm, the study's "
                     f"{num(f['reference_mm'], 'g')} mm)\n\n" + _sizes_table(sizes) + "\n\n"
                     + _comparison(f) + "\n")
    if not parts:
        return ""
    return ("\n## σt at the lab's disc size\n\n"
            "The closed loop fits σt on the study's disc (Table 5); σt falls with the disc's "
            "size, so where the lab CSV names the diameter of its discs (`bts_diameter_mm`) "
            "the verified card's σt is measured again on discs of a few sizes (the study's, "
            "the lab's, one between), on fresh packing seeds, each disc loaded as the study's "
            "with its contact cap scaled with D (the same share of the disc as on the study's "
            "disc), and compared with the lab's σt at the lab's size.\n\n"
            + "\n".join(parts))
