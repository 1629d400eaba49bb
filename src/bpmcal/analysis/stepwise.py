"""Stepwise polynomial regression of the macro responses on the screened meso-parameters
(paper section 3.2, section 4.1.2-4.1.4, Table 4 and the regression equations).

Terms
    A term is a tuple of parameter names: ``("pb_coh_MPa",)`` a main effect,
    ``("pb_kratio", "pb_kratio")`` a quadratic term, ``("pb_coh_MPa", "pb_ten_MPa")`` a
    two-way interaction. Its name is ``pb_coh_MPa``, ``pb_kratio^2`` or
    ``pb_coh_MPa*pb_ten_MPa``; factors are ordered as the response's candidate list.

Stages (cumulative candidate pools, per response; candidates = its screened parameters)
    ``main`` main effects; ``quadratic`` + squares of the candidates; ``interaction`` +
    pairwise products of the candidates. Each stage starts from the terms retained by the
    previous stage (the paper builds each stage on the previous one) and runs the
    bidirectional selection below over its pool; retained terms of earlier stages may be
    removed again.

Bidirectional selection (OLS, statsmodels)
    *Forward*: among pool terms not in the model that are admissible under the hierarchy
    policy, a term may enter only if (i) its t-test p-value in the enlarged model is
    ``< alpha_in`` (0.05), (ii) the adjusted R² strictly increases and (iii) no term of the
    enlarged model has a VIF above ``vif_max``. Of the admissible terms the one with the
    smallest p-value enters (for equal model size that is also the largest adjusted-R²
    gain). *Backward*, after each entry: the removable term with the largest p-value is
    dropped while that p-value is ``> alpha_out`` (0.05). ``alpha_out >= alpha_in`` is
    required (a term that just entered is then never removed at once).
    *Cycling guard*: every model (set of terms) visited is remembered and a forward step
    that would recreate a visited model is not taken, so a removal is never undone into a
    loop; since the number of models is finite the procedure terminates (``max_steps`` is a
    further cap, recorded in the step log when hit).

Collinearity
    Variance inflation factors are computed on *centred* terms: each raw variable is
    centred at its sample mean before squares and products are formed (so ``x`` and ``x²``
    are not spuriously collinear), then ``VIF_j = 1 / (1 - R²_j)`` with ``R²_j`` from
    regressing term ``j`` on the others with an intercept. Default limit ``vif_max = 10``
    (the common rule of thumb for serious collinearity); the final VIFs are in the
    coefficient tables.

Hierarchy policy (``hierarchy``; default ``"strong"``)
    ``"strong"``: ``x²`` needs ``x`` in the model and ``x·z`` needs both ``x`` and ``z``;
    ``"weak"``: ``x²`` needs ``x`` and ``x·z`` needs ``x`` or ``z``; ``"none"``: no
    constraint (what the paper's printed stage-2 ``σc`` equation implies: it keeps
    ``kp*²`` without ``kp*``). Under a heredity policy a main effect is protected from
    backward removal while a retained higher-order term needs it, whatever its p-value.
    Reason: in physical (uncentred) units the p-value of ``x`` in a model containing ``x²``
    or ``x·z`` tests the slope at ``x = 0`` (outside the sampled range) and changes with
    the origin of the units, whereas with strong heredity every other p-value and the
    adjusted R² are invariant to shifts of the units. A consequence: a purely quadratic
    effect whose linear trend is insignificant cannot enter under heredity.

Final models are fitted by OLS in *physical (uncentred) paper units*, so the equations read
like the paper's, e.g.
``ucs_MPa = 2.20·pb_coh_MPa + 1.51·pb_ten_MPa − 428.14·porosity − 11.53·pb_kratio + 115.54``.
Each model reports coefficients with standard errors, t, p and 95 % confidence intervals,
VIFs, R², adjusted R², a repeated k-fold cross-validated R² (pooled out-of-fold
predictions per repetition; the terms are those selected on all rows, so the CV R² does not
include the selection step and is somewhat optimistic), the statsmodels summary text,
predictions and analytical partial derivatives (for Newton steps in the calibration).
:meth:`StepwiseResults.to_dict` / :meth:`StepwiseResults.from_dict` give a JSON-ready
round trip (``results/regression/models.json``).
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
import pandas as pd
import statsmodels.api as sm

from bpmcal.io.tables import markdown_table
from bpmcal.params import ParameterError

from ._common import (
    check_params,
    check_responses,
    kfold_indices,
    symbol,
    usable_rows,
)

Term = tuple[str, ...]
STAGES: tuple[str, ...] = ("main", "quadratic", "interaction")
HIERARCHIES: tuple[str, ...] = ("strong", "weak", "none")
TABLE_COLUMNS: tuple[str, ...] = ("coef", "std_err", "t", "p_value", "ci_low", "ci_high", "vif")
STEP_COLUMNS: tuple[str, ...] = ("response", "stage", "step", "action", "term", "p_value", "adj_r2",
                                 "n_terms", "note")
FORMAT = "bpmcal.stepwise/1"


# -- terms ----------------------------------------------------------------------------------
def term_name(term: Term) -> str:
    """``a``, ``a^2`` or ``a*b``."""
    if len(term) == 1:
        return term[0]
    if len(term) == 2:
        return f"{term[0]}^2" if term[0] == term[1] else f"{term[0]}*{term[1]}"
    raise ValueError(f"term {term!r}: expected one or two factors")


def parse_term(name: str | Sequence[str]) -> Term:
    """Inverse of :func:`term_name`; also accepts a tuple/list of factor names."""
    if isinstance(name, str):
        if name.endswith("^2"):
            factors: Sequence[str] = (name[:-2], name[:-2])
        else:
            factors = tuple(name.split("*"))
    else:
        factors = tuple(name)
    if not 1 <= len(factors) <= 2:
        raise ValueError(f"term {name!r}: expected 'x', 'x^2' or 'x*z'")
    check_params(set(factors), "term factor")
    return tuple(factors)


def term_label(term: Term, symbols: bool = False, ascii: bool = False) -> str:
    """Human-readable term: ``τcp·σcp``, ``kp*²`` (symbols) or ``pb_kratio^2`` (ascii)."""
    names = [symbol(f) if symbols else f for f in term]
    if len(term) == 2 and term[0] == term[1]:
        return names[0] + ("^2" if ascii else "²")
    return ("*" if ascii else "·").join(names)


def _kind(term: Term) -> str:
    return "main" if len(term) == 1 else ("quadratic" if term[0] == term[1] else "interaction")


def stage_pool(candidates: Sequence[str], stage: str) -> list[Term]:
    """All candidate terms of a stage (cumulative), in canonical order."""
    if stage not in STAGES:
        raise ValueError(f"stage={stage!r}: expected one of {STAGES}")
    level = STAGES.index(stage)
    pool: list[Term] = [(c,) for c in candidates]
    if level >= 2:
        pool += list(combinations(candidates, 2))
    if level >= 1:
        pool += [(c, c) for c in candidates]
    return pool


def _canonical(terms, candidates: Sequence[str]) -> tuple[Term, ...]:
    """Mains, then interactions, then squares (the paper's order); within each by candidate order."""
    rank = {c: i for i, c in enumerate(candidates)}
    order = {"main": 0, "interaction": 1, "quadratic": 2}
    return tuple(sorted(terms, key=lambda t: (order[_kind(t)], [rank.get(f, len(rank)) for f in t])))


def _columns(X, names) -> tuple[dict[str, np.ndarray], bool]:
    """Columns of a DataFrame or a mapping of scalars/arrays; flag True for scalar input."""
    missing = [n for n in names if n not in X]
    if missing:
        raise ParameterError(f"missing parameter(s) {missing} needed by the model")
    cols = {n: np.asarray(X[n], dtype=float) for n in names}
    scalar = not isinstance(X, pd.DataFrame) and all(c.ndim == 0 for c in cols.values())
    return {n: np.atleast_1d(c) for n, c in cols.items()}, scalar


def design_matrix(X, terms: Sequence[Term], center: Mapping[str, float] | None = None) -> np.ndarray:
    """Matrix of the term columns (no intercept) of a DataFrame or mapping; with ``center``
    each raw variable is shifted by ``center[name]`` before products are formed."""
    names = sorted({f for t in terms for f in t})
    cols, _ = _columns(X, names)
    if center is not None:
        cols = {n: c - center[n] for n, c in cols.items()}
    n = len(next(iter(cols.values()))) if cols else len(X)
    out = np.ones((n, len(terms)))
    for j, t in enumerate(terms):
        for f in t:
            out[:, j] = out[:, j] * cols[f]
    return out


def vif(X, terms: Sequence[Term]) -> np.ndarray:
    """Variance inflation factors of ``terms`` on centred variables (see module docstring).

    ``X`` is a DataFrame of the raw parameters; each variable is centred at its mean before
    squares/products are formed. Returns ``inf`` for an exactly collinear term.
    """
    terms = list(terms)
    if len(terms) <= 1:
        return np.ones(len(terms))
    names = sorted({f for t in terms for f in t})
    center = {n: float(np.mean(X[n])) for n in names}
    Z = design_matrix(X, terms, center)
    out = np.empty(len(terms))
    for j in range(len(terms)):
        z = Z[:, j]
        A = np.column_stack([np.ones(len(z)), np.delete(Z, j, axis=1)])
        resid = z - A @ np.linalg.lstsq(A, z, rcond=None)[0]
        ss_tot = float(np.sum((z - z.mean()) ** 2))
        ss_res = float(np.sum(resid**2))
        out[j] = math.inf if ss_res <= 1e-12 * ss_tot else ss_tot / ss_res
    return out


def _lstsq(X: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    A = np.column_stack([np.ones(len(y)), X])
    beta = np.linalg.lstsq(A, y, rcond=None)[0]
    return float(beta[0]), beta[1:]


def cv_r2(X: np.ndarray, y: np.ndarray, n_splits: int, n_repeats: int, seed: int) -> np.ndarray:
    """Repeated k-fold CV R² of OLS with intercept on fixed columns ``X``: for each repetition
    1 - Σ(y - ŷ_oof)² / Σ(y - ȳ)² over the pooled out-of-fold predictions."""
    rng = np.random.default_rng(seed)
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    out = np.empty(n_repeats)
    for r in range(n_repeats):
        pred = np.empty(len(y))
        for tr, va in kfold_indices(len(y), n_splits, rng):
            b0, b = _lstsq(X[tr], y[tr])
            pred[va] = b0 + X[va] @ b
        out[r] = 1.0 - float(np.sum((y - pred) ** 2)) / ss_tot
    return out


def _jsonable(v):
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


# -- one fitted model -----------------------------------------------------------------------
@dataclass(eq=False)
class RegressionModel:
    """A polynomial regression model ``response = intercept + Σ coef_t · term_t`` in paper
    units, with its fit statistics (``None``/empty when fitted without statistics)."""

    response: str
    terms: tuple[Term, ...]
    coef: np.ndarray
    intercept: float
    stage: str = ""
    table: pd.DataFrame | None = None  # index Intercept + term names, columns TABLE_COLUMNS
    r2: float | None = None
    adj_r2: float | None = None
    cv_r2: tuple[float, ...] = ()
    n_obs: int | None = None
    summary_text: str = ""
    ols: object = field(default=None, repr=False, compare=False)  # statsmodels results

    def __post_init__(self):
        self.terms = tuple(tuple(t) for t in self.terms)
        self.coef = np.asarray(self.coef, dtype=float).reshape(len(self.terms))
        self.intercept = float(self.intercept)
        self._params = tuple(dict.fromkeys(f for t in self.terms for f in t))

    @property
    def params(self) -> tuple[str, ...]:
        """Meso-parameters the model depends on (order of first appearance)."""
        return self._params

    @property
    def term_names(self) -> tuple[str, ...]:
        return tuple(term_name(t) for t in self.terms)

    @property
    def cv_r2_mean(self) -> float | None:
        return float(np.mean(self.cv_r2)) if self.cv_r2 else None

    @property
    def cv_r2_std(self) -> float | None:
        return float(np.std(self.cv_r2, ddof=1)) if len(self.cv_r2) > 1 else None

    def design(self, X) -> np.ndarray:
        """The model's term columns (no intercept) for a DataFrame or mapping."""
        return design_matrix(X, self.terms)

    def predict(self, X):
        """Predicted response for a DataFrame (array) or a mapping of scalars (float)."""
        _, scalar = _columns(X, self.params)
        if self.terms:
            y = self.intercept + self.design(X) @ self.coef
        else:
            y = np.full(len(X) if isinstance(X, pd.DataFrame) else 1, self.intercept)
        return float(y[0]) if scalar else y

    def gradient(self, X) -> dict[str, np.ndarray | float]:
        """Analytical partial derivatives ∂response/∂parameter for every parameter of the
        model, at the rows of a DataFrame (arrays) or at a mapping of scalars (floats)."""
        cols, scalar = _columns(X, self.params)
        out = {}
        for p in self.params:
            g = 0.0
            for c, t in zip(self.coef, self.terms):
                for i, f in enumerate(t):
                    if f == p:
                        rest = [cols[h] for k, h in enumerate(t) if k != i]
                        g = g + c * (np.prod(rest, axis=0) if rest else 1.0)
            g = np.broadcast_to(np.asarray(g, float), np.shape(next(iter(cols.values()))))
            out[p] = float(g[0]) if scalar else np.array(g)
        return out

    def partials(self, df: pd.DataFrame) -> pd.DataFrame:
        """:meth:`gradient` as a DataFrame (one column ``d<response>/d<parameter>`` each)."""
        return pd.DataFrame({f"d{self.response}/d{p}": g for p, g in self.gradient(df).items()},
                            index=df.index)

    def equation(self, symbols: bool = False, digits: int = 3, ascii: bool = False) -> str:
        """``response = c1·term1 + ... + intercept`` (terms in the paper's order). Numbers
        with |value| >= 1 get 2 decimals, smaller ones ``digits`` significant figures."""
        def num(v: float) -> str:
            return f"{abs(v):.2f}" if abs(v) >= 1 else f"{abs(v):.{digits}g}"

        minus, times = ("-", "*") if ascii else ("−", "·")
        parts = [(c, f"{num(c)}{times}{term_label(t, symbols, ascii)}")
                 for c, t in zip(self.coef, self.terms)]
        parts.append((self.intercept, num(self.intercept)))
        rhs = ""
        for i, (c, text) in enumerate(parts):
            sign = (minus if c < 0 else "") if i == 0 else (f" {minus} " if c < 0 else " + ")
            rhs += sign + text
        return f"{symbol(self.response) if symbols else self.response} = {rhs}"

    def summary(self) -> str:
        """The statsmodels summary text (empty for models fitted without statistics)."""
        return self.summary_text

    def with_coefficients(self, intercept: float, coef) -> RegressionModel:
        """The same terms with other coefficients (no statistics)."""
        return RegressionModel(self.response, self.terms, coef, intercept, stage=self.stage)

    def refit(self, df: pd.DataFrame) -> RegressionModel:
        """Least-squares refit of the same terms on the usable rows of other data, without
        statistics (fast)."""
        df = usable_rows(df, list(self.params) + [self.response]).data
        b0, b = _lstsq(self.design(df), np.asarray(df[self.response], float))
        return self.with_coefficients(b0, b)

    def to_dict(self) -> dict:
        """JSON-serialisable representation (non-finite numbers become ``None``)."""
        table = None
        if self.table is not None:
            table = [{"term": idx, **{c: _jsonable(row[c]) for c in TABLE_COLUMNS}}
                     for idx, row in self.table.iterrows()]
        return {
            "response": self.response, "stage": self.stage, "intercept": self.intercept,
            "terms": [{"name": term_name(t), "factors": list(t), "coef": float(c)}
                      for t, c in zip(self.terms, self.coef)],
            "table": table, "r2": _jsonable(self.r2), "adj_r2": _jsonable(self.adj_r2),
            "cv_r2": [float(v) for v in self.cv_r2], "n_obs": self.n_obs, "summary": self.summary_text,
        }

    @classmethod
    def from_dict(cls, d: Mapping) -> RegressionModel:
        check_responses([d["response"]])
        terms = [parse_term(t["factors"]) for t in d["terms"]]
        table = None
        if d.get("table") is not None:
            table = pd.DataFrame.from_records(d["table"]).set_index("term")
            table = table.reindex(columns=list(TABLE_COLUMNS)).astype(float)
            table.index.name = None
        return cls(d["response"], terms, [t["coef"] for t in d["terms"]], d["intercept"],
                   stage=d.get("stage", ""), table=table, r2=d.get("r2"), adj_r2=d.get("adj_r2"),
                   cv_r2=tuple(d.get("cv_r2") or ()), n_obs=d.get("n_obs"),
                   summary_text=d.get("summary", ""))


def fit_terms(df: pd.DataFrame, response: str, terms: Sequence, *, stage: str = "",
              cv_folds: int = 5, cv_repeats: int = 10, seed: int = 0) -> RegressionModel:
    """OLS fit (statsmodels) of ``response`` on the given terms in physical units, with the full
    statistics (coefficient table with 95 % CIs and centred VIFs, R², adjusted R², repeated
    k-fold CV R² unless ``cv_folds == 0``, summary text) on the usable rows of ``df``
    (``status == "ok"``, finite values). Terms may be tuples or names (``"a"``, ``"a^2"``,
    ``"a*b"``)."""
    terms = tuple(parse_term(t) for t in terms)
    check_responses([response])
    df = usable_rows(df, list(dict.fromkeys(f for t in terms for f in t)) + [response]).data
    y = np.asarray(df[response], float)
    X = design_matrix(df, terms)
    if len(y) <= len(terms) + 1:
        raise ValueError(f"{len(y)} rows are too few for {len(terms)} terms plus an intercept")
    names = [term_name(t) for t in terms]
    res = sm.OLS(y, np.column_stack([np.ones(len(y)), X])).fit()
    ci = np.asarray(res.conf_int(alpha=0.05))
    table = pd.DataFrame({"coef": res.params, "std_err": res.bse, "t": res.tvalues, "p_value": res.pvalues,
                          "ci_low": ci[:, 0], "ci_high": ci[:, 1],
                          "vif": np.concatenate([[np.nan], vif(df, terms)])},
                         index=["Intercept"] + names)
    cv = cv_r2(X, y, cv_folds, cv_repeats, seed) if cv_folds else np.array([])
    with warnings.catch_warnings():  # statsmodels warns about small n / kurtosis tests
        warnings.simplefilter("ignore")
        text = _timeless(res.summary(yname=response, xname=["Intercept"] + names).as_text())
    return RegressionModel(response, terms, res.params[1:], res.params[0], stage=stage, table=table,
                           r2=float(res.rsquared), adj_r2=float(res.rsquared_adj),
                           cv_r2=tuple(float(v) for v in cv), n_obs=len(y), summary_text=text, ols=res)


# -- the selection --------------------------------------------------------------------------
class StepwiseRegression:
    """Three-stage bidirectional stepwise regression (see the module docstring).

    Parameters
    ----------
    stages:
        Subsequence of ``("main", "quadratic", "interaction")``, in that order.
    alpha_in, alpha_out:
        Entry and removal p-value thresholds (0.05, 0.05); ``alpha_out >= alpha_in``.
    vif_max:
        A term is not admitted if any VIF (centred terms) of the enlarged model exceeds it (10).
    hierarchy:
        ``"strong"`` (default), ``"weak"`` or ``"none"``.
    cv_folds, cv_repeats, seed:
        Repeated k-fold CV R² of every stage model (5 folds × 10 repetitions; 0 folds = off;
        seed 12, the default study's ``regression.seed``).
    max_steps:
        Cap on forward steps per stage.
    """

    def __init__(self, *, stages: Sequence[str] = STAGES, alpha_in: float = 0.05, alpha_out: float = 0.05,
                 vif_max: float = 10.0, hierarchy: str = "strong", cv_folds: int = 5, cv_repeats: int = 10,
                 seed: int = 12, max_steps: int = 100):
        stages = tuple(stages)
        ordered = all(s in STAGES for s in stages) and list(stages) == sorted(stages, key=STAGES.index)
        if not stages or not ordered or len(set(stages)) != len(stages):
            raise ValueError(f"stages={stages!r}: expected a non-empty ordered subsequence of {STAGES}")
        for name, a in (("alpha_in", alpha_in), ("alpha_out", alpha_out)):
            if not 0.0 < float(a) < 1.0:
                raise ValueError(f"{name}={a!r}: expected a probability in (0, 1)")
        if alpha_out < alpha_in:
            raise ValueError(f"alpha_out={alpha_out!r} < alpha_in={alpha_in!r}: a term could enter and be "
                             "removed at once; expected alpha_out >= alpha_in")
        if not float(vif_max) > 1.0:
            raise ValueError(f"vif_max={vif_max!r}: expected a number > 1 (VIF >= 1 by definition)")
        if hierarchy not in HIERARCHIES:
            raise ValueError(f"hierarchy={hierarchy!r}: expected one of {HIERARCHIES}")
        if cv_folds and (cv_folds < 2 or cv_repeats < 1):
            raise ValueError(f"cv_folds={cv_folds!r}, cv_repeats={cv_repeats!r}: expected 0 (off) or "
                             ">= 2 folds and >= 1 repetition")
        self.stages = stages
        self.alpha_in, self.alpha_out = float(alpha_in), float(alpha_out)
        self.vif_max = float(vif_max)
        self.hierarchy = hierarchy
        self.cv_folds, self.cv_repeats = int(cv_folds), int(cv_repeats)
        self.seed = int(seed)
        self.max_steps = int(max_steps)

    def settings(self) -> dict:
        return {"stages": list(self.stages), "alpha_in": self.alpha_in, "alpha_out": self.alpha_out,
                "vif_max": self.vif_max, "hierarchy": self.hierarchy, "cv_folds": self.cv_folds,
                "cv_repeats": self.cv_repeats, "seed": self.seed, "max_steps": self.max_steps}

    # hierarchy ---------------------------------------------------------------------------
    def _parents_ok(self, term: Term, model: set) -> bool:
        if len(term) == 1 or self.hierarchy == "none":
            return True
        a, b = term
        if a == b:
            return (a,) in model
        if self.hierarchy == "strong":
            return (a,) in model and (b,) in model
        return (a,) in model or (b,) in model

    def _removable(self, term: Term, model: set) -> bool:
        rest = model - {term}
        return all(self._parents_ok(t, rest) for t in rest)

    # one stage -----------------------------------------------------------------------------
    def _select(self, data: pd.DataFrame, response: str, pool: list[Term], start: list[Term],
                stage: str, log: list[dict]) -> list[Term]:
        y = data[response].to_numpy(float)
        cols = {t: design_matrix(data, [t])[:, 0] for t in pool}

        def ols(terms):
            A = np.column_stack([np.ones(len(y))] + [cols[t] for t in terms])
            return sm.OLS(y, A).fit()

        def record(action, term, p, res, note=""):
            log.append({"response": response, "stage": stage, "step": len(log), "action": action,
                        "term": term_name(term), "p_value": p, "adj_r2": float(res.rsquared_adj),
                        "n_terms": int(res.df_model), "note": note})

        model = list(start)
        visited = {frozenset(model)}
        current = ols(model)
        for _ in range(self.max_steps):
            best = None
            for t in pool:
                if t in model or not self._parents_ok(t, set(model)) or frozenset(model + [t]) in visited:
                    continue
                res = ols(model + [t])
                p = float(res.pvalues[-1])
                if not (p < self.alpha_in and res.rsquared_adj > current.rsquared_adj):
                    continue
                v = float(np.max(vif(data, model + [t])))
                if v > self.vif_max:
                    record("blocked", t, p, res, f"max VIF {v:.3g} > {self.vif_max:g}")
                    continue
                if best is None or p < best[0]:
                    best = (p, t, res)
            if best is None:
                break
            p, t, current = best
            model.append(t)
            visited.add(frozenset(model))
            record("enter", t, p, current)
            while True:
                pv = {tm: float(current.pvalues[i + 1]) for i, tm in enumerate(model)}
                out = [tm for tm in model if pv[tm] > self.alpha_out and self._removable(tm, set(model))]
                if not out:
                    break
                worst = max(out, key=pv.get)
                model.remove(worst)
                visited.add(frozenset(model))
                current = ols(model)
                record("remove", worst, pv[worst], current)
        else:
            record("stop", model[-1] if model else ("-",), float("nan"), current,
                   f"max_steps={self.max_steps} reached")
        return model

    def fit(self, df: pd.DataFrame, candidates: Mapping[str, Sequence[str]]) -> StepwiseResults:
        """Run the stages for every response in ``candidates`` (response -> screened
        parameters, e.g. :attr:`ScreeningResults.selected`) on the usable rows of ``df``."""
        if not candidates:
            raise ValueError("candidates is empty: expected a mapping response -> parameter names")
        cands = {r: check_params(c, "candidate") for r, c in candidates.items()}
        check_responses(cands)
        needed = list(dict.fromkeys([p for c in cands.values() for p in c] + list(cands)))
        rows = usable_rows(df, needed)
        data = rows.data
        models: dict[str, dict[str, RegressionModel]] = {}
        log: list[dict] = []
        for response, cand in cands.items():
            models[response] = {}
            terms: list[Term] = []
            for stage in self.stages:
                terms = self._select(data, response, stage_pool(cand, stage), terms, stage, log)
                terms = list(_canonical(terms, cand))
                models[response][stage] = fit_terms(data, response, terms, stage=stage,
                                                    cv_folds=self.cv_folds, cv_repeats=self.cv_repeats,
                                                    seed=self.seed)
        steps = pd.DataFrame.from_records(log, columns=list(STEP_COLUMNS))
        return StepwiseResults(models=models, candidates=cands, steps=steps, rows=rows.describe(),
                               settings=self.settings())


# -- results --------------------------------------------------------------------------------
@dataclass
class StepwiseResults:
    """Results of :meth:`StepwiseRegression.fit`: ``models[response][stage]`` are
    :class:`RegressionModel` objects; ``steps`` logs every entry, removal and VIF block;
    ``rows`` holds the row counts (``n_used``, ``n_dropped``, ...); ``settings`` the rules
    used (including the hierarchy policy)."""

    models: dict[str, dict[str, RegressionModel]]
    candidates: dict[str, tuple[str, ...]]
    steps: pd.DataFrame
    rows: dict[str, int]
    settings: dict
    #: row counts of responses fitted on other rows than ``rows`` (:func:`combine`)
    response_rows: dict[str, dict[str, int]] = field(default_factory=dict)

    @property
    def n_dropped(self) -> int:
        return self.rows["n_dropped"]

    @property
    def responses(self) -> tuple[str, ...]:
        return tuple(self.models)

    @property
    def final_models(self) -> dict[str, RegressionModel]:
        """The last stage's model of every response (what the calibration inverts)."""
        return {r: list(st.values())[-1] for r, st in self.models.items()}

    def model(self, response: str, stage: str | None = None) -> RegressionModel:
        if response not in self.models:
            raise KeyError(f"no model for response {response!r}; have {list(self.models)}")
        return self.final_models[response] if stage is None else self.models[response][stage]

    def predict(self, df: pd.DataFrame, stage: str | None = None) -> pd.DataFrame:
        """Predictions of every response (columns) for the rows of ``df``."""
        return pd.DataFrame({r: self.model(r, stage).predict(df) for r in self.models}, index=df.index)

    def fit_table(self) -> pd.DataFrame:
        """Per response and stage: number of terms, R², adjusted R², CV R² mean and std."""
        recs = [{"response": r, "stage": s, "n_terms": len(m.terms), "r2": m.r2, "adj_r2": m.adj_r2,
                 "cv_r2_mean": m.cv_r2_mean, "cv_r2_std": m.cv_r2_std, "n_obs": m.n_obs}
                for r, st in self.models.items() for s, m in st.items()]
        return pd.DataFrame.from_records(recs).set_index(["response", "stage"])

    def to_frame(self) -> pd.DataFrame:
        """Long coefficient table: response, stage, term, coef, std_err, t, p_value, ci_low,
        ci_high, vif."""
        parts = []
        for r, st in self.models.items():
            for s, m in st.items():
                if m.table is None:
                    tab = pd.DataFrame({"coef": [m.intercept, *m.coef]}, index=["Intercept", *m.term_names])
                    tab = tab.reindex(columns=list(TABLE_COLUMNS))
                else:
                    tab = m.table
                parts.append(tab.rename_axis("term").reset_index().assign(response=r, stage=s))
        out = pd.concat(parts, ignore_index=True)
        return out[["response", "stage", "term", *TABLE_COLUMNS]]

    def equations(self, stage: str | None = None, symbols: bool = False,
                  ascii: bool = False) -> dict[str, str]:
        """Equation string per response (final stage unless ``stage`` is given)."""
        return {r: self.model(r, stage).equation(symbols=symbols, ascii=ascii) for r in self.models}

    def table4_terms(self, which: str = "retained", symbols: bool = False) -> pd.DataFrame:
        """The paper's Table 4 layout: per response, the interaction and the quadratic terms
        (``"-"`` when none). ``which="retained"`` lists the terms of the final model;
        ``"candidates"`` the full candidate set built from the screened parameters (the
        paper's Table 4 appears to list the latter: for σc it shows all 6 products and 4
        squares while its final equation keeps 2 and 2)."""
        if which not in ("retained", "candidates"):
            raise ValueError(f"which={which!r}: expected 'retained' or 'candidates'")
        recs = {}
        for r, cand in self.candidates.items():
            terms = self.model(r).terms if which == "retained" else stage_pool(cand, "interaction")
            cell = {k: ", ".join(term_label(t, symbols) for t in terms if _kind(t) == k) or "-"
                    for k in ("interaction", "quadratic")}
            recs[symbol(r) if symbols else r] = {"Interaction term": cell["interaction"],
                                                 "Quadratic term": cell["quadratic"]}
        out = pd.DataFrame.from_dict(recs, orient="index")
        out.index.name = "Macro-parameters" if symbols else "response"
        return out

    def table4_markdown(self, which: str = "retained") -> str:
        return markdown_table(self.table4_terms(which, symbols=True), floatfmt=".2f")

    def summary(self) -> str:
        """Plain-text report: rules, rows, fit statistics per stage, equations, coefficients."""
        s = self.settings
        lines = [f"Stepwise regression: {self.rows['n_used']} rows used, {self.rows['n_dropped']} dropped "
                 f"({self.rows['n_failed']} not ok: failed, invalid or missing runs; "
                 f"{self.rows['n_missing']} missing values)",
                 f"entry p < {s['alpha_in']:g} and adjusted R² gain; removal p > {s['alpha_out']:g}; "
                 f"VIF (centred terms) <= {s['vif_max']:g}; hierarchy: {s['hierarchy']}",
                 *(f"  {r}: fitted on its own rows: {n['n_used']} used, {n['n_dropped']} "
                   f"dropped ({n['n_failed']} not ok: failed, invalid or missing runs; "
                   f"{n['n_missing']} missing values)"
                   for r, n in self.response_rows.items()),
                 "", self.fit_table().round(4).to_string(), ""]
        for r, st in self.models.items():
            lines.append(f"{r} (candidates: {', '.join(self.candidates[r]) or 'none'})")
            lines += [f"  [{stage}] {m.equation()}" for stage, m in st.items()]
        lines += ["", self.to_frame().round(6).to_string(index=False)]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-serialisable representation of everything but the statsmodels objects."""
        steps = self.steps.astype(object).where(self.steps.notna(), None).to_dict(orient="records")
        d = {"format": FORMAT, "settings": dict(self.settings), "rows": dict(self.rows),
             "candidates": {r: list(c) for r, c in self.candidates.items()},
             "models": {r: {s: m.to_dict() for s, m in st.items()} for r, st in self.models.items()},
             "steps": steps}
        if self.response_rows:
            d["response_rows"] = {r: dict(n) for r, n in self.response_rows.items()}
        return d

    @classmethod
    def from_dict(cls, d: Mapping) -> StepwiseResults:
        if d.get("format") != FORMAT:
            raise ValueError(f"format={d.get('format')!r}: expected {FORMAT!r}")
        models = {r: {s: RegressionModel.from_dict(m) for s, m in st.items()}
                  for r, st in d["models"].items()}
        steps = pd.DataFrame.from_records(d.get("steps") or [], columns=list(STEP_COLUMNS))
        return cls(models=models, candidates={r: tuple(c) for r, c in d["candidates"].items()},
                   steps=steps, rows=dict(d["rows"]), settings=dict(d["settings"]),
                   response_rows={r: dict(n) for r, n in (d.get("response_rows") or {}).items()})


def combine(first: StepwiseResults, *others: StepwiseResults) -> StepwiseResults:
    """One result of regressions of different responses fitted on different rows (e.g.
    sigma_t on the samples whose Brazilian test is ok): the models of ``others`` follow
    those of ``first``; their row counts are kept in ``response_rows``."""
    models, cands = dict(first.models), dict(first.candidates)
    rows = dict(first.response_rows)
    for o in others:
        dup = set(o.models) & set(models)
        if dup:
            raise ValueError(f"combine: response(s) {sorted(dup)} fitted twice")
        models.update(o.models)
        cands.update(o.candidates)
        rows.update({r: dict(o.rows) for r in o.models})
    steps = pd.concat([first.steps, *(o.steps for o in others)], ignore_index=True)
    return StepwiseResults(models=models, candidates=cands, steps=steps, rows=dict(first.rows),
                           settings=dict(first.settings), response_rows=rows)


def models_from_dict(d: Mapping) -> dict[str, RegressionModel]:
    """The final model of every response from a :meth:`StepwiseResults.to_dict` dict (what
    the calibration step needs from ``results/regression/models.json``)."""
    return StepwiseResults.from_dict(d).final_models


__all__ = ["STAGES", "HIERARCHIES", "Term", "term_name", "parse_term", "term_label", "stage_pool",
           "design_matrix", "vif", "cv_r2", "RegressionModel", "fit_terms", "StepwiseRegression",
           "StepwiseResults", "models_from_dict", "combine"]


def _timeless(summary: str) -> str:
    """statsmodels' summary without the wall-clock date and time it stamps in its header
    (``Date:``/``Time:``), so a model file depends on its data only (bit-for-bit reruns)."""
    import re

    def blank(m):  # the stamp's characters as dashes, so the columns stay aligned
        return f"{m.group(1)}:{m.group(2)}" + "-" * len(m.group(3))

    return re.sub(r"(Date|Time):(\s+)(\S.*?)(?=\s{2,}|$)", blank, summary, flags=re.M)
