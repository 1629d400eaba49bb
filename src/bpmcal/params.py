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
import numbers
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

#: The strength scatter of the parallel bond (PFC's material-modeling package, fistPkg:
#: ``pbm_ten_sd``, ``pbm_coh_sd``): the standard deviations of the per-contact tensile
#: strength ``pb_ten`` and cohesion ``pb_coh``, whose means are ``pb_ten_MPa`` and
#: ``pb_coh_MPa``. Each bond draws its own pair at installation from a Gaussian truncated
#: at zero (``lab.microstructure.install_strength_scatter``). Optional keys, default 0 (every
#: bond at the mean, as the paper); not Table 2 parameters.
PB_SCATTER: dict[str, Param] = {p.name: p for p in [
    Param("pb_ten_sd_MPa", "sd(sigma_cp)", r"$s(\sigma_c^p)$", "MPa", 1e6, 0.0, 0.0, 0.0,
          math.inf, False, "standard deviation of the per-bond tensile strength pb_ten",
          unicode="sd(σcp)"),
    Param("pb_coh_sd_MPa", "sd(tau_cp)", r"$s(\tau_c^p)$", "MPa", 1e6, 0.0, 0.0, 0.0,
          math.inf, False, "standard deviation of the per-bond cohesion pb_coh",
          unicode="sd(τcp)"),
]}
#: defaults of the parallel bond's optional keys: no scatter
PB_DEFAULTS: dict[str, float] = {"pb_ten_sd_MPa": 0.0, "pb_coh_sd_MPa": 0.0}

#: The ball parameters every contact model shares.
BALL_PARAMS: tuple[str, ...] = ("rmin_mm", "porosity")
#: ... by name: the smallest ball radius and the porosity of the packing
RMIN, POROSITY = BALL_PARAMS

#: The flat-joint card (PFC ``flatjoint``, docs/contact_laws.md): the interface's
#: deformability and strength, its discretisation, and the flat-jointed material's
#: microstructure (docs/flatjoint-spec.md §6). ``lo``/``hi`` are starting design ranges, not Table 2.
FJ_PARAMS: dict[str, Param] = {p.name: p for p in [
    Param("fj_emod_GPa", "Ec", r"$E_c$", "GPa", 1e9, 20.0, 120.0, 0.0, math.inf, True,
          "flat-joint effective modulus (= linear emod at walls and new contacts)",
          unicode="E*"),
    Param("fj_kratio", "k*", r"$k^*$", "", 1.0, 1.0, 4.0, 0.0, math.inf, True,
          "flat-joint normal-to-shear stiffness ratio", unicode="κ*"),
    Param("fj_ten_MPa", "sigma_b", r"$\sigma_b$", "MPa", 1e6, 5.0, 60.0, 0.0, math.inf, False,
          "tensile strength of bonded elements", unicode="σb"),
    Param("fj_coh_MPa", "c_b", r"$c_b$", "MPa", 1e6, 20.0, 300.0, 0.0, math.inf, False,
          "cohesion of bonded elements", unicode="cb"),
    Param("fj_fa_deg", "phi_b", r"$\varphi_b$", "deg", 1.0, 0.0, 50.0, 0.0, 90.0, False,
          "local friction angle of bonded elements", hi_open=True, unicode="φb"),
    Param("fj_fric", "mu", r"$\mu$", "", 1.0, 0.3, 0.9, 0.0, math.inf, False,
          "friction coefficient of unbonded elements (and of linear contacts)", unicode="μ"),
    Param("fj_rmul", "lambda", r"$\lambda$", "", 1.0, 1.0, 1.0, 0.0, math.inf, True,
          "interface radius multiplier", unicode="λ"),
    Param("fj_nr", "N_r", r"$N_r$", "", 1.0, 1.0, 1.0, 1.0, 16.0, False,
          "elements in the radial direction (integer)", unicode="Nr"),
    Param("fj_nal", "N_al", r"$N_\alpha$", "", 1.0, 3.0, 3.0, 1.0, 32.0, False,
          "elements in the circumferential direction (integer)", unicode="Nα"),
    Param("fj_gi_ratio", "g_i", r"$g_i/\bar R$", "", 1.0, 0.0, 0.5, 0.0, 5.0, False,
          "installation gap over the mean ball radius", unicode="gi/R̄"),
    Param("fj_slit_frac", "phi_S", r"$\phi_S$", "", 1.0, 0.0, 0.5, 0.0, 1.0, False,
          "fraction of slit (unbonded, closed) flat joints", unicode="φS"),
    Param("fj_gap_frac", "phi_G", r"$\phi_G$", "", 1.0, 0.0, 0.5, 0.0, 1.0, False,
          "fraction of gapped (unbonded, open) flat joints", unicode="φG"),
    Param("fj_gap0_ratio", "g_0", r"$g_0/\bar R$", "", 1.0, 0.0, 0.1, 0.0, 5.0, False,
          "initial gap of gapped flat joints over the mean ball radius", unicode="g0/R̄"),
    # the strength scatter (fistPkg's fjm_ten_sd, fjm_coh_sd): per flat joint, shared by
    # its elements, as PFC's fj_ten / fj_coh are contact properties (PB_SCATTER)
    Param("fj_ten_sd_MPa", "sd(sigma_b)", r"$s(\sigma_b)$", "MPa", 1e6, 0.0, 0.0, 0.0,
          math.inf, False, "standard deviation of the per-joint tensile strength fj_ten",
          unicode="sd(σb)"),
    Param("fj_coh_sd_MPa", "sd(c_b)", r"$s(c_b)$", "MPa", 1e6, 0.0, 0.0, 0.0, math.inf,
          False, "standard deviation of the per-joint cohesion fj_coh", unicode="sd(cb)"),
]}

#: defaults of the flat-joint card's optional keys (PFC's usual 3D choices, docs/flatjoint-spec.md §5-6)
FJ_DEFAULTS: dict[str, float] = {"fj_rmul": 1.0, "fj_nr": 1.0, "fj_nal": 3.0,
                                 "fj_gi_ratio": 0.0, "fj_slit_frac": 0.0, "fj_gap_frac": 0.0,
                                 "fj_gap0_ratio": 0.0, "fj_ten_sd_MPa": 0.0,
                                 "fj_coh_sd_MPa": 0.0}
#: integer-valued flat-joint parameters (element counts)
FJ_INTEGERS: tuple[str, ...] = ("fj_nr", "fj_nal")
#: the parallel bond's radius multiplier, fixed by the paper (section 2.2: lambda_p = 1)
PB_RMUL = 1.0

@dataclass(frozen=True)
class ContactModel:
    """A contact model's card, as the study sees it: the one declaration the design,
    screening, regression, calibration, ratio sweep, schema checks, CLI help and report
    read (issue 27's registry; :data:`CONTACT_MODELS`).

    ``params``: every card parameter (ball parameters first), name -> :class:`Param`
    (unit, physical domain, default design range ``lo``/``hi``); ``strength``: the
    (tensile, cohesion) pair whose ratio a calibration may fix or free, or None;
    ``ratio_symbol``: that ratio as the tables write it; ``integers``: parameters that
    take integer values (element counts); ``defaults``: values of optional keys;
    ``free``: the parameters a calibration frees by default (the paper's method, with
    the tensile strength derived through the ratio); ``title``: the model in words;
    ``ratio_advice``: what to try when a target σc/σt lies ``"above"`` or ``"below"``
    what this model's cards reach (the calibration's ``no-exact-fit`` message adds it);
    ``quiet``: optional keys that cards, designs and run files leave out while they are at
    their defaults (the strength scatter: a study without it writes what it wrote before
    the keys existed; absent means the default).

    How a card builds its material (``lab.specimen.card_material``): ``material``, card
    parameter -> the engine material fields it sets (``dem.material``: SI units, through
    :func:`to_si`; an integer parameter as an integer); ``material_fixed``, engine fields
    the model fixes; ``microstructure``, card parameter -> field of the flat-jointed
    microstructure (``lab.microstructure.Microstructure``), empty for a model without one.
    """

    name: str
    title: str
    params: dict[str, Param]
    strength: tuple[str, str] | None
    ratio_symbol: str
    free: tuple[str, ...]
    integers: tuple[str, ...] = ()
    defaults: dict[str, float] | None = None
    ratio_advice: dict[str, str] | None = None
    material: dict[str, tuple[str, ...]] | None = None
    material_fixed: dict[str, float] | None = None
    microstructure: dict[str, str] | None = None
    quiet: tuple[str, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.params)

    @property
    def ten(self) -> str | None:
        """The tensile strength of the strength pair (the derived one under a ratio)."""
        return self.strength[0] if self.strength else None

    @property
    def coh(self) -> str | None:
        """The cohesion of the strength pair."""
        return self.strength[1] if self.strength else None

    def tensile_free(self, free=None, fixed=()) -> tuple[str, ...]:
        """The parameters a calibration against a tensile target frees: ``free`` (else
        the model's default) with the tensile strength beside them, since σt then sets
        the strength ratio; unchanged when ``fixed`` holds the tensile strength (σt a
        plain target) or the model has no strength pair."""
        base = tuple(free) if free is not None else self.free
        if self.ten is None or self.ten in fixed or self.ten in base:
            return base
        return base + (self.ten,)

    def design_ranges(self) -> dict[str, tuple[float, float]]:
        """The default design ranges (paper units): Table 2 for the parallel bond."""
        return {p.name: (p.lo, p.hi) for p in self.params.values()}

    def is_integer(self, name: str) -> bool:
        return name in self.integers


LINEARPBOND = ContactModel(
    "linearpbond", "linear parallel bond", {**PARAMS, **PB_SCATTER}, ("pb_ten_MPa", "pb_coh_MPa"),
    "σcp/τcp", ("pb_emod_GPa", "pb_kratio", "pb_coh_MPa"), defaults=PB_DEFAULTS,
    ratio_advice={
        "above": "a σc/σt this high is beyond bonded spheres with parallel bonds (their "
                 "known limit, for which PFC's flat joint was made): try "
                 "`contact_model: flatjoint`",
        "below": "a lower σc/σt needs a higher tensile strength against the cohesion: "
                 "widen the range of pb_ten_MPa upwards (or of pb_coh_MPa downwards)"},
    # the paper's set: the linear part shares the bond's modulus and stiffness ratio
    material={"pb_emod_GPa": ("emod", "pb_emod"), "pb_kratio": ("kratio", "pb_kratio"),
              "pb_ten_MPa": ("pb_ten",), "pb_coh_MPa": ("pb_coh",), "pb_fa_deg": ("pb_fa",),
              "fric": ("fric",), "pb_ten_sd_MPa": ("pb_ten_sd",),
              "pb_coh_sd_MPa": ("pb_coh_sd",)},
    material_fixed={"pb_rmul": PB_RMUL}, quiet=tuple(PB_SCATTER))
FLATJOINT = ContactModel(
    "flatjoint", "flat joint", {**{k: PARAMS[k] for k in BALL_PARAMS}, **FJ_PARAMS},
    ("fj_ten_MPa", "fj_coh_MPa"), "σb/cb", ("fj_emod_GPa", "fj_kratio", "fj_coh_MPa"),
    FJ_INTEGERS, FJ_DEFAULTS,
    ratio_advice={
        "above": "a higher σc/σt needs more interlocking: widen fj_coh_MPa upwards, "
                 "fj_ten_MPa downwards, or free fj_slit_frac",
        "below": "a σc/σt this low is what parallel bonds give more easily: try "
                 "`contact_model: linearpbond`"},
    material={"fj_emod_GPa": ("fj_emod",), "fj_kratio": ("fj_kratio",),
              "fj_ten_MPa": ("fj_ten",), "fj_coh_MPa": ("fj_coh",), "fj_fa_deg": ("fj_fa",),
              "fj_fric": ("fj_fric",), "fj_rmul": ("fj_rmul",), "fj_nr": ("fj_nr",),
              "fj_nal": ("fj_nal",), "fj_ten_sd_MPa": ("fj_ten_sd",),
              "fj_coh_sd_MPa": ("fj_coh_sd",)},
    microstructure={"fj_gi_ratio": "gi_ratio", "fj_slit_frac": "slit_frac",
                    "fj_gap_frac": "gap_frac", "fj_gap0_ratio": "gap0_ratio"},
    quiet=("fj_ten_sd_MPa", "fj_coh_sd_MPa"))

#: contact models by PFC name: their cards (:class:`ContactModel`)
MODELS: dict[str, ContactModel] = {m.name: m for m in (LINEARPBOND, FLATJOINT)}
#: contact models by PFC name: the parameters of their cards
CONTACT_MODELS: dict[str, dict[str, Param]] = {k: m.params for k, m in MODELS.items()}

# ---------------------------------------------------------------- the closed loop's budget
#: ``max_rounds`` of a loop that sizes its budget by its free parameters (:func:`auto_rounds`)
AUTO_ROUNDS = "auto"
#: rounds per free parameter of ``max_rounds="auto"``
ROUNDS_PER_FREE = 2


def auto_rounds(n_free: int) -> int:
    """The round budget of a loop with ``n_free`` free parameters: ``ROUNDS_PER_FREE``
    per parameter. A secant (Broyden) method learns the Jacobian one step direction at a
    time; on a linear system it solves within 2n steps (Gay 1979, SIAM J. Numer. Anal.
    16, 623-630). The loop's steps are damped, capped and noisy, so this is a scale, not
    a guarantee: the paper's three free parameters keep its 6 rounds, four (both
    strengths free under a σt target) get 8, five 10 (docs/calibration.md, "The round
    budget", says what was measured; :class:`~bpmcal.analysis.calibration.ClosedLoop`
    uses it)."""
    if isinstance(n_free, bool) or not isinstance(n_free, numbers.Integral) or n_free < 1:
        raise ValueError(f"n_free={n_free!r}: expected a number of free parameters >= 1")
    return ROUNDS_PER_FREE * int(n_free)


DEFAULT_CONTACT_MODEL = "linearpbond"
#: every parameter of every contact model, name -> Param (the names do not overlap
#: except for the ball parameters, which are the same Param)
ALL_PARAMS: dict[str, Param] = {k: v for m in MODELS.values() for k, v in m.params.items()}


def contact_model(name: str | None = None) -> ContactModel:
    """The registered contact model ``name`` (default: the parallel bond); an unknown
    name raises :class:`ParameterError` naming the choices."""
    if name is None:
        return MODELS[DEFAULT_CONTACT_MODEL]
    if name not in MODELS:
        raise ParameterError(f"contact_model={name!r}: expected one of {', '.join(MODELS)}")
    return MODELS[name]


def model_of(names) -> ContactModel:
    """The contact model of a card, a table's columns or a list of names: the model whose
    own parameter names they use (:func:`card_model`; a dict's ``contact_model`` key is
    honoured; in a list, names that are no parameter - ``sample_id``, responses - are
    ignored)."""
    if isinstance(names, dict):
        return MODELS[card_model(dict(names))]
    return MODELS[card_model(dict.fromkeys((n for n in names if n in ALL_PARAMS), 0.0))]


def card_model(values: dict) -> str:
    """The contact model of a card (its ``contact_model`` key, or the model whose own
    names it uses; parallel bond if neither). A card mixing both models' names, or naming
    one model and using the other's names, raises :class:`ParameterError`."""
    named = values.get("contact_model")
    if named is not None and named not in CONTACT_MODELS:
        raise ParameterError(f"contact_model={named!r}: expected one of "
                             f"{', '.join(CONTACT_MODELS)}")
    pb = sorted(k for k in values if k in LINEARPBOND.params and k not in BALL_PARAMS)
    fj = sorted(k for k in values if k in FJ_PARAMS)
    if pb and fj:
        raise ParameterError(f"mixed card: parallel-bond keys {pb} and flat-joint keys {fj}; "
                             "a card is for one contact model")
    used = "flatjoint" if fj else ("linearpbond" if pb else None)
    if named is not None and used is not None and used != named:
        keys = fj or pb
        raise ParameterError(f"contact_model={named!r}, but the card has {used} keys {keys}")
    return named or used or DEFAULT_CONTACT_MODEL


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
    Response("tri_MPa", "sigma_1,d", r"$\sigma_{1,d}$", "MPa", 1e6,
             "triaxial strength: peak sigma1 at the study's design confinement "
             "(triaxial.design_sigma3_MPa)", "σ1(σ3,d)"),
]}

#: Responses the paper calibrates against.
TARGETS: tuple[str, ...] = ("ucs_MPa", "E_GPa", "nu")

#: The Brazilian tensile strength of every design sample (the study's ``bts`` job), a
#: column of the dataset when the study runs the Brazilian test.
BTS = "bts_MPa"

#: The tensile tests a study can run on every design sample: response -> test (the
#: Brazilian test, ``bts``, and the direct-tension test, ``dtt``). Each is a column of
#: the dataset with its own ``<test>_status`` when the study runs it, is screened and
#: regressed on its own rows, and is a calibration target where the lab gives it.
TENSILE_TESTS: dict[str, str] = {"bts_MPa": "bts", "dtt_MPa": "dtt"}
#: The tensile strengths a card can be calibrated against (Brazilian, direct tension), in
#: the order a card's target is looked for.
TENSILE_RESPONSES: tuple[str, ...] = tuple(TENSILE_TESTS)

#: The triaxial strength of every design sample: the peak axial stress sigma1 of one
#: triaxial test at the study's design confinement (``triaxial.design_sigma3_MPa``), a
#: column of the dataset when the study sets that confinement. With the UCS sigma_c it
#: fixes the curvature of the strength envelope (Hoek-Brown mi), which a card's
#: microstructure (a flat joint's slit fraction) sets.
TRI = "tri_MPa"

#: The strengths among the responses: the peak stress of a test (UCS, Brazilian, direct
#: tension, triaxial at the design confinement). A stronger bond never makes a weaker
#: specimen, so none of them falls when a bond strength of the contact model's strength
#: pair (:attr:`ContactModel.strength`) rises (the closed loop's starting Jacobian holds
#: to it: ``analysis.calibration.closed_loop``).
STRENGTH_RESPONSES: tuple[str, ...] = ("ucs_MPa", *TENSILE_RESPONSES, TRI)

#: Every test a study can run on each design sample besides the UCS test: response ->
#: test (the dataset's ``<test>_status``, ``<test>_error``, ...). Each is screened and
#: regressed on its own rows and is a calibration target where the lab gives it.
SAMPLE_TESTS: dict[str, str] = {**TENSILE_TESTS, TRI: "tri"}

#: Responses the study screens (Table 3) and regresses (Table 4, models.json): the
#: calibration targets, and the per-sample tests' strengths the dataset has.
ANALYSED: tuple[str, ...] = (*TARGETS, *SAMPLE_TESTS)

#: Fixed by the paper (section 2.2).
RADIUS_RATIO = 1.66  # Rmax / Rmin
DENSITY = 2294.0  # kg/m^3


class ParameterError(ValueError):
    """A parameter is missing, unknown or outside its domain/range."""


def to_si(name: str, value: float) -> float:
    """Paper units -> SI for a parameter or response name."""
    if name in ALL_PARAMS:
        return float(value) * ALL_PARAMS[name].si
    if name in RESPONSES:
        return float(value) * RESPONSES[name].si
    raise ParameterError(f"unknown quantity {name!r}")


def from_si(name: str, value: float) -> float:
    """SI -> paper units."""
    if name in ALL_PARAMS:
        return float(value) / ALL_PARAMS[name].si
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
        raise error(f"{name}={_shown(v)}: expected {expected}, got "
                    f"{'a boolean' if isinstance(v, bool) else type(v).__name__}")
    try:
        x = float(v)
    except (TypeError, ValueError, OverflowError):
        raise error(f"{name}={_shown(v)}: expected {expected}") from None
    if not math.isfinite(x):
        raise error(f"{name}={v!r}: expected a finite number ({expected})")
    return x


def _shown(v, limit: int = 60) -> str:
    """``repr(v)`` for a message, cut to ``limit`` characters."""
    r = repr(v)
    return r if len(r) <= limit else f"{r[:limit]}... ({len(r) - limit:,} more characters)"


def validate_params(values: dict, *, require_all: bool = True, within_table2: bool = False
                    ) -> dict[str, float]:
    """Check a dict of meso-parameters (paper units). Returns floats.

    Unknown names, missing names (``require_all``), non-numbers and values outside the
    physical domain raise :class:`ParameterError` naming the value and what is expected;
    ``within_table2`` additionally requires the Table 2 ranges.
    """
    model = card_model(values)
    table = CONTACT_MODELS[model]
    values = {k: v for k, v in values.items() if k != "contact_model"}
    unknown = sorted(set(values) - set(table))
    if unknown:
        raise ParameterError(f"unknown parameter(s) {unknown}; expected names from {list(table)}"
                             + (f" (contact model {model})" if model != DEFAULT_CONTACT_MODEL
                                else ""))
    if require_all:  # the model's optional keys at their defaults
        defaults = MODELS[model].defaults or {}
        values = {**{k: v for k, v in defaults.items() if k not in values}, **values}
        missing = [p for p in table if p not in values]
        if missing:
            raise ParameterError(f"missing parameter(s) {missing}")
    out = {}
    for k, v in values.items():
        p = table[k]
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
        if not math.isfinite(x * p.si):  # (the engine's SI value: e.g. 1e300 GPa)
            raise ParameterError(f"{k}={x:g}{unit}: too large, expected a number in "
                                 f"{p.unit or 'its unit'} well below 1e300")
        if within_table2 and not (p.lo <= x <= p.hi):
            raise ParameterError(f"{k}={x:g}{unit} is outside the Table 2 range "
                                 f"[{p.lo:g}, {p.hi:g}]{unit}")
        if k in FJ_INTEGERS and x != int(x):
            raise ParameterError(f"{k}={x:g}: expected an integer ({p.description})")
        out[k] = x
    if model == "flatjoint":
        frac = out.get("fj_slit_frac", 0.0) + out.get("fj_gap_frac", 0.0)
        if frac > 1.0:
            raise ParameterError(f"fj_slit_frac + fj_gap_frac = {frac:g}: expected at most 1 "
                                 "(the rest of the flat joints are bonded)")
        out["contact_model"] = model
    defaults = MODELS[model].defaults or {}
    quiet = [k for k in MODELS[model].quiet if k in out and out[k] == defaults[k]]
    # the card's order; the quiet keys (no strength scatter) left out at their defaults
    return {k: out[k] for k in (*table, "contact_model") if k in out and k not in quiet}
