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
obstacle problem; ds(tag): a Signorini condition on the tagged facets; P2 on triangles and
tetrahedra: the P1-iso-P2 lumped mass, :func:`~contact.models.problem.lumped_weights`) or
given, and λ_h the nodal multiplier density: F(u_h; v) = Σ_i w_i λ_i v_i.  A linear problem
is assembled once (K, b); a nonlinear one re-assembles R(x) and its tangent K_T(x) = J(x)
at every Newton iterate (:class:`ResidualProblem`).

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

from ..base.lifetime import destroy
from ..base.timing import Stopwatch
from ..solvers.current import nodal_geometry
from ..solvers.floating import floating_bodies
from ..solvers.options import SolverOptions
from ..solvers.problem import (
    CurrentContact,
    DiscreteProblem,
    NodeBlockMatrix,
    ProblemData,
    Symmetry,
)
from ..solvers.result import Result
from ..solvers.snes import solve_problem
from . import form_checks as checks
from .constraints import Condition, ContactSet, Unilateral, check_condition
from .contacts import BodiesProblem, contact_set, mirror_axes
from .discrete import Problem
from .physics import Physics
from .problem import assemble_system


@dataclass
class ResidualProblem(Problem):
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
        ``contact.solvers.predictor``); the caller destroys it.
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


@dataclass
class RotatedResidualProblem(ResidualProblem):
    """The residual problem in rotated unknowns x = Qᵀ u.

    The residual problem in rotated unknowns x = Qᵀ u (Q orthogonal and block-diagonal:
    the contact nodes of a tilted plane on their (n, t) axes, the others unrotated, as in
    :func:`contact.models.obstacles.plane_contact`):

        R̃(x) = Qᵀ R(Q x),     K̃(x) = Qᵀ K_T(Q x) Q,

    so that u·n ≤ g is a bound on one unknown per contact node.  K̃ is written into ``K``
    (MatPtAP reusing its pattern: the solvers keep their references to it).
    """

    K_T: PETSc.Mat | None = None  # the tangent in the displacement unknowns
    _R: PETSc.Vec | None = field(default=None, repr=False)

    def _rotation(self) -> tuple[PETSc.Mat, PETSc.Mat]:
        """(Q, K_T): always given (the builder passes both; None only as defaults)."""
        assert self.basis is not None and self.K_T is not None, "basis (Q), K_T not set"
        return self.basis, self.K_T

    def _set_iterate(self, x: PETSc.Vec) -> None:
        u = self.u_h.x
        self._rotation()[0].mult(x, u.petsc_vec)  # u = Q x
        u.scatter_forward()

    def residual(self, x: PETSc.Vec, out: PETSc.Vec) -> None:
        """Write Qᵀ R(Q x) into out."""
        if self._R is None:
            self._R = out.duplicate()
        super().residual(x, self._R)
        self._rotation()[0].multTranspose(self._R, out)

    def linearize(self, x: PETSc.Vec) -> None:
        """K = Qᵀ K_T(Q x) Q."""
        self._set_iterate(x)
        Q, K_T = self._rotation()
        self._assemble_tangent(K_T)
        K_T.PtAP(Q, result=self.K)

    def full_tangent(self, x: PETSc.Vec) -> PETSc.Mat:
        """Qᵀ J(Q x) Q with the Dirichlet rows and columns kept (a new matrix)."""
        A = super().full_tangent(x)
        out = A.PtAP(self._rotation()[0])
        A.destroy()
        return out

    def destroy(self) -> None:
        """Destroy the problem's PETSc objects, the tangent and the residual included."""
        super().destroy()
        destroy(self.K_T, self._R)


@dataclass
class MortarResidualProblem(RotatedResidualProblem, BodiesProblem):
    """A residual problem of several bodies coupled by mortar pairs (finite strain).

    The unknowns are x = Q⁻¹ u of the mortar change of basis u = Q x
    (:func:`~.contacts.mortar_set`: each slave node's displacement relative to the master
    surface, in its frame), so that

        R̃(x) = Qᵀ F(Q x),     K̃(x) = Qᵀ J(Q x) Q,

    F and J assembled *without* Dirichlet conditions (the conditions hold on the unknowns x,
    ``bcs``: a fixed component of a slave node is one of its frame's axes there), and the
    rows of the fixed unknowns replaced by x_d − x̄_d (residual) and the identity (tangent;
    their columns zeroed: every iterate holds x̄_d, so the Newton step is the same).  Q is
    that of the coupling the problem was built with (on the reference configuration, or on
    the current one of a displacement u^k: :mod:`contact.drivers.recouple`).  The contact
    force is the one the pairs transmit (:class:`BodiesProblem`).
    """

    _fixed: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def _fixed_unknowns(self) -> tuple[np.ndarray, np.ndarray]:
        """(owned fixed unknowns d, their values x̄_d) of the conditions on x (``bcs``)."""
        if self._fixed is None:
            n_owned = self.V.dofmap.index_map.size_local * self.V.dofmap.index_map_bs
            values = np.zeros(len(self.u_h.x.array))
            dofs = [np.zeros(0, np.int32)]
            for bc in self.bcs:
                bc.set(values)
                dofs.append(bc.dof_indices()[0])
            d = np.unique(np.concatenate(dofs))
            d = d[d < n_owned].astype(np.int32)
            self._fixed = (d, values[d])
        return self._fixed

    def residual(self, x: PETSc.Vec, out: PETSc.Vec) -> None:
        """Write Qᵀ F(Q x) into out, x_d − x̄_d on the fixed unknowns."""
        self._set_iterate(x)
        if self._F is None:
            self._F = dolfinx.fem.petsc.create_vector(self.V)
        F = self._F
        with F.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(F, self._forms()[0])  # type: ignore[arg-type]
        F.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
        self._rotation()[0].multTranspose(F, out)
        d, values = self._fixed_unknowns()
        out.array_w[d] = x.array_r[d] - values

    def linearize(self, x: PETSc.Vec) -> None:
        """K = Qᵀ J(Q x) Q, the fixed unknowns' rows and columns the identity's."""
        self._set_iterate(x)
        Q, K_T = self._rotation()
        K_T.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(K_T, self._forms()[1])  # type: ignore[arg-type]
        K_T.assemble()
        K_T.PtAP(Q, result=self.K)
        lo = self.K.getOwnershipRange()[0]
        d = self._fixed_unknowns()[0]
        self.K.zeroRowsColumns((lo + d).astype(PETSc.IntType), diag=1.0)  # type: ignore[arg-type]


@dataclass
class CurrentResidualProblem(ResidualProblem):
    """The residual problem with contact on the current configuration.

    The residual problem with contact on the current configuration
    (:mod:`contact.solvers.current`, ``current`` set): the unknowns are the displacements,
    a contact node's residual block is read in the frame of its current normal ñ(x_i).
    The nodal quantities below are those of the iterate in ``u_h`` (the residual ``r``
    passed in is R(u_h), as :func:`contact.solvers.owned_residual` gives it).
    """

    @property
    def cc(self) -> CurrentContact:
        """The contact nodes and the rigid surface (always set on this problem)."""
        assert self.current is not None, "built with contact on the current configuration"
        return self.current

    def _rows(self) -> np.ndarray:
        bs = self.V.dofmap.index_map_bs
        return self.cc.nodes[:, None] * bs + np.arange(bs)

    def multiplier(self, r: np.ndarray) -> np.ndarray:
        """λ_i = ñ_i·R_i / w_i (≤ 0 in contact): the normal nodal force per reference area."""
        rows = self._rows()
        geo = nodal_geometry(self.cc, self.u_h.x.array[rows])
        return np.einsum("ka,ka->k", geo.frames[:, :, 0], r[rows]) / self.constraint.w

    def pressure(self, r: np.ndarray) -> np.ndarray:
        """The nominal contact pressure p_i = −λ_i (force per reference area, ≥ 0)."""
        return -self.multiplier(r)

    def nodal_gap(self, x: np.ndarray) -> np.ndarray:
        """g(X_i + u_i): the gap of the deformed contact node (x holds the displacements)."""
        cc = self.cc
        return cc.surface.project(cc.X + x[self._rows()])[0]

    def gap_output(self, x: np.ndarray) -> fem.Function:
        """The current gap g(X_i + u_i) at the contact nodes, NaN elsewhere."""
        gap = self.nodal_output("gap", self.nodal_gap(x))
        on = self.nodal_output("on", np.ones(len(self.constraint.dofs)))
        gap.x.array[on.x.array < 0.5] = np.nan
        return gap

    def constrained_hessian(self, x: PETSc.Vec, active: np.ndarray) -> tuple[PETSc.Mat, np.ndarray]:
        """Return the Hessian of the Lagrangian on the active constraints' tangent space.

        (Ã, held rows): the Hessian of the Lagrangian L = Π + Σ_i μ_i g_i(u) at the
        solution x, on the tangent space of the active constraints — what decides the
        stability of a constrained equilibrium (:func:`negative_eigenvalues`).  With
        μ_i = ñ_i·R_i (= w_i λ_i ≤ 0; R_i = μ_i ñ_i at a frictionless solution) and
        ∇²g = −Dn,

            ∇²L = K_T − Σ_{i active} μ_i P_i Dn_i P_i,

        (against a circle or sphere −μ Dn = −w p (I − n nᵀ)/|x − c|: a convex obstacle
        softens the body's tangential motion — it can roll off), rotated to the active nodes'
        current frames, Ã = Qᵀ ∇²L Q; the held rows are their normal unknowns.  A new
        matrix (the caller destroys it); K becomes K_T(x).
        """
        cc, bs = self.cc, self.V.dofmap.index_map_bs
        rows = self._rows()
        r = x.duplicate()
        self.residual(x, r)
        self.linearize(x)
        u = x.array_r[rows]
        geo = nodal_geometry(cc, u)
        Dn = cc.surface.project(cc.X + u)[2]
        free = ~cc.fixed
        mu = np.einsum("ka,ka->k", geo.frames[:, :, 0], r.array_r[rows])
        nodes = cc.nodes[active]
        curvature, frames = NodeBlockMatrix(self.K, bs), NodeBlockMatrix(self.K, bs)
        blocks = np.zeros((curvature.local_nodes, bs, bs))
        blocks[nodes] = (-mu[:, None, None] * (free[:, :, None] * Dn * free[:, None, :]))[active]
        hessian = self.K.duplicate(copy=True)
        subset = PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN
        hessian.axpy(1.0, curvature.set(blocks), structure=subset)  # type: ignore[arg-type]
        Q = frames.identity()
        Q[nodes] = geo.frames[active]
        out = hessian.PtAP(frames.set(Q))
        destroy(hessian, curvature.mat, frames.mat, r)
        return out, (nodes * bs).astype(np.int32)

    def contact_force(self, r: np.ndarray) -> float:
        """Return the resultant of the nodal contact forces along the normal n.

        F = −m_n Σ_i R_i·n: the resultant of the nodal contact forces along the normal n
        at the first point of contact (m_n the mirror images pressing along n,
        :meth:`~contact.solvers.problem.DiscreteProblem.copies_along`; frictionless:
        Σ w_i p_i ñ_i·n).
        """
        n = np.asarray(self.data.n, dtype=float)
        local = -float(np.sum(r[self._rows()][:, : len(n)] @ n))
        return self.copies_along(n) * self.V.mesh.comm.allreduce(local, op=MPI.SUM)


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
        constraint: Condition | Sequence[Condition],
        bcs: Sequence[fem.DirichletBC] = (),
        physics: Physics | None = None,
        u_prev: fem.Function | None = None,
    ) -> ComplementarityProblem:
        """Build the problem K u − b = w λ of a linear form pair a(u, v) = L(v).

        K and b are assembled once, here, after every argument is checked.

        Args:
            a: The bilinear form a(w, v) (a trial function w and a test function v on u's
                space), a UFL form or a compiled ``dolfinx.fem.Form``.
            L: the linear form L(v) (a test function on u's space).
            u: the Function that receives the solution (and is the initial guess).
            constraint: where and how u is bounded: a :class:`~.constraints.Unilateral`, a
                :class:`~.constraints.RigidObstacle`, or :class:`~.constraints.MortarPair`
                s (a list, with at most one rigid obstacle); a rigid obstacle's or a
                pair's friction law is part of it.
            bcs: Dirichlet conditions on u's space (or its subspaces).
            physics: the equations the forms discretise (``physics``),
                which the estimators read; None: no estimate.
            u_prev: the previous load step's solution (friction's slips start there).

        Returns:
            The problem, ready to :meth:`solve`; close it (or use ``with``).

        Raises:
            TypeError: For a form of the wrong rank or kind (one line naming it).
            ValueError: For forms, conditions or a constraint that do not fit u's space.
        """
        t0 = time.perf_counter()
        V, bcs = _checked(u, bcs, constraint, [("a", a, 2), ("L", L, 1)])
        return cls(
            make_problem(
                "linear",
                V,
                u,
                bcs,
                lambda: assemble_system(fem.form(a), fem.form(L), bcs),
                conditions_of(constraint),
                t0,
                physics=physics,
                u_prev=u_prev,
            )
        )

    @classmethod
    def from_residual(
        cls,
        F: ufl.Form,
        u: fem.Function,
        constraint: Condition | Sequence[Condition],
        bcs: Sequence[fem.DirichletBC] = (),
        J: ufl.Form | None = None,
        physics: Physics | None = None,
        u_prev: fem.Function | None = None,
        energy: ufl.Form | None = None,
        current: bool = True,
        coupled_at: np.ndarray | None = None,
    ) -> ComplementarityProblem:
        """Build the problem R(u) = w λ of a residual F(u; v), nonlinear in ``u``.

        R and its tangent J are re-assembled at every Newton iterate.

        Args:
            F: The residual F(u; v), a linear form in the test function v on u's space,
                written in u.
            u: the Function F is written in: the initial guess, then the solution.
            constraint: where and how u is bounded (as for :meth:`from_forms`).
            bcs: Dirichlet conditions on u's space (or its subspaces).
            J: The bilinear form ∂F/∂u (default ``ufl.derivative(F, u)``; required when F
                is a compiled ``dolfinx.fem.Form``).
            physics: the equations F discretises (``physics``), which the
                estimators read; None: no estimate.
            u_prev: the previous load step's solution (friction's slips start there).
            energy: Π(u) with F = ∂Π/∂u, if F is the gradient of an energy (the energy line
                search of ``contact.solvers.energy_search``).
            current: a rigid obstacle whose gap is not affine in u (a curved surface, or
                friction) is met on the current configuration (finite strain); False: on the
                reference configuration.
            coupled_at: :class:`~.constraints.MortarPair` s coupled on the current
                configuration of these nodal displacements (u's array, owned and ghost
                entries; finite strain: ``contact.drivers.recouple.solve_recoupled``
                iterates the coupling to its fixed point), or None: on the reference
                configuration.

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
        return cls(
            make_problem(
                "residual",
                V,
                u,
                bcs,
                lambda: ResidualProblem.matrices(J_form, bcs),
                conditions_of(constraint),
                t0,
                physics=physics,
                residual={
                    "F_form": F_form,
                    "J_form": J_form,
                    "energy_form": None if energy is None else fem.form(energy),
                },
                current=current,
                u_prev=u_prev,
                coupled_at=coupled_at,
            )
        )

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


def conditions_of(constraint: Any) -> tuple:
    """The contact conditions of a ``constraint`` argument: one condition or a sequence."""
    if isinstance(constraint, (list, tuple)):
        return tuple(constraint)
    return (constraint,)


def _checked(
    u: Any,
    bcs: Any,
    constraint: Any,
    forms: list[tuple[str, Any, int]],
    residual: tuple[Any, Any] | None = None,
) -> tuple[fem.FunctionSpace, list]:
    """Return (V, bcs as a list) once every argument passed its checks on every rank.

    (V, bcs as a list) once every argument passed its local checks on every rank
    (:mod:`~contact.models.form_checks`): the forms' (name, form, rank), F written in u
    (``residual`` = (F, J)), the Dirichlet conditions, the contact conditions — and the
    number of Dirichlet conditions and the conditions' shapes are the same on every rank.
    """
    V = checks.check_unknown(u).function_space
    bc_list = checks.bcs_list(bcs)

    def local() -> dict[str, object]:
        for name, form, rank in forms:
            checks.check_form(name, form, rank, V)
        if residual is not None:
            checks.check_written_in(*residual, u=u)
        checks.check_bcs(bc_list, V)
        shape: dict[str, object] = {"bcs": len(bc_list or ())}
        for condition in conditions_of(constraint):
            shape.update(check_condition(condition, V))
        return shape

    checks.agree(V.mesh.comm, local, same=True)
    assert bc_list is not None  # check_bcs refused None
    return V, bc_list


def make_problem(
    kind: str,
    V: fem.FunctionSpace,
    u_h: fem.Function,
    bcs: list,
    matrices: Callable[[], tuple[PETSc.Mat, PETSc.Vec]],
    conditions: Sequence[Condition],
    t0: float,
    *,
    physics: Physics | None = None,
    data: ProblemData | None = None,
    residual: dict | None = None,
    current: bool = False,
    u_prev: fem.Function | None = None,
    allow_empty: bool = False,
    bodies: tuple[Any, list[str]] = (None, []),
    coupled_at: np.ndarray | None = None,
) -> Problem:
    """Return the problem of an assembled system and its contact conditions.

    How every builder makes one (the own forms of :class:`ComplementarityProblem`, the
    scene's models).

    Args:
        kind: ``linear`` (R(x) = K x − b) or ``residual`` (R and K_T re-assembled at every
            iterate).
        V: the unknown's space.
        u_h: the function the solution goes into.
        bcs: the Dirichlet conditions K and b were assembled with.
        matrices: K and b (K_T at u_h's values and a zero b for a residual problem), called
            after a unilateral condition's nodes are known (their checks come first).
        conditions: the contact conditions (:func:`~.contacts.contact_set`).
        t0: when building began (``assembly_time``).
        physics: the equations (what the estimators read), or None.
        data: more data for the reports (the scene's: f, t, ds, the reaction form …).
        residual: a residual problem's :class:`ResidualProblem` fields (F_form, J_form,
            energy_form, min_jacobian).
        current: a residual problem meets a rigid obstacle on its current configuration
            where the gap is not affine in u.
        u_prev: the previous load step's displacement (friction's slips start there).
        allow_empty: a unilateral condition may constrain no DoF.
        bodies: (cell tags, names) of several bodies in one mesh: the rigid motions each
            body keeps free (:func:`~contact.solvers.floating.floating_bodies`).
        coupled_at: mortar pairs coupled on the current configuration of these nodal
            displacements (finite strain; :func:`~.contacts.mortar_set`), or None: on the
            reference configuration.

    Returns:
        The problem (its friction set from the conditions' friction law, if any).
    """
    conditions = tuple(conditions)
    if len(conditions) == 1 and isinstance(conditions[0], Unilateral):
        # the condition's checks come before anything is assembled
        cs = conditions[0].discretise(V, bcs, allow_empty)
        K, b = matrices()
    else:
        K, b = matrices()
        cs = contact_set(
            V, K, b, bcs, conditions, current=current, u_prev=u_prev, coupled_at=coupled_at
        )
    K_T = None
    if cs.K is not None:  # a change of basis: K̃ = Qᵀ K Q and b̃ = Qᵀ b replace K and b
        if kind == "residual":  # K keeps the pattern of K_T(u)
            K_T = K
            b.destroy()
        else:
            destroy(K, b)
        K, b = cs.K, cs.b
    fixed = np.concatenate([bc.dof_indices()[0] for bc in bcs] or [np.zeros(0, np.int32)])
    comm = V.mesh.comm
    bs = V.dofmap.index_map_bs
    fields: dict[str, Any] = {}
    if bs == 1:  # no Dirichlet DoF on any rank: only the constraint holds the body
        fields["semicoercive"] = comm.allreduce(len(fixed), op=MPI.SUM) == 0
    else:  # an elastic body: its near-nullspace, rigid motions, mirror images
        fields.update(_body_fields(V, fixed, cs, physics, bodies))
    mortar = cs.data.couplings is not None
    problem_class: type[Problem]
    if kind == "residual" and mortar:
        problem_class = MortarResidualProblem
    elif kind == "residual":
        problem_class = {
            "plain": ResidualProblem,
            "rotated": RotatedResidualProblem,
            "current": CurrentResidualProblem,
        }[cs.kind]
    else:
        problem_class = BodiesProblem if mortar else Problem
    problem = problem_class(
        V,
        u_h,
        cs.bcs or bcs,
        K,
        b,
        cs.constraint,
        basis=cs.basis,
        basis_inverse=cs.basis_inverse,
        output=cs.output,
        current=cs.current,
        data=(data or ProblemData()).updated(cs.data),
        **fields,
        assembly_time=time.perf_counter() - t0,
        physics=physics,
        contacts=conditions,
        u_prev=u_prev,
        **(residual or {}),
    )
    if isinstance(problem, RotatedResidualProblem):
        problem.K_T = K_T
    laws = {
        c.friction for c in conditions if not isinstance(c, Unilateral) and c.friction is not None
    }
    if len(laws) > 1:
        raise ValueError("friction: the conditions of one problem share one friction law")
    if laws:  # (only a frictional problem loads the friction modules)
        from .friction import friction_set

        problem.friction = friction_set(problem, laws.pop(), u_prev)
    return problem


def _body_fields(
    V: fem.FunctionSpace,
    fixed: np.ndarray,
    cs: ContactSet,
    physics: Physics | None,
    bodies: tuple[Any, list[str]],
) -> dict[str, Any]:
    """Return the DiscreteProblem fields of an elastic body that follow from its conditions.

    The DiscreteProblem fields of an elastic body (or several in one mesh) that follow
    from its conditions: the rigid-body near-nullspace (in the unknowns of the change of
    basis, if any), the rigid motions no Dirichlet or symmetry condition holds, and the
    mirror images its symmetry planes stand for (every plane for one body; with mortar
    pairs the planes through the pairs' contact nodes).
    """
    from .elasticity import rigid_body_modes

    basis, inverse = cs.basis, cs.basis_inverse
    planes = [] if physics is None else list(physics.boundary.symmetry)
    if cs.data.couplings is not None:
        boundary = physics.boundary if physics is not None else None
        facets = [(boundary.facets((tag,)), k) for tag, k in planes] if boundary else []
        assert cs.data.contact_nodes is not None  # a mortar set's
        axes = tuple(sorted(mirror_axes(V.mesh, facets, cs.data.contact_nodes)))
    else:
        axes = tuple(k for _, k in planes)
    tags, names = bodies
    return {
        "symmetry": Symmetry(axes),
        "near_nullspace": rigid_body_modes(V, None if inverse is not None else basis, inverse),
        "floating": floating_bodies(V, fixed, tags, names),
    }
