"""One complete virtual UCS test from the paper's parameters to an HDF5 file.

``run_ucs_file`` is what ``bpmcal ucs`` and the workflow call: validate the 8 meso-
parameters (paper units), get the packing (cached), build the specimen, run the test,
write the HDF5 file atomically. A run that goes numerically unstable, or a parameter
combination that cannot be built, produces a *failure record* (status "failed" and the
message) instead of an exception, so a study is not stopped by one bad sample; any other
exception is a bug and propagates.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from .. import params as P
from ..dem._jit import set_threads
from ..dem.errors import InstabilityError
from ..io.h5 import write_run
from .specimen import GenesisError, SpecimenSpec, build_specimen, get_packing, paper_material
from .ucs import UCSSettings, run_ucs, settings_dict


@dataclass(frozen=True)
class Geometry:
    scale: float = 1.0
    diameter_mm: float = 50.0
    height_mm: float = 100.0
    sigma0_MPa: float = 0.1  # locked-in isotropic stress after genesis
    install_gap_mm: float = 0.0  # bonds on pairs with gap <= this
    relax_ratio: float = 1e-2

    def to_dict(self):
        return {"scale": self.scale, "diameter_mm": self.diameter_mm * self.scale,
                "height_mm": self.height_mm * self.scale, "sigma0_MPa": self.sigma0_MPa,
                "install_gap_mm": self.install_gap_mm, "relax_ratio": self.relax_ratio}


@dataclass
class RunOutcome:
    status: str
    summary: dict = field(default_factory=dict)
    error: str = ""
    path: object = None


def make_specimen(params: dict, seed: int, geometry: Geometry = Geometry(), *, cache=None,
                  threads=None, progress=None):
    """Validated parameters (paper units) -> a bonded Specimen (packing from the cache)."""
    p = P.validate_params(params)
    spec = SpecimenSpec.from_paper_units(p["rmin_mm"], p["porosity"], seed,
                                         scale=geometry.scale,
                                         diameter_mm=geometry.diameter_mm,
                                         height_mm=geometry.height_mm,
                                         relax_ratio=geometry.relax_ratio)
    pk = get_packing(spec, cache=cache)
    mat = paper_material(p["pb_emod_GPa"], p["pb_kratio"], p["pb_ten_MPa"], p["pb_coh_MPa"],
                         p["pb_fa_deg"], p["fric"])
    return build_specimen(pk, mat, sigma0=geometry.sigma0_MPa * 1e6,
                          install_gap=geometry.install_gap_mm * 1e-3, threads=threads,
                          progress=progress)


def ucs_inputs(params: dict, seed: int, geometry: Geometry, settings: UCSSettings) -> dict:
    d = {k: float(params[k]) for k in P.PARAMS if k in params}
    d.update(geometry.to_dict())
    d["seed"] = int(seed)
    d.update({f"ucs_{k}": v for k, v in settings_dict(settings).items()})
    return d


def run_ucs_file(out, params: dict, seed: int, geometry: Geometry = Geometry(),
                 settings: UCSSettings = UCSSettings(), *, cache=None, threads=None,
                 progress=None, keep_particles: bool = True) -> RunOutcome:
    """Run one UCS test and write ``out`` (HDF5). Returns the outcome; unstable runs and
    unbuildable specimens give status "failed" (and a failure-record file)."""
    p = P.validate_params(params)  # bad input: raise before any work
    inputs = ucs_inputs(p, seed, geometry, settings)
    if threads:
        set_threads(threads)  # for the whole run, genesis included
    t0 = time.perf_counter()
    try:
        sp = make_specimen(p, seed, geometry, cache=cache, threads=threads)
        t_gen = time.perf_counter() - t0
        m = sp.model
        ini = {"position": m.positions.copy(), "radius": m.radii.copy()}
        res = run_ucs(sp, settings, progress=progress)
    except (InstabilityError, GenesisError) as e:
        msg = f"{type(e).__name__}: {e}"
        write_run(out, test="ucs", inputs=inputs, status="failed", error=msg,
                  summary={"wall_s": time.perf_counter() - t0})
        return RunOutcome(status="failed", error=msg, path=out)
    summ = dict(res.summary)
    g = sp.report
    summ.update({"n_balls": g["n_balls"], "n_bonds": g["n_bonds"],
                 "porosity_achieved": g["porosity_achieved"],
                 "coordination": g["coordination"],
                 "locked_in_stress_MPa": g["locked_in_stress_MPa"],
                 "genesis_s": t_gen, "wall_s": time.perf_counter() - t0,
                 "test_s": summ["wall_s"]})
    for k in ("ucs_MPa", "E_GPa", "nu"):
        if not math.isfinite(summ[k]):
            summ["warning"] = (f"{k} is not finite: too few records in the fit window or no "
                               "peak; see the series")
    ev = res.cracks
    cracks = {"step": ev["step"], "time": ev["time"], "position": ev["pos"],
              "normal": ev["normal"], "mode": ev["mode"], "radius": ev["radius"],
              "energy": ev["energy"], "sigma": ev["sigma"], "tau": ev["tau"],
              "sigma_n": ev["sigma_n"], "i": ev["i"], "j": ev["j"]}
    bi, bj = m.bond_pairs()
    bonds = {"i": bi, "j": bj, "state": m.bond_states.copy(), "break_step": m.bond_break_steps.copy()}
    fin = {"position": m.positions.copy(), "velocity": m.velocities.copy(),
           "angular_velocity": m.angular_velocities.copy()} if keep_particles else None
    write_run(out, test="ucs", inputs=inputs, summary=summ, genesis=g, series=res.series,
              cracks=cracks, particles_initial=ini if keep_particles else None,
              particles_final=fin, bonds=bonds if keep_particles else None)
    return RunOutcome(status="ok", summary=summ, path=out)


def run_impact_file(out, params: dict, seed: int, geometry: Geometry = Geometry(),
                    settings=None, *, cache=None, threads=None, progress=None) -> RunOutcome:
    """Drop-hammer impact on a specimen of the given parameters -> HDF5 file (test
    "impact"; the same conventions as the UCS run files)."""
    from .impact import ImpactSettings, run_impact
    from .impact import settings_dict as impact_dict

    st = settings or ImpactSettings()
    p = P.validate_params(params)
    inputs = {k: float(p[k]) for k in P.PARAMS}
    inputs.update(geometry.to_dict())
    inputs["seed"] = int(seed)
    inputs.update({f"impact_{k}": v for k, v in impact_dict(st).items()})
    if threads:
        set_threads(threads)
    t0 = time.perf_counter()
    try:
        sp = make_specimen(p, seed, geometry, cache=cache, threads=threads)
        ini = {"position": sp.model.positions.copy(), "radius": sp.model.radii.copy()}
        res = run_impact(sp, st, progress=progress)
    except (InstabilityError, GenesisError) as e:
        msg = f"{type(e).__name__}: {e}"
        write_run(out, test="impact", inputs=inputs, status="failed", error=msg,
                  summary={"wall_s": time.perf_counter() - t0})
        return RunOutcome(status="failed", error=msg, path=out)
    m = sp.model
    summ = dict(res.summary)
    summ["velocity"] = st.velocity
    summ["hammer_mass"] = st.hammer_mass
    summ["total_s"] = time.perf_counter() - t0
    ev = res.cracks
    cracks = {"step": ev["step"], "time": ev["time"], "position": ev["pos"],
              "normal": ev["normal"], "mode": ev["mode"], "radius": ev["radius"],
              "energy": ev["energy"], "sigma": ev["sigma"], "tau": ev["tau"],
              "sigma_n": ev["sigma_n"], "i": ev["i"], "j": ev["j"]}
    bi, bj = m.bond_pairs()
    write_run(out, test="impact", inputs=inputs, summary=summ, genesis=sp.report,
              series=res.series, cracks=cracks, particles_initial=ini,
              particles_final={"position": m.positions.copy(), "velocity": m.velocities.copy(),
                               "angular_velocity": m.angular_velocities.copy(),
                               "fragment": res.fragments["label"]},
              bonds={"i": bi, "j": bj, "state": m.bond_states.copy(),
                     "break_step": m.bond_break_steps.copy()},
              groups={"fragments": {"mass": res.fragments["mass"],
                                    "size": res.fragments["size"]}})
    return RunOutcome(status="ok", summary=summ, path=out)
