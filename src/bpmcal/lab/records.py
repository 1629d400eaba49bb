"""What every quasi-static lab test records the same way: the engine's energy terms in its
time series, its crack counts by mode, and its crack events timed from the start of the
loading. Shared by the UCS, triaxial, Brazilian and direct-tension tests."""
from __future__ import annotations

import numpy as np

from ..dem.layout import BOND_SHEAR, BOND_TENSION

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


def append_cracks(ser: dict, states) -> None:
    """Append the counts of bonds broken in tension and in shear (``Model.bond_states``)."""
    ser["cracks_tension"].append(int(np.count_nonzero(states == BOND_TENSION)))
    ser["cracks_shear"].append(int(np.count_nonzero(states == BOND_SHEAR)))


def loading_cracks(m, step0: int, dt: float) -> dict:
    """``Model.breaks()`` with steps and times counted from ``step0``, the start of the
    loading (a crack of the genesis has a negative step)."""
    ev = m.breaks()
    ev["step"] = ev["step"] - step0
    ev["time"] = ev["step"] * dt
    return ev
