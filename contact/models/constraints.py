"""Contact conditions: the objects a user composes with their own forms.

Contact conditions a problem is subject to, each an object over UFL measures and
DOLFINx functions that a user composes with their own forms
(:class:`~contact.models.forms.ComplementarityProblem`) and that the scene's models build
alike (SPEC §1–2, docs/theory.md §1):

* :class:`Unilateral` — u ≤ g or u ≥ g at the nodes of a measure (dx: an obstacle in Ω;
  ds(tag): a Signorini condition on tagged facets), or at given DoFs;
* :class:`RigidObstacle` — an elastic body's tagged facets against a rigid surface
  (:class:`Plane` with any normal, :class:`Ball` — a circle or sphere —, :class:`Cylinder`,
  or the user's :class:`SignedDistance`): u·n ≤ g with n(x) the normal towards the obstacle
  and g(x) the initial gap, in small strain; on the current configuration for a
  hyperelastic body where the gap is not affine in u;
* :class:`MortarPair` — two tagged surfaces of bodies in one mesh, coupled by dual mortar
  (docs/theory.md §1.5);

and the friction law on a rigid obstacle's or a pair's contact nodes, :class:`Tresca` or
:class:`Coulomb` (docs/theory.md §1.4).

A surface is its signed distance g(x) (> 0 on the body's side) with the unit normal
n(x) = −∇g towards the obstacle and its derivative Dn = dn/dx: :meth:`Plane.project` and its
siblings give them at points (NumPy, every Newton iterate on the current configuration),
:meth:`Plane.expression` as UFL in the spatial coordinate (the estimators' n and g).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import dolfinx
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from ..base import indices
from ..solvers.options import FrictionOptions
from ..solvers.problem import Constraint, Output, ProblemData
from . import form_checks as checks
from .problem import contact_ends, lumped_weights


@dataclass
class ContactSet:
    """What a problem's contact conditions make of its assembled K and b.

    What a problem's contact conditions make of its assembled K and b: the constraint set,
    the parts of the :class:`~contact.solvers.problem.DiscreteProblem` they decide (where
    the nodal fields are written, the change of basis u = Q x, the current configuration's
    nodes), the data the estimators and reports read (``data``), and — where a change of
    basis replaced them — the new K̃, b̃ and the Dirichlet conditions on the unknowns.
    """

    constraint: Constraint
    output: Output = field(default_factory=Output)
    data: ProblemData = field(default_factory=ProblemData)
    K: Any = None  # PETSc.Mat K̃ = Qᵀ K Q, or None
    b: Any = None  # PETSc.Vec b̃ = Qᵀ b, or None
    bcs: list | None = None
    basis: Any = None  # PETSc.Mat Q with u = Q x, or None
    basis_inverse: Any = None  # PETSc.Mat Q⁻¹ when Q is not orthogonal, or None
    current: Any = None  # contact on the current configuration (CurrentContact), or None

    @property
    def kind(self) -> str:
        """How a residual problem reads its unknowns.

        How a residual problem reads its unknowns: ``plain`` (u), ``rotated`` (x = Qᵀ u,
        contact nodes on their (n, t) axes) or ``current`` (contact on the current
        configuration).
        """
        if self.current is not None:
            return "current"
        return "rotated" if self.basis is not None else "plain"


#: a bound: a number, a Function on V, a UFL expression (of ``ufl.SpatialCoordinate``), values
#: at the constrained DoFs, or f(x) → values at points x of shape (3, n) (as
#: ``Function.interpolate`` takes it)
Bound = float | fem.Function | ufl.core.expr.Expr | np.ndarray | Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Unilateral:
    """A unilateral constraint u ≤ g (``side="upper"``) or u ≥ g (``side="lower"``).

    Where it holds: ``measure`` — ``ufl.dx`` (default: every node of Ω, the obstacle
    problem) or ``ds(tag)`` with the facet tags as its ``subdomain_data`` (the nodes of those
    facets, a Signorini condition); its weights w_i = ∫ φ_i d(measure) (P2 on triangles and
    tetrahedra: the P1-iso-P2 lumped mass, positive where ∫ φ_i is not;
    ``lumped_weights`` of ``contact.models.problem``).  On a vector space
    the constraint acts on one ``component`` u_k (e.g. the normal displacement against a
    plane): its DoFs there, and a bound given as a number, values at those DoFs, or a
    scalar f(x).  Or explicit ``dofs`` (owned local indices of V, any components) with
    ``weights`` (default 1: λ_i is then the nodal reaction R_i).  Dirichlet DoFs are never
    constrained.  A bound given as a UFL expression is interpolated at the nodes, and the
    equilibrated estimator reads it as written (the obstacle ψ itself, not its
    interpolant); ``nodal`` may give the interpolant instead (g on a space, the scene's
    expressions evaluated at the DoF points).

    A record: its fields are checked against u's space when a problem is built
    (``check_constraint``), on every rank alike — the
    side, a bound that is finite (a callable's values of shape (n,) for points of shape
    (3, n)), a measure that selects some facet or cell, ``dofs`` that are owned integer
    indices given once each, ``weights`` finite and > 0.

    Args:
        bound: g: a number, a Function on V, values at the constrained DoFs, a callable
            ``x -> values`` on points of shape (3, n), or a UFL expression. On a vector
            space with ``component``, a scalar bound of that component.
        side: ``"upper"`` for u ≤ g, ``"lower"`` for u ≥ g.
        measure: ``ufl.dx`` (the default) or ``ds(tag)``.
        dofs: Explicit owned local DoF indices of V, instead of a measure.
        weights: The weights w_i of ``dofs`` (default 1).
        component: On a vector space, the component k the constraint acts on.
        nodal: g on a space, when the bound's interpolant should come from elsewhere than
            the bound as written.

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
    nodal: Callable[[fem.FunctionSpace], fem.Function] | None = None

    @property
    def sign(self) -> float:
        """The constraint's sign σ, +1 for u ≤ g and −1 for u ≥ g."""
        return 1.0 if self.side == "upper" else -1.0

    @property
    def in_domain(self) -> bool:
        """Whether the constraint holds in Ω (``dx``: the obstacle problem), not on facets."""
        return self.dofs is None and (
            self.measure is None or self.measure.integral_type() == "cell"
        )

    @property
    def ids(self) -> tuple[int, ...]:
        """The facet tags of Γ_C (``ds(tag)``); () in Ω or at given DoFs."""
        if self.measure is None or self.measure.integral_type() != "exterior_facet":
            return ()
        return measure_ids(self.measure)

    def discretise(
        self, V: fem.FunctionSpace, bcs: Sequence[fem.DirichletBC], allow_empty: bool = False
    ) -> ContactSet:
        """Return the constraint set of this condition on u's space V.

        Its DoFs, weights and bound
        (:meth:`nodes`, :meth:`bound_function`); on facets of a scalar space, the ends of
        Γ_C on the closure of Γ_D, which get the multiplier of their nearest contact DoF
        (``contact_ends``).  Collective.
        """
        dofs, w = self.nodes(V, bcs, allow_empty)
        g = self.bound_function(V, dofs)
        output = Output()
        if self.ids and self.component is None and self.dofs is None:
            n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
            tdim = V.mesh.topology.dim
            assert self.measure is not None  # a facet condition
            candidates = fem.locate_dofs_topological(V, tdim - 1, measure_facets(self.measure))
            fixed = np.concatenate([bc.dof_indices()[0] for bc in bcs] or [np.zeros(0, np.int32)])
            ends = contact_ends(V, candidates[candidates < n_owned], candidates, fixed)
            output = Output(ends=ends[0], end_neighbours=ends[1])
        constraint = Constraint(
            dofs, g.x.array[dofs].copy(), w, self.sign, in_domain=self.in_domain
        )
        return ContactSet(constraint, output, ProblemData(g_h=g))

    def nodes(
        self, V: fem.FunctionSpace, bcs: Sequence[fem.DirichletBC], allow_empty: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the constrained owned DoFs (no Dirichlet DoF) and their weights.

        (dofs, w): the constrained owned DoFs (no Dirichlet DoF) and their weights.
        Collective; the constraint is checked first (``check_constraint``).
        A measure that selects nothing, or (unless ``allow_empty``) a constraint left with no
        DoF on any rank, is a ValueError (on every rank).
        """
        comm = V.mesh.comm
        n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        fixed = np.concatenate([bc.dof_indices()[0] for bc in bcs] or [np.zeros(0, np.int32)])
        if self.dofs is not None:
            dofs = np.asarray(self.dofs, dtype=np.int32)
            w = np.ones(len(dofs)) if self.weights is None else np.asarray(self.weights, float)
            keep = ~np.isin(dofs, fixed)
            if not allow_empty:
                checks.check_constrained(comm, dofs[keep], by_dofs=True)
            return dofs[keep], w[keep]
        measure = self.measure if self.measure is not None else ufl.dx(domain=V.mesh)
        dofs = _dofs_of(V, measure, self.component)
        dofs = indices.setdiff(dofs[dofs < n_owned], fixed).astype(np.int32)
        if not allow_empty:
            checks.check_constrained(comm, dofs, by_dofs=False)
        w = lumped_weights(V, measure, self.component)[dofs]
        if comm.allreduce(bool(np.any(w <= 0)), op=MPI.LOR):
            raise ValueError(
                "Unilateral.measure: some constrained DoFs have a lumped weight ≤ 0; "
                "give dofs and weights"
            )
        return dofs, w

    def bound_function(self, V: fem.FunctionSpace, dofs: np.ndarray) -> fem.Function:
        """Return the bound g as a Function on V (at the constrained DoFs at least).

        Collective: a callable bound that
        fails or returns the wrong shape, values of the wrong length, or a bound that is
        not finite at some constrained DoF, is a ValueError on every rank.
        """
        comm = V.mesh.comm
        if self.nodal is not None:
            g = self.nodal(V)
            checks.check_finite_bound(comm, g.x.array[dofs])
            return g
        g = fem.Function(V, name="bound")
        interpolated = isinstance(self.bound, (fem.Function, ufl.core.expr.Expr)) or callable(
            self.bound
        )
        if interpolated and self.component is not None:  # a scalar bound on u_k's DoFs
            S, to_parent = V.sub(self.component).collapse()
            into = fem.Function(S)
        else:
            S, to_parent, into = V, None, g

        def assign() -> None:  # local: no collective
            bound = self.bound
            if isinstance(bound, fem.Function) and bound.function_space is S:
                into.x.array[:] = bound.x.array
            elif isinstance(bound, fem.Function):
                into.interpolate(bound)
            elif isinstance(bound, ufl.core.expr.Expr):
                into.interpolate(fem.Expression(bound, S.element.interpolation_points))
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
    ``check_constraint``).  Collective; a tagged measure that selects no
    entity on any rank is a ValueError.
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


def _vector(x: np.ndarray) -> np.ndarray:
    return np.asarray(x, dtype=float)


@dataclass(frozen=True)
class Plane:
    """A rigid plane through ``point`` with the normal ν pointing towards the body.

    g(x) = (x − p)·ν, n = −ν, Dn = 0 (``normal`` is normalised).

    Args:
        point: a point p of the plane (gdim coordinates).
        normal: the plane's normal ν, towards the body (any length; any direction: a tilted
            plane rotates its contact nodes to their (n, t) axes).

    Example:
        >>> import contact
        >>> floor = contact.Plane(point=[0.0, -0.1], normal=[1.0, 2.0])  # tilted
        >>> floor.normal.round(4).tolist()
        [0.4472, 0.8944]
    """

    point: np.ndarray
    normal: np.ndarray

    def __post_init__(self) -> None:
        """Store the point and the normalised normal as float arrays."""
        nu = _vector(self.normal)
        object.__setattr__(self, "point", _vector(self.point))
        object.__setattr__(self, "normal", nu / np.linalg.norm(nu))

    @property
    def scale(self) -> float:
        """The size of the numbers g subtracts beyond the coordinates, ``|p|``."""
        return float(np.max(np.abs(self.point), initial=0.0))

    @property
    def position(self) -> np.ndarray:
        """The plane's reference point p (a moving plane's translation is that of p)."""
        return self.point

    def project(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(g, n, Dn) at the points x (k, gdim)."""
        k, d = x.shape
        return (x - self.point) @ self.normal, np.tile(-self.normal, (k, 1)), np.zeros((k, d, d))

    def expression(self, X: Any) -> tuple[Any, Any]:
        """(n, g) as UFL in the spatial coordinate X: n = −ν, g = (X − p)·ν."""
        nu = self.normal
        return (
            ufl.as_vector((-nu).tolist()),
            ufl.dot(X - ufl.as_vector(self.point.tolist()), ufl.as_vector(nu.tolist())),
        )

    def axis(self) -> int | None:
        """Return k when the normal is a coordinate direction ±e_k, else None.

        u·n ≤ g is then a bound on the single component u_k.
        """
        k = int(np.argmax(np.abs(self.normal)))
        return k if abs(abs(self.normal[k]) - 1.0) <= 1e-12 else None


@dataclass(frozen=True)
class Ball:
    """A rigid circle (2D) or sphere (3D), the body outside.

    With ``r = |x − c|``: g = r − R, n = (c − x)/r, Dn = −(I − n nᵀ)/r.

    Args:
        center: the centre c (gdim coordinates).
        radius: the radius R > 0.

    Example:
        >>> import contact, numpy as np
        >>> ball = contact.Ball(center=[0.0, 2.0], radius=1.0)
        >>> g, n, Dn = ball.project(np.array([[0.0, 0.5]]))
        >>> g.tolist(), (n + 0.0).tolist()
        ([0.5], [[0.0, 1.0]])
    """

    center: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        """Store the centre as a float array."""
        object.__setattr__(self, "center", _vector(self.center))
        object.__setattr__(self, "radius", float(self.radius))

    @property
    def scale(self) -> float:
        """The size of the numbers g subtracts beyond the coordinates, ``|c| + R``."""
        return float(np.max(np.abs(self.center), initial=0.0)) + self.radius

    @property
    def position(self) -> np.ndarray:
        """The centre c (a moving ball's translation is that of c)."""
        return self.center

    def project(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (g, n, Dn) at the points x (k, gdim).

        A point at the centre or not finite (an
        iterate that diverged) gives NaN there, without a warning: the solver stops on it
        (``diverged_function_nanorinf``) and says so.
        """
        rel = x - self.center
        r = np.linalg.norm(rel, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            n = -rel / r[:, None]
            d = x.shape[1]
            Dn = -(np.eye(d)[None] - n[:, :, None] * n[:, None, :]) / r[:, None, None]
        return r - self.radius, n, Dn

    def expression(self, X: Any) -> tuple[Any, Any]:
        """(n, g) as UFL in the spatial coordinate X."""
        c = ufl.as_vector(self.center.tolist())
        return (c - X) / ufl.sqrt(ufl.dot(c - X, c - X)), ufl.sqrt(
            ufl.dot(X - c, X - c)
        ) - self.radius


@dataclass(frozen=True)
class Cylinder:
    """A rigid circular cylinder (3D), the body outside.

    With p = (x − c) − ((x − c)·a) a and ``r = |p|``: g = r − R, n = −p/r,
    Dn = −(I − a aᵀ − n nᵀ)/r.

    Args:
        point: a point c of the cylinder's axis.
        axis: the axis' direction a (normalised).
        radius: the radius R > 0.

    Example:
        >>> import contact, numpy as np
        >>> roller = contact.Cylinder(point=[0, 0, 2], axis=[0, 1, 0], radius=1.0)
        >>> g, n, Dn = roller.project(np.array([[0.0, 5.0, 0.5]]))
        >>> g.tolist(), (n + 0.0).tolist()
        ([0.5], [[0.0, 0.0, 1.0]])
    """

    point: np.ndarray
    axis: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        """Store the point and the normalised axis as float arrays."""
        a = _vector(self.axis)
        object.__setattr__(self, "point", _vector(self.point))
        object.__setattr__(self, "axis", a / np.linalg.norm(a))
        object.__setattr__(self, "radius", float(self.radius))

    @property
    def scale(self) -> float:
        """The size of the numbers g subtracts beyond the coordinates, ``|c| + R``."""
        return float(np.max(np.abs(self.point), initial=0.0)) + self.radius

    @property
    def position(self) -> np.ndarray:
        """The axis' point c (a moving cylinder's translation is that of c)."""
        return self.point

    def project(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(g, n, Dn) at the points x (k, 3)."""
        a = self.axis
        rel = x - self.point
        perp = rel - (rel @ a)[:, None] * a
        r = np.linalg.norm(perp, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):  # a point on the axis: NaN
            n = -perp / r[:, None]
            d = x.shape[1]
            P = np.eye(d) - np.outer(a, a)
            Dn = -(P[None] - n[:, :, None] * n[:, None, :]) / r[:, None, None]
        return r - self.radius, n, Dn

    def expression(self, X: Any) -> tuple[Any, Any]:
        """(n, g) as UFL in the spatial coordinate X."""
        a, c = ufl.as_vector(self.axis.tolist()), ufl.as_vector(self.point.tolist())
        perp = (X - c) - ufl.dot(X - c, a) * a
        r = ufl.sqrt(ufl.dot(perp, perp))
        return -perp / r, r - self.radius


@dataclass(frozen=True)
class SignedDistance:
    """A rigid obstacle given by its signed distance and normal.

    A rigid obstacle given by the user as its signed distance g(x) (> 0 on the body's side)
    and unit normal n(x) = −∇g towards it (NumPy: points (k, gdim) → (k,) and (k, gdim)).

    Args:
        gap: g at points.
        normal: n at points.
        expression_of: g as UFL of the spatial coordinate X, for the estimators (``n = −∇g/|∇g|``);
            None: the estimators refuse this obstacle.
        curvature: Dn = dn/dx at points (k, gdim, gdim), for contact on the current
            configuration (None: 0, a Jacobian without the obstacle's curvature term).
        scale: the size of the numbers g subtracts beyond the point's coordinates.

    Example:
        >>> import contact, numpy as np
        >>> wall = contact.SignedDistance(  # the plane x = 1, the body on its left
        ...     gap=lambda x: 1.0 - x[:, 0],
        ...     normal=lambda x: np.tile([1.0, 0.0], (len(x), 1)),
        ...     expression_of=lambda X: 1.0 - X[0],
        ... )
        >>> wall.project(np.array([[0.25, 0.0]]))[0].tolist()
        [0.75]
    """

    gap: Callable[[np.ndarray], np.ndarray]
    normal: Callable[[np.ndarray], np.ndarray]
    expression_of: Callable[[Any], Any] | None = None
    curvature: Callable[[np.ndarray], np.ndarray] | None = None
    scale: float = 0.0
    position: np.ndarray | None = None

    def project(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(g, n, Dn) at the points x (k, gdim)."""
        k, d = x.shape
        Dn = np.zeros((k, d, d)) if self.curvature is None else self.curvature(x)
        return np.asarray(self.gap(x), float), np.asarray(self.normal(x), float), Dn

    def expression(self, X: Any) -> tuple[Any, Any]:
        """Return (n, g) as UFL, ``n = −∇g/|∇g|`` of the user's expression."""
        if self.expression_of is None:
            raise ValueError(
                "SignedDistance.expression_of: the estimators need g as a UFL expression"
            )
        g = self.expression_of(X)
        grad = ufl.grad(g)
        return -grad / ufl.sqrt(ufl.dot(grad, grad)), g


#: a rigid obstacle's surface
Surface = Plane | Ball | Cylinder | SignedDistance


@dataclass(frozen=True)
class Tresca:
    """Tresca friction: ``|λ_t| ≤ s``, sticking below the threshold (docs/theory.md §1.4).

    Args:
        threshold: the slip threshold s ≥ 0 (a stress): a number or a UFL expression of
            the spatial coordinate; the estimators read it as written.
        at_nodes: s at points x of shape (3, n) → (n,), where the nodal values should come
            from elsewhere than the UFL expression (None: evaluated from it).
        options: the knobs of the tangential rows (``FrictionOptions``).

    Example:
        >>> import contact
        >>> contact.Tresca(0.3).law
        'tresca'
    """

    threshold: Any
    at_nodes: Callable[[np.ndarray], np.ndarray] | None = None
    options: FrictionOptions = FrictionOptions()
    #: the names its messages give (the threshold's, and when it is evaluated)
    key: str = "Tresca.threshold"
    when: str = ""

    law = "tresca"

    def values(self, V: fem.FunctionSpace, nodes: np.ndarray) -> np.ndarray:
        """Return the threshold s at the nodes (blocks of V's DoFs).

        From ``at_nodes`` at their coordinates, or the threshold itself interpolated at
        them.
        """
        X = V.tabulate_dof_coordinates()[nodes]
        if self.at_nodes is not None:
            return np.asarray(self.at_nodes(X.T), dtype=float)
        if not isinstance(self.threshold, ufl.core.expr.Expr):
            return np.full(len(nodes), float(self.threshold))
        S, to_parent = V.sub(0).collapse()
        s = fem.Function(S)
        s.interpolate(fem.Expression(self.threshold, S.element.interpolation_points))
        node_of = np.asarray(to_parent, dtype=np.int64) // V.dofmap.index_map_bs
        values = np.empty(len(node_of))
        values[node_of] = s.x.array
        return values[nodes]


@dataclass(frozen=True)
class Coulomb:
    """Coulomb friction: ``|λ_t| ≤ F |λ_n|`` (docs/theory.md §1.4).

    Args:
        coefficient: the friction coefficient F ≥ 0.
        options: the knobs of the tangential rows (``FrictionOptions``: c_t, the HSW or
            projection form, Newton or the fixed point).

    Example:
        >>> import contact
        >>> law = contact.Coulomb(0.3)
        >>> law.law, law.coefficient
        ('coulomb', 0.3)
    """

    coefficient: float
    options: FrictionOptions = FrictionOptions()

    law = "coulomb"


#: a friction law
Friction = Tresca | Coulomb


@dataclass(frozen=True)
class RigidObstacle:
    """An elastic body's contact facets against a rigid surface: u·n ≤ g.

    Small strain: the normal and gap of the reference configuration; finite strain: the
    gap of the deformed point, where the gap is not affine in u.

    Args:
        surface: :class:`Plane`, :class:`Ball`, :class:`Cylinder` or :class:`SignedDistance`.
        measure: ``ds(tag)`` of the contact facets (``subdomain_data`` the facet tags).
        friction: :class:`Tresca`, :class:`Coulomb` or None (frictionless).
        motion: the surface's translation since the previous load step (the slip of contact
            on the current configuration is relative to it); None: at rest.
        moving: the surface moves with the load: contact nodes may start inside it (a
            prescribed penetration; a curved obstacle at rest refuses them).

    Example:
        >>> import contact, ufl
        >>> from dolfinx import mesh
        >>> from mpi4py import MPI
        >>> msh = mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
        >>> bottom = mesh.locate_entities_boundary(msh, 1, lambda x: x[1] < 1e-12)
        >>> tags = mesh.meshtags(msh, 1, bottom, 3)
        >>> ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
        >>> floor = contact.Plane(point=[0.0, -0.01], normal=[0.2, 1.0])
        >>> contact.RigidObstacle(floor, ds(3), friction=contact.Coulomb(0.3)).ids
        (3,)
    """

    surface: Surface
    measure: ufl.Measure
    friction: Friction | None = None
    motion: np.ndarray | None = None
    moving: bool = False

    @property
    def ids(self) -> tuple[int, ...]:
        """The facet tags of the contact facets."""
        return measure_ids(self.measure)


@dataclass(frozen=True)
class MortarPair:
    """Two tagged surfaces of bodies in one mesh, in contact through dual mortar.

    The ``slave`` surface's nodes carry the constraint g_i − x_{i,n} ≥ 0 on their
    displacement relative to the ``master`` surface (docs/theory.md §1.5).

    Args:
        slave: ``ds(tag)`` of the slave facets.
        master: ``ds(tag)`` of the master facets.
        friction: :class:`Tresca`, :class:`Coulomb` or None.
        search: the largest distance between a slave facet and a master facet it meets
            (None: the diameter of the pair's surfaces).
        names: the slave and master surfaces' names in messages.

    Example:
        >>> import contact, ufl
        >>> from dolfinx import mesh
        >>> from mpi4py import MPI
        >>> msh = mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
        >>> ds = ufl.Measure("ds", domain=msh)
        >>> pair = contact.MortarPair(slave=ds(5), master=ds(6), names=("upper", "lower"))
        >>> pair.ids, pair.master_ids
        ((5,), (6,))
    """

    slave: ufl.Measure
    master: ufl.Measure
    friction: Friction | None = None
    search: float | None = None
    names: tuple[str, str] = ("slave", "master")

    @property
    def ids(self) -> tuple[int, ...]:
        """The facet tags of the slave surface."""
        return measure_ids(self.slave)

    @property
    def master_ids(self) -> tuple[int, ...]:
        """The facet tags of the master surface."""
        return measure_ids(self.master)


def measure_ids(measure: ufl.Measure) -> tuple[int, ...]:
    """The tag values a measure integrates over (``ds(3)``: (3,), ``ds((3, 4))``: (3, 4))."""
    tag = measure.subdomain_id()
    return tuple(tag) if isinstance(tag, tuple) else (tag,)


def measure_facets(measure: ufl.Measure) -> np.ndarray:
    """The local facets (sorted) a tagged ``ds`` measure integrates over."""
    tags = measure.subdomain_data()
    return np.sort(tags.indices[np.isin(tags.values, measure_ids(measure))]).astype(np.int32)


#: a contact condition of a problem
Condition = Unilateral | RigidObstacle | MortarPair


def check_condition(c: Any, V: fem.FunctionSpace) -> dict[str, object]:
    """Check a contact condition on its own and against u's space.

    A contact condition ``c`` on its own and against u's space ``V`` (local data; a
    one-line TypeError or ValueError naming the argument): a :class:`Unilateral`
    (``check_constraint``), or a :class:`RigidObstacle` /
    :class:`MortarPair` on a vector space of gdim components, over tagged facets of u's
    mesh, with a surface and a friction law of the kinds above.  Returns what decides the
    collectives it enters (for :func:`~.form_checks.agree` with ``same``).
    """
    if isinstance(c, Unilateral):
        return checks.check_constraint(c, V)
    if not isinstance(c, (RigidObstacle, MortarPair)):
        raise TypeError(
            f"constraint: expected a contact.Unilateral, got {type(c).__name__} (or a "
            "RigidObstacle, a MortarPair, or a list of conditions)"
        )
    name = type(c).__name__
    if V.dofmap.index_map_bs != V.mesh.geometry.dim:
        raise ValueError(f"{name}: u must be a displacement (a vector of gdim components)")
    measures = (
        {"measure": c.measure}
        if isinstance(c, RigidObstacle)
        else {
            "slave": c.slave,
            "master": c.master,
        }
    )
    for key, measure in measures.items():
        checks.check_measure(measure, V, f"{name}.{key}")
        if measure is None or measure.integral_type() != "exterior_facet":
            raise ValueError(f"{name}.{key}: expected ds(tag) of the contact facets")
        if measure.subdomain_id() == "everywhere":
            raise ValueError(f"{name}.{key}: expected ds(tag) with the facet tags")
    if isinstance(c, RigidObstacle) and not isinstance(
        c.surface, (Plane, Ball, Cylinder, SignedDistance)
    ):
        raise TypeError(
            f"RigidObstacle.surface: expected a Plane, Ball, Cylinder or SignedDistance, "
            f"got {type(c.surface).__name__}"
        )
    if c.friction is not None and not isinstance(c.friction, (Tresca, Coulomb)):
        raise TypeError(
            f"{name}.friction: expected a Tresca or Coulomb law, got {type(c.friction).__name__}"
        )
    return {
        f"{name}.{key}": f"{m.integral_type()}({m.subdomain_id()})" for key, m in measures.items()
    }
