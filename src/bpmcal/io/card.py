"""Material cards: the calibrated parameters of one lab specimen with everything that
explains them, as YAML, in a versioned format (``CARD_FORMAT``).

Written by ``bpmcal calibrate`` (one card per specimen) and extended by ``bpmcal verify``
(the ``verification`` section); read by every command that takes a card (``verify``,
``scatter``, ``sweep-plan``, ``impact``, ``ucs/bts/triaxial --params``) and by the report,
all through :func:`read_card`.

Format 1 (keys in this order; paper units)::

    card_format: 1
    specimen            the lab specimen's name
    status, message     the inversion's outcome (ok | non-unique | within-error |
                        no-exact-fit | unreachable; within-error: missed, but within the
                        regression's own prediction error)
    ratio_ten_coh       the bond-strength ratio pb_ten/pb_coh used (null: both free, as when
                        the lab's tensile strength sets it)
    strength_ratio      value: pb_ten/pb_coh of ``parameters``; set_by: bts_MPa target |
                        ratio sweep | config calibration.ratio | both strengths free
                        (the config key is calibration.strength_ratio now; the set_by
                        value keeps its card-format-1 spelling)
    parameters          the card's parameters (the regression's answer): the paper's 8
                        for the parallel bond, the flat joint's for a flat-joint study
    roles               free | derived | fixed, per parameter
    ranges              the design space (the config's ranges)
    calibration_bounds  the config's calibration.bounds
    bounds              effective bounds of the calibrated parameters, and where each comes from
    at_bound, widen, advice   what stops the fit and what to widen
    targets, lab        the lab values calibrated against (σc, E, ν, and σt = bts_MPa when the
                        lab row gives it), and the whole lab row
    target_se           (when the lab row gives ``<target>_se``) the lab values' standard
                        errors: the closed loop and the fresh-seed check compare two means
    predicted, residuals_pct  the regression's responses at ``parameters``
    missed              every target missed by more than the inversion's tolerance: target,
                        value, predicted, error_pct (empty when all are met)
    reach               for a no-exact-fit with σt: the σt and σc/σt spans the models reach
                        while they meet the other targets
    reach_test          (a missed target) the miss against the models' prediction error:
                        chi2_min, dof, p_reach, reachable, the point and each target's z
    alternatives        other solutions that fit as well
    bootstrap           n_boot, scheme and the 95 % intervals
    dataset_note        how many samples the regression used
    provenance          bpmcal_version, git_commit, inputs_hash
    verification        (verified cards) status, message, rounds, rtol, seed, best_round,
                        single_pass and closed_loop responses, the closed loop's parameters,
                        geometry, widen; per round shown the seed mean of every
                        response, seed_sd, seed_cv and n_seeds; missed (every target the
                        best round misses by more than rtol: target, value, dem,
                        error_pct); bts_geometry (with σt); seeds (the best round's),
                        seeds_per_round, max_seeds (the seed set's growth limit);
                        jacobian (the loop's final Broyden estimate, response ->
                        parameter -> ∂response/∂parameter, paper units);
                        jacobian_sign_held (when any: the regression's negative
                        slopes of a strength against a bond strength that the loop
                        started from 0 instead: response, parameter, regression);
                        tensile_specimens (when > 1: a seed's σt is the mean of this
                        many specimens, in the loop's last rounds, the transfer and
                        the fresh-seed check); tensile (with a seed-CV target,
                        ``verification.tensile_seed_cv``: seed_cv_target, start, max,
                        specimen_cv and its dof, seed_cv_expected, chance_above, and
                        every raise of the count: round, from, to, specimen_cv, dof)
    calibrated_at_scale (verified cards) the specimen scale the parameters were last fitted at
    transfer            (transferred cards, ``bpmcal transfer``) status, rounds, scale,
                        tolerance_pct, at_transfer and final responses, parameters
    posterior           (posterior cards, ``bpmcal posterior``) status, note, identifiability,
                        hdi_prob, parameters (card, mean, sd, hdi, card_quantile,
                        card_in_hdi, role, hdi_cut_by_prior), directions, suggestions, predictions, reach,
                        lab_sd, surrogates, sampler, refine, learning_curve
                        (docs/methods/posterior.md)

Keys added within format 1 (``strength_ratio``, ``missed``, ``reach``, ``reach_test``,
``posterior``, ``target_se``,
``verification.missed``, ``verification.bts_geometry``, ``verification.jacobian``,
``verification.max_seeds``, ``verification.seeds_per_round``,
``verification.jacobian_sign_held``, ``verification.tensile``) are optional for readers: cards
written before them stay readable.

A card without ``card_format`` (bpmcal before this format was versioned) or of a newer
format is refused with a message that says what to do (:class:`CardError`).
"""
from __future__ import annotations

from pathlib import Path

from .. import params as P
from .checks import BadInput, read_yaml
from .tables import write_yaml

#: the format of the cards this bpmcal writes and reads
CARD_FORMAT = 1


class CardError(BadInput):
    """A file is not a material card this bpmcal can read."""


def write_card(path, card: dict) -> Path:
    """Write ``card`` (a mapping of the keys above) with ``card_format`` first, atomically."""
    body = {k: v for k, v in card.items() if k != "card_format"}
    return write_yaml(path, {"card_format": CARD_FORMAT, **body})


def is_card(d) -> bool:
    """Whether a YAML mapping claims to be a material card (rather than a flat mapping of
    the 8 parameters)."""
    return isinstance(d, dict) and ("card_format" in d or "parameters" in d)


def check_card(d, where: str, need=("parameters",)) -> dict:
    """Check a mapping read from ``where`` as a card of :data:`CARD_FORMAT` with the keys
    ``need`` and valid parameters; returns it. CardError / ParameterError name ``where``."""
    if not isinstance(d, dict):
        raise CardError(f"{where}: expected a material card (a YAML mapping)")
    fmt = d.get("card_format")
    if fmt is None:
        raise CardError(f"{where}: no card_format: a material card of an older bpmcal (or "
                        f"not a card); this bpmcal reads card format {CARD_FORMAT}: rerun "
                        "'bpmcal calibrate' (in a study: snakemake reruns it)")
    if isinstance(fmt, bool) or not isinstance(fmt, int):
        raise CardError(f"{where}: card_format={fmt!r}: expected the integer {CARD_FORMAT}")
    if fmt > CARD_FORMAT:
        raise CardError(f"{where}: card_format {fmt} is newer than this bpmcal reads "
                        f"({CARD_FORMAT}); update bpmcal")
    if fmt < CARD_FORMAT:
        raise CardError(f"{where}: card_format {fmt} is older than this bpmcal reads "
                        f"({CARD_FORMAT}); rerun 'bpmcal calibrate'")
    missing = [k for k in need if k not in d]
    if missing:
        raise CardError(f"{where}: not a complete material card (no {', '.join(missing)}; "
                        "expected the output of 'bpmcal calibrate' or 'bpmcal verify')")
    for key in ("verification", "transfer"):  # sections a command may take parameters from
        sec = d.get(key)
        if sec is not None and not isinstance(sec, dict):
            raise CardError(f"{where}: '{key}' is not a mapping (got {type(sec).__name__}); "
                            "expected the section 'bpmcal verify' or 'bpmcal transfer' writes")
        params = (sec or {}).get("parameters")
        if params is not None and not isinstance(params, dict):
            raise CardError(f"{where}: '{key}.parameters' is not a mapping of parameter "
                            "names to values")
    if "parameters" in d:
        if not isinstance(d["parameters"], dict):
            raise CardError(f"{where}: 'parameters' is not a mapping of parameter names to "
                            "values")
        try:
            P.validate_params(d["parameters"])
        except P.ParameterError as e:
            raise P.ParameterError(f"{where}: {e}") from None
    return d


def read_card(path, flag: str = "", need=("parameters",)) -> dict:
    """Read and check a material card (:func:`check_card`); ``flag`` names the command-line
    option it came from in messages."""
    where = f"{flag} {path}" if flag else str(path)
    return check_card(read_yaml(path, flag or "card"), where, need)


def card_parameters(card: dict) -> dict:
    """The parameters a card stands for: the full-size transfer's when it ran, else the
    closed loop's when it ran, else the calibration's."""
    transferred = (card.get("transfer") or {}).get("parameters")
    verified = (card.get("verification") or {}).get("parameters")
    return dict(transferred or verified or card["parameters"])
