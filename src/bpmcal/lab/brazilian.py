"""Brazilian (diametral compression) test of a bonded disc: the indirect tensile strength.

Specimen (ISRM suggested method): a disc of diameter D and thickness t = D/2, D = 50 mm at
full size, shrunk by the specimen scale like the UCS cylinder (``SpecimenSpec`` with
``diameter = D``, ``height = t``; 20 x 10 mm and ~390 balls at the default scale 0.4 with
Rmin 0.8 mm). It is packed and bonded by the same genesis as the cylinder (the same cached
packing procedure in a vessel D x t with its axis along z), then the whole vessel is
removed and the disc settles free (``build_specimen(boundary="free")``): the flat faces of
a Brazilian disc are free, and its curved face must not stay held by the vessel.

Platens, as the diametral-compression test of PFC's material-modeling package: two rigid
planar walls with normals along y (the load axis is y, the disc axis z), each placed to
just touch the outermost ball (no initial overlap). A flat platen bears on the curved face
along a line (the few balls of the generatrix the vessel packed flat); the ISRM curved
jaws are not modelled. The platens have friction (``platen_fric`` 0.3, steel on rock):
a free disc between frictionless platens has an unconstrained rolling/spinning mode and,
touched first by one ball per side, spins at tens of rad/s (measured) before it comes to
rest; friction removes that mode (seating in 1-2 thousand steps instead of 20-70
thousand). The friction confines the contact zones: sigma_t is ~15 % higher than with
frictionless platens (A1 set, scale 0.4, seeds 1 and 3: 6.94 vs 6.05 and 9.42 vs 8.11
MPa); ``platen_fric=0`` gives PFC's frictionless walls.

Stages:

1. **Seating** (``seat``): both platens are servo-controlled (``servo.Servo``, speed
   capped at ``seat_velocity``) to the seating load 2 P / (pi D t) = ``seat_stress``
   (0.1 MPa) until both carry it within 5 %, the disc is in equilibrium (mean
   unbalanced-force ratio <= 1e-2) and no ball moves faster than ``seat_velocity``, as a
   laboratory seating load. The seated state does not depend on the loading speed.
2. **Loading**: the platens approach each other at ``platen_velocity`` each; local
   damping 0.7. With ``approach_velocity`` > ``platen_velocity`` (default 0: off) they
   close at that speed until the first bond breaks, then at ``platen_velocity``: the disc
   is elastic up to the first crack (with flat platens at 26-40 % of the peak strain on
   the default study's samples), so only the time to get there is saved; the study uses
   it (``bts.approach_velocity``, README "Brazilian tests in the study").

Measurements, recorded every ``record_strain`` of diametral strain (approach / D), the
approach counted from the seated platen positions:

- load P = mean of the two platen forces (the y-component the balls exert on each), the
  two forces (``load_bottom``, ``load_top``), the approach delta;
- ``tensile_stress`` = 2 P / (pi D t), the tensile stress at the disc centre for a line
  load (Hondros/ISRM), with the nominal D and t of the specimen;
- cracks (broken bonds) by mode; their positions and normals are in the crack events;
- the energy terms of the engine, as in the UCS test.

Result: sigma_t = 2 P_peak / (pi D t) with P_peak the largest mean load; the approach and
diametral strain at the peak; the mismatch of the two platen forces at the peak; crack
counts at the peak and at the end; ``cracks_central_frac_peak``, the share of the cracks
formed up to the peak within D/4 of the disc centre (with flat platens most pre-peak
cracks start under the platens and run along the loaded diameter; the split through the
centre comes at the peak). The test stops when the load falls below ``stop_drop`` (70 %)
of the peak at least ``post_peak_min`` diametral strain after it, at ``max_strain``, or
after ``max_steps``.

Loading rate: the default 0.00625 m/s per platen is 8x slower than the UCS default,
because the Brazilian peak is set by a few bond breaks under the platens rather than by
the damage of the whole specimen. Halving it changed sigma_t by 0.007-0.15 % on packing
seeds 1-3 and by 0.1-2.8 % on seeds 1-6 at scale 0.4 (A1 set; README); at 0.0125 m/s
halving changed it by up to 9.9 %. A single disc of ~400 balls can still take either of
two failure paths (a few % apart) when the loading changes slightly, so compare seeds'
medians, not single runs.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from ..dem.errors import InputError
from ..dem.layout import BOND_SHEAR, BOND_TENSION
from .servo import Servo, ServoError, ServoLoop
from .specimen import Specimen
from .stepping import cycle

#: columns of the recorded time series
BTS_SERIES = ("step", "time", "displacement", "diametral_strain", "load", "load_bottom",
              "load_top", "tensile_stress", "cracks_tension", "cracks_shear", "kinetic",
              "strain_linear", "strain_bond", "slip", "damping", "dashpot", "released",
              "work_walls", "unbalanced")


@dataclass(frozen=True)
class BTSSettings:
    platen_velocity: float = 0.00625  # m/s, each platen (see the module docstring)
    damping: float = 0.7
    platen_fric: float = 0.3
    stop_drop: float = 0.7  # stop when load < stop_drop * peak after the peak
    max_strain: float = 0.05  # platen approach / D
    max_steps: int = 3_000_000
    record_strain: float = 1e-5  # diametral strain (approach / D) between records
    post_peak_min: float = 0.002  # also require this much diametral strain past the peak
    central_band: float = 0.25  # cracks within central_band * D of the centre are central
    seat_stress: float = 0.1e6  # Pa, seating load as 2 P / (pi D t) before loading
    seat_velocity: float = 0.0125  # m/s, platen speed cap and at-rest threshold of seating
    seat_tol: float = 0.05  # seated: both platen loads within this fraction of the target
    seat_ratio: float = 1e-2  # ... and the mean unbalanced-force ratio below this
    max_seat_steps: int = 200_000
    servo_alpha: float = 0.8  # servo relaxation factor during seating (PFC default)
    approach_velocity: float = 0.0  # m/s, each platen until the first crack (0: off)

    def __post_init__(self):
        if not (self.platen_velocity > 0 and math.isfinite(self.platen_velocity)):
            raise InputError(f"platen_velocity={self.platen_velocity!r}: expected a positive "
                             "speed in m/s")
        if not (0.0 <= self.damping < 1.0):
            raise InputError(f"damping={self.damping!r}: expected a local damping in [0, 1)")
        if not (self.platen_fric >= 0 and math.isfinite(self.platen_fric)):
            raise InputError(f"platen_fric={self.platen_fric!r}: expected a friction "
                             "coefficient >= 0")
        if not (0.0 < self.stop_drop < 1.0):
            raise InputError(f"stop_drop={self.stop_drop!r}: expected a fraction in (0, 1)")
        if not (0.0 < self.max_strain <= 0.5):
            raise InputError(f"max_strain={self.max_strain!r}: expected a diametral strain "
                             "in (0, 0.5]")
        if not (self.record_strain > 0 and math.isfinite(self.record_strain)):
            raise InputError(f"record_strain={self.record_strain!r}: expected > 0")
        if not (math.isfinite(self.approach_velocity) and self.approach_velocity >= 0):
            raise InputError(f"approach_velocity={self.approach_velocity!r}: expected a speed "
                             ">= 0 in m/s (0: no fast approach)")
        if not (self.post_peak_min >= 0):
            raise InputError(f"post_peak_min={self.post_peak_min!r}: expected >= 0")
        if not (0.0 < self.central_band <= 0.5):
            raise InputError(f"central_band={self.central_band!r}: expected a fraction of D "
                             "in (0, 0.5]")
        for k in ("seat_stress", "seat_velocity"):
            v = getattr(self, k)
            if not (v > 0 and math.isfinite(v)):
                raise InputError(f"{k}={v!r}: expected a positive number (SI units)")
        if not (0.0 < self.seat_tol < 1.0 and self.seat_ratio > 0):
            raise InputError(f"seat_tol={self.seat_tol!r}, seat_ratio={self.seat_ratio!r}: "
                             "expected 0 < seat_tol < 1 and seat_ratio > 0")
        if not (int(self.max_steps) > 0):
            raise InputError(f"max_steps={self.max_steps!r}: expected a positive integer")


@dataclass
class BTSResult:
    summary: dict
    series: dict  # column -> np.ndarray
    cracks: dict  # event arrays (Model.breaks()), steps relative to the start of loading
    settings: BTSSettings


def tensile_strength(load, diameter, thickness):
    """Brazilian tensile stress 2 P / (pi D t) [Pa] for a load P [N] (ISRM)."""
    return 2.0 * np.asarray(load, float) / (math.pi * diameter * thickness)


def analyse(series: dict, diameter: float, thickness: float) -> dict:
    """sigma_t, the peak load and where it is, from a recorded series."""
    P = np.asarray(series["load"], float)
    ip = int(np.argmax(P))
    pa = float(series["load_bottom"][ip])
    pb = float(series["load_top"][ip])
    peak = float(P[ip])
    return {"bts_MPa": float(tensile_strength(peak, diameter, thickness)) / 1e6,
            "peak_load_N": peak,
            "peak_displacement_mm": float(series["displacement"][ip]) * 1e3,
            "peak_strain": float(series["diametral_strain"][ip]),
            "platen_mismatch": abs(pa - pb) / peak if peak > 0 else math.nan,
            "cracks_tension_peak": int(series["cracks_tension"][ip]),
            "cracks_shear_peak": int(series["cracks_shear"][ip]),
            "peak_record": ip}


def add_platens(sp: Specimen, fric: float = 0.0) -> tuple[int, int]:
    """Two planar platens with normals along +-y touching the outermost balls of a free
    disc (no initial overlap). Returns their wall ids (bottom at -y, top at +y)."""
    m = sp.model
    if m.n_walls:
        raise InputError(f"the Brazilian disc must be free (built with boundary='free'); "
                         f"it has {m.n_walls} wall(s)")
    y = m.positions[:, 1]
    r = m.radii
    lo = float((y - r).min())
    hi = float((y + r).max())
    wb = m.add_plane_wall((0.0, lo, 0.0), (0.0, 1.0, 0.0), fric=fric)
    wt = m.add_plane_wall((0.0, hi, 0.0), (0.0, -1.0, 0.0), fric=fric)
    return wb, wt


def seat(sp: Specimen, platens, st: BTSSettings) -> dict:
    """Bring both platens onto the disc under servo control until each carries the
    seating load 2 P / (pi D t) = ``seat_stress`` and the disc is in equilibrium. A free
    disc touched first by one ball per side is in an indifferent state (it can roll or
    spin on frictionless platens): seating lets it find its bearing contacts at a small
    load, as a seating load does in the laboratory, so that the loading stage starts from
    a statically determinate state."""
    m = sp.model
    D, t = sp.spec.diameter, sp.spec.height
    F = st.seat_stress * math.pi * D * t / 2.0
    servos = [Servo(m, w, lambda: F, alpha=st.servo_alpha, vmax=st.seat_velocity)
              for w in platens]
    loop = ServoLoop(m, servos)
    s0 = m.step
    ratio = math.inf
    vmax = math.inf
    seated = False
    while m.step - s0 < st.max_seat_steps:
        loop.run(200)
        ok = all(abs(s.error()) <= st.seat_tol * F for s in servos)
        # at rest: the forces balance and no ball moves faster than the seating platens
        # (a disc spinning on frictionless platens balances its forces but is not seated)
        vmax = float(np.sqrt((m.velocities ** 2).sum(axis=1).max()))
        if ok and vmax <= st.seat_velocity:
            ratio = m.unbalanced_ratio()
            if ratio <= st.seat_ratio:
                seated = True
                break
    for s in servos:
        s.stop()
    if not seated:
        raise ServoError(
            f"the disc did not seat: platen loads {[round(s.force(), 3) for s in servos]} N "
            f"for a seating load of {F:.4g} N, unbalanced-force ratio {ratio:.3g}, fastest "
            f"ball {vmax:.3g} m/s after {m.step - s0} steps (platen friction "
            f"{st.platen_fric:g}: a free disc can spin on frictionless platens)")
    return {"seat_steps": int(m.step - s0), "seat_load_N": F, "seat_ratio": float(ratio)}


def run_bts(sp: Specimen, settings: BTSSettings = BTSSettings(), progress=None) -> BTSResult:
    """Run the test on the free disc ``sp`` (its model is modified: platens are added).
    ``progress(dict)`` is called after every record with the latest values."""
    st = settings
    m = sp.model
    D = sp.spec.diameter
    t = sp.spec.height
    v = st.platen_velocity
    wb, wt = add_platens(sp, st.platen_fric)
    m.set_damping(st.damping)
    m.set_timestep(None)
    dt = m.dt
    seated = seat(sp, (wb, wt), st)

    def platens(speed):
        m.set_wall_velocity(wb, velocity=(0.0, speed, 0.0))
        m.set_wall_velocity(wt, velocity=(0.0, -speed, 0.0))
        return max(1, int(round(st.record_strain * D / (2 * speed * dt))))  # steps per record

    approach = st.approach_velocity > v  # fast approach until the first crack
    n_rec = platens(st.approach_velocity if approach else v)
    approach_strain = 0.0
    c0 = m.positions[:, :2].mean(axis=0)  # disc centre (x, y)
    yb0, yt0 = float(m.wall_position(wb)[1]), float(m.wall_position(wt)[1])
    ser = {k: [] for k in BTS_SERIES}
    e0 = m.energies()
    e0_walls = e0["work_walls_each"][wb] + e0["work_walls_each"][wt]
    step0 = m.step
    t_start = m.time
    t0 = time.perf_counter()
    peak = 0.0
    peak_strain = 0.0
    reason = "max_steps"

    def record():
        e = m.energies()
        fb = abs(m.wall_force(wb)[1])
        ft = abs(m.wall_force(wt)[1])
        delta = (float(m.wall_position(wb)[1]) - yb0) + (yt0 - float(m.wall_position(wt)[1]))
        P = 0.5 * (fb + ft)
        states = m.bond_states
        ser["step"].append(m.step - step0)
        ser["time"].append(m.time - t_start)
        ser["displacement"].append(delta)
        ser["diametral_strain"].append(delta / D)
        ser["load"].append(P)
        ser["load_bottom"].append(fb)
        ser["load_top"].append(ft)
        ser["tensile_stress"].append(float(tensile_strength(P, D, t)))
        ser["cracks_tension"].append(int(np.count_nonzero(states == BOND_TENSION)))
        ser["cracks_shear"].append(int(np.count_nonzero(states == BOND_SHEAR)))
        for k in ("kinetic", "strain_linear", "strain_bond", "slip", "damping", "dashpot",
                  "released"):
            ser[k].append(e[k] - e0[k] if k in ("slip", "damping", "dashpot", "released")
                          else e[k])
        ser["work_walls"].append(e["work_walls_each"][wb] + e["work_walls_each"][wt]
                                 - e0_walls)
        ser["unbalanced"].append(m.unbalanced_ratio())
        return P, delta / D

    record()
    while True:
        if m.step - step0 >= st.max_steps:
            reason = "max_steps"
            break
        cycle(m, n_rec)
        P, eps = record()
        if approach and ser["cracks_tension"][-1] + ser["cracks_shear"][-1] > 0:
            approach, approach_strain = False, eps  # the first crack: load at v from here
            n_rec = platens(v)
        if P > peak:
            peak, peak_strain = P, eps
        if progress is not None:
            progress({"strain": eps, "stress_MPa": ser["tensile_stress"][-1] / 1e6,
                      "peak_MPa": float(tensile_strength(peak, D, t)) / 1e6,
                      "cracks": ser["cracks_tension"][-1] + ser["cracks_shear"][-1],
                      "steps": m.step - step0, "wall_s": time.perf_counter() - t0})
        if peak > 0 and P < st.stop_drop * peak and eps - peak_strain >= st.post_peak_min:
            reason = "post_peak_drop"
            break
        if eps >= st.max_strain:
            reason = "max_strain"
            break
    wall = time.perf_counter() - t0
    series = {k: np.asarray(vv) for k, vv in ser.items()}
    summ = analyse(series, D, t)
    ev = m.breaks()
    ev["step"] = ev["step"] - step0  # relative to the start of loading (< 0: before)
    ev["time"] = ev["step"] * dt
    ip = summ.pop("peak_record")
    upto = ev["step"] <= series["step"][ip]
    central = np.hypot(*(ev["pos"][upto, :2] - c0).T) <= st.central_band * D
    summ.update({
        "cracks_central_frac_peak": float(central.mean()) if central.size else math.nan,
        "cracks_tension": int(series["cracks_tension"][-1]),
        "cracks_shear": int(series["cracks_shear"][-1]),
        "steps": int(m.step - step0), "wall_s": wall, "stop_reason": reason,
        "dt": dt, "platen_velocity": v, "approach_velocity": st.approach_velocity,
        "approach_strain": approach_strain,
        "diameter_mm": D * 1e3, "thickness_mm": t * 1e3,
        "records": int(series["step"].size), **seated,
    })
    return BTSResult(summary=summ, series=series, cracks=ev, settings=st)


def settings_dict(st: BTSSettings) -> dict:
    return asdict(st)
