"""Host independence of the numbers (docs/reproducibility.md).

The default study gave different datasets on an AVX-512 host and an AVX2 host because
numpy's AVX-512 power kernel rounded some ball masses differently from the C library and
OpenBLAS's kernel choice changed the UCS fits. These tests emulate the other host on this
one: numpy's SIMD targets switched off (``NPY_DISABLE_CPU_FEATURES``), another OpenBLAS
kernel set (``OPENBLAS_CORETYPE``), and (slow) the numba kernels compiled for an AVX2 CPU
(``NUMBA_CPU_NAME``/``NUMBA_CPU_FEATURES``); a genesis + UCS run must then give the same
packing, series and summary, bit for bit, as the native run.
"""
import json
import math
import os
import platform
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from bpmcal.dem import Material, Model
from bpmcal.exact_math import OPENBLAS_CORE, libm_pow, lsq_slope, pin_openblas
from bpmcal.lab.ucs import fit_slope

SRC = str(Path(__file__).resolve().parents[2] / "src")
X86_LINUX = sys.platform == "linux" and platform.machine().lower() in ("x86_64", "amd64")


def _cpu_flags():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


FLAGS = _cpu_flags()


def _numpy_simd():
    """numpy's dispatch targets found on this CPU, and whether AVX-512F is among them."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    found = [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]
    return found, bool(__cpu_features__.get("AVX512F"))


# ------------------------------------------------------------------------------ unit level
def test_ball_masses_are_c_library_cubes_and_physical():
    rng = np.random.default_rng(5)
    r = rng.uniform(0.6e-3, 1.66e-3, 4000)  # the study's radii (Rmin 0.6-1.0 mm, x1.66)
    pos = rng.uniform(0.0, 0.1, (r.size, 3))
    rho = 2650.0
    m = Model(pos, r, rho, Material(emod=1e9, kratio=1.0, fric=0.0, pb_emod=1e9, pb_kratio=1.0,
                                    pb_ten=1e6, pb_coh=1e6, pb_fa=0.0))
    ref = np.array([rho * (4.0 / 3.0) * math.pi * math.pow(v, 3.0) for v in r.tolist()])
    assert np.array_equal(m.B.mass, ref)  # not numpy's (host-dependent) vector kernels
    # and the mass is rho 4/3 pi r^3: within 3 ulp of the exact product of the inputs
    exact = [Fraction(rho) * Fraction(4.0 / 3.0) * Fraction(math.pi) * Fraction(v) ** 3
             for v in r.tolist()]
    err = [abs(Fraction(a) - e) / Fraction(math.ulp(float(e))) for a, e in zip(m.B.mass, exact)]
    assert max(err) <= 3


def test_libm_pow_is_the_c_library_element_by_element():
    x = np.array([[0.6e-3, 1.0e-3], [1.66e-3, 2.0]])
    assert np.array_equal(libm_pow(x, 3), [[math.pow(v, 3.0) for v in row] for row in x.tolist()])
    assert libm_pow(x, 3).shape == x.shape and libm_pow([], 3).shape == (0,)


def test_lsq_slope_is_the_exact_least_squares_slope_rounded_once():
    x = np.arange(10) / 8.0  # dyadic: the line is exact in binary
    assert lsq_slope(x, 3.0 * x + 0.25) == 3.0
    assert lsq_slope(x, -0.5 * x) == -0.5
    rng = np.random.default_rng(2)
    x = np.sort(rng.uniform(4e-4, 6e-4, 25))
    y = 5.0e10 * x + rng.normal(0.0, 2e5, x.size)
    # the normal equations in exact arithmetic (independent of lsq_slope's formula)
    X, Y = [Fraction(v) for v in x.tolist()], [Fraction(v) for v in y.tolist()]
    xm, ym = sum(X) / len(X), sum(Y) / len(Y)
    exact = sum((a - xm) * (b - ym) for a, b in zip(X, Y)) / sum((a - xm) ** 2 for a in X)
    assert lsq_slope(x, y) == float(exact)
    assert fit_slope(x, y) == float(exact)  # E and nu of every UCS run (np.polyfit: 3 ulp off)
    assert abs(lsq_slope(x, y) - np.polyfit(x, y, 1)[0]) <= 1e-12 * abs(float(exact))
    assert math.isnan(lsq_slope([1.0, 2.0], [1.0, 2.0]))  # fewer than 3 points
    assert math.isnan(lsq_slope([1.0, 1.0, 1.0], [1.0, 2.0, 3.0]))  # constant x
    assert math.isnan(lsq_slope([1.0, 2.0, math.nan], [1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="3 x values but 2 y values"):
        lsq_slope([1.0, 2.0, 3.0], [1.0, 2.0])


def test_pin_openblas_respects_the_user_and_a_loaded_numpy():
    assert pin_openblas({"OPENBLAS_CORETYPE": "Zen"}) == "Zen"
    env = {}
    assert pin_openblas(env) is None and env == {}  # numpy is loaded: too late to pin
    env = {"BPMCAL_NATIVE_BLAS": "1"}
    assert pin_openblas(env) is None and "OPENBLAS_CORETYPE" not in env


@pytest.mark.skipif(not (X86_LINUX and {"avx2", "fma"} <= FLAGS),
                    reason="OpenBLAS kernels are pinned on x86-64 Linux hosts with AVX2+FMA only")
def test_importing_bpmcal_first_pins_the_openblas_kernels():
    pytest.importorskip("threadpoolctl")
    code = ("import bpmcal, json, os, numpy, scipy.linalg, threadpoolctl\n"
            "print(json.dumps([os.environ.get('OPENBLAS_CORETYPE'), sorted({i['architecture'] "
            "for i in threadpoolctl.threadpool_info() if i['internal_api'] == 'openblas'})]))")
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_CORETYPE", "BPMCAL_NATIVE_BLAS")}
    env["PYTHONPATH"] = SRC + os.pathsep + env.get("PYTHONPATH", "")
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    coretype, archs = json.loads(r.stdout.splitlines()[-1])
    assert coretype == OPENBLAS_CORE
    assert archs and all(a.lower() == OPENBLAS_CORE.lower() for a in archs), archs


# ------------------------------------------------------------- a run under host emulation
RUN = r"""
import hashlib, json, sys
import numpy  # before bpmcal: OpenBLAS keeps the kernels this environment selects
from bpmcal.lab.runner import Geometry, make_specimen
from bpmcal.lab.ucs import UCSSettings, run_ucs

def h(*arrays):
    m = hashlib.sha256()
    for a in arrays:
        m.update(numpy.ascontiguousarray(a).tobytes())
    return m.hexdigest()

p = dict(rmin_mm=0.8, porosity=0.3, pb_emod_GPa=30.0, pb_kratio=2.5, pb_ten_MPa=25.0,
         pb_coh_MPa=30.0, pb_fa_deg=35.0, fric=0.35)
sp = make_specimen(p, 7, Geometry(scale=0.24), cache=sys.argv[1], threads=1)
built = h(sp.model.B.pos, sp.model.B.mass, sp.model.Bd.state)
res = run_ucs(sp, UCSSettings(platen_velocity=0.1, record_strain=4e-5))
summary = {k: repr(v) for k, v in res.summary.items() if k not in ("wall_s",)}
print(json.dumps({"built": built, "series": h(*res.series.values()), "summary": summary}))
"""


def _run(tmp_path, name, **env_over):
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "NUMBA_CPU_NAME",
                        "NUMBA_CPU_FEATURES")}
    env.update(env_over)
    env["PYTHONPATH"] = SRC + os.pathsep + env.get("PYTHONPATH", "")
    cache = tmp_path / f"packings-{name}"  # every run builds its own packing
    r = subprocess.run([sys.executable, "-c", RUN, str(cache)], env=env, capture_output=True,
                       text=True, timeout=1500)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.splitlines()[-1])


@pytest.fixture(scope="module")
def native(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("native"), "native")


def _other_blas_core():
    """An OpenBLAS kernel set other than the one this host picks (both run here)."""
    from threadpoolctl import threadpool_info

    archs = {i["architecture"].lower() for i in threadpool_info()
             if i["internal_api"] == "openblas"}
    return "Nehalem" if archs != {"nehalem"} else "Prescott"


@pytest.mark.skipif(not X86_LINUX, reason="emulates x86-64 hosts (numpy SIMD targets, OpenBLAS "
                    "kernels)")
@pytest.mark.slow
def test_genesis_and_ucs_do_not_depend_on_numpy_simd_or_blas_kernels(native, tmp_path):
    pytest.importorskip("threadpoolctl")
    found, avx512 = _numpy_simd()
    if not avx512:
        pytest.skip("no AVX-512 on this host: numpy runs the same kernels with and without the "
                    "emulation, so it would show nothing")
    emulated = _run(tmp_path, "emulated", NPY_DISABLE_CPU_FEATURES=" ".join(found),
                    OPENBLAS_CORETYPE=_other_blas_core())
    assert emulated == native


@pytest.mark.slow
@pytest.mark.skipif(not X86_LINUX, reason="emulates x86-64 hosts")
def test_kernels_compiled_for_an_avx2_cpu_give_the_same_run(native, tmp_path):
    """The numba kernels compiled for an AVX2 CPU (no AVX-512; a fresh numba cache) plus
    numpy without its AVX-512 targets and OpenBLAS's Haswell kernels: a full AVX2 host."""
    import llvmlite.binding as ll

    feats = ll.get_host_cpu_features()
    if not feats.get("avx512f"):
        pytest.skip("no AVX-512 on this host: the kernels are compiled for AVX2 already")
    if not (feats.get("avx2") and feats.get("fma")):
        pytest.skip("the emulated host has AVX2 and FMA; this one does not")
    for k in list(feats):
        if k.startswith(("avx512", "amx", "avx10")):
            feats[k] = False
    found, _ = _numpy_simd()
    emulated = _run(tmp_path, "avx2", NUMBA_CACHE_DIR=str(tmp_path / "numba-avx2"),
                    NUMBA_CPU_NAME="haswell", NUMBA_CPU_FEATURES=feats.flatten(),
                    NPY_DISABLE_CPU_FEATURES=" ".join(f for f in found
                                                      if f.startswith(("X86_V4", "AVX512"))),
                    OPENBLAS_CORETYPE="Haswell")
    assert emulated == native
