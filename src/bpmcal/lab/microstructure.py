"""What each installed contact of a specimen draws from its packing seed (steps 4-5 of the
genesis, ``lab.specimen.build_specimen``): a flat-jointed material's microstructure, the
type of each flat joint (bonded, gapped or slit: :class:`Microstructure`,
:func:`install_microstructure`), and the strength scatter, each contact's own tensile
strength and cohesion (:func:`truncated_normal`, :func:`install_strength_scatter`). Each
draw has its own stream of the packing seed, so the same seed gives the same contacts."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..dem import Model
from ..dem import flatjoint as FJ
from ..dem.errors import InputError


@dataclass(frozen=True)
class Microstructure:
    """A flat-jointed material's microstructure (docs/flatjoint-spec.md §6; the card's ``fj_gi_ratio``,
    ``fj_slit_frac``, ``fj_gap_frac``, ``fj_gap0_ratio``): flat joints are installed on
    every pair whose surface gap is at most ``gi_ratio`` x the mean ball radius; of the N
    joints, round(``gap_frac`` N) are gapped (all elements unbonded, surfaces
    ``gap0_ratio`` x the mean radius apart), round(``slit_frac`` N) slit (unbonded,
    touching) and the rest bonded, on a random order of the contacts drawn from the
    packing seed (``install_microstructure``; Itasca's fistPkg takes exact counts too)."""

    gi_ratio: float = 0.0
    slit_frac: float = 0.0
    gap_frac: float = 0.0
    gap0_ratio: float = 0.0

    def __post_init__(self):
        for name in ("gi_ratio", "slit_frac", "gap_frac", "gap0_ratio"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"fj_{name}={v!r}: expected a finite number >= 0")
        if self.slit_frac + self.gap_frac > 1.0:
            raise InputError(f"fj_slit_frac + fj_gap_frac = {self.slit_frac + self.gap_frac:g}:"
                             " expected at most 1")


def install_microstructure(m: Model, micro: Microstructure, seed: int, rmean: float) -> dict:
    """Draw each installed flat joint's type (``Microstructure``) from the packing seed,
    in contact order, and install it. Returns the fractions actually installed."""
    nb = m.n_bonds
    # exact counts, as Itasca's fistPkg (round(phi_G N) gapped, round(phi_S N) slit, the
    # rest bonded), on a seeded random order of the contacts (bpmcal's contact order
    # follows the balls' space-filling order: taking it as it is would cluster each type)
    n_g = int(round(micro.gap_frac * nb))
    n_s = min(int(round(micro.slit_frac * nb)), nb - n_g)
    order = np.random.default_rng([int(seed), 0x464A]).permutation(nb)
    t = np.full(nb, FJ.MT_BONDED)
    t[order[:n_g]] = FJ.MT_GAPPED
    t[order[n_g:n_g + n_s]] = FJ.MT_SLIT
    m.set_flatjoint_types(t, gap0=micro.gap0_ratio * rmean)
    frac = np.bincount(t, minlength=3) / max(nb, 1)
    return {"fj_bonded_frac": float(frac[FJ.MT_BONDED]),
            "fj_gapped_frac": float(frac[FJ.MT_GAPPED]),
            "fj_slit_frac_installed": float(frac[FJ.MT_SLIT]),
            "fj_gi_mm": float(micro.gi_ratio * rmean * 1e3),
            "fj_gap0_mm": float(micro.gap0_ratio * rmean * 1e3)}


def truncated_normal(rng: np.random.Generator, mean: float, sd: float, n: int) -> np.ndarray:
    """``n`` values of a Gaussian of ``mean`` and ``sd`` truncated at zero as PFC's
    material-modeling package draws strengths (fistPkg ``ft_valNormDist``: a negative draw
    is drawn again), i.e. the Gaussian conditioned on >= 0. ``sd`` = 0 gives ``mean``
    exactly, without touching ``rng``."""
    if sd == 0.0:
        return np.full(n, float(mean))
    x = mean + sd * rng.standard_normal(n)
    bad = np.flatnonzero(x < 0.0)
    while bad.size:  # in order, so the result depends on the seed only
        x[bad] = mean + sd * rng.standard_normal(bad.size)
        bad = bad[x[bad] < 0.0]
    return x


def install_strength_scatter(m: Model, material, seed: int) -> dict:
    """The strength scatter (``pb_ten_sd``/``pb_coh_sd``, ``fj_ten_sd``/``fj_coh_sd``):
    every installed contact draws its own tensile strength and cohesion, independently,
    from the material's means and standard deviations (``truncated_normal``; PFC assigns
    ``pb_ten``/``pb_coh`` per bond and ``fj_ten``/``fj_coh`` per flat joint, which its
    elements share), in contact order, from a stream of the packing seed. Without scatter
    (both sd 0) nothing is drawn or set: the contacts keep the means, bit for bit.
    Returns what was drawn (empty without scatter)."""
    ten, ten_sd, coh, coh_sd = material.strengths()
    if ten_sd == 0.0 and coh_sd == 0.0:
        return {}
    rng = np.random.default_rng([int(seed), 0x5343])  # "SC": the scatter's own stream
    nb = m.n_bonds
    t = truncated_normal(rng, ten, ten_sd, nb)
    c = truncated_normal(rng, coh, coh_sd, nb)
    m.set_bond_strengths(t, c)
    return {"strength_ten_mean_MPa": float(t.mean() / 1e6) if nb else math.nan,
            "strength_ten_sd_MPa": float(t.std() / 1e6) if nb else math.nan,
            "strength_coh_mean_MPa": float(c.mean() / 1e6) if nb else math.nan,
            "strength_coh_sd_MPa": float(c.std() / 1e6) if nb else math.nan}
