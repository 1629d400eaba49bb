"""The lab-test driver (bpmcal.lab.driver) on a test whose stress-strain curve is known in
closed form: a 'model' that only counts steps and time, loaded at a constant strain rate,
whose stress is a triangle (linear rise to the peak, linear fall). Where the driver must
stop, at which record, after how many steps, with which peak, follows from the curve and
the settings alone; so does the Brazilian-style contact event (a drop that ``stop``
refuses) and the cut-offs. And the registry: every quasi-static test is a LabTest whose
peak series it records."""
import math
from dataclasses import dataclass

import numpy as np
import pytest

from bpmcal.lab import registry
from bpmcal.lab.driver import LoadingTest, PeakTracker, record_common, run_test

DT = 1e-7  # s per step
N_REC = 50  # steps per record
RATE = 2.0  # strain per second: 1e-5 strain per record


class ClockModel:
    """The model interface the driver and ``stepping.cycle`` use, without particles."""

    n = 10

    def __init__(self):
        self.step, self.time, self.dt = 0, 0.0, DT

    def cycle(self, k, record=True):
        self.step += int(k)
        self.time = self.step * DT  # exact multiples: no drift

    def crack_counts(self):
        return 0, 0

    def energies(self):
        return {k: 0.0 for k in ("kinetic", "strain_linear", "strain_bond", "slip",
                                 "damping", "dashpot", "released")}

    def unbalanced_ratio(self):
        return 0.0


@dataclass(frozen=True)
class Settings:
    stop_drop: float = 0.5
    post_peak_strain: float = 2e-5
    max_strain: float = 0.01
    max_steps: int = 1_000_000


class Triangle(LoadingTest):
    """sigma = E eps up to ``eps_p``, then E eps_p - F (eps - eps_p), as many times as
    ``teeth`` says (a saw: each tooth a rise and a fall to zero, the next one higher);
    ``refuse`` drops that ``stop`` does not accept as the failure."""

    def __init__(self, settings, teeth=((1e-4, 1e6),), E=1e11, refuse=0):
        self.settings, self.m, self.E = settings, ClockModel(), E
        self.teeth, self.refuse, self.judged = teeth, refuse, 0

    def prepare(self):
        self.series = {k: [] for k in ("step", "time", "strain", "stress", "cracks_tension",
                                       "cracks_shear", "kinetic", "strain_linear",
                                       "strain_bond", "slip", "damping", "dashpot",
                                       "released", "unbalanced")}
        self.step0, self.dt, self.bound = self.m.step, DT, 1000
        self.e0 = self.m.energies()
        self.record()
        self.stop_drop = self.settings.stop_drop

    def load_step(self):
        from bpmcal.lab.stepping import cycle

        cycle(self.m, N_REC)

    def strain_now(self):
        return RATE * self.m.time

    def curve(self, eps):
        base = 0.0
        for k, (eps_p, F) in enumerate(self.teeth):
            rise = self.E * (eps_p - base)
            if eps <= eps_p:
                return self.E * (eps - base) * (1 + k)
            fall_end = eps_p + rise / F
            if eps <= fall_end or k == len(self.teeth) - 1:
                return (rise - F * (eps - eps_p)) * (1 + k)
            base = fall_end
        raise AssertionError

    def record(self):
        eps = self.strain_now()
        s = self.curve(eps)
        record_common(self, self.m.energies(), self.e0, 0.0)
        self.series["strain"].append(eps)
        self.series["stress"].append(s)
        return s, eps

    def stop(self, tracker):
        self.judged += 1
        return self.judged > self.refuse

    def analyse(self, end):
        return end


def test_the_driver_stops_where_the_curve_says():
    """Rise to 10 MPa at strain 1e-4, fall at F = 1e12 Pa per unit strain: the stress is
    below half the peak 5e-6 past it, but the drop counts only once post_peak_strain
    (1.5e-5) has passed: at the second record after the peak (records every 1e-5 of
    strain), the 12th."""
    st = Settings(post_peak_strain=1.5e-5)
    t = Triangle(st, teeth=((1e-4, 1e12),))
    end = run_test(t)
    rec_strain = RATE * N_REC * DT  # 1e-5
    assert rec_strain == pytest.approx(1e-5)
    n_peak = round(1e-4 / rec_strain)  # the record of the peak (10)
    n_stop = n_peak + math.ceil(st.post_peak_strain / rec_strain - 1e-9)  # 12
    assert end.reason == "post_peak_drop"
    assert end.tracker.peak == pytest.approx(1e11 * 1e-4)  # 10 MPa, the curve's peak
    assert end.tracker.peak == max(t.series["stress"])
    assert end.tracker.peak_record == n_peak
    assert t.series["strain"][n_peak] == pytest.approx(1e-4)
    assert len(t.series["step"]) == n_stop + 1  # + the first record, before loading
    assert t.m.step == n_stop * N_REC == end.summary(t)["steps"]
    assert end.records(t) == n_stop + 1 and end.summary(t)["dt"] == DT


def test_a_slow_fall_stops_only_below_stop_drop():
    """A fall slow enough that post_peak_strain passes long before the stress reaches
    half the peak: the stop is at the first record below stop_drop x peak."""
    st = Settings()
    F = 1.03e10  # Pa per unit strain: half of 10 MPa lost 4.85e-4 past the peak
    t = Triangle(st, teeth=((1e-4, F),))
    end = run_test(t)
    s = np.array(t.series["stress"])
    below = np.flatnonzero((s < 0.5 * end.tracker.peak) & (np.arange(s.size) > 10))
    assert end.reason == "post_peak_drop" and len(s) - 1 == below[0]
    assert s[-1] < 0.5 * 1e7 <= s[-2]


def test_a_drop_stop_refuses_is_a_contact_event_and_the_peak_restarts():
    """The Brazilian split check's hook: the first drop is refused (a contact event,
    recorded with its peak), the peak restarts and the second, higher tooth's drop ends
    the test at that tooth's peak."""
    st = Settings(post_peak_strain=1.5e-5)
    t = Triangle(st, teeth=((1e-4, 1e12), (3e-4, 1e12)), refuse=1)
    end = run_test(t)
    assert end.reason == "post_peak_drop" and t.judged == 2
    (ev,) = end.tracker.events
    assert ev["load_N"] == pytest.approx(1e7) and ev["strain"] == pytest.approx(1e-4)
    assert ev["drop_to_N"] < 0.5 * ev["load_N"]
    assert end.tracker.peak == max(t.series["stress"])
    assert end.tracker.peak_strain > ev["strain"]


@pytest.mark.parametrize("cut, reason", [("max_strain", "max_strain"),
                                         ("max_steps", "max_steps")])
def test_a_curve_that_never_drops_stops_at_the_cut_off(cut, reason):
    """A rise only: the test ends at max_strain (the first record at or past it) or after
    max_steps (the first record interval that reaches it)."""
    kw = {"max_strain": 2e-4, "max_steps": 10 ** 9} if cut == "max_strain" else {
        "max_strain": 0.5, "max_steps": 7 * N_REC}
    t = Triangle(Settings(**kw), teeth=((1.0, 1e12),))
    end = run_test(t)
    assert end.reason == reason
    if cut == "max_strain":
        assert t.series["strain"][-1] >= 2e-4 > t.series["strain"][-2]
    else:
        assert t.m.step == 7 * N_REC  # no interval starts at or past the bound


def test_progress_reports_the_latest_record_and_the_peak_in_mpa():
    lines = []
    t = Triangle(Settings(), teeth=((1e-4, 1e12),))
    run_test(t, progress=lines.append)
    assert len(lines) == len(t.series["step"]) - 1  # one per loading record
    last = lines[-1]
    assert last["peak_MPa"] == pytest.approx(10.0)
    assert last["stress_MPa"] == pytest.approx(t.series["stress"][-1] / 1e6)
    assert last["steps"] == t.m.step and last["bound_steps"] == 1000


def test_the_peak_tracker_takes_a_post_peak_strain_or_a_function_of_the_peak_strain():
    fixed = PeakTracker(0.5, 1e-3)
    scaled = PeakTracker(0.5, lambda eps_p: 0.5 * eps_p)
    for tr in (fixed, scaled):
        tr.add(10.0, 1e-3)
    assert not fixed.add(1.0, 1.5e-3) and fixed.add(1.0, 2e-3)  # 1e-3 past the peak
    assert not scaled.add(1.0, 1.2e-3) and scaled.add(1.0, 2e-3)  # half the peak's strain
    below = PeakTracker(0.7, 0.0, peak0=-math.inf)  # a deviator starting below zero
    assert not below.add(-5.0, 0.0) and below.peak == -5.0 and not below.add(-6.0, 1e-4)


@pytest.mark.parametrize("name", [n for n, k in registry.LAB_TESTS.items() if k.test_class])
def test_every_driven_test_is_a_lab_test_whose_series_holds_its_peak(name):
    """Each registered quasi-static test implements the protocol and records the series
    its peak is read from, beside the common columns."""
    from bpmcal.lab import brazilian, direct_tension, triaxial, ucs

    k = registry.kind(name)
    for method in ("prepare", "load_step", "record", "stop", "analyse", "on_record",
                   "post_peak", "shown", "strain_now"):
        assert callable(getattr(k.test_class, method))
    series = {"ucs": ucs.SERIES, "bts": brazilian.BTS_SERIES, "dtt": direct_tension.DTT_SERIES,
              "triaxial": triaxial.TRIAXIAL_SERIES}[name]
    assert k.peak_series in series
    assert {"step", "time", "cracks_tension", "cracks_shear", "unbalanced"} <= set(series)
    assert isinstance(k.settings(), k.settings)


def test_the_registry_covers_every_sample_test_and_the_stages_runners():
    from bpmcal import params as P
    from bpmcal.stages import measure
    from bpmcal.study import gather

    assert set(registry.SAMPLE_KINDS) == {"ucs", *P.SAMPLE_TESTS.values()}
    assert set(measure.RUNNERS) == set(registry.SAMPLE_KINDS)
    assert set(gather.TEST_COLUMNS) == set(P.SAMPLE_TESTS.values())
    with pytest.raises(KeyError, match="expected one of ucs, bts, dtt, triaxial, impact"):
        registry.kind("shear")


@pytest.mark.parametrize("name", [n for n, k in registry.LAB_TESTS.items() if k.test_class])
@pytest.mark.parametrize("field, bad", [("damping", 1.0), ("stop_drop", 0.0),
                                        ("max_strain", 0.6), ("max_steps", 0),
                                        ("max_steps", 2.5), ("record_strain", 0.0),
                                        ("record_strain", float("nan")),
                                        ("post_peak_strain", -1e-4), ("fit_window", (0.6, 0.4)),
                                        ("density_scaling", 1.5), ("density_scaling", -0.1),
                                        ("density_scaling", True),
                                        ("density_scaling", float("nan"))])
def test_every_driven_test_checks_the_settings_they_share_alike(name, field, bad):
    """The settings every driven test has are checked once (``check_loading_settings``):
    the same bad value is refused by each test's settings with the same message (the
    Brazilian test has no fit window)."""
    from bpmcal.dem.errors import InputError

    cls = registry.kind(name).settings
    if field not in cls.__dataclass_fields__:
        pytest.skip(f"{name} has no {field}")
    with pytest.raises(InputError, match=f"^{field}="):
        cls(**{field: bad})


@pytest.mark.parametrize("seed", [1, 2])
def test_density_scaling_gives_the_same_quasi_static_answer_in_fewer_steps(seed, tmp_path):
    """A UCS test and a Brazilian test of A1 with PFC's density scaling (the median ball's
    critical timestep) against the true masses (0): the time step grows by the gain the
    summary records, the loading takes about that many times fewer steps, and the answer
    is the quasi-static one: E and ν as without (elastic: the same to 0.1 % and 0.5 %), σc
    and σt within 3 % (the post-crack path of a small specimen moves a little with any
    change of the trajectory). With the true masses the summary has no density keys."""
    import dataclasses

    from support.paper import A1, FAST, SMALL

    from bpmcal.lab.brazilian import BTSSettings
    from bpmcal.lab.runner import bts_geometry, bts_test, ucs_test

    kw = dict(threads=1, keep_particles=False, cache=tmp_path)
    runs = {q: (ucs_test(A1, seed, SMALL, dataclasses.replace(FAST, density_scaling=q),
                         **kw).summary,
                bts_test(A1, seed, bts_geometry(scale=0.45),
                         BTSSettings(density_scaling=q, retests=0), **kw).summary)
            for q in (0.0, 0.5)}
    (u0, b0), (u1, b1) = runs[0.0], runs[0.5]
    assert "density_dt_gain" not in u0 and "density_dt_gain" not in b0
    for s0, s1 in ((u0, u1), (b0, b1)):
        gain = s1["density_dt_gain"]
        assert gain > 1.2 and s1["density_mass_added"] > 0
        assert s1["dt"] == pytest.approx(gain * s0["dt"], rel=1e-9)
        assert s1["steps"] == pytest.approx(s0["steps"] / gain, rel=0.15)
    assert u1["E_GPa"] == pytest.approx(u0["E_GPa"], rel=1e-3)
    assert u1["nu"] == pytest.approx(u0["nu"], rel=5e-3)
    assert u1["ucs_MPa"] == pytest.approx(u0["ucs_MPa"], rel=0.03)
    assert b0["bts_valid"] and b1["bts_valid"]
    assert b1["bts_MPa"] == pytest.approx(b0["bts_MPa"], rel=0.03)


def test_the_default_scales_the_axial_tests_of_parallel_bonds_only(tmp_path):
    """density_scaling None (every settings class's default): the UCS and triaxial tests of
    a parallel-bonded card run at the contact model's quantile (AXIAL_DENSITY_SCALING,
    the same run as the quantile given), a flat-jointed card's and every Brazilian or
    direct-tension test with the true masses (the same run as 0)."""
    import dataclasses

    from support.paper import A1, FAST, FJ1, SMALL

    from bpmcal.lab.brazilian import BTSSettings
    from bpmcal.lab.driver import AXIAL_DENSITY_SCALING, density_quantile
    from bpmcal.lab.runner import bts_geometry, bts_test, ucs_test

    assert AXIAL_DENSITY_SCALING == {"linearpbond": 0.5, "flatjoint": None}
    assert density_quantile(FAST, True, "linearpbond") == 0.5
    assert density_quantile(FAST, True, "flatjoint") is None
    assert density_quantile(BTSSettings(), False, "linearpbond") is None
    assert density_quantile(BTSSettings(density_scaling=0.3), False, "flatjoint") == 0.3
    kw = dict(threads=1, keep_particles=False, cache=tmp_path)
    short = dataclasses.replace(FAST, max_strain=2e-3)  # elastic: E, ν and the steps
    pb = {q: ucs_test(A1, 1, SMALL, dataclasses.replace(short, density_scaling=q),
                      **kw).summary for q in (None, 0.5)}
    same = ("steps", "dt", "E_GPa", "nu", "density_dt_gain", "density_mass_added")
    assert pb[None]["density_dt_gain"] > 1.2
    assert {k: pb[None][k] for k in same} == {k: pb[0.5][k] for k in same}
    fj = {q: ucs_test(FJ1, 1, SMALL, dataclasses.replace(short, density_scaling=q),
                      **kw).summary for q in (None, 0.0)}
    assert "density_dt_gain" not in fj[None] and fj[None]["steps"] == fj[0.0]["steps"]
    assert fj[None]["dt"] == fj[0.0]["dt"]
    bts = {q: bts_test(A1, 1, bts_geometry(scale=0.45), BTSSettings(density_scaling=q,
                                                                        retests=0),
                       **kw).summary for q in (None, 0.0)}
    assert "density_dt_gain" not in bts[None] and bts[None]["bts_MPa"] == bts[0.0]["bts_MPa"]
