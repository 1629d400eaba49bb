"""Is a tensile test a valid measurement? Where its fracture started, and whether it split
the specimen as the test's formula assumes. Pure functions (crack events and a recorded
series in, a verdict out), applied to every Brazilian and direct-tension run.

The cracks of the failure ("the burst") are the cracks formed from the record before the
peak load on: the peak is the load at which the specimen breaks, so the failure's cracks
form in the record interval that contains it and after. Cracks formed earlier are the
diffuse pre-peak damage (in a Brazilian disc most of it under the loading contacts).

**Brazilian** (ISRM suggested method, 1978: "the fracture should initiate at the centre
of the disc"; a test whose fracture starts at a loading contact is invalid):

- *initiation*: the first ``max(INIT_MIN, INIT_FRACTION x burst)`` cracks of the burst
  (ordered by the step they formed in) are where the fracture started; their median
  distance from the disc centre along the loaded diameter, |y - y_c| / R, must lie in the
  central zone, at most ``central_zone`` (0.5: the middle half of the loaded diameter).
  Otherwise the run is invalid: "fracture initiated next to the bottom/top platen" (or
  jaw).
- *no crack grown from a contact before the peak*: the cracks formed before the burst on
  the loaded diameter (the band below) beyond the central zone, on either side, must
  number less than ``PRE_FRACTION`` of the burst's cracks. A fracture that grows stably
  from under a loader and reaches the centre only at the peak started at the contact,
  though the burst itself starts near the centre (a planted weak zone under a platen:
  20-54 % of the burst grew there before the peak; valid capped discs of 9-23 balls
  across: 1-14 %, tests/unit/lab/test_brazilian.py and docs/measurements); otherwise invalid:
  "a fracture grew from the top platen before the peak".
- *split along the loaded diameter*: at least ``SPLIT_FRACTION`` of the burst's cracks lie
  within the band |x - x_c| <= max(D/8, 1.5 mean ball diameters) around the loaded
  diameter; otherwise invalid: "the fracture did not follow the loaded diameter".
- a test that ended without a post-peak drop (``max_strain``/``max_steps``), or with no
  crack in the burst, did not split the disc: invalid.

**Direct tension**: the fracture (the median height of the burst's cracks) must lie in the
gauge section, at least ``clearance`` from the inner face of either grip; otherwise
invalid: "failure next to the bottom/top grip".

**Flat joints: one crack per contact.** A flat joint breaks element by element (its 1 x 3
elements, by default, fail one at a time as it opens or bends), so its element breaks are
not independent cracks: a joint whose three elements fail as the split passes would count
three times, a joint under a loader that loses one element to bending once. Both verdicts
therefore judge the crack events per contact (:func:`per_contact`): a flat joint is one
crack, formed at the step of its first broken element, at that element's position, in its
mode; the burst, the initiation, the pre-peak count and the split band all count contacts.
Parallel bonds (one event per bond) are judged as they are.

An invalid run gives no strength value (``bts_MPa`` / ``dtt_MPa`` NaN; the peak stress
stays in ``bts_peak_MPa`` / ``dtt_peak_MPa`` for inspection), and says why in
``bts_invalid_reason`` / ``dtt_invalid_reason``.

**Complete or not** (:func:`cut_off_reason`, every quasi-static test): a test's measure
is defined by what it must reach: the UCS, triaxial and direct-tension tests a peak
followed by the drop to ``stop_drop`` of it (``stop_reason`` "post_peak_drop"), the
Brazilian test the split that ends it the same way. A loading stopped by a cut-off first
(``max_strain``, ``max_steps``) measured no strength: the stress at the cut-off is no
sigma_c (nor a sigma_1 at failure, nor a sigma_t). Such a run is written with status
"incomplete" and the reason (``stages.runs``), and every analysis treats it as a failed
measurement, never a value.
"""
from __future__ import annotations

import math

import numpy as np

#: fewest cracks that mark where a fracture started ...
INIT_MIN = 5
#: ... or this share of the burst's cracks, whichever is more
INIT_FRACTION = 0.1
#: share of the burst's cracks that must lie in the band of the loaded diameter (a split)
SPLIT_FRACTION = 0.5
#: pre-peak cracks on the loaded diameter beyond the central zone (one side), as a share
#: of the burst's cracks, from which a fracture counts as grown from that contact
PRE_FRACTION = 0.15


def burst_mask(crack_step, series_step, peak_record: int) -> np.ndarray:
    """Cracks of the failure: formed after the record before the peak (steps relative to
    the start of loading; genesis cracks, step < 0, excluded)."""
    cs = np.asarray(crack_step)
    st = np.asarray(series_step)
    start = int(st[peak_record - 1]) if peak_record > 0 else 0
    return (cs >= 0) & (cs > start)


def per_contact(cracks: dict) -> dict:
    """The crack events with one event per contact (module docstring): for flat joints
    (events with an ``element`` key, ``bond`` the contact), each contact's first element
    break (the earliest step; of equal steps the first event, as ``Model.breaks`` orders
    them), in step order; other events unchanged."""
    if "element" not in cracks or "bond" not in cracks:
        return cracks
    bond = np.asarray(cracks["bond"])
    step = np.asarray(cracks["step"])
    order = np.lexsort((np.arange(bond.size), step))
    _, first = np.unique(bond[order], return_index=True)
    keep = np.sort(order[first])
    keep = keep[np.argsort(step[keep], kind="stable")]
    return {k: (np.asarray(v)[keep] if np.ndim(v) and len(v) == bond.size else v)
            for k, v in cracks.items()}


def _first(cs: np.ndarray, mask: np.ndarray, k: int) -> np.ndarray:
    idx = np.flatnonzero(mask)
    order = idx[np.argsort(cs[idx], kind="stable")]
    return order[:k]


def bts_validity(cracks: dict, series_step, peak_record: int, *, centre, radius: float,
                 mean_ball_diameter: float, central_zone: float = 0.5,
                 ended: bool = True, contact: str = "platen") -> dict:
    """Verdict on one Brazilian run (module docstring). ``cracks``: the run's crack events
    (``step``, ``pos``); ``centre``: (x, y) of the disc centre; the load axis is y;
    ``contact``: what loads the disc ("platen", "jaw"), for the reason. Flat-joint
    element breaks are judged per contact (:func:`per_contact`)."""
    cracks = per_contact(cracks)
    cs = np.asarray(cracks["step"])
    pos = np.asarray(cracks["pos"], float).reshape(-1, 3)
    b = burst_mask(cs, series_step, peak_record)
    nb = int(b.sum())
    out = {"bts_valid": False, "bts_invalid_reason": "", "burst_cracks": nb,
           "init_cracks": 0, "init_offset": math.nan, "init_side": "",
           "split_band_fraction": math.nan, "pre_contact_fraction": math.nan}
    if not ended:
        out["bts_invalid_reason"] = ("the disc did not split: the test ended without a "
                                     "post-peak load drop")
        return out
    if nb == 0:
        out["bts_invalid_reason"] = "the disc did not split: no crack formed at the peak"
        return out
    k = max(INIT_MIN, int(math.ceil(INIT_FRACTION * nb)))
    first = _first(cs, b, k)
    dy = (pos[first, 1] - centre[1]) / radius
    off = float(np.median(np.abs(dy)))
    side = "top" if float(np.median(dy)) > 0 else "bottom"
    half_band = max(0.25 * radius, 1.5 * mean_ball_diameter)
    on_band = np.abs(pos[:, 0] - centre[0]) <= half_band
    band = float(np.mean(on_band[b]))
    pre = (cs >= 0) & ~b & on_band
    y = (pos[:, 1] - centre[1]) / radius
    grown = {"top": int(np.count_nonzero(pre & (y > central_zone))),
             "bottom": int(np.count_nonzero(pre & (y < -central_zone)))}
    g_side = max(grown, key=grown.get)
    pre_frac = grown[g_side] / nb
    out.update(init_cracks=int(first.size), init_offset=off, init_side=side,
               split_band_fraction=band, pre_contact_fraction=pre_frac)
    if off > central_zone:
        out["bts_invalid_reason"] = (
            f"fracture initiated next to the {side} {contact}: the first {first.size} cracks of "
            f"the failure lie at a median {off:.2f} R from the centre along the loaded "
            f"diameter (the central zone is {central_zone:g} R; ISRM)")
    elif pre_frac >= PRE_FRACTION:
        out["bts_invalid_reason"] = (
            f"a fracture grew from the {g_side} {contact} before the peak: "
            f"{grown[g_side]} cracks on the loaded diameter beyond the central zone before "
            f"the failure, {pre_frac:.0%} of its {nb} (less than {PRE_FRACTION:.0%} "
            "expected of a split that starts at the centre)")
    elif band < SPLIT_FRACTION:
        out["bts_invalid_reason"] = (
            f"the fracture did not follow the loaded diameter: {band:.0%} of the failure's "
            f"{nb} cracks lie within {half_band * 1e3:.3g} mm of it (at least "
            f"{SPLIT_FRACTION:.0%} expected for a split)")
    else:
        out["bts_valid"] = True
    return out


def dtt_validity(cracks: dict, series_step, peak_record: int, *, grip_faces,
                 clearance: float, ended: bool = True) -> dict:
    """Verdict on one direct-tension run (module docstring); ``grip_faces``: heights of
    the inner faces of the bottom and top grips; the axis is z. Flat-joint element breaks
    are judged per contact (:func:`per_contact`)."""
    cracks = per_contact(cracks)
    cs = np.asarray(cracks["step"])
    pos = np.asarray(cracks["pos"], float).reshape(-1, 3)
    b = burst_mask(cs, series_step, peak_record)
    zb, zt = (float(v) for v in grip_faces)
    out = {"dtt_valid": False, "dtt_invalid_reason": "", "burst_cracks": int(b.sum()),
           "fracture_height": math.nan, "fracture_grip_distance_mm": math.nan}
    if not ended:
        out["dtt_invalid_reason"] = ("the specimen did not break: the test ended without a "
                                     "post-peak load drop")
        return out
    if not b.any():
        out["dtt_invalid_reason"] = "the specimen did not break: no crack formed at the peak"
        return out
    zf = float(np.median(pos[b, 2]))
    db, dt = zf - zb, zt - zf
    d = min(db, dt)
    out.update(fracture_height=(zf - zb) / (zt - zb), fracture_grip_distance_mm=d * 1e3)
    if d < clearance:
        side = "bottom" if db < dt else "top"
        out["dtt_invalid_reason"] = (
            f"failure next to the {side} grip: the fracture lies {d * 1e3:.3g} mm from the "
            f"grip's face (at least {clearance * 1e3:.3g} mm, the grip clearance, expected)")
    else:
        out["dtt_valid"] = True
    return out


#: the stop reasons that mean the test reached what defines its measure
COMPLETE = ("post_peak_drop",)


def cut_off_reason(measure: tuple[str, str, str] | None, summary: dict) -> str:
    """Why a finished run measured nothing: its loading stopped at a cut-off
    (``max_strain``, ``max_steps``) before the peak and the drop that define its
    ``measure`` ((what it measures, the summary key of its peak, unit): the test's
    ``registry.LabTestKind.measure``; None, a test without one: ""); "" for a complete
    run. ``registry.incomplete_reason`` by the test's name."""
    if measure is None:
        return ""
    stop = str(summary.get("stop_reason", ""))
    if stop in COMPLETE:
        return ""
    measure, key, unit = measure
    what = {"max_strain": "its max_strain", "max_steps": "its max_steps"}.get(
        stop, f"stop reason {stop!r}")
    peak = summary.get(key)
    at = (f"; {peak:.4g} {unit} is the stress at the cut-off, not a {measure}"
          if isinstance(peak, (int, float)) and math.isfinite(peak) else "")
    fix = ("raise max_strain" if stop == "max_strain" else "raise max_steps or load faster")
    return (f"the loading stopped at {what} after {int(summary.get('steps', 0))} "
            f"steps, before the peak and the drop to stop_drop that define {measure}{at}; "
            f"{fix}")
