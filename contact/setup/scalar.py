"""Scalar Signorini and obstacle models (docs/theory.md §1.1–1.2): forms, Dirichlet data and the
nodal constraint set.

Weak form, P1 (or P2) Lagrange u_h with u_h = u_D on Γ_D:

    a(u, v) = ∫_Ω k ∇u·∇v dx,     L(v) = ∫_Ω f v dx + ∫_{Γ_N} t v ds + ∫_{Γ_C} t_C v ds,

assembled once into K and the lifted load b (:func:`contact.models.problem.assemble_system`).
λ_i is the contact flux k ∂u/∂n − t_C (Signorini) or −div(k∇u) − f (obstacle).  Units:
with u in [U], k in [K], lengths in [L], λ is in [K·U/L] on Γ_C and [K·U/L²] in Ω.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import ufl
from dolfinx import fem
from mpi4py import MPI

from ..base import expressions, spaces
from ..base.errors import ConfigError
from ..models.constraints import Unilateral
from ..models.discrete import Problem
from ..models.physics import BoundaryData, Diffusion
from ..models.problem import assemble_system
from ..solvers.problem import ProblemData
from .checks import check_scene_data
from .data import coefficient, interpolate_expression

if TYPE_CHECKING:
    from .scene import Scene

#: the space comes from ``contact.base.spaces`` (made once per mesh: on a refined mesh, the
#: space the previous solution was prolonged to); False: a space of the problem's own, the
#: old path (the same problem)
SHARED_SPACE = True
#: u_D is evaluated at the Dirichlet DoFs only (the condition reads no other; zero
#: elsewhere); False: at every DoF, the old path (the same problem)
DIRICHLET_NODES = True


def scalar_problem(scene: Scene, degree: int | None = None) -> Problem:
    """Assemble the scalar Signorini or obstacle problem of ``scene`` (docs/theory.md
    §1.1–1.2, §2): its forms, its :class:`~contact.models.constraints.Unilateral` condition
    (:meth:`~contact.models.constraints.Unilateral.discretise`) and its
    :class:`~contact.models.physics.Diffusion` equations."""
    t0 = time.perf_counter()
    check_scene_data(scene)  # every datum finite where it is used, k > 0 (ConfigError)
    cfg, msh, bnd = scene.config, scene.mesh, scene.boundary
    degree = degree or cfg.mesh.degree
    data = cfg.data
    element = ("Lagrange", degree)
    V = spaces.functionspace(msh, element) if SHARED_SPACE else fem.functionspace(msh, element)
    tdim = msh.topology.dim
    a, L, forms = scalar_forms(scene, V)
    k, f, t, t_C, ds = (forms[key] for key in ("k", "f", "t", "t_C", "ds"))
    dx = ufl.Measure("dx", domain=msh)
    signorini = cfg.model.type == "signorini"

    # u = u_D on Γ_D (every DoF on the closure of the Dirichlet facets)
    dirichlet_dofs = fem.locate_dofs_topological(V, tdim - 1, bnd.facets("dirichlet"))
    u_D = interpolate_expression(
        V, data.u_D, scene, nodes=dirichlet_dofs if DIRICHLET_NODES else None
    )
    bcs = [fem.dirichletbc(u_D, dirichlet_dofs)]

    K, b = assemble_system(a, L, bcs)

    # the condition u ≤ g on Γ_C, or σ(u − ψ) ≤ 0 in Ω, its lumped weights w_i = ∫ φ_i there
    bound_text = data.g if signorini else data.psi
    g_h = interpolate_expression(V, bound_text, scene)
    condition = Unilateral(
        g_h if signorini else expressions.to_ufl(data.psi, msh, cfg.constants, t=scene.t_constant),
        side="upper" if signorini or cfg.model.bound == "upper" else "lower",
        measure=ds(bnd.ids_with_role("contact")) if signorini else dx,
        nodal=lambda _: g_h,
    )
    contact = condition.discretise(V, bcs, allow_empty=True)
    # no Dirichlet DoF on any rank: only the constraint holds the body (K is singular)
    semicoercive = msh.comm.allreduce(len(dirichlet_dofs), op=MPI.SUM) == 0
    if semicoercive:
        check_semicoercive(b, condition.sign, cfg.model.type)
    physics = scalar_physics(scene, forms)
    return Problem(
        V,
        fem.Function(V, name="u_h"),
        bcs,
        K,
        b,
        contact.constraint,
        output=contact.output,
        semicoercive=semicoercive,
        data=ProblemData(k=k, f=f, t=t, t_C=t_C, ds=ds).updated(contact.data),
        assembly_time=time.perf_counter() - t0,
        physics=physics,
        contacts=(condition,),
    )


def scalar_physics(scene: Scene, forms: dict) -> Diffusion:
    """The scene's :class:`~contact.models.physics.Diffusion` equations over the UFL data
    ``forms`` of :func:`scalar_forms` (what the estimators check)."""
    cfg, msh, bnd = scene.config, scene.mesh, scene.boundary
    data = cfg.data
    k, f, t, t_C = (forms[key] for key in ("k", "f", "t", "t_C"))
    signorini = cfg.model.type == "signorini"
    contact_ids = bnd.ids_with_role("contact")
    return Diffusion(
        k,
        f,
        BoundaryData(
            bnd.tags,
            dirichlet=bnd.ids_with_role("dirichlet"),
            neumann={
                **{i: t for i in bnd.ids_with_role("neumann")},
                **({i: t_C for i in contact_ids} if signorini else {}),
            },
            free=bnd.ids_with_role("natural"),
        ),
        exact=None
        if data.exact is None
        else expressions.to_ufl(str(data.exact), msh, cfg.constants, t=scene.time),
        dirichlet_value=lambda space: interpolate_expression(space, data.u_D, scene),
    )


def scalar_forms(scene: Scene, V: fem.FunctionSpace) -> tuple[fem.Form, fem.Form, dict]:
    """The compiled forms a(u, v) = ∫ k ∇u·∇v dx and L(v) = (f, v)_Ω + ⟨t, v⟩_{Γ_N} +
    ⟨t_C, v⟩_{Γ_C} of the scene on the Lagrange space V, and the UFL data k, f, t, t_C and
    the boundary measure ds (a dict)."""
    data, msh, bnd = scene.config.data, scene.mesh, scene.boundary
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    # a scalar model's data are single expressions (a list is refused at load)
    assert isinstance(data.f, str) and isinstance(data.t, str)
    k, f = coefficient(data.k, scene), coefficient(data.f, scene)
    t, t_C = coefficient(data.t, scene), coefficient(data.t_C, scene)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=bnd.tags)
    dx = ufl.Measure("dx", domain=msh)
    a = k * ufl.inner(ufl.grad(u), ufl.grad(v)) * dx
    L = f * v * dx
    for i in bnd.ids_with_role("neumann"):
        L += t * v * ds(i)
    for i in bnd.ids_with_role("contact"):
        L += t_C * v * ds(i)
    return fem.form(a), fem.form(L), {"k": k, "f": f, "t": t, "t_C": t_C, "ds": ds}


#: |L(1)| below this fraction of Σ_i |b_i| counts as a zero resultant
RESULTANT_RTOL = 1e-10


def check_semicoercive(b, sign: float, model: str) -> None:
    """A scene without a Dirichlet part is held by the constraint alone (semi-coercive):
    K is singular, its kernel the constants, and the energy ½ a(u, u) − L(u) is bounded
    below on {σ u ≤ σ g} exactly when the load's resultant pushes the body onto the
    obstacle, σ L(1) > 0 with L(1) = ∫_Ω f + ∫_{Γ_N} t + ∫_{Γ_C} t_C = Σ_i b_i (the basis
    functions sum to one).  Otherwise u_h − s·1 lowers the energy for every s > 0: no
    solution (σ L(1) < 0) or none unique (L(1) = 0).  One vector sum, so checked at assembly;
    a bad resultant is bad input (ConfigError, exit 2) naming ``data.f``."""
    resultant, scale = b.sum(), b.norm(1)
    if sign * resultant > RESULTANT_RTOL * scale:
        return
    bound = "u ≤ g" if sign > 0 else "u ≥ psi"
    what = (
        "is zero: any constant shift of a solution is another, no unique solution"
        if abs(resultant) <= RESULTANT_RTOL * scale
        else f"= {resultant:.3g} pulls it away from the obstacle ({bound}): no solution exists"
    )
    raise ConfigError(
        f"data.f: the scene has no dirichlet boundary, so only the {model} constraint holds the "
        f"body, and the load's resultant ∫f + ∫t + ∫t_C {what}; push the body onto "
        f"the obstacle "
        "or add a dirichlet boundary"
    )
