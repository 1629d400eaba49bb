"""``BondsMixin``: the parallel bonds of ``Model``: installing them, their reference gaps,
per-contact strengths and strength factors, their state, and the breakage events.

This is the contact-model-specific part of the Python facade (the linear parallel-bond
model; its laws are in ``laws.py`` and ``bondblock.py``). A mixin of
:class:`bpmcal.dem.model.Model`, not usable alone: it works on the model's ``Bd``
(``Bonds``), ``P`` (``Pairs``), ``B``, ``material``, ``iprm``, ``eacc`` and calls
``_touch``, ``_ensure_lists``, ``_alloc_pairs`` and ``pair_gaps``.
"""
from __future__ import annotations

import math

import numpy as np

from . import bondblock as bb
from .errors import InputError
from .flatjoint import C_COH, C_LX, C_LZ, C_SF, C_TEN
from .model_arrays import IDX, Bonds, readonly
from .slots import BOND_INTACT, E_DASH, E_SLIP, I_NB, I_NBROKEN, I_NPAIRS, I_REBUILD


class BondsMixin:
    """Parallel bonds of :class:`~bpmcal.dem.model.Model` (in the order of
    :meth:`bond_pairs`: bond ``k`` is pair ``k`` of the neighbour list)."""

    def _empty_bonds(self, nb):
        ten, _, coh, _ = self.material.strengths()  # new bonds: the material's means
        return Bonds(blk=bb.new_state(nb, ten, coh), state=np.zeros(nb, np.int8),
                     step=np.full(nb, -1, np.int64), pos=np.zeros((nb, 3)),
                     nrm=np.zeros((nb, 3)), energy=np.zeros(nb), estr=np.zeros(nb),
                     sig=np.zeros((nb, 3)), ptr=np.zeros(self.n + 1, np.int64),
                     part=np.zeros(nb, np.int64))

    @property
    def n_bonds(self) -> int:
        return int(self.iprm[I_NB])

    @property
    def n_broken(self) -> int:
        return int(self.iprm[I_NBROKEN])

    @property
    def bond_states(self) -> np.ndarray:
        """State of every bond pair (read-only view): 0 intact, 1 broken in tension,
        2 broken in shear (``BOND_*``), in the order of :meth:`bond_pairs`."""
        return readonly(self.Bd.state)

    @property
    def bond_break_steps(self) -> np.ndarray:
        """Step at which each bond broke, -1 if intact (read-only view)."""
        return readonly(self.Bd.step)

    def bond(self, gap: float = 0.0, rgap=None) -> int:
        """Install parallel bonds on every unbonded pair with surface gap <= ``gap`` (PFC
        ``contact method bond gap``). Bonds are created with zero force and moment; the
        linear shear force of the pair is kept. ``rgap`` optionally gives, per new bond (in
        the order of :meth:`bond_pairs` after the call), the reference gap of its linear
        component (default 0). Returns the number of new bonds."""
        g = float(gap)
        if not math.isfinite(g):
            raise InputError(f"gap={gap!r}: expected a finite installation gap in m")
        if self.material.contact_model == "flatjoint":
            if rgap is not None:
                raise InputError("rgap: flat joints are installed force-free; a reference "
                                 "gap applies to parallel bonds only")
            return self._install_flatjoints(g)
        self._touch()
        self._ensure_lists()
        P, Bd = self.P, self.Bd
        nb = int(self.iprm[I_NB])
        m = int(self.iprm[I_NPAIRS])
        vi, vj = P.pi[nb:m].copy(), P.pj[nb:m].copy()
        sel = self.pair_gaps(vi, vj) <= g
        if not sel.any():
            return 0
        # fold the energy of Verlet pairs that become bonds (their pair slots move)
        self.eacc[E_SLIP] += P.slip[nb:m].sum()
        self.eacc[E_DASH] += P.dash[nb:m].sum()
        ni, nj, nfs = vi[sel], vj[sel], P.fs[nb:m][sel].copy()
        ndf = P.df[nb:m][sel].copy()
        nnew = ni.shape[0]
        nbt = nb + nnew
        new = self._empty_bonds(nbt)
        for name in ("state", "step", "pos", "nrm", "energy", "estr", "sig"):
            getattr(new, name)[:nb] = getattr(Bd, name)
        for f in range(bb.NSF):  # blocked state: old bonds keep theirs
            bb.set_field(new.blk, f, nb, bb.get_field(Bd.blk, f, nb))
        newk = np.arange(nb, nbt)
        for c in range(3):
            new.blk[bb.field_index(bb.S_LX + c, nbt)[newk]] = nfs[:, c]
            new.blk[bb.field_index(bb.S_DFX + c, nbt)[newk]] = ndf[:, c]
        if rgap is not None:
            rg = np.asarray(rgap, float).reshape(-1)
            if rg.shape != (nnew,) or not np.all(np.isfinite(rg)):
                raise InputError(f"rgap: expected {nnew} finite reference gaps, "
                                 f"got shape {rg.shape}")
            new.blk[bb.field_index(bb.S_RG, nbt)[newk]] = rg
        oi, oj = P.pi[:nb].copy(), P.pj[:nb].copy()
        ai = np.concatenate([oi, ni]).astype(IDX)
        aj = np.concatenate([oj, nj]).astype(IDX)
        if nbt > P.pi.shape[0]:
            self._alloc_pairs(int(nbt * 1.5) + 8 * self.n)
            P = self.P
        P.pi[:nbt], P.pj[:nbt] = ai, aj
        P.fs[:nbt] = 0.0  # bond pairs keep their linear shear force in the blocked state
        P.df[:nbt] = 0.0
        P.act[:nbt] = 1
        P.slip[:nbt] = np.concatenate([P.slip[:nb], np.zeros(nnew)])
        P.dash[:nbt] = np.concatenate([P.dash[:nb], np.zeros(nnew)])
        # partner CSR (j > i of each bond (i, j), i < j by construction)
        order = np.lexsort((aj, ai))
        counts = np.bincount(ai, minlength=self.n)
        new.ptr[1:] = np.cumsum(counts)
        new.part[:] = aj[order]
        self.Bd = new
        self.iprm[I_NB] = nbt
        self.iprm[I_NPAIRS] = nbt
        P.vptr[:] = 0  # no Verlet history left to carry (all contacting pairs are bonds)
        self.iprm[I_REBUILD] = 1
        self._ensure_lists()
        return nnew

    def bond_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        nb = self.n_bonds
        return self.P.pi[:nb].astype(np.int32), self.P.pj[:nb].astype(np.int32)

    def set_bond_rgap(self, rgap):
        """Reference gaps [m] of the linear component of the bond pairs (PFC ``rgap``).
        Once a bond has broken and its surfaces are apart (gap >= 0), a negative reference
        gap is set to 0: a broken pair that comes back into contact is repelled from the
        first touch, as in PFC."""
        rg = np.asarray(rgap, float).reshape(-1)
        if rg.shape != (self.n_bonds,) or not np.all(np.isfinite(rg)):
            raise InputError(f"rgap: expected {self.n_bonds} finite values, got shape {rg.shape}")
        bb.set_field(self.Bd.blk, bb.S_RG, self.n_bonds, rg)
        self._touch()

    def set_bond_strength_factors(self, factors):
        """Per-bond strength factors: bond k (in the order of :meth:`bond_pairs`) fails at
        its own tensile strength and cohesion (:meth:`set_bond_strengths`; the material's
        ``pb_ten`` and ``pb_coh`` unless scattered) times ``factors[k]`` (its friction
        angle and stiffnesses are unchanged): the end and contact caps of the lab tests.
        New bonds get factor 1. A scalar applies to every bond. For flat joints the factor
        multiplies the joint's ``fj_ten`` and ``fj_coh``, for every element."""
        nb = self.n_bonds
        f = np.broadcast_to(np.asarray(factors, float), (nb,)) if np.ndim(factors) == 0 \
            else np.asarray(factors, float).reshape(-1)
        if f.shape != (nb,) or not np.all(np.isfinite(f)) or np.any(f < 0):
            raise InputError(f"strength factors: expected {nb} finite values >= 0, got "
                             f"shape {f.shape}")
        if self.material.contact_model == "flatjoint":
            self.Fj.c[:, C_SF] = f
        else:
            bb.set_field(self.Bd.blk, bb.S_SF, nb, f)
            bb.set_strengths(self.Bd.blk, nb)
        self._touch()

    def set_bond_strengths(self, ten, coh):
        """Each contact's own tensile strength and cohesion [Pa] (PFC's per-contact
        ``pb_ten`` / ``pb_coh``, or ``fj_ten`` / ``fj_coh`` shared by a flat joint's
        elements), in the order of :meth:`bond_pairs`: a strength scatter
        (``lab.microstructure.install_strength_scatter``). Bonds get the material's means at
        installation; a strength factor (:meth:`set_bond_strength_factors`) multiplies
        these. A scalar applies to every contact."""
        nb = self.n_bonds
        out = []
        for name, v in (("tensile strengths", ten), ("cohesions", coh)):
            a = np.broadcast_to(np.asarray(v, float), (nb,)) if np.ndim(v) == 0 \
                else np.asarray(v, float).reshape(-1)
            if a.shape != (nb,) or not np.all(np.isfinite(a)) or np.any(a < 0):
                raise InputError(f"bond {name}: expected {nb} finite values >= 0 Pa, got "
                                 f"shape {a.shape}")
            out.append(a)
        if self.material.contact_model == "flatjoint":
            self.Fj.c[:, C_TEN] = out[0]
            self.Fj.c[:, C_COH] = out[1]
        else:
            bb.set_field(self.Bd.blk, bb.S_TEN0, nb, out[0])
            bb.set_field(self.Bd.blk, bb.S_COH0, nb, out[1])
            bb.set_strengths(self.Bd.blk, nb)
        self._touch()

    def _reset_bond_strengths(self):
        """Every installed contact's strengths to the material's means (``set_material``)."""
        ten, _, coh, _ = self.material.strengths()
        self.set_bond_strengths(ten, coh)

    @property
    def bond_strengths(self) -> tuple[np.ndarray, np.ndarray]:
        """(tensile strengths, cohesions) of every contact [Pa] (copies; before their
        strength factors; :meth:`set_bond_strengths`)."""
        if self.material.contact_model == "flatjoint":
            return self.Fj.c[:, C_TEN].copy(), self.Fj.c[:, C_COH].copy()
        nb = self.n_bonds
        return (bb.get_field(self.Bd.blk, bb.S_TEN0, nb),
                bb.get_field(self.Bd.blk, bb.S_COH0, nb))

    @property
    def bond_strength_factors(self) -> np.ndarray:
        """Strength factor of every bond pair (a copy; :meth:`set_bond_strength_factors`)."""
        if self.material.contact_model == "flatjoint":
            return self.Fj.c[:, C_SF].copy()
        return bb.get_field(self.Bd.blk, bb.S_SF, self.n_bonds)

    def breaks(self) -> dict:
        """Broken bonds as events sorted by (step, bond index): step, time, bond, i, j,
        mode (1 tension, 2 shear), position, normal, bond radius, released energy. With
        flat joints, one event per broken element (``bond`` is the contact), with its
        ``element`` index and ``area``; ``radius`` is that of a disk of the element's
        area."""
        if self.material.contact_model == "flatjoint":
            return self._flatjoint_breaks()
        st = self.Bd.state
        k = np.flatnonzero(st != BOND_INTACT)
        k = k[np.lexsort((k, self.Bd.step[k]))]
        i, j = self.P.pi[k].astype(np.int32), self.P.pj[k].astype(np.int32)
        r = self.material.pb_rmul * np.minimum(self.B.radius[i], self.B.radius[j])
        return {"step": self.Bd.step[k].copy(), "bond": k, "i": i.copy(), "j": j.copy(),
                "mode": st[k].astype(np.int64), "pos": self.Bd.pos[k].copy(),
                "normal": self.Bd.nrm[k].copy(), "radius": r,
                "energy": self.Bd.energy[k].copy(), "sigma": self.Bd.sig[k, 0].copy(),
                "tau": self.Bd.sig[k, 1].copy(), "sigma_n": self.Bd.sig[k, 2].copy()}

    def bond_state(self) -> dict:
        """Current parallel-bond state of every bond pair (copies): normal force (tension
        positive) [N], shear force vector [N], twisting moment [N m], bending moment vector
        [N m], state (0 intact, 1 tension, 2 shear), reference gap of the linear part [m].
        Flat joints: :meth:`flatjoint_state`."""
        if self.material.contact_model == "flatjoint":
            raise InputError("bond_state: the model has flat joints; use flatjoint_state()")
        Bd = self.Bd
        nb = self.n_bonds
        g = lambda f: bb.get_field(Bd.blk, f, nb)  # noqa: E731
        vec = lambda f: np.column_stack([g(f), g(f + 1), g(f + 2)]) if nb else np.zeros((0, 3))  # noqa: E731
        return {"fn": g(bb.S_FN), "fs": vec(bb.S_SX), "mt": g(bb.S_MT), "mb": vec(bb.S_BX),
                "state": Bd.state.copy(), "rgap": g(bb.S_RG)}

    def linear_shear_forces(self) -> np.ndarray:
        """Shear force vector of the linear component of every listed pair [N]."""
        self._ensure_lists()
        out = self.P.fs[: int(self.iprm[I_NPAIRS])].copy()
        nb = self.n_bonds
        if self.material.contact_model == "flatjoint":  # deleted flat joints
            out[:nb] = self.Fj.c[:, C_LX:C_LZ + 1]
            return out
        for c in range(3):
            out[:nb, c] = bb.get_field(self.Bd.blk, bb.S_LX + c, nb)
        return out
