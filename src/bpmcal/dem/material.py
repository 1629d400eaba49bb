"""Material properties of the two contact models, SI: the linear + linear-parallel-bond
model (PFC ``linearpbond``, :class:`Material`) and the flat-joint model (PFC
``flatjoint``, :class:`FlatJointMaterial`).

Names follow PFC's properties: ``emod`` (E*), ``kratio`` (kappa*), ``fric`` (mu),
``pb_emod`` (E-bar), ``pb_kratio`` (kappa-bar), ``pb_ten`` (sigma-bar_c), ``pb_coh``
(c-bar), ``pb_fa`` (phi-bar, degrees), ``pb_rmul`` (lambda-bar), ``pb_mcf`` (beta-bar),
``dp_nratio``/``dp_sratio`` (dashpot critical-damping ratios); ``fj_emod``,
``fj_kratio``, ``fj_ten``, ``fj_coh``, ``fj_fa``, ``fj_fric``, ``fj_rmul``, ``fj_nr``,
``fj_nal`` for the flat joint.

Strength scatter (PFC's material-modeling package, fistPkg: ``pbm_ten_sd``,
``pbm_coh_sd``, ``fjm_ten_sd``, ``fjm_coh_sd``): ``pb_ten_sd``, ``pb_coh_sd``,
``fj_ten_sd``, ``fj_coh_sd`` are the standard deviations of the per-contact strengths,
whose means are ``pb_ten`` ... ``fj_coh``. The engine keeps one tensile strength and one
cohesion per contact (``Model.set_bond_strengths``), set to the means at installation;
the lab draws the scatter (``lab.microstructure.install_strength_scatter``). Default 0.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import ClassVar

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

    contact_model: ClassVar[str] = "linearpbond"
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
    pb_ten_sd: float = 0.0  # standard deviation of the per-bond pb_ten [Pa]
    pb_coh_sd: float = 0.0  # standard deviation of the per-bond pb_coh [Pa]

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
        _check("pb_ten_sd", self.pb_ten_sd, 0.0, inf, False, " Pa",
               "standard deviation of the tensile strength >= 0")
        _check("pb_coh_sd", self.pb_coh_sd, 0.0, inf, False, " Pa",
               "standard deviation of the cohesion >= 0")
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

    def strengths(self) -> tuple[float, float, float, float]:
        """(tensile mean, its sd, cohesion mean, its sd) of the per-contact strengths [Pa]."""
        return (float(self.pb_ten), float(self.pb_ten_sd), float(self.pb_coh),
                float(self.pb_coh_sd))

    def springs(self) -> tuple:
        """(modulus name, ratio name, what, radius multiplier) of each spring set: the
        linear contacts and the parallel bonds."""
        return (("emod", "kratio", "linear contacts", 1.0),
                ("pb_emod", "pb_kratio", "parallel bonds", self.pb_rmul))


def _count(name: str, value, lo: int, hi: int, what: str) -> int:
    """An element count: an integer in [lo, hi] (a float with an integer value is
    accepted, 1.5 or True is not)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            (isinstance(value, float) and not value.is_integer()):
        raise InputError(f"{name}={value!r}: expected an integer in [{lo}, {hi}] ({what})")
    v = int(value)
    if not lo <= v <= hi:
        raise InputError(f"{name}={v}: out of its domain [{lo}, {hi}] ({what})")
    return v


@dataclass(frozen=True)
class FlatJointMaterial:
    """Flat-joint material (PFC ``flatjoint``), SI units (Pa, degrees for fj_fa).

    The flat joints are installed by :meth:`bpmcal.dem.Model.bond`; the pairs that come
    into contact later and the ball-wall contacts are linear contacts with ``emod``,
    ``kratio`` and ``fric`` (by default the flat joint's own ``fj_emod``, ``fj_kratio``
    and ``fj_fric``). Strengths are those of the bonded elements (``fj_ten``, ``fj_coh``,
    ``fj_fa``); unbonded elements carry no tension and slip at ``fj_fric``. Element
    shear force is removed when an element breaks (PFC residual mode 0)."""

    contact_model: ClassVar[str] = "flatjoint"

    fj_emod: float  # E* of the interface [Pa]
    fj_kratio: float  # kappa* = kn/ks [-]
    fj_ten: float  # tensile strength of bonded elements [Pa]
    fj_coh: float  # cohesion of bonded elements [Pa]
    fj_fa: float  # local friction angle of bonded elements [deg]
    fj_fric: float  # friction coefficient of unbonded elements [-]
    fj_rmul: float = 1.0  # radius multiplier lambda [-]
    fj_nr: int = 1  # elements in the radial direction [-]
    fj_nal: int = 3  # elements in the circumferential direction [-]
    emod: float | None = None  # linear contacts: E* (default fj_emod) [Pa]
    kratio: float | None = None  # linear contacts: kappa* (default fj_kratio) [-]
    fric: float | None = None  # linear contacts: friction (default fj_fric) [-]
    dp_nratio: float = 0.0
    dp_sratio: float = 0.0
    fj_ten_sd: float = 0.0  # standard deviation of the per-joint fj_ten [Pa]
    fj_coh_sd: float = 0.0  # standard deviation of the per-joint fj_coh [Pa]

    def __post_init__(self):
        inf = math.inf
        for lin, fj in (("emod", "fj_emod"), ("kratio", "fj_kratio"), ("fric", "fj_fric")):
            if getattr(self, lin) is None:
                object.__setattr__(self, lin, getattr(self, fj))
        _check("fj_emod", self.fj_emod, 0.0, inf, True, " Pa", "effective modulus > 0")
        _check("fj_kratio", self.fj_kratio, 0.0, inf, True, "", "stiffness ratio kn/ks > 0")
        _check("fj_ten", self.fj_ten, 0.0, inf, False, " Pa", "tensile strength >= 0")
        _check("fj_coh", self.fj_coh, 0.0, inf, False, " Pa", "cohesion >= 0")
        if isinstance(self.fj_fa, (int, float)) and float(self.fj_fa) >= 90.0:
            raise InputError(f"fj_fa={self.fj_fa:g} deg: out of its physical domain [0, 90) "
                             "(friction angle in degrees)")
        _check("fj_fa", self.fj_fa, 0.0, 90.0, False, " deg", "friction angle in [0, 90)")
        _check("fj_fric", self.fj_fric, 0.0, inf, False, "", "friction coefficient >= 0")
        _check("fj_rmul", self.fj_rmul, 0.0, inf, True, "", "radius multiplier > 0")
        object.__setattr__(self, "fj_nr", _count("fj_nr", self.fj_nr, 1, 16,
                                                 "elements in the radial direction"))
        object.__setattr__(self, "fj_nal", _count("fj_nal", self.fj_nal, 1, 32,
                                                  "elements in the circumferential direction"))
        _check("emod", self.emod, 0.0, inf, True, " Pa", "linear effective modulus > 0")
        _check("kratio", self.kratio, 0.0, inf, True, "", "linear stiffness ratio > 0")
        _check("fric", self.fric, 0.0, inf, False, "", "linear friction coefficient >= 0")
        _check("fj_ten_sd", self.fj_ten_sd, 0.0, inf, False, " Pa",
               "standard deviation of the tensile strength >= 0")
        _check("fj_coh_sd", self.fj_coh_sd, 0.0, inf, False, " Pa",
               "standard deviation of the cohesion >= 0")
        _check("dp_nratio", self.dp_nratio, 0.0, 1.0, False, "", "critical-damping ratio in [0, 1]")
        _check("dp_sratio", self.dp_sratio, 0.0, 1.0, False, "", "critical-damping ratio in [0, 1]")

    @property
    def n_elements(self) -> int:
        return self.fj_nr * self.fj_nal

    def replace(self, **kw) -> FlatJointMaterial:
        d = asdict(self)
        unknown = set(kw) - {f.name for f in fields(self)}
        if unknown:
            raise InputError(f"unknown material properties: {sorted(unknown)}")
        d.update(kw)
        return FlatJointMaterial(**d)

    def to_dict(self) -> dict:
        return asdict(self)

    def strengths(self) -> tuple[float, float, float, float]:
        """(tensile mean, its sd, cohesion mean, its sd) of the per-contact strengths [Pa]."""
        return (float(self.fj_ten), float(self.fj_ten_sd), float(self.fj_coh),
                float(self.fj_coh_sd))

    def springs(self) -> tuple:
        """(modulus name, ratio name, what, radius multiplier) of each spring set: the
        linear contacts and the flat joints."""
        return (("emod", "kratio", "linear contacts", 1.0),
                ("fj_emod", "fj_kratio", "flat joints", self.fj_rmul))


#: either contact model's material
MATERIALS = (Material, FlatJointMaterial)


def stiffest_modulus(material) -> float:
    """The largest effective modulus of a material's springs [Pa] (wave speed, guards)."""
    if isinstance(material, FlatJointMaterial):
        return max(float(material.emod), float(material.fj_emod))
    return max(float(material.emod), float(material.pb_emod))


def stiffest_spring(material) -> str:
    """Which of a material's springs is the stiffest (it sets the critical timestep), named
    by the property that makes it so: the normal springs are E* of each part, the shear
    springs E*/kappa* (PFC's deformability method; the same contact area and length scale
    every spring of a contact alike)."""
    cands = []
    for e, k, what, _ in material.springs():
        E = float(getattr(material, e))
        kr = float(getattr(material, k))
        cands.append((E, f"{e} = {E:.4g} Pa (the normal stiffness of the {what})"))
        cands.append((E / kr, f"{k} = {kr:.4g} (the shear stiffness of the {what}, "
                              f"{e}/{k} = {E / kr:.4g} Pa, is {1.0 / kr:.4g} x their normal "
                              "stiffness)"))
    # a tie (a card gives the linear contacts the bond's moduli) names the bond's property:
    # that is the one a card sets
    return max(enumerate(cands), key=lambda c: (c[1][0], c[0]))[1][1]


def expected_failure_strain(material, tension: bool = False) -> float:
    """A scale of the strain at which a bonded specimen of this material fails: its
    bonds' (flat joints') larger strength over their modulus, or with ``tension`` (a
    direct-tension test) their tensile strength over it. Lab tests run to a few times
    this (``lab.budget.check_loading_steps``); only a step estimate uses it."""
    if isinstance(material, FlatJointMaterial):
        ten, coh, emod = material.fj_ten, material.fj_coh, material.fj_emod
    else:
        ten, coh, emod = material.pb_ten, material.pb_coh, material.pb_emod
    return (float(ten) if tension else max(float(ten), float(coh))) / float(emod)
