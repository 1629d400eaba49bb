"""What every quasi-static lab test records the same way: the engine's energy terms in its
time series, its crack counts by mode, and its crack events timed from the start of the
loading. Shared by the UCS, triaxial, Brazilian and direct-tension tests."""
from __future__ import annotations

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
