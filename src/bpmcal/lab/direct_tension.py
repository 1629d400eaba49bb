"""Direct-tension test of a bonded cylinder: the uniaxial tensile strength.

The direct-tension test of PFC's material-modeling package (Itasca uses it for sigma_t of
hard rock): the end regions of the specimen are gripped and pulled apart, and
sigma_t = peak force / cross-section.

Specimen: the UCS cylinder of the same geometry and genesis (``SpecimenSpec``; 20 x 40 mm
at the default scale 0.4), built free of its vessel (``build_specimen(boundary="free")``:
no wall touches it, its lateral face is free).

Grips (``grip_length``, default 0.2 of the height at each end): every ball whose centre
lies within ``grip_length x H`` of an end face belongs to that end's grip. A grip's balls
move together along the axis at the grip velocity (their axial velocity is fixed,
``Model.fix(FIX_VZ)``), and are otherwise free: lateral motion and rotation follow their
bonds, so the grips let the specimen contract laterally (a grip that also held the balls
laterally would restrain the Poisson contraction at its face and concentrate stress there;
a design choice, as PFC's package does not say how its grips act laterally).

Loading: the two grips move apart at ``grip_velocity`` each (default 0.01 m/s); local
damping 0.7. The balls of a grip carry the specimen's tension through their bonds to the
free part: the load on a grip is the axial resultant of the contact forces on its balls
(``Model.ball_forces``); the load P is the mean of the two grips' loads, and the axial
stress P / (pi R0^2) with R0 the specimen's radius at the start of the test. The axial
strain is the grips' separation change over the initial height H0.

Result: ``dtt_MPa`` = the peak axial stress. The test stops when the load falls below
``stop_drop`` (20 %) of the peak at least ``post_peak_strain`` axial strain after it, at
``max_strain``, or after ``max_steps``. E_t: the slope of stress vs axial strain over
``fit_window`` (20-50 %) of the peak (a tensile modulus, reported only).

Validity (``validity.dtt_validity``): the specimen must break in its gauge section, away
from the grips. The fracture's position is the median height of the cracks of the failure
(those formed from the record before the peak on); a fracture whose median lies within
``grip_clearance`` mean ball diameters (default 1) of a grip's face is *next to a grip*:
the run is recorded with ``dtt_valid`` false and that reason, and gives no sigma_t
(``dtt_MPa`` NaN; ``dtt_peak_MPa`` keeps the peak stress for inspection).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..dem.errors import InputError
from ..dem.slots import FIX_VZ
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
from .records import loading_cracks
from .specimen import Specimen
from .stepping import cycle, loading_bound
from .validity import dtt_validity

#: columns of the recorded time series
DTT_SERIES = ("step", "time", "axial_strain", "axial_stress", "stress_top", "stress_bottom",
              "cracks_tension", "cracks_shear", "kinetic", "strain_linear", "strain_bond",
              "slip", "damping", "dashpot", "released", "unbalanced")


@dataclass(frozen=True)
class DTTSettings:
    grip_velocity: float = 0.01  # m/s, each grip
    grip_length: float = 0.2  # fraction of the height held by each grip
    damping: float = 0.7
    stop_drop: float = 0.2  # stop when the load < stop_drop * peak after the peak ...
    post_peak_strain: float = 1e-4  # ... at least this axial strain past it
    max_strain: float = 0.02
    max_steps: int = 3_000_000
    record_strain: float = 2e-6  # axial strain between records
    fit_window: tuple = (0.2, 0.5)  # E_t over this range of the peak stress
    grip_clearance: float = 1.0  # mean ball diameters: a fracture closer to a grip is invalid
    density_scaling: float | None = None  # quantile: PFC's density scaling (lab.driver)

    def loading_at(self, length: float) -> Loading:
        """The loading of a cylinder of ``length`` [m] (the height between the grips' ends)."""
        return platen_loading("direct tension", self, length, field="grip_velocity",
                              loaders="grips", tension=True)

    def __post_init__(self):
        def positive(name, v):
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and v > 0
                                           and math.isfinite(v)):
                raise InputError(f"{name}={v!r}: expected a positive number")
        positive("grip_velocity", self.grip_velocity)
        if not (isinstance(self.grip_length, (int, float)) and 0.0 < self.grip_length < 0.45):
            raise InputError(f"grip_length={self.grip_length!r}: expected a fraction of the "
                             "height in (0, 0.45) at each end (the grips may not meet)")
        check_loading_settings(self)
        if not (self.grip_clearance >= 0 and math.isfinite(self.grip_clearance)):
            raise InputError(f"grip_clearance={self.grip_clearance!r}: expected a number of "
                             "mean ball diameters >= 0")


@dataclass
class DTTResult:
    summary: dict
    series: dict
    cracks: dict
    settings: DTTSettings
    grip_balls: tuple = ()  # (bottom, top) ball indices of the grips


def grips(sp: Specimen, grip_length: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Balls of the bottom and top grips (centres within ``grip_length`` x H of an end
    face) and the heights of the grips' inner faces."""
    m = sp.model
    z = m.positions[:, 2]
    H = sp.z_top - sp.z_bottom
    zb = sp.z_bottom + grip_length * H
    zt = sp.z_top - grip_length * H
    bot = np.flatnonzero(z <= zb)
    top = np.flatnonzero(z >= zt)
    if bot.size == 0 or top.size == 0:
        raise InputError(f"grip_length={grip_length:g}: a grip holds no ball in a specimen "
                         f"{H * 1e3:.3g} mm high; make the grips longer")
    return bot, top, zb, zt


def analyse(series: dict, settings: DTTSettings) -> dict:
    """sigma_t, the peak strain and the tensile modulus from a recorded series."""
    s = np.asarray(series["axial_stress"], float)
    e = np.asarray(series["axial_strain"], float)
    ip = int(np.argmax(s))
    peak = float(s[ip])
    lo, hi = settings.fit_window
    pre = slice(0, ip + 1)
    win = (s[pre] >= lo * peak) & (s[pre] <= hi * peak)
    Et = lsq_slope(e[pre][win], s[pre][win])
    return {"dtt_peak_MPa": peak / 1e6, "peak_strain": float(e[ip]),
            "E_t_GPa": Et / 1e9, "fit_points": int(win.sum()),
            "cracks_tension_peak": int(series["cracks_tension"][ip]),
            "cracks_shear_peak": int(series["cracks_shear"][ip]), "peak_record": ip}


class DirectTensionTest(LoadingTest):
    """The direct-tension test of the free cylinder ``sp`` as a ``driver.LabTest``: grips
    pulled apart, the load the mean of the grips' axial resultants."""

    def __init__(self, sp: Specimen, settings: DTTSettings):
        self.sp, self.settings, self.m = sp, settings, sp.model

    def prepare(self) -> None:
        st, sp, m = self.settings, self.sp, self.m
        if m.n_walls:
            raise InputError(f"the direct-tension specimen must be free (built with "
                             f"boundary='free'); it has {m.n_walls} wall(s)")
        H0 = self.H0 = sp.z_top - sp.z_bottom
        self.R0 = sp.radius0
        self.area = math.pi * self.R0 * self.R0
        loading = st.loading_at(H0)
        v = self.v = loading.velocity
        bot, top, self.zb, self.zt = grips(sp, st.grip_length)
        self.grips = (bot, top)
        m.fix(bot, FIX_VZ)
        m.fix(top, FIX_VZ)
        vb = np.zeros((bot.size, 3))
        vb[:, 2] = -v
        vt = np.zeros((top.size, 3))
        vt[:, 2] = v
        m.set_velocity(bot, vel=np.column_stack([m.velocities[bot, :2], vb[:, 2]]))
        m.set_velocity(top, vel=np.column_stack([m.velocities[top, :2], vt[:, 2]]))
        m.set_damping(st.damping)
        self.dt = scaled_timestep(self)
        self.bound = loading_bound(m, st, loading)
        self.n_rec = max(1, int(round(st.record_strain * H0 / (2 * v * self.dt))))
        self.series = {k: [] for k in DTT_SERIES}
        self.e0 = m.energies()
        self.step0 = m.step
        self.t_start = m.time
        self.record()
        self.stop_drop = st.stop_drop

    def load_step(self) -> None:
        cycle(self.m, self.n_rec)

    def strain_now(self) -> float:
        return 2.0 * self.v * (self.m.time - self.t_start) / self.H0

    def record(self) -> tuple[float, float]:
        m, ser, area, (bot, top) = self.m, self.series, self.area, self.grips
        e = m.energies()
        f, _ = m.ball_forces()
        ft = -float(f[top, 2].sum())  # the specimen pulls the top grip down
        fb = float(f[bot, 2].sum())
        eps = self.strain_now()
        record_common(self, e, self.e0, self.t_start)
        ser["axial_strain"].append(eps)
        ser["axial_stress"].append(0.5 * (ft + fb) / area)
        ser["stress_top"].append(ft / area)
        ser["stress_bottom"].append(fb / area)
        return ser["axial_stress"][-1], eps

    def analyse(self, end: Loaded) -> DTTResult:
        st, m, (bot, top), zb, zt = self.settings, self.m, self.grips, self.zb, self.zt
        series = {k: np.asarray(vv) for k, vv in self.series.items()}
        summ = analyse(series, st)
        ip = summ.pop("peak_record")
        ev = loading_cracks(m, self.step0, self.dt)
        dbar = 2.0 * float(m.radii.mean())
        val = dtt_validity(ev, series["step"], ip, grip_faces=(zb, zt),
                           clearance=st.grip_clearance * dbar,
                           ended=end.reason == "post_peak_drop")
        summ.update(val)
        summ["dtt_MPa"] = summ["dtt_peak_MPa"] if val["dtt_valid"] else math.nan
        summ.update(end.summary(self))
        summ.update({
            "grip_velocity": self.v, "strain_rate": 2 * self.v / self.H0,
            "records": end.records(self), "grip_balls_bottom": int(bot.size), "grip_balls_top": int(top.size),
            "gauge_length_mm": (zt - zb) * 1e3, "diameter_mm": 2e3 * self.R0,
            "height_mm": self.H0 * 1e3, "mean_ball_diameter_mm": dbar * 1e3,
            "balls_across": 2.0 * self.R0 / dbar, "peak_step": int(series["step"][ip]),
        })
        return DTTResult(summary=summ, series=series, cracks=ev, settings=st,
                         grip_balls=(bot, top))


def run_dtt(sp: Specimen, settings: DTTSettings = DTTSettings(), progress=None) -> DTTResult:
    """Run the test on the free cylinder ``sp`` (its model is modified: grips are fixed):
    :class:`DirectTensionTest` on the lab-test driver (``driver.run_test``).
    ``progress(dict)`` is called after every record with the latest values."""
    return run_test(DirectTensionTest(sp, settings), progress)


def settings_dict(st: DTTSettings) -> dict:
    d = asdict(st)
    d["fit_window"] = list(d["fit_window"])
    return d
