"""bpmcal.dem: bonded-sphere DEM engine with PFC3D's linear + linear-parallel-bond semantics.

Layers: ``laws`` (one contact), ``kernels`` (laws mapped over pairs, integration, neighbour
search; numba), ``model`` (Python driver: state, walls, bonds, energies). See
../shared/PBM.md for the contact laws and kernels.py for the stepping scheme.
"""
from .errors import InputError, InstabilityError
from .layout import BOND_INTACT, BOND_SHEAR, BOND_TENSION, FIX_ALL
from .material import Material
from .model import ENERGY_TERMS, Model

__all__ = ["Model", "Material", "InputError", "InstabilityError", "ENERGY_TERMS",
           "FIX_ALL", "BOND_INTACT", "BOND_TENSION", "BOND_SHEAR"]
