"""What every quasi-static lab test records the same way: the engine's energy terms in its
time series, its crack counts by mode, and its crack events timed from the start of the
loading; the lateral gauge of a cylinder. Shared by the UCS, triaxial, Brazilian and
direct-tension tests."""
from __future__ import annotations

import numpy as np

from ..dem.errors import InputError

#: energy terms of a test's series: state energies as they are, dissipated ones counted
#: from the start of the loading (``e0``)
ENERGY_TERMS = ("kinetic", "strain_linear", "strain_bond", "slip", "damping", "dashpot",
                "released")
_SINCE_START = ("slip", "damping", "dashpot", "released")


def append_energies(ser: dict, e: dict, e0: dict) -> None:
    """Append the energy terms of ``e`` (``Model.energies()``) to the series ``ser``, the
    dissipated ones relative to ``e0`` (the energies when the loading started)."""
    for k in ENERGY_TERMS:
        ser[k].append(e[k] - e0[k] if k in _SINCE_START else e[k])


def append_cracks(ser: dict, m) -> None:
    """Append the counts of cracks in tension and in shear of model ``m``
    (``Model.crack_counts``: broken parallel bonds, or broken flat-joint elements)."""
    nt, ns = m.crack_counts()
    ser["cracks_tension"].append(nt)
    ser["cracks_shear"].append(ns)


def loading_cracks(m, step0: int, dt: float) -> dict:
    """``Model.breaks()`` with steps and times counted from ``step0``, the start of the
    loading (a crack of the genesis has a negative step)."""
    ev = m.breaks()
    ev["step"] = ev["step"] - step0
    ev["time"] = ev["step"] * dt
    return ev


class LateralGauge:
    """The lateral gauge of a cylinder (the UCS and triaxial tests): the surface balls
    (``sp.surface``, those that touched the lateral vessel wall at the end of genesis)
    whose centres lie within ``band`` (fractions of the height ``H0`` above ``z_base``) in
    the positions ``pos0`` at the start of the test; ``strain(pos)``: their mean radial
    displacement over ``R0``, compression positive (expansion negative)."""

    def __init__(self, sp, pos0, z_base: float, H0: float, band, R0: float):
        z0 = pos0[sp.surface, 2]
        sel = (z0 >= z_base + band[0] * H0) & (z0 <= z_base + band[1] * H0)
        self.balls = sp.surface[sel]
        if self.balls.size < 3:
            raise InputError(f"only {self.balls.size} surface balls in the lateral strain "
                             "band: the specimen is too small for a lateral strain measurement")
        self.rho0 = np.hypot(pos0[self.balls, 0], pos0[self.balls, 1])
        self.R0 = R0

    def strain(self, pos) -> float:
        rho = np.hypot(pos[self.balls, 0], pos[self.balls, 1])
        return -float((rho - self.rho0).mean()) / self.R0
