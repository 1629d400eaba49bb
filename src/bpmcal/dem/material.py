"""Material properties of the linear + linear-parallel-bond model (PFC ``linearpbond``), SI.

Names follow PFC's properties: ``emod`` (E*), ``kratio`` (kappa*), ``fric`` (mu),
``pb_emod`` (E-bar), ``pb_kratio`` (kappa-bar), ``pb_ten`` (sigma-bar_c), ``pb_coh``
(c-bar), ``pb_fa`` (phi-bar, degrees), ``pb_rmul`` (lambda-bar), ``pb_mcf`` (beta-bar),
``dp_nratio``/``dp_sratio`` (dashpot critical-damping ratios).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from .errors import InputError


def _check(name: str, value: float, lo: float, hi: float, lo_open: bool, unit: str, what: str):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}={value!r}: expected a number ({what})") from None
    if not math.isfinite(v):
        raise InputError(f"{name}={value!r}: expected a finite number ({what})")
    bad_lo = v <= lo if lo_open else v < lo
    if bad_lo or v > hi:
        lo_b = "(" if lo_open else "["
        hi_s = "inf" if math.isinf(hi) else f"{hi:g}"
        raise InputError(
            f"{name}={v:g}{unit}: out of its physical domain {lo_b}{lo:g}, {hi_s}] ({what})")
    return v


@dataclass(frozen=True)
class Material:
    """Linear-parallel-bond material, SI units (Pa, degrees for pb_fa)."""

    emod: float  # E* of the linear component [Pa]
    kratio: float  # kappa* = kn/ks [-]
    fric: float  # friction coefficient of ball-ball contacts [-]
    pb_emod: float  # E-bar [Pa]
    pb_kratio: float  # kappa-bar [-]
    pb_ten: float  # tensile strength [Pa]
    pb_coh: float  # cohesion [Pa]
    pb_fa: float  # friction angle [deg]
    pb_rmul: float = 1.0  # bond radius multiplier lambda-bar [-]
    pb_mcf: float = 1.0  # moment-contribution factor beta-bar [-]
    dp_nratio: float = 0.0  # normal critical-damping ratio [-]
    dp_sratio: float = 0.0  # shear critical-damping ratio [-]

    def __post_init__(self):
        inf = math.inf
        _check("emod", self.emod, 0.0, inf, True, " Pa", "effective modulus E* > 0")
        _check("kratio", self.kratio, 0.0, inf, True, "", "stiffness ratio kn/ks > 0")
        _check("fric", self.fric, 0.0, inf, False, "", "friction coefficient >= 0")
        _check("pb_emod", self.pb_emod, 0.0, inf, True, " Pa", "bond modulus > 0")
        _check("pb_kratio", self.pb_kratio, 0.0, inf, True, "", "bond stiffness ratio > 0")
        _check("pb_ten", self.pb_ten, 0.0, inf, False, " Pa", "tensile strength >= 0")
        _check("pb_coh", self.pb_coh, 0.0, inf, False, " Pa", "cohesion >= 0")
        if float(self.pb_fa) >= 90.0:
            raise InputError(f"pb_fa={self.pb_fa:g} deg: out of its physical domain [0, 90) "
                             "(friction angle in degrees)")
        _check("pb_fa", self.pb_fa, 0.0, 90.0, False, " deg", "friction angle in [0, 90)")
        _check("pb_rmul", self.pb_rmul, 0.0, inf, True, "", "bond radius multiplier > 0")
        _check("pb_mcf", self.pb_mcf, 0.0, 1.0, False, "", "moment-contribution factor in [0, 1]")
        _check("dp_nratio", self.dp_nratio, 0.0, 1.0, False, "", "critical-damping ratio in [0, 1]")
        _check("dp_sratio", self.dp_sratio, 0.0, 1.0, False, "", "critical-damping ratio in [0, 1]")

    def replace(self, **kw) -> Material:
        d = asdict(self)
        unknown = set(kw) - {f.name for f in fields(self)}
        if unknown:
            raise InputError(f"unknown material properties: {sorted(unknown)}")
        d.update(kw)
        return Material(**d)

    def to_dict(self) -> dict:
        return asdict(self)
