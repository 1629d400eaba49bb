"""The calibration space: free, fixed and derived parameters, their bounds, the unit cube.

A calibration splits the parameters into *fixed* ones, *free* ones bounded by the design
space (``ranges``, optionally narrowed by ``bounds``) and, with a bond-strength ratio
``a = pb_ten / pb_coh``, the *derived* ``pb_ten_MPa``. :class:`CalibrationSpace` checks
such a split, intersects ``pb_coh_MPa``'s range with ``pb_ten_MPa``'s divided by the
ratio, remembers the configured key every effective bound comes from (for messages
such as "pb_coh_MPa at the upper bound 35.7 (= upper bound 50 of ranges.pb_ten_MPa /
ratio 1.4)") and maps the free parameters to the unit cube. :func:`bts_strengths`
frees the ratio when a tensile strength is a target; :func:`check_calibration_space`
lets a stage reject bad input before it writes anything.

The method: ``docs/methods/calibration.md`` (section "Parametrisation").
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bpmcal import params as P
from bpmcal.params import (
    ALL_PARAMS,
    TENSILE_RESPONSES,
    ContactModel,
    ParameterError,
    model_of,
    validate_params,
)

from .._common import check_params, check_responses
from ..stepwise import RegressionModel

PAPER_RATIO = 1.4


@dataclass(frozen=True)
class SearchSpace:
    """Where a calibration may look (:func:`~.inversion.invert`, :class:`~.closed_loop.ClosedLoop`):
    the design ``ranges`` (parameter -> (lo, hi), paper units; required), the ``free``
    parameters (None: the contact model's default set, plus the tensile strength when
    ``ratio`` is None), the bond-strength ``ratio`` σ/τ (None: both strengths free) and
    optional narrower ``bounds``."""

    ranges: Mapping[str, Sequence[float]]
    free: Sequence[str] | None = None
    ratio: float | None = PAPER_RATIO
    bounds: Mapping[str, Sequence[float]] | None = None
PAPER_FIXED: dict[str, float] = {P.POROSITY: 0.34, P.RMIN: 0.8}
DEFAULT_FREE: tuple[str, ...] = P.LINEARPBOND.free
_TEN, _COH = P.LINEARPBOND.strength


def tensile_target(targets) -> str | None:
    """The tensile strength among ``targets`` (the first of
    :data:`bpmcal.params.TENSILE_RESPONSES`), or None."""
    return next((r for r in TENSILE_RESPONSES if r in targets), None)
_EDGE = 1e-6  # |u| or |1 - u| below this counts as "on the bound"


def space_model(*names) -> ContactModel:
    """The contact model of a calibration: the one whose names its free, fixed and ranged
    parameters use (each argument an iterable of names or a mapping; None skipped)."""
    return model_of([k for group in names if group is not None for k in group
                     if k != "contact_model"])


def _default_free(free: Sequence[str] | None, ratio: float | None,
                  model: ContactModel | None = None) -> tuple[str, ...]:
    """``free``, or the model's default free parameters (:attr:`ContactModel.free`; the
    parallel bond's ``DEFAULT_FREE``), with its tensile strength when no ratio derives it."""
    if free is not None:
        return tuple(free)
    model = model or space_model()
    return model.free if ratio is not None else model.free + (model.ten,)


def bts_strengths(targets: Mapping[str, float], free: Sequence[str] | None, fixed: Mapping[str, float],
                  ratio: float | None) -> tuple[tuple[str, ...] | None, float | None, str]:
    """The free parameters and ratio of a calibration against ``targets``: with a tensile
    strength target (``bts_MPa`` or ``dtt_MPa``) σt sets the bond-strength ratio, so
    the model's tensile strength (``pb_ten_MPa``, ``fj_ten_MPa``) is freed beside its
    cohesion and the ratio is None; without it
    ``free`` and ``ratio`` are returned unchanged. The third value says where the ratio
    comes from: the tensile response, or ``"ratio"`` (the given one: configured, or the
    ratio sweep's choice). ``pb_ten_MPa`` fixed by the user keeps σt a plain target
    (``"ratio"``)."""
    tr = tensile_target(targets)
    model = space_model(free, fixed)
    if tr is None or model.ten in fixed:
        return (tuple(free) if free is not None else None), ratio, "ratio"
    return model.tensile_free(free, fixed), None, tr


class CalibrationSpace:
    """Free parameters <-> unit cube, with fixed values and the strength-ratio constraint.

    ``ranges``: the design space (the sampled ranges, paper units) of every free parameter,
    of ``pb_ten_MPa`` when it is derived, and of any fixed parameter that should be checked;
    ``bounds``: optional narrower limits of free (or derived) parameters. Every effective
    bound remembers which configured range it comes from (:meth:`edge_text`).
    """

    def __init__(self, free, fixed: Mapping[str, float], ratio: float | None,
                 ranges: Mapping[str, Sequence[float]], bounds: Mapping[str, Sequence[float]] | None):
        if ratio is not None:
            ratio = float(ratio)
            if not (math.isfinite(ratio) and ratio > 0):
                raise ParameterError(f"ratio={ratio!r}: expected a positive number σcp/τcp (or None)")
        self.ratio = ratio
        self.model = space_model(free, fixed, ranges)
        self.ten, self.coh = self.model.strength
        self.free = check_params(_default_free(free, ratio, self.model), "free parameter")
        if not self.free:
            raise ParameterError("no free parameter: expected at least one name in free")
        self.fixed = {k: v for k, v in validate_params(dict(fixed), require_all=False).items()
                      if k != "contact_model"}
        both = sorted(set(self.free) & set(self.fixed))
        if both:
            raise ParameterError(f"parameter(s) {both} are both free and fixed")
        if ratio is not None:
            if self.ten in self.free or self.ten in self.fixed:
                raise ParameterError(f"{self.ten} is derived as ratio × {self.coh} (ratio={ratio:g}); "
                                     "remove it from "
                                     "free/fixed or pass ratio=None")
            if self.coh not in self.free and self.coh not in self.fixed:
                raise ParameterError(f"the strength ratio needs {self.coh} to be free or fixed")
        self.ranges = _check_ranges(ranges)
        needed = list(self.free) + ([self.ten] if ratio is not None else [])
        self._check_design(needed)
        box, origin = self._apply_bounds(bounds, needed)
        self.box = box
        lo = np.array([box[p][0] for p in self.free])
        hi = np.array([box[p][1] for p in self.free])
        self.origin = {p: dict(origin[p]) for p in self.free}
        self._apply_strength_ratio(box, origin, lo, hi)
        self.lo, self.hi = lo, hi
        self.width = hi - lo

    def _check_design(self, needed: list[str]) -> None:
        """Every calibrated parameter (``needed``) has a sampled range of some width, and
        every fixed value with a range lies inside it."""
        ratio = self.ratio
        missing = [p for p in needed if p not in self.ranges]
        if missing:
            raise ParameterError(f"ranges lacks {missing}: the sampled range (design space) of every free "
                                 "parameter"
                                 + (f" and of the derived {self.ten}" if ratio is not None else "")
                                 + " is needed; the regression is valid only there")
        for p in needed:
            lo, hi = self.ranges[p]
            if not lo < hi:
                raise ParameterError(f"ranges.{p}=[{lo:g}, {hi:g}] has no width: {p} was not sampled, so it "
                                     "cannot be calibrated (fix it instead)")
        for p, v in self.fixed.items():
            if p in self.ranges and not _inside(v, *self.ranges[p]):
                lo, hi = self.ranges[p]
                raise ParameterError(f"fixed {p}={v:g} is outside ranges.{p}=[{lo:g}, {hi:g}], the sampled "
                                     "space (the regression is not valid there): fix a value inside it, or "
                                     f"widen ranges.{p} and rerun the design")

    def _apply_bounds(self, bounds: Mapping[str, Sequence[float]] | None, needed: list[str]
                      ) -> tuple[dict, dict]:
        """The box of every calibrated parameter (its range, narrowed by ``bounds``) and
        where each side comes from: ``origin[p][side] = (configured key, None)``."""
        ratio = self.ratio
        box = {p: self.ranges[p] for p in needed}
        origin = {p: {s: (f"ranges.{p}", None) for s in ("lower", "upper")} for p in needed}
        for name, b in (bounds or {}).items():
            check_params([name], "bounded parameter")
            try:
                lo, hi = (float(v) for v in b)
            except (TypeError, ValueError):
                raise ParameterError(f"calibration.bounds.{name}={b!r}: expected [lo, hi]") from None
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ParameterError(f"calibration.bounds.{name}={list(b)!r}: expected finite [lo, hi] "
                                     "with lo < hi")
            if name not in needed:
                derived = f", derived: {self.ten}" if ratio is not None else ""
                raise ParameterError(f"calibration.bounds.{name}: {name} is not calibrated (free: "
                                     f"{list(self.free)}{derived}); bounds apply to calibrated "
                                     "parameters only")
            rlo, rhi = self.ranges[name]
            if not (_inside(lo, rlo, rhi) and _inside(hi, rlo, rhi)):
                raise ParameterError(f"calibration.bounds.{name}=[{lo:g}, {hi:g}] reaches beyond "
                                     f"ranges.{name}=[{rlo:g}, {rhi:g}], the sampled space (the regression "
                                     "is not valid outside it): narrow the bounds, or widen "
                                     f"ranges.{name} and rerun the design")
            box[name] = (max(lo, rlo), min(hi, rhi))
            if lo > rlo:
                origin[name]["lower"] = (f"calibration.bounds.{name}", None)
            if hi < rhi:
                origin[name]["upper"] = (f"calibration.bounds.{name}", None)
        return box, origin

    def _apply_strength_ratio(self, box: dict, origin: dict, lo: np.ndarray, hi: np.ndarray) -> None:
        """With a ratio: intersect a free ``pb_coh_MPa``'s bounds (``lo``, ``hi``, in place)
        with ``pb_ten_MPa``'s divided by the ratio (recording ``(key, pb_ten bound)`` as the
        origin of a side it sets), or check that a fixed one's derived ``pb_ten_MPa`` lies in
        its box. The parallel-bond specific part of the space (its strength pair)."""
        ratio = self.ratio
        if ratio is not None and self.coh in self.free:
            j = self.free.index(self.coh)
            if box[self.ten][0] / ratio > lo[j]:
                lo[j] = box[self.ten][0] / ratio
                self.origin[self.coh]["lower"] = (origin[self.ten]["lower"][0], box[self.ten][0])
            if box[self.ten][1] / ratio < hi[j]:
                hi[j] = box[self.ten][1] / ratio
                self.origin[self.coh]["upper"] = (origin[self.ten]["upper"][0], box[self.ten][1])
            if not lo[j] < hi[j]:
                raise ParameterError(f"no {self.coh} in {list(box[self.coh])} gives {self.ten} = "
                                     f"{ratio:g} × {self.coh} inside {list(box[self.ten])} "
                                     f"(ranges.{self.coh} and ranges.{self.ten} do not "
                                     "overlap at this ratio): widen one of them and rerun the design")
        if ratio is not None and self.coh in self.fixed:
            ten = ratio * self.fixed[self.coh]
            if not _inside(ten, *box[self.ten]):
                raise ParameterError(f"{self.ten} = {ratio:g} × {self.fixed[self.coh]:g} = {ten:g} "
                                     "is outside "
                                     f"{origin[self.ten]['lower'][0]}={list(box[self.ten])}")

    @property
    def derived(self) -> tuple[str, ...]:
        return (self.ten,) if self.ratio is not None else ()

    @property
    def calibrated(self) -> tuple[str, ...]:
        """Free and derived parameters (what a calibration determines)."""
        return self.free + self.derived

    def bounds(self) -> dict[str, tuple[float, float]]:
        """Effective bounds of the free parameters and of the derived ``pb_ten_MPa``."""
        out = {p: (float(a), float(b)) for p, a, b in zip(self.free, self.lo, self.hi)}
        if self.ratio is not None and self.coh in out:
            out[self.ten] = (self.ratio * out[self.coh][0], self.ratio * out[self.coh][1])
        return out

    def bound_origins(self) -> dict[str, dict[str, str]]:
        """For every effective bound: the configured key it comes from, e.g.
        ``{"pb_coh_MPa": {"lower": "ranges.pb_coh_MPa", "upper": "ranges.pb_ten_MPa / ratio 1.4"}}``."""
        out = {}
        for p in self.free:
            out[p] = {s: key + (f" / ratio {self.ratio:g}" if via is not None else "")
                      for s, (key, via) in self.origin[p].items()}
        if self.ratio is not None and self.coh in self.free:
            out[self.ten] = {s: key + (f" × ratio {self.ratio:g}" if via is None else "")
                         for s, (key, via) in self.origin[self.coh].items()}
        return out

    def edge_text(self, p: str, side: str, value: float, margin: float = 0.0) -> str:
        """``pb_coh_MPa at the upper bound 35.7 (= upper bound 50 of ranges.pb_ten_MPa / ratio 1.4)``;
        with the closed loop's ``margin`` (:meth:`loop_box`) past a design range, which says so."""
        key, via = self.origin[p][side]
        j = self.free.index(p)
        edge = self.lo[j] if side == "lower" else self.hi[j]
        if margin > 0 and key.startswith("ranges.") and not math.isclose(value, edge):
            return (f"{p} at the {side} bound {value:g} of the closed loop ({key} widened by "
                    f"the margin {margin:g} of its width, inside {p}'s physical domain)")
        if via is None:
            return f"{p} at the {side} bound {value:g} of {key}"
        return (f"{p} at the {side} bound {value:g} (= {side} bound {via:g} of {key} / ratio {self.ratio:g}; "
                f"{self.ten} = {via:g})")

    def beyond_limits(self, x: np.ndarray) -> list[dict]:
        """Every calibrated parameter (free or derived) of the free values ``x`` outside its
        configured limits (:attr:`box`): parameter, side, the configured key to widen
        (``calibration.bounds.<p>`` when the bound narrows the range on that side, else
        ``ranges.<p>``), the bound, the value needed and whether it is beyond the range."""
        point = self.full(x)
        out = []
        for p in self.calibrated:
            lo, hi = self.box[p]
            w = hi - lo
            v = point[p]
            for side, beyond in (("lower", v < lo - 1e-9 * w), ("upper", v > hi + 1e-9 * w)):
                if not beyond:
                    continue
                key = (f"calibration.bounds.{p}" if (side == "lower" and lo > self.ranges[p][0])
                       or (side == "upper" and hi < self.ranges[p][1]) else f"ranges.{p}")
                rlo, rhi = self.ranges[p]
                out.append({"parameter": p, "side": side, "key": key,
                            "bound": lo if side == "lower" else hi, "needed": float(v),
                            "beyond_ranges": bool(v < rlo or v > rhi)})
        return out

    def distance_outside(self, x: np.ndarray) -> float:
        """How far the free values ``x`` lie outside the configured limits: the sum over the
        calibrated parameters of the distance past their box, in box widths."""
        point = self.full(x)
        box = self.box
        return sum(max(0.0, box[p][0] - point[p], point[p] - box[p][1]) / (box[p][1] - box[p][0])
                   for p in self.calibrated)

    def x(self, u: np.ndarray) -> np.ndarray:
        return self.lo + np.asarray(u, float) * self.width

    def u(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, float) - self.lo) / self.width

    def full(self, x: np.ndarray) -> dict[str, float]:
        out = dict(self.fixed)
        out.update(zip(self.free, (float(v) for v in x)))
        if self.ratio is not None:
            out[self.ten] = self.ratio * out[self.coh]
        return out

    def free_values(self, params: Mapping[str, float]) -> np.ndarray:
        missing = [p for p in self.free if p not in params]
        if missing:
            raise ParameterError(f"missing free parameter(s) {missing}")
        return np.array([float(params[p]) for p in self.free])

    def check_models(self, models: Mapping[str, RegressionModel], responses: Sequence[str]) -> None:
        known = set(self.fixed) | set(self.free) | set(self.derived)
        for r in responses:
            missing = [p for p in models[r].params if p not in known]
            if missing:
                raise ParameterError(f"the {r} model needs {missing}: give them in fixed or free")

    def jacobian(self, models: Mapping[str, RegressionModel], responses: Sequence[str], x) -> np.ndarray:
        """∂model_k/∂x_j (physical units), chain rule through the ratio constraint."""
        point = self.full(x)
        J = np.zeros((len(responses), len(self.free)))
        for k, r in enumerate(responses):
            grad = models[r].gradient(point)
            for j, p in enumerate(self.free):
                J[k, j] = grad.get(p, 0.0)
                if p == self.coh and self.ratio is not None:
                    J[k, j] += self.ratio * grad.get(self.ten, 0.0)
        return J

    def at_bound(self, u: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> list[tuple[str, str, float]]:
        """(parameter, side, value) of every free parameter on an edge of the box (in unit
        coordinates ``box = (ulo, uhi)``, default the bounds [0, 1])."""
        ulo, uhi = box if box is not None else (np.zeros(len(self.free)), np.ones(len(self.free)))
        xlo, xhi = self.limits((ulo, uhi))
        out = []
        for j, p in enumerate(self.free):
            if u[j] <= ulo[j] + _EDGE:
                out.append((p, "lower", float(xlo[j])))
            elif u[j] >= uhi[j] - _EDGE:
                out.append((p, "upper", float(xhi[j])))
        return out

    def limits(self, box: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The box ``(ulo, uhi)`` (unit coordinates) in physical units; an edge the loop did
        not widen is the bound itself, to the bit (not lo + 1 x width)."""
        ulo, uhi = box
        return (np.where(ulo == 0.0, self.lo, self.lo + ulo * self.width),
                np.where(uhi == 1.0, self.hi, self.lo + uhi * self.width))

    def loop_box(self, margin: float) -> tuple[np.ndarray, np.ndarray]:
        """The closed loop's box in unit coordinates: [0, 1], widened by ``margin`` range
        widths on every side whose bound is a design range (``ranges``; never past a
        ``bounds`` narrowing), kept inside the parameter's physical domain."""
        ulo, uhi = np.zeros(len(self.free)), np.ones(len(self.free))
        if margin <= 0:
            return ulo, uhi
        elo, ehi = self.extended(margin)
        for j, p in enumerate(self.free):
            if self.origin[p]["lower"][0].startswith("ranges."):
                ulo[j] = min(0.0, (elo[j] - self.lo[j]) / self.width[j])
            if self.origin[p]["upper"][0].startswith("ranges."):
                uhi[j] = max(1.0, (ehi[j] - self.lo[j]) / self.width[j])
        return ulo, uhi

    def extended(self, factor: float) -> tuple[np.ndarray, np.ndarray]:
        """The free-parameter box widened by ``factor`` range widths on each side, kept inside
        each parameter's physical domain (for the extrapolated "what to widen" search)."""
        lo, hi = self.lo - factor * self.width, self.hi + factor * self.width
        for j, p in enumerate(self.free):
            d = ALL_PARAMS[p]
            lo[j] = max(lo[j], d.phys_lo + (1e-3 * self.width[j] if d.lo_open else 0.0))
            hi[j] = min(hi[j], d.phys_hi)
        return lo, hi


def check_calibration_space(free, fixed: Mapping[str, float], ratio: float | None,
                            ranges: Mapping[str, Sequence[float]],
                            bounds: Mapping[str, Sequence[float]] | None = None) -> None:
    """Raise :class:`ParameterError` if free/fixed/ratio/ranges/bounds do not define a valid
    calibration space (the checks :func:`invert` makes first), so a caller can reject bad
    input before it writes anything."""
    CalibrationSpace(free, fixed, ratio, ranges, bounds)

def _check_ranges(ranges) -> dict[str, tuple[float, float]]:
    if ranges is None:
        raise ParameterError("ranges is required: the sampled range (design space) of the parameters, "
                             "e.g. the study config's ranges")
    out = {}
    for name, r in dict(ranges).items():
        check_params([name], "ranged parameter")
        try:
            lo, hi = (float(v) for v in r)
        except (TypeError, ValueError):
            raise ParameterError(f"ranges.{name}={r!r}: expected [low, high]") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ParameterError(f"ranges.{name}={list(r)!r}: expected finite [low, high] with low <= high")
        out[name] = (lo, hi)
    return out


def _inside(v: float, lo: float, hi: float) -> bool:
    tol = 1e-9 * max(abs(lo), abs(hi), hi - lo, 1e-300)
    return lo - tol <= v <= hi + tol


def _check_targets(targets: Mapping[str, float], models: Mapping[str, RegressionModel] | None
                   ) -> tuple[tuple[str, ...], np.ndarray]:
    responses = check_responses(targets)
    if not responses:
        raise ValueError("targets is empty: expected e.g. {'ucs_MPa': ..., 'E_GPa': ..., 'nu': ...}")
    t = np.array([float(targets[r]) for r in responses])
    bad = [f"{r}={targets[r]!r}" for r, v in zip(responses, t) if not (math.isfinite(v) and v != 0)]
    if bad:
        raise ValueError(f"target(s) {bad}: expected finite non-zero values (errors are relative)")
    if models is not None:
        missing = [r for r in responses if r not in models]
        if missing:
            raise ValueError(f"no regression model for target(s) {missing}; models given: {list(models)}")
    return responses, t

