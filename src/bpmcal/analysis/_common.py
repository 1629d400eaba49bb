"""Helpers shared by the analysis modules: selecting usable dataset rows, seeded k-fold
splits and the paper's symbols for tables (from ``bpmcal.params``, the one symbol table).

Dataset contract (``results/dataset.csv``): one row per LHS sample with the 8
meso-parameters (:data:`bpmcal.params.PARAM_NAMES`, paper units; a flat-joint study
has the flat joint's card, :data:`bpmcal.params.MODELS`), the responses
(:data:`bpmcal.params.RESPONSES`), ``status`` (``"ok"``/``"failed"``) and ``error``.
Only rows with ``status == "ok"`` and finite values in every column an analysis needs
are used; :func:`usable_rows` returns how many rows were dropped and why, and every
results object carries those counts.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from bpmcal.params import ALL_PARAMS, RESPONSES, ParameterError, model_of


def symbol(name: str) -> str:
    """The paper's symbol (Unicode) of a parameter or response name (the name itself if
    unknown)."""
    q = ALL_PARAMS.get(name) or RESPONSES.get(name)
    return q.unicode if q is not None else name


def check_params(names: Iterable[str], what: str = "parameter") -> tuple[str, ...]:
    """Return ``names`` as a tuple after checking each is a card parameter of one
    contact model (:data:`bpmcal.params.MODELS`: the paper's 8 meso-parameters, or the
    flat joint's)."""
    names = tuple(names)
    bad = [n for n in names if n not in ALL_PARAMS]
    if bad:
        try:
            known = list(model_of([n for n in names if n in ALL_PARAMS]).params)
        except ParameterError:
            known = list(ALL_PARAMS)
        raise ParameterError(f"unknown {what}(s) {bad}; expected names from {known}")
    if len(set(names)) != len(names):
        raise ParameterError(f"duplicate {what} names in {list(names)}")
    return names


def dataset_params(df: pd.DataFrame) -> tuple[str, ...]:
    """The designed parameters of a dataset: the card parameters of its contact model
    (the one whose names its columns use) that vary over its samples, in the model's
    order. A parameter held at one value (a flat joint's element counts, a fixed
    parameter of one's own rock) carries no information for screening or regression."""
    model = model_of(df.columns)
    return tuple(p for p in model.params if p in df.columns and df[p].nunique(dropna=True) > 1)


def check_responses(names: Iterable[str]) -> tuple[str, ...]:
    """Return ``names`` as a tuple after checking each is a known response name."""
    names = tuple(names)
    bad = [n for n in names if n not in RESPONSES]
    if bad:
        raise ParameterError(f"unknown response(s) {bad}; expected names from {list(RESPONSES)}")
    return names


@dataclass(frozen=True)
class RowSelection:
    """Outcome of :func:`usable_rows`: the rows used and how many were dropped."""

    data: pd.DataFrame
    n_total: int
    n_failed: int  # status != "ok"
    n_missing: int  # status ok but a needed value missing / not finite

    @property
    def n_used(self) -> int:
        return len(self.data)

    @property
    def n_dropped(self) -> int:
        return self.n_failed + self.n_missing

    def describe(self) -> dict[str, int]:
        return {"n_total": self.n_total, "n_used": self.n_used, "n_dropped": self.n_dropped,
                "n_failed": self.n_failed, "n_missing": self.n_missing}


def usable_rows(df: pd.DataFrame, columns: Sequence[str]) -> RowSelection:
    """Rows of ``df`` with ``status == "ok"`` and finite numbers in all ``columns``.

    A frame without a ``status`` column is taken as all-ok (synthetic data). Missing
    columns raise ``ValueError`` naming them.
    """
    if not isinstance(df, pd.DataFrame):
        raise TypeError(f"expected a pandas DataFrame, got {type(df).__name__}")
    missing_cols = [c for c in columns if c not in df.columns]
    if missing_cols:
        raise ValueError(f"dataset lacks column(s) {missing_cols}; it has {list(df.columns)}")
    if "status" in df.columns:
        ok = df["status"].astype(str).str.strip().str.lower().eq("ok").to_numpy()
    else:
        ok = np.ones(len(df), dtype=bool)
    values = df.loc[:, list(columns)].apply(pd.to_numeric, errors="coerce").to_numpy(float)
    finite = np.isfinite(values).all(axis=1)
    keep = ok & finite
    data = df.loc[keep].copy()
    data[list(columns)] = values[keep]
    return RowSelection(data=data.reset_index(drop=True), n_total=len(df),
                        n_failed=int((~ok).sum()), n_missing=int((ok & ~finite).sum()))


def kfold_indices(n: int, n_splits: int, rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray]]:
    """Shuffled k-fold split of ``range(n)``: a list of (train, validation) index arrays.

    Fold sizes differ by at most one (the first ``n % n_splits`` folds get the extra row),
    as in scikit-learn's ``KFold(shuffle=True)``.
    """
    if not isinstance(n_splits, (int, np.integer)) or n_splits < 2:
        raise ValueError(f"n_splits={n_splits!r}: expected an integer >= 2")
    if n < n_splits:
        raise ValueError(f"{n} rows cannot be split into {n_splits} folds")
    perm = rng.permutation(n)
    sizes = np.full(n_splits, n // n_splits)
    sizes[: n % n_splits] += 1
    out, start = [], 0
    for size in sizes:
        val = np.sort(perm[start:start + size])
        train = np.sort(np.concatenate([perm[:start], perm[start + size:]]))
        out.append((train, val))
        start += size
    return out


def r2_score(y: np.ndarray, yhat: np.ndarray) -> float:
    """Coefficient of determination 1 - SS_res / SS_tot (SS_tot about the mean of ``y``)."""
    y = np.asarray(y, float)
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    ss_res = float(np.sum((y - np.asarray(yhat, float)) ** 2))
    return 1.0 - ss_res / ss_tot if ss_tot > 0 else float("nan")


def seed_from(rng: np.random.Generator) -> int:
    """A non-negative 31-bit integer seed drawn from ``rng`` (for libraries taking an int)."""
    return int(rng.integers(0, 2**31 - 1))
