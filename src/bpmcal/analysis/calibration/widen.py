"""What to widen when the targets are out of reach of the sampled ranges.

For an ``unreachable`` or ``no-exact-fit`` inversion the regression is extrapolated into
a box 2, then 5, then 20 range widths wider on each side (within each parameter's
physical domain) until some point meets the targets; the point least outside the
configured limits names every configured key to widen (``ranges.<p>`` or
``calibration.bounds.<p>``) and the value it must reach. When even the extrapolated
models cannot meet every target, their best compromise is used instead. All values are
indicative: the regression is not validated outside the sampled space.

The method: ``docs/methods/calibration.md`` (section "Inversion", "What to widen").
"""
from __future__ import annotations

from .fit import _fit, _fmt_pct
from .space import CalibrationSpace

_EXTEND = (2.0, 5.0, 20.0)  # range widths added on each side, in turn, for the "what to widen" search


def _what_to_widen(space: CalibrationSpace, models, responses, t, x_best, tol: float, n_starts: int, seed: int
                   ) -> tuple[list[dict], str]:
    """Which configured limit keeps the targets out of reach, and how far it must move.

    The regression is extrapolated into a box 2, then 5, then 20 range widths wider on each
    side (:data:`_EXTEND`, within each parameter's physical domain) until some point meets
    the targets; among the points that meet the targets there,
    the one least outside the configured limits is taken, and every calibrated parameter
    (free or derived) outside its configured range or bound is reported with the configured
    key to widen and the value it must reach. Indicative only: outside the sampled ranges
    the regression is not validated.
    """
    for factor in _EXTEND:
        elo, ehi = space.extended(factor)
        fits = _fit(space, models, responses, t, elo, ehi, [x_best], n_starts, seed)
        reach = [f for f in fits if f[1] <= tol]
        if reach:
            break
    if not reach:
        return _compromise_advice(space, responses, fits[0], x_best, tol)
    x = min(reach, key=lambda f: (space.distance_outside(f[2]), f[0]))[2]
    return _reach_advice(space, x)


def _compromise_advice(space: CalibrationSpace, responses, best: tuple, x_best, tol: float
                       ) -> tuple[list[dict], str]:
    """Not even the extrapolated models meet every target: the limits to widen to reach
    their best compromise ``best`` (a :func:`_fit` row), or the limits that stop the fit at
    ``x_best``, or that widening does not help."""
    point = space.full(best[2])
    missed = ", ".join(f"{r} {100 * v:+.2f} %" for r, v in zip(responses, best[3]) if abs(v) > tol)
    models_say = (f"The fitted models, extrapolated up to {_EXTEND[-1]:g} range widths beyond the "
                  f"sampled space, cannot meet all targets either (best relative residuals "
                  f"{_fmt_pct(responses, best[3])})")
    items = space.beyond_limits(best[2])
    if items:
        for it in items:
            it["reaches_targets"] = False
        where = ", ".join(f"{p} = {point[p]:.4g}" for p in space.calibrated)
        parts = [f"{it['key']} {'below' if it['side'] == 'lower' else 'above'} {it['needed']:.4g} "
                 f"(its {it['side']} bound is now {it['bound']:.4g})" for it in items]
        return items, (f"{models_say}. Their best compromise lies at {where}: widen {'; '.join(parts)} "
                       "and rerun the design so that a new regression covers it. What it still misses "
                       f"({missed}) may need another free parameter (calibration.free) or other fixed "
                       "values (calibration.fixed). Indicative only: the regression is not validated "
                       "outside the sampled space.")
    u_best = space.u(x_best)
    for p, side, v in space.at_bound(u_best):
        key, via = space.origin[p][side]
        name = key.split(".", 1)[1] if key.startswith("ranges.") else key.rsplit(".", 1)[1]
        items.append({"parameter": name, "side": side, "key": key,
                      "bound": float(via) if via is not None else float(v), "needed": None,
                      "beyond_ranges": key.startswith("ranges."), "reaches_targets": False})
    if items:
        keys = ", ".join(f"{it['key']} ({it['side']} bound {it['bound']:.4g})" for it in items)
        return items, (f"{models_say}, and their best compromise lies inside the configured limits, "
                       f"so they cannot tell how far to widen. The limits that stop the fit are {keys}: "
                       "widen them and rerun the design so that a new regression covers the targets, "
                       "or free another parameter (calibration.free) or change a fixed value "
                       "(calibration.fixed).")
    return [], (f"{models_say}, and no configured bound is active: with these models widening the "
                "ranges does not help; free another parameter (calibration.free) or change a fixed "
                "value (calibration.fixed), then rerun.")


def _reach_advice(space: CalibrationSpace, x) -> tuple[list[dict], str]:
    """The extrapolated models meet the targets at ``x``: every configured limit to move
    there, and how far."""
    items = space.beyond_limits(x)
    for it in items:
        it["reaches_targets"] = True
    if not items:  # a point inside the limits meets the targets: the multi-start missed it
        return [], ("A point inside the configured limits meets the targets when started from the "
                    "extrapolated search; the multi-start missed it (increase n_starts).")
    parts = []
    for it in items:
        word = "below" if it["side"] == "lower" else "above"
        parts.append(f"{it['key']} {word} {it['needed']:.4g} "
                     f"(its {it['side']} bound is now {it['bound']:.4g})")
        if it["key"].startswith("calibration.bounds") and it["beyond_ranges"]:
            parts.append(f"ranges.{it['parameter']} {word} {it['needed']:.4g}")
    rerun = any(it["key"].startswith("ranges") or it["beyond_ranges"] for it in items)
    point = space.full(x)
    where = ", ".join(f"{p} = {point[p]:.4g}" for p in space.calibrated)
    advice = (f"To reach the targets widen {'; '.join(parts)}"
              + (" and rerun the design (new samples, screening, regression)" if rerun else "")
              + f". The regression extrapolated beyond the sampled space meets the targets at {where}: "
              "indicative only (the regression is not validated there), so leave a margin.")
    return items, advice
