"""Drop-hammer impact on a bonded specimen: energy budget, crack stages, fragments.

Set-up: the specimen stands on its fixed bottom platen, the anvil (friction
``anvil_fric``, the hammer's too); its top platen is removed; a rigid hammer (a plane of
mass ``hammer_mass``, wider than anything it can hit, so no ball can slip under its edge)
starts just above the top face moving down at ``velocity``; gravity on;
no local damping (dynamic run); contact dashpots with critical-damping ratios
``dp_ratio`` (normal and shear).

Energies (J), recorded over time, all relative to the moment of release:
- ``W_in``: work done by the hammer on the rock (its boundary work) - the hammer's
  kinetic-energy loss plus the small potential-energy loss of its weight;
  ``W_in_paper`` = 1/2 M (v0^2 - v^2), the paper's definition;
- ``G_f`` (``released``): strain energy released by broken bonds, the paper's
  fracture-related energy; ``eta_f`` = G_f / W_in;
- rock: kinetic, linear-contact and bond strain energy, friction slip, dashpot dissipation;
  ``work_gravity`` on the rock.
The budget closes: W_in + work_gravity = d(kinetic + strain) + slip + dashpot + G_f;
``closure_rel`` = |difference| / max(the largest W_in so far, 1 % of the hammer's kinetic
energy at release) at every record: the energy the test has put in, floored so that the
first records after touch-down (W_in of micro-joules) do not divide a round-off by nearly
nothing.

Stages from the crack history: initiation = first record with >= 1 % of the final crack
count, through-failure = first record with >= 90 %; propagation in between; the time of
the largest crack rate is reported too.

The run ends when the hammer has rebounded (moving up) and ``after_rebound`` more time
has passed, when the hammer has come down to two ball diameters above the anvil (the
specimen is crushed through; steel would hit steel), or at ``duration``.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from ..dem.errors import InputError
from ..dem.slots import BOND_INTACT
from ..exact_math import libm_pow
from . import fragments as F
from .specimen import Specimen
from .stepping import cycle

IMPACT_SERIES = ("step", "time", "hammer_z", "hammer_v", "W_in", "W_in_paper", "cracks_tension",
                 "cracks_shear", "kinetic", "strain_linear", "strain_bond", "slip", "damping",
                 "dashpot", "released", "work_gravity", "eta_f", "closure_rel")


@dataclass(frozen=True)
class ImpactSettings:
    velocity: float = 6.0  # m/s, downwards
    hammer_mass: float = 4.383  # kg (2 x 78.9 J / (6 m/s)^2 at full scale)
    dp_ratio: float = 0.1  # contact dashpot critical-damping ratio (normal and shear)
    anvil_fric: float = 0.3  # friction coefficient of the anvil and the hammer
    gravity: float = 9.81
    duration: float = 40e-3  # s, at most (the study: impact.duration_ms); the rebound
    # ends it first: 8 / 15 / 20 ms at scale 0.25 / 0.5 / 0.75 for the A1 card
    # (docs/measurements/2026-11-26-impact-size.md)
    after_rebound: float = 2e-4  # s, kept running after the hammer moves up
    record_dt: float = 5e-6  # s between records (the study: impact.record_us)
    gap: float = 1e-5  # m, initial hammer gap above the top face

    def __post_init__(self):
        for k in ("velocity", "hammer_mass", "duration", "record_dt"):
            v = getattr(self, k)
            if not (v > 0 and math.isfinite(v)):
                raise InputError(f"{k}={v!r}: expected a positive number")
        if not (0.0 <= self.dp_ratio <= 1.0):
            raise InputError(f"dp_ratio={self.dp_ratio!r}: expected in [0, 1]")
        if not (0.0 <= self.anvil_fric <= 10.0):  # NaN fails too
            raise InputError(f"anvil_fric={self.anvil_fric!r}: expected a friction "
                             "coefficient in [0, 10]")


@dataclass
class ImpactResult:
    summary: dict
    series: dict
    cracks: dict
    fragments: dict
    settings: ImpactSettings


def primary_burst(t, n_cracks) -> float:
    """Crack count of the primary fracture burst: the count when the crack rate, after its
    peak, first falls below 1 % of the peak (the final count if it never does). A slow late
    phase (the hammer crushing the fragment bed) then does not shift the stages."""
    t = np.asarray(t, float)
    n = np.asarray(n_cracks, float)
    if n.size < 3 or n[-1] <= 0:
        return float(n[-1]) if n.size else 0.0
    rate = np.gradient(n, t)
    ip = int(np.argmax(rate))
    below = np.nonzero(rate[ip:] < 0.01 * rate[ip])[0]
    return float(n[ip + below[0]] if below.size else n[-1])


def crack_stages(t, n_cracks) -> dict:
    """Stage times from the crack history: initiation (1 % of the primary burst's cracks),
    peak crack rate, through-failure (90 % of the primary burst, see ``primary_burst``),
    and the number of cracks after the burst (``late_cracks``)."""
    t = np.asarray(t, float)
    n = np.asarray(n_cracks, float)
    total = n[-1] if n.size else 0.0
    if total <= 0:
        return {"t_initiation": math.nan, "t_peak_rate": math.nan, "t_through": math.nan,
                "late_cracks": 0}
    ref = primary_burst(t, n)
    i1 = int(np.argmax(n >= max(1.0, 0.01 * ref)))
    i9 = int(np.argmax(n >= 0.9 * ref))
    rate = np.gradient(n, t) if n.size > 1 else np.zeros(1)
    return {"t_initiation": float(t[i1]), "t_peak_rate": float(t[int(np.argmax(rate))]),
            "t_through": float(t[i9]), "late_cracks": int(total - ref)}


#: the floor of closure_rel's denominator, as a fraction of the hammer's kinetic energy at release
CLOSURE_FLOOR = 0.01


def closure_rel(residual: float, w_in_max: float, ek0: float) -> float:
    """|``residual``| of the energy budget relative to the energy put in so far
    (``w_in_max``, the largest W_in up to now), floored at ``CLOSURE_FLOOR`` x the
    hammer's kinetic energy at release ``ek0``."""
    den = max(w_in_max, CLOSURE_FLOOR * ek0)
    return abs(residual) / den if den > 0 else 0.0


def run_impact(sp: Specimen, st: ImpactSettings = ImpactSettings(), progress=None) -> ImpactResult:
    m = sp.model
    wb, wt = sp.platens
    m.remove_wall(wt)  # the top platen goes; the bottom one stays, fixed
    m.set_wall_friction(wb, st.anvil_fric)
    m.set_damping(0.0)
    m.set_material(sp.material.replace(dp_nratio=st.dp_ratio, dp_sratio=st.dp_ratio))
    m.set_gravity((0.0, 0.0, -st.gravity))
    z_top = float((m.positions[:, 2] + m.radii).max())
    hammer = m.add_plane_wall((0.0, 0.0, z_top + st.gap), (0.0, 0.0, -1.0),
                              velocity=(0.0, 0.0, -st.velocity), fric=st.anvil_fric,
                              mass=st.hammer_mass)
    m.set_timestep(None)
    dt = m.dt
    n_rec = max(1, int(round(st.record_dt / dt)))
    e0 = m.energies()
    rock_mass = float(m.masses.sum())
    step0, t0 = m.step, m.time
    ser = {k: [] for k in IMPACT_SERIES}
    wall0 = time.perf_counter()
    ek0 = 0.5 * st.hammer_mass * st.velocity ** 2
    w_max = [0.0]  # the largest W_in so far

    def rec():
        e = m.energies()
        v = float(m.wall_velocity(hammer)[2])
        w_in = e["work_walls_each"][hammer] - e0["work_walls_each"][hammer]
        n_t, n_s = m.crack_counts()
        d = {k: e[k] - e0[k] for k in ("kinetic", "strain_linear", "strain_bond", "slip",
                                         "damping", "dashpot", "released", "removed")}
        grav_rock = (e["work_gravity"] - e["work_gravity_walls"]) - (
            e0["work_gravity"] - e0["work_gravity_walls"])
        lhs = w_in + grav_rock  # the bottom platen is fixed: it does no work
        stored = sum(d.values())
        ser["step"].append(m.step - step0)
        ser["time"].append(m.time - t0)
        ser["hammer_z"].append(float(m.wall_position(hammer)[2]))
        ser["hammer_v"].append(v)
        ser["W_in"].append(w_in)
        ser["W_in_paper"].append(0.5 * st.hammer_mass * (st.velocity ** 2 - v ** 2))
        ser["cracks_tension"].append(n_t)
        ser["cracks_shear"].append(n_s)
        for k, val in d.items():
            if k in ser:
                ser[k].append(val)
        ser["work_gravity"].append(grav_rock)
        ser["eta_f"].append(d["released"] / w_in if w_in > 0 else 0.0)
        w_max[0] = max(w_max[0], w_in)
        ser["closure_rel"].append(closure_rel(lhs - stored, w_max[0], ek0))
        return v

    rec()
    t_rebound = None
    reason = "duration"
    z_floor = float(m.wall_position(wb)[2]) + 4.0 * float(m.radii.max())
    while m.time - t0 < st.duration:
        cycle(m, n_rec)
        v = rec()
        if progress is not None:
            progress({"strain": 0.0, "stress_MPa": 0.0, "peak_MPa": 0.0,
                      "cracks": ser["cracks_tension"][-1] + ser["cracks_shear"][-1],
                      "steps": m.step - step0, "wall_s": time.perf_counter() - wall0})
        if v > 0 and t_rebound is None:
            t_rebound = m.time - t0
        if t_rebound is not None and m.time - t0 - t_rebound >= st.after_rebound:
            reason = "rebound"
            break
        if float(m.wall_position(hammer)[2]) <= z_floor:
            reason = "hammer_on_anvil"
            break
    series = {k: np.asarray(v) for k, v in ser.items()}
    ncr = series["cracks_tension"] + series["cracks_shear"]
    stages = crack_stages(series["time"], ncr)
    # fragments
    bi, bj = m.bond_pairs()
    labels = F.fragments(m.n, bi, bj, m.bond_states == BOND_INTACT)
    fmass, fsize = F.fragment_sizes(labels, m.radii, sp.spec.density)
    solid = float((4 / 3 * np.pi * libm_pow(m.radii, 3)).sum())
    orig = (6 * solid / np.pi) ** (1 / 3)
    mean_d = 2 * float(m.radii.mean())
    w_in = float(series["W_in"][-1])
    summ = {
        "W_in_J": w_in, "W_in_paper_J": float(series["W_in_paper"][-1]),
        "G_f_J": float(series["released"][-1]),
        "eta_f": float(series["eta_f"][-1]),
        "closure_rel_max": float(series["closure_rel"][1:].max()) if series["closure_rel"].size > 1 else 0.0,
        "hammer_v_end": float(series["hammer_v"][-1]),
        "t_rebound_s": t_rebound if t_rebound is not None else math.nan,
        "cracks_tension": int(series["cracks_tension"][-1]),
        "cracks_shear": int(series["cracks_shear"][-1]),
        **{f"{k}_s": v for k, v in stages.items() if k.startswith("t_")},
        "cracks_after_burst": stages["late_cracks"],
        "n_fragments": int(fmass.size), "largest_fragment_frac": float(fmass.max() / fmass.sum()),
        "original_size_mm": orig * 1e3, "t10_pct": F.t10(fmass, fsize, orig),
        "ecs_kWh_t": w_in / rock_mass / F.KWH_PER_T,
        "balls_per_t10_fragment": (orig / 10 / mean_d) ** 3,
        "rock_mass_kg": rock_mass, "steps": int(m.step - step0), "dt": dt,
        "wall_s": time.perf_counter() - wall0, "stop_reason": reason,
        "n_balls": int(m.n), "n_bonds": int(m.n_bonds),
    }
    ev = m.breaks()
    ev["step"] = ev["step"] - step0
    ev["time"] = ev["step"] * dt
    frag = {"label": labels, "mass": fmass, "size": fsize}
    return ImpactResult(summary=summ, series=series, cracks=ev, fragments=frag, settings=st)


def settings_dict(st: ImpactSettings) -> dict:
    return asdict(st)
