"""Bring your own forms: the complementarity problem of any UFL forms.

Solved by our semismooth Newton (or PETSc's VI solvers), with no scene.

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
from .problem import assemble_system, lumped_weights

#: a bound: a number, a Function on V, values at the constrained DoFs, or f(x) → values
#: at points x of shape (3, n) (as ``Function.interpolate`` takes it)
Bound = float | fem.Function | np.ndarray | Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Unilateral:
    """A unilateral constraint u ≤ g (``side="upper"``) or u ≥ g (``side="lower"``).

    It holds at the nodes of a measure's cells or facets, with the lumped weights
    w_i = ∫ φ_i d(measure), or at explicit DoFs with given weights; the multiplier λ_h of
    the solve is then the density F(u_h; v) = Σ_i w_i λ_i v_i. Dirichlet DoFs are never
    constrained. A record: its fields are checked against u's space when a problem is built
    (``form_checks.check_constraint``), on every rank alike — the side,
    a bound that is finite (a callable's values of shape (n,) for points of shape (3, n)), a
    measure that selects some facet or cell, ``dofs`` that are owned integer indices given
    once each, ``weights`` finite and > 0; each a ``ValueError`` or ``TypeError`` naming the
    field.

    Args:
        bound: g: a number, a Function on V, values at the constrained DoFs, or a callable
            ``x -> values`` on points of shape (3, n) (as ``Function.interpolate`` takes it).
            On a vector space with ``component``, a scalar bound of that component.
        side: ``"upper"`` for u ≤ g, ``"lower"`` for u ≥ g.
        measure: ``ufl.dx`` (the default: every node of Ω, the obstacle problem) or
            ``ds(tag)`` with the facet tags as its ``subdomain_data`` (the nodes of those
            facets: a Signorini condition).
        dofs: Explicit owned local DoF indices of V (any components), instead of a measure.
        weights: The weights w_i of ``dofs`` (default 1: λ_i is then the nodal reaction).
        component: On a vector space, the component k the constraint acts on (u_k ≤ g or
            u_k ≥ g, e.g. the normal displacement against a plane).

    Example:
        >>> import contact
        >>> floor = contact.Unilateral(-0.1, side="lower")
        >>> floor.sign, floor.measure is None
        (-1.0, True)
    """

    bound: Bound
    side: str = "upper"
    measure: ufl.Measure | None = None
    dofs: np.ndarray | None = None
    weights: np.ndarray | None = None
    component: int | None = None

    @property
    def sign(self) -> float:
        """The constraint's sign σ, +1 for u ≤ g and −1 for u ≥ g."""
        return 1.0 if self.side == "upper" else -1.0

    def nodes(
        self, V: fem.FunctionSpace, bcs: Sequence[fem.DirichletBC]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the constrained owned DoFs (no Dirichlet DoF) and their weights.

        Collective; the constraint is checked first
        (``form_checks.check_constraint``).

        Args:
            V: The space of u.
            bcs: The Dirichlet conditions (their DoFs are not constrained).

        Returns:
            (dofs, w): owned local DoF indices and their weights.

        Raises:
            ValueError: On every rank, for a measure that selects nothing, a constraint
                left with no DoF on any rank, or constrained DoFs whose weight is not
                positive.
        """
        comm = V.mesh.comm
        n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        fixed = np.concatenate([bc.dof_indices()[0] for bc in bcs] or [np.zeros(0, np.int32)])
        if self.dofs is not None:
            dofs = np.asarray(self.dofs, dtype=np.int32)
            w = np.ones(len(dofs)) if self.weights is None else np.asarray(self.weights, float)
            keep = ~np.isin(dofs, fixed)
            checks.check_constrained(comm, dofs[keep], by_dofs=True)
            return dofs[keep], w[keep]
        measure = self.measure if self.measure is not None else ufl.dx(domain=V.mesh)
        dofs = _dofs_of(V, measure, self.component)
        dofs = np.setdiff1d(dofs[dofs < n_owned], fixed).astype(np.int32)
        checks.check_constrained(comm, dofs, by_dofs=False)
        w = lumped_weights(V, measure, self.component)[dofs]
        if comm.allreduce(bool(np.any(w <= 0)), op=MPI.LOR):
            raise ValueError(
                "Unilateral.measure: some constrained DoFs have ∫ φ_i = 0 "
                "(e.g. P2 vertices); use P1 or give dofs and weights"
            )
        return dofs, w

    def bound_function(self, V: fem.FunctionSpace, dofs: np.ndarray) -> fem.Function:
        """Return the bound g as a Function on V (at the constrained DoFs at least).

        Args:
            V: The space of u.
            dofs: The constrained DoFs (of :meth:`nodes`).

        Returns:
            g on V.

        Raises:
            ValueError: On every rank (collective), for a callable bound that fails or
                returns the wrong shape, values of the wrong length, or a bound that is not
                finite at some constrained DoF.
        """
        comm = V.mesh.comm
        g = fem.Function(V, name="bound")
        interpolated = isinstance(self.bound, fem.Function) or callable(self.bound)
        if interpolated and self.component is not None:  # a scalar bound on u_k's DoFs
            S, to_parent = V.sub(self.component).collapse()
            into = fem.Function(S)
        else:
            S, to_parent, into = V, None, g

        def assign() -> None:  # local: no collective
            bound = self.bound
            if isinstance(bound, fem.Function):
                into.interpolate(bound)
            elif callable(bound):
                into.interpolate(checks.shaped(bound, S))
            elif np.ndim(bound) == 0:
                g.x.array[:] = float(bound)
            else:
                values = np.asarray(bound, dtype=float)
                if values.shape != dofs.shape:
                    raise ValueError(
                        "Unilateral.bound: expected one value per constrained DoF "
                        f"({len(dofs)}), got shape {values.shape}"
                    )
                g.x.array[dofs] = values
            if to_parent is not None:
                g.x.array[to_parent] = into.x.array

        checks.agree(comm, assign)
        g.x.scatter_forward()
        checks.check_finite_bound(comm, g.x.array[dofs])
        return g


def _dofs_of(V: fem.FunctionSpace, measure: ufl.Measure, component: int | None) -> np.ndarray:
    """Return the constrained DoFs of a measure's cells or facets.

    The DoFs (local; of one ``component`` of a vector space) of the cells (``dx``) or
    exterior facets (``ds``) a measure covers (checked:
    :func:`~contact.models.form_checks.check_constraint`). Collective; a tagged measure
    that selects no entity on any rank is a ValueError.
    """
    msh, tdim = V.mesh, V.mesh.topology.dim
    kind, tag, tags = measure.integral_type(), measure.subdomain_id(), measure.subdomain_data()
    dim = tdim if kind == "cell" else tdim - 1
    if dim < tdim:
        msh.topology.create_connectivity(dim, tdim)
    if tag == "everywhere":
        if kind == "cell" and component is not None:
            return np.asarray(V.sub(component).collapse()[1], dtype=np.int32)
        if kind == "cell":
            index_map = V.dofmap.index_map
            return np.arange(index_map.size_local + index_map.num_ghosts, dtype=np.int32)
        entities = dolfinx.mesh.exterior_facet_indices(msh.topology)
    else:
        ids = tag if isinstance(tag, tuple) else (tag,)
        entities = np.concatenate([tags.find(i) for i in ids])
        checks.check_selects(msh.comm, measure, tags, ids, entities)
    if component is None:
        return fem.locate_dofs_topological(V, dim, entities)
    S = V.sub(component).collapse()[0]
    return fem.locate_dofs_topological((V.sub(component), S), dim, entities)[0]


@dataclass
class ResidualProblem(DiscreteProblem):
    """A discrete problem with a nonlinear residual, re-assembled at every iterate.

    A discrete problem with a nonlinear residual: R(x) = F(x; ·) and K = J(x) are
    re-assembled at each iterate (x is copied into ``u_h``, the function F is written in).
    Dirichlet rows: R_i = x_i − g_i and J's identity rows, as for K x − b.
    """

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
        """Whether the residual is the gradient of an energy (``energy_form`` given)."""
        return self.energy_form is not None

    def admissible(self, x: PETSc.Vec) -> bool:
        """Return whether u = x inverts no matter (det F > 0 where checked).

        Whether u = x inverts no matter: det F > 0 at every point :attr:`min_jacobian`
        checks (True without it; collective).  Leaves u_h = x.
        """
        self._set_iterate(x)
        return self.min_jacobian is None or self.min_jacobian() > 0

    def energy(self, x: PETSc.Vec) -> float:
        """Return the energy Π(x) = ∫ ψ dX − L(u) at u = x.

        Π(x) = ∫ ψ dX − L(u) at u = x (the Dirichlet values are x's own); +∞ where u inverts
        matter (det F ≤ 0 somewhere, with :attr:`min_jacobian`): no deformation is
        admissible there, whatever a law's ψ says (St Venant–Kirchhoff's is finite, even
        zero for a reflection).
        """
        assert self.energy_form is not None, "energy: the problem has no energy form"
        if not self.admissible(x):
            return np.inf
        local = fem.assemble_scalar(self.energy_form)
        return float(self.V.mesh.comm.allreduce(local, op=MPI.SUM))

    @staticmethod
    def matrices(J_form: fem.Form, bcs: list) -> tuple[PETSc.Mat, PETSc.Vec]:
        """Return the matrix and vector to build the problem with.

        (K, b) to build it with: K = J(u) at the current u (the pattern of every K_T(x)), b
        = 0 (R(x) = K x − b is never used).
        """
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
        """Set ``out`` = R(x) = F(x; φ_i), with x_i − g_i on Dirichlet rows."""
        self._set_iterate(x)
        if self._F is None:
            self._F = dolfinx.fem.petsc.create_vector(self.V)
        F, u = self._F, self.u_h.x.petsc_vec
        F_form, J_form = self._forms()
        with F.localForm() as local:
            local.set(0.0)
        # assemble_vector(Vec, form): the overload into an existing vector (not in the stubs)
        dolfinx.fem.petsc.assemble_vector(F, F_form)  # type: ignore[arg-type]
        if not (self.skip_zero_lifting and self._meets_dirichlet(u)):
            dolfinx.fem.petsc.apply_lifting(F, [J_form], bcs=[self.bcs], x0=[u], alpha=-1.0)
        add, reverse = PETSc.InsertMode.ADD, PETSc.ScatterMode.REVERSE
        F.ghostUpdate(addv=add, mode=reverse)  # type: ignore[arg-type]
        dolfinx.fem.petsc.set_bc(F, self.bcs, u, -1.0)
        out.array_w[:] = F.array_r

    #: skip the lifting J (g − x) of the Dirichlet columns where x meets the Dirichlet values
    #: exactly (it is then zero; every iterate after the first Newton step): the lifting
    #: evaluates the tangent's kernel on every cell at Γ_D and the symmetry planes, 4× the
    #: residual's own assembly on a 3D hyperelastic body (False: the old path, to measure)
    skip_zero_lifting = True

    def _meets_dirichlet(self, u: PETSc.Vec) -> bool:
        """Whether u_i = g_i exactly on every Dirichlet DoF of every rank (collective)."""
        local = True
        for bc in self.bcs:
            dofs, owned = bc.dof_indices()
            values = np.zeros(len(self.u_h.x.array))
            bc.set(values)
            dofs = dofs[:owned]
            local = local and bool(np.array_equal(u.array_r[dofs], values[dofs]))
        return bool(self.V.mesh.comm.allreduce(local, op=MPI.LAND))

    def _assemble_tangent(self, A: PETSc.Mat) -> None:
        """Assemble A = J(u_h) at the current ``u_h`` into A's pattern.

        A = J(u_h) at the current ``u_h`` into A's pattern (that of :meth:`matrices`),
        Dirichlet rows and columns identity.
        """
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
        """Return a new matrix J(x) with the Dirichlet rows and columns kept.

        A new matrix J(x) with the Dirichlet rows and columns kept (the coupling of a
        prescribed increment into the free rows: the tangent predictor,
        :mod:`contact.solvers.predictor`); the caller destroys it.
        """
        self._set_iterate(x)
        A = dolfinx.fem.petsc.assemble_matrix(self._forms()[1])
        A.assemble()
        return A

    def destroy(self) -> None:
        """Destroy the PETSc objects, the residual vector's too."""
        super().destroy()
        if self._F is not None:
            self._F.destroy()


class ComplementarityProblem:
    """The complementarity problem of your own UFL forms, and its solver.

    Given a residual F(u; v) on a Lagrange space V — a bilinear form a(u, v) with a load
    L(v), or any form nonlinear in u with its derivative J = ∂F/∂u —, Dirichlet conditions
    and a :class:`Unilateral` constraint at a set of nodes C, the problem is

        R_i(u) = w_i λ_i (i ∈ C),  R_i(u) = 0 (i ∉ C, not Dirichlet),
        σ (g_i − u_i) ≥ 0,  −σ λ_i ≥ 0,  (g_i − u_i) λ_i = 0 (i ∈ C),

    with R_i(u) = F(u; φ_i) and σ = +1 for u ≤ g, −1 for u ≥ g. Build it with
    :meth:`from_forms` (linear: K and b assembled once) or :meth:`from_residual` (R and its
    tangent re-assembled at every Newton iterate), then :meth:`solve`. It owns PETSc
    objects: :meth:`close` it, or use it in a ``with`` block.

    The builders check every argument before assembling anything
    (``contact.models.form_checks``), on every rank alike: a form of the wrong rank,
    on another space or mesh, a Dirichlet condition on another space, a measure that
    selects nothing, DoFs that are not owned integer indices, weights that are not finite
    and positive, a bound that is not finite or a callable bound of the wrong shape is one
    ``TypeError`` or ``ValueError`` line naming the argument, raised on all ranks.

    Args:
        problem: The discrete problem (made by the two builders; not built by hand).

    Example:
        >>> import numpy as np, ufl
        >>> from mpi4py import MPI
        >>> import contact
        >>> from dolfinx import fem, mesh
        >>> msh = mesh.create_unit_square(MPI.COMM_WORLD, 16, 16)
        >>> V = fem.functionspace(msh, ("Lagrange", 1))
        >>> u, v = fem.Function(V), ufl.TestFunction(V)
        >>> a = ufl.inner(ufl.grad(ufl.TrialFunction(V)), ufl.grad(v)) * ufl.dx
        >>> L = -10 * v * ufl.dx
        >>> facets = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
        >>> bc = fem.dirichletbc(0.0, fem.locate_dofs_topological(V, 1, facets), V)
        >>> floor = contact.Unilateral(-0.1, side="lower")
        >>> with contact.ComplementarityProblem.from_forms(a, L, u, floor, [bc]) as problem:
        ...     result = problem.solve("min")
        >>> result.converged, result.n_active > 0, float(u.x.array.min()) >= -0.1 - 1e-12
        (True, True, True)
    """

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
    ) -> ComplementarityProblem:
        """Build the problem K u − b = w λ of a linear form pair a(u, v) = L(v).

        K and b are assembled once, here, after every argument is checked.

        Args:
            a: The bilinear form a(w, v) (a trial function w and a test function v on u's
                space), a UFL form or a compiled ``dolfinx.fem.Form``.
            L: The linear form L(v) (a test function on u's space).
            u: A Function on V: its values are the initial guess, and it receives the
                solution (``Result.u_h`` is ``u``).
            constraint: Where and how u is bounded.
            bcs: Dirichlet conditions on u's space (or its subspaces).

        Returns:
            The problem, ready to :meth:`solve`; close it (or use ``with``).

        Raises:
            TypeError: For a form of the wrong rank or kind (one line naming it).
            ValueError: For forms, conditions or a constraint that do not fit u's space.
        """
        t0 = time.perf_counter()
        V, bcs = _checked(u, bcs, constraint, [("a", a, 2), ("L", L, 1)])
        return cls(
            _discrete(
                DiscreteProblem,
                u,
                bcs,
                lambda: assemble_system(fem.form(a), fem.form(L), bcs),
                constraint,
                t0,
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
    ) -> ComplementarityProblem:
        """Build the problem R(u) = w λ of a residual F(u; v), nonlinear in ``u``.

        R and its tangent J are re-assembled at every Newton iterate.

        Args:
            F: The residual F(u; v), a linear form in the test function v on u's space,
                written in u.
            u: The Function F is written in: its values are the initial guess, and it
                receives the solution (``Result.u_h`` is ``u``).
            constraint: Where and how u is bounded.
            bcs: Dirichlet conditions on u's space (or its subspaces).
            J: The bilinear form ∂F/∂u (default ``ufl.derivative(F, u)``; required when F
                is a compiled ``dolfinx.fem.Form``).

        Returns:
            The problem, ready to :meth:`solve`; close it (or use ``with``).

        Raises:
            TypeError: For a form of the wrong rank or kind (one line naming it).
            ValueError: For forms, conditions or a constraint that do not fit u's space.
        """
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
        )
        problem.F_form, problem.J_form = F_form, J_form
        return cls(problem)

    def solve(self, method: str = "fb", verbose: bool = False, **options: Any) -> Result:
        """Solve from u's current values (Dirichlet values put in).

        Collective; never raises on divergence (``Result.converged``).

        Args:
            method: fb, min, blend, vinewtonrsls or vinewtonssls.
            verbose: Print a line per Newton iteration (rank 0).
            **options: The ``solver`` options of a scene: ``rtol``, ``atol``, ``max_it``,
                ``line_search``, ``polish``, ``linear``, ``petsc_options``, …

        Returns:
            The same :class:`~contact.solvers.result.Result` as :func:`contact.solve`:
            ``u_h`` (the user's u), ``lmbda_h``, ``active``, ``history``, ``converged``,
            ``reason``.

        Raises:
            ConfigError: For an unknown or invalid option (one line naming it).
            RuntimeError: After :meth:`close`.
            ValueError: On every rank, for an initial guess that is not finite.
        """
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
        """Return the problem (a ``with`` block closes it at its end)."""
        return self

    def __exit__(self, *exc: Any) -> None:
        """Close the problem."""
        self.close()


def _checked(
    u: Any,
    bcs: Any,
    constraint: Any,
    forms: list[tuple[str, Any, int]],
    residual: tuple[Any, Any] | None = None,
) -> tuple[fem.FunctionSpace, list]:
    """Return (V, bcs as a list) once every argument passed its checks on every rank.

    (V, bcs as a list) once every argument passed its local checks on every rank
    (``contact.models.form_checks``): the forms' (name, form, rank), F written in u
    (``residual`` = (F, J)), the Dirichlet conditions, the constraint — and the number of
    Dirichlet conditions and the constraint's shape are the same on every rank.
    """
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


def _discrete[P: DiscreteProblem](
    kind: type[P],
    u: fem.Function,
    bcs: list,
    matrices: Callable[[], tuple[PETSc.Mat, PETSc.Vec]],
    constraint: Unilateral,
    t0: float,
) -> P:
    """Return the solver's problem, the constraint checked collectively first.

    The solver's problem: the constraint's nodes, weights and bound on u's space (checked
    collectively), then K and b from ``matrices()``.
    """
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
    )
