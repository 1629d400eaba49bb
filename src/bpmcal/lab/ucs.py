"""Uniaxial compression test of a bonded specimen (quasi-static, PFC practice).

Loading: two frictionless (by default) planar platens on the specimen's end faces approach
each other, each at ``platen_velocity`` (default 0.05 m/s), or at ``strain_rate x H0 / 2``
when a strain rate is given; local damping 0.7. How quasi-static a test is depends on
the platen speed, not on the strain rate: the dynamic overstress is ~ rho c v and the
number of wave transits before the peak is ~ eps_p c / (2 v), both independent of the
specimen size. Halving 0.05 m/s changes sigma_c by about a per cent and E far less (measured at scale
0.4: docs/measurements/2026-11-22-loading-rate-and-size.md), so a small specimen can be
loaded at a higher strain rate than a large one.

Approach (``approach_velocity`` > the platen velocity; by default 0.1 m/s, twice it): the
platens close at ``approach_velocity`` until the first bond breaks (the specimen is
elastic up to there, and E and nu do not depend on the rate), then slow linearly to the
platen velocity over ``approach_ramp`` times the time a compression wave takes to cross
the specimen (its secant modulus and bulk density at the switch: :func:`transit_steps`),
so that the slowing does not ring through the fit window. The axial strain is the sum of
the stretches loaded at each speed (the platens' approach, exactly). At 0.1 m/s (twice the
default platen velocity) and 5 transits (the defaults) it saved a fifth of the steps and
left sigma_c, E and nu as they were on the default study's 150 design samples
(docs/measurements/2026-12-02-loading-protocol.md).

Measurements, recorded every ``record_strain`` of axial strain (compression positive):

- axial stress sigma = mean of the two platen forces / initial area pi (D/2)^2;
- axial strain eps_a = platen approach / initial height H0;
- lateral strain eps_r = -mean radial displacement / (D/2) of the *surface balls* (those
  that touched the lateral vessel wall at the end of genesis) whose centres lie within
  the central band ``lateral_band`` (10-90 %) of the height (compression positive, so
  expansion is negative); volumetric strain eps_v = eps_a + 2 eps_r;
- cracks (broken bonds) by mode, the energy terms of the engine;
- a central axial gauge, ``axial_strain_central``: the change of the distance between the
  mean heights of two slabs of balls (centres within 0.05 H of 0.25 H and 0.75 H) over
  their initial distance. It sees the bulk only, without the compliance of the platen
  contacts and of the end layers (the balls packed against a platen have fewer bonds
  than the bulk; docs/measurements/2026-11-26-end-layers.md).

End caps (``end_cap``, off by default; 1 mean ball diameter caps the first layer of balls;
``bpmcal ucs --end-cap``, config ``compression.end_cap``):
the balls packed against a flat platen form a layer with fewer bonds (a ball touching a
platen has ~27 % fewer than a bulk ball, the balls within half a mean ball diameter d of
it ~37 % fewer; docs/measurements/2026-11-26-end-layers.md), and with frictionless platens that
layer, not the bulk, decides sigma_c: 13-41 % of the cracks before the peak lie within
one d of a platen (6-11 % of the bonds), and strengthening only the bonds there raised
sigma_c by 9-15 % (paper's A1 card, 6 packings, scale 0.4; 5.7 % at full size, one
packing; 1-12 % on 7 design samples at 0.4) while E moved by < 1.5 % and nu by < 0.004;
failure then starts in the bulk.
With ``end_cap = h`` (mean ball diameters), every bond whose contact point lies within h
of an end face gets ``end_cap_factor`` (1000) x its tensile strength and cohesion when the
test starts (``specimen.apply_end_caps``; PFC: per-contact ``pb_ten``/``pb_coh`` assigned
by range); stiffnesses are unchanged, so the caps do not alter E by construction. The
summary reports ``end_cap_bonds`` and ``end_cap_broken`` (0 when the caps hold).

Results: sigma_c = peak stress; E = least-squares slope of sigma vs eps_a and
nu = -slope of eps_r vs eps_a over the pre-peak records with 0.4 <= sigma/sigma_c <= 0.6
(``fit_window``; the laboratory's practice: the target nu is read there), and beside it
``nu_pre_dilation``, nu before crack dilation: where the tangent nu of a 0.1 sigma_c bin
rises more than 25 % above its value over 0.1-0.2 sigma_c inside the window (a flat-jointed
card with slits dilates from about 0.3 sigma_c), it is fitted over the window of the same
proportions that ends there (``nu_window_lo``/``_hi``; ``dilation_onset``), else it is nu;
strain at peak;
pre-peak energy density U_p = integral of sigma d eps_a from 0 to the peak (trapezoids,
the paper's Table 6); ``E_central_GPa``, the slope of sigma vs the central gauge's strain
over E's window (the bulk modulus of the specimen's middle half, not what the paper calls
E); crack-initiation stress = sigma when the crack count first reaches ``ci_fraction``
(1 %) of the count at peak (at least one).
The test stops when sigma falls below ``stop_drop`` (70 %) of the peak after the peak, at
``max_strain``, or after ``max_steps``; ``stop_reason`` says which.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..dem.errors import InputError
from ..exact_math import lsq_slope
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
from .specimen import Specimen, apply_end_caps
from .stepping import cycle, loading_bound

#: columns of the recorded time series
SERIES = ("step", "time", "axial_strain", "lateral_strain", "volumetric_strain",
          "axial_stress", "stress_top", "stress_bottom", "cracks_tension", "cracks_shear",
          "kinetic", "strain_linear", "strain_bond", "slip", "damping", "dashpot",
          "released", "work_walls", "unbalanced", "axial_strain_central")
#: strength factor of the bonds of the end caps (``UCSSettings.end_cap``): unbreakable in
#: practice (no capped bond broke in any measured run; docs/measurements/2026-11-26-end-layers.md)
END_CAP_FACTOR = 1000.0
#: the end caps' height by default [mean ball diameters]: none, PFC's standard practice and
#: how the study's results were measured (1 caps the first layer of balls packed against a
#: platen; 2 diameters gave the same sigma_c within 0.7 %; docs/measurements/2026-11-26-end-layers.md)
END_CAP_HEIGHT = 0.0


def check_end_cap(height, factor):
    """The end-cap settings of an axial test (``UCSSettings``, ``TriaxialSettings``)."""
    if isinstance(height, bool) or not (isinstance(height, (int, float))
                                        and 0.0 <= height <= 10.0):  # NaN fails too
        raise InputError(f"end_cap={height!r}: expected a height in [0, 10] mean ball "
                         "diameters (0: no end caps)")
    if isinstance(factor, bool) or not (isinstance(factor, (int, float))
                                        and 1.0 <= factor <= 1e6):
        raise InputError(f"end_cap_factor={factor!r}: expected a strength factor in "
                         "[1, 1e6]")


def install_end_caps(sp: Specimen, height: float, factor: float) -> np.ndarray:
    """The end caps of an axial test on ``sp`` (``specimen.apply_end_caps``); the indices
    of the capped bonds (none when ``height`` is 0). The caps may not meet: each must be
    less than half the specimen's height."""
    if height <= 0:
        return np.zeros(0, np.int64)
    dbar = 2.0 * float(sp.model.radii.mean())
    if 2.0 * height * dbar >= sp.z_top - sp.z_bottom:
        raise InputError(f"end_cap={height:g} mean ball diameters ({height * dbar * 1e3:.3g} mm)"
                         f": the two caps would meet in a specimen "
                         f"{(sp.z_top - sp.z_bottom) * 1e3:.3g} mm high")
    return apply_end_caps(sp, height, factor)["end_cap_index"]


#: the central axial gauge: two slabs of balls at these fractions of the height (centres
#: within +-0.05 H), their mean axial displacements give ``axial_strain_central``
CENTRAL_GAUGE = (0.25, 0.75)


@dataclass(frozen=True)
class UCSSettings:
    platen_velocity: float = 0.05  # m/s, each platen (used when strain_rate is None)
    strain_rate: float | None = None  # 1/s; if given, each platen moves at rate * H0 / 2
    damping: float = 0.7
    platen_fric: float = 0.0
    stop_drop: float = 0.7  # stop when stress < stop_drop * peak after the peak
    max_strain: float = 0.03
    max_steps: int = 3_000_000
    record_strain: float = 1e-5  # axial strain between records
    fit_window: tuple = (0.4, 0.6)
    ci_fraction: float = 0.01
    lateral_band: tuple = (0.1, 0.9)
    post_peak_strain: float = 0.002  # also require this much strain past the peak to stop
    end_cap: float = END_CAP_HEIGHT  # end caps [mean ball diameters], 0: none (module docstring)
    end_cap_factor: float = END_CAP_FACTOR  # strength factor of the end caps' bonds
    approach_velocity: float = 0.1  # m/s, each platen until the first crack (0: off)
    approach_ramp: float = 5.0  # wave transits over which the platens slow from it to v
    density_scaling: float | None = None  # quantile: PFC's density scaling (lab.driver)

    def loading_at(self, length: float) -> Loading:
        """The loading of a cylinder of ``length`` [m] (the loaded height)."""
        return platen_loading("UCS", self, length)

    def __post_init__(self):
        check_end_cap(self.end_cap, self.end_cap_factor)
        if self.strain_rate is not None and not (self.strain_rate > 0
                                                 and math.isfinite(self.strain_rate)):
            raise InputError(f"strain_rate={self.strain_rate!r}: expected a positive rate in 1/s")
        if not (self.platen_velocity > 0 and math.isfinite(self.platen_velocity)):
            raise InputError(f"platen_velocity={self.platen_velocity!r}: expected a positive "
                             "speed in m/s")
        if not (0.0 <= self.platen_fric <= 10.0):  # NaN fails too
            raise InputError(f"platen_fric={self.platen_fric!r}: expected a friction "
                             "coefficient in [0, 10]")
        check_loading_settings(self)
        check_approach(self.approach_velocity, self.approach_ramp)


def check_approach(v, ramp) -> None:
    """The approach velocity and ramp of the UCS test (``UCSSettings``)."""
    if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v)
                                   and 0.0 <= v <= 100.0):
        raise InputError(f"approach_velocity={v!r}: expected a speed in [0, 100] m/s (0: no "
                         "fast approach)")
    if isinstance(ramp, bool) or not (isinstance(ramp, (int, float)) and math.isfinite(ramp)
                                      and 0.0 <= ramp <= 1000.0):
        raise InputError(f"approach_ramp={ramp!r}: expected a number of wave transits in "
                         "[0, 1000] (0: the platens slow at once)")


@dataclass
class UCSResult:
    summary: dict
    series: dict  # column -> np.ndarray
    cracks: dict  # event arrays (Model.breaks())
    settings: UCSSettings

    def series_frame(self):
        import pandas as pd
        return pd.DataFrame(self.series)


def fit_slope(x, y):
    """Least-squares slope of y on x (NaN if fewer than 3 points), computed without BLAS
    so that E and nu do not depend on the host (bpmcal.exact_math.lsq_slope)."""
    return lsq_slope(np.asarray(x, float), np.asarray(y, float))


#: the Poisson's ratio's dilation check: the tangent nu over bins of this width (fraction of
#: sigma_c) from ``NU_REF[0]`` up; the first bin (``NU_REF``) is the elastic reference
NU_BIN = 0.1
NU_REF = (0.1, 0.2)
#: a bin whose tangent nu exceeds the reference by more than this fraction has dilated
NU_DILATION = 0.25


def dilation_onset(sig, ea, er, peak: float, hi: float) -> float:
    """Where crack dilation starts inside the pre-peak records (``sig``, ``ea``, ``er``),
    as a fraction of ``peak``: the lower edge of the first bin of width ``NU_BIN`` (from
    ``NU_REF[0]`` up to ``hi``) whose tangent nu (-d eps_r / d eps_a) exceeds the elastic
    reference, the tangent nu over ``NU_REF``, by more than ``NU_DILATION``; ``hi`` when
    none does (or the reference cannot be fitted). The laboratory's crack-initiation
    stress is read the same way, where the lateral strain leaves its linear trend."""
    def tangent(a, b):
        w = (sig >= a * peak) & (sig <= b * peak)
        return -fit_slope(ea[w], er[w])

    ref = tangent(*NU_REF)
    if not (math.isfinite(ref) and ref > 0):
        return hi
    k = 1
    while NU_REF[0] + (k + 1) * NU_BIN <= hi + 1e-12:
        a = NU_REF[0] + k * NU_BIN
        t = tangent(a, a + NU_BIN)
        if math.isfinite(t) and t > ref * (1.0 + NU_DILATION):
            return a
        k += 1
    return hi


def analyse(series: dict, settings: UCSSettings) -> dict:
    """sigma_c, E, nu, peak strain, U_p and the crack-initiation stress from a series.
    nu is fitted over the E window; ``nu_pre_dilation`` too unless the specimen dilates
    inside it (:func:`dilation_onset` below its top): then over the window of the same
    proportions that ends where dilation starts (``nu_window_lo``/``_hi`` say which, in
    fractions of sigma_c)."""
    s = np.asarray(series["axial_stress"])
    ea = np.asarray(series["axial_strain"])
    er = np.asarray(series["lateral_strain"])
    cr = np.asarray(series["cracks_tension"]) + np.asarray(series["cracks_shear"])
    ip = int(np.argmax(s))
    peak = float(s[ip])
    pre = slice(0, ip + 1)
    lo, hi = settings.fit_window
    win = (s[pre] >= lo * peak) & (s[pre] <= hi * peak)
    E = fit_slope(ea[pre][win], s[pre][win])
    ec = series.get("axial_strain_central")
    E_c = fit_slope(np.asarray(ec)[pre][win], s[pre][win]) if ec is not None else math.nan
    onset = dilation_onset(s[pre], ea[pre], er[pre], peak, hi)
    if onset < hi:  # nu before crack dilation (module docstring)
        nlo, nhi = lo * onset / hi, onset
        nwin = (s[pre] >= nlo * peak) & (s[pre] <= nhi * peak)
    else:
        nlo, nhi, nwin = lo, hi, win
    nu = -fit_slope(ea[pre][win], er[pre][win])
    nu_pre = -fit_slope(ea[pre][nwin], er[pre][nwin])
    up = float(np.trapezoid(s[: ip + 1], ea[: ip + 1])) if ip > 0 else 0.0
    ci_target = max(1.0, settings.ci_fraction * cr[ip])
    hit = np.flatnonzero(cr >= ci_target)
    ci = float(s[hit[0]]) if hit.size and hit[0] <= ip else math.nan
    return {"ucs_MPa": peak / 1e6, "E_GPa": E / 1e9, "E_central_GPa": E_c / 1e9, "nu": nu,
            "peak_strain": float(ea[ip]), "u_pre_MJm3": up / 1e6,
            "crack_init_MPa": ci / 1e6, "fit_points": int(win.sum()),
            "nu_pre_dilation": nu_pre, "nu_window_lo": float(nlo), "nu_window_hi": float(nhi),
            "cracks_tension_peak": int(series["cracks_tension"][ip]),
            "cracks_shear_peak": int(series["cracks_shear"][ip])}


class _Axial:
    """The two platens of an axial test, closing at ``speed`` each: the axial strain (the
    platens' approach over the height ``H0``, summed over the stretches loaded at one
    speed), the steps between records, and the switch from an approach speed to the
    loading's, ramped down over ``ramp`` steps (0: at once)."""

    def __init__(self, m, platens, H0: float, speed: float):
        self.m, self.platens, self.H0 = m, platens, H0
        self.approach_strain = 0.0
        self.approaching = False  # at an approach speed until the first crack
        self.ramp = None  # (from speed, to speed, steps, steps done)
        self._set(speed)

    def _set(self, speed: float) -> None:
        wb, wt = self.platens
        self.speed = speed
        self.m.set_wall_velocity(wb, velocity=(0.0, 0.0, speed))
        self.m.set_wall_velocity(wt, velocity=(0.0, 0.0, -speed))

    def records_every(self, record_strain: float, dt: float) -> None:
        self.n_rec = max(1, int(round(record_strain * self.H0 / (2 * self.speed * dt))))

    def start(self) -> None:
        """The loading starts now (strain 0)."""
        self.t_from, self.e_from = self.m.time, 0.0

    def strain(self) -> float:
        return self.e_from + 2 * self.speed * (self.m.time - self.t_from) / self.H0

    def _speed_now(self, speed: float) -> None:
        self.e_from, self.t_from = self.strain(), self.m.time
        self._set(speed)

    def switch(self, speed: float, record_strain: float, dt: float, ramp: int = 0) -> None:
        """From now on toward ``speed``: at once, or ramped linearly over ``ramp`` steps."""
        self.approach_strain = self.strain()
        self.approaching = False
        if ramp > 0:
            self.ramp = (self.speed, speed, int(ramp), 0)
        else:
            self._speed_now(speed)
        self.target = speed
        self.records_every_target = (record_strain, dt)
        if ramp <= 0:
            self.records_every(record_strain, dt)

    def advance(self, cycle) -> None:
        """One record interval: ``cycle(n)`` steps (during a ramp in pieces of
        :data:`RAMP_PIECE` steps, each at its own speed)."""
        if self.ramp is None:
            cycle(self.n_rec)
            return
        left = self.n_rec
        v0, v1, n, k = self.ramp
        while left > 0 and k < n:
            piece = min(RAMP_PIECE, left, n - k)
            self._speed_now(v0 + (v1 - v0) * (k + 0.5 * piece) / n)
            cycle(piece)
            left -= piece
            k += piece
        self.ramp = (v0, v1, n, k)
        if k >= n:
            self.ramp = None
            self._speed_now(v1)
            self.records_every(*self.records_every_target)
        if left > 0:
            cycle(left)


def transit_steps(m, stress: float, strain: float, length: float, area: float) -> float:
    """Steps a compression wave takes to cross a specimen of ``length`` and cross-section
    ``area`` at its secant modulus now (``stress`` / ``strain``) and bulk density (its
    balls' mass over its volume)."""
    rho = float(m.masses.sum()) / (area * length)
    c = math.sqrt(max(stress, 0.0) / max(strain, 1e-30) / rho)
    return length / (c * m.dt) if c > 0 else 0.0


#: steps at one speed during the ramp from the approach speed to the loading's
RAMP_PIECE = 8


class UCSTest(LoadingTest):
    """The UCS test of specimen ``sp`` as a ``driver.LabTest``: end caps, the platens'
    approach and its ramp to the loading speed (``on_record``: the approach speed's hook),
    the lateral and central gauges."""

    def __init__(self, sp: Specimen, settings: UCSSettings):
        self.sp, self.settings, self.m = sp, settings, sp.model

    def prepare(self) -> None:
        st, sp, m = self.settings, self.sp, self.m
        H0 = self.H0 = sp.z_top - sp.z_bottom
        R0 = sp.radius0
        self.area = math.pi * R0 * R0
        loading = st.loading_at(H0)
        v = self.v = loading.velocity
        self.caps = install_end_caps(sp, st.end_cap, st.end_cap_factor)  # before anything moves
        wb, wt = self.walls = sp.platens
        approach = st.approach_velocity > v  # fast until the first crack, then at v
        ax = self.ax = _Axial(m, (wb, wt), H0, st.approach_velocity if approach else v)
        ax.approaching = approach
        m.set_wall_friction([wb, wt], st.platen_fric)
        m.set_damping(st.damping)
        self.dt = scaled_timestep(self, axial=True)
        self.bound = loading_bound(m, st, loading)
        ax.records_every(st.record_strain, self.dt)
        pos0 = m.positions.copy()
        self.gauge = LateralGauge(sp, pos0, sp.z_bottom, H0, st.lateral_band, R0)
        self.slabs = [np.flatnonzero(np.abs(pos0[:, 2] - (sp.z_bottom + f * H0)) <= 0.05 * H0)
                      for f in CENTRAL_GAUGE]
        self.zc0 = [pos0[g, 2].mean() for g in self.slabs]
        self.series = {k: [] for k in SERIES}
        self.e0 = m.energies()
        self.step0 = m.step
        self.cracks0 = sum(m.crack_counts())  # of the genesis, if any
        ax.start()
        self.t_start = m.time
        self.e0_walls = self.e0["work_walls_each"][wb] + self.e0["work_walls_each"][wt]
        self.record()
        self.stop_drop = st.stop_drop

    def load_step(self) -> None:
        self.ax.advance(lambda n: cycle(self.m, n))

    def record(self) -> tuple[float, float]:
        m, ser, (wb, wt), area = self.m, self.series, self.walls, self.area
        slabs, zc0 = self.slabs, self.zc0
        e = m.energies()
        ft = abs(m.wall_force(wt)[2])
        fb = abs(m.wall_force(wb)[2])
        ea = self.ax.strain()
        er = self.gauge.strain(m.positions)
        record_common(self, e, self.e0, self.t_start)
        ser["axial_strain"].append(ea)
        ser["lateral_strain"].append(er)
        ser["axial_strain_central"].append(
            -((m.positions[slabs[1], 2].mean() - zc0[1])
              - (m.positions[slabs[0], 2].mean() - zc0[0]))
            / (zc0[1] - zc0[0]))
        ser["volumetric_strain"].append(ea + 2 * er)
        ser["axial_stress"].append(0.5 * (ft + fb) / area)
        ser["stress_top"].append(ft / area)
        ser["stress_bottom"].append(fb / area)
        ser["work_walls"].append(e["work_walls_each"][wb] + e["work_walls_each"][wt]
                                 - self.e0_walls)
        return ser["axial_stress"][-1], ea

    def on_record(self, stress: float, strain: float) -> None:
        ser, ax, st = self.series, self.ax, self.settings
        if ax.approaching and ser["cracks_tension"][-1] + ser["cracks_shear"][-1] > self.cracks0:
            ramp = st.approach_ramp * transit_steps(self.m, stress, strain, self.H0, self.area)
            ax.switch(self.v, st.record_strain, self.dt, int(math.ceil(ramp)))  # the first crack

    def strain_now(self) -> float:
        return self.ax.strain()

    def post_peak(self, peak_strain: float) -> float:
        return min(self.settings.post_peak_strain, 0.5 * peak_strain)

    def analyse(self, end: Loaded) -> UCSResult:
        st, m, caps = self.settings, self.m, self.caps
        series = {k: np.asarray(vv) for k, vv in self.series.items()}
        summ = analyse(series, st)
        summ.update(end.summary(self))
        summ.update({
            "platen_velocity": self.v, "strain_rate": 2 * self.v / self.H0,
            "approach_velocity": st.approach_velocity, "approach_strain": self.ax.approach_strain,
            "records": end.records(self), "end_cap_bonds": int(caps.size),
            "end_cap_broken": int(np.count_nonzero(np.isin(m.bond_states[caps], (1, 2)))),
        })
        ev = loading_cracks(m, self.step0, self.dt)  # relative to the start of loading
        return UCSResult(summary=summ, series=series, cracks=ev, settings=st)


def run_ucs(sp: Specimen, settings: UCSSettings = UCSSettings(), progress=None) -> UCSResult:
    """Run the test on specimen ``sp`` (its model is modified): :class:`UCSTest` on the
    lab-test driver (``driver.run_test``). ``progress(dict)`` is called after every record
    with the latest values."""
    return run_test(UCSTest(sp, settings), progress)


def settings_dict(st: UCSSettings) -> dict:
    d = asdict(st)
    d["fit_window"] = list(d["fit_window"])
    d["lateral_band"] = list(d["lateral_band"])
    return d
