"""One complete virtual lab test from the paper's parameters: validate the 8 meso-
parameters (paper units), get the packing (cached), build the specimen, run the test, and
return everything a run file holds as a :class:`LabRun` (no file is written here: the
stages in ``bpmcal.stages.runs`` write it, or a failure record).

:func:`lab_test` runs any test of the registry (``lab.registry.LAB_TESTS``: its driver
class on ``lab.driver``, its specimen, boundary and checks); ``ucs_test``, ``bts_test``
(Brazilian), ``dtt_test`` (direct tension) and ``triaxial_test`` are it by name, and
``impact_test`` (not driven) shares its conventions. A run that goes numerically
unstable, a specimen that cannot be built or does not settle, or a servo stage that does
not converge raises one of
:data:`RUN_FAILURES`: the run failed, which a study records as data (a failure record);
any other exception is a bug. :func:`test_inputs` (``*_inputs`` by name) gives the inputs
a run file records, also for a run that failed or was not run.

``genesis_max_steps`` bounds the settling of the specimen (``specimen.build_specimen``);
``progress`` receives the genesis phases (``{"phase", "steps", "ratio", "target",
"wall_s"}``), then the records of the test.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .. import params as P
from ..cost import phase
from ..dem._jit import numba, set_threads
from ..dem.errors import InputError, InstabilityError
from .brazilian import BTSSettings, resolved_disc
from .budget import StepBudgetError
from .direct_tension import DTTSettings
from .driver import run_test
from .impact import ImpactSettings, run_impact
from .packing_cache import get_packing
from .registry import kind
from .seeds import retest_seed, retry
from .servo import ServoError
from .specimen import (
    DEFAULT_GENESIS,
    GENESES,
    GenesisError,
    SpecimenSpec,
    build_specimen,
    card_material,
    default_install_gap,
)
from .triaxial import TriaxialSettings
from .ucs import UCSSettings

#: the exceptions that mean "this run failed" (a failure record, not a bug)
RUN_FAILURES = (InstabilityError, GenesisError, ServoError, StepBudgetError)


@dataclass(frozen=True)
class Geometry:
    scale: float = 1.0
    diameter_mm: float = 50.0
    height_mm: float = 100.0
    sigma0_MPa: float = 0.1  # locked-in isotropic stress after genesis ("bpmcal" only)
    install_gap_mm: float | None = None  # bonds on pairs with gap <= this (None: genesis's)
    relax_ratio: float = 1e-2
    genesis: str = DEFAULT_GENESIS  # steps 4-5 of the genesis: "pfc" | "bpmcal" (lab.specimen)

    def __post_init__(self):
        if self.genesis not in GENESES:
            raise InputError(f"genesis={self.genesis!r}: expected one of {', '.join(GENESES)}")
        checks = (  # name, value, low, high, low end open
            ("scale", self.scale, 0.0, 10.0, True),
            ("diameter_mm", self.diameter_mm, 0.0, math.inf, True),
            ("height_mm", self.height_mm, 0.0, math.inf, True),
            ("sigma0_MPa", self.sigma0_MPa, 0.0, 1e4, False),
            ("install_gap_mm", self.install_gap_mm, 0.0, 1e3, False),
            ("relax_ratio", self.relax_ratio, 0.0, 1.0, True))
        for name, v, lo, hi, lo_open in checks:
            if v is None and name == "install_gap_mm":
                continue
            v = P.as_number(v, name, "a number", InputError)
            if (v <= lo if lo_open else v < lo) or v > hi:
                raise InputError(f"{name}={v!r}: expected a number in {'(' if lo_open else '['}"
                                 f"{lo:g}, {hi:g}]")

    def install_gap(self, rmin_mm: float) -> float:
        """The installation gap [mm] used with balls of minimum radius ``rmin_mm``: the
        given one, or the genesis's default (``specimen.default_install_gap``)."""
        if self.install_gap_mm is not None:
            return float(self.install_gap_mm)
        return default_install_gap(self.genesis, 1.0) * float(rmin_mm)

    def to_dict(self, rmin_mm: float | None = None):
        """The run file's geometry inputs; ``install_gap_mm`` is the gap used (needs
        ``rmin_mm`` when the genesis's default applies; NaN without it)."""
        gap = (self.install_gap(rmin_mm) if rmin_mm is not None or self.install_gap_mm is not None
               else math.nan)
        return {"scale": self.scale, "diameter_mm": self.diameter_mm * self.scale,
                "height_mm": self.height_mm * self.scale, "sigma0_MPa": self.sigma0_MPa,
                "install_gap_mm": gap, "relax_ratio": self.relax_ratio,
                "genesis": self.genesis}


@dataclass
class LabRun:
    """A finished virtual test: what its run file holds (``bpmcal.io.h5.write_run``)."""

    test: str  # "ucs" | "bts" | "dtt" | "triaxial" | "impact"
    inputs: dict
    summary: dict
    genesis: dict
    series: dict
    cracks: dict
    particles_initial: dict | None = None
    particles_final: dict | None = None
    bonds: dict | None = None
    groups: dict | None = None


def specimen_spec(params: dict, seed: int, geometry: Geometry) -> SpecimenSpec:
    """The specimen of validated ``params`` (paper units) and ``geometry``; an InputError
    when it cannot be built (e.g. fewer than 3 ball diameters across): a check that
    needs no work."""
    return SpecimenSpec.from_paper_units(params[P.RMIN], params[P.POROSITY], seed,
                                         scale=geometry.scale,
                                         diameter_mm=geometry.diameter_mm,
                                         height_mm=geometry.height_mm,
                                         relax_ratio=geometry.relax_ratio)


def make_specimen(params: dict, seed: int, geometry: Geometry = Geometry(), *, cache=None,
                  threads=None, progress=None, genesis_max_steps=None,
                  boundary: str = "platens"):
    """Validated parameters (paper units) of either contact model -> a bonded (or
    flat-jointed) Specimen (packing from the cache); ``boundary``: which vessel walls stay
    (``build_specimen``). A flat-joint card's installation gap is its own ``fj_gi_ratio``
    (``geometry.install_gap_mm`` applies to parallel bonds)."""
    p = P.validate_params(params)
    spec = specimen_spec(p, seed, geometry)
    with phase("genesis"):  # the cost ledger's phases (bpmcal.cost)
        with phase("packing"):
            pk = get_packing(spec, cache=cache, progress=progress, threads=threads)
        mat, micro = card_material(p)
        gap = None if micro is not None else geometry.install_gap(p[P.RMIN]) * 1e-3
        with phase("build"):
            return build_specimen(pk, mat, sigma0=geometry.sigma0_MPa * 1e6, install_gap=gap,
                                  threads=threads, progress=progress,
                                  max_steps=genesis_max_steps, boundary=boundary,
                                  genesis=geometry.genesis, microstructure=micro)


#: the ISRM Brazilian disc at full size: D = 50 mm, t = D / 2 (scaled like the cylinder)
BTS_DIAMETER_MM = 50.0
BTS_THICKNESS_MM = 25.0


def bts_geometry(scale: float = 1.0, diameter_mm: float = BTS_DIAMETER_MM,
                 thickness_mm: float = BTS_THICKNESS_MM, **kw) -> Geometry:
    """Geometry of a Brazilian disc (``height_mm`` is the disc thickness)."""
    return Geometry(scale=scale, diameter_mm=diameter_mm, height_mm=thickness_mm, **kw)


#: The one setting in which the default study's tests differ from the library's defaults:
#: the size of their specimens (config/config.yaml ``specimen.scale``, ``bts.scale``,
#: ``impact.scale``; tests/workflow/test_defaults.py holds them equal). ``Geometry()`` and
#: the lab commands default to the laboratory's full-size specimens (scale 1); the study
#: shrinks them to run on a laptop, so a full-size test measures a different σc, E or σt
#: by the size effect (docs/lab-tests.md). A lab command at another scale says so once
#: (``bpmcal.cli.runs``). Keys: the cylinder, the Brazilian disc, the impact's cylinder.
STUDY_SCALES = {"cylinder": 0.4, "disc": 0.55, "impact": 0.5}


# ------------------------------------------------------------------ the inputs a run records
def _base_inputs(params: dict, seed: int, geometry: Geometry) -> dict:
    model = params.get("contact_model", P.DEFAULT_CONTACT_MODEL)
    d = {k: float(params[k]) for k in P.CONTACT_MODELS[model] if k in params}
    d.update(geometry.to_dict(params.get(P.RMIN)))
    if model != P.DEFAULT_CONTACT_MODEL:  # parallel-bond run files are as before
        d["contact_model"] = model
        d["install_gap_mm"] = math.nan  # the card's fj_gi_ratio applies
    d["seed"] = int(seed)
    return d


def test_inputs(test: str, params: dict, seed: int, geometry: Geometry, settings) -> dict:
    """The inputs a run file of lab test ``test`` (``registry.LAB_TESTS``) records: the
    card, the geometry, the seed and its settings under ``<test>_`` (a disc's thickness
    and a confined test's sigma3 beside them)."""
    k = kind(test)
    d = _base_inputs(params, seed, geometry)
    if k.disc:
        d["thickness_mm"] = d["height_mm"]
    if k.confined:
        d["sigma3_MPa"] = settings.sigma3 / 1e6
    d.update({f"{test}_{key}": v for key, v in k.settings_dict(settings).items()})
    return d


def ucs_inputs(params: dict, seed: int, geometry: Geometry, settings: UCSSettings) -> dict:
    """:func:`test_inputs` of the UCS test."""
    return test_inputs("ucs", params, seed, geometry, settings)


def bts_inputs(params: dict, seed: int, geometry: Geometry, settings: BTSSettings) -> dict:
    """:func:`test_inputs` of the Brazilian test."""
    return test_inputs("bts", params, seed, geometry, settings)


def dtt_inputs(params: dict, seed: int, geometry: Geometry, settings: DTTSettings) -> dict:
    """:func:`test_inputs` of the direct-tension test."""
    return test_inputs("dtt", params, seed, geometry, settings)


def triaxial_inputs(params: dict, seed: int, geometry: Geometry,
                    settings: TriaxialSettings) -> dict:
    """:func:`test_inputs` of the triaxial test."""
    return test_inputs("triaxial", params, seed, geometry, settings)


def impact_inputs(params: dict, seed: int, geometry: Geometry,
                  settings: ImpactSettings) -> dict:
    """:func:`test_inputs` of the impact test."""
    return test_inputs("impact", params, seed, geometry, settings)


# ------------------------------------------------------------------ the tests
def _crack_arrays(ev: dict) -> dict:
    return {"step": ev["step"], "time": ev["time"], "position": ev["pos"],
            "normal": ev["normal"], "mode": ev["mode"], "radius": ev["radius"],
            "energy": ev["energy"], "sigma": ev["sigma"], "tau": ev["tau"],
            "sigma_n": ev["sigma_n"], "i": ev["i"], "j": ev["j"],
            # flat joints: one crack per broken element (its index in the contact, area)
            **{k: ev[k] for k in ("element", "area") if k in ev}}


def _morphology(test: str, sp, res, ini: dict) -> dict:
    """Failure morphology of a finished run (``lab.morphology``): crack heights along the
    loading axis (the cylinder's axis; a Brazilian disc's loaded diameter, y), the
    principal fracture plane (fitted with a half-thickness of 1.5 mean ball diameters)
    and the fragments."""
    from .morphology import Frame, run_summary

    m = sp.model
    if "peak_step" in res.summary:  # the test knows its peak (a Brazilian split)
        peak_step = int(res.summary["peak_step"])
    else:
        peak = res.series[kind(test).peak_series]
        peak_step = int(res.series["step"][int(np.argmax(peak))])
    band = 3.0 * float(np.mean(ini["radius"]))
    if test == "bts":
        xc, yc = (float(v) for v in ini["position"][:, :2].mean(axis=0))
        d = 2.0 * sp.radius0
        frame = Frame(axis=1, low=yc - 0.5 * d, length=d,
                      centre_point=(xc, yc, 0.5 * (sp.z_bottom + sp.z_top)), width=d,
                      half_thickness=band)
    else:
        frame = Frame(axis=2, low=sp.z_bottom, length=sp.z_top - sp.z_bottom,
                      centre_point=(0.0, 0.0, 0.5 * (sp.z_bottom + sp.z_top)),
                      width=2.0 * sp.radius0, half_thickness=band)
    bi, bj = m.bond_pairs()
    return run_summary(res.cracks, peak_step, frame, n_balls=m.n, bond_i=bi, bond_j=bj,
                       bond_state=m.bond_states, radius=m.radii)


def _threads(m) -> int:
    """The most numba threads the model ran with (forced, or chosen by the model)."""
    return max(m.threads_used, default=numba.get_num_threads())


@dataclass(frozen=True)
class _How:
    """How one lab test runs (:func:`_lab_test`): the packing ``cache``, numba
    ``threads``, the ``progress`` sink and the genesis's step budget, as the public test
    functions take them; ``keep_particles`` (the particles in the run file), ``finite``
    (summary keys that must be finite, else a warning) and ``cost_phase`` (the cost
    ledger's phase: default the test's name, ``bpmcal.cost``)."""

    cache: object = None
    threads: int | None = None
    progress: object = None
    genesis_max_steps: int | None = None
    keep_particles: bool = True
    finite: tuple = ()
    cost_phase: str | None = None


def _lab_test(test: str, params: dict, seed: int, geometry: Geometry, inputs: dict,
              boundary: str, run, how: _How) -> LabRun:
    """Shared body of the UCS, Brazilian, direct-tension and triaxial tests: specimen, test, results;
    booked to the cost ledger's phase ``how.cost_phase`` (default: the test's name;
    ``bpmcal.cost``)."""
    with phase(how.cost_phase or test):
        return _lab_test_run(test, params, seed, geometry, inputs, boundary, run, how)


def _lab_test_run(test: str, params: dict, seed: int, geometry: Geometry, inputs: dict,
                  boundary: str, run, how: _How) -> LabRun:
    """``_lab_test``'s work: genesis (phase ``genesis``), the test (``test``), its
    results (``results``)."""
    cache, threads, progress = how.cache, how.threads, how.progress
    genesis_max_steps, keep_particles, finite = how.genesis_max_steps, how.keep_particles, how.finite
    if threads:
        set_threads(threads)  # for the whole run, genesis included
    t0 = time.perf_counter()
    sp = make_specimen(params, seed, geometry, cache=cache, threads=threads,
                       progress=progress, genesis_max_steps=genesis_max_steps,
                       boundary=boundary)
    t_gen = time.perf_counter() - t0
    m = sp.model
    ini = {"position": m.positions.copy(), "radius": m.radii.copy()}
    with phase("test"):
        res = run(sp)
    with phase("results"):
        return _lab_run(test, sp, res, ini, inputs, t0, t_gen, keep_particles, finite)


def _lab_run(test, sp, res, ini, inputs, t0, t_gen, keep_particles, finite) -> LabRun:
    """The LabRun of a finished test: its summary (with the failure morphology and the
    specimen's genesis report), series, cracks and particles."""
    m = sp.model
    summ = dict(res.summary)
    summ.update(_morphology(test, sp, res, ini))
    g = sp.report
    summ.update({"n_balls": g["n_balls"], "n_bonds": g["n_bonds"],
                 "porosity_achieved": g["porosity_achieved"],
                 "coordination": g["coordination"],
                 "contacts_per_ball": g["contacts_per_ball"],
                 "bonds_per_ball": g["bonds_per_ball"], "bonds_per_cm3": g["bonds_per_cm3"],
                 "install_gap_mm": g["install_gap_mm"], "genesis": g["genesis"],
                 "locked_in_stress_MPa": g["locked_in_stress_MPa"],
                 "genesis_s": t_gen, "wall_s": time.perf_counter() - t0,
                 "test_s": summ["wall_s"],
                 "threads": _threads(m)})
    bad = [k for k in finite if not math.isfinite(summ[k])]
    if bad:
        summ["warning"] = (f"{', '.join(bad)} not finite: too few records in the fit window "
                           "or no peak; see the series")
    bi, bj = m.bond_pairs()
    bonds = {"i": bi, "j": bj, "state": m.bond_states.copy(), "break_step": m.bond_break_steps.copy()}
    fin = {"position": m.positions.copy(), "velocity": m.velocities.copy(),
           "angular_velocity": m.angular_velocities.copy()} if keep_particles else None
    return LabRun(test=test, inputs=inputs, summary=summ, genesis=g, series=res.series,
                  cracks=_crack_arrays(res.cracks),
                  particles_initial=ini if keep_particles else None, particles_final=fin,
                  bonds=bonds if keep_particles else None)


def default_geometry(test: str) -> Geometry:
    """The specimen of lab test ``test`` by default: the ISRM disc at scale 1
    (:func:`bts_geometry`) for the Brazilian test, the 50 x 100 mm cylinder else."""
    return bts_geometry() if kind(test).disc else Geometry()


def lab_test(test: str, params: dict, seed: int, geometry: Geometry | None = None,
             settings=None, *, cache=None, threads=None, progress=None,
             keep_particles: bool = True, genesis_max_steps: int | None = None) -> LabRun:
    """One lab test ``test`` (``registry.LAB_TESTS``) of ``params`` on packing ``seed``:
    its specimen (``geometry``, default :func:`default_geometry`; the registry's
    boundary), its ``driver.LabTest`` on the driver with ``settings`` (default: the
    settings class's defaults), its results. A test with retests (the Brazilian) runs
    :func:`_retested`; the impact, which the driver does not run, :func:`impact_test`
    (its particles are always kept: its fragments are labelled on them)."""
    k = kind(test)
    st = settings or k.settings()
    geo = geometry or default_geometry(test)
    p = P.validate_params(params)  # bad input: raise before any work
    kw = dict(cache=cache, threads=threads, progress=progress,
              genesis_max_steps=genesis_max_steps)
    if k.test_class is None:
        return impact_test(p, seed, geo, st, **kw)
    asked = geo
    if k.disc:  # a disc too coarse for the card's contact model is enlarged
        geo = resolved_disc(geo, p, st)
    inputs = test_inputs(test, p, seed, geo, st)
    if k.disc:
        inputs.update(disc_scale_requested=float(asked.scale), disc_enlarged=geo is not asked)

    def specimen(s: int, retest: bool = False) -> LabRun:  # a retest booked apart (bpmcal.cost)
        how = _How(**kw, keep_particles=keep_particles, finite=k.finite,
                   cost_phase=f"{test}_retest" if retest else None)
        return _lab_test(test, p, s, geo, inputs, k.boundary,
                         lambda sp: run_test(k.test_class(sp, st), progress), how)

    if k.retests:
        return _retested(specimen, seed, st.retests, progress)
    return specimen(seed)


def _retested(specimen, seed: int, retests: int, progress) -> LabRun:
    """The first valid of up to ``1 + retests`` specimens (``specimen(packing seed,
    retest)``): an invalid one is discarded and another packed with
    ``seeds.retest_seed``, in ``seeds.retry``, the one retry loop; the summary's
    ``discs``, ``disc_seed`` and ``discarded`` say which, and ``wall_s`` is the time of
    all of them."""
    discarded, wall = [], [0.0]

    def discard(k: int, run: LabRun) -> None:
        reason = run.summary["bts_invalid_reason"]
        discarded.append(f"seed {retest_seed(seed, k)}: {reason}")
        wall[0] += run.summary["wall_s"]
        if progress is not None:
            progress({"note": f"disc {k + 1} invalid ({reason}); "
                              f"testing disc {k + 2} of at most {retests + 1}"})

    # an invalid disc is discarded and another tested, as in the laboratory (lab.brazilian)
    run, k = retry(lambda k: specimen(retest_seed(seed, k), k > 0), retests + 1,
                   lambda r: r.summary["bts_valid"], discard)
    run.summary.update(discs=k + 1, disc_seed=retest_seed(seed, k),
                       discarded="; ".join(discarded), wall_s=wall[0] + run.summary["wall_s"])
    return run


def ucs_test(params: dict, seed: int, geometry: Geometry = Geometry(),
             settings: UCSSettings = UCSSettings(), **kw) -> LabRun:
    """One UCS test (``lab.ucs``) on the cylinder of ``geometry``: :func:`lab_test`."""
    return lab_test("ucs", params, seed, geometry, settings, **kw)


def bts_test(params: dict, seed: int, geometry: Geometry | None = None,
             settings: BTSSettings | None = None, **kw) -> LabRun:
    """One Brazilian test (``lab.brazilian``) of packing ``seed``: the first valid of up to
    ``1 + settings.retests`` discs (:func:`_retested`); ``geometry`` defaults to the ISRM
    disc 50 x 25 mm at scale 1 (``bts_geometry``): :func:`lab_test`."""
    return lab_test("bts", params, seed, geometry, settings, **kw)


def dtt_test(params: dict, seed: int, geometry: Geometry = Geometry(),
             settings: DTTSettings | None = None, **kw) -> LabRun:
    """One direct-tension test (``lab.direct_tension``) on the free cylinder of
    ``geometry`` (the UCS cylinder by default): :func:`lab_test`."""
    return lab_test("dtt", params, seed, geometry, settings, **kw)


def triaxial_test(params: dict, seed: int, geometry: Geometry = Geometry(),
                  settings: TriaxialSettings | None = None, **kw) -> LabRun:
    """One triaxial test (``lab.triaxial``; sigma3 in ``settings``) on the UCS cylinder of
    ``geometry``: :func:`lab_test`."""
    return lab_test("triaxial", params, seed, geometry, settings, **kw)


def impact_test(params: dict, seed: int, geometry: Geometry = Geometry(),
                settings: ImpactSettings | None = None, *, cache=None, threads=None,
                progress=None, genesis_max_steps: int | None = None) -> LabRun:
    """Drop-hammer impact (``lab.impact``) on the cylinder of ``geometry``; the final
    particles carry their fragment label, ``groups["fragments"]`` every fragment's mass
    and size."""
    st = settings or ImpactSettings()
    p = P.validate_params(params)
    inputs = impact_inputs(p, seed, geometry, st)
    if threads:
        set_threads(threads)
    with phase("impact"):  # the cost ledger (bpmcal.cost)
        return _impact_run(p, seed, geometry, st, inputs, cache=cache, threads=threads,
                           progress=progress, genesis_max_steps=genesis_max_steps)


def _impact_run(p, seed, geometry, st, inputs, *, cache, threads, progress,
                genesis_max_steps) -> LabRun:
    """``impact_test``'s work: genesis, the drop (phase ``test``), its LabRun."""
    t0 = time.perf_counter()
    sp = make_specimen(p, seed, geometry, cache=cache, threads=threads, progress=progress,
                       genesis_max_steps=genesis_max_steps)
    ini = {"position": sp.model.positions.copy(), "radius": sp.model.radii.copy()}
    with phase("test"):
        res = run_impact(sp, st, progress=progress)
    m = sp.model
    summ = dict(res.summary)
    summ["velocity"] = st.velocity
    summ["hammer_mass"] = st.hammer_mass
    summ["total_s"] = time.perf_counter() - t0
    summ["threads"] = _threads(m)
    summ.update({k: sp.report[k] for k in ("genesis", "install_gap_mm", "coordination",
                                           "contacts_per_ball",
                                           "bonds_per_ball", "bonds_per_cm3")})
    bi, bj = m.bond_pairs()
    return LabRun(test="impact", inputs=inputs, summary=summ, genesis=sp.report,
                  series=res.series, cracks=_crack_arrays(res.cracks), particles_initial=ini,
                  particles_final={"position": m.positions.copy(), "velocity": m.velocities.copy(),
                                   "angular_velocity": m.angular_velocities.copy(),
                                   "fragment": res.fragments["label"]},
                  bonds={"i": bi, "j": bj, "state": m.bond_states.copy(),
                         "break_step": m.bond_break_steps.copy()},
                  groups={"fragments": {"mass": res.fragments["mass"],
                                        "size": res.fragments["size"]}})
