"""``MeasureMixin``: what ``Model`` reports about its state: the energy terms and their
balance, the unbalanced-force ratio, coordination numbers, resultant ball forces and
momentum.

A mixin of :class:`bpmcal.dem.model.Model`, not usable alone: it reads the model's ``B``,
``P``, ``Bd``, ``S``, ``W``, ``prm``, ``iprm``, ``eacc`` through the measuring kernels of
``diagnostics.py``; :meth:`MeasureMixin.energies` runs a zero-step ``cycle`` first when
the state's energies are not recorded.
"""
from __future__ import annotations

import math

import numpy as np

from . import diagnostics as D
from .slots import E_REMOVED, I_FORCES, I_NB, I_NPAIRS, I_NSLOTS

#: Energy terms reported by :meth:`Model.energies` (J).
ENERGY_TERMS = ("kinetic", "kinetic_walls", "strain_linear", "strain_bond", "slip",
                "dashpot", "damping", "released", "removed", "work_walls", "work_gravity",
                "work_constraints")


class MeasureMixin:
    """Measurements of :class:`~bpmcal.dem.model.Model` (no state changes, except that
    they make the current forces and energies current)."""

    def energies(self) -> dict:
        """Energy terms [J] of the current state (step n), consistent with the integrator.

        Inputs: ``work_walls`` (walls with prescribed motion; every wall's work on the balls
        is in ``work_walls_each``), ``work_gravity``,
        ``work_constraints`` (of prescribed velocities). Stored: ``kinetic`` (balls,
        1/2 m v_{n-1/2}.v_{n+1/2} + rotation), ``kinetic_walls`` (rigid walls),
        ``strain_linear``, ``strain_bond``. Dissipated or released: ``slip``, ``dashpot``,
        ``damping``, ``released`` (strain energy of bonds at breakage).
        """
        if not self._recorded:
            if self.iprm[I_FORCES] == 0:
                self.iprm[I_FORCES] = 1
            self.cycle(0, record=True)
        B, P, Bd, S, W = self.B, self.P, self.Bd, self.S, self.W
        lin, bond, slip, dash, damp, grav, fixw, rel = D.sum_energies(
            B.edamp, B.egrav, B.efix, P.estr, P.slip, P.dash, int(self.iprm[I_NPAIRS]),
            Bd.estr, Bd.energy, Bd.state, int(self.iprm[I_NB]), S.estr, S.slip, S.dash,
            int(self.iprm[I_NSLOTS]), self.eacc, self.material.contact_model == "flatjoint")
        kin, dmp2, grv2, cst2 = D.measure_balls(B.vel, B.angvel, B.force, B.moment, B.mass,
                                                B.inertia, B.fix, B.fbuf, B.pmask, S.ptr,
                                                S.f, S.m, self.prm)
        wout = np.zeros((self.n_walls, 3))
        D.measure_walls(W.vel, W.radv, W.mass, W.force, W.radsum, self.prm, wout)
        ww = W.work + wout[:, 1]
        e = {"kinetic": kin, "kinetic_walls": float(wout[:, 0].sum()), "strain_linear": lin,
             "strain_bond": bond, "slip": slip, "dashpot": dash, "damping": damp + dmp2,
             "released": rel, "removed": float(self.eacc[E_REMOVED]),
             # rigid-body walls are part of the system (their kinetic energy is stored
             # energy), so only walls with prescribed motion do external work
             "work_walls": float(ww[W.mass == 0.0].sum()) + self._removed_work,
             "work_gravity": grav + grv2 + float((W.grav + wout[:, 2]).sum())
             + self._removed_grav,
             "work_constraints": fixw + cst2, "work_walls_each": ww.tolist(),
             "work_gravity_walls": float((W.grav + wout[:, 2]).sum()) + self._removed_grav}
        # B.force and B.moment are the resultants of this state and these settings (prm:
        # gravity, damping, dt), until a cycle or a change from Python (_touch)
        self._measured = True
        self._measured_prm = self.prm.copy()
        return e

    @staticmethod
    def energy_balance(e: dict, e0: dict | None = None) -> dict:
        """Inputs, stored, dissipated between two :meth:`energies` snapshots and the
        relative closure error |input - (d stored + d dissipated)| / max(|input|, stored)."""
        def parts(x):
            inp = x["work_walls"] + x["work_gravity"] + x["work_constraints"]
            sto = x["kinetic"] + x["kinetic_walls"] + x["strain_linear"] + x["strain_bond"]
            dis = x["slip"] + x["dashpot"] + x["damping"] + x["released"] + x["removed"]
            return inp, sto, dis
        i1, s1, d1 = parts(e)
        i0, s0, d0 = parts(e0) if e0 is not None else (0.0, 0.0, 0.0)
        inp, sto, dis = i1 - i0, s1 - s0, d1 - d0
        scale = max(abs(inp), abs(s1), abs(s0), 1e-300)
        return {"input": inp, "stored": sto, "dissipated": dis,
                "error": inp - sto - dis, "rel_error": abs(inp - sto - dis) / scale}

    def unbalanced_ratio(self) -> float:
        """Mean unbalanced force of free balls / mean contact force (PFC ratio-average)."""
        free = self.B.fix == 0
        if not free.any():
            return 0.0
        if not (self._measured and np.array_equal(self.prm, self._measured_prm)):
            self.energies()  # current resultant forces (measure pass)
        # np.linalg.norm(f, axis=1) is sqrt(add.reduce(f * f, axis=1)) for real f: the
        # same ufuncs on the same values, without its argument handling, and without the
        # copy of a mask that selects every ball
        f = self.B.force if free.all() else self.B.force[free]
        fu = np.sqrt(np.add.reduce(f * f, axis=1)).mean()
        fc, cnt = D.contact_force_mean(self.B.pos, self.B.radius, self.P.pi, self.P.pj,
                                       self.P.fs, int(self.iprm[I_NPAIRS]), int(self.iprm[I_NB]),
                                       self.Bd.state, self.Bd.blk, self.prm, self.Fj.c)
        if cnt == 0 or fc == 0.0:
            return math.inf if fu > 0 else 0.0
        return float(fu / fc)

    def coordination_numbers(self) -> np.ndarray:
        """Contacts per ball now (bonded or touching)."""
        self._ensure_lists()
        if self.material.contact_model == "flatjoint":  # the contacts of Model.contacts
            i, j = self.contacts()
            return (np.bincount(i, minlength=self.n)
                    + np.bincount(j, minlength=self.n)).astype(np.int64)
        return D.coordination(self.B.pos, self.B.radius, self.P.pi, self.P.pj,
                              int(self.iprm[I_NPAIRS]), int(self.iprm[I_NB]), self.Bd.state,
                              self.Bd.blk)

    def ball_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """Resultant force (contacts + gravity) [N] and moment [N m] on every ball at the
        current positions (copies)."""
        self.energies()
        return self.B.force.copy(), self.B.moment.copy()

    def momentum(self) -> tuple[np.ndarray, np.ndarray]:
        """Linear momentum and angular momentum about the origin (Sum m x_n x v_{n+1/2}
        + I w, the leapfrog-conserved form, using x before the last position update)."""
        B = self.B
        p = (B.mass[:, None] * B.vel).sum(axis=0)
        x_prev = B.pos - B.vel * self.dt
        L = (B.mass[:, None] * np.cross(x_prev, B.vel)).sum(axis=0) + (
            B.inertia[:, None] * B.angvel).sum(axis=0)
        return p, L
