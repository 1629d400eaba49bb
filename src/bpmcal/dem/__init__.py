"""bpmcal.dem: bonded-sphere DEM engine with PFC3D's linear, linear-parallel-bond and
flat-joint semantics.

Layers (numba kernels below ``model``):

- ``laws`` (one contact) and ``motion`` (one ball): the physics, as small inlined functions;
  ``flatjoint``: the flat joint's law (one interface of elements) and its loop over the
  flat-jointed pairs;
- ``kernels``: laws mapped over pairs and wall slots, integration, the chunk runner
  (``bondblock`` holds the vectorised bond pairs); ``neighbors``: Verlet lists and
  ball-wall slots; ``diagnostics``: energies, critical timestep, unbalanced force;
- ``model``: the Python driver (state, walls, bonds, measurements) and the public API.

The contact laws are documented in ``docs/contact_laws.md``; the stepping scheme in the
header of ``kernels.py``.
"""
from .errors import InputError, InstabilityError
from .material import FlatJointMaterial, Material
from .model import ENERGY_TERMS, Model
from .slots import (
    BOND_INTACT,
    BOND_SHEAR,
    BOND_TENSION,
    FIX_ALL,
    FIX_VX,
    FIX_VY,
    FIX_VZ,
    FIX_WX,
    FIX_WY,
    FIX_WZ,
)

__all__ = ["Model", "Material", "FlatJointMaterial", "InputError", "InstabilityError", "ENERGY_TERMS",
           "FIX_ALL", "FIX_VX", "FIX_VY", "FIX_VZ", "FIX_WX", "FIX_WY", "FIX_WZ",
           "BOND_INTACT", "BOND_TENSION", "BOND_SHEAR"]
