"""The lab CSVs of a study, read and checked in one place (a leaf of ``bpmcal.study``):

- the lab specimens table (``lab.csv``: :data:`LAB_COLUMNS`, optional
  :data:`LAB_OPTIONAL`): :func:`read_lab`, :func:`lab_problems`, :func:`load_lab`;
- the optional lab triaxial table (``triaxial.lab_csv``: one row per test, ``specimen,
  sigma3_MPa, sigma1_MPa``; ``specimen`` names a row of ``lab.csv``, sigma3 >= 0
  (compression positive) and sigma1 > sigma3, in MPa): :data:`LAB_TRIAXIAL_COLUMNS`,
  :func:`lab_triaxial_problems`, :func:`load_lab_triaxial`.

Lines starting with ``#`` are comments (the data's source). Every problem is reported by
row and column, all at once, before any job runs (:class:`~.errors.ConfigError`).
``study.config`` validates the configuration with these; ``study.lab_triaxial`` is the
former home of the triaxial part and re-exports it.
"""
from __future__ import annotations

import math
from pathlib import Path

from ..io.safe_names import name_problem
from .errors import ConfigError

LAB_COLUMNS = ("specimen", "ucs_MPa", "E_GPa", "nu")
#: optional columns: empty = not given for that specimen; ``bts_MPa`` (Brazilian tensile
#: strength) or ``dtt_MPa`` (direct-tension strength, the alternative σt target; not both
#: on one row) makes σt a calibration target of that specimen (``stages.calibration.calibrate``);
#: ``tri_MPa`` (sigma1 at failure in a triaxial test at the study's design confinement,
#: ``triaxial.design_sigma3_MPa``) makes the triaxial strength a target
#: optional standard errors of the lab values (``<column>_se``, the column's unit, >= 0;
#: e.g. the standard deviation over the lab's n specimens / sqrt(n)): the closed loop and
#: the fresh-seed check then compare two means, each with its error
LAB_SE = tuple(f"{c}_se" for c in ("ucs_MPa", "E_GPa", "nu", "bts_MPa", "dtt_MPa", "tri_MPa"))
#: ``bts_diameter_mm``: the diameter of the lab's Brazilian discs [mm] (> 0; with its row's
#: ``bts_MPa``): σt falls with the disc's size, so the study says at which size it compared
LAB_OPTIONAL = ("u_pre_MJm3", "bts_MPa", "dtt_MPa", "tri_MPa", "bts_diameter_mm", *LAB_SE)


def lab_problems(df, key: str) -> list[str]:
    """Problems of a lab table (a DataFrame read with ``read_lab``), named by column and
    specimen."""
    import pandas as pd

    missing = [c for c in LAB_COLUMNS if c not in df.columns]
    if missing:
        return [f"lab.csv: {key!r} lacks column(s) {missing}; expected {list(LAB_COLUMNS)} "
                f"(+ optional {', '.join(LAB_OPTIONAL)})"]
    if len(df) == 0:
        return [f"lab.csv: {key!r} has no specimen rows"]
    msgs = []
    for s in df["specimen"]:
        m = name_problem(s)
        if m:
            msgs.append(f"lab.csv: {key!r} specimen {m} (it becomes a file name)")
    if df["specimen"].duplicated().any():
        dup = sorted(set(df.loc[df["specimen"].duplicated(), "specimen"]))
        msgs.append(f"lab.csv: {key!r} has duplicate specimen names {dup}")
    for c in ("ucs_MPa", "E_GPa", "nu", *[o for o in LAB_OPTIONAL if o in df.columns]):
        optional = c in LAB_OPTIONAL
        for spec, raw in zip(df["specimen"], df[c]):
            if optional and (raw is None or (isinstance(raw, float) and math.isnan(raw))
                             or (isinstance(raw, str) and not raw.strip())):
                continue  # an empty optional value
            try:
                v = float(pd.to_numeric(pd.Series([raw]), errors="coerce").iloc[0])
            except (TypeError, ValueError):
                v = math.nan
            if c in LAB_SE:
                value = df.loc[df["specimen"] == spec, c[:-3]]
                if not (math.isfinite(v) and v >= 0):
                    msgs.append(f"lab.csv: {key!r} specimen {spec} {c}={raw!r}: expected a "
                                "standard error >= 0 (or empty)")
                elif c[:-3] not in df.columns or not _given(value.iloc[0]):
                    msgs.append(f"lab.csv: {key!r} specimen {spec} {c}={raw!r}: a standard "
                                f"error without its value {c[:-3]}")
            elif not (math.isfinite(v) and v > 0):
                msgs.append(f"lab.csv: {key!r} specimen {spec} {c}={raw!r}: expected a "
                            f"positive number{' (or empty)' if optional else ''}")
            elif c == "nu" and v >= 0.5:
                msgs.append(f"lab.csv: {key!r} specimen {spec} nu={raw!r}: expected below 0.5")
    if "bts_diameter_mm" in df.columns:
        alone = [str(sp) for sp, d, b in zip(df["specimen"], df["bts_diameter_mm"],
                                             df["bts_MPa"] if "bts_MPa" in df.columns
                                             else [None] * len(df))
                 if _given(d) and not _given(b)]
        if alone:
            msgs.append(f"lab.csv: {key!r} specimen {', '.join(alone)} gives bts_diameter_mm without "
                        "bts_MPa: expected the diameter of the discs of a Brazilian σt")
    if "bts_MPa" in df.columns and "dtt_MPa" in df.columns:
        both = [str(sp) for sp, a, b in zip(df["specimen"], df["bts_MPa"], df["dtt_MPa"])
                if _given(a) and _given(b)]
        if both:
            msgs.append(f"lab.csv: {key!r} specimen(s) {both} give both bts_MPa and dtt_MPa: "
                        "expected one tensile strength per specimen (the Brazilian or the "
                        "direct-tension one; they are different measurements)")
    return msgs


def _given(raw) -> bool:
    """An optional lab value that is not empty."""
    return not (raw is None or (isinstance(raw, float) and math.isnan(raw))
                or (isinstance(raw, str) and not raw.strip()))


def read_lab(path):
    """The lab specimens table as read everywhere: lines whose first non-blank character is
    ``#`` are comments (the data's source, units, notes) and are skipped; specimen names
    are kept as text ("007" stays "007") and the values as text until checked. Raises
    ConfigError for a file that is not a CSV table."""
    import io

    import pandas as pd

    try:
        text = Path(path).read_text()
        body = "".join(ln for ln in text.splitlines(keepends=True)
                       if not ln.lstrip().startswith("#"))
        return pd.read_csv(io.StringIO(body), dtype=str, keep_default_na=False,
                           na_values=[""])
    except (OSError, pd.errors.EmptyDataError, pd.errors.ParserError, UnicodeDecodeError,
            ValueError) as e:
        raise ConfigError(f"lab.csv: cannot read {str(path)!r}: "
                          f"{' '.join(str(e).split())[:200]}") from None


def load_lab(path):
    """The validated lab table (ConfigError listing every problem): specimen as text,
    the values as floats (NaN for an empty optional value)."""
    import pandas as pd

    df = read_lab(path)
    msgs = lab_problems(df, str(path))
    if msgs:
        raise ConfigError("invalid lab table:\n  " + "\n  ".join(msgs))
    for c in (*LAB_COLUMNS[1:], *LAB_OPTIONAL):
        if c in df.columns:
            df[c] = pd.to_numeric(df[c], errors="coerce")
    return df


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
