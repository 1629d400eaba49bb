"""Names, units and ranges of the study's parameters and responses: the one place where
the paper's units (mm, GPa, MPa, degrees) are converted to SI and back.

Meso-parameters use PFC property names with the unit in the name (docs/architecture.md):

======================  =========  ======  ===============  =======================
name                    symbol     unit    Table 2 range    SI factor
======================  =========  ======  ===============  =======================
``rmin_mm``             Rmin       mm      0.6 - 1.0        1e-3  (m)
``porosity``            n          -       0.20 - 0.36      1
``pb_emod_GPa``         Ecp        GPa     10 - 50          1e9   (Pa)
``pb_kratio``           kp*        -       1 - 5            1
``pb_ten_MPa``          sigma_cp   MPa     10 - 50          1e6   (Pa)
``pb_coh_MPa``          tau_cp     MPa     10 - 50          1e6   (Pa)
``pb_fa_deg``           phi_p      deg     15 - 55          1 (degrees kept)
``fric``                mu_p       -       0.15 - 0.55      1
======================  =========  ======  ===============  =======================

Responses: ``ucs_MPa`` (sigma_c), ``E_GPa``, ``nu``, ``peak_strain``, ``u_pre_MJm3``
(pre-peak energy density), ``cracks_tension``, ``cracks_shear``.

This is the one table of names, symbols (``symbol`` plain text for logs and the CLI,
``unicode`` for tables, ``latex`` for figures), units and physical domains: the config
schema's parameter limits are tested against it (``tests/workflow/test_defaults.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Param:
    name: str
    symbol: str  # the paper's symbol (plain text)
    latex: str  # for figures
    unit: str  # the paper's unit ("" for dimensionless)
    si: float  # multiply by this to get SI
    lo: float  # Table 2 range (paper units)
    hi: float
    phys_lo: float  # physical domain (paper units), for input validation
    phys_hi: float
    lo_open: bool = False
    description: str = ""
    hi_open: bool = False
    unicode: str = ""  # the paper's symbol for tables (σcp, ...)


#: The 8 meso-parameters of the LHS design, in the paper's Table 2 order.
PARAMS: dict[str, Param] = {p.name: p for p in [
    Param("rmin_mm", "Rmin", r"$R_\mathrm{min}$", "mm", 1e-3, 0.6, 1.0, 0.0, math.inf, True,
          "minimum ball radius (radii uniform in [Rmin, 1.66 Rmin])", unicode="Rmin"),
    Param("porosity", "n", r"$n$", "", 1.0, 0.20, 0.36, 0.0, 0.9, True,
          "nominal porosity as PFC's ball distribute (summed ball volume = (1-n) V)", unicode="n"),
    Param("pb_emod_GPa", "Ecp", r"$E_c^p$", "GPa", 1e9, 10.0, 50.0, 0.0, math.inf, True,
          "parallel-bond effective modulus (= linear emod)", unicode="Ecp"),
    Param("pb_kratio", "kp*", r"$k_p^*$", "", 1.0, 1.0, 5.0, 0.0, math.inf, True,
          "parallel-bond normal-to-shear stiffness ratio (= linear kratio)", unicode="kp*"),
    Param("pb_ten_MPa", "sigma_cp", r"$\sigma_c^p$", "MPa", 1e6, 10.0, 50.0, 0.0, math.inf,
          False, "parallel-bond tensile strength", unicode="σcp"),
    Param("pb_coh_MPa", "tau_cp", r"$\tau_c^p$", "MPa", 1e6, 10.0, 50.0, 0.0, math.inf, False,
          "parallel-bond cohesion (shear strength at zero normal stress)", unicode="τcp"),
    Param("pb_fa_deg", "phi_p", r"$\varphi_p$", "deg", 1.0, 15.0, 55.0, 0.0, 90.0, False,
          "parallel-bond friction angle", hi_open=True, unicode="φp"),
    Param("fric", "mu_p", r"$\mu_p$", "", 1.0, 0.15, 0.55, 0.0, math.inf, False,
          "ball-ball friction coefficient", unicode="μp"),
]}

PARAM_NAMES: tuple[str, ...] = tuple(PARAMS)


def table2_ranges() -> dict[str, tuple[float, float]]:
    """The paper's Table 2 sampling ranges (paper units): the design space of the default
    study. Calibration bounds come from a study's own ``ranges``, never from these."""
    return {p.name: (p.lo, p.hi) for p in PARAMS.values()}


@dataclass(frozen=True)
class Response:
    name: str
    symbol: str
    latex: str
    unit: str
    si: float
    description: str
    unicode: str = ""  # the paper's symbol for tables


RESPONSES: dict[str, Response] = {r.name: r for r in [
    Response("ucs_MPa", "sigma_c", r"$\sigma_c$", "MPa", 1e6, "peak axial stress (UCS)", "σc"),
    Response("E_GPa", "E", r"$E$", "GPa", 1e9, "Young's modulus (fit over 40-60 % of peak)", "E"),
    Response("nu", "nu", r"$\nu$", "", 1.0, "Poisson's ratio (fit over 40-60 % of peak)", "ν"),
    Response("peak_strain", "eps_p", r"$\varepsilon_p$", "", 1.0, "axial strain at peak", "εp"),
    Response("u_pre_MJm3", "Up", r"$U_p$", "MJ/m3", 1e6, "pre-peak energy density", "Up"),
    Response("cracks_tension", "Nt", r"$N_t$", "", 1.0, "tensile cracks", "Nt"),
    Response("cracks_shear", "Ns", r"$N_s$", "", 1.0, "shear cracks", "Ns"),
    Response("bts_MPa", "sigma_t", r"$\sigma_t$", "MPa", 1e6,
             "Brazilian tensile strength 2 P_peak / (pi D t)", "σt"),
    Response("dtt_MPa", "sigma_t,d", r"$\sigma_{t,d}$", "MPa", 1e6,
             "direct-tension strength: peak grip force / cross-section", "σt,d"),
]}

#: Responses the paper calibrates against.
TARGETS: tuple[str, ...] = ("ucs_MPa", "E_GPa", "nu")

#: The Brazilian tensile strength of every design sample (the study's ``bts`` job), a
#: column of the dataset when the study runs the Brazilian test.
TENSILE = "bts_MPa"

#: The tensile tests a study can run on every design sample: response -> test (the
#: Brazilian test, ``bts``, and the direct-tension test, ``dtt``). Each is a column of
#: the dataset with its own ``<test>_status`` when the study runs it, is screened and
#: regressed on its own rows, and is a calibration target where the lab gives it.
TENSILE_TESTS: dict[str, str] = {"bts_MPa": "bts", "dtt_MPa": "dtt"}

#: Responses the study screens (Table 3) and regresses (Table 4, models.json): the
#: calibration targets, and the tensile strengths the dataset has.
ANALYSED: tuple[str, ...] = (*TARGETS, *TENSILE_TESTS)

#: Fixed by the paper (section 2.2).
RADIUS_RATIO = 1.66  # Rmax / Rmin
DENSITY = 2294.0  # kg/m^3
PB_RMUL = 1.0  # lambda_p


class ParameterError(ValueError):
    """A parameter is missing, unknown or outside its domain/range."""


def to_si(name: str, value: float) -> float:
    """Paper units -> SI for a parameter or response name."""
    if name in PARAMS:
        return float(value) * PARAMS[name].si
    if name in RESPONSES:
        return float(value) * RESPONSES[name].si
    raise ParameterError(f"unknown quantity {name!r}")


def from_si(name: str, value: float) -> float:
    """SI -> paper units."""
    if name in PARAMS:
        return float(value) / PARAMS[name].si
    if name in RESPONSES:
        return float(value) / RESPONSES[name].si
    raise ParameterError(f"unknown quantity {name!r}")


def as_number(v, name: str, expected: str = "a number", error=None) -> float:
    """``v`` as a finite float; booleans (YAML ``true``), strings, None and NaN/inf raise
    ``error`` (default :class:`ParameterError`) naming the value and what was expected."""
    error = error or ParameterError
    if type(v).__module__ == "numpy" and hasattr(v, "item"):
        v = v.item()  # numpy scalar -> Python (plain repr in messages)
    if isinstance(v, bool) or v is None or isinstance(v, (str, bytes)):
        raise error(f"{name}={v!r}: expected {expected}, got "
                    f"{'a boolean' if isinstance(v, bool) else type(v).__name__}")
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise error(f"{name}={v!r}: expected {expected}") from None
    if not math.isfinite(x):
        raise error(f"{name}={v!r}: expected a finite number ({expected})")
    return x


def validate_params(values: dict, *, require_all: bool = True, within_table2: bool = False
                    ) -> dict[str, float]:
    """Check a dict of meso-parameters (paper units). Returns floats.

    Unknown names, missing names (``require_all``), non-numbers and values outside the
    physical domain raise :class:`ParameterError` naming the value and what is expected;
    ``within_table2`` additionally requires the Table 2 ranges.
    """
    unknown = sorted(set(values) - set(PARAMS))
    if unknown:
        raise ParameterError(f"unknown parameter(s) {unknown}; expected names from {list(PARAMS)}")
    if require_all:
        missing = [p for p in PARAMS if p not in values]
        if missing:
            raise ParameterError(f"missing parameter(s) {missing}")
    out = {}
    for k, v in values.items():
        p = PARAMS[k]
        x = as_number(v, k, f"a number in {p.unit}" if p.unit else "a dimensionless number",
                      ParameterError)
        unit = f" {p.unit}" if p.unit else ""
        bad_lo = x <= p.phys_lo if p.lo_open else x < p.phys_lo
        bad_hi = x >= p.phys_hi if p.hi_open else x > p.phys_hi
        if bad_lo or bad_hi:
            b = "(" if p.lo_open else "["
            e = ")" if p.hi_open else "]"
            raise ParameterError(f"{k}={x:g}{unit} is outside its physical domain "
                                 f"{b}{p.phys_lo:g}, {p.phys_hi:g}{e} ({p.description})")
        if within_table2 and not (p.lo <= x <= p.hi):
            raise ParameterError(f"{k}={x:g}{unit} is outside the Table 2 range "
                                 f"[{p.lo:g}, {p.hi:g}]{unit}")
        out[k] = x
    return out
