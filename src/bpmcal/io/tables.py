"""Tables and text outputs, written atomically (``bpmcal.io.atomic``), in one style.

- :func:`markdown_table`: the one Markdown renderer (GitHub pipe tables; no ``tabulate``):
  the report's tables, Tables 3 and 4 in the paper's layout, the ``.md`` beside every CSV.
- :func:`write_table`: a DataFrame as CSV plus its Markdown rendering (same stem, ``.md``;
  the table convention of ``bpmcal.io.study_files``).
- :func:`write_json`, :func:`write_yaml`: plain JSON/YAML of results (numpy scalars become
  Python numbers, NaN becomes null: :func:`plain`).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from .atomic import atomic_path, write_text

if TYPE_CHECKING:  # pandas is imported where a table is rendered: a DEM job (which writes
    import pandas as pd  # YAML and JSON only) does not pay its ~0.3 s import


def _cell(v, floatfmt: str) -> str:
    if isinstance(v, (float, np.floating)):
        return "" if math.isnan(v) else format(float(v), floatfmt)
    return "" if v is None else str(v)


def markdown_table(data, header=None, *, floatfmt: str = ".4g", index: bool = True) -> str:
    """A GitHub-flavoured Markdown pipe table.

    ``data``: a DataFrame (its index as leading column(s) when ``index``; a MultiIndex gives
    one column per level; numeric columns right-aligned, floats as ``floatfmt``, NaN
    empty), or a list of rows with ``header`` (cells as ``str``; left-aligned)."""
    import pandas as pd

    if isinstance(data, pd.DataFrame):
        df = data
        idx = df.index.to_frame(index=False) if index else pd.DataFrame(index=range(len(df)))
        idx.columns = ["" if c is None else str(c) for c in idx.columns]
        if index and len(idx.columns) == 1 and df.index.name is None:
            idx.columns = [""]
        cols = list(idx.columns) + [str(c) for c in df.columns]
        numeric = ([pd.api.types.is_numeric_dtype(t) for t in idx.dtypes]
                   + [pd.api.types.is_numeric_dtype(t) for t in df.dtypes])
        rows = [[_cell(v, floatfmt) for v in (*i, *r)] for i, r in
                zip(idx.itertuples(index=False, name=None),
                    df.itertuples(index=False, name=None))]
        align = ["---:" if num else ":---" for num in numeric]
    else:
        if header is None:
            raise ValueError("markdown_table: rows need a header")
        cols = [str(h) for h in header]
        rows = [[_cell(c, floatfmt) for c in r] for r in data]
        align = ["---"] * len(cols)
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join(align) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def write_table(df: pd.DataFrame, path, *, index: bool = True, floatfmt: str = ".4g",
                markdown: str | None = None) -> list[Path]:
    """Write ``df`` to ``path`` (CSV) and its Markdown rendering beside it (``.md``), both
    atomically; ``markdown`` replaces the default rendering (e.g. the paper's layout)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=index)
    md = markdown if markdown is not None else markdown_table(df, floatfmt=floatfmt, index=index)
    return [path, write_text(path.with_suffix(".md"), md.rstrip("\n") + "\n")]


def plain(v):
    """numpy/pandas scalars and NaN -> plain JSON/YAML-able Python (NaN and inf -> None)."""
    if isinstance(v, dict):
        return {str(k): plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return None if not math.isfinite(f) else f
    return v


def write_json(path, obj, *, indent: int = 2) -> Path:
    """``obj`` as JSON (``plain`` values), atomically."""
    return write_text(path, json.dumps(plain(obj), indent=indent) + "\n")


def write_yaml(path, d: dict) -> Path:
    """``d`` as YAML in insertion order (``plain`` values), atomically."""
    return write_text(path, yaml.safe_dump(plain(d), sort_keys=False))


def write_csv(df: pd.DataFrame, path, *, index: bool = False) -> Path:
    """``df`` as CSV (no Markdown beside it: data files such as the design), atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=index)
    return path
