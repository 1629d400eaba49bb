"""The structure-of-arrays records that ``Model`` owns, and the small array helpers that
``model.py`` and its mixins (``model_walls``, ``model_bonds``, ``model_measure``) share.

Each record is a namedtuple of numpy arrays, passed as is to the numba kernels: ``Balls``
(one row per ball), ``Pairs`` (the neighbour list, bond pairs first), ``Bonds`` (the
parallel bonds, their blocked state in ``blk``: ``bondblock``), ``Slots`` (ball-wall
contacts), ``Walls`` and ``FlatJoints`` (the flat joints' state, when the installed
pairs are flat joints rather than parallel bonds). ``Model`` allocates and grows them;
nothing here runs a step.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from .errors import InputError

Balls = namedtuple("Balls", "pos vel angvel force moment radius mass inertia fix pos_ref "
                   "edamp egrav efix fbuf pmask")
Pairs = namedtuple("Pairs", "pi pj fs df act slip dash estr vptr pi2 pj2 fs2 vptr2 cand part")
Bonds = namedtuple("Bonds", "blk state step pos nrm energy estr sig ptr part")
Slots = namedtuple("Slots", "b w fs df rg f m rad slip dash estr ptr b2 w2 fs2 ptr2")
Walls = namedtuple("Walls", "type pos nrm rad disk vel radv fric mass force radsum work "
                   "grav disp")
#: flat joints (``flatjoint.py``): per contact ``c`` (floats, C_*), ``flag`` (K_*); per
#: element state ``es``, shear force ``ef`` (s, t), slip flag ``eslip``; the element
#: table ``geo``; per element break records (``estep``: -1 intact, ``epos``, ``enrm``,
#: ``esig`` (sigma, tau), ``een`` released energy); ``prm`` the law's parameters
FlatJoints = namedtuple("FlatJoints", "c flag es ef eslip geo estep epos enrm esig een prm")

#: type of the ball indices in the pair and wall-slot lists: unsigned, so that numba
#: emits no negative-index wraparound code where the kernels index ball arrays with them
#: (the public methods return int32 copies)
IDX = np.uint32


def aligned_zeros(shape, align=64):
    """Zeroed float64 array whose data start on an ``align``-byte boundary (so that the
    8-float rows of the force buffers each fill exactly one cache line)."""
    n = int(np.prod(shape))
    raw = np.zeros(n + align // 8)
    off = (-raw.ctypes.data % align) // 8
    return raw[off:off + n].reshape(shape)


def readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of an engine array (no copy; reflects later steps)."""
    v = a.view()
    v.flags.writeable = False
    return v


def vec3(name, v):
    """``v`` as three finite floats (an InputError naming ``name`` otherwise)."""
    a = np.asarray(v, dtype=float).reshape(-1)
    # math.isfinite on the three floats: a third of np.isfinite's cost (a servo sets a
    # wall's velocity every step)
    if a.shape != (3,) or not all(map(math.isfinite, a.tolist())):
        raise InputError(f"{name}={v!r}: expected three finite numbers")
    return a
