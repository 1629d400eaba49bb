"""The lab CSVs of a study, read and checked in one place (a leaf of ``bpmcal.study``):

- the lab specimens table (``lab.csv``: :data:`LAB_COLUMNS`, optional
  :data:`LAB_OPTIONAL`): :func:`read_lab`, :func:`lab_problems`, :func:`load_lab`;
- the optional lab triaxial table (``triaxial.lab_csv``: one row per test, ``specimen,
  sigma3_MPa, sigma1_MPa``; ``specimen`` names a row of ``lab.csv``, sigma3 >= 0
  (compression positive) and sigma1 > sigma3, in MPa): :data:`LAB_TRIAXIAL_COLUMNS`,
  :func:`lab_triaxial_problems`, :func:`load_lab_triaxial`.

Lines starting with ``#`` are comments (the data's source). The tables are schemas: a
column that is not one of them is refused with the nearest known name (a typo such as
``bts_Mpa`` would otherwise drop that target silently), and every value must lie within
the physical bounds of rock (:data:`LAB_BOUNDS`; a modulus of 1e-300 GPa is a typo, not a
rock). Every problem is reported by row and column, all at once, before any job runs
(:class:`~.errors.ConfigError`); values quoted in messages are cut.
``study.config`` validates the configuration with these.
"""
from __future__ import annotations

import difflib
import math
from pathlib import Path

from ..io.safe_names import clip, name_problem, shown
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
#: the physical bounds of each lab value (open below, closed above; a standard error is
#: bounded by its value's upper bound): the weakest rocks' sigma_c is near 1 MPa and the
#: strongest's 500-600 MPa, moduli range from ~0.1 to ~150 GPa, tensile strengths stay
#: below ~50 MPa and a triaxial sigma_1 below a few GPa; the bounds leave a wide margin
#: around these and refuse only what no rock has (a typo's 1e-300 or 1e30)
LAB_BOUNDS = {"ucs_MPa": (0.0, 2000.0), "E_GPa": (1e-3, 500.0), "nu": (0.0, 0.5),
              "u_pre_MJm3": (0.0, 100.0), "bts_MPa": (0.0, 200.0), "dtt_MPa": (0.0, 200.0),
              "tri_MPa": (0.0, 10000.0),
              # a Brazilian disc: ISRM's 54 mm, large-scale tests a few hundred mm
              "bts_diameter_mm": (0.0, 2000.0)}
#: the bounds of the lab triaxial table's stresses [MPa] (sigma3 from 0 inclusive)
TRIAXIAL_BOUNDS = {"sigma3_MPa": (0.0, 2000.0), "sigma1_MPa": (0.0, 10000.0)}


def _unknown_columns(df, known, where: str) -> list[str]:
    """A problem for each column of ``df`` that is not in ``known``, with the nearest
    known name when there is one (``bts_Mpa`` -> ``bts_MPa``)."""
    lower = {k.lower(): k for k in known}
    msgs = []
    for c in df.columns:
        if c in known:
            continue
        near = lower.get(str(c).lower()) or next(
            iter(difflib.get_close_matches(str(c), list(known), n=1, cutoff=0.6)), None)
        hint = f"; did you mean {near!r}?" if near else ""
        msgs.append(f"{where} has an unknown column {shown(c)}{hint} (known: "
                    f"{', '.join(known)})")
    return msgs


def _bounded(c: str, v: float) -> str | None:
    """What is wrong with lab value ``v`` of column ``c`` (a finite number), or None."""
    lo, hi = LAB_BOUNDS.get(c[:-3] if c.endswith("_se") else c, (0.0, math.inf))
    if c.endswith("_se"):
        return None if 0 <= v <= hi else f"expected a standard error in [0, {hi:g}]"
    if c == "nu":
        return None if 0 < v < 0.5 else "expected a Poisson's ratio in (0, 0.5)"
    return None if lo < v <= hi else f"expected a value in ({lo:g}, {hi:g}] (rock)"


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
    msgs = _unknown_columns(df, (*LAB_COLUMNS, *LAB_OPTIONAL), f"lab.csv: {key!r}")
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
            where = f"lab.csv: {key!r} specimen {clip(str(spec))} {c}={shown(raw)}"
            if c in LAB_SE:
                value = df.loc[df["specimen"] == spec, c[:-3]]
                if not (math.isfinite(v) and v >= 0):
                    msgs.append(f"{where}: expected a standard error >= 0 (or empty)")
                elif c[:-3] not in df.columns or not _given(value.iloc[0]):
                    msgs.append(f"{where}: a standard error without its value {c[:-3]}")
                elif _bounded(c, v):
                    msgs.append(f"{where}: {_bounded(c, v)}")
            elif not (math.isfinite(v) and v > 0):
                msgs.append(f"{where}: expected a positive number"
                            f"{' (or empty)' if optional else ''}")
            elif c == "nu" and v >= 0.5:
                msgs.append(f"{where}: expected below 0.5")
            elif _bounded(c, v):
                msgs.append(f"{where}: {_bounded(c, v)}")
    if "bts_diameter_mm" in df.columns:
        alone = [clip(str(sp)) for sp, d, b in zip(df["specimen"], df["bts_diameter_mm"],
                                             df["bts_MPa"] if "bts_MPa" in df.columns
                                             else [None] * len(df))
                 if _given(d) and not _given(b)]
        if alone:
            msgs.append(f"lab.csv: {key!r} specimen {', '.join(alone)} gives bts_diameter_mm "
                        "without bts_MPa: expected the diameter of the discs of a Brazilian σt")
    if "bts_MPa" in df.columns and "dtt_MPa" in df.columns:
        both = [str(sp) for sp, a, b in zip(df["specimen"], df["bts_MPa"], df["dtt_MPa"])
                if _given(a) and _given(b)]
        if both:
            msgs.append(f"lab.csv: {key!r} specimen(s) {both} give both bts_MPa and dtt_MPa: "
                        "expected one tensile strength per specimen (the Brazilian or the "
                        "direct-tension one; they are different measurements)")
    return msgs


def lab_disc_diameters(df, study_mm: float, rel: float = 1e-6) -> dict:
    """Specimen -> the diameter [mm] of its lab Brazilian discs, for the rows of a validated
    lab table (``load_lab``) whose ``bts_diameter_mm`` is given and differs from the
    study's disc ``study_mm`` by more than ``rel`` of it: the specimens whose σt the study
    compares at the lab's size (rule ``bts_size``); {} without the column."""
    if "bts_diameter_mm" not in df.columns:
        return {}
    return {str(s): float(d) for s, d in zip(df["specimen"], df["bts_diameter_mm"])
            if _given(d) and abs(float(d) - study_mm) > rel * study_mm}


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
    msgs = _unknown_columns(df, LAB_TRIAXIAL_COLUMNS, where)
    known = None if specimens is None else [str(s) for s in specimens]
    for i, r in enumerate(df.to_dict("records"), start=1):
        spec = r["specimen"]
        if known is not None and str(spec) not in known:
            msgs.append(f"{where} row {i}: specimen {shown(spec)} is not in lab.csv (specimens "
                        f"{shown(known)})")
        s3, s1 = _number(r["sigma3_MPa"]), _number(r["sigma1_MPa"])
        for c, v in (("sigma3_MPa", s3), ("sigma1_MPa", s1)):
            if math.isfinite(v) and v > TRIAXIAL_BOUNDS[c][1]:
                msgs.append(f"{where} row {i}: {c}={shown(r[c])}: expected at most "
                            f"{TRIAXIAL_BOUNDS[c][1]:g} MPa (rock)")
        if not (math.isfinite(s3) and s3 >= 0):
            msgs.append(f"{where} row {i}: sigma3_MPa={shown(r['sigma3_MPa'])}: expected a number "
                        ">= 0 (confining stress in MPa, compression positive)")
        if not (math.isfinite(s1) and s1 > 0):
            msgs.append(f"{where} row {i}: sigma1_MPa={shown(r['sigma1_MPa'])}: expected a "
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
