"""The energy search's Newton system solved by CG + GAMG, with an indefiniteness test that
needs no factorization (large 3D hyperelastic bodies).

:class:`.curvature.CurvatureSystem` reads the inertia of the reduced Newton matrix

    A = P K_T P + diag(d/s on the free rows, 1 on the fixed rows)

from its LDLᵀ factorization.  On a 3D mesh of a few hundred thousand DoFs that
factorization costs more memory and time than the rest of the Newton step together, while
CG preconditioned by algebraic multigrid (GAMG, the rigid-body near-nullspace) solves the
same system in tens of iterations.  :class:`KrylovCurvatureSystem` keeps CG + GAMG and tests
for indefiniteness with what the Krylov solve gives for free:

1. **negative curvature in CG** — CG breaks down (``DIVERGED_INDEFINITE_MAT``) when a search
   direction p has pᵀ A p ≤ 0, a direct proof that A is not positive definite;
2. **a Lanczos estimate** — CG's coefficients are those of the Lanczos process of the
   preconditioned operator M⁻¹A; the eigenvalues θ of its tridiagonal matrix (Ritz values,
   ``KSPComputeEigenvalues``) lie within the spectrum of M⁻¹A, and for a positive definite
   preconditioner M the spectrum of M⁻¹A has the signs of the spectrum of A (Sylvester's law
   of inertia applied to M^{−1/2} A M^{−1/2}), so min θ < 0 proves indefiniteness;
3. **the step's curvature** — the computed step y itself: yᵀ A y ≤ 0 (one product).

A GAMG hierarchy built from an indefinite A may be indefinite itself
(``DIVERGED_INDEFINITE_PC``); that counts as indefinite too, so the test errs on the side of
the shift.  The test detects indefiniteness; it does not certify definiteness (a negative
eigenvalue that the right-hand side does not excite stays unseen) and it does not count the
negative eigenvalues: ``negative`` is 1 ("at least one") when the test fires.

Where it fires the tangent is shifted as with the factorization, A_τ = A + τ D (τ = τ₀,
10 τ₀, … until the test passes), and the direction of negative curvature is computed by the
same inverse iteration v ← A_τ⁻¹ D v, each application one CG + GAMG solve to
:data:`INVERSE_RTOL` (:meth:`.curvature.CurvatureSystem.negative_direction`).

:func:`lanczos_negative` applies the same estimate to a stand-alone symmetric matrix (the
per-step stability count of a load path, :func:`contact.models.hyperelastic.negative_eigenvalues`,
when the solve used this system).
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..base.norms import norm2
from .curvature import MAX_SHIFTS, TAU_GROWTH, TAU_MIN, CurvatureSystem
from .problem import DiscreteProblem
from .reduced import ReducedSystem

#: a Ritz value below −RITZ_RTOL · (the largest one) counts as negative (round-off of the
#: Lanczos recurrence stays orders of magnitude below)
RITZ_RTOL = 1e-8
#: the relative tolerance of each CG solve of the inverse iteration
INVERSE_RTOL = 1e-6
#: the Lanczos estimate of :func:`lanczos_negative`: its CG solve's tolerance and length
LANCZOS_RTOL = 1e-8
LANCZOS_MAX_IT = 400

_INDEFINITE = (
    PETSc.KSP.ConvergedReason.DIVERGED_INDEFINITE_MAT,
    PETSc.KSP.ConvergedReason.DIVERGED_INDEFINITE_PC,
)


def ritz_negative(ksp: PETSc.KSP) -> bool:
    """Whether the Ritz values of the last CG solve of ``ksp`` (set up with
    ``setComputeEigenvalues(True)``) include a negative one (module doc, 2; collective: the
    tridiagonal matrix is the same on every rank)."""
    if ksp.getIterationNumber() < 1:
        return False
    theta = np.real(np.asarray(ksp.computeEigenvalues()))
    if not len(theta):
        return False
    top = float(np.max(np.abs(theta)))
    return bool(np.min(theta) < -RITZ_RTOL * top)


class KrylovCurvatureSystem(CurvatureSystem):
    """:class:`.curvature.CurvatureSystem` solved by CG + GAMG (module doc): the Newton step
    of each law is a CG solve (Eisenstat–Walker forcing with ``forcing``) whose breakdown,
    Ritz values and the step's own curvature decide whether A is positive definite; if not,
    the shifted A_τ is solved instead.  The attributes after each Newton solve are those of
    the factorized system: ``negative`` (1 when the test fired, else 0), ``shift`` (τ),
    ``factorizations`` (here: the CG solves of the step, one per shift tried)."""

    gather_direction = False  # each application of A_τ⁻¹ a CG solve (negative_direction)
    resumable = True  # a polishing solve may be staged (.polish)

    def __init__(self, problem: DiscreteProblem, prefix: str, forcing: bool = True):
        super().__init__(problem, prefix, forcing=forcing)
        self.ksp.setComputeEigenvalues(True)
        self._probing = False  # a Newton solve whose breakdown is a finding, not an error
        self.tests = {"breakdown": 0, "ritz": 0, "step": 0}  # what fired, over all solves

    def set_options(self) -> None:
        """The inner KSP's options (CG + GAMG by default), no lagging: K_T changes at every
        iterate, GAMG is set up again for each Newton step (its interpolation reused)."""
        ReducedSystem.set_options(self)
        self.lag = False
        self.ksp.setComputeEigenvalues(True)

    def set_law(self, s: PETSc.Vec, d: PETSc.Vec) -> None:
        """A for the law (s, d) at the current K_T (always rebuilt: K_T changed); the test
        and the shift come with the Newton solve (:meth:`solve`)."""
        self._held = None
        self.K.getDiagonal(self.Kdiag)
        ReducedSystem.set_law(self, s, d)
        self._set_shift_diagonal()
        self.factorizations = 0
        if self._direction is not None:
            self._direction.destroy()
            self._direction = None
        self.curvature = np.nan
        if not self._polishing:
            self.negative, self.shift = 0, 0.0

    def solve(
        self,
        F: PETSc.Vec,
        y: PETSc.Vec,
        newton: bool = False,
        rtol: float | None = None,
        resume: bool = False,
    ) -> None:
        """y = A⁻¹ r (:meth:`.reduced.ReducedSystem.solve`); a Newton solve (``newton``) is
        tested for indefiniteness and repeated with the shifted A_τ until the test passes
        (module doc)."""
        if not newton or self._polishing:
            super().solve(F, y, newton=newton, rtol=rtol, resume=resume)
            return
        self._probing = True
        try:
            super().solve(F, y, newton=True)
            eta = self.log[-1]["rtol"]
            self.factorizations = 1
            negative = self._indefinite(y)
            self.negative = int(negative)
            tau, added = max(TAU_MIN, self._tau_last / 4), 0.0
            while negative and self.factorizations <= MAX_SHIFTS:
                if not np.isfinite(tau * self.Kmax):
                    break
                shift = self._scaled(self.D, tau - added)
                add = PETSc.InsertMode.ADD_VALUES
                self.A.setDiagonal(shift, addv=add)  # type: ignore[arg-type]
                added = tau
                self._rebuild()
                super().solve(F, y, rtol=eta)
                self.factorizations += 1
                negative = self._indefinite(y)
                tau *= TAU_GROWTH
            self.shift = added
            self._tau_last = added
        finally:
            self._probing = False

    def _indefinite(self, y: PETSc.Vec) -> bool:
        """Whether the last CG solve shows A indefinite (module doc, 1–3; collective)."""
        if self.last_reason in _INDEFINITE:
            self.tests["breakdown"] += 1
            return True
        if ritz_negative(self.ksp):
            self.tests["ritz"] += 1
            return True
        Ay = y.duplicate()
        self.A.mult(y, Ay)
        curvature = float(y.dot(Ay).real)
        size = norm2(Ay) * norm2(y)
        Ay.destroy()
        if size > 0 and curvature <= -RITZ_RTOL * size:
            self.tests["step"] += 1
            return True
        return False

    def _start_over(self, y: PETSc.Vec, rtol: float, atol: float, r0: float) -> int:
        """A breakdown of a Newton solve is the test's finding (the shift follows), not a
        hierarchy to rebuild; other breakdowns as in :class:`.reduced.ReducedSystem`."""
        if self._probing and self.last_reason in _INDEFINITE:
            return 0
        return super()._start_over(y, rtol, atol, r0)

    def negative_direction(self) -> PETSc.Vec | None:
        """v of :meth:`.curvature.CurvatureSystem.negative_direction`, each application of
        A_τ⁻¹ a CG + GAMG solve to :data:`INVERSE_RTOL` (A_τ is positive definite)."""
        if not self.shift or self._direction is not None:
            return super().negative_direction()
        rtol, atol, dtol, max_it = self.ksp.getTolerances()
        self.ksp.setTolerances(rtol=INVERSE_RTOL, atol=0.0, max_it=self._max_it)
        try:
            return super().negative_direction()
        finally:
            self.ksp.setTolerances(rtol=rtol, atol=atol, divtol=dtol, max_it=max_it)


class GamgSolver:
    """A stand-alone CG + GAMG solver of a symmetric matrix A (the 3D elasticity defaults
    of :func:`.options.default_options`, the near-nullspace on its copy that GAMG is built
    from): the tangent predictor's and the Lanczos estimate's linear solves where the rest
    of the solve is iterative.  ``prefix`` names its options; use it as a context manager
    (its PETSc objects and options are released on exit)."""

    def __init__(
        self,
        A: PETSc.Mat,
        near_nullspace: PETSc.NullSpace | None,
        tdim: int,
        prefix: str,
        rtol: float,
        max_it: int = 10000,
    ):
        from .options import default_options, petsc_value

        self.ksp = PETSc.KSP().create(A.getComm())
        self.ksp.setOptionsPrefix(prefix)
        self.P = A.duplicate(copy=True)
        if near_nullspace is not None:
            self.P.setNearNullSpace(near_nullspace)
        self.ksp.setOperators(A, self.P)
        self.prefix = prefix
        self.defaults = default_options("gamg", tdim, A.getComm().getSize())
        opts = PETSc.Options()
        for key, val in self.defaults.items():
            opts.setValue(prefix + key, petsc_value(val))
        self.ksp.setFromOptions()
        self.ksp.setTolerances(rtol=rtol, atol=0.0, max_it=max_it)

    def __enter__(self) -> GamgSolver:
        return self

    def __exit__(self, *exc) -> None:
        opts = PETSc.Options()
        for key in self.defaults:
            opts.delValue(self.prefix + key)
        self.ksp.destroy()
        self.P.destroy()


def lanczos_negative(
    A: PETSc.Mat, near_nullspace: PETSc.NullSpace | None, tdim: int, prefix: str
) -> int:
    """1 if the symmetric matrix A shows a negative eigenvalue to the Lanczos estimate of a
    CG + GAMG solve (module doc; a fixed pseudo-random right-hand side, the same on any
    number of ranks for the same global numbering), else 0 — "at least one", not a count.
    ``tdim``: the mesh's dimension (GAMG's defaults); ``prefix``: the options prefix of the
    KSP.  Collective."""
    b, x = A.createVecLeft(), A.createVecRight()
    try:
        with GamgSolver(A, near_nullspace, tdim, prefix, LANCZOS_RTOL, LANCZOS_MAX_IT) as gs:
            gs.ksp.setComputeEigenvalues(True)
            lo, hi = A.getOwnershipRange()
            rng = np.random.default_rng(12345)
            # the same vector on any partition: generated for the global rows, sliced
            b.array_w[:] = rng.standard_normal(A.getSize()[0])[lo:hi]
            gs.ksp.solve(b, x)
            if gs.ksp.getConvergedReason() in _INDEFINITE:
                return 1
            return int(ritz_negative(gs.ksp))
    finally:
        b.destroy()
        x.destroy()
