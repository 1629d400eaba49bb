"""Can a lab test's loading reach the card's failure? Answered before any specimen is
built (``budget.screen_loading``: the timestep bound, ``max_steps`` and ``max_strain``
against the card's failure-strain scale), for one card (:func:`screen_test_loading`, the
run commands) and for a whole design space (:func:`hopeless_everywhere`, the study's
config validation: a loading no card of the ranges can complete fails before the first
job, not after every sample failed).
"""
from __future__ import annotations

import itertools

from .. import params as P
from .budget import BudgetError, estimate_balls, screen_loading

#: the design-space corners :func:`hopeless_everywhere` screens at most (2 ** 10)
MAX_CORNERS = 1024
#: the engine material fields the screen reads (``dem.material``: moduli, stiffness
#: ratios, strengths and the flat joint's radius multiplier)
_SCREENED_FIELDS = ("emod", "kratio", "_ten", "_coh", "rmul")


def screen_test_loading(test: str, params: dict, geometry, settings) -> None:
    """``budget.screen_loading`` of lab test ``test`` ("ucs", "triaxial", "bts", "dtt")
    of the validated card ``params`` on ``geometry`` (``runner.Geometry``; the disc's
    diameter is the Brazilian test's loaded length) with ``settings``: a ``BudgetError``
    naming the cause if the loading cannot reach the card's failure."""
    from ..dem.material import expected_failure_strain, stiffest_spring
    from .registry import kind
    from .specimen import card_material

    material, _ = card_material(params)
    g = geometry
    loading = settings.loading_at(g.scale * (g.diameter_mm if kind(test).disc else g.height_mm)
                                  * 1e-3)
    n = estimate_balls(params[P.RMIN], params[P.POROSITY], scale=g.scale,
                       diameter_mm=g.diameter_mm, height_mm=g.height_mm)
    screen_loading(loading, material, P.to_si(P.RMIN, params[P.RMIN]),
                   max_strain=settings.max_strain, max_steps=settings.max_steps, n_balls=n,
                   spring=stiffest_spring(material),
                   failure_strain=expected_failure_strain(material, loading.tension))


def _screened(model: P.ContactModel) -> list[str]:
    """The card parameters the screen depends on: ball size and porosity (the ball count,
    the timestep), the moduli, stiffness ratios and strengths (the timestep, the failure
    strain); friction angles, friction and element counts do not enter it."""
    out = [P.RMIN, P.POROSITY]
    out += [k for k, fields in (model.material or {}).items()
            if k not in out and not model.is_integer(k)
            and all(f.endswith(_SCREENED_FIELDS) for f in fields)]
    return out


def hopeless_everywhere(test: str, ranges: dict, model: P.ContactModel, geometry,
                        settings) -> str | None:
    """None if some card of the design space ``ranges`` ({name: [lo, hi]}, paper units, of
    ``model``'s parameters; a parameter without a range at the model's default) passes
    :func:`screen_test_loading`, else the refusal at the first corner (every range at its
    low end). The screen is monotonic in each parameter, so when every corner of the box
    is refused, every card inside it is."""
    base = {k: float(v[0]) for k, v in ranges.items()}
    base.update({k: v for k, v in (model.defaults or {}).items() if k not in base})
    varied = [k for k in _screened(model) if k in ranges and ranges[k][0] != ranges[k][1]]
    if 2 ** len(varied) > MAX_CORNERS:
        return None
    first = None
    for corner in itertools.product(*([ranges[k][0], ranges[k][1]] for k in varied)):
        card = {**base, **dict(zip(varied, map(float, corner))),
                "contact_model": model.name}
        try:
            screen_test_loading(test, P.validate_params(card), geometry, settings)
            return None
        except P.ParameterError as e:  # (BudgetError; a corner outside the domain: skip)
            if isinstance(e, BudgetError) and first is None:
                first = str(e)
    return first
