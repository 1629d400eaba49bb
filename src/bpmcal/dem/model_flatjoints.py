"""``FlatJointsMixin``: the flat joints of ``Model`` (PFC ``flatjoint``): installing them
with their microstructural types, their per-element state and breakage events, and the
parameters the kernel reads.

A mixin of :class:`bpmcal.dem.model.Model`, not usable alone. The flat-jointed pairs take
the place of the bond pairs (the first ``n_bonds`` pairs of the neighbour list, ``Bd``
keeps their partner lists and a per-contact summary state); their law is in
``flatjoint.py``, their state in ``Fj`` (``model_arrays.FlatJoints``).
"""
from __future__ import annotations

import math

import numpy as np

from . import flatjoint as fj
from .errors import InputError
from .material import FlatJointMaterial
from .model_arrays import IDX, FlatJoints, readonly
from .slots import BOND_NONE, E_DASH, E_SLIP, I_NB, I_NPAIRS, I_REBUILD


def empty_flatjoints(nb: int, nr: int = 1, nal: int = 1) -> FlatJoints:
    """Zeroed flat-joint state for ``nb`` contacts of ``nr`` x ``nal`` elements."""
    ne = int(nr) * int(nal)
    return FlatJoints(c=np.zeros((nb, fj.NC)), flag=np.zeros((nb, fj.NK), np.int8),
                      es=np.zeros((nb, ne), np.int8), ef=np.zeros((nb, ne, 2)),
                      eslip=np.zeros((nb, ne), np.uint8), geo=fj.element_table(nr, nal),
                      estep=np.full((nb, ne), -1, np.int64), epos=np.zeros((nb, ne, 3)),
                      enrm=np.zeros((nb, ne, 3)), esig=np.zeros((nb, ne, 2)),
                      een=np.zeros((nb, ne)), prm=np.zeros(10))


def flatjoint_params(material: FlatJointMaterial) -> np.ndarray:
    """The law's parameters in the order ``flatjoint.fj_range`` reads them."""
    return np.array([material.fj_emod, 1.0 / material.fj_kratio, material.fj_ten,
                     material.fj_coh, math.tan(math.radians(material.fj_fa)),
                     material.fj_fric, material.fj_rmul, material.emod, 1.0 / material.kratio,
                     material.fric])


class FlatJointsMixin:
    """Flat joints of :class:`~bpmcal.dem.model.Model` (contact ``k`` is pair ``k`` of the
    neighbour list, as for the parallel bonds)."""

    @property
    def contact_model(self) -> str:
        """The contact model of the installed pairs: ``linearpbond`` or ``flatjoint``."""
        return self.material.contact_model

    def _install_flatjoints(self, gap: float) -> int:
        """Flat joints on every listed pair with surface gap <= ``gap``: all elements
        bonded, force-free (reference gap = the pair's gap now), frame s chosen per pair
        from its normal. Called by :meth:`bond`; installs once."""
        if self.n_bonds:
            raise InputError("flat joints are installed once, on the packed assembly; "
                             f"this model already has {self.n_bonds}")
        self._touch()
        self._ensure_lists()
        P = self.P
        m = int(self.iprm[I_NPAIRS])
        vi, vj = P.pi[:m].copy(), P.pj[:m].copy()
        g = self.pair_gaps(vi, vj)
        sel = g <= gap
        if not sel.any():
            return 0
        self.eacc[E_SLIP] += P.slip[:m].sum()
        self.eacc[E_DASH] += P.dash[:m].sum()
        ni, nj = vi[sel], vj[sel]
        # pairs in increasing (i, j) order, as the bond pairs
        order = np.lexsort((nj, ni))
        ni, nj = ni[order], nj[order]
        # the reference gap in the kernel's own operations (laws.kinematics), so that
        # installation is force-free to the last bit
        dd = self.B.pos[nj] - self.B.pos[ni]
        gi = np.sqrt(dd[:, 0] * dd[:, 0] + dd[:, 1] * dd[:, 1] + dd[:, 2] * dd[:, 2]) - (
            self.B.radius[ni] + self.B.radius[nj])
        nb = ni.shape[0]
        mat = self.material
        F = empty_flatjoints(nb, mat.fj_nr, mat.fj_nal)
        F.es[:] = fj.E_BONDED
        F.flag[:, fj.K_LIVE] = 1
        F.flag[:, fj.K_TYPE] = fj.MT_BONDED
        F.c[:, fj.C_GREF] = gi
        F.c[:, fj.C_SF] = 1.0
        F.c[:, fj.C_TEN] = mat.fj_ten  # each joint's own strengths: the material's means
        F.c[:, fj.C_COH] = mat.fj_coh
        d = self.B.pos[nj] - self.B.pos[ni]
        n = d / np.linalg.norm(d, axis=1)[:, None]
        # s: the unit vector perpendicular to n closest to the global axis least aligned
        # with n (deterministic, no randomness)
        ax = np.argmin(np.abs(n), axis=1)
        e = np.zeros_like(n)
        e[np.arange(nb), ax] = 1.0
        s = e - (e * n).sum(axis=1)[:, None] * n
        s /= np.linalg.norm(s, axis=1)[:, None]
        F.c[:, fj.C_SX:fj.C_SZ + 1] = s
        F.prm[:] = self.Fj.prm
        Bd = self._empty_bonds(nb)
        counts = np.bincount(ni.astype(np.int64), minlength=self.n)
        Bd.ptr[1:] = np.cumsum(counts)
        Bd.part[:] = nj
        if nb > P.pi.shape[0]:
            self._alloc_pairs(int(nb * 1.5) + 8 * self.n)
            P = self.P
        P.pi[:nb] = ni.astype(IDX)
        P.pj[:nb] = nj.astype(IDX)
        P.fs[:nb] = 0.0
        P.df[:nb] = 0.0
        P.act[:nb] = 1
        P.slip[:nb] = 0.0
        P.dash[:nb] = 0.0
        self.Bd = Bd
        self.Fj = F
        self.iprm[I_NB] = nb
        self.iprm[I_NPAIRS] = nb
        P.vptr[:] = 0
        self.iprm[I_REBUILD] = 1
        self._ensure_lists()
        return nb

    def set_flatjoint_types(self, mtype, gap0=None):
        """Microstructural type of every flat joint (PFC ``fj_mtype``; in the order of
        :meth:`bond_pairs`): 0 bonded (all elements bonded), 1 gapped (all elements
        unbonded, the surfaces ``gap0`` [m] apart), 2 slit (all elements unbonded, surfaces
        touching). Set right after installation, before any step."""
        self._require_flatjoints()
        nb = self.n_bonds
        t = np.asarray(mtype).reshape(-1)
        if t.shape != (nb,) or not np.isin(t, (fj.MT_BONDED, fj.MT_GAPPED,
                                               fj.MT_SLIT)).all():
            raise InputError(f"flat-joint types: expected {nb} values in {{0, 1, 2}} "
                             f"(bonded, gapped, slit), got shape {t.shape}")
        g0 = np.zeros(nb) if gap0 is None else np.broadcast_to(
            np.asarray(gap0, float), (nb,)).copy()
        if not np.all(np.isfinite(g0)) or np.any(g0 < 0):
            raise InputError("flat-joint initial gaps gap0: expected finite values >= 0 m")
        F = self.Fj
        F.flag[:, fj.K_TYPE] = t
        g0 = np.where(t == fj.MT_GAPPED, g0, 0.0)
        # g_s = gap - g_ref = g_0 now: shift the reference gap
        F.c[:, fj.C_GREF] -= g0 - F.c[:, fj.C_G0]
        F.c[:, fj.C_G0] = g0
        F.es[:] = np.where((t == fj.MT_BONDED)[:, None], fj.E_BONDED, fj.E_UNBONDED)
        self.Bd.state[:] = np.where(t == fj.MT_BONDED, 0, BOND_NONE)
        self._touch()

    def _require_flatjoints(self):
        if not isinstance(self.material, FlatJointMaterial) or self.n_bonds == 0:
            raise InputError("this model has no flat joints (material contact model "
                             f"{self.material.contact_model!r}, {self.n_bonds} installed)")

    @property
    def flatjoint_types(self) -> np.ndarray:
        """Microstructural type of every flat joint (0 bonded, 1 gapped, 2 slit; copy)."""
        return self.Fj.flag[:, fj.K_TYPE].astype(np.int64)

    @property
    def element_states(self) -> np.ndarray:
        """State of every flat-joint element (n_bonds, n_elements), read-only view:
        3 bonded, 0 unbonded from installation, 1 broken in tension, 2 in shear."""
        return readonly(self.Fj.es)

    def element_table(self) -> np.ndarray:
        """The element geometry of a unit interface (``flatjoint.element_table``)."""
        return self.Fj.geo.copy()

    def flatjoint_state(self) -> dict:
        """Current state of every flat joint (copies): interface radius [m], surface gap
        g_s [m], relative bend rotation theta_b (s, t) [rad], frame vector s, element
        states and shear forces (s, t) [N], slip flags, live (0 once deleted)."""
        self._require_flatjoints()
        i, j = self.bond_pairs()
        F = self.Fj
        rad = self.material.fj_rmul * np.minimum(self.B.radius[i], self.B.radius[j])
        return {"radius": rad, "gap": self.pair_gaps(i, j) - F.c[:, fj.C_GREF],
                "theta_b": F.c[:, fj.C_TBS:fj.C_TBT + 1].copy(),
                "s": F.c[:, fj.C_SX:fj.C_SZ + 1].copy(), "state": F.es.copy(),
                "shear": F.ef.copy(), "slip": F.eslip.copy(),
                "type": self.flatjoint_types, "live": F.flag[:, fj.K_LIVE].copy(),
                "gap0": F.c[:, fj.C_G0].copy()}

    def _flatjoint_breaks(self) -> dict:
        """Element breaks as events sorted by (step, contact, element)."""
        F = self.Fj
        kk, ee = np.nonzero(F.estep >= 0)
        o = np.lexsort((ee, kk, F.estep[kk, ee]))
        kk, ee = kk[o], ee[o]
        i, j = self.P.pi[kk].astype(np.int32), self.P.pj[kk].astype(np.int32)
        rad = self.material.fj_rmul * np.minimum(self.B.radius[i], self.B.radius[j])
        area = F.geo[ee, fj.G_A] * rad * rad
        return {"step": F.estep[kk, ee].copy(), "bond": kk, "i": i.copy(), "j": j.copy(),
                "mode": F.es[kk, ee].astype(np.int64), "pos": F.epos[kk, ee].copy(),
                "normal": F.enrm[kk, ee].copy(), "radius": np.sqrt(area / math.pi),
                "energy": F.een[kk, ee].copy(), "sigma": F.esig[kk, ee, 0].copy(),
                "tau": F.esig[kk, ee, 1].copy(), "sigma_n": F.esig[kk, ee, 0].copy(),
                "element": ee.astype(np.int64), "area": area}

    def crack_counts(self) -> tuple[int, int]:
        """(cracks in tension, cracks in shear) so far: broken parallel bonds, or broken
        flat-joint elements."""
        if self.material.contact_model == "flatjoint" and self.n_bonds:
            es = self.Fj.es
            return int(np.count_nonzero(es == fj.E_TENSION)), int(np.count_nonzero(
                es == fj.E_SHEAR))
        st = self.Bd.state
        return int(np.count_nonzero(st == 1)), int(np.count_nonzero(st == 2))
