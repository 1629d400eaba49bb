"""One driver for the quasi-static lab tests: UCS, Brazilian, direct tension, triaxial.

A test is a :class:`LabTest`: it **prepares** its specimen (loaders, caps, damping, the
time step, seating or consolidation, the step bound of its loading, the first record),
**loads** one record interval at a time (``load_step``), **records** one row of its
series (returning the loading's stress and strain), says whether a load drop **stops**
it (``stop``: the Brazilian test's split check; an axial test stops at any drop) and
**analyses** the finished loading into its result. :func:`run_test` runs one: it owns
what every test did the same way before, each in its own loop:

- the cycling: ``load_step`` runs its steps through ``stepping.cycle`` (Python runs
  the chunks, numba the steps), and the driver checks ``settings.max_steps`` before
  each interval;
- the peak (:class:`PeakTracker`): the peak stress, its strain and record; a drop below
  ``stop_drop`` x the peak at least ``post_peak(peak strain)`` past it ends the test if
  ``stop`` says so, else it is a contact event and the peak restarts; ``max_strain``
  ends it too;
- the progress line and its heartbeat (``stepping.LoadingProgress``, ``heartbeat``):
  the strain, the stress and peak as ``shown``, the cracks, steps, ETA;
- the common record columns (:func:`record_common`: step, time, crack counts, the
  engine's energy terms, the unbalanced-force ratio) and the common summary
  (:meth:`Loaded.summary`: final crack counts, steps, wall time, stop reason, time step;
  :meth:`Loaded.records`);
- the time step (:func:`scaled_timestep`), with PFC's density scaling where the
  settings ask for it (``density_scaling``; by default the axial tests of parallel-bonded
  cards: :data:`AXIAL_DENSITY_SCALING`);
- the checks of the settings they share (:func:`check_loading_settings`).

Hooks with defaults (:class:`LoadingTest`): ``on_record(stress, strain)`` after every
loading record (the Brazilian test ends its fast approach there: the approach speed),
``post_peak`` (the strain past the peak before a drop counts), ``shown`` (MPa for the
progress line) and ``peak0`` (the peak before the first record: -inf for the triaxial
deviator, which may start below zero). ``strain_now`` (the heartbeat's strain between two
records) is each test's own: no default.

The drop-hammer impact test (``lab.impact``) is not driven here: it is dynamic, not
quasi-static. It has no peak to track and no strain to bound it: it ends on time (the
hammer's rebound plus a settling time, the hammer reaching the anvil, or the duration),
its records are fixed time intervals rather than strain increments, and its measures
are energies integrated over the whole run. It shares the set-up of every test
(``runner.make_specimen``) and the interruptible cycling (``stepping.cycle``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Protocol

from ..dem.errors import InputError
from .records import append_cracks, append_energies
from .stepping import LoadingProgress, heartbeat


def check_loading_settings(st) -> None:
    """The checks of the settings every driven test has (its ``*Settings.__post_init__``
    calls this beside its own): ``damping``, ``stop_drop``, ``max_strain``, ``max_steps``,
    ``record_strain``, ``post_peak_strain`` and, where there is one, ``fit_window``. An
    InputError naming the first bad value and what was expected."""
    def number(v) -> bool:  # a real number (not a bool), finite; NaN fails
        return (isinstance(v, (int, float)) or hasattr(v, "__float__")) and not isinstance(
            v, bool) and math.isfinite(float(v))

    checks = (
        ("damping", lambda v: 0.0 <= v < 1.0, "a local damping in [0, 1)"),
        ("stop_drop", lambda v: 0.0 < v < 1.0, "a fraction in (0, 1)"),
        ("max_strain", lambda v: 0.0 < v <= 0.5, "a strain in (0, 0.5]"),
        ("max_steps", lambda v: v > 0 and float(v).is_integer(), "a positive integer"),
        ("record_strain", lambda v: v > 0, "a strain > 0"),
        ("post_peak_strain", lambda v: v >= 0, "a strain >= 0"),
    )
    for name, ok, expected in checks:
        v = getattr(st, name)
        if not (number(v) and ok(v)):
            raise InputError(f"{name}={v!r}: expected {expected}")
    q = getattr(st, "density_scaling", None)
    if q is not None and not (number(q) and 0.0 <= q <= 1.0):
        raise InputError(f"density_scaling={q!r}: expected a quantile in [0, 1] (the balls' "
                         "critical timestep every ball's mass is scaled to reach), or None: "
                         "no scaling")
    window = getattr(st, "fit_window", None)
    if window is not None:
        lo, hi = window
        if not (0.0 <= lo < hi <= 1.0):
            raise InputError(f"fit_window={window!r}: expected 0 <= lo < hi <= 1")


#: the density-scaling quantile of the axial tests (UCS, triaxial) whose settings give
#: none, by contact model: the median ball's critical timestep for parallel bonds (paired
#: with the true masses on the default study's 150 design samples: σc, E, ν within 0.1 %
#: in median and bias for 0.73 of the steps, docs/measurements/2026-12-02j-density-scaling.md),
#: the true masses for flat joints (their σc, E, ν moved by several per cent per sample)
AXIAL_DENSITY_SCALING = {"linearpbond": 0.5, "flatjoint": None}


def density_quantile(settings, axial: bool, contact_model: str) -> float | None:
    """The density-scaling quantile a test runs with: its settings' ``density_scaling``,
    or, when that is None, :data:`AXIAL_DENSITY_SCALING` of the card's ``contact_model``
    for an ``axial`` test (UCS, triaxial) and the true masses (None) for the tensile
    tests."""
    q = getattr(settings, "density_scaling", None)
    if q is None and axial:
        q = AXIAL_DENSITY_SCALING.get(contact_model)
    return q


def scaled_timestep(test, axial: bool = False) -> float:
    """The time step of a prepared test (its model ``test.m``): PFC's 0.8 x the critical
    timestep, after scaling the balls' inertial masses to the quantile
    :func:`density_quantile` gives of their own critical timesteps (``Model.scale_density``:
    quasi-static loading only; None or 0: the true masses). Keeps what the scaling did on
    the test (``density``: ``dt_gain``, ``mass_added``; None without scaling) for its
    summary."""
    m = test.m
    q = density_quantile(test.settings, axial, m.material.contact_model)
    test.density = m.scale_density(q) if q else None
    m.set_timestep(None)
    return m.dt


class PeakTracker:
    """The peak of a loading: the stress at which the specimen fails, not the top of a
    seating or contact-crushing event.

    ``add(stress, strain)`` takes every loading record and returns True when the stress
    has dropped below ``stop_drop`` x the peak at least ``post_peak_strain`` after it (a
    strain, or a function of the peak's strain). The caller then says
    whether that drop is the failure (``judge``: the Brazilian test's split check; an
    axial test's drop always is). A drop that is not is a contact event: it is recorded
    in ``events`` (its peak, strain and the stress it dropped to), and the peak starts
    again from the current record. ``peak_record`` is the index of the record of the peak
    (the first record, before loading, is record 0); ``peak0`` the peak before any."""

    def __init__(self, stop_drop: float, post_peak_strain, peak0: float = 0.0):
        self.stop_drop = float(stop_drop)
        p = post_peak_strain
        self._post = p if callable(p) else (lambda _, p=float(p): p)
        self.peak, self.peak_strain, self.peak_record = peak0, 0.0, 0
        self.events: list[dict] = []
        self._n = 0  # records seen (the first, at zero load, is record 0)
        self._last = (0.0, 0.0)

    @property
    def post_peak_strain(self) -> float:
        """The strain past the peak a drop needs now."""
        return self._post(self.peak_strain)

    def add(self, load: float, strain: float) -> bool:
        self._n += 1
        k = self._n
        self._last = (float(load), float(strain))
        if load > self.peak:
            self.peak, self.peak_strain, self.peak_record = float(load), float(strain), k
        return (self.peak > 0 and load < self.stop_drop * self.peak
                and strain - self.peak_strain >= self._post(self.peak_strain))

    def judge(self, split: bool) -> bool:
        """After a drop: True (stop) if it was the failure, else record a contact event
        and restart the peak from the current record."""
        if split:
            return True
        load, strain = self._last
        self.events.append({"record": self.peak_record, "load_N": self.peak,
                            "strain": self.peak_strain, "drop_to_N": load})
        self.peak, self.peak_strain, self.peak_record = load, strain, self._n
        return False


class LabTest(Protocol):
    """What :func:`run_test` drives. Attributes set by ``prepare``: ``m`` (the model),
    ``settings`` (``max_steps``, ``max_strain``), ``series`` (column -> list), ``step0``
    (the model's step when loading starts), ``dt`` (its time step), ``bound`` (the
    loading's step estimate, ``stepping.loading_bound``), ``stop_drop`` (the drop that
    may end it). The hooks (``on_record``, ``post_peak``, ``shown``, ``peak0``) have
    defaults in :class:`LoadingTest`; ``strain_now`` has none (each test's own strain)."""

    def prepare(self) -> None: ...

    def load_step(self) -> None: ...

    def record(self) -> tuple[float, float]: ...

    def stop(self, tracker: PeakTracker) -> bool: ...

    def analyse(self, end: Loaded): ...

    def strain_now(self) -> float: ...  # the strain now, between two records (the heartbeat's)


class LoadingTest:
    """The hooks' defaults of a :class:`LabTest` (module docstring)."""

    peak0 = 0.0

    def stop(self, tracker: PeakTracker) -> bool:
        return True

    def on_record(self, stress: float, strain: float) -> None:
        pass

    def post_peak(self, peak_strain: float) -> float:
        return self.settings.post_peak_strain

    def shown(self, stress: float, peak: float) -> tuple[float, float]:
        return stress / 1e6, peak / 1e6



@dataclass
class Loaded:
    """A finished loading: why it stopped (``post_peak_drop``, ``max_strain`` or
    ``max_steps``), its peak tracker, its wall time [s]."""

    reason: str
    tracker: PeakTracker
    wall_s: float

    def summary(self, test, before_stop: dict | None = None) -> dict:
        """The summary entries every test reports: its final crack counts, steps, wall
        time, (``before_stop``: a test's own entries here, the triaxial consolidation's
        time), stop reason and time step. The number of records (:meth:`records`) each
        test places itself: the order of a summary's keys is the order of the columns of
        the tables built from it (a closed loop's seed table), kept as it was."""
        ser, m = test.series, test.m
        d = getattr(test, "density", None)  # with density scaling: its timestep gain
        return {"cracks_tension": int(ser["cracks_tension"][-1]),
                "cracks_shear": int(ser["cracks_shear"][-1]),
                "steps": int(m.step - test.step0), "wall_s": self.wall_s,
                **(before_stop or {}), "stop_reason": self.reason, "dt": test.dt,
                **({} if d is None else {"density_dt_gain": d["dt_gain"],
                                         "density_mass_added": d["mass_added"]})}

    @staticmethod
    def records(test) -> int:
        """The number of records of the test's series (the first, before loading, too)."""
        return len(test.series["step"])


def record_common(test, e: dict, e0: dict, t_start: float) -> None:
    """Append the columns every quasi-static test records: ``step`` and ``time`` since the
    start of loading, the crack counts, the engine's energy terms since ``e0`` (``e``:
    ``Model.energies()`` now) and the unbalanced-force ratio."""
    ser, m = test.series, test.m
    ser["step"].append(m.step - test.step0)
    ser["time"].append(m.time - t_start)
    append_cracks(ser, m)
    append_energies(ser, e, e0)
    ser["unbalanced"].append(m.unbalanced_ratio())


def load(test, progress=None) -> Loaded:
    """Load a prepared test (its first record taken) until it stops: the driver's loop
    (module docstring)."""
    m, st, ser, step0 = test.m, test.settings, test.series, test.step0
    t0 = time.perf_counter()
    track = PeakTracker(test.stop_drop, test.post_peak, test.peak0)
    tell = LoadingProgress(progress, m, step0, test.bound, st.max_strain)
    reason = "max_steps"
    with heartbeat(lambda: tell(strain=test.strain_now())):
        while m.step - step0 < st.max_steps:
            test.load_step()
            s, eps = test.record()
            test.on_record(s, eps)
            dropped = track.add(s, eps)
            s_mpa, peak_mpa = test.shown(s, track.peak)
            tell(strain=eps, stress_MPa=s_mpa, peak_MPa=peak_mpa,
                 cracks=ser["cracks_tension"][-1] + ser["cracks_shear"][-1])
            if dropped and track.judge(test.stop(track)):
                reason = "post_peak_drop"
                break
            if eps >= st.max_strain:
                reason = "max_strain"
                break
    return Loaded(reason, track, time.perf_counter() - t0)


def run_test(test: LabTest, progress=None):
    """Prepare ``test``, load it to its stop, analyse it: its result. ``progress(dict)``
    receives the latest values after every record."""
    test.prepare()
    end = load(test, progress)
    return test.analyse(end)
