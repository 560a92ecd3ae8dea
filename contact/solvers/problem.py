"""The discrete contact problem every model produces and every solver consumes.

A model assembles, once per mesh, the stiffness matrix K (Dirichlet rows and columns
replaced by identity) and the lifted load b, so that R(x) = K x − b is the discrete
residual in the solver's unknowns x (x = Qᵀ u when a change of basis u = Q x rotates
contact nodes to their (n, t) axes).  The complementarity conditions act on a set of
nodes (docs/theory.md §2):

    R_i = w_i λ_i,   σ(g_i − x_i) ≥ 0,   −σ λ_i ≥ 0,   (g_i − x_i) λ_i = 0,

with lumped weights w_i = ∫ φ_i over Γ_C (Signorini, elasticity: the contact nodes not on
the closure of Γ_D) or over Ω (obstacle: every free node), and σ = +1 for x ≤ g, −1 for
x ≥ ψ.  λ_i is the nodal multiplier density (a flux or a pressure).

A frictional problem adds the tangential unknowns of the contact nodes and the data of
their friction law (:class:`FrictionSet`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from typing import Any, Protocol

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base import spaces
from ..base.errors import ConfigError
from ..base.lifetime import destroy
from .options import FrictionOptions


@dataclass
class Constraint:
    """The nodal complementarity set: owned local DoF indices with bound, weight and sign."""

    dofs: np.ndarray  # owned local indices into the PETSc vector
    g: np.ndarray  # bound g_i (Signorini gap) or ψ_i (obstacle) at those DoFs
    w: np.ndarray  # lumped weights w_i > 0
    sign: float  # σ = +1: u ≤ g ; σ = −1: u ≥ ψ
    # the size of what g is computed from, in the units of u: a gap measured between node
    # coordinates X carries round-off ≈ ε max|X| (coincident surfaces give ±1e-16 instead of
    # 0, its sign set by the partition), so kinks are decided relative to it too
    # (:meth:`contact.solvers.newton.Complementarity.tie_tolerance`); 0 for gaps given as data
    scale: float = 0.0
    in_domain: bool = False  # the constraint holds in Ω (obstacle), not on Γ_C

    def global_size(self, comm: MPI.Comm) -> int:
        return comm.allreduce(len(self.dofs), op=MPI.SUM)


@dataclass
class Output:
    """Where the nodal fields of a solution (λ_h, the gap, the active set) are written.

    A scalar model writes them on V itself (every field None); an elastic body on the
    contact component's collapsed scalar subspace S, with the S → V DoF map.

    Attributes:
        space: S, or None for V.
        map: the V DoFs of S's DoFs (S → V), or None when S = V.
        bound: the bound on S (g, ψ, or n_k g of a plane), or None: the data's ``g_h``.
        lambda_sign: the multiplier reported, λ_i = lambda_sign · R_i / w_i (−1 against a
            plane whose normal points along −e_k).
        nodes: the S DoFs of the contact nodes (several bodies), or None.
        ends: the owned contact DoFs on the closure of Γ_D (the ends of Γ_C), or None.
        end_neighbours: the nearest constrained DoF of each end (local index).
    """

    space: fem.FunctionSpace | None = None
    map: np.ndarray | None = None
    bound: fem.Function | None = None
    lambda_sign: float = 1.0
    nodes: np.ndarray | None = None
    ends: np.ndarray | None = None
    end_neighbours: np.ndarray | None = None


@dataclass(frozen=True)
class Symmetry:
    """The mirror planes x_k = c behind a modelled part (an elastic body cut by its symmetry
    planes): the body stands for 2^(number of planes) copies of the part.

    Attributes:
        axes: the k of each mirror plane x_k = c (sorted, each once).
    """

    axes: tuple[int, ...] = ()

    @property
    def copies(self) -> int:
        """The copies of the modelled part the body stands for, 2^(number of planes)."""
        return 2 ** len(self.axes)

    def copies_along(self, n: np.ndarray | None) -> int:
        """The factor of a scalar force along the direction ``n``: 2^(number of planes
        x_k = c that contain n, n_k = 0); every copy (:attr:`copies`) when ``n`` is None.

        The mirror image across such a plane presses alongside the modelled part; the
        image across a plane normal to n (a frictionless floor under a block pressed from
        above) is a second contact zone pressing the other way — the force through the body
        is that of one zone, so that plane does not multiply it."""
        if n is None:
            return self.copies
        n = np.asarray(n, dtype=float)
        size = float(np.max(np.abs(n), initial=0.0))
        return 2 ** sum(1 for k in self.axes if abs(n[k]) <= 1e-12 * size)


@dataclass
class ProblemData:
    """The continuous problem's data beside the algebra: what the estimators, the baselines
    and the reports read (the solvers read none of it).  Every field is optional: a builder
    sets those its model has.

    Attributes:
        k: the conductivity of a scalar model (UFL).
        f: the source or body load (UFL).
        t: the flux or traction on Γ_N (UFL).
        t_C: the load on Γ_C of a scalar Signorini model (UFL).
        ds: ``ds`` over the boundary parts' facet tags.
        mu: the Lamé parameter μ of an elastic body (a number or a DG0 function).
        lmbda_L: the Lamé parameter λ_L (idem).
        stresses: u ↦ (P, σ) of a hyperelastic law.
        body: the body number of each cell (DG0) of several bodies in one mesh.
        g_h: the bound on V of a unilateral condition.
        n: the contact normal at the first point of contact (gdim,): at the constrained
            node that :meth:`DiscreteProblem.contact_gaps` ranks first.
        n_ufl: the rigid obstacle's normal as UFL of the spatial coordinate.
        g_ufl: the rigid obstacle's initial gap as UFL of the spatial coordinate.
        normals: the contact normal of each constrained node (nodes, gdim).
        contact_nodes: the coordinates of the pairs' slave nodes (this rank's).
        contact_mask: the hp DoFs on Γ_C (bool over the hp space's active DoFs).
        couplings: the mortar couplings of the pairs (:class:`contact.models.mortar.Coupling`),
            or None: no pair.
        pair_nodes: the first ``pair_nodes`` constrained nodes are the pairs' slave nodes.
        current_gap: the current gap of each constrained node (row for row with the
            constraint) where the bound g is not one: pairs coupled on the current
            configuration of u^k bound the unknowns by g_i^k + x_{i,n}(u^k).
        u_bcs: the Dirichlet conditions on u where the problem's own ``bcs`` act on the
            unknowns of a change of basis.
        reaction_form: the residual form whose value on Γ_D is the reaction force.
        reaction_basis: Q of test functions that span a subspace of V (u = Q x, an hp
            space): the reaction is Qᵀ of that residual on the unknowns ``bcs`` hold.
        deformed_area: the form of the lumped deformed areas of the contact nodes.
    """

    k: Any = None
    f: Any = None
    t: Any = None
    t_C: Any = None
    ds: Any = None
    mu: Any = None
    lmbda_L: Any = None
    stresses: Callable[[Any], tuple] | None = None
    body: fem.Function | None = None
    g_h: fem.Function | None = None
    n: np.ndarray | None = None
    n_ufl: Any = None
    g_ufl: Any = None
    normals: np.ndarray | None = None
    contact_nodes: np.ndarray | None = None
    contact_mask: np.ndarray | None = None
    couplings: list | None = None
    pair_nodes: int | None = None
    current_gap: np.ndarray | None = None
    u_bcs: list | None = None
    reaction_form: fem.Form | None = None
    reaction_basis: PETSc.Mat | None = None
    deformed_area: fem.Form | None = None

    def updated(self, other: ProblemData) -> ProblemData:
        """A copy with the fields that ``other`` sets (not None) taken from it."""
        changes = {f.name: getattr(other, f.name) for f in fields(other)}
        return replace(self, **{k: v for k, v in changes.items() if v is not None})


@dataclass
class DiscreteProblem:
    """Everything the solver needs: K u − b = w λ on the constraint set, = 0 elsewhere.

    The algebraic core (V, u_h, bcs, K, b, the constraint, the change of basis, the
    near-nullspace) and optional parts: where the nodal fields are written
    (:class:`Output`), the symmetry planes (:class:`Symmetry`), a friction law's set
    (:class:`FrictionSet`), contact on the current configuration
    (:class:`CurrentContact`) and the continuous problem's data
    (:class:`ProblemData`).
    """

    V: fem.FunctionSpace
    u_h: fem.Function
    bcs: list
    K: PETSc.Mat
    b: PETSc.Vec
    constraint: Constraint
    # NCP scaling (gap per λ), nodal or one number; set by solve()
    c: np.ndarray | float | None = None
    basis: PETSc.Mat | None = None  # Q with u = Q x: per-node rotations to (n, t) axes, or None
    # Q⁻¹ when Q is not orthogonal (mortar coupling); else Qᵀ
    basis_inverse: PETSc.Mat | None = None
    near_nullspace: PETSc.NullSpace | None = None  # rigid-body modes (elasticity, for GAMG)
    # no Dirichlet DoF: K is singular (constants), held by the constraint alone
    semicoercive: bool = False
    floating: list = field(default_factory=list)  # (body, free rigid motions): bodies nothing holds
    assembly_time: float = 0.0
    output: Output = field(default_factory=Output)
    symmetry: Symmetry = field(default_factory=Symmetry)
    friction: FrictionSet | None = None  # the tangential unknowns of a frictional problem
    # contact on the current configuration (a gap nonlinear in u): the nodes and the rigid
    # surface, else None
    current: CurrentContact | None = None
    data: ProblemData = field(default_factory=ProblemData)

    def destroy(self) -> None:
        """Destroy the PETSc objects of the problem (K, b, Q, Q⁻¹, the near-nullspace, the
        mortar matrices); its functions stay usable.  Call it once the problem's last result
        is done with (:meth:`contact.solvers.result.Result.release`)."""
        couplings = self.data.couplings or []
        destroy(
            self.K,
            self.b,
            self.basis,
            self.basis_inverse,
            self.near_nullspace,
            *(c.M for c in couplings),
        )

    def nodes_across(self) -> float:
        """The nodes across the constrained set (:func:`nodes_across`; collective): across
        Γ_C, or Ω for an obstacle (the constraint in the domain)."""
        V = self.V
        tdim, bs = V.mesh.topology.dim, V.dofmap.index_map_bs
        nodes = np.unique(self.constraint.dofs // bs)
        points = V.tabulate_dof_coordinates()[nodes]
        dim = tdim if self.constraint.in_domain else tdim - 1
        return nodes_across(points, dim, V.mesh.comm)

    def dirichlet_rows(self) -> np.ndarray:
        """The owned rows of the unknowns that Dirichlet conditions (and the symmetry planes'
        prescribed components) hold: local indices, sorted."""
        rows = [dofs[:owned] for dofs, owned in (bc.dof_indices() for bc in self.bcs)]
        return np.unique(np.concatenate([np.zeros(0, np.int32), *rows]))

    #: R(x) = K x − b is affine; a nonlinear residual re-assembles R and K = K_T(x)
    #: (:class:`contact.models.forms.ResidualProblem`)
    nonlinear = False

    def residual(self, x: PETSc.Vec, out: PETSc.Vec) -> None:
        """out = R(x) = K x − b."""
        self.K.mult(x, out)
        out.axpy(-1.0, self.b)

    #: whether :meth:`energy` knows the total potential Π with R = ∂Π/∂x (a hyperelastic
    #: body: the energy line search of :mod:`contact.solvers.energy_search`)
    has_energy = False

    def admissible(self, x: PETSc.Vec) -> bool:
        """Whether x is an admissible state (a hyperelastic body: no inverted matter)."""
        return True

    def energy(self, x: PETSc.Vec) -> float:
        """Π(x), the total potential whose gradient is R (collective); only where
        :attr:`has_energy`."""
        raise NotImplementedError(f"{type(self).__name__} has no energy")

    def linearize(self, x: PETSc.Vec) -> None:
        """K = K_T(x), the tangent of R at x: nothing to do for R(x) = K x − b.  The solvers
        call it at every iterate before they use K (Jacobian, polishing)."""

    def full_tangent(self, x: PETSc.Vec) -> PETSc.Mat:
        """A new matrix: the tangent at x with its Dirichlet rows and columns kept (a nonlinear
        residual only: :mod:`contact.solvers.predictor`)."""
        raise NotImplementedError(f"{type(self).__name__} has no full tangent")

    def to_unknowns(self, u: PETSc.Vec, x: PETSc.Vec) -> None:
        """x = Q⁻¹ u (the solver's unknowns from displacements; Qᵀ u for a rotation, a copy
        when Q = I)."""
        if self.basis_inverse is not None:
            self.basis_inverse.mult(u, x)
        elif self.basis is None:
            u.copy(x)
        else:
            self.basis.multTranspose(u, x)

    def to_displacement(self, x: PETSc.Vec, u: PETSc.Vec) -> None:
        """u = Q x."""
        if self.basis is None:
            x.copy(u)
        else:
            self.basis.mult(x, u)

    def pressure(self, r: np.ndarray) -> np.ndarray:
        """p_i = −σ R_i / w_i ≥ 0 on the constrained DoFs (owned residual ``r``): the contact
        pressure −λ_n of elasticity, the flux −σλ_i into the obstacle of scalar models."""
        con = self.constraint
        return -con.sign * r[con.dofs] / con.w

    def multiplier(self, r: np.ndarray) -> np.ndarray:
        """λ_i = ±R_i / w_i (:attr:`Output.lambda_sign`) on the constrained DoFs (owned
        residual ``r``)."""
        con = self.constraint
        return self.output.lambda_sign * r[con.dofs] / con.w

    #: the unknowns carry polynomials of variable degree (an hp space): Krylov solvers with
    #: GAMG lose their robustness, which ``solver.linear: auto`` takes into account
    variable_degree = False

    def patch_preconditioner(self) -> Callable[[PETSc.PC], None]:
        """The problem's own p-robust preconditioner of its reduced Newton system
        (``solver.linear: hp_patch``): a function that sets a PC up as it.  A problem
        without one refuses.

        Returns:
            The function of the PC (kept by the problem, destroyed with it).
        """
        raise ConfigError(
            "solver.linear: hp_patch applies to scalar hp problems (adapt.strategy: hp) only"
        )

    def unknowns(self) -> int:
        """The number of unknowns the solver works on (all ranks): V's DoFs, or fewer where
        the change of basis u = Q x leaves some of V's DoFs unused (an hp space)."""
        V = self.V
        return V.dofmap.index_map.size_global * V.dofmap.index_map_bs

    def node_coordinates(self) -> np.ndarray:
        """The coordinates (gdim columns) of the nodes of the constrained DoFs."""
        V = self.V
        nodes = self.constraint.dofs // V.dofmap.index_map_bs
        return V.tabulate_dof_coordinates()[nodes, : V.mesh.geometry.dim]

    def contact_gaps(self) -> np.ndarray:
        """What the constrained nodes rank by for the first point of contact
        (``contact.models.problem.first_contact_point``; units of length): σ g, the initial
        gap; for pairs coupled on the current configuration two columns, the current gap
        (``ProblemData.current_gap``), then, among the nodes it ties (those touching), the
        bound g_i^k + x_{i,n}(u^k) = n_i · (Σ_j c_ij X_j − X_i): the reference distance to
        the node's current projection along its current normal, the initial gap of bodies
        that have not slid (the centre of a Hertz contact, not its edge)."""
        con = self.constraint
        if self.data.current_gap is None:
            return con.sign * con.g
        return np.c_[self.data.current_gap, con.sign * con.g]

    def nodal_gap(self, x: np.ndarray) -> np.ndarray:
        """σ(g_i − x_i) on the constrained DoFs (owned unknowns ``x``): ≥ 0 when feasible."""
        con = self.constraint
        return con.sign * (con.g - x[con.dofs])

    def contact_force(self, r: np.ndarray) -> float:
        """The resultant contact force over all ranks (collective),

            F = m_n Σ_i w_i p_i (n_i · n),

        p_i from :meth:`pressure`, n_i the nodal contact normals and n the one at the first
        point of contact (n_i · n = 1 against a plane, and for scalar models), m_n the
        mirror images that press along n (:meth:`copies_along`).  Units: force per unit
        thickness in 2D elasticity (N/m), force in 3D (N); ∫ flux over Γ_C (or Ω) for
        scalar models."""
        con = self.constraint
        normals, n = self.data.normals, self.data.n
        along = normals @ n if normals is not None and n is not None else 1.0
        local = float(np.sum(con.w * self.pressure(r) * along))
        return self.copies_along() * self.V.mesh.comm.allreduce(local, op=MPI.SUM)

    def copies_along(self, n: np.ndarray | None = None) -> int:
        """The factor of a scalar force along the direction ``n`` (default: the contact
        normal at the first point of contact; without one, every copy):
        :meth:`Symmetry.copies_along`."""
        return self.symmetry.copies_along(self.data.n if n is None else n)

    def outputs(self, x: np.ndarray, r: np.ndarray, active: np.ndarray) -> tuple[fem.Function, ...]:
        """Nodal fields on the output space S: the multiplier λ_h (:meth:`multiplier` on the
        constrained DoFs, 0 elsewhere), the gap (:meth:`gap_output`) and the 0/1 active
        set.  ``x`` and ``r`` are the owned unknowns and residual at the solution,
        ``active`` the mask over the constrained DoFs."""
        lmbda = self.nodal_output("lambda_h", self.multiplier(r))
        return lmbda, self.gap_output(x), self.nodal_output("active", active.astype(float))

    def nodal_output(self, name: str, values: np.ndarray) -> fem.Function:
        """A function ``name`` on the output space S with ``values`` at the constrained DoFs
        and 0 elsewhere (λ_h also at the ends of Γ_C, :meth:`_extend_to_ends`)."""
        V = self.V
        fn, where = self.unknowns_function(name, values), self.output
        out = spaces.zero_function(where.space or V, name)
        out.x.array[:] = fn.x.array if where.map is None else fn.x.array[where.map]
        return out

    def unknowns_function(self, name: str, values: np.ndarray) -> fem.Function:
        """A function of V holding ``values`` at the constrained unknowns and 0 at the others
        (λ_h also at the ends of Γ_C, :meth:`_extend_to_ends`): the unknowns x, before Q."""
        fn = spaces.zero_function(self.V)
        fn.x.array[self.constraint.dofs] = values
        fn.x.scatter_forward()
        if name == "lambda_h":
            self._extend_to_ends(fn)
        return fn

    def gap_output(self, x: np.ndarray) -> fem.Function:
        """The gap σ(bound − u) on S (≥ 0 when feasible), NaN off the constrained DoFs of a
        contact boundary Γ_C (g − u inside Ω is no gap); for an obstacle (constraint in Ω)
        it is ψ − u everywhere.  ``x``: the owned unknowns."""
        V, con, where = self.V, self.constraint, self.output
        S = where.space or V
        unknowns = spaces.zero_function(V)
        unknowns.x.array[: len(x)] = x
        unknowns.x.scatter_forward()
        u = unknowns.x.array if where.map is None else unknowns.x.array[where.map]
        gap = spaces.zero_function(S, "gap")
        gap.x.array[:] = con.sign * (self.bound_function().x.array - u)
        if not con.in_domain:
            on = self.nodal_output("on", np.ones(len(con.dofs)))
            gap.x.array[on.x.array < 0.5] = np.nan
        return gap

    def _extend_to_ends(self, lmbda: fem.Function) -> None:
        """The ends of Γ_C on the closure of Γ_D carry no constraint, and their residual row
        mixes the flux through Γ_C with that through Γ_D; give them the multiplier of the
        nearest contact node (constant extrapolation) so that λ_h is the discrete contact
        flux on all of Γ_C and the estimator sees no spurious jump there."""
        ends = self.output.ends
        if ends is not None and len(ends):
            lmbda.x.array[ends] = lmbda.x.array[self.output.end_neighbours]
        lmbda.x.scatter_forward()

    def bound_function(self) -> fem.Function:
        """The bound (g or ψ; n_k g for elasticity) on the output space."""
        bound = self.output.bound if self.output.bound is not None else self.data.g_h
        assert bound is not None, "a problem has its bound on the output space or V"
        return bound


@dataclass
class FrictionSet:
    """The tangential unknowns of the contact nodes and the data of their friction law.

    Arrays are per owned contact node, in the order of ``problem.constraint.dofs``; m is the
    number of tangential directions (gdim − 1)."""

    law: str  # "tresca" | "coulomb"
    n_comp: int  # position of the normal unknown in the node's block
    t_comps: np.ndarray  # (m,) positions of the tangential unknowns in the block
    tangent: np.ndarray  # (n, m) owned local indices of the tangential unknowns
    free: np.ndarray  # (n, m) bool: not fixed by a Dirichlet/symmetry condition
    frames: np.ndarray  # (n, gdim, m) the tangent vectors t_i in global axes
    c_t: np.ndarray  # (n,) tangential scaling (stress per length)
    threshold: np.ndarray | None  # (n,) Tresca: s(x_i, t) (stress)
    coefficient: float | None  # Coulomb: F
    x_prev: np.ndarray  # (n, m) tangential unknowns at the previous load step
    #: the knobs of the tangential rows (form, Coulomb solver, fixed point; c_t is above)
    options: FrictionOptions = field(default_factory=FrictionOptions)

    @property
    def m(self) -> int:
        return self.tangent.shape[1]


class RigidSurface(Protocol):
    """A rigid obstacle as a signed distance (module doc); ``scale`` is the size of the
    numbers its distance subtracts beyond the point's coordinates (|c| + R_o, |p|)."""

    @property
    def scale(self) -> float: ...

    def project(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(g, n, Dn) at the points x (k, gdim): the signed distances (k,), the unit normals
        towards the obstacle (k, gdim), their derivatives dn/dx (k, gdim, gdim)."""
        ...


@dataclass
class CurrentContact:
    """The contact nodes of a body against a rigid obstacle on the current configuration
    (owned nodes, none fixed in every component; arrays row for row)."""

    nodes: np.ndarray  # (k,) owned local node indices (the blocks of bs DoFs of V)
    X: np.ndarray  # (k, gdim) reference positions
    fixed: np.ndarray  # (k, bs) bool: components held by a Dirichlet / symmetry condition
    surface: RigidSurface
    u_prev: np.ndarray  # (k, gdim) displacement at the previous load step (friction's slip)
    motion: np.ndarray  # (gdim,) the obstacle's translation Δc since the previous load step


class NodeBlockMatrix:
    """An AIJ matrix with the row layout of ``layout`` and one dense bs×bs block per owned
    node (bs = the vector block size): the pattern of the rotation Q (u = Q x) and of the
    friction law's B and D (H = B K + D).  ``set(blocks)`` writes all blocks, an array
    (local nodes, bs, bs), in one CSR call; the pattern never changes, so products with it
    can reuse their symbolic phase."""

    def __init__(self, layout: PETSc.Mat, bs: int):
        lo, hi = layout.getOwnershipRange()
        self.bs, self.local_nodes = bs, (hi - lo) // bs
        n = self.local_nodes
        # row (node, i) holds columns (node, 0 … bs−1)
        self.indptr = np.arange(0, n * bs * bs + 1, bs, dtype=PETSc.IntType)
        cols = lo + np.arange(n * bs, dtype=PETSc.IntType).reshape(n, 1, bs)
        self.indices = np.broadcast_to(cols, (n, bs, bs)).ravel().copy()
        self.mat = PETSc.Mat().createAIJ(layout.getSizes(), bsize=bs, nnz=(bs, 0), comm=layout.comm)  # type: ignore[arg-type]

    def identity(self) -> np.ndarray:
        """Identity blocks, (local nodes, bs, bs)."""
        return np.tile(np.eye(self.bs), (self.local_nodes, 1, 1))

    def set(self, blocks: np.ndarray) -> PETSc.Mat:
        values = np.ascontiguousarray(blocks, dtype=PETSc.ScalarType).ravel()
        self.mat.setValuesCSR(self.indptr, self.indices, values)  # type: ignore[arg-type]
        self.mat.assemble()
        return self.mat


def nodal_scaling(K: PETSc.Mat, dofs: np.ndarray, w: np.ndarray, kappa: float = 1.0) -> np.ndarray:
    """Default NCP scaling ``c: auto``:  c_i = κ w_i / K_ii  on each constrained node
    (κ = ``solver.kappa``, default 1).

    Then b_i = −σ c_i R_i / w_i = −σ κ R_i / K_ii is the displacement one Jacobi step would
    move node i by: the NCP compares two lengths of the same discrete origin, the gap and
    the local correction.  Scaling k (or E) scales R and K_ii alike, so it cancels; on any
    mesh the two parts of a Jacobian row  (K_ii/κ) ∂_aφ e_i + ∂_bφ K_i  keep the size of K's
    own rows, which keeps Krylov + GAMG working.  Measured (fb with polishing, Newton steps +
    polishing solves): with nested iteration on problem A (docs/theory.md §7), κ = 1 needs
    1+1 per level and κ = 100 2+1 (min: 1 against 4); from u = 0 on signorini_square at 512², κ = 1
    needs 17+1 and κ = 100 10+1 (a large κ makes the first step predict contact wherever the load
    pushes, and the retreat is fast).  A cold start on a fine mesh corrects smooth modes,
    which the Jacobi-sized κ = 1 underestimates by ~L/h; a nested guess leaves local errors,
    for which κ = 1 is right.  With GAMG, κ = 100 slows each linear solve (hertz_3d, min from
    u = 0: 130 s against 45 s, 10 steps either way; nested 5 steps against 3 —
    ``python demos/bench/bench_hertz.py --set solver.kappa=100``).  Hence κ = 1 by default; the
    cold-start scene signorini_square sets κ = 100.
    """
    diag = K.getDiagonal()
    out = kappa * w / diag.array_r[dofs]
    diag.destroy()
    return out


#: ``solver.max_it: auto`` allows at least this many Newton steps
MAX_IT_FLOOR = 50
#: … and this many per node across the constrained set (:func:`newton_max_it`)
MAX_IT_PER_NODE_ACROSS = 1.0


def nodes_across(points: np.ndarray, dim: int, comm: MPI.Comm) -> float:
    """The number of nodes across a set of nodes of dimension ``dim`` (a curve, a surface,
    a domain) at coordinates ``points`` (the owned ones, rows; collective):
    n = L (N / V)^(1/dim), with N the nodes, L the longest edge of their bounding box and V
    the product of its ``dim`` longest edges — the nodes along L if they are spread evenly
    (a square: √N; a line: N; a 1024 × 8 strip: 1024), at most N.

    Args:
        points: the owned nodes' coordinates, one row each.
        dim: the dimension of the set (0: a point, one node across).
        comm: the communicator the nodes are spread over.

    Returns:
        n ≥ 1.
    """
    count = comm.allreduce(len(points), op=MPI.SUM)
    if count == 0 or dim <= 0:
        return 1.0
    gdim = points.shape[1]
    lo, hi = np.full(gdim, np.inf), np.full(gdim, -np.inf)
    if len(points):
        lo, hi = points.min(axis=0), points.max(axis=0)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    edges = np.sort(hi - lo)[::-1][:dim]
    if len(edges) < dim or edges[-1] <= 0.0:  # degenerate: by the count alone
        return max(1.0, float(count) ** (1.0 / dim))
    # (never more than the nodes: clusters far apart span a box they do not fill)
    return min(float(count), max(1.0, float(edges[0] * (count / np.prod(edges)) ** (1.0 / dim))))


def newton_max_it(max_it: int | str, across: float) -> int:
    """The most Newton steps of a solve: ``max_it`` (``solver.max_it``) if it is a number;
    for ``auto`` max(:data:`MAX_IT_FLOOR`, ⌈n⌉) with n the nodes ``across`` the
    constrained set (:func:`nodes_across`: along Γ_C, or across Ω for an obstacle).

    Why: from a cold start an active-set path moves the free boundary by a band of nodes
    or more per step, so its Newton steps grow like 1/h and end within about n steps —
    measured 0.14–0.17 n for min on deal.II's step-41 obstacle (21, 39, 75 and 144 steps
    at 128² … 1024² cells), 0.42 n for PETSc's vinewtonssls (53 steps at 128²), where a
    fixed 50 failed from 512² on.  A solve that cannot converge stops after O(1/h) steps,
    about what the slowest path that can would cost.  Sets at most 50 nodes across keep
    the floor of 50.

    Args:
        max_it: a positive number of steps, or ``"auto"``.
        across: the nodes across the constrained set.

    Returns:
        The step limit.
    """
    if max_it != "auto":
        return int(max_it)
    return max(MAX_IT_FLOOR, int(np.ceil(MAX_IT_PER_NODE_ACROSS * across - 1e-9)))
