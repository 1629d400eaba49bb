"""The optional lab CSV of triaxial points (``triaxial.lab_csv``): one row per test,

    specimen, sigma3_MPa, sigma1_MPa

(lines starting with ``#`` are comments: the data's source). ``specimen`` names a row of
the lab CSV (``lab.csv``), so that its points are compared with that specimen's cards;
sigma3 >= 0 (compression positive) and sigma1 > sigma3, in MPa. Every problem is reported
by row and column, all at once, before any job runs (:class:`ConfigError`).
"""
from __future__ import annotations

import math

from .config import ConfigError, read_lab

#: the columns of the lab triaxial CSV
LAB_TRIAXIAL_COLUMNS = ("specimen", "sigma3_MPa", "sigma1_MPa")


def _number(raw) -> float:
    try:
        v = float(str(raw).strip())
    except (TypeError, ValueError):
        return math.nan
    return v


def lab_triaxial_problems(df, key: str, specimens=None) -> list[str]:
    """Problems of a lab triaxial table read with ``read_lab`` (``key``: its path in the
    messages; ``specimens``: the lab CSV's specimen names, None to skip that check)."""
    where = f"triaxial.lab_csv: {key!r}"
    missing = [c for c in LAB_TRIAXIAL_COLUMNS if c not in df.columns]
    if missing:
        return [f"{where} lacks column(s) {missing}; expected {list(LAB_TRIAXIAL_COLUMNS)}"]
    if len(df) == 0:
        return [f"{where} has no rows (expected one row per triaxial test)"]
    msgs = []
    known = None if specimens is None else [str(s) for s in specimens]
    for i, r in enumerate(df.to_dict("records"), start=1):
        spec = r["specimen"]
        if known is not None and str(spec) not in known:
            msgs.append(f"{where} row {i}: specimen {spec!r} is not in lab.csv (specimens "
                        f"{known})")
        s3, s1 = _number(r["sigma3_MPa"]), _number(r["sigma1_MPa"])
        if not (math.isfinite(s3) and s3 >= 0):
            msgs.append(f"{where} row {i}: sigma3_MPa={r['sigma3_MPa']!r}: expected a number "
                        ">= 0 (confining stress in MPa, compression positive)")
        if not (math.isfinite(s1) and s1 > 0):
            msgs.append(f"{where} row {i}: sigma1_MPa={r['sigma1_MPa']!r}: expected a "
                        "positive number (axial stress at failure in MPa)")
        elif math.isfinite(s3) and s3 >= 0 and not s1 > s3:
            msgs.append(f"{where} row {i}: sigma1_MPa={s1:g} <= sigma3_MPa={s3:g}: expected "
                        "sigma1 > sigma3 at failure")
    return msgs


def load_lab_triaxial(path, specimens=None):
    """The validated lab triaxial table (ConfigError listing every problem): specimen as
    text, sigma3_MPa and sigma1_MPa as floats."""
    df = read_lab(path)
    msgs = lab_triaxial_problems(df, str(path), specimens)
    if msgs:
        raise ConfigError("invalid lab triaxial table:\n  " + "\n  ".join(msgs))
    df = df[list(LAB_TRIAXIAL_COLUMNS)].copy()
    df["specimen"] = df["specimen"].astype(str)
    for c in LAB_TRIAXIAL_COLUMNS[1:]:
        df[c] = df[c].astype(float)
    return df
