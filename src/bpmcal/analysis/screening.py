"""XGBoost screening of the meso-parameters (paper section 3.1, Table 3).

For each response (default ``ucs_MPa``, ``E_GPa``, ``nu``) an XGBoost regressor is trained
on the 8 meso-parameters in a seeded, *shuffled* 5-fold cross-validation (the same folds
for every response). In each fold the model is trained on the ~80 % training rows; the
importances are computed from that fold's *training* model and the held-out ~20 % gives
the fold's validation R². Shares are averaged over the folds (mean and sample standard
deviation, ``ddof=1``).

Importance types (each normalised per fold to a share in percent summing to 100 over the
input features; a fold whose raw importances are all zero gives NaN):

``gain``
    average gain of the splits on a feature (``Booster.get_score(importance_type="gain")``;
    this is what ``XGBRegressor.feature_importances_`` returns by default and is what the
    paper's Table 3 reports). Note that xgboost's *plotting* default
    (``xgboost.plot_importance``) is ``weight`` (number of splits), which ranks features
    differently; ``weight`` is not used here.
``total_gain``
    gain summed over all splits on a feature.
``permutation``
    held-out permutation importance: on the validation fold, the drop of R² when one
    column is permuted (``n_repeats`` seeded permutations, averaged); negative drops are
    clipped to 0 before normalising.
``shap``
    mean absolute SHAP value over the fold's *training* rows, from xgboost's own TreeSHAP
    (``Booster.predict(DMatrix, pred_contribs=True)``; the bias column is discarded).

Null reference ("shadow features"): a second model per fold is trained on the 8 inputs plus
a seeded random permutation of each input column (``shadow_<name>``), which keeps each
marginal distribution but has no relation to the response. Its importances are normalised
over all 16 features; :attr:`ScreeningResults.shadow_max` is the largest fold-averaged
shadow share per response and importance type, i.e. the share pure noise can obtain. A
parameter whose share is not clearly above it should not be called influential.

Selection (``rule``), per response, on the fold-mean shares of one importance type,
``importance`` (default ``gain``); candidates are listed in decreasing share:

``threshold`` (the paper's rule, the default)
    a parameter whose share exceeds ``threshold`` percent (default 10).
``above_noise``
    a parameter whose mean-|SHAP| share *in the shadow model* exceeds the largest shadow
    share of that model (the all-relevant rule of Boruta, Kursa & Rudnicki 2010, in one
    iteration: a parameter the trees use more than any column of pure noise carries
    signal), or whose share of ``importance`` exceeds ``threshold``. SHAP, not gain: the
    average gain favours a column split on rarely, so a shadow can out-gain a real weak
    parameter (:data:`NOISE_IMPORTANCE`). Meant for a response whose importance spreads over more
    parameters than a fixed share admits (σt of a parallel-bonded material: the bond
    pair and porosity, and kp* and φp at 3-5 % each, docs/measurements); the stepwise
    regression then keeps only the terms that are significant. One iteration of shadows
    on ~150 rows is noisy: a parameter near the noise share can fall either side.
``all``
    every parameter is a candidate: the screening only reports, and the stepwise
    regression's entry test (``alpha_in``) alone chooses the terms. bpmcal's default for
    σt, which the paper does not screen: its trees fit σt worse than the regression does
    (validation R² about 0.7) and a 10 % share drops kp* and φp, which carry σt
    measurably (docs/measurements).

XGBoost settings (:data:`DEFAULT_XGB_PARAMS`) suit ~150 rows and 8 inputs: 300 trees of
depth 3 with learning rate 0.05 and row subsampling 0.8 (shallow, slowly learning trees
resist over-fitting on small data; depth 3 still represents the two-way interactions of
Table 4), squared-error loss, one thread. Any key can be overridden with
``xgb_params`` (``n_estimators`` and ``n_jobs`` are mapped to xgboost's native
``num_boost_round`` and ``nthread``); the random seed is derived from ``seed``. The native
``xgboost.train`` API is used so that scikit-learn is not needed.
"""
from __future__ import annotations

import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import xgboost as xgb

from bpmcal.io.tables import markdown_table
from bpmcal.params import PARAM_NAMES, TARGETS

from ._common import (
    check_params,
    check_responses,
    kfold_indices,
    r2_score,
    seed_from,
    symbol,
    usable_rows,
)

IMPORTANCE_TYPES: tuple[str, ...] = ("gain", "total_gain", "permutation", "shap")
#: selection rules (module docstring)
RULES: tuple[str, ...] = ("threshold", "above_noise", "all")
#: the importance ``above_noise`` compares with the shadows
NOISE_IMPORTANCE = "shap"

#: Default XGBoost hyper-parameters (scikit-learn style names), see the module docstring.
DEFAULT_XGB_PARAMS: dict[str, object] = {
    "n_estimators": 300,
    "max_depth": 3,
    "learning_rate": 0.05,
    "subsample": 0.8,
    "colsample_bytree": 1.0,
    "min_child_weight": 1.0,
    "reg_lambda": 1.0,
    "objective": "reg:squarederror",
    "n_jobs": 1,
}

SHADOW_PREFIX = "shadow_"


def _response_rng(seed: int, response: str) -> np.random.Generator:
    """A stream per response that does not depend on which other responses are screened."""
    return np.random.default_rng([int(seed), zlib.crc32(response.encode())])


def _normalise(raw: np.ndarray) -> np.ndarray:
    total = float(np.sum(raw))
    return 100.0 * raw / total if total > 0 else np.full(raw.shape, np.nan)


class XGBScreening:
    """Cross-validated XGBoost importance screening (see the module docstring).

    Parameters
    ----------
    params:
        Input meso-parameters (default: all 8, paper order).
    responses:
        Responses to screen (default ``("ucs_MPa", "E_GPa", "nu")``).
    n_splits:
        Number of shuffled CV folds (default 5).
    threshold:
        Selection threshold in percent (default 10.0).
    rule:
        Selection rule, one of :data:`RULES` (default ``threshold``, the paper's);
        ``above_noise`` needs ``shadow``.
    importance:
        Importance type that drives the selection, one of :data:`IMPORTANCE_TYPES`.
    n_repeats:
        Permutations per column for the permutation importance (default 10).
    shadow:
        Fit the shadow-feature null reference (default True).
    xgb_params:
        Overrides of :data:`DEFAULT_XGB_PARAMS`.
    seed:
        Seeds the folds, xgboost's subsampling, the permutations and the shadow columns
        (default 11, the default study's ``screening.seed``).
    """

    def __init__(self, params: Sequence[str] = PARAM_NAMES, responses: Sequence[str] = TARGETS, *,
                 n_splits: int = 5, threshold: float = 10.0, importance: str = "gain",
                 n_repeats: int = 10, shadow: bool = True, rule: str = "threshold",
                 xgb_params: Mapping[str, object] | None = None, seed: int = 11):
        self.params = check_params(params)
        self.responses = check_responses(responses)
        if not self.params or not self.responses:
            raise ValueError("need at least one parameter and one response")
        if not isinstance(n_splits, (int, np.integer)) or n_splits < 2:
            raise ValueError(f"n_splits={n_splits!r}: expected an integer >= 2")
        if not 0.0 <= float(threshold) < 100.0:
            raise ValueError(f"threshold={threshold!r}: expected a percentage in [0, 100)")
        if importance not in IMPORTANCE_TYPES:
            raise ValueError(f"importance={importance!r}: expected one of {IMPORTANCE_TYPES}")
        if rule not in RULES:
            raise ValueError(f"rule={rule!r}: expected one of {RULES}")
        if rule == "above_noise" and not shadow:
            raise ValueError("rule='above_noise' compares with the shadow model: shadow=True")
        if not isinstance(n_repeats, (int, np.integer)) or n_repeats < 1:
            raise ValueError(f"n_repeats={n_repeats!r}: expected an integer >= 1")
        overrides = dict(xgb_params or {})
        for key in ("seed", "random_state"):
            if key in overrides:
                raise ValueError(f"xgb_params[{key!r}]: set the seed with XGBScreening(seed=...)")
        self.xgb_params = {**DEFAULT_XGB_PARAMS, **overrides}
        self.n_splits = int(n_splits)
        self.threshold = float(threshold)
        self.importance = importance
        self.n_repeats = int(n_repeats)
        self.shadow = bool(shadow)
        self.rule = rule
        self.seed = int(seed)

    # -- one model ---------------------------------------------------------------------
    def _train(self, X: np.ndarray, y: np.ndarray, names: list[str], seed: int) -> xgb.Booster:
        p = dict(self.xgb_params)
        rounds = int(p.pop("n_estimators"))
        p["nthread"] = int(p.pop("n_jobs"))
        p["seed"] = seed
        return xgb.train(p, self._dmatrix(X, names, y), num_boost_round=rounds)

    def _dmatrix(self, X: np.ndarray, names: list[str], y: np.ndarray | None = None) -> xgb.DMatrix:
        # nthread must be given: the default (all cores) costs ~30 ms per construction
        return xgb.DMatrix(X, label=y, feature_names=names, nthread=int(self.xgb_params["n_jobs"]))

    def _importances(self, booster: xgb.Booster, names: list[str], X_tr: np.ndarray,
                     X_va: np.ndarray, y_va: np.ndarray, rng: np.random.Generator
                     ) -> tuple[dict[str, np.ndarray], float]:
        """Raw importances of every type (unnormalised) and the validation R²."""
        raw: dict[str, np.ndarray] = {}
        for kind in ("gain", "total_gain"):
            score = booster.get_score(importance_type=kind)
            raw[kind] = np.array([float(score.get(n, 0.0)) for n in names])
        contribs = booster.predict(self._dmatrix(X_tr, names), pred_contribs=True)
        raw["shap"] = np.abs(contribs[:, :-1].astype(float)).mean(axis=0)
        base = r2_score(y_va, booster.predict(self._dmatrix(X_va, names)))
        # all permuted copies in one prediction: shape (feature, repeat, row, column)
        p, n_rep = len(names), self.n_repeats
        Xp = np.broadcast_to(X_va, (p, n_rep) + X_va.shape).copy()
        for j in range(p):
            for r in range(n_rep):
                Xp[j, r, :, j] = rng.permutation(X_va[:, j])
        pred = booster.predict(self._dmatrix(Xp.reshape(-1, p), names)).reshape(p, n_rep, -1)
        drops = np.array([np.mean([base - r2_score(y_va, pr) for pr in pred[j]]) for j in range(p)])
        raw["permutation"] = np.clip(drops, 0.0, None)
        return raw, base

    # -- public ------------------------------------------------------------------------
    def fit(self, df: pd.DataFrame) -> ScreeningResults:
        """Screen every response on the usable rows of ``df`` (see module docstring)."""
        rows = usable_rows(df, list(self.params) + list(self.responses))
        if rows.n_used < 2 * self.n_splits:
            raise ValueError(f"only {rows.n_used} usable rows ({rows.n_dropped} dropped); "
                             f"need at least {2 * self.n_splits} for {self.n_splits}-fold CV")
        X = rows.data[list(self.params)].to_numpy(float)
        folds = kfold_indices(len(X), self.n_splits, np.random.default_rng(self.seed))
        names = list(self.params)
        shadow_names = names + [SHADOW_PREFIX + n for n in names]
        records, cv = [], []
        for response in self.responses:
            y = rows.data[response].to_numpy(float)
            rng = _response_rng(self.seed, response)
            X_shadow = np.column_stack([X] + [rng.permutation(X[:, j]) for j in range(X.shape[1])])
            for k, (tr, va) in enumerate(folds):
                fits = [("main", X, names)] + ([("shadow", X_shadow, shadow_names)] if self.shadow else [])
                for model, Xm, fnames in fits:
                    booster = self._train(Xm[tr], y[tr], fnames, seed_from(rng))
                    raw, r2 = self._importances(booster, fnames, Xm[tr], Xm[va], y[va], rng)
                    if model == "main":
                        cv.append({"response": response, "fold": k, "r2": r2,
                                   "n_train": len(tr), "n_val": len(va)})
                    for kind in IMPORTANCE_TYPES:
                        for feat, share in zip(fnames, _normalise(raw[kind])):
                            records.append({"response": response, "model": model, "fold": k,
                                            "importance": kind, "feature": feat, "share": share})
        return ScreeningResults(
            params=self.params, responses=self.responses, threshold=self.threshold,
            importance=self.importance, importances=pd.DataFrame.from_records(records),
            cv=pd.DataFrame.from_records(cv), rows=rows.describe(),
            rules={r: self.rule for r in self.responses},
            settings={"n_splits": self.n_splits, "n_repeats": self.n_repeats, "shadow": self.shadow,
                      "seed": self.seed, "xgb_params": dict(self.xgb_params)})


@dataclass
class ScreeningResults:
    """Results of :meth:`XGBScreening.fit`.

    ``importances`` is the long table (response, model ``main``/``shadow``, fold,
    importance, feature, share %); everything else is derived from it. ``rows`` holds
    the row counts (``n_used``, ``n_dropped``, ``n_failed``, ``n_missing``).
    """

    params: tuple[str, ...]
    responses: tuple[str, ...]
    threshold: float
    importance: str
    importances: pd.DataFrame
    cv: pd.DataFrame
    rows: dict[str, int]
    settings: dict = field(default_factory=dict)
    #: row counts of responses screened on other rows than ``rows`` (:func:`combine`)
    response_rows: dict[str, dict[str, int]] = field(default_factory=dict)
    #: selection rule per response (:data:`RULES`; a response not named: ``threshold``)
    rules: dict[str, str] = field(default_factory=dict)

    @property
    def n_dropped(self) -> int:
        return self.rows["n_dropped"]

    def _main(self, importance: str) -> pd.DataFrame:
        if importance not in IMPORTANCE_TYPES:
            raise ValueError(f"importance={importance!r}: expected one of {IMPORTANCE_TYPES}")
        imp = self.importances
        return imp[(imp["model"] == "main") & (imp["importance"] == importance)]

    def share(self, importance: str = "gain") -> pd.DataFrame:
        """Fold-mean share (%) per parameter (rows, paper order) and response (columns)."""
        tab = self._main(importance).pivot_table(index="feature", columns="response", values="share",
                                                 aggfunc="mean", dropna=False)
        return tab.reindex(index=list(self.params), columns=list(self.responses))

    def share_std(self, importance: str = "gain") -> pd.DataFrame:
        """Fold-to-fold standard deviation (ddof=1) of the shares, same layout as :meth:`share`."""
        tab = self._main(importance).pivot_table(index="feature", columns="response", values="share",
                                                 aggfunc=lambda s: float(np.std(s, ddof=1)), dropna=False)
        return tab.reindex(index=list(self.params), columns=list(self.responses))

    @property
    def shadow_max(self) -> pd.DataFrame:
        """Largest fold-mean share of a shadow feature, per response (rows) and importance type."""
        imp = self.importances
        sh = imp[(imp["model"] == "shadow") & imp["feature"].str.startswith(SHADOW_PREFIX)]
        if sh.empty:
            return pd.DataFrame(index=list(self.responses), columns=list(IMPORTANCE_TYPES), dtype=float)
        means = sh.groupby(["response", "importance", "feature"])["share"].mean()
        tab = means.groupby(["response", "importance"]).max().unstack("importance")
        return tab.reindex(index=list(self.responses), columns=list(IMPORTANCE_TYPES))

    @property
    def cv_r2(self) -> pd.DataFrame:
        """Validation R² of the XGBoost models: mean, std (ddof=1) and one column per fold."""
        per_fold = self.cv.pivot(index="response", columns="fold", values="r2")
        per_fold.columns = [f"fold{c}" for c in per_fold.columns]
        out = pd.DataFrame({"mean": per_fold.mean(axis=1), "std": per_fold.std(axis=1, ddof=1)})
        return pd.concat([out, per_fold], axis=1).reindex(list(self.responses))

    def selected_by(self, importance: str | None = None, threshold: float | None = None
                    ) -> dict[str, tuple[str, ...]]:
        """Parameters whose fold-mean share exceeds ``threshold`` %, per response, largest first."""
        importance = importance or self.importance
        threshold = self.threshold if threshold is None else float(threshold)
        tab = self.share(importance)
        return {r: tuple(tab[r][tab[r] > threshold].sort_values(ascending=False).index)
                for r in self.responses}

    def shadow_model_share(self, importance: str | None = None) -> pd.DataFrame:
        """Fold-mean share (%) of each parameter in the shadow model (rows: parameters,
        columns: responses; normalised over parameters and shadows together)."""
        importance = importance or self.importance
        imp = self.importances
        sh = imp[(imp["model"] == "shadow") & (imp["importance"] == importance)
                 & ~imp["feature"].str.startswith(SHADOW_PREFIX)]
        tab = sh.pivot_table(index="feature", columns="response", values="share",
                             aggfunc="mean", dropna=False)
        return tab.reindex(index=list(self.params), columns=list(self.responses))

    def above_noise(self, importance: str = NOISE_IMPORTANCE) -> dict[str, tuple[str, ...]]:
        """Parameters whose shadow-model share exceeds the largest shadow share, per
        response, in decreasing main-model share (empty without the shadow model)."""
        share, noise = self.share(importance), self.shadow_max
        inside = self.shadow_model_share(importance)
        out = {}
        for r in self.responses:
            bar = noise.loc[r, importance]
            keep = inside[r] > bar if np.isfinite(bar) else pd.Series(False, index=inside.index)
            out[r] = tuple(share[r][keep.reindex(share.index, fill_value=False)]
                           .sort_values(ascending=False).index)
        return out

    def rule_of(self, response: str) -> str:
        return self.rules.get(response, "threshold")

    @property
    def selected(self) -> dict[str, tuple[str, ...]]:
        """Regression candidates per response under its rule (:data:`RULES`)."""
        by_share = self.selected_by()
        if set(self.rules.values()) <= {"threshold"}:
            return by_share
        noisy = self.above_noise() if "above_noise" in self.rules.values() else {}
        share = self.share(self.importance)
        out = {}
        for r in self.responses:
            rule = self.rule_of(r)
            if rule == "threshold":
                out[r] = by_share[r]
                continue
            keep = set(share.index) if rule == "all" else set(by_share[r]) | set(noisy[r])
            out[r] = tuple(p for p in share[r].sort_values(ascending=False).index if p in keep)
        return out

    def to_frame(self) -> pd.DataFrame:
        """Tidy table indexed by (response, parameter): mean and std share of every importance
        type, the shadow maximum of every type and whether the parameter is selected."""
        parts = {}
        for kind in IMPORTANCE_TYPES:  # DataFrame.unstack() -> Series indexed (response, parameter)
            parts[f"{kind}_mean"] = self.share(kind).unstack()
            parts[f"{kind}_std"] = self.share_std(kind).unstack()
        out = pd.DataFrame(parts)
        out.index.names = ["response", "parameter"]
        shadow = self.shadow_max
        for kind in IMPORTANCE_TYPES:
            out[f"{kind}_shadow_max"] = [shadow.loc[r, kind] for r, _ in out.index]
        sel = self.selected
        out["selected"] = [p in sel[r] for r, p in out.index]
        return out

    def summary(self) -> str:
        """Plain-text report: rows used, CV R², shares of every type, shadow maxima, selection."""
        lines = [f"XGBoost screening: {self.rows['n_used']} rows used, {self.rows['n_dropped']} dropped "
                 f"({self.rows['n_failed']} not ok: failed, invalid or missing runs; "
                 f"{self.rows['n_missing']} missing values); "
                 f"{self.settings.get('n_splits')}-fold shuffled CV, seed {self.settings.get('seed')}"]
        lines += [f"  {r}: screened on its own rows: {n['n_used']} used, {n['n_dropped']} dropped "
                  f"({n['n_failed']} not ok: failed, invalid or missing runs; "
                  f"{n['n_missing']} missing values)"
                  for r, n in self.response_rows.items()]
        lines += ["", "Validation R² of the XGBoost models:", self.cv_r2.round(3).to_string(), ""]
        for kind in IMPORTANCE_TYPES:
            mean, std = self.share(kind), self.share_std(kind)
            tab = mean.round(2).astype(str) + " ± " + std.round(2).astype(str)
            lines += [f"Importance share (%), {kind} (mean ± std over folds):", tab.to_string(), ""]
        lines += ["Largest shadow (noise) share (%):", self.shadow_max.round(2).to_string(), ""]
        if "above_noise" in self.rules.values():
            lines += [f"Share (%) of {NOISE_IMPORTANCE} in the shadow model (beside the shadows):",
                      self.shadow_model_share(NOISE_IMPORTANCE).round(2).to_string(), ""]
        lines += [f"Selected (share of {self.importance} > {self.threshold:g} %; "
                  "'above noise': also above the largest shadow share of shap in the shadow model; "
                  "'all': every parameter):"]
        lines += [f"  {r} ({self.rule_of(r).replace('_', ' ')}): {', '.join(s) if s else '(none)'}"
                  for r, s in self.selected.items()]
        return "\n".join(lines)


def combine(first: ScreeningResults, *others: ScreeningResults) -> ScreeningResults:
    """One result of screenings of different responses over the same parameters, with the
    same threshold and importance type, fitted on different rows (e.g. sigma_t on the
    samples whose Brazilian test is ok): the responses of ``others`` follow those of
    ``first``, their row counts are kept in ``response_rows`` and their selection rules in
    ``rules``. Each response's shares
    are its own screening's (a response's random stream does not depend on the others)."""
    resp, rows = list(first.responses), dict(first.response_rows)
    rules = {r: first.rule_of(r) for r in first.responses}
    for o in others:
        if o.params != first.params or o.threshold != first.threshold or \
                o.importance != first.importance:
            raise ValueError("combine: the screenings differ in parameters, threshold or "
                             "importance type")
        dup = set(o.responses) & set(resp)
        if dup:
            raise ValueError(f"combine: response(s) {sorted(dup)} screened twice")
        resp += list(o.responses)
        rows.update({r: dict(o.rows) for r in o.responses})
        rules.update({r: o.rule_of(r) for r in o.responses})
    return ScreeningResults(
        params=first.params, responses=tuple(resp), threshold=first.threshold,
        importance=first.importance,
        importances=pd.concat([first.importances, *(o.importances for o in others)],
                              ignore_index=True),
        cv=pd.concat([first.cv, *(o.cv for o in others)], ignore_index=True),
        rows=dict(first.rows), settings=dict(first.settings), response_rows=rows,
        rules=rules)


def table3(results: ScreeningResults, importance: str = "gain", symbols: bool = False) -> pd.DataFrame:
    """The paper's Table 3: rows = the meso-parameters (paper order), columns = responses,
    values = fold-mean importance share in percent. With ``symbols`` the labels are the
    paper's symbols (``τcp``, ``σc (%)``, ...)."""
    tab = results.share(importance)
    if symbols:
        tab = tab.rename(index=symbol, columns=lambda r: f"{symbol(r)} (%)")
        tab.index.name = "Meso-parameters"
    return tab


def table3_markdown(results: ScreeningResults, importance: str = "gain", floatfmt: str = ".4f") -> str:
    """Table 3 as a Markdown table with the paper's symbols and 4 decimals."""
    return markdown_table(table3(results, importance, symbols=True), floatfmt=floatfmt)
