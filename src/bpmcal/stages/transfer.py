"""The transfer stage (``workflow/rules/analysis.smk``, ``bpmcal transfer``): run a verified
card on a larger specimen (the study's ``transfer.scale``), and continue its closed loop
there when a response misses its lab value by more than one run's seed scatter at that
size (:func:`scatter_factor`); :func:`transfer_table` collects the transferred cards.

The stage reads the files it is given, checks them and its output paths before any work,
and writes exactly the files it is given (``bpmcal.io.study_files``).
"""
from __future__ import annotations

import dataclasses
import math

import pandas as pd

from .. import params as P
from ..analysis.calibration.loop_settings import MAX_ROUNDS, LoopSettings
from ..io.card import card_parameters, read_card, write_card
from ..io.checks import BadInput
from ..io.tables import write_table
from ..lab.run_context import RunContext
from .inputs import CSV, H5, YAML, output_dirs, outputs, read_models
from .verification import (
    _dem_loop,
    _loop_box,
    _not_run,
    _outside_text,
    _responses,
    check_tri_target,
)

#: the most correction rounds of a transfer (its first round is the transfer run itself)
MAX_CORRECTIONS = MAX_ROUNDS - 1


def transfer(card, models, *, out_card, rounds, run, tests, loop: LoopSettings = LoopSettings(),
             ctx: RunContext = RunContext(), max_rounds=2, z=2.0) -> dict:
    """Full-size transfer of a verified card: run its parameters once (packing
    ``loop.seed``) on the specimen of ``tests`` (:class:`~.measure.SeedTests`; the study's
    ``transfer.scale``, 1.0 = the lab's 50 x 100 mm) and, when a response misses its lab
    target by more than the seed scatter of one run at that size (max(``loop.rtol``, ``z``
    x the seed CV the verification measured x :func:`scatter_factor`, which shrinks it
    with the larger specimen's ball count)), continue the closed loop at that size for at
    most ``max_rounds`` more rounds of one run each: Newton-Broyden as in :func:`verify`,
    starting from the Jacobian the verification's loop had learned from the DEM
    (``verification.jacobian``; the regression's at the card's point for a card without
    one). The regression's Jacobian can be wrong where the loop ended - at a model's
    vertex its sign flips - while the DEM's relative sensitivities change little with the
    specimen size. ``ctx``: how its DEM runs (:class:`~bpmcal.lab.run_context.RunContext`).

    Writes the transferred card (``out_card``: the verified card with a ``transfer``
    section - status ``within-scatter`` (no correction needed), ``corrected`` (met after
    corrections), ``max_rounds``/``stalled``/``failed`` (not met: the best round is
    kept), or ``not-run`` - the responses at transfer and of the best round, the
    tolerances, the parameters; and ``calibrated_at_scale``: the transfer's scale when the
    loop ran), the rounds table and ``run`` (the best round's run file). Readers take the
    transfer's parameters (:func:`bpmcal.io.card.card_parameters`). A card with a
    tensile-strength target runs its Brazilian test as :func:`verify` does, on the disc
    and with the loading of ``tests`` (default the ISRM disc at the transfer's scale; the
    study passes its `bts` section, as to the verification); a direct-tension target runs
    its test on the transfer's cylinder, a triaxial-strength target (``tri_MPa``) the
    triaxial test of ``tests.tri_settings`` on it; σt is the mean of as many specimens
    per seed as the verification's (``verification.tensile_specimens``, default 1). Of
    ``loop`` (:class:`~bpmcal.analysis.calibration.LoopSettings`) the transfer takes the
    seed, the tolerance, the bounds (the design ranges widened by ``loop.range_margin``
    of their width, as the verification's) and the Jacobian update rule
    (``loop.jacobian_update``); its loop runs one seed, so its rounds do not grow, polish
    or adapt the tensile specimens."""
    c = read_card(card, "--card", need=("parameters", "targets", "roles", "ranges",
                                        "verification"))
    if isinstance(max_rounds, bool) or not isinstance(max_rounds, int) \
            or not 0 <= max_rounds <= MAX_CORRECTIONS:
        raise BadInput(f"--max-rounds {max_rounds!r}: expected an integer in 0 .. "
                       f"{MAX_CORRECTIONS} (correction rounds after the transfer run)")
    model_set = read_models(models)
    params = card_parameters(c)
    check_tri_target(card, c["targets"], tests.tri_settings)
    ctx.check_budget(params, tests.geometry)
    outputs((out_card, "--out-card", YAML), (rounds, "--rounds", CSV), (run, "--run", H5))
    output_dirs((ctx.cache, "--specimen-cache"))
    targets = {k: float(v) for k, v in c["targets"].items()}
    v = c["verification"]
    geometry, seed = tests.geometry, loop.seed
    base = {"scale": float(geometry.scale), "seed": int(seed), "max_rounds": max_rounds,
            "from_scale": c.get("calibrated_at_scale", (v.get("geometry") or {}).get("scale")),
            "geometry": geometry.to_dict()}
    if v.get("status") == "not-run" or not v.get("closed_loop"):
        reason = f"not run: the card's closed loop did not run ({v.get('message', '')})"
        return _not_run(c, out_card, "transfer", {
            "status": "not-run", "message": reason, "rounds": 0, **base, "tolerance_pct": None,
            "at_transfer": None, "final": None, "parameters": None}, rounds=rounds, run=run,
            error=reason, params=params, seed=seed, tests=tests)
    shrink = scatter_factor(v.get("geometry"), geometry)
    tol = _tolerances(v, targets, loop.rtol, z, shrink)
    # one seed, 1 + max_rounds rounds; σt measured as the verification's loop measured it
    one = dataclasses.replace(loop, seeds_per_round=1, max_seeds=1, max_rounds=1 + max_rounds,
                              tensile_specimens=int(v.get("tensile_specimens", 1)),
                              tensile_seed_cv=None, max_tensile_specimens=None,
                              triaxial_seeds=None)
    res, by_round, best, _ = _dem_loop(c, model_set, targets, params=params, run=run,
                                       tests=tests, loop=one, ctx=ctx, rtol=tol,
                                       jacobian=v.get("jacobian"))
    write_table(res.history, rounds, index=False)
    out = dict(c)
    section = _transfer_section(res, by_round, best, targets, base=base, tol=tol, shrink=shrink,
                                range_margin=loop.range_margin)
    if section["status"] != "failed":
        out["calibrated_at_scale"] = float(geometry.scale)
    out["transfer"] = section
    write_card(out_card, out)
    return out


def _tolerances(v: dict, targets: dict, rtol, z: float, shrink: float) -> dict:
    """The transfer's tolerance of every target: max(``rtol``, ``z`` x the seed CV the
    verification measured (its ``closed_loop.seed_cv``) x ``shrink``), ``rtol`` without a CV."""
    cv = (v["closed_loop"].get("seed_cv") or {})
    tol = {}
    for k in targets:
        x = float(cv.get(k, math.nan)) if cv.get(k) is not None else math.nan
        tol[k] = max(float(rtol), z * x * shrink) if math.isfinite(x) else float(rtol)
    return tol


def _transfer_section(res, by_round: list, best: int, targets: dict, *, base: dict, tol: dict,
                      shrink: float, range_margin: float) -> dict:
    """The transferred card's ``transfer`` section from the closed loop's result ``res``:
    ``within-scatter`` (converged in the first round), ``corrected`` or the loop's status."""
    if res.status == "converged":
        status = "within-scatter" if len(by_round) == 1 else "corrected"
    else:
        status = res.status
    ran = status != "failed"
    return {
        "status": status, "message": res.message + _outside_text(res.outside, range_margin),
        "rounds": len(by_round), **_loop_box(res, range_margin),
        "corrections": len(by_round) - 1, **base, "best_round": best + 1,
        "tolerance_pct": {k: 100 * t for k, t in tol.items()}, "scatter_factor": shrink,
        "at_transfer": _responses(by_round[0], targets),
        "final": _responses(by_round[best], targets),
        "parameters": ({k: float(x) for k, x in res.params.items() if k in P.ALL_PARAMS}
                       if ran else None)}


def scatter_factor(verified_geometry: dict | None, geometry) -> float:
    """How much less one run of the specimen ``geometry`` scatters between packing seeds
    than one of the verification's (``verified_geometry``, the card's
    ``verification.geometry``): sqrt(V_verified / V), the specimens' volumes (the same
    balls, so their ball counts) - a response averaged over N independent grains scatters
    as 1/sqrt(N). Measured on B2's set, 10 seeds at scale 0.4 against 4 at full size (16 x
    the balls, 0.25 by this rule): CV ratios 0.34 (σc), 0.39 (E), 0.08 (ν). 1.0 when the
    card does not record its geometry."""
    def volume(g):  # Geometry.to_dict: the specimen's actual (scaled) size
        return float(g["diameter_mm"]) ** 2 * float(g["height_mm"])

    try:
        v0 = volume(verified_geometry or {})
    except (KeyError, TypeError, ValueError):
        return 1.0
    v1 = volume(geometry.to_dict())
    return math.sqrt(v0 / v1) if v0 > 0 and v1 > 0 else 1.0


def transfer_table(cards, *, table) -> pd.DataFrame:
    """One row per transferred card and response: the verified seed mean at the
    calibration scale, the full-size response at transfer and after the corrections,
    their errors in % of the lab value, the tolerance and the status."""
    loaded = [read_card(c, "--cards", need=("specimen", "targets", "verification",
                                            "transfer")) for c in cards]
    outputs((table, "--table", CSV))
    rows = []
    for c in loaded:
        t, v = c["transfer"], c["verification"]
        for k in P.TARGETS:
            def val(section, key=k):
                return (section or {}).get(key, math.nan) if section else math.nan

            def err(section, key=k):
                return ((section or {}).get("errors_pct") or {}).get(key, math.nan)
            rows.append({
                "specimen": c["specimen"], "response": k, "lab": c["targets"][k],
                "verified_scale": t.get("from_scale"),
                "verified_mean": val(v.get("closed_loop")),
                "verified_err_pct": err(v.get("closed_loop")),
                "scale": t["scale"], "at_transfer": val(t.get("at_transfer")),
                "at_transfer_err_pct": err(t.get("at_transfer")),
                "tolerance_pct": (t.get("tolerance_pct") or {}).get(k, math.nan),
                "final": val(t.get("final")), "final_err_pct": err(t.get("final")),
                "rounds": t.get("rounds"), "status": t["status"]})
    df = pd.DataFrame(rows)
    write_table(df, table, index=False)
    return df
