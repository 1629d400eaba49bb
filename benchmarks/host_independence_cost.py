"""What host independence costs: genesis and one UCS sample at the default study's scale.

One design sample of ``config/config.yaml`` (default s000, scale 0.4): the packing is
relaxed from scratch (no cache), bonded, and tested with ``--threads`` numba threads; each
stage is timed ``--repeats`` times (wall and CPU time; on a shared machine the CPU time is
the better comparison) and the medians are printed with the load average. The replaced
operations are timed on their own as well, on the sample's own data: ball masses (numpy's
``r ** 3`` vs the C library's ``pow`` per ball) and the UCS fits of E and nu
(``np.polyfit`` vs :func:`bpmcal.exact_math.lsq_slope`).

    python benchmarks/host_independence_cost.py --sample s000 --repeats 3 [--json]

Runs with any bpmcal version on ``PYTHONPATH`` (the micro-benchmarks need
``bpmcal.exact_math``), so the same script times the code before and after the change.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import yaml
from _study import CONFIG, cpu_model, study_design, ucs_settings


def _best(f, n):
    """Median wall time of ``n`` calls of f [s]."""
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--sample", default="s000")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1,
                    help="numba threads for the whole run (the workflow's resources.dem_threads: 1)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)

    import bpmcal
    from bpmcal.dem._jit import set_threads
    from bpmcal.lab.runner import Geometry
    from bpmcal.lab.specimen import SpecimenSpec, build_specimen, paper_material, relax_packing
    from bpmcal.lab.ucs import run_ucs

    cfg = yaml.safe_load(Path(a.config).read_text())
    p = study_design(cfg).set_index("sample_id").loc[a.sample]
    sp_cfg = cfg["specimen"]
    geo = Geometry(scale=sp_cfg["scale"], diameter_mm=sp_cfg["diameter_mm"],
                   height_mm=sp_cfg["height_mm"], sigma0_MPa=sp_cfg["sigma0_MPa"],
                   install_gap_mm=sp_cfg["install_gap_mm"], relax_ratio=sp_cfg["relax_ratio"])
    spec = SpecimenSpec.from_paper_units(p.rmin_mm, p.porosity, int(p.seed), scale=geo.scale,
                                         diameter_mm=geo.diameter_mm, height_mm=geo.height_mm,
                                         relax_ratio=geo.relax_ratio)
    mat = paper_material(p.pb_emod_GPa, p.pb_kratio, p.pb_ten_MPa, p.pb_coh_MPa, p.pb_fa_deg,
                         p.fric)
    settings = ucs_settings(cfg)
    # install_gap_mm null: the genesis's own gap; the config's genesis when it names one
    gap = None if geo.install_gap_mm is None else geo.install_gap_mm * 1e-3
    genesis = {"genesis": sp_cfg["genesis"]} if "genesis" in sp_cfg else {}
    set_threads(a.threads)
    load0 = os.getloadavg()
    # warm-up: numba cache load / compile, not timed
    warm = SpecimenSpec.from_paper_units(1.0, 0.3, 1, scale=0.24)
    build_specimen(relax_packing(warm), mat, sigma0=geo.sigma0_MPa * 1e6)

    t_relax, t_build, t_ucs, cpu_gen, cpu_ucs, res = [], [], [], [], [], None
    for _ in range(a.repeats):
        t, c = time.perf_counter(), time.process_time()
        pk = relax_packing(spec)
        t_relax.append(time.perf_counter() - t)
        t = time.perf_counter()
        sp = build_specimen(pk, mat, sigma0=geo.sigma0_MPa * 1e6, install_gap=gap,
                            threads=a.threads, **genesis)
        t_build.append(time.perf_counter() - t)
        cpu_gen.append(time.process_time() - c)
        t, c = time.perf_counter(), time.process_time()
        res = run_ucs(sp, settings)
        t_ucs.append(time.perf_counter() - t)
        cpu_ucs.append(time.process_time() - c)
    out = {
        "bpmcal": bpmcal.__file__, "sample": a.sample, "scale": geo.scale,
        "n_balls": int(sp.model.n), "ucs_steps": int(res.summary["steps"]),
        "ucs_MPa": res.summary["ucs_MPa"], "E_GPa": res.summary["E_GPa"],
        "nu": res.summary["nu"], "repeats": a.repeats,
        "relax_s_median": statistics.median(t_relax),
        "build_s_median": statistics.median(t_build),
        "genesis_s_median": statistics.median([x + y for x, y in zip(t_relax, t_build)]),
        "ucs_s_median": statistics.median(t_ucs),
        "genesis_cpu_s_median": statistics.median(cpu_gen),
        "ucs_cpu_s_median": statistics.median(cpu_ucs),
        "relax_steps": int(pk.report["relax_steps"]), "threads": a.threads,
        "openblas_coretype": os.environ.get("OPENBLAS_CORETYPE", ""),
        "cpu": cpu_model(), "loadavg_before": load0, "loadavg_after": os.getloadavg(),
    }
    try:
        from bpmcal.exact_math import libm_pow, lsq_slope
    except ImportError:  # a version before bpmcal.exact_math: end-to-end timings only
        libm_pow = lsq_slope = None
    if libm_pow is not None:
        r = sp.model.B.radius
        s = res.series
        ip = int(np.argmax(s["axial_stress"]))
        pre = slice(0, ip + 1)
        w = (s["axial_stress"][pre] >= 0.4 * s["axial_stress"][ip]) & (
            s["axial_stress"][pre] <= 0.6 * s["axial_stress"][ip])
        x, y = s["axial_strain"][pre][w], s["axial_stress"][pre][w]
        out.update({
            "masses_numpy_pow_us": 1e6 * _best(lambda: r ** 3, 200),
            "masses_libm_pow_us": 1e6 * _best(lambda: np.array([math.pow(v, 3.0)
                                                                 for v in r.tolist()]), 200),
            "fit_points": int(w.sum()),
            "fit_polyfit_us": 1e6 * _best(lambda: np.polyfit(x, y, 1), 200),
            "fit_lsq_slope_us": 1e6 * _best(lambda: lsq_slope(x, y), 200),
        })
    if a.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:24s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
