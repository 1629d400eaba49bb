"""The report's cells: a number as the tables show it (:func:`num`), a difference in %
(:func:`pct_diff`), and one row of the comparison with the paper (:func:`compare`),
shared by the report's sections (``report.build``, ``report.verification``)."""
from __future__ import annotations

import math


def pct_diff(ours, theirs) -> str:
    """``ours`` against ``theirs`` in % of ``theirs`` ('–' when either is missing)."""
    if ours is None or theirs is None or not math.isfinite(float(ours)) or float(theirs) == 0:
        return "–"
    return f"{100 * (float(ours) - float(theirs)) / abs(float(theirs)):+.1f} %"


def num(v, fmt=".3f") -> str:
    """A table cell: ``v`` formatted with ``fmt``, '–' when it is not finite, ``str(v)``
    when it is not a number."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    return "–" if not math.isfinite(x) else format(x, fmt)


def compare(comp: list, section, item, ours, theirs, unit="") -> None:
    """Record one comparison with a published value (a row of ``tables/comparison.csv``)."""
    try:
        o = float(ours)
    except (TypeError, ValueError):
        o = math.nan
    t = float(theirs)
    comp.append({"section": section, "quantity": item, "unit": unit, "ours": o, "paper": t,
                 "difference": o - t if math.isfinite(o) else math.nan,
                 "difference_pct": 100 * (o - t) / abs(t) if math.isfinite(o) and t else math.nan})


def read_table(lay, name: str, **kw):
    """The study's table ``name`` (``StudyFiles.table``) as a DataFrame (``kw``: pandas'
    ``read_csv`` options), ``None`` when a partial study has not written it: each
    section then leaves itself out."""
    from pathlib import Path

    import pandas as pd

    f = Path(lay.table(name))
    return pd.read_csv(f, **kw) if f.exists() else None
