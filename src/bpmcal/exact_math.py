"""Host-independent numerics for the result-determining paths.

The same inputs must give bit-identical results on every x86-64 host with AVX2 and FMA
(docs/reproducibility.md). Two things in the numeric stack choose their code by the CPU
they run on, and both changed the default study's numbers between an AVX-512 host and an
AVX2 host:

- **numpy's vectorised transcendental functions.** On hosts with AVX-512, numpy computes
  float64 ``power``, ``exp``, ``log``, ``cbrt``, ``arctan2``, ... with its AVX-512 (SVML)
  kernels; elsewhere it calls the C library. The two round differently in the last bit for
  a few per cent of the arguments (``r ** 3``: ~5 % of ball radii). A last-bit difference
  in one ball mass is enough for the genesis trajectory, and with it every packing and
  every UCS result, to diverge. :func:`libm_pow` and :func:`libm_exp` call the C library
  for every element instead (what numpy does on a host without AVX-512), so the result no
  longer depends on which kernels numpy picked.
- **OpenBLAS kernels.** OpenBLAS picks its kernels (SkylakeX, Haswell, Zen, ...) for the
  CPU it finds; least-squares fits (``np.polyfit``, ``np.linalg.lstsq``, statsmodels OLS,
  ``scipy.optimize``) then differ in the last bits between hosts. :func:`lsq_slope` is a
  BLAS-free least-squares slope (exact rational arithmetic, rounded once) for the UCS
  measurement; for the analysis stages, :func:`pin_openblas` (called when ``bpmcal`` is
  imported) selects OpenBLAS's Haswell kernels on every x86-64 Linux host with AVX2 and
  FMA, *if* numpy and scipy are not loaded yet (the ``bpmcal`` command always imports
  ``bpmcal`` first). Haswell kernels are what OpenBLAS uses on AVX2 hosts (Intel since
  Haswell, AMD Zen 1-3, whose "Zen" kernels give the same results here).

What stays host-dependent: hosts without FMA (the C library's FMA and non-FMA variants of
``pow``/``sin``/``exp`` round differently, and the numba kernels are compiled with FMA
contraction), other CPU architectures, other versions of numpy/numba/OpenBLAS/glibc.
"""
from __future__ import annotations

import math
import os
import platform
import sys
from fractions import Fraction

#: OpenBLAS kernel set pinned on x86-64 hosts with AVX2 + FMA
OPENBLAS_CORE = "Haswell"


def _cpu_flags() -> set[str]:
    """CPU feature flags from /proc/cpuinfo (empty where that file does not exist)."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pin_openblas(environ=None) -> str | None:
    """Select OpenBLAS's Haswell kernels (``OPENBLAS_CORETYPE``) on an x86-64 Linux host
    with AVX2 and FMA, before numpy or scipy load OpenBLAS. Returns the core type in
    effect, or None when it was not (and could not be) set: another CPU, numpy or scipy
    already imported. A ``OPENBLAS_CORETYPE`` set by the user is left as it is, and
    ``BPMCAL_NATIVE_BLAS=1`` switches the pinning off."""
    env = os.environ if environ is None else environ
    if "OPENBLAS_CORETYPE" in env:
        return env["OPENBLAS_CORETYPE"]
    if env.get("BPMCAL_NATIVE_BLAS", "") not in ("", "0"):
        return None
    if "numpy" in sys.modules or "scipy" in sys.modules:
        return None  # OpenBLAS has chosen already
    if sys.platform != "linux" or platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    if not {"avx2", "fma"} <= _cpu_flags():
        return None
    env["OPENBLAS_CORETYPE"] = OPENBLAS_CORE
    return OPENBLAS_CORE


def libm_pow(x, p: float):
    """``x ** p`` element by element through the C library's ``pow`` (float64 array)."""
    import numpy as np

    a = np.asarray(x, dtype=float)
    p = float(p)
    return np.fromiter((math.pow(v, p) for v in a.ravel().tolist()), dtype=float,
                       count=a.size).reshape(a.shape)


def libm_exp(x):
    """``exp(x)`` element by element through the C library (float64 array)."""
    import numpy as np

    a = np.asarray(x, dtype=float)
    return np.fromiter((math.exp(v) for v in a.ravel().tolist()), dtype=float,
                       count=a.size).reshape(a.shape)


def lsq_slope(x, y) -> float:
    """Least-squares slope of ``y`` on ``x`` (with intercept), without BLAS: computed
    exactly in rational arithmetic from the float64 inputs and rounded once, so the result
    is the correctly rounded slope on every host. NaN if fewer than 3 points or constant
    ``x``."""
    xf = [float(v) for v in x]
    yf = [float(v) for v in y]
    if len(xf) != len(yf):
        raise ValueError(f"lsq_slope: {len(xf)} x values but {len(yf)} y values")
    n = len(xf)
    if n < 3 or not all(map(math.isfinite, xf + yf)):
        return math.nan
    xs = [Fraction(v) for v in xf]
    ys = [Fraction(v) for v in yf]
    sx, sy = sum(xs), sum(ys)
    sxx = n * sum(v * v for v in xs) - sx * sx
    if sxx == 0:
        return math.nan
    sxy = n * sum(a * b for a, b in zip(xs, ys)) - sx * sy
    return float(sxy / sxx)
