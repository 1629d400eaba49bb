"""Conventional triaxial compression test (sigma1 > sigma2 = sigma3) of a bonded cylinder.

Confinement: the genesis vessel's rigid, frictionless cylindrical wall is kept
(``build_specimen(boundary="vessel")``) and its radius is servo-controlled (PFC's wall
servo, ``servo.Servo``: v_r = G (sigma_measured - sigma3) A, G = alpha / (K dt), capped
at ``servo_vmax``) so that the lateral wall stress, the radial force sum / (2 pi R_c H)
with R_c the current wall radius and H the current platen distance, equals sigma3. This
is the confinement of PFC's material-modeling package for a cylindrical vessel. Its
limitation: a rigid cylinder imposes one radial displacement on the whole lateral
surface (a lab membrane lets the specimen barrel or shear through), so localisation
through the lateral surface is restrained and post-peak behaviour is stiffer than in the
laboratory; the peak is less affected. The alternative, a pressure on the exposed area
of the surface balls (a flexible membrane), needs a surface-tracking algorithm and is
not implemented.

Stages:

1. **Consolidation**: all three walls are servo-controlled to the isotropic stress sigma3
   (the platens to sigma3 pi R_c^2, at least the seating stress ``seat_stress``, 0.1 MPa,
   so that the platens stay in contact when sigma3 = 0) until every wall stress is within
   ``consol_tol`` of its target and the specimen is in equilibrium (mean unbalanced-force
   ratio <= ``consol_ratio``).
2. **Axial loading**: the platens approach each other at ``platen_velocity`` each (as in
   the UCS test) while the lateral servo holds sigma3; the servo acts every
   ``servo_interval`` steps (default every step), inside the engine (``lab.servo``:
   its targets are ``WallTarget`` stresses on the cell's areas).

Measurements, recorded every ``record_strain`` of axial strain, strains counted from the
start of axial loading (compression positive):

- axial stress sigma1 = mean platen force / (pi R_c0^2), the cross-section at the start
  of axial loading (R_c0: wall radius after consolidation), as the UCS test and ASTM
  D7012 (initial area). Not the current wall radius: at low sigma3 the wall follows the
  most bulging balls, not the mean surface, and would overstate the area;
- confining stress sigma3 as measured on the lateral wall (recorded: it is what the
  servo holds), deviator q = sigma1 - sigma3 (measured);
- axial strain eps_a = platen approach / H0 (H0: platen distance after consolidation);
- lateral strain eps_r from the *surface balls* in the central band, as in the UCS
  test (so sigma3 = 0 gives the UCS definition), and ``lateral_strain_wall`` = -(R_c -
  R_c0) / R_c0 from the wall radius; volumetric strain eps_a + 2 eps_r;
- cracks by mode and the energy terms of the engine.

Results: the peak is the largest deviator q_p; ``sigma1_MPa`` = sigma3 (target) + q_p,
i.e. the peak axial stress with the servo's small deviation from sigma3 removed
(``sigma1_measured_MPa`` is the platen stress at that record); E = slope of q vs eps_a
and nu = -slope of eps_r vs eps_a over the pre-peak records with q in ``fit_window``
(40-60 %) of q_p (``nu_wall`` from the wall radius); ``u_pre_MJm3`` = integral of q d eps_a
up to the peak; ``crack_init_MPa`` = q when the crack count first reaches 1 % of the count
at the peak; ``sigma3_maxdev_rel`` = max |sigma3
measured - sigma3| / sigma3 over the records up to the peak (the servo's accuracy; NaN
for sigma3 = 0, where ``sigma3_maxdev_MPa`` gives it in MPa). The test stops as the UCS
test: q below ``stop_drop`` of q_p after the peak, ``max_strain`` or ``max_steps``.

End caps (``end_cap``, ``end_cap_factor``): as in the UCS test (``lab.ucs``), installed
before the consolidation.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from ..dem.errors import InputError
from .budget import Loading, platen_loading
from .driver import (
    Loaded,
    LoadingTest,
    check_loading_settings,
    record_common,
    run_test,
    scaled_timestep,
)
from .records import LateralGauge, loading_cracks
from .servo import Servo, ServoError, ServoLoop, WallTarget
from .specimen import Specimen
from .stepping import loading_bound
from .ucs import END_CAP_FACTOR, END_CAP_HEIGHT, check_end_cap, fit_slope, install_end_caps

#: columns of the recorded time series
TRIAXIAL_SERIES = ("step", "time", "axial_strain", "lateral_strain", "lateral_strain_wall",
                   "volumetric_strain", "axial_stress", "confining_stress", "deviator",
                   "stress_top", "stress_bottom", "wall_radius", "cracks_tension",
                   "cracks_shear", "kinetic", "strain_linear", "strain_bond", "slip",
                   "damping", "dashpot", "released", "work_walls", "unbalanced")


@dataclass(frozen=True)
class TriaxialSettings:
    sigma3: float = 0.0  # Pa, confining stress
    platen_velocity: float = 0.05  # m/s, each platen (used when strain_rate is None)
    strain_rate: float | None = None  # 1/s; if given, each platen moves at rate * H0 / 2
    damping: float = 0.7
    platen_fric: float = 0.0
    wall_fric: float = 0.0  # lateral wall (a membrane carries no shear)
    servo_alpha: float = 0.8  # relaxation factor of the servo gain (PFC default)
    servo_vmax: float = 5.0  # m/s, velocity cap of the servo-controlled walls
    servo_interval: int = 1  # steps between servo updates
    servo_feedforward: bool = True  # add the contacting balls' mean velocity (servo.py)
    gain_update: int = 10  # steps between gain updates
    seat_stress: float = 0.1e6  # Pa, least platen stress during consolidation
    consol_tol: float = 0.005  # consolidated: every wall stress within this of its target
    consol_tol_abs: float = 0.005e6  # Pa, ... or within this (sigma3 near zero)
    consol_ratio: float = 1e-2  # ... and the mean unbalanced-force ratio below this
    max_consol_steps: int = 1_000_000
    stop_drop: float = 0.7  # stop when q < stop_drop * peak q after the peak
    max_strain: float = 0.03
    max_steps: int = 3_000_000
    record_strain: float = 1e-5  # axial strain between records
    fit_window: tuple = (0.4, 0.6)
    lateral_band: tuple = (0.1, 0.9)
    post_peak_strain: float = 0.002  # also require this much strain past the peak to stop
    ci_fraction: float = 0.01
    end_cap: float = END_CAP_HEIGHT  # end caps as in the UCS test (lab.ucs) [mean ball diameters]
    end_cap_factor: float = END_CAP_FACTOR
    density_scaling: float | None = None  # quantile: PFC's density scaling (lab.driver)

    def loading_at(self, length: float) -> Loading:
        """The axial loading of a cylinder of ``length`` [m] (the consolidated height)."""
        return platen_loading("triaxial", self, length)

    def __post_init__(self):
        check_end_cap(self.end_cap, self.end_cap_factor)
        s3 = self.sigma3
        if not (isinstance(s3, (int, float)) and math.isfinite(s3) and s3 >= 0):
            raise InputError(f"sigma3={s3!r}: expected a confining stress >= 0 Pa")
        if self.strain_rate is not None and not (self.strain_rate > 0
                                                 and math.isfinite(self.strain_rate)):
            raise InputError(f"strain_rate={self.strain_rate!r}: expected a positive rate in 1/s")
        for k in ("platen_velocity", "servo_vmax", "seat_stress"):
            v = getattr(self, k)
            if not (v > 0 and math.isfinite(v)):
                raise InputError(f"{k}={v!r}: expected a positive number (SI units)")
        for k in ("platen_fric", "wall_fric", "consol_tol_abs"):
            v = getattr(self, k)
            if not (v >= 0 and math.isfinite(v)):
                raise InputError(f"{k}={v!r}: expected a number >= 0")
        check_loading_settings(self)
        if not (0.0 < self.servo_alpha <= 1.0):
            raise InputError(f"servo_alpha={self.servo_alpha!r}: expected 0 < alpha <= 1")
        if int(self.servo_interval) < 1 or int(self.gain_update) < 1:
            raise InputError(f"servo_interval={self.servo_interval!r}, gain_update="
                             f"{self.gain_update!r}: expected integers >= 1")
        if not (0.0 < self.consol_tol < 1.0 and self.consol_ratio > 0):
            raise InputError(f"consol_tol={self.consol_tol!r}, consol_ratio="
                             f"{self.consol_ratio!r}: expected 0 < tol < 1, ratio > 0")


@dataclass
class TriaxialResult:
    summary: dict
    series: dict  # column -> np.ndarray
    cracks: dict  # event arrays (Model.breaks()), steps relative to the start of loading
    settings: TriaxialSettings


class _Cell:
    """The three walls of the triaxial cell and the stresses they measure."""

    def __init__(self, sp: Specimen):
        if sp.lateral_wall is None or len(sp.platens) != 2:
            raise InputError("the triaxial test needs a specimen built with "
                             "boundary='vessel' (cylinder and both platens kept)")
        self.m = sp.model
        self.wl = sp.lateral_wall
        self.wb, self.wt = sp.platens

    def radius(self) -> float:
        return self.m.wall_radius(self.wl)

    def height(self) -> float:
        m = self.m
        return float(m.wall_position(self.wt)[2] - m.wall_position(self.wb)[2])

    def area(self) -> float:
        return math.pi * self.radius() ** 2

    def lateral_area(self) -> float:
        return 2.0 * math.pi * self.radius() * self.height()

    def platen_stresses(self, area: float | None = None) -> tuple[float, float]:
        """Axial stresses on the two platens over ``area`` (default: the current
        cross-section pi R_c^2)."""
        m = self.m
        a = self.area() if area is None else area
        return (abs(float(m.wall_force(self.wb)[2])) / a,
                abs(float(m.wall_force(self.wt)[2])) / a)

    def lateral_stress(self) -> float:
        return self.m.wall_radial_force(self.wl) / self.lateral_area()


def consolidate(sp: Specimen, st: TriaxialSettings) -> dict:
    """Stage 1: servo all three walls to the isotropic stress sigma3 (platens at least to
    ``seat_stress``) until the targets are held and the specimen is in equilibrium."""
    m = sp.model
    c = _Cell(sp)
    s_ax = max(st.sigma3, st.seat_stress)
    kw = dict(alpha=st.servo_alpha, vmax=st.servo_vmax, approach=st.platen_velocity,
              feedforward=st.servo_feedforward)
    servos = [Servo(m, c.wl, WallTarget.lateral(st.sigma3, c.wl, c.wb, c.wt), **kw),
              Servo(m, c.wb, WallTarget.section(s_ax, c.wl), **kw),
              Servo(m, c.wt, WallTarget.section(s_ax, c.wl), **kw)]
    loop = ServoLoop(m, servos, interval=st.servo_interval, gain_update=st.gain_update)
    H0, R0 = c.height(), c.radius()
    s0 = m.step
    ratio = math.inf
    done = False
    while m.step - s0 < st.max_consol_steps:
        loop.run(200, record=False)
        errs = [abs(c.lateral_stress() - st.sigma3)] + [abs(s - s_ax)
                                                        for s in c.platen_stresses()]
        tol = [max(st.consol_tol * st.sigma3, st.consol_tol_abs)] + [
            max(st.consol_tol * s_ax, st.consol_tol_abs)] * 2
        if all(e <= t for e, t in zip(errs, tol)):
            ratio = m.unbalanced_ratio()
            if ratio <= st.consol_ratio:
                done = True
                break
    for s in servos[1:]:
        s.stop()
    if not done:
        raise ServoError(
            f"consolidation to sigma3 = {st.sigma3 / 1e6:g} MPa did not converge: wall "
            f"stresses {c.lateral_stress() / 1e6:.4g} (lateral), "
            f"{', '.join(f'{s / 1e6:.4g}' for s in c.platen_stresses())} MPa (platens), "
            f"unbalanced-force ratio {ratio:.3g} after {m.step - s0} steps")
    return {"consol_steps": int(m.step - s0), "consol_ratio": float(ratio),
            "consol_axial_strain": (H0 - c.height()) / H0,
            "consol_lateral_strain": (R0 - c.radius()) / R0,
            "servo": servos[0]}


def analyse(series: dict, settings: TriaxialSettings) -> dict:
    """Peak, sigma1, E, nu and the servo accuracy from a recorded series."""
    st = settings
    q = np.asarray(series["deviator"], float)
    ea = np.asarray(series["axial_strain"], float)
    er = np.asarray(series["lateral_strain"], float)
    erw = np.asarray(series["lateral_strain_wall"], float)
    s3m = np.asarray(series["confining_stress"], float)
    cr = np.asarray(series["cracks_tension"]) + np.asarray(series["cracks_shear"])
    ip = int(np.argmax(q))
    qp = float(q[ip])
    pre = slice(0, ip + 1)
    lo, hi = st.fit_window
    win = (q[pre] >= lo * qp) & (q[pre] <= hi * qp)
    E = fit_slope(ea[pre][win], q[pre][win])
    nu = -fit_slope(ea[pre][win], er[pre][win])
    nu_w = -fit_slope(ea[pre][win], erw[pre][win])
    dev = np.abs(s3m[pre] - st.sigma3)
    up = float(np.trapezoid(q[: ip + 1], ea[: ip + 1])) if ip > 0 else 0.0
    ci_target = max(1.0, st.ci_fraction * cr[ip])
    hit = np.flatnonzero(cr >= ci_target)
    ci = float(q[hit[0]]) if hit.size and hit[0] <= ip else math.nan
    return {"sigma1_MPa": (st.sigma3 + qp) / 1e6,
            "sigma3_MPa": st.sigma3 / 1e6,
            "deviator_MPa": qp / 1e6,
            "sigma1_measured_MPa": float(series["axial_stress"][ip]) / 1e6,
            "E_GPa": E / 1e9, "nu": nu, "nu_wall": nu_w,
            "peak_strain": float(ea[ip]), "u_pre_MJm3": up / 1e6,
            "crack_init_MPa": ci / 1e6, "fit_points": int(win.sum()),
            "sigma3_maxdev_MPa": float(dev.max()) / 1e6,
            "sigma3_maxdev_rel": float(dev.max()) / st.sigma3 if st.sigma3 > 0 else math.nan,
            "sigma3_mean_MPa": float(s3m[pre].mean()) / 1e6,
            "cracks_tension_peak": int(series["cracks_tension"][ip]),
            "cracks_shear_peak": int(series["cracks_shear"][ip])}


class TriaxialTest(LoadingTest):
    """The triaxial test of ``sp`` (built with ``boundary="vessel"``) as a
    ``driver.LabTest``: consolidation to sigma3 in ``prepare``, then axial loading with the
    lateral wall servo-controlled (``load_step``); its peak is the deviator's."""

    peak0 = -math.inf  # the deviator may start below zero

    def __init__(self, sp: Specimen, settings: TriaxialSettings):
        self.sp, self.settings, self.m = sp, settings, sp.model

    def prepare(self) -> None:
        st, sp, m = self.settings, self.sp, self.m
        cell = self.cell = _Cell(sp)
        wb, wt, wl = cell.wb, cell.wt, cell.wl
        m.set_wall_friction([wb, wt], st.platen_fric)
        m.set_wall_friction(wl, st.wall_fric)
        self.caps = install_end_caps(sp, st.end_cap, st.end_cap_factor)  # before consolidation
        m.set_damping(st.damping)
        self.dt = scaled_timestep(self, axial=True)
        self.bound = loading_bound(m, st, st.loading_at(sp.z_top - sp.z_bottom))
        t_c = time.perf_counter()
        self.con = consolidate(sp, st)
        lateral = self.con.pop("servo")
        self.consol_s = time.perf_counter() - t_c
        H0 = self.H0 = cell.height()
        self.Rc0 = cell.radius()
        self.A0 = math.pi * self.Rc0 ** 2
        v = self.v = st.loading_at(H0).velocity
        m.set_wall_velocity(wb, velocity=(0.0, 0.0, v))
        m.set_wall_velocity(wt, velocity=(0.0, 0.0, -v))
        self.loop = ServoLoop(m, [lateral], interval=st.servo_interval,
                              gain_update=st.gain_update)
        self.n_rec = max(1, int(round(st.record_strain * H0 / (2 * v * self.dt))))
        self.gauge = LateralGauge(sp, m.positions.copy(), float(m.wall_position(wb)[2]), H0,
                                  st.lateral_band, sp.radius0)
        self.series = {k: [] for k in TRIAXIAL_SERIES}
        self.e0 = m.energies()
        self.walls = (wb, wt, wl)
        self.e0_walls = sum(self.e0["work_walls_each"][w] for w in self.walls)
        self.step0 = m.step
        self.t_start = m.time
        self.record()
        self.stop_drop = st.stop_drop

    def load_step(self) -> None:
        self.loop.run(self.n_rec)

    def strain_now(self) -> float:
        return 2 * self.v * (self.m.time - self.t_start) / self.H0

    def record(self) -> tuple[float, float]:
        m, ser, cell, H0 = self.m, self.series, self.cell, self.H0
        e = m.energies()
        sb, stp = cell.platen_stresses(self.A0)
        s1 = 0.5 * (sb + stp)
        s3 = cell.lateral_stress()
        ea = (H0 - cell.height()) / H0
        er = self.gauge.strain(m.positions)
        erw = -(cell.radius() - self.Rc0) / self.Rc0
        record_common(self, e, self.e0, self.t_start)
        ser["axial_strain"].append(ea)
        ser["lateral_strain"].append(er)
        ser["lateral_strain_wall"].append(erw)
        ser["volumetric_strain"].append(ea + 2 * er)
        ser["axial_stress"].append(s1)
        ser["confining_stress"].append(s3)
        ser["deviator"].append(s1 - s3)
        ser["stress_top"].append(stp)
        ser["stress_bottom"].append(sb)
        ser["wall_radius"].append(cell.radius())
        ser["work_walls"].append(sum(e["work_walls_each"][w] for w in self.walls)
                                 - self.e0_walls)
        return s1 - s3, ea

    def post_peak(self, peak_strain: float) -> float:
        return min(self.settings.post_peak_strain, 0.5 * peak_strain)

    def shown(self, q: float, peak: float) -> tuple[float, float]:
        return self.series["axial_stress"][-1] / 1e6, (peak + self.settings.sigma3) / 1e6

    def analyse(self, end: Loaded) -> TriaxialResult:
        st, m, caps = self.settings, self.m, self.caps
        series = {k: np.asarray(vv) for k, vv in self.series.items()}
        summ = analyse(series, st)
        summ.update(end.summary(self, before_stop={"consol_s": self.consol_s}))
        summ.update({
            "platen_velocity": self.v, "strain_rate": 2 * self.v / self.H0,
            "records": end.records(self), "servo_interval": int(st.servo_interval),
            "servo_alpha": float(st.servo_alpha), **self.con,
            "end_cap_bonds": int(caps.size),
            "end_cap_broken": int(np.count_nonzero(np.isin(m.bond_states[caps], (1, 2)))),
        })
        ev = loading_cracks(m, self.step0, self.dt)  # relative to the start of axial loading
        return TriaxialResult(summary=summ, series=series, cracks=ev, settings=st)


def run_triaxial(sp: Specimen, settings: TriaxialSettings = TriaxialSettings(),
                 progress=None) -> TriaxialResult:
    """Consolidate specimen ``sp`` (built with ``boundary="vessel"``) to sigma3 and load
    it axially (its model is modified): :class:`TriaxialTest` on the lab-test driver
    (``driver.run_test``). ``progress(dict)`` is called after every record."""
    return run_test(TriaxialTest(sp, settings), progress)


def settings_dict(st: TriaxialSettings) -> dict:
    d = asdict(st)
    d["fit_window"] = list(d["fit_window"])
    d["lateral_band"] = list(d["lateral_band"])
    return d
