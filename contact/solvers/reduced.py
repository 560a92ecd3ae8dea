"""The Newton system of a diagonal law as a symmetric positive definite system (SPEC §8).

For fb, min and blend the generalized Jacobian is  H = diag(s) K + diag(d)  with s, d ≥ 0
(:mod:`.newton`; never s_i = d_i = 0).  The step y of  H y = F  splits by rows:

* s_i = 0 ("fixed" rows: the law fixes the unknown):  d_i y_i = F_i,  so  y_i = F_i / d_i;
* s_i > 0 ("free" rows), divided by s_i:  (K y)_i + (d_i / s_i) y_i = F_i / s_i.

Moving the known fixed values to the right-hand side, as for Dirichlet rows, gives with
P = diag(free) and y_X the vector of the fixed values (zero on free rows)

    A y = r,   A = P K P + diag(d / s on free rows, 1 on fixed rows),
               r = P (F / s − K y_X) + y_X,

and A is K restricted to the free rows plus a non-negative diagonal: symmetric, and
positive definite wherever K is on the free rows.  A keeps K's sparsity pattern (the
eliminated couplings are stored zeros), so it is rebuilt each Newton step by one copy,
one ``MatDiagonalScale`` and one ``MatDiagonalSet``, and an algebraic multigrid
preconditioner can keep its hierarchy: CG + GAMG (with the rigid-body near-nullspace for
elasticity) and ``pc_gamg_reuse_interpolation``, so that later Newton steps only recompute
the Galerkin coarse operators.

Rows with s_i ≤ ``FIXED`` · d_i / K_ii are treated as fixed: there d_i / s_i ≥ K_ii / FIXED,
and dropping their couplings changes y_i by a relative O(FIXED), below round-off.

Inexact Newton: the Krylov solve of step k stops at the relative residual η_k of
Eisenstat and Walker (SIAM J. Sci. Comput. 17, 1996, choice 2),

    η_k = γ (‖Φ_k‖ / ‖Φ_{k−1}‖)^α,   γ = 0.9, α = 2,   η_0 = ETA_MAX,
    safeguard η_k ≥ γ η_{k−1}^α when that exceeds 0.1,   η_k ≤ ETA_MAX,

and never below what SNES's stopping test needs: the residual of the linear model is the
next ‖Φ‖ (when the law does not change), so the solve stops once ‖r‖ ≤ ``stop`` / 10
(``stop`` = max(atol, rtol ‖Φ_0‖), set by the solver).  With ``forcing=False`` every
solve runs to ``rtol`` (:data:`EXACT_RTOL`, or the user's ``ksp_rtol``).

This applies to diagonal laws only; a block law (friction, H = B K + D) uses the
assembled system of :mod:`.linear`.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

FIXED = 1e-14     # s_i ≤ FIXED d_i / K_ii: the row is eliminated
ETA_MAX = 0.1     # the loosest forcing term
GAMMA, ALPHA = 0.9, 2.0
EXACT_RTOL = 1e-10

#: PETSc options of the inner solve (``solver.petsc_options`` override them)
REDUCED_PETSC_OPTIONS = {"ksp_type": "cg", "ksp_norm_type": "unpreconditioned", "pc_type": "gamg",
                         "pc_gamg_reuse_interpolation": True, "ksp_rtol": EXACT_RTOL}


class ReducedSystem:
    """Solves H y = F, H = diag(s) K + diag(d), through the SPD system A y = r (module doc)
    with a Krylov solver of its own (options prefix ``prefix``, CG + GAMG by default).

    :meth:`set_law` builds A for a law (s, d); :meth:`solve` solves for one right-hand
    side.  ``J`` is a matrix-free H (y = s ⊙ K x + d ⊙ x) for SNES, whose own KSP is a
    single application of :meth:`solve` (:meth:`configure`)."""

    def __init__(self, K: PETSc.Mat, near_nullspace: PETSc.NullSpace | None, prefix: str,
                 forcing: bool = True):
        self.K = K
        self.A = K.duplicate(copy=True)
        if near_nullspace is not None:
            self.A.setNearNullSpace(near_nullspace)
        self.Kdiag = K.getDiagonal()
        self.s, self.d = K.createVecLeft(), K.createVecLeft()
        self.p, self.y_fixed, self.r, self.work = (K.createVecLeft() for _ in range(4))
        self.ksp = PETSc.KSP().create(K.getComm())
        self.ksp.setOptionsPrefix(prefix)
        self.ksp.setOperators(self.A)
        self.forcing = forcing
        self.stop = 0.0                  # SNES's stopping value of ‖Φ‖ (set by the solver)
        self.previous = None             # ‖Φ‖ and η of the last Newton solve
        self.krylov_iterations = 0
        self.fixed_rows = 0
        self.fixed = np.zeros(K.getLocalSize()[0], dtype=bool)
        self._rtol = EXACT_RTOL
        self.last_reason = 0
        m, n = K.getSizes()
        self.J = PETSc.Mat().createPython((m, n), context=_MatrixFreeH(self), comm=K.getComm())
        self.J.setUp()

    def set_options(self) -> None:
        """Take the inner KSP's tolerance after it has read the options database."""
        self._rtol = self.ksp.getTolerances()[0]

    def configure(self, snes: PETSc.SNES, prefix: str) -> None:
        """Make SNES's KSP one application of :meth:`solve` (preonly + a Python PC); its
        options prefix becomes ``prefix`` so the user's ksp/pc options reach the inner KSP."""
        outer = snes.getKSP()
        outer.setOptionsPrefix(prefix)
        outer.setType("preonly")
        pc = outer.getPC()
        pc.setType(PETSc.PC.Type.PYTHON)
        pc.setPythonContext(_ApplyInverse(self))

    def set_law(self, s: PETSc.Vec, d: PETSc.Vec) -> None:
        """Build A for the law (s, d) (the Newton step's or a polishing step's)."""
        s.copy(self.s)
        d.copy(self.d)
        sa, da = self.s.array_r, self.d.array_r
        fixed = sa <= FIXED * da / np.maximum(np.abs(self.Kdiag.array_r), np.finfo(float).tiny)
        self.fixed = fixed
        self.fixed_rows = int(fixed.sum())
        p = self.p.array_w
        p[:] = np.where(fixed, 0.0, 1.0)
        self.K.copy(self.A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self.A.diagonalScale(L=self.p, R=self.p)
        diag = self.work.array_w
        with np.errstate(divide="ignore", invalid="ignore"):
            diag[:] = np.where(fixed, 1.0, da / np.where(fixed, 1.0, sa))
        self.A.setDiagonal(self.work, addv=PETSc.InsertMode.ADD_VALUES)
        self.ksp.setOperators(self.A)

    def solve(self, F: PETSc.Vec, y: PETSc.Vec, newton: bool = False) -> None:
        """y = H⁻¹ F for the current law; ``newton`` marks a Newton step (forcing applies)."""
        fixed = self.fixed
        sa, da, fa = self.s.array_r, self.d.array_r, F.array_r
        yx = self.y_fixed.array_w
        yx[:] = np.where(fixed, fa / np.where(fixed, da, 1.0), 0.0)
        self.K.mult(self.y_fixed, self.work)                       # K y_X
        r = self.r.array_w
        with np.errstate(divide="ignore", invalid="ignore"):
            r[:] = np.where(fixed, yx, fa / np.where(fixed, 1.0, sa) - self.work.array_r)
        rtol = self._rtol
        if newton and self.forcing:
            rtol = self._forcing(F.norm())
        atol = 0.05 * self.stop                                    # ‖Φ_new‖ ≤ 2 ‖r_A‖ (s ≤ 2)
        self.ksp.setTolerances(rtol=rtol, atol=atol)
        self.ksp.solve(self.r, y)
        self.krylov_iterations += self.ksp.getIterationNumber()
        self.last_reason = self.ksp.getConvergedReason()

    def _forcing(self, fnorm: float) -> float:
        if self.previous is None:
            eta = ETA_MAX
        else:
            f_old, eta_old = self.previous
            eta = GAMMA * (fnorm / f_old) ** ALPHA if f_old > 0 else ETA_MAX
            safe = GAMMA * eta_old**ALPHA
            if safe > 0.1:
                eta = max(eta, safe)
            eta = min(eta, ETA_MAX)
        eta = max(eta, self._rtol)
        self.previous = (fnorm, eta)
        return eta

    def destroy(self) -> None:
        for obj in (self.A, self.Kdiag, self.s, self.d, self.p, self.y_fixed, self.r, self.work,
                    self.ksp, self.J):
            obj.destroy()


class _MatrixFreeH:
    """H x = s ⊙ (K x) + d ⊙ x for the current law (SNES's Jacobian; line searches use it)."""

    def __init__(self, system: ReducedSystem):
        self.system = system

    def mult(self, mat, x, y):
        sy = self.system
        sy.K.mult(x, y)
        y.pointwiseMult(y, sy.s)
        _add_product(y, sy.d, x)


def _add_product(y: PETSc.Vec, d: PETSc.Vec, x: PETSc.Vec) -> None:
    """y += d ⊙ x."""
    y.array_w[:] += d.array_r * x.array_r


class _ApplyInverse:
    """Python PC of SNES's preonly KSP: one solve of the reduced system per Newton step."""

    def __init__(self, system: ReducedSystem):
        self.system = system

    def apply(self, pc, x, y):
        self.system.solve(x, y, newton=True)
        if self.system.last_reason < 0:  # SNES then stops: diverged_linear_solve
            pc.setFailedReason(PETSc.PC.FailedReason.SUBPC_ERROR)
