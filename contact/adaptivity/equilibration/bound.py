"""A guaranteed upper bound of the energy error for the scalar Signorini and obstacle
problems (docs/theory.md §1.1–1.2, §9), from an equilibrated flux (:func:`.flux.reconstruct_flux`).

Notation: |||v|||² = ∫_Ω k |∇v|², e = u − u_h; σ = +1 for the constraint u ≤ g (Signorini, and
the upper obstacle ψ = g), σ = −1 for u ≥ ψ, so σ(u − g) ≤ 0 and σλ ≤ 0 for the exact
multiplier λ (k∂u/∂n − t_C on Γ_C; −div(k∇u) − f in Ω).  σ_h ∈ RT_p is the reconstructed flux,

    −div σ_h = Π_p f (+ λ̃_h for the obstacle),   σ_h·n = Π_p t on Γ_N,
    σ_h·n = Π_p t_C + λ̃_h on Γ_C,

with λ̃_h the discrete multiplier of :mod:`.multiplier` (σλ̃_h ≤ 0 pointwise).  Per cell T

    A_T = ‖k^{-1/2}(σ_h − k∇u_h)‖_T + osc_T,     A = (Σ_T A_T²)^{1/2}     (osc_T:
    :class:`.flux.Flux`),

w ∈ H¹(Ω) with w = 0 on Γ_D and w ≥ σ(u_h − g) on Γ_C (Signorini) or in Ω (obstacle),
W = |||w|||, s_h = u_h − σw (feasible: σ(s_h − g) ≤ 0 where the constraint acts), A_s as A with
s_h for u_h, and

    B = ∫ (−σλ̃_h)(w − σ(u_h − g)) ≥ 0     (over Γ_C, or Ω).

**Theorem.**  Assume u_h = u_D on Γ_D and, for Signorini, g ∈ P_p on each contact facet (the
discrete problem sees g through its interpolant g_h; the obstacle uses ψ itself).  Then,
with R(S, P) = ½(S + (S² + 4P)^{1/2}), each of

    (i)   η_1 = R(A + W, A W + B),
    (ii)  η_2 = R(A_s, B) + W,
    (iii) η_3 = (R(A_s, B)² + 2X + W²)^{1/2}   (obstacle; X below),

bounds |||u − u_h||| with no unknown constant, and η = min(η_1, η_2, η_3).

Proof (Braess, Numer. Math. 101, 2005; Weiss & Wohlmuth, Math. Comp. 78, 2009; Ern &
Vohralík, SINUM 53, 2015).  For any v ∈ H¹ with v = u_D on Γ_D, integrating by parts against
σ_h,

    (k∇(u − v), ∇(u − v)) = (f − Π_p f, u − v) + ⟨t − Π_p t, u − v⟩ + (σ_h − k∇v, ∇(u − v))
                            + ⟨λ − λ̃_h, u − v⟩,

⟨·,·⟩ on Γ_N ∪ Γ_C resp. Γ_C or Ω.  The first three terms are ≤ Σ_T A_T(v) |||u − v|||_T
(the oscillations are orthogonal to constants: Poincaré h_T/π on convex cells and the trace
inequality of :func:`.flux.oscillation`).  With λ(u − g) = 0, σλ ≤ 0, σλ̃_h ≤ 0, σ(u − g) ≤ 0:

    ⟨λ − λ̃_h, u − v⟩ = −⟨λ, v − g⟩ − ⟨λ̃_h, u − g⟩ + ⟨λ̃_h, v − g⟩ ≤ −⟨λ, v − g⟩ + ⟨−σλ̃_h, −σ(v −
    g)⟩.

(ii): v = s_h is feasible, so −⟨λ, s_h − g⟩ ≤ 0 and ⟨−σλ̃_h, −σ(s_h − g)⟩ = B: |||u − s_h|||² ≤
A_s |||u − s_h||| + B, then the triangle inequality with |||s_h − u_h||| = W.  (i): v = u_h,
−⟨λ, u_h − g⟩ ≤ ⟨−σλ, w⟩, and the weak equation tested with w gives ⟨−σλ, w⟩ ≤
(|||e||| + A) W + ⟨−σλ̃_h, w⟩, so |||e|||² ≤ (A + W)|||e||| + A W + B.  (iii) (obstacle):
|||e|||² = |||u − s_h|||² + 2(k∇(u − s_h), ∇(s_h − u_h)) + W², and with s_h − u_h = −σw,
(k∇(u − s_h), −σ∇w) = −σ(f, w) + (−σλ, w) + σ(k∇s_h, ∇w) ≤ X := −σ(f, w) + ((−σL)⁺, w) +
σ(k∇s_h, ∇w), L = −div(k∇ψ) − f, by the Lewy–Stampacchia inequality 0 ≤ −σλ ≤ (−σL)⁺
(Kinderlehrer & Stampacchia, ch. IV; it needs div(k∇ψ) ∈ L², true for the shipped obstacles).
∎

Realization.  Signorini: w is the smallest nodal w ∈ V_h above σ(u_h − g_h) on Γ_C
(:func:`bernstein_lifting`: P1 nodal values; P2 also the midpoint value that makes the
Bernstein coefficients non-negative), zero for a feasible P1 u_h.  Obstacle: w = (σ(u_h − ψ))⁺
with the exact ψ (by quadrature of degree 2p + 6 across its kinks), s_h = max or min of u_h
and ψ; σ_h is fitted to k∇s_h (:class:`.flux.FluxData` ``target``), which makes A_s small on
the contact set where u = ψ = s_h.  The Dirichlet datum: u_h = I_p u_D on Γ_D only; D =
|||e_D|||, e_D ∈ P_{p+1} equal to I_{p+1}u_D − u_h at the DoFs on Γ_D (zero elsewhere and on
Γ_C), enters as in (i)–(ii): R(A + W + D, A(W + D) + B), R(A_s + D, A_s D + B) (exact for
u_D ∈ P_{p+1}(Γ_D); otherwise D stands in for the Dirichlet error, of higher order).  The data
f, t, t_C enter through quadrature of degree 2p + 4 (exact for polynomial data of degree
≤ p + 2), and the algebraic residual of the solve through the patches' projected balance
defect (:attr:`.flux.Flux.defect`, reported): the bound is guaranteed up to these.

The indicators η_T² = A_T² + W_T² + D_T² + B_T (A_{s,T} when (ii) or (iii) is the smaller
bound) are DG0 forms, so marking is unchanged; η is the bound, not (Σ η_T²)^{1/2}.  The
terms reported are Σ_T ‖k^{-1/2}(σ_h − k∇u_h)‖²_T ("flux"), Σ osc_T² ("oscillation"), B
("complementarity"), W² ("feasibility") and D² ("dirichlet").
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ...models.constraints import Unilateral
from ...models.discrete import Problem
from ...models.physics import Diffusion
from ...solvers import Result
from ..cellwise import assemble_terms
from .flux import Flux, FluxData, reconstruct_flux

if TYPE_CHECKING:
    from .stress import Stress

TERMS = ("flux", "oscillation", "complementarity", "feasibility", "dirichlet")
#: D_T² of the Dirichlet lifting e_D integrated over the cells with a DoF of e_D only (zero
#: elsewhere); False: over every cell, the plain path (the same numbers)
DIRICHLET_CELLS = True
#: with :data:`DIRICHLET_CELLS` and a P1 solution, u_D evaluated at the DoFs of those cells
#: only (the P2 space of their submesh: the same points, one DoF per edge), not at every DoF
#: of the mesh's P2 space; False: at every DoF, the plain path (the same values)
DIRICHLET_SUBMESH = True
#: serially, with :data:`DIRICHLET_SUBMESH` and a constant k, the whole Dirichlet term (e_D,
#: I_2 u_h and D_T²) on the submesh of the cells with a vertex on Γ_D: no P2 space of the
#: whole mesh; False: e_D in the P2 space of the mesh (the same D_T² bit for bit)
DIRICHLET_ON_SUBMESH = True


@dataclass
class Bound:
    """η (the guaranteed bound), η_T (DG0), the totals of the terms, the parts A, B, W, D of
    the theorem, the flux and timings (seconds)."""

    eta: float
    eta_T: fem.Function
    terms: dict
    parts: dict
    flux: Flux | Stress  # the scalar flux, or the elastic stress (:mod:`.elastic`)
    seconds: dict = field(default_factory=dict)


def flux_data(problem: Problem, result: Result) -> tuple[FluxData, str, float]:
    """The inputs of :func:`reconstruct_flux` for a solve of a scalar problem: (data,
    multiplier, sign)."""
    physics, condition = _scalar(problem)
    boundary, loads = physics.boundary, physics.boundary.neumann
    contact = {i: loads.get(i, 0) for i in condition.ids}
    flux = FluxData(
        result.u_h,
        physics.f,
        physics.k,
        boundary.tags,
        dirichlet=boundary.dirichlet,
        neumann={i: t for i, t in loads.items() if i not in contact},
        contact=contact,
        lmbda_h=result.lmbda_h,
    )
    return flux, ("cells" if condition.in_domain else "facets"), -problem.constraint.sign


def _scalar(problem: Problem) -> tuple[Diffusion, Unilateral]:
    """The scalar equations and the one unilateral condition of ``problem`` (else a
    ValueError: the equilibrated flux of :mod:`.flux` is that of −div(k ∇u) = f)."""
    physics = problem.physics
    contacts = problem.contacts
    if (
        not isinstance(physics, Diffusion)
        or len(contacts) != 1
        or not isinstance(contacts[0], Unilateral)
    ):
        raise ValueError(
            "estimator: equilibrated works for the scalar equations (Diffusion) with one "
            f"Unilateral condition, not {type(physics).__name__} with "
            f"{', '.join(type(c).__name__ for c in contacts) or 'no condition'}"
        )
    return physics, contacts[0]


def guaranteed_bound(
    problem: Problem,
    result: Result,
    backend: str = "compiled",
    degree: int | None = None,
    lifting: fem.Function | None = None,
    multiplier_rule: Any = None,
) -> Bound:
    """The bound of the module docstring for a solve of a scalar problem (collective);
    ``backend`` and ``degree``: the patch solver and the flux's degree of
    :func:`.flux.reconstruct_flux`; ``lifting``: w of a Signorini scene, if the caller
    has it (hp: Bernstein coefficients on facets of any degree), else
    :func:`bernstein_lifting`; ``multiplier_rule``: :class:`.cells.FluxData`'s."""
    seconds = {}
    t0 = time.perf_counter()
    data, multiplier, sign = flux_data(problem, result)
    data.multiplier_rule = multiplier_rule
    sigma = -sign  # the constraint sign: σ(u − g) ≤ 0
    msh = problem.V.mesh
    u_h, k = result.u_h, data.k
    DG0 = fem.functionspace(msh, ("DG", 0))
    v = ufl.TestFunction(DG0)
    lift = _feasibility(problem, result, sigma, k, v, lifting)
    grad_w = lift.grad
    data.target = k * (ufl.grad(u_h) - sigma * grad_w)  # k∇s_h: fit σ_h to the feasible s_h
    flux = reconstruct_flux(data, multiplier, sign, backend=backend, degree=degree)
    seconds["flux"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    p = _degree(u_h)
    # |σ_h − k∇u_h|² is a polynomial of degree 2m (m: the basix degree of σ_h's RT space) for
    # a constant k: degree 2m + 2 leaves two for a polynomial k; the obstacle's kinks
    # (w = (σ(u_h − ψ))⁺) take 2p + 6
    m = flux.sigma_h.function_space.element.basix_element.degree
    quad = 2 * p + 6 if multiplier == "cells" else 2 * m + 2
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": quad})
    B_form = lift.complementarity(flux.lmbda)
    q = flux.sigma_h - k * ufl.grad(u_h)
    q_s = q + sigma * k * grad_w  # σ_h − k∇s_h, s_h = u_h − σ w feasible
    forms = {
        "F": ufl.inner(q, q) / k * v * dx,
        "Fs": ufl.inner(q_s, q_s) / k * v * dx,
        "W2": k * ufl.inner(grad_w, grad_w) * v * dx,
        "B": B_form,
        **({} if lift.cross is None else {"X": lift.cross}),
    }
    n_owned = msh.topology.index_map(msh.topology.dim).size_local
    local = {name: val[:n_owned] for name, val in assemble_terms(forms).items()}
    local["D2"] = _dirichlet(problem, result, v, k)
    cross_T = local.pop("X", None)
    local = {name: np.maximum(val, 0.0) for name, val in local.items()}
    cross = np.inf if cross_T is None else msh.comm.allreduce(float(np.sum(cross_T)), op=MPI.SUM)
    A_T, As_T = np.sqrt(local["F"]) + flux.osc, np.sqrt(local["Fs"]) + flux.osc
    comm = msh.comm
    total = {
        name: comm.allreduce(float(np.sum(val)), op=MPI.SUM)
        for name, val in (
            ("A2", A_T**2),
            ("As2", As_T**2),
            ("flux", local["F"]),
            ("oscillation", flux.osc**2),
            ("complementarity", local["B"]),
            ("feasibility", local["W2"]),
            ("dirichlet", local["D2"]),
        )
    }
    A, As, B = np.sqrt(total["A2"]), np.sqrt(total["As2"]), total["complementarity"]
    W, D = np.sqrt(total["feasibility"]), np.sqrt(total["dirichlet"])
    direct = root_bound(A + W + D, A * (W + D) + B)
    s_bound = root_bound(As + D, As * D + B)  # |||u − s_h|||
    feasible = s_bound + W
    split = np.sqrt(max(s_bound**2 + 2 * cross + W**2, 0.0))
    eta = min(direct, feasible, split)
    A_T = A_T if direct <= min(feasible, split) else As_T
    eta_T = indicators(DG0, A_T**2, local["W2"], local["D2"], local["B"])
    seconds["terms"] = time.perf_counter() - t0
    terms = {name: total[name] for name in TERMS}
    parts = {
        "A": A,
        "A_s": As,
        "B": B,
        "W": W,
        "D": D,
        "X": cross,
        "direct": direct,
        "feasible": feasible,
        "split": split,
        "defect": flux.defect,
    }
    return Bound(float(eta), eta_T, terms, parts, flux, {**flux.seconds, **seconds})


def indicators(DG0: fem.FunctionSpace, *squares: np.ndarray) -> fem.Function:
    """η_T = (Σ of the owned cells' ``squares``)^{1/2} as a DG0 function (ghosts updated)."""
    eta_T = fem.Function(DG0, name="eta_T")
    eta_T.x.array[: len(squares[0])] = np.sqrt(sum(squares))
    eta_T.x.scatter_forward()
    return eta_T


def root_bound(S: float, P: float) -> float:
    """The positive root bound of x² ≤ S x + P: x ≤ ½ (S + (S² + 4P)^{1/2})."""
    return 0.5 * (S + np.sqrt(S**2 + 4 * P))


def _degree(u_h: fem.Function) -> int:
    return u_h.function_space.element.basix_element.degree


def cellwise(form) -> np.ndarray:
    """The owned entries of a DG0 form's vector (interior-facet terms summed over ranks)."""
    vec = fem.assemble_vector(fem.form(form))
    vec.scatter_reverse(la.InsertMode.add)
    return vec.array[: vec.index_map.size_local].copy()


@dataclass
class _Lifting:
    """w of the module docstring: its gradient, λ̃ ↦ the DG0 form of B_T, and (obstacle) the
    DG0 form of the cross term X, or None."""

    grad: Any  # UFL
    complementarity: Callable[[Any], Any]
    cross: Any = None


def _obstacle(bound: Any, problem: Problem) -> Any:
    """ψ as UFL: as written when it is a UFL expression or a Function (not its interpolant),
    a number as a constant; values at the DoFs or a callable only through their
    interpolant, the problem's bound function."""
    if isinstance(bound, ufl.core.expr.Expr):
        return bound
    if np.ndim(bound) == 0 and not callable(bound):
        return fem.Constant(problem.V.mesh, float(bound))
    return problem.bound_function()


def _feasibility(
    problem: Problem, result: Result, sigma: float, k, w_test, lifting: fem.Function | None = None
) -> _Lifting:
    u_h = result.u_h
    physics, condition = _scalar(problem)
    msh = problem.V.mesh
    boundary = physics.boundary
    if condition.in_domain:
        psi = _obstacle(condition.bound, problem)
        f = physics.f
        s = sigma * (u_h - psi)
        # kinks
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 2 * _degree(u_h) + 6})
        w = ufl.conditional(ufl.gt(s, 0), s, 0)
        grad_w = ufl.conditional(ufl.gt(s, 0), ufl.grad(s), ufl.zero(msh.geometry.dim))
        L = -ufl.div(k * ufl.grad(psi)) - f  # Lewy–Stampacchia: 0 ≤ −σλ ≤ (−σL)⁺
        grad_s = ufl.grad(u_h) - sigma * grad_w
        cross = (
            (
                -sigma * f * w
                + ufl.max_value(-sigma * L, 0) * w
                + sigma * k * ufl.inner(grad_s, grad_w)
            )
            * w_test
            * dx
        )
        return _Lifting(
            grad_w,
            lambda lmbda: (-sigma * lmbda) * ufl.conditional(ufl.lt(s, 0), -s, 0) * w_test * dx,
            cross,
        )
    g_h = problem.bound_function()
    contact = condition.ids
    w = (
        bernstein_lifting(u_h, g_h, boundary.facets(contact), boundary.facets(boundary.dirichlet))
        if lifting is None
        else lifting
    )
    ds = boundary.measure(msh)
    return _Lifting(
        ufl.grad(w),
        lambda lmbda: sum((-lmbda) * (w - (u_h - g_h)) * w_test * ds(i) for i in contact),
    )


def bernstein_lifting(
    u_h: fem.Function, g_h: fem.Function, facets: np.ndarray, dirichlet: np.ndarray
) -> fem.Function:
    """The smallest nodal w ∈ V with u_h − g_h ≤ w on the contact ``facets`` and w = 0 on the
    ``dirichlet`` facets: vertex values max(u_h − g_h, 0); for P2 the midpoint value m of a
    contact facet with vertex values w_0, w_1 is max(0, d_m + (w_0 − d_0 + w_1 − d_1)/4)
    (d = u_h − g_h), which makes the Bernstein coefficients of w − d on the facet
    non-negative."""
    V = u_h.function_space
    msh = V.mesh
    tdim = msh.topology.dim
    w = fem.Function(V, name="w")
    dvals = u_h.x.array - g_h.x.array
    msh.topology.create_connectivity(tdim - 1, tdim)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    c2f = msh.topology.connectivity(tdim, tdim - 1).array.reshape(-1, tdim + 1)
    cells = (
        np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
        if len(facets)
        else np.zeros(0, np.int32)
    )
    local = np.argmax(c2f[cells] == facets[:, None], axis=1) if len(facets) else np.zeros(0, int)
    layout = V.dofmap.dof_layout
    closure = np.array([layout.entity_closure_dofs(tdim - 1, j) for j in range(tdim + 1)])
    fdofs = (
        V.dofmap.list[cells[:, None], closure[local]]
        if len(facets)
        else np.zeros((0, closure.shape[1]), int)
    )
    nv = tdim  # vertex DoFs of a facet come first
    vdofs = np.unique(fdofs[:, :nv])
    w.x.array[vdofs] = np.maximum(dvals[vdofs], 0.0)
    if fdofs.shape[1] > nv:  # P2 on segments: one midpoint per facet
        d0, d1, dm = dvals[fdofs[:, 0]], dvals[fdofs[:, 1]], dvals[fdofs[:, 2]]
        w0, w1 = w.x.array[fdofs[:, 0]], w.x.array[fdofs[:, 1]]
        w.x.array[fdofs[:, 2]] = np.maximum(0.0, dm + (w0 - d0 + w1 - d1) / 4)
    w.x.array[fem.locate_dofs_topological(V, tdim - 1, dirichlet)] = 0.0
    return w


def _dirichlet(problem: Problem, result: Result, w_test, k) -> np.ndarray:
    """D_T² = ∫_T k |∇e_D|² of the module docstring (zero without a Dirichlet part)."""
    physics, condition = _scalar(problem)
    u_h = result.u_h
    msh = problem.V.mesh
    tdim = msh.topology.dim
    boundary = physics.boundary
    constant = isinstance(k, fem.Constant | int | float)
    serial = msh.comm.size == 1 and _degree(u_h) == 1 and constant
    if DIRICHLET_CELLS and DIRICHLET_SUBMESH and DIRICHLET_ON_SUBMESH and serial:
        return _dirichlet_on_submesh(physics, condition, u_h, k)
    V2 = fem.functionspace(msh, ("Lagrange", _degree(u_h) + 1))
    dofs = np.setdiff1d(
        fem.locate_dofs_topological(V2, tdim - 1, boundary.facets(boundary.dirichlet)),
        fem.locate_dofs_topological(V2, tdim - 1, boundary.facets(condition.ids)),
    )
    e_D = fem.Function(V2)
    u2 = fem.Function(V2)
    dx = ufl.Measure("dx", domain=msh)
    if DIRICHLET_CELLS:  # the cells with a DoF of e_D: the only ones where D_T ≠ 0
        on = np.zeros(V2.dofmap.index_map.size_local + V2.dofmap.index_map.num_ghosts, bool)
        on[dofs] = True
        cells = np.flatnonzero(on[V2.dofmap.list].any(axis=1)).astype(np.int32)
        u2.interpolate(u_h, cells0=cells, cells1=cells)
        owned = cells[cells < msh.topology.index_map(tdim).size_local]  # each cell once
        dx = ufl.Measure("dx", domain=msh, subdomain_data=[(1, owned)], subdomain_id=1)
    else:
        u2.interpolate(u_h)
    if physics.dirichlet_value is not None:
        if DIRICHLET_CELLS and DIRICHLET_SUBMESH and _degree(u_h) == 1:
            u_D = _on_cells(physics.dirichlet_value, V2, cells)
        else:
            u_D = physics.dirichlet_value(V2).x.array
        e_D.x.array[dofs] = u_D[dofs] - u2.x.array[dofs]
    e_D.x.scatter_forward()
    return cellwise(k * ufl.inner(ufl.grad(e_D), ufl.grad(e_D)) * w_test * dx)


def _on_cells(value: Callable, V2: fem.FunctionSpace, cells: np.ndarray) -> np.ndarray:
    """The values of ``value`` (u_D interpolated into a given P2 space, the physics'
    ``dirichlet_value``) at the DoFs of V2 in ``cells`` (0 elsewhere), computed on the P2 space
    of the submesh of these cells (collective).  A submesh cell has its parent's vertices in
    the same order, so its local DoF j lies at its parent's DoF j: the same points (P2 has
    one DoF per edge, which no edge orientation moves)."""
    msh = V2.mesh
    tdim = msh.topology.dim
    sub, cell_map, _, _ = dmesh.create_submesh(msh, tdim, cells)
    W = fem.functionspace(sub, ("Lagrange", 2))
    cmap = sub.topology.index_map(tdim)
    local = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
    parent = cell_map.sub_topology_to_topology(local, inverse=False)
    out = np.zeros(
        (V2.dofmap.index_map.size_local + V2.dofmap.index_map.num_ghosts) * V2.dofmap.index_map_bs
    )
    out[V2.dofmap.list[parent]] = value(W).x.array[W.dofmap.list[local]]
    return out


def _dirichlet_on_submesh(physics: Diffusion, condition: Unilateral, u_h, k) -> np.ndarray:
    """D_T² of :func:`_dirichlet` for a P1 u_h and a constant k on one rank, computed on the
    submesh of the cells with a vertex on a Dirichlet facet (every cell with a DoF of e_D, and
    every contact facet through such a vertex; D_T² = 0 on the others, and on the submesh's
    cells without a DoF of e_D, where e_D = 0).  A submesh cell has its parent's vertices in
    the same order: the same local facets, P2 DoFs at the same points, I_2 u_h there from the
    same P1 coefficients (the interpolation weights are 0, ½ and 1: the same sums in any order)
    and so the same kernel of the same values: D_T² bit for bit."""
    msh = u_h.function_space.mesh
    tdim = msh.topology.dim
    boundary = physics.boundary
    n = msh.topology.index_map(tdim).size_local
    out = np.zeros(n)
    dirichlet = boundary.facets(boundary.dirichlet)
    msh.topology.create_connectivity(tdim - 1, 0)
    msh.topology.create_connectivity(0, tdim)
    msh.topology.create_connectivity(tdim - 1, tdim)
    f2v = msh.topology.connectivity(tdim - 1, 0).array.reshape(-1, tdim)  # simplices
    vertices = np.unique(f2v[dirichlet])
    cells = np.unique(_links(msh.topology.connectivity(0, tdim), vertices)).astype(np.int32)
    if not len(cells) or physics.dirichlet_value is None:
        return out  # e_D = 0
    msh.topology.create_connectivity(tdim, tdim - 1)
    sub, cell_map, _, _ = dmesh.create_submesh(msh, tdim, cells)
    ns = sub.topology.index_map(tdim).size_local
    parent = cell_map.sub_topology_to_topology(np.arange(ns, dtype=np.int32), inverse=False)
    # the submesh facets of parent facets: local facet j of a cell is opposite its vertex j
    sub.topology.create_connectivity(tdim, tdim - 1)
    sub.topology.create_connectivity(tdim - 1, tdim)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    c2f = msh.topology.connectivity(tdim, tdim - 1).array.reshape(-1, tdim + 1)
    sub_c2f = sub.topology.connectivity(tdim, tdim - 1).array.reshape(-1, tdim + 1)
    sub_of = np.full(n, -1, dtype=np.int64)
    sub_of[parent] = np.arange(ns)

    def sub_facets(facets: np.ndarray) -> np.ndarray:
        # a facet through a vertex on Γ_D has all its cells in the submesh (the others carry
        # no DoF of e_D): its first cell will do
        c = f2c.array[f2c.offsets[facets]]
        facets, c = facets[sub_of[c] >= 0], c[sub_of[c] >= 0]
        j = np.argmax(c2f[c] == facets[:, None], axis=1)
        return np.unique(sub_c2f[sub_of[c], j]).astype(np.int32)

    W = fem.functionspace(sub, ("Lagrange", 2))
    dofs = np.setdiff1d(
        fem.locate_dofs_topological(W, tdim - 1, sub_facets(dirichlet)),
        fem.locate_dofs_topological(W, tdim - 1, sub_facets(boundary.facets(condition.ids))),
    )
    u1 = fem.Function(fem.functionspace(sub, ("Lagrange", 1)))
    u1.x.array[u1.function_space.dofmap.list] = u_h.x.array[u_h.function_space.dofmap.list[parent]]
    u2 = fem.Function(W)
    u2.interpolate(u1)
    e_D = fem.Function(W)
    e_D.x.array[dofs] = physics.dirichlet_value(W).x.array[dofs] - u2.x.array[dofs]
    ks = fem.Constant(sub, k.value) if isinstance(k, fem.Constant) else float(k)
    w = ufl.TestFunction(fem.functionspace(sub, ("DG", 0)))
    dx = ufl.Measure("dx", domain=sub)
    out[parent] = cellwise(ks * ufl.inner(ufl.grad(e_D), ufl.grad(e_D)) * w * dx)
    return out


def _links(adjacency, nodes: np.ndarray) -> np.ndarray:
    """The links of ``nodes`` in a DOLFINx adjacency list, concatenated."""
    if not len(nodes):
        return np.zeros(0, dtype=adjacency.array.dtype)
    start, end = adjacency.offsets[nodes], adjacency.offsets[nodes + 1]
    counts = end - start
    first = np.repeat(start - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts)
    return adjacency.array[first + np.arange(counts.sum())]
