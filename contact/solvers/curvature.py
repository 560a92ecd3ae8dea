"""The Newton system of a problem with an energy: the tangent's inertia, a shifted tangent
and a direction of negative curvature (issue 31).

A hyperelastic body's residual is the gradient of its total potential Π
(:mod:`contact.models.hyperelastic`): R = ∂Π/∂x, K_T = ∂²Π/∂x².  The Newton system of fb,
min and blend, H = diag(s) K_T + diag(d), is equivalent to the symmetric system of
:mod:`.reduced`,

    A y = r,     A = P K_T P + diag(d/s on the free rows, 1 on the fixed rows),

K_T on the free rows plus the law's non-negative diagonal.  Factorized by LDLᵀ (MUMPS,
``ICNTL(13) = 1``: the inertia of the whole matrix on any number of ranks; a small one on
several ranks gathered whole onto every rank, :class:`.linear.GatheredFactor`) its inertia
(n₋, n₀, n₊) comes with the solve.  With n₋ = n₀ = 0 the Newton step is a descent direction
of Π on the free rows; with n₋ > 0 — St Venant–Kirchhoff in strong compression, a strip
past its buckling load — Newton's method heads for a saddle of Π (an unstable equilibrium)
as readily as for a minimum, and its steps may wander (the SVK arch pressed 40 % in one
step: 30–50 iterations).  Then (:class:`CurvatureSystem`):

1. **shifted tangent** (inertia correction: Nocedal & Wright, *Numerical Optimization*,
   Alg. 3.3; Wächter & Biegler, Math. Program. 106, 2006, §3.1): A_τ = A + τ D with
   D = diag(|K_ii|) on the free rows outside the contact set (the contact rows keep the
   exact linearization of φ), τ = τ₀, 10 τ₀, … until A_τ has no negative or zero
   eigenvalue; τ₀ = max(:data:`TAU_MIN`, τ_last / 4) (the last Newton step's τ, as IPOPT
   does).  The step y = A_τ⁻¹ r is a descent direction of Π on the free rows.
2. **direction of negative curvature** (Moré & Sorensen, Math. Program. 16, 1979):
   v, the eigenvector of the pencil (A, D) of its most negative eigenvalue μ₁, by inverse
   iteration with A_τ's factorization, v ← A_τ⁻¹ D v (A_τ is positive definite, so the
   largest eigenvalue 1/(μ + τ) of A_τ⁻¹ D is that of μ₁; rate (μ₁ + τ)/(μ₂ + τ)).  Along
   v the energy falls quadratically, vᵀ A v = μ₁ vᵀ D v < 0: the line search of
   :mod:`.energy_search` follows it off a saddle (a strip buckles; a perfect one would
   otherwise stay straight).  Its sign is fixed by the data alone: the sign of the energy
   slope R·v, or where that is round-off (a symmetric saddle), of v's projection on a
   fixed generic field of the DoF coordinates — the same on any number of ranks.
   Up to :data:`GATHERED_DIRECTION_SIZE` unknowns A_τ is gathered once onto rank 0 and the
   iteration runs there on its dense inverse (then v is scattered back): the same
   iteration and stopping test, without the distributed solve, products and norms of each
   iteration — messages that cost more than the arithmetic of so small a system on more
   than one rank.  Above that size (or with the attribute ``gather_direction`` False) each
   iteration solves with the distributed factorization.

The inertia is the count of :func:`contact.models.hyperelastic.negative_eigenvalues` at an
iterate (with the law's diagonal on the contact rows), so no extra factorization is made
when the tangent is definite.
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..base.norms import norm2
from .linear import ReducedNewtonSystem, factor_inertia, gather_factor, gathers
from .problem import DiscreteProblem

TAU_MIN = 1e-6  # the first shift, relative to diag(K)
TAU_GROWTH = 10.0  # the shift grows by this factor until the inertia is right
MAX_SHIFTS = 12  # τ up to TAU_MIN · 10¹¹: beyond it the step is a scaled gradient step anyway
INVERSE_ITERATIONS = 60  # most; stops when the residual of the pencil ...
EIGEN_RTOL = 1e-8  # ... ‖A v − μ D v‖ ≤ EIGEN_RTOL ‖A_τ v‖
#: most unknowns for which the inverse iteration runs on rank 0 on A_τ gathered and
#: inverted densely (module doc, 2.); 0: always the distributed factorization
GATHERED_DIRECTION_SIZE = 2000

#: PETSc options of the LDLᵀ factorization (the user's ``solver.petsc_options`` may add to them)
CURVATURE_PETSC_OPTIONS = {
    "ksp_type": "preonly",
    "pc_type": "cholesky",
    "pc_factor_mat_solver_type": "mumps",
    "mat_mumps_icntl_13": 1,  # the root node without ScaLAPACK: the global inertia
    "mat_mumps_icntl_24": 1,  # null pivots detected (a singular A counts as not definite)
}


class CurvatureSystem(ReducedNewtonSystem):
    """:class:`.linear.ReducedNewtonSystem` factorized by LDLᵀ, with the inertia of each
    Newton step's A, the shift that makes it positive definite and, on request, the
    direction of negative curvature (module doc).  After each Newton law: ``negative``
    (n₋ + n₀ of the unshifted A), ``shift`` (τ, 0 if none), ``factorizations`` (this law's)."""

    #: the direction's inverse iteration on A_τ gathered onto rank 0 when it is small
    #: (:data:`GATHERED_DIRECTION_SIZE`); False: always with the distributed factorization
    gather_direction = True
    #: a small system on several ranks factorized whole on every rank
    #: (:class:`.linear.GatheredFactor`, :data:`.linear.GATHERED_FACTOR_SIZE`) when the options
    #: ask for MUMPS's LDLᵀ; False: MUMPS across the ranks
    gather_factor = True

    def __init__(self, problem: DiscreteProblem, prefix: str, forcing: bool = False):
        super().__init__(problem, prefix, forcing=forcing)
        self.lag = False
        n = self.K.getLocalSize()[0]
        outside = np.ones(n, dtype=bool)  # free rows outside the contact set and Γ_D
        outside[problem.constraint.dofs] = False
        outside[problem.dirichlet_rows()] = False
        self.outside = outside
        self.D = self.K.createVecLeft()  # τ's diagonal: |K_ii| on the rows outside
        self.z = self.K.createVecLeft()  # the generic field that fixes v's sign
        X = problem.V.tabulate_dof_coordinates()
        bs = problem.V.dofmap.index_map_bs
        node, comp = np.divmod(np.arange(n), bs)
        self.z.array_w[:] = X[node] @ np.array([1.0, np.sqrt(2.0), np.sqrt(3.0)]) + np.pi * comp
        self.negative, self.shift, self.factorizations = 0, 0.0, 0
        self.Kmax = 0.0  # the largest entry of D (overflow guard of the shift)
        self.total_factorizations = 0
        self._tau_last = 0.0
        self._polishing = False
        self._direction: PETSc.Vec | None = None  # v of the current law, once computed
        self.curvature = np.nan  # μ₁ of the current law (the Rayleigh quotient of v)
        self.inverse_iterations = 0  # of the last direction

    def set_options(self) -> None:
        super().set_options()
        self.lag = False  # a factorization, not a preconditioner to lag
        pc = self.ksp.getPC()
        mumps = pc.getType() == "cholesky" and pc.getFactorSolverType() == "mumps"
        if self.gather_factor and mumps and gathers(self.A):
            gather_factor(pc, "cholesky")

    def set_law(self, s: PETSc.Vec, d: PETSc.Vec) -> None:
        """A for the law (s, d) at the current K_T, factorized; the Newton step's law (not a
        polishing law) gets the inertia test and the shift (module doc)."""
        self._held = None  # K = K_T(x) changed since: A is always rebuilt
        self.K.getDiagonal(self.Kdiag)
        super().set_law(s, d)
        self._set_shift_diagonal()
        self.ksp.setOperators(self.A, self.A)
        negative = self._factor()
        self.factorizations = 1
        if self._direction is not None:
            self._direction.destroy()
            self._direction = None
        self.curvature = np.nan
        if self._polishing:
            return
        self.negative, self.shift = negative, 0.0
        tau, added = max(TAU_MIN, self._tau_last / 4), 0.0
        while negative and self.factorizations <= MAX_SHIFTS:
            if not np.isfinite(tau * self.Kmax):  # K_T's entries overflow (cells collapsed)
                break
            self.A.setDiagonal(self._scaled(self.D, tau - added), addv=PETSc.InsertMode.ADD_VALUES)  # type: ignore[arg-type]
            added = tau
            negative = self._factor()
            self.factorizations += 1
            tau *= TAU_GROWTH
        self.shift = added
        self._tau_last = added

    #: a factorization: a polishing solve is exact at once (not staged, :mod:`.polish`)
    resumable = False

    def solve_law(self, s, d, F, y, rtol=None, resume=False) -> None:
        """Polishing: its law's solve, without the inertia test (module doc)."""
        self._polishing = True
        try:
            super().solve_law(s, d, F, y, rtol=rtol, resume=resume)
        finally:
            self._polishing = False

    def negative_direction(self) -> PETSc.Vec | None:
        """v (D-normalized, vᵀ D v = 1) of the most negative eigenvalue μ₁ of the pencil
        (A, D) of the current Newton law, by inverse iteration with A_τ's factorization
        (module doc); ``curvature`` = μ₁.  None when the tangent was definite (no shift)."""
        if not self.shift:
            return None
        if self._direction is not None:
            return self._direction
        if self._gathers():
            v, mu = self.gathered_direction()
            self.curvature = mu
            if not mu < 0:
                v.destroy()
                return None
            self._direction = v
            return v
        v, w, Dv = self.D.duplicate(), self.D.duplicate(), self.D.duplicate()
        v.pointwiseMult(self.D, self.z)  # a generic start in the rows D acts on
        mu = np.nan
        for self.inverse_iterations in range(1, INVERSE_ITERATIONS + 1):
            Dv.pointwiseMult(self.D, v)
            self.ksp.solve(Dv, w)  # w = A_τ⁻¹ D v
            w.copy(v)
            Dv.pointwiseMult(self.D, v)
            vDv = float(v.dot(Dv).real)
            if not vDv > 0:
                break
            v.scale(1.0 / np.sqrt(vDv))
            Dv.scale(1.0 / np.sqrt(vDv))
            self.A.mult(v, w)
            size = norm2(w)  # ‖A_τ v‖: the scale of its round-off
            w.axpy(-self.shift, Dv)  # w = A v = A_τ v − τ D v
            mu = float(v.dot(w).real)  # vᵀ A v / vᵀ D v
            w.axpy(-mu, Dv)  # the pencil's residual A v − μ D v
            if norm2(w) <= EIGEN_RTOL * size:
                break
        w.destroy()
        Dv.destroy()
        self.curvature = mu
        if not mu < 0:  # the shift made a zero pivot definite: no direction of descent
            v.destroy()
            return None
        self._direction = v
        return v

    def _gathers(self) -> bool:
        """Whether the direction is computed on A_τ gathered onto rank 0 (module doc, 2.):
        on more than one rank, up to :data:`GATHERED_DIRECTION_SIZE` unknowns."""
        size = self.D.getSize()
        return (
            self.gather_direction and self.D.getComm().size > 1 and size <= GATHERED_DIRECTION_SIZE
        )

    def gathered_direction(self) -> tuple[PETSc.Vec, float]:
        """v and μ₁ of :meth:`negative_direction` by the same inverse iteration, run on rank 0
        on A_τ gathered in the global row order and inverted densely; v scattered back
        (collective: one gather, one broadcast and one scatter; a singular A_τ is a
        LinAlgError on every rank)."""
        comm = self.D.getComm().tompi4py()
        indptr, indices, values = self.A.getValuesCSR()
        parts = comm.gather((indptr, indices, values, self.D.array_r.copy(), self.z.array_r.copy()))
        lo, hi = self.D.getOwnershipRange()
        result: tuple[np.ndarray, float, int] | np.linalg.LinAlgError | None = None
        if comm.rank == 0:
            assert parts is not None
            n = self.D.getSize()
            A = np.zeros((n, n))
            start = 0
            for ip, ind, val, Dl, _ in parts:
                rows = np.repeat(np.arange(start, start + len(Dl)), np.diff(ip))
                A[rows, ind] = val
                start += len(Dl)
            D = np.concatenate([p[3] for p in parts])
            z = np.concatenate([p[4] for p in parts])
            try:
                result = _inverse_iteration(A, D, z, self.shift)
            except np.linalg.LinAlgError as exc:  # every rank raises it, none waits in bcast
                result = exc
        result = comm.bcast(result if comm.rank == 0 else None)
        if isinstance(result, np.linalg.LinAlgError):
            raise np.linalg.LinAlgError(f"the gathered A_τ of the curvature direction: {result}")
        v_all, mu, self.inverse_iterations = result
        v = self.D.duplicate()
        v.array_w[:] = v_all[lo:hi]
        return v, mu

    def orientation(self, v: PETSc.Vec) -> float:
        """vᵀ z: v's projection on the fixed generic field (sign of a direction on a saddle)."""
        return float(v.dot(self.z).real)

    def _set_shift_diagonal(self) -> None:
        D = self.D.array_w
        D[:] = np.where(self.outside & ~self.fixed, np.abs(self.Kdiag.array_r), 0.0)
        self.Kmax = float(self.D.norm(PETSc.NormType.INFINITY))  # type: ignore[arg-type]

    def _scaled(self, D: PETSc.Vec, tau: float) -> PETSc.Vec:
        self.work.array_w[:] = tau * D.array_r
        return self.work

    def _factor(self) -> int:
        """Factorize A (its current values); the number of its negative and zero eigenvalues."""
        pc = self.ksp.getPC()
        self.ksp.setOperators(self.A, self.A)  # new values: a new numerical factorization
        self.ksp.setUp()
        self.total_factorizations += 1
        negative, zero, _ = factor_inertia(pc)
        return int(negative) + int(zero)

    def destroy(self) -> None:
        super().destroy()
        for obj in (self.D, self.z, self._direction):
            if obj is not None:
                obj.destroy()


def _inverse_iteration(
    A: np.ndarray, D: np.ndarray, z: np.ndarray, shift: float
) -> tuple[np.ndarray, float, int]:
    """The inverse iteration of :meth:`CurvatureSystem.negative_direction` on a dense A_τ:
    (v, μ₁, iterations), v D-normalized (μ₁ NaN if vᵀ D v vanished at once)."""
    inverse = np.linalg.inv(A)
    v = D * z
    mu, iterations = np.nan, 0
    for iterations in range(1, INVERSE_ITERATIONS + 1):  # noqa: B007  (the count is returned)
        v = inverse @ (D * v)
        Dv = D * v
        vDv = float(v @ Dv)
        if not vDv > 0:
            break
        v /= np.sqrt(vDv)
        Dv /= np.sqrt(vDv)
        w = A @ v
        size = float(np.linalg.norm(w))
        w -= shift * Dv
        mu = float(v @ w)
        w -= mu * Dv
        if np.linalg.norm(w) <= EIGEN_RTOL * size:
            break
    return v, mu, iterations
