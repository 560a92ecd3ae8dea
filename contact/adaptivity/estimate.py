"""Residual a posteriori error estimator (docs/theory.md §5) as DG0 indicator forms.

With w a DG0 test function, one assembly per term of the form below gives every η_T²
(each term's vector is kept, so its total Σ_T costs no second assembly):

    η_T² = h_T² ‖f + div(k∇u_h)‖²_T                               volume
         + Σ_{E ⊂ ∂T interior} ½ h_E ‖[k ∂u_h/∂n]‖²_E                jump
         + Σ_{E ⊂ ∂T ∩ Γ_N} h_E ‖t − k ∂u_h/∂n‖²_E                   neumann  (t = 0 on
                                                                     unmarked facets)
         + Σ_{E ⊂ ∂T ∩ Γ_C} ( h_E ‖λ_h + t_C − k ∂u_h/∂n‖²_E         consistency
                              + ‖λ_h⁺‖²_E                            sign (λ⁺ = max(λ, 0))
                              + ∫_E |min(λ_h, 0)(u_h − g)| ds )      complementarity

Elasticity replaces k∂u/∂n by the traction σ(u_h)n and adds the frictionless tangential
term h_E ‖σ_t(u_h)‖²_E on Γ_C; with friction (Hild & Lleras, SIAM J. Numer. Anal. 47, 2009)
that term becomes h_E ‖λ_t − σ_t(u_h)‖²_E and two terms join: ‖(|λ_t| − ρ)⁺‖²_E (friction
bound) and ∫_E |ρ |s_t| + λ_t·s_t| ds (slip; ≥ 0 and zero when the law holds pointwise).

For the obstacle problem (constraint σ(u − ψ) ≤ 0 in Ω, λ = −div(k∇u) − f) the same
terms live in the cells: the volume residual is f + λ_h + div(k∇u_h), the sign term is
h_T² ‖(σλ_h)⁺‖²_T and the complementarity term ∫_T min(σλ_h, 0) σ(u_h − ψ) dx.  h_T is
the cell diameter, h_E the facet size.  η = (Σ_T η_T²)^{1/2}.  A P2 obstacle solution's
λ_h enters as the P1 density of its reactions (:func:`vertex_density`; 2D only: in 3D the
residual estimator is refused, :data:`RESIDUAL_P2_OBSTACLE_3D`).

The complementarity integrand is taken in absolute value: it equals
min(λ_h, 0)(u_h − g) ≥ 0 whenever u_h ≤ g, and stays a non-negative indicator (instead of
making Σ η_T² negative) for an infeasible u_h, e.g. between nodes for P2 or after a solve
that did not converge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from mpi4py import MPI
from ufl.geometry import FacetJacobianDeterminant

from ..base.errors import ConfigError
from ..models.constraints import Friction, MortarPair, RigidObstacle, Unilateral
from ..models.discrete import Problem
from ..models.physics import BoundaryData, Diffusion, Elasticity
from ..models.problem import iso_p2_rule, iso_p2_weights
from ..solvers import Result
from .cellwise import assemble_terms

TERMS = ("volume", "jump", "neumann", "consistency", "sign", "complementarity")
#: the refusal of the residual estimator for a P2 obstacle problem in 3D (also by the scene's
#: configuration when its mesh shows the dimension): the vertices of a contact zone are
#: lifted by O(h²) (docs/theory.md §1.2), so div(k∇u_h) oscillates by O(λ) there
RESIDUAL_P2_OBSTACLE_3D = (
    "estimator: residual does not converge with a P2 obstacle solution in 3D (its volume "
    "term sees the vertices lifted off the obstacle in the contact zone); use equilibrated"
)
#: the estimators of :func:`estimate`: the residual estimator (this module) and the guaranteed
#: bounds of an equilibrated flux (:mod:`.equilibration`), σ_h ∈ RT_p or, for a P1 solution,
#: the lowest-order flux σ_h ∈ RT_0
KINDS = ("residual", "equilibrated", "equilibrated_rt0")


@dataclass
class Estimate:
    """The a posteriori error estimate of one solve (:func:`contact.estimate`).

    Attributes:
        eta_T: The cell indicators η_T as a DG0 function (what :func:`contact.mark` takes).
        eta: The global estimate η = (Σ_T η_T²)^{1/2} for the residual estimator, the
            guaranteed bound for the equilibrated ones (an energy norm, in the units of
            (force × length)^{1/2}).
        terms: The global total Σ_T of each term of η_T² (residual: ``volume``, ``jump``,
            ``neumann``, ``consistency``, ``sign``, ``complementarity``, plus the friction
            and pair terms where they apply; equilibrated: the parts of the bound).
        computed: False for a solve the adaptive loop leaves unestimated (its last level
            with ``adapt.estimate_last`` false, :meth:`skipped`: no η_T, η NaN, no terms).
    """

    eta_T: fem.Function | None
    eta: float
    terms: dict[str, float]
    computed: bool = True

    @classmethod
    def skipped(cls) -> Estimate:
        """Return the estimate of a solve left unestimated: no η_T, η NaN, no terms."""
        return cls(None, math.nan, {}, computed=False)


def _cellwise(msh, degree: fem.Function | None = None):
    """Return what every indicator form needs.

    What every indicator form needs: the DG0 test function w, the facet normal, h_T (cell
    diameter), h_E (facet size), h_S (its mean on interior facets), dx, dS, and a zero form
    to start sums from.  With the cells' ``degree`` p_T (an hp solution, DG0) the sizes are
    the p-weighted h_T/p_T, h_E/p_E and h_S/max(p⁺, p⁻).
    """
    w = ufl.TestFunction(fem.functionspace(msh, ("DG", 0)))
    dx, dS = ufl.Measure("dx", domain=msh), ufl.Measure("dS", domain=msh)
    h_T, h_E = cell_sizes(msh, w.ufl_function_space())
    h_S = ufl.avg(h_E)  # interior facets
    if degree is not None:
        h_T, h_S = h_T / degree, h_S / ufl.max_value(degree("+"), degree("-"))
        h_E = h_E / degree
    zero = fem.Constant(msh, 0.0) * w * dx
    return w, ufl.FacetNormal(msh), h_T, h_E, h_S, dx, dS, zero


def cell_sizes(msh: dmesh.Mesh, dg0: fem.FunctionSpace) -> tuple[Any, Any]:
    """Return h_T (the cell diameter) and h_E (the facet size |E|^{1/(d−1)}) as UFL expressions.

    On a mesh of affine cells they are UFL's own CellDiameter and FacetArea^{1/(d−1)}.  On
    curved cells (a coordinate element of degree > 1, for which UFL computes neither) h_T
    is the diameter of the cell's vertex simplex, a DG0 function on every local cell
    (ghosts included), and h_E = (|det J_E| |Ê|)^{1/(d−1)} with J_E the facet's Jacobian
    and |Ê| the reference facet's measure (1 for the unit interval, 1/2 for the unit
    triangle): the facet's measure where it is flat, pointwise on a curved facet.  Both
    equal the affine values on straight cells and differ from them by O(h/R) relative on
    a boundary of curvature radius R.

    Args:
        msh: the mesh (lengths in its unit).
        dg0: the DG0 space of ``msh`` that carries h_T on curved cells.

    Returns:
        (h_T, h_E), lengths.
    """
    tdim = msh.topology.dim
    if msh.geometry.cmaps[0].degree == 1:
        return ufl.CellDiameter(msh), ufl.FacetArea(msh) ** (1.0 / (tdim - 1))
    n_all = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    P = msh.geometry.x[msh.geometry.dofmaps[0][:n_all, : tdim + 1]]
    i, j = np.triu_indices(tdim + 1, 1)
    h_T = fem.Function(dg0)
    h_T.x.array[dg0.dofmap.list[:n_all, 0]] = np.linalg.norm(P[:, i] - P[:, j], axis=2).max(axis=1)
    reference = 1.0 if tdim == 2 else 0.5  # |Ê|: the unit interval, the unit triangle
    h_E = (ufl.algebra.Abs(FacetJacobianDeterminant(msh)) * reference) ** (1.0 / (tdim - 1))
    return h_T, h_E


def indicator_terms(
    problem: Problem, result: Result, degree: fem.Function | None = None
) -> dict[str, ufl.Form]:
    """Return the estimator's terms as UFL forms linear in a DG0 test function.

    The terms as UFL forms linear in a DG0 test function (SPEC §5): of the scalar
    equations (:func:`scalar_terms`) or of an elastic body (:func:`elasticity_terms`);
    ``degree``: the cells' polynomial degrees of an hp solution (DG0).
    """
    if isinstance(problem.physics, Diffusion):
        return scalar_terms(problem, result, degree)
    return elasticity_terms(problem, result, degree)


def natural_facets(
    boundary: BoundaryData, msh: dmesh.Mesh, held: tuple[int, ...] = ()
) -> tuple[ufl.Measure, int | None]:
    """Return ``ds`` over the boundary parts with the undeclared exterior facets tagged.

    The exterior facets that no part of ``boundary`` names (Γ_D, Γ_N, the free and
    symmetry parts) and that are not in ``held`` (the contact parts' tags) carry the
    natural condition σ(u)n = 0 in the problem solved, as the equilibrated bounds take
    them (:class:`~.equilibration.cells.FluxData`); the residual estimator checks that
    condition there too.  Collective.

    Args:
        boundary: the problem's boundary parts.
        msh: the mesh.
        held: the tags of the contact parts.

    Returns:
        (ds, tag): ``ds`` over the parts' tags and ``tag`` on those facets, a value no part
        uses; ``boundary.measure(msh)`` and None when every exterior facet is declared.
    """
    tags, tdim = boundary.tags, msh.topology.dim
    declared = {
        *boundary.dirichlet,
        *boundary.neumann,
        *boundary.free,
        *(tag for tag, _ in boundary.symmetry),
        *held,
    }
    msh.topology.create_connectivity(tdim - 1, tdim)
    exterior = dmesh.exterior_facet_indices(msh.topology)
    facet_map = msh.topology.index_map(tdim - 1)
    value = np.full(facet_map.size_local + facet_map.num_ghosts, -1, dtype=np.int64)
    value[tags.indices] = tags.values
    undeclared = exterior[~np.isin(value[exterior], list(declared))]
    comm = msh.comm
    if comm.allreduce(len(undeclared), op=MPI.SUM) == 0:
        return boundary.measure(msh), None
    fresh = comm.allreduce(int(np.max(tags.values, initial=0)), op=MPI.MAX) + 1
    value[undeclared] = fresh
    facets = np.flatnonzero(value >= 0).astype(np.int32)
    extended = dmesh.meshtags(msh, tdim - 1, facets, value[facets].astype(np.int32))
    return ufl.Measure("ds", domain=msh, subdomain_data=extended), fresh


def _physics[T](problem: Problem, kind: type[T]) -> T:
    """The problem's physics, which must be a ``kind``."""
    physics = problem.physics
    if not isinstance(physics, kind):
        raise ValueError(
            f"problem: its physics is {type(physics).__name__}, not {kind.__name__} "
            "(declare it when the problem is built: physics=...)"
        )
    return physics


def scalar_terms(
    problem: Problem, result: Result, degree: fem.Function | None = None
) -> dict[str, ufl.Form]:
    """The terms of the scalar Signorini and obstacle problems (module doc).

    With the cells' ``degree`` p_T (an hp solution, DG0) the weights are h_T/p_T and
    h_E/p_E, p_E the larger degree of the facet's cells (Melenk & Wohlmuth, Adv. Comput.
    Math. 15, 2001).
    """
    physics = _physics(problem, Diffusion)
    msh = problem.V.mesh
    u_h, lmbda_h = result.u_h, result.lmbda_h
    f, boundary = physics.f, physics.boundary
    (condition,) = problem.contacts
    assert isinstance(condition, Unilateral)  # a scalar problem's one condition
    contact = () if condition.in_domain else condition.ids
    loads = boundary.neumann
    g = problem.bound_function()
    ds, natural = natural_facets(boundary, msh, contact)
    w, n, h_T, h_E, h_S, dx, dS, zero = _cellwise(msh, degree)
    sigma = problem.constraint.sign
    flux = physics.flux(u_h)  # k ∇u_h
    obstacle = condition.in_domain
    if obstacle and iso_p2_rule(problem.V, ufl.dx) is not None:
        if msh.topology.dim == 3:
            raise ConfigError(RESIDUAL_P2_OBSTACLE_3D)
        lmbda_h = vertex_density(lmbda_h)

    residual = f + ufl.div(flux) + (lmbda_h if obstacle else 0)
    terms = {
        "volume": h_T**2 * residual**2 * w * dx,
        # ½ h_E ‖[k ∂u_h/∂n]‖²_E to each of the two cells of an interior facet
        "jump": 0.5 * h_S * ufl.jump(flux, n) ** 2 * (w("+") + w("-")) * dS,
        "neumann": zero,
        "consistency": zero,
        "sign": zero,
        "complementarity": zero,
    }
    for i in (i for i in loads if i not in contact):
        terms["neumann"] += h_E * (loads[i] - ufl.dot(flux, n)) ** 2 * w * ds(i)
    for i in (*boundary.free, *([] if natural is None else [natural])):
        terms["neumann"] += h_E * ufl.dot(flux, n) ** 2 * w * ds(i)
    if obstacle:
        terms["sign"] = h_T**2 * ufl.max_value(sigma * lmbda_h, 0) ** 2 * w * dx
        terms["complementarity"] = (
            abs(ufl.min_value(sigma * lmbda_h, 0) * sigma * (u_h - g)) * w * dx
        )
    else:
        for i in contact:
            t_C = loads.get(i, 0)
            terms["consistency"] += h_E * (lmbda_h + t_C - ufl.dot(flux, n)) ** 2 * w * ds(i)
            terms["sign"] += ufl.max_value(lmbda_h, 0) ** 2 * w * ds(i)
            terms["complementarity"] += abs(ufl.min_value(lmbda_h, 0) * (u_h - g)) * w * ds(i)
    return terms


def vertex_density(lmbda_h: fem.Function) -> fem.Function:
    """The multiplier of a P2 obstacle solution as a P1 density, for the residual terms.

    The nodal λ_i = R_i / w_i of a P2 solution alternates between the vertices (λ_i ≈ 0:
    their loads ∫ λ φ_i are O(h²) or negative) and the edge midpoints (≈ 4λ/3 in 2D), an
    O(λ) oscillation in every cell of a contact zone that the volume residual would measure
    as error.  Tested with the P1 hats ψ_a instead, the reactions are smooth:

        λ̄_a = R(ψ_a) / ∫ ψ_a,    R(ψ_a) = Σ_i ψ_a(x_i) R_i = Σ_i ψ_a(x_i) w_i λ_i,

    (units of λ: a flux per volume), the nodal rule of the weights w_i
    (:func:`~contact.models.problem.iso_p2_rule`) integrating ψ_a λ_h to Σ_i w_i λ_i ψ_a(x_i)
    exactly, and ∫ ψ_a exactly (ψ_a is affine on each cell).  λ̄ ≥ 0 where every λ_i ≥ 0
    (σ = −1; ≤ 0 for σ = +1): its sign is the multiplier's.  Collective.

    Args:
        lmbda_h: λ_h on the P2 space of u_h.

    Returns:
        λ̄_h on the P1 space of the same mesh.
    """
    V = lmbda_h.function_space
    msh = V.mesh
    points, weights = iso_p2_weights(msh.topology.dim)
    dx = ufl.dx(
        domain=msh,
        metadata={
            "quadrature_rule": "custom",
            "quadrature_points": points,
            "quadrature_weights": weights,
        },
    )
    P1 = fem.functionspace(msh, ("Lagrange", 1))
    psi = ufl.TestFunction(P1)
    reaction, area = (
        fem.assemble_vector(fem.form(form)) for form in (psi * lmbda_h * dx, psi * dx)
    )
    for vector in (reaction, area):
        vector.scatter_reverse(la.InsertMode.add)
    density = fem.Function(P1, name="lambda_P1")
    n = P1.dofmap.index_map.size_local
    density.x.array[:n] = reaction.array[:n] / area.array[:n]
    density.x.scatter_forward()
    return density


def elasticity_terms(
    problem: Problem, result: Result, degree: fem.Function | None = None
) -> dict[str, ufl.Form]:
    """Return the terms of an elastic body (docs/theory.md §5).

    docs/theory.md §5 for elasticity: k∂u/∂n becomes the traction T = σ(u_h)n, and on Γ_C (normal
    n_c towards the obstacle, λ_n the contact pressure, g the initial gap)

        h_E ‖λ_n − T·n_c‖²_E + h_E ‖T − (T·n_c) n_c‖²_E + ‖λ_n⁺‖²_E + ∫_E |min(λ_n, 0)(u_h·n_c − g)|

    (consistency, tangential — frictionless —, sign, complementarity).  A hyperelastic
    body's terms are those of the reference configuration, with the first Piola–Kirchhoff
    stress P(u_h) for σ and λ_n per reference area; where its contact is met on the current
    configuration (``problem.current``: a circle or sphere, or friction) n_c is the
    obstacle's normal at the deformed point x = X + u_h and the complementarity term
    ∫_E |min(λ_n, 0) g(X + u_h)| (g the obstacle's signed distance), with friction the slip
    that of the solver (along the current tangents, relative to the obstacle's motion).
    With the cells' ``degree`` p_T (an hp solution, DG0) the weights are h_T/p_T and
    h_E/p_E, as in :func:`scalar_terms`.
    """
    physics = _physics(problem, Elasticity)
    msh = problem.V.mesh
    u_h, lam = result.u_h, result.lmbda_h
    f, boundary = physics.f, physics.boundary
    rigid = [c for c in problem.contacts if isinstance(c, RigidObstacle)]
    pairs = [c for c in problem.contacts if isinstance(c, MortarPair)]
    held = (*(i for c in rigid for i in c.ids), *(i for c in pairs for i in c.ids + c.master_ids))
    ds, natural = natural_facets(boundary, msh, held)
    w, n, h_T, h_E, h_S, dx, dS, zero = _cellwise(msh, degree)
    sigma = physics.flux(u_h)  # σ(u_h), or P(u_h) of a hyperelastic body
    frictional = result.friction is not None
    T = ufl.dot(sigma, n)  # traction σ(u_h) n
    terms = {
        "volume": h_T**2 * ufl.inner(f + ufl.div(sigma), f + ufl.div(sigma)) * w * dx,
        "jump": 0.5
        * h_S
        * ufl.inner(ufl.jump(sigma, n), ufl.jump(sigma, n))
        * (w("+") + w("-"))
        * dS,
        "neumann": zero,
        "consistency": zero,
        "tangential": zero,
        "sign": zero,
        "complementarity": zero,
    }
    for i, t in boundary.neumann.items():
        terms["neumann"] += h_E * ufl.inner(t - T, t - T) * w * ds(i)
    for i in (*boundary.free, *([] if natural is None else [natural])):
        terms["neumann"] += h_E * ufl.inner(T, T) * w * ds(i)
    surface_fields = None
    if frictional:  # the solver's nodal λ_t,i and slip increments as P1 vectors
        from ..solvers.friction import surface_functions

        surface_fields = surface_functions(result)[:2]
    current = problem.current is not None  # contact on the current configuration
    X = ufl.SpatialCoordinate(msh)
    for obstacle in rigid:  # the rigid obstacle's contact parts
        # small strain: n_c and the gap g_c of the reference point, the gap u·n_c − g_c;
        # on the current configuration both at the deformed point x = X + u_h, the gap −g
        n_c, g_c = obstacle.surface.expression(X + u_h if current else X)
        gap = -g_c if current else ufl.dot(u_h, n_c) - g_c
        Tn = ufl.dot(T, n_c)
        Tt = T - Tn * n_c
        friction = None
        if frictional and obstacle.friction is not None:
            assert surface_fields is not None
            rho = friction_bound(obstacle.friction, problem, lam)
            friction = FrictionFields(surface_fields[0], surface_fields[1], rho)
            # λ_t − σ_t(u_h) instead of σ_t(u_h), and the friction terms; the slip of the
            # load step: small strain s_t = (I − n nᵀ)(u_h − u_prev), on the current
            # configuration the solver's nodal slip (along the current tangents, relative
            # to the obstacle's own motion)
            du = u_h - problem.u_prev if problem.u_prev is not None else u_h
            lam_t = friction.lam_t
            slip_t = friction.slip if current else du - ufl.dot(du, n_c) * n_c
            Tt = Tt - lam_t
            terms.update(friction_bound=zero, slip=zero)
        for i in obstacle.ids:
            terms["consistency"] += h_E * (lam - Tn) ** 2 * w * ds(i)
            terms["tangential"] += h_E * ufl.inner(Tt, Tt) * w * ds(i)
            terms["sign"] += ufl.max_value(lam, 0) ** 2 * w * ds(i)
            terms["complementarity"] += abs(ufl.min_value(lam, 0) * gap) * w * ds(i)
            if friction is not None:
                norm_t = ufl.sqrt(ufl.inner(lam_t, lam_t))
                terms["friction_bound"] += ufl.max_value(norm_t - rho, 0) ** 2 * w * ds(i)
                terms["slip"] += (
                    abs(rho * ufl.sqrt(ufl.inner(slip_t, slip_t)) + ufl.inner(lam_t, slip_t))
                    * w
                    * ds(i)
                )
    if pairs:  # several bodies: the interface terms on both sides of each pair
        friction = None
        law = pairs[0].friction
        if frictional and law is not None:
            assert surface_fields is not None
            rho = friction_bound(law, problem, lam)
            friction = FrictionFields(surface_fields[0], surface_fields[1], rho)
        for key, form in interface_terms(
            problem, result, pairs, w, n, h_E, T, friction, ds
        ).items():
            terms[key] = terms.get(key, zero) + form
    return terms


@dataclass(frozen=True)
class FrictionFields:
    """Return the UFL data of the friction terms on the contact surfaces.

    UFL data of the friction terms (docs/theory.md §1.4, Hild–Lleras) on the contact
    surfaces: the tangential multiplier λ_t and the solver's slip increment s_t (P1 vectors
    of the nodal λ_t,i and s_t,i, :func:`contact.solvers.friction.surface_functions`; the
    pairs' terms take this s_t, a rigid obstacle's the slip (I − n nᵀ)(u_h − u_prev) of the
    load step) and the bound ρ (Tresca: the threshold expression s(x, t); Coulomb:
    F·(−λ_n,h)⁺, :func:`friction_bound`).
    """

    lam_t: fem.Function
    slip: fem.Function
    rho: ufl.core.expr.Expr


def interface_terms(
    problem: Problem,
    result: Result,
    pairs: list[MortarPair],
    w,
    n,
    h_E,
    T,
    friction: FrictionFields | None,
    ds: ufl.Measure | None = None,
) -> dict[str, ufl.Form]:
    """Return the estimator terms on the pairs' surfaces, both sides measured.

    Estimator terms on the pairs' surfaces (docs/theory.md §5 with both sides measured): on
    the slave surface h_E ‖λ_h − T·n‖² (consistency), h_E ‖T_t‖² (tangential, frictionless;
    with friction h_E ‖T_t − λ_t‖² and the terms ‖(|λ_t| − ρ)⁺‖², ∫ |ρ|s_t| + λ_t·s_t| of
    docs/theory.md §1.4, s_t the nodal relative slip increment), ‖λ_h⁺‖² (sign) and
    |min(λ_h, 0) g_h| (complementarity, g_h the nodal gap); on the master surface h_E ‖λ^m −
    T·n‖² (consistency_master) and h_E ‖T_t‖² (with friction h_E ‖T_t + λ_t^m‖², λ_t carried
    over like the pressure).  T = σ(u_h) n, n the outward normal of the facet's own body,
    T_t = T − (T·n) n; ``friction`` the friction data of a frictional solve, else None;
    ``ds`` the measure of the other terms (default: over the boundary parts' tags).

    Hyperelastic bodies (their pairs coupled on the current configuration): T = P(u_h) N is
    the nominal traction on the reference facet (normal N), n the facet's current normal
    n = cof F N / |cof F N| and the pressures λ_h, λ^m, λ_t (per current area) enter per
    reference area, times the stretch da/dA = |cof F N| (Nanson: n da = cof F N dA), so
    that T = (da/dA) λ n at equilibrium: consistency h_E ((da/dA) λ_h − T·n)², tangential
    h_E ‖T_t − (da/dA) λ_t‖²; the gap g_h is the current one of the last coupling.
    """
    from ..models.mortar import master_pressure, master_vector

    physics = _physics(problem, Elasticity)
    msh = problem.V.mesh
    ds = physics.boundary.measure(msh) if ds is None else ds
    lam = result.lmbda_h
    gap = result.gap.copy()  # the nodal gap, NaN off the constrained nodes → 0
    gap.x.array[np.isnan(gap.x.array)] = 0.0
    lam_m = master_pressure(result)
    stretch = 1.0  # da/dA: the pressures are per current area at finite strain
    if physics.law is not None:  # pairs coupled on the current configuration
        u_h = result.u_h
        F = ufl.Identity(len(u_h)) + ufl.grad(u_h)
        nanson = ufl.det(F) * ufl.dot(ufl.inv(F).T, n)  # n da/dA (Nanson)
        stretch = ufl.sqrt(ufl.inner(nanson, nanson))
        n = nanson / stretch  # the facet's current normal
    Tn = ufl.dot(T, n)
    Tt = T - Tn * n
    zero = fem.Constant(msh, 0.0) * w * ufl.dx(domain=msh)
    terms = {"consistency_master": zero}
    slave_ids = [i for pair in pairs for i in pair.ids]
    master_ids = [i for pair in pairs for i in pair.master_ids]
    extra = {"consistency": zero, "tangential": zero, "sign": zero, "complementarity": zero}
    Tt_s, Tt_m = Tt, Tt
    # the tangential traction is λ_t on the slave side, −λ_t^m on the master side
    if friction is not None:
        lam_t, slip, rho = friction.lam_t, friction.slip, friction.rho
        Tt_s = Tt - stretch * lam_t
        Tt_m = Tt + stretch * master_vector(result, lam_t)
        extra.update(friction_bound=zero, slip=zero)
    for i in slave_ids:
        extra["consistency"] += h_E * (stretch * lam - Tn) ** 2 * w * ds(i)
        extra["tangential"] += h_E * ufl.inner(Tt_s, Tt_s) * w * ds(i)
        extra["sign"] += ufl.max_value(lam, 0) ** 2 * w * ds(i)
        extra["complementarity"] += abs(ufl.min_value(lam, 0) * gap) * w * ds(i)
        if friction is not None:  # Hild–Lleras: the bound and the slip's direction
            extra["friction_bound"] += (
                ufl.max_value(ufl.sqrt(ufl.inner(lam_t, lam_t)) - rho, 0) ** 2 * w * ds(i)
            )
            extra["slip"] += (
                abs(rho * ufl.sqrt(ufl.inner(slip, slip)) + ufl.inner(lam_t, slip)) * w * ds(i)
            )
    for i in master_ids:
        terms["consistency_master"] += h_E * (stretch * lam_m - Tn) ** 2 * w * ds(i)
        extra["tangential"] += h_E * ufl.inner(Tt_m, Tt_m) * w * ds(i)
    return {**extra, **terms}


def friction_bound(law: Friction, problem: Problem, lam: fem.Function):
    """Return ρ of a friction law as UFL.

    ρ of a friction law (UFL): Coulomb F·(−λ_h)⁺, Tresca its threshold s(x, t) as
    written.
    """
    if law.law == "coulomb":
        return law.coefficient * ufl.max_value(-lam, 0)  # type: ignore[union-attr]
    return law.threshold  # type: ignore[union-attr]


def check_shared_facets(msh: Any, name: str) -> None:
    """Refuse a distributed mesh without ghost cells across the ranks' facets.

    The residual estimator's jump terms integrate over every interior facet from the cells
    on both sides, so on a facet between two ranks' cells the owning rank must hold the
    other cell as a ghost: a mesh created with ``ghost_mode=GhostMode.shared_facet``
    (``dolfinx.mesh.create_*`` and ``XDMFFile.read_mesh`` by default; ``create_mesh`` and
    gmsh's ``model_to_mesh`` need that partitioner).  Collective: the owned facets between
    ranks with a single local cell are counted over the ranks, so every rank raises alike.

    Args:
        msh: the mesh the estimator will integrate over.
        name: the argument that brought it, for the message.
    """
    comm = msh.comm
    if comm.size == 1:
        return
    topology, tdim = msh.topology, msh.topology.dim
    topology.create_entities(tdim - 1)
    topology.create_connectivity(tdim - 1, tdim)
    cells = np.diff(topology.connectivity(tdim - 1, tdim).offsets)
    facets = topology.interprocess_facets()
    owned = facets[facets < topology.index_map(tdim - 1).size_local]  # each facet once
    lonely = comm.allreduce(int(np.count_nonzero(cells[owned] == 1)), op=MPI.SUM)
    if lonely:
        raise ValueError(
            f"{name}: mesh {msh.name!r} has {lonely} facet(s) between ranks without the "
            "cell across (ghost mode none), which the residual estimator's jump terms "
            "need: create it with ghost_mode=GhostMode.shared_facet (or partitioner="
            "create_cell_partitioner(GhostMode.shared_facet, 2) for create_mesh, gmsh)"
        )


def estimate(problem: Any, result: Result, kind: str = "residual") -> Estimate:
    """Estimate the error of a solve of ``problem`` (the ESTIMATE step).

    η_T and η of a solve of ``problem`` (collective): the residual estimator
    (docs/theory.md §5) or a guaranteed bound from an equilibrated flux (§9).

    Args:
        problem: the solved problem (a :class:`~contact.models.forms.ComplementarityProblem`
            or the problem of a result), with its physics declared.
        result: its :class:`~contact.solvers.result.Result`.
        kind: ``residual``, ``equilibrated`` (σ_h ∈ RT_p) or ``equilibrated_rt0`` (the
            lowest-order flux of a P1 solution; scalar equations only).

    Returns:
        The :class:`Estimate`: η_T (DG0), η and each term's total.  A result of another
        problem, a kind that is not one of :data:`KINDS`, or for the residual estimator a
        distributed mesh created without ghost cells across the ranks' facets
        (:func:`check_shared_facets`), is a ValueError.
    """
    problem = getattr(problem, "problem", None) or problem
    if (
        not isinstance(result, Result)
        or not isinstance(problem, Problem)
        or result.u_h.function_space.mesh is not problem.V.mesh
    ):
        raise ValueError(
            "result: expected the contact.Result of a solve of this problem (same mesh)"
        )
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    if kind == "residual":
        return residual_estimate(problem, result)
    # docs/theory.md §9: a guaranteed bound
    if isinstance(problem.physics, Elasticity):
        from .equilibration.elastic import elastic_bound

        bound = elastic_bound(problem, result)
    else:
        from .equilibration.bound import guaranteed_bound
        from .equilibration.flux import LOWEST

        lowest = kind == "equilibrated_rt0"  # σ_h ∈ RT_0 (P1)
        bound = guaranteed_bound(problem, result, degree=LOWEST if lowest else None)
    return Estimate(bound.eta_T, bound.eta, bound.terms)


def residual_estimate(
    problem: Problem, result: Result, degree: fem.Function | None = None
) -> Estimate:
    """Return the residual estimator of a solve of ``problem``.

    The residual estimator (docs/theory.md §5) of a solve of ``problem`` (collective): the
    terms of η_T² assembled together as DG0 vectors (:func:`.cellwise.assemble_terms`), η_T²
    their sum, each term's total the sum
    of its owned entries; ``degree``: the cells' degrees of an hp solution (DG0: the
    weights h/p of :func:`scalar_terms`).  A distributed mesh without ghost cells across
    the ranks' facets is a ValueError on every rank (:func:`check_shared_facets`).
    """
    check_shared_facets(problem.V.mesh, "problem")
    terms = indicator_terms(problem, result, degree)
    vecs = assemble_terms(terms)
    eta_sq = sum(vecs.values())
    W = next(iter(terms.values())).arguments()[0].ufl_function_space()  # the DG0 space of w
    eta_T = fem.Function(W, name="eta_T")
    eta_T.x.array[:] = np.sqrt(np.maximum(eta_sq, 0.0))
    comm = problem.V.mesh.comm
    n_owned = W.dofmap.index_map.size_local
    totals = {
        name: comm.allreduce(float(np.sum(v[:n_owned])), op=MPI.SUM) for name, v in vecs.items()
    }
    eta = float(np.sqrt(sum(totals.values())))
    return Estimate(eta_T, eta, totals)
