"""bpmcal: calibrated bonded-particle (DEM) models of rock from laboratory tests."""
from .exact_math import pin_openblas as _pin_openblas

__version__ = "0.1.0"

# Before numpy/scipy load OpenBLAS: the same BLAS kernels on every x86-64 host with AVX2
# and FMA, so fits give bit-identical results across hosts (bpmcal.exact_math).
_pin_openblas()
