"""Bring your own forms: the complementarity problem of any UFL forms, solved by our
semismooth Newton (or PETSc's VI solvers), with no scene.

Given a residual F(u; v) on a space V (Lagrange, one value per node) — a bilinear form
a(u, v) with a load L(v), F = a(u, v) − L(v), or any form nonlinear in u with its
derivative J = ∂F/∂u — Dirichlet conditions, and a unilateral constraint at a set of nodes
C, the problem is (SPEC §2)

    R_i(u) = w_i λ_i   (i ∈ C),     R_i(u) = 0   (i ∉ C, not Dirichlet),
    σ (g_i − u_i) ≥ 0,   −σ λ_i ≥ 0,   (g_i − u_i) λ_i = 0   (i ∈ C),

with R_i(u) = F(u; φ_i), σ = +1 for u ≤ g (``side="upper"``) and −1 for u ≥ g
(``side="lower"``), lumped weights w_i = ∫ φ_i over the constraint's measure (dx: the
obstacle problem; ds(tag): a Signorini condition on the tagged facets) or given, and λ_h the
nodal multiplier density: F(u_h; v) = Σ_i w_i λ_i v_i.  A linear problem is assembled once
(K, b); a nonlinear one re-assembles R(x) and its tangent K_T(x) = J(x) at every Newton
iterate (:class:`ResidualProblem`).

    problem = ComplementarityProblem.from_residual(F, u, Unilateral(psi, side="lower"), [bc])
    result = problem.solve(method="fb")      # result.u_h is u; result.lmbda_h, .active, .history
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import dolfinx.fem.petsc
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base.timing import Stopwatch
from ..solvers.options import SolverOptions
from ..solvers.problem import Constraint, DiscreteProblem
from ..solvers.result import Result
from ..solvers.snes import solve_problem
from . import form_checks as checks
from .constraints import Unilateral
from .discrete import Problem
from .physics import Physics
from .problem import assemble_system


@dataclass
class ResidualProblem(Problem):
    """A discrete problem with a nonlinear residual: R(x) = F(x; ·) and K = J(x) are
    re-assembled at each iterate (x is copied into ``u_h``, the function F is written in).
    Dirichlet rows: R_i = x_i − g_i and J's identity rows, as for K x − b."""

    F_form: fem.Form | None = None
    J_form: fem.Form | None = None
    #: Π(u) with F = ∂Π/∂u, when the residual is the gradient of an energy (hyperelasticity)
    energy_form: fem.Form | None = None
    #: the smallest det F of the current u_h (collective), where Π is +∞ for det F ≤ 0
    min_jacobian: Callable[[], float] | None = None
    _F: PETSc.Vec | None = field(default=None, repr=False)

    nonlinear = True

    @property
    def has_energy(self) -> bool:  # type: ignore[override]
        return self.energy_form is not None

    def admissible(self, x: PETSc.Vec) -> bool:
        """Whether u = x inverts no matter: det F > 0 at every point :attr:`min_jacobian`
        checks (True without it; collective).  Leaves u_h = x."""
        self._set_iterate(x)
        return self.min_jacobian is None or self.min_jacobian() > 0

    def energy(self, x: PETSc.Vec) -> float:
        """Π(x) = ∫ ψ dX − L(u) at u = x (the Dirichlet values are x's own); +∞ where u
        inverts matter (det F ≤ 0 somewhere, with :attr:`min_jacobian`): no deformation is
        admissible there, whatever a law's ψ says (St Venant–Kirchhoff's is finite, even
        zero for a reflection)."""
        assert self.energy_form is not None, "energy: the problem has no energy form"
        if not self.admissible(x):
            return np.inf
        local = fem.assemble_scalar(self.energy_form)
        return float(self.V.mesh.comm.allreduce(local, op=MPI.SUM))

    @staticmethod
    def matrices(J_form: fem.Form, bcs: list) -> tuple[PETSc.Mat, PETSc.Vec]:
        """(K, b) to build it with: K = J(u) at the current u (the pattern of every K_T(x)),
        b = 0 (R(x) = K x − b is never used)."""
        K = dolfinx.fem.petsc.assemble_matrix(J_form, bcs=bcs)
        K.assemble()
        b = dolfinx.fem.petsc.create_vector(J_form.function_spaces[0])
        b.set(0.0)
        return K, b

    def _forms(self) -> tuple[fem.Form, fem.Form]:
        """(F, J): always given (the builders pass them; None only as dataclass defaults)."""
        assert self.F_form is not None and self.J_form is not None, "F_form, J_form not set"
        return self.F_form, self.J_form

    def _set_iterate(self, x: PETSc.Vec) -> None:
        u = self.u_h.x
        u.petsc_vec.array_w[:] = x.array_r
        u.scatter_forward()

    def residual(self, x: PETSc.Vec, out: PETSc.Vec) -> None:
        """out = R(x) = F(x; φ_i), x_i − g_i on Dirichlet rows."""
        self._set_iterate(x)
        if self._F is None:
            self._F = dolfinx.fem.petsc.create_vector(self.V)
        F, u = self._F, self.u_h.x.petsc_vec
        F_form, J_form = self._forms()
        with F.localForm() as local:
            local.set(0.0)
        # assemble_vector(Vec, form): the overload into an existing vector (not in the stubs)
        dolfinx.fem.petsc.assemble_vector(F, F_form)  # type: ignore[arg-type]
        dolfinx.fem.petsc.apply_lifting(F, [J_form], bcs=[self.bcs], x0=[u], alpha=-1.0)
        add, reverse = PETSc.InsertMode.ADD, PETSc.ScatterMode.REVERSE
        F.ghostUpdate(addv=add, mode=reverse)  # type: ignore[arg-type]
        dolfinx.fem.petsc.set_bc(F, self.bcs, u, -1.0)
        out.array_w[:] = F.array_r

    def _assemble_tangent(self, A: PETSc.Mat) -> None:
        """A = J(u_h) at the current ``u_h`` into A's pattern (that of :meth:`matrices`),
        Dirichlet rows and columns identity."""
        J_form = self._forms()[1]
        A.zeroEntries()
        # assemble_matrix(Mat, form, bcs): the overload into an existing matrix (not in the
        # stubs, which read the Mat as the form and the form as bcs)
        assemble = dolfinx.fem.petsc.assemble_matrix
        assemble(A, J_form, bcs=self.bcs)  # type: ignore[arg-type, misc]
        A.assemble()

    def linearize(self, x: PETSc.Vec) -> None:
        """K = J(x), Dirichlet rows and columns identity (same sparsity each time)."""
        self._set_iterate(x)
        self._assemble_tangent(self.K)

    def full_tangent(self, x: PETSc.Vec) -> PETSc.Mat:
        """A new matrix J(x) with the Dirichlet rows and columns kept (the coupling of a
        prescribed increment into the free rows: the tangent predictor,
        :mod:`contact.solvers.predictor`); the caller destroys it."""
        self._set_iterate(x)
        A = dolfinx.fem.petsc.assemble_matrix(self._forms()[1])
        A.assemble()
        return A

    def destroy(self) -> None:
        super().destroy()
        if self._F is not None:
            self._F.destroy()


class ComplementarityProblem:
    """A complementarity problem of the user's forms (module docstring) and its solver.

    Build it with :meth:`from_forms` (linear: a, L) or :meth:`from_residual` (F, J), then
    :meth:`solve`; it owns PETSc objects (K, b): :meth:`close` it, or use ``with``.

    The builders check every argument before assembling anything
    (:mod:`~contact.models.form_checks`), on every rank alike: a form of the wrong rank,
    on another space or mesh, a Dirichlet condition on another space, a measure that
    selects nothing, DoFs that are not owned integer indices, weights that are not finite
    and positive, a bound that is not finite or a callable bound of the wrong shape is one
    ``TypeError`` or ``ValueError`` line naming the argument, raised on all ranks."""

    def __init__(self, problem: DiscreteProblem):
        self.problem: DiscreteProblem | None = problem  # None once closed
        self._comm = problem.V.mesh.comm

    @classmethod
    def from_forms(
        cls,
        a: ufl.Form,
        L: ufl.Form,
        u: fem.Function,
        constraint: Unilateral,
        bcs: Sequence[fem.DirichletBC] = (),
        physics: Physics | None = None,
    ) -> ComplementarityProblem:
        """K u − b = w λ from a(u, v) = L(v) (``u`` receives the solution: u_h).

        Args:
            a: the bilinear form a(w, v) (a trial function w and a test function v on u's
                space), a UFL form or a compiled ``dolfinx.fem.Form``.
            L: the linear form L(v) (a test function on u's space).
            u: the Function that receives the solution (and is the initial guess).
            constraint: where and how u is bounded.
            bcs: Dirichlet conditions on u's space (or its subspaces).
            physics: the equations the forms discretise (:mod:`~contact.models.physics`),
                which the estimators read; None: no estimate.

        Returns:
            The problem, K and b assembled once; close it (or use ``with``)."""
        t0 = time.perf_counter()
        V, bcs = _checked(u, bcs, constraint, [("a", a, 2), ("L", L, 1)])
        return cls(
            _discrete(
                Problem,
                u,
                bcs,
                lambda: assemble_system(fem.form(a), fem.form(L), bcs),
                constraint,
                t0,
                physics,
            )
        )

    @classmethod
    def from_residual(
        cls,
        F: ufl.Form,
        u: fem.Function,
        constraint: Unilateral,
        bcs: Sequence[fem.DirichletBC] = (),
        J: ufl.Form | None = None,
        physics: Physics | None = None,
    ) -> ComplementarityProblem:
        """R(u) = w λ from a residual F(u; v), nonlinear in the Function ``u`` it is written
        in, and J = ∂F/∂u (default ``ufl.derivative(F, u)``); ``u``'s values are the initial
        guess and receive the solution.

        Args:
            F: the residual F(u; v), a linear form in the test function v on u's space,
                written in u.
            u: the Function F is written in: the initial guess, then the solution.
            constraint: where and how u is bounded.
            bcs: Dirichlet conditions on u's space (or its subspaces).
            J: the bilinear form ∂F/∂u (default ``ufl.derivative(F, u)``; required when F
                is a compiled ``dolfinx.fem.Form``).
            physics: the equations F discretises (:mod:`~contact.models.physics`), which the
                estimators read; None: no estimate.

        Returns:
            The problem, R and its tangent re-assembled at every Newton iterate; close it
            (or use ``with``)."""
        t0 = time.perf_counter()
        forms = [("F", F, 1)] + ([("J", J, 2)] if J is not None else [])
        V, bcs = _checked(u, bcs, constraint, forms, residual=(F, J))
        J = ufl.derivative(F, u) if J is None else J
        F_form, J_form = fem.form(F), fem.form(J)
        problem = _discrete(
            ResidualProblem,
            u,
            bcs,
            lambda: ResidualProblem.matrices(J_form, bcs),
            constraint,
            t0,
            physics,
        )
        problem.F_form, problem.J_form = F_form, J_form
        return cls(problem)

    def solve(self, method: str = "fb", verbose: bool = False, **options: Any) -> Result:
        """Solve from u's current values (Dirichlet values put in).

        Args:
            method: fb, min, blend, vinewtonrsls or vinewtonssls.
            verbose: print the Newton history (rank 0).
            options: any other field of :class:`~contact.solvers.options.SolverOptions`
                (``rtol``, ``max_it``, ``petsc_options``, …; a bad one: ConfigError naming
                it).

        Returns:
            The :class:`~contact.solvers.result.Result` (never raises on divergence):
            ``u_h`` (the user's u), ``lmbda_h``, ``active``, ``history``, ``converged``,
            ``reason``.  After :meth:`close` a RuntimeError; an initial guess that is not
            finite a ValueError (on every rank)."""
        opts = SolverOptions.parse({"method": method, **options})

        def ready() -> DiscreteProblem:
            if self.problem is None:
                raise RuntimeError(
                    "ComplementarityProblem.solve: the problem is closed (close(), or the end "
                    "of its with-block, destroyed K and b); build a new one"
                )
            checks.check_initial_guess(self.problem.u_h)
            return self.problem

        p = checks.agree(self._comm, ready)
        timers = {"assembly": p.assembly_time, "solve": 0.0}
        return solve_problem(
            p,
            p.u_h,
            opts,
            p.V.mesh.comm,
            verbose,
            False,
            timers,
            Stopwatch(before=p.assembly_time),
            check_options=bool(opts.petsc_options),
        )

    def close(self) -> None:
        """Destroy the PETSc objects (K, b); the functions stay usable."""
        if self.problem is not None:
            self.problem.destroy()
            self.problem = None

    def __enter__(self) -> ComplementarityProblem:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _checked(
    u: Any,
    bcs: Any,
    constraint: Any,
    forms: list[tuple[str, Any, int]],
    residual: tuple[Any, Any] | None = None,
) -> tuple[fem.FunctionSpace, list]:
    """(V, bcs as a list) once every argument passed its local checks on every rank
    (:mod:`~contact.models.form_checks`): the forms' (name, form, rank), F written in u
    (``residual`` = (F, J)), the Dirichlet conditions, the constraint — and the number of
    Dirichlet conditions and the constraint's shape are the same on every rank."""
    V = checks.check_unknown(u).function_space
    bc_list = checks.bcs_list(bcs)

    def local() -> dict[str, object]:
        for name, form, rank in forms:
            checks.check_form(name, form, rank, V)
        if residual is not None:
            checks.check_written_in(*residual, u=u)
        checks.check_bcs(bc_list, V)
        if not isinstance(constraint, Unilateral):
            raise TypeError(
                f"constraint: expected a contact.Unilateral, got {type(constraint).__name__}"
            )
        return {"bcs": len(bc_list or ()), **checks.check_constraint(constraint, V)}

    checks.agree(V.mesh.comm, local, same=True)
    assert bc_list is not None  # check_bcs refused None
    return V, bc_list


def _discrete[P: Problem](
    kind: type[P],
    u: fem.Function,
    bcs: list,
    matrices: Callable[[], tuple[PETSc.Mat, PETSc.Vec]],
    constraint: Unilateral,
    t0: float,
    physics: Physics | None = None,
) -> P:
    """The solver's problem: the constraint's nodes, weights and bound on u's space (checked
    collectively), then K and b from ``matrices()``."""
    V = u.function_space
    dofs, w = constraint.nodes(V, bcs)
    g = constraint.bound_function(V, dofs)
    fixed = V.mesh.comm.allreduce(sum(len(bc.dof_indices()[0]) for bc in bcs), op=MPI.SUM)
    in_domain = constraint.dofs is None and (
        constraint.measure is None or constraint.measure.integral_type() == "cell"
    )
    K, b = matrices()
    return kind(
        V,
        u,
        bcs,
        K,
        b,
        Constraint(dofs, g.x.array[dofs].copy(), w, constraint.sign),
        in_domain=in_domain,
        semicoercive=fixed == 0,
        data={"g_h": g},
        assembly_time=time.perf_counter() - t0,
        physics=physics,
        contacts=(constraint,),
    )
