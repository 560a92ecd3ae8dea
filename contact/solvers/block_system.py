"""The Newton system of friction's block law H = B K + D (:mod:`.friction`) reduced like the
diagonal law's (:mod:`.reduced`), and solved by GMRES + GAMG (``solver.linear: gmres``).

B and D have one bs × bs block per node (identity / zero off the contact surface).  A row
whose B row vanishes is a row the law fixes: its equation is D_ii y_i = F_i when the D row
is diagonal too — every sticking tangential row (J_μ = 0, D_tt = w c_t I, no Coulomb
coupling: J_ρ = 0) and every normal row of min's active set (∂_b φ = 0).  As in
:mod:`.reduced`, with X the fixed rows (max_j |B_ij| ≤ FIXED |D_ii| / K_ii and the D row
diagonal to FIXED), P = diag(free) and y_X = F_X / D_XX,

    A y = r,   A = P L H P + (I − P),   r = P L (F − H y_X) + y_X,

L = diag(1 / B_ii) on the free rows (1 / max_j |B_ij| where B_ii is below 10⁻³ of it): the
free rows are K's rows plus a diagonal, as in the frictionless reduction, but for the
slipping nodes, whose tangential rows keep the Coulomb coupling B_tn (K y)_n + D_tn y_n to
their normal row and HSW's non-symmetric 2 × 2 blocks.  Those are a few rows of the contact
surface: A is K restricted to the free rows up to a perturbation of low rank, GMRES (right
preconditioned, unpreconditioned residual norm) with GAMG on A converges about as CG does on
the frictionless system.  The forcing terms of inexact Newton are the diagonal law's
(Eisenstat–Walker, exact once a Newton step repeats the law).

GAMG is set up for each Newton step's A (``LAG = False``), its interpolation reused
(``pc_gamg_reuse_interpolation``): such a set-up is the Galerkin products alone, a few
GMRES iterations' worth.  Every Newton step moves the stick/slip sets, and a row that changes
sides changes A by a row and column of K: a hierarchy lagged from an earlier A
(``reduced_lag_pc true``, the rule of :class:`~.reduced.ReducedSystem`, which pays where a
set-up costs 8 CG iterations) stalls on those few directions — friction_box_3d at [48, 48,
24] cells, 2 ranks, the first load step's second Newton solve took 18 GMRES iterations lagged
against 10 fresh (``Result.krylov_log``: iterations and GAMG ``setups`` per solve).
Measured (``bench_cost.py path --variants new,lag``, friction_box_3d at [72, 72, 36] cells,
591519 DoFs, 2 ranks, CPU time over one CG + GAMG solve of K in the same process,
demos/RESULTS.md §9): load steps 2.06×, 2.19×, 2.49× with a set-up per Newton step (65–84
GMRES iterations a step), 3.48×, 4.13×, 3.98× lagged (115–160); an earlier run 2.29×,
2.49×, 2.77× against 3.15×, 3.66×, 4.04×.

``solver.linear: direct`` (MUMPS on H) and ``bcgs`` (BiCGStab + GAMG on H) keep the assembled
paths of :mod:`.linear`.
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from .problem import DiscreteProblem
from .reduced import FIXED, ReducedSystem

#: a free row's scaling 1 / B_ii unless |B_ii| < SCALE_FLOOR max_j |B_ij| (then 1 / max_j |B_ij|)
SCALE_FLOOR = 1e-3


class BlockReducedSystem(ReducedSystem):
    """:class:`~.reduced.ReducedSystem` for the block law H = B K + D (module doc).  ``H`` is
    the assembled Jacobian (the pattern of B K: :meth:`FrictionalComplementarity.matrix`),
    SNES's Jacobian, owned by this object; :meth:`set_block` builds A from the blocks the
    Jacobian callback wrote into it."""

    LAG = False  # a GAMG set-up per Newton step (module doc)

    def __init__(self, problem: DiscreteProblem, H: PETSc.Mat, prefix: str, forcing: bool = True):
        self.H = H
        super().__init__(
            problem.K,
            problem.near_nullspace,
            prefix,
            forcing,
            pattern=H,
            dirichlet=problem.dirichlet_rows(),
        )
        self.l = self.K.createVecLeft()  # L: the free rows' scaling
        self.p = self.K.createVecLeft()  # P = diag(free)
        self._d_fixed = np.ones(self.fixed.shape)  # D_ii on the fixed rows (1 elsewhere)
        self._blocks: tuple[np.ndarray, np.ndarray] = (np.zeros(0), np.zeros(0))

    def _jacobian(self) -> PETSc.Mat:
        """SNES's Jacobian: the assembled H."""
        return self.H

    def set_block(self, Bv: np.ndarray, Dv: np.ndarray) -> None:
        """Build A from the blocks (local nodes, bs, bs) of B and D, H = B K + D being in
        :attr:`H` already."""
        self._blocks = (Bv, Dv)
        n, bs, _ = Bv.shape
        b_ii = np.einsum("nii->ni", Bv).ravel()
        d_ii = np.einsum("nii->ni", Dv).ravel()
        b_row = np.abs(Bv).max(axis=2).ravel()
        d_off = np.abs(Dv - Dv * np.eye(bs)).max(axis=2).ravel()
        kdiag = np.maximum(np.abs(self.Kdiag.array_r), np.finfo(float).tiny)
        fixed = (d_ii != 0) & (b_row <= FIXED * np.abs(d_ii) / kdiag)
        fixed &= d_off <= FIXED * np.abs(d_ii)
        # a Dirichlet row (an identity row and column of K) whose B and D rows are diagonal:
        # its row of H is H_ii = B_ii K_ii + D_ii alone, so y_i = F_i / H_ii exactly
        known = self.dirichlet & (b_row <= np.abs(b_ii)) & (d_off == 0) & (b_ii * kdiag + d_ii != 0)
        fixed |= known
        self.fixed = fixed
        self.fixed_rows = int(fixed.sum())
        self._d_fixed = np.where(known, b_ii * kdiag + d_ii, np.where(fixed, d_ii, 1.0))
        self.p.array_w[:] = np.where(fixed, 0.0, 1.0)
        pivot = np.where(np.abs(b_ii) >= SCALE_FLOOR * b_row, b_ii, b_row)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.l.array_w[:] = np.where(fixed | (pivot == 0), 1.0, 1.0 / pivot)
        self._begin_law()
        self.H.copy(self.A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)  # type: ignore[arg-type]
        self.work.pointwiseMult(self.p, self.l)
        self.A.diagonalScale(L=self.work, R=self.p)
        self.work.array_w[:] = np.where(fixed, 1.0, 0.0)
        self.A.setDiagonal(self.work, addv=PETSc.InsertMode.ADD_VALUES)  # type: ignore[arg-type]
        self._operator_changed()

    def _right_hand_side(self, F: PETSc.Vec) -> np.ndarray:
        """y_X = F_X / D_XX, r = P L (F − H y_X) + y_X; returns y_X."""
        fixed, fa = self.fixed, F.array_r
        yx = self.y_fixed.array_w
        yx[:] = np.where(fixed, fa / self._d_fixed, 0.0)
        self.H.mult(self.y_fixed, self.work)  # H y_X
        r = self.r.array_w
        r[:] = np.where(fixed, yx, self.l.array_r * (fa - self.work.array_r))
        return yx

    def _law(self) -> tuple[np.ndarray, np.ndarray]:
        """The blocks of B and D (flattened)."""
        return self._blocks[0].ravel(), self._blocks[1].ravel()

    def count(self, ksp: PETSc.KSP) -> None:
        """The inner solves count themselves."""

    def destroy(self) -> None:
        super().destroy()  # destroys H as J
        self.l.destroy()
        self.p.destroy()
