"""One solve of a scene by a baseline enforcement (penalty, augmented Lagrangian, Nitsche).

The scene's contact constraint as UFL for the baseline enforcements
(:mod:`contact.solvers.baselines`, docs/theory.md §10): the pieces of
:class:`~contact.solvers.baselines.UnilateralContact` read off the scene and its
:class:`~contact.solvers.problem.DiscreteProblem`, whose space, Dirichlet conditions and
outputs the baseline shares (its ``u_h`` is the unknown).

* scalar Signorini: d(u) = u ≤ g on Γ_C, σ_n(w) = k ∇w·n_Γ, t₀ = −t_C, modulus k;
* obstacle (constraint in Ω): d(u) = σ u ≤ σ ψ on dx (penalty and augmented Lagrangian);
* linear elasticity against a rigid plane, circle or sphere: d(u) = u·n ≤ g with the
  obstacle's normal n (towards the obstacle) and initial gap g, σ_n(w) = (σ(w) n_Γ)·n, modulus
  E; with friction the tangential parts w − (w·n) n and the scene's Tresca threshold or
  Coulomb coefficient.

The bulk stiffness is the problem's own K where the problem's unknowns are the
displacements (no change of basis: scalar models, coordinate planes); against a tilted
plane, a circle or a sphere the problem holds K̃ = QᵀKQ, and K is assembled here anew.
:func:`solve_baseline` solves from the initial guess the scene's solve chose and returns the
:class:`~contact.solvers.result.Result` on the scene's discrete problem, so that every output
of a scene (fields, tables, forces, estimators) reads it as it reads semismooth Newton's.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..base.errors import ConfigError
from ..base.lifetime import destroy
from ..base.timing import Stopwatch
from ..models.problem import assemble_system
from ..solvers.baselines import FrictionLaw, UnilateralContact, solve_enforced
from ..solvers.nodal_baselines import mortar_scale, solve_nodal
from ..solvers.options import SolverOptions
from ..solvers.problem import DiscreteProblem
from ..solvers.result import Result
from .data import coefficient
from .scene import Scene


def unilateral_contact(scene: Scene, problem: DiscreteProblem) -> tuple[UnilateralContact, list]:
    """The scene's constraint for a baseline method, and the PETSc objects made for it (the
    caller destroys them once the solve is done; the problem's own K and b are borrowed)."""
    cfg = scene.config
    msh = scene.mesh
    made: list = []
    if cfg.model.type in ("signorini", "obstacle"):
        k = problem.data.k
        if cfg.model.type == "signorini":
            n_facet = ufl.FacetNormal(msh)
            assert isinstance(cfg.data.g, str)  # a scalar scene's single expression
            measure = problem.data.ds(scene.boundary.ids_with_role("contact"))
            normal, gap = (lambda w: w), coefficient(cfg.data.g, scene)
            traction = lambda w: k * ufl.dot(ufl.grad(w), n_facet)  # noqa: E731
            data = -problem.data.t_C
        else:  # u ≤ ψ (σ = 1) or u ≥ ψ (σ = −1) in Ω: σ u ≤ σ ψ
            sign = problem.constraint.sign
            assert isinstance(cfg.data.psi, str)
            measure, traction, data = ufl.dx(domain=msh), None, 0.0
            normal, gap = (lambda w: sign * w), sign * coefficient(cfg.data.psi, scene)
        contact = UnilateralContact(
            problem.u_h, problem.K, problem.b, problem.bcs, measure, normal, gap, k,
            traction=traction, traction_data=data,
        )  # fmt: skip
        return contact, made
    if cfg.model.type != "elasticity" or cfg.bodies or problem.current is not None:
        raise ConfigError(
            f"solver.method: {cfg.solver.method} is available for scalar Signorini and "
            "obstacle scenes and one linear elastic body against a rigid obstacle"
        )
    from ..models.elasticity import epsilon, rigid_body_modes, stress

    data = problem.data
    mu, lmbda_L = data.mu, data.lmbda_L
    n, g = data.n_ufl, data.g_ufl
    n_facet = ufl.FacetNormal(msh)
    V = problem.V
    K, b, nullspace = problem.K, problem.b, problem.near_nullspace
    if problem.basis is not None:  # the problem's unknowns are rotated: K in displacements
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        a = ufl.inner(stress(u, mu, lmbda_L), epsilon(v)) * ufl.dx(domain=msh)
        L = ufl.inner(data.f, v) * ufl.dx(domain=msh)
        for i in scene.boundary.ids_with_role("neumann"):
            L += ufl.inner(data.t, v) * data.ds(i)
        K, b = assemble_system(fem.form(a), fem.form(L), problem.bcs)
        nullspace = rigid_body_modes(V)
        made += [K, b, nullspace]

    def along_n(w):
        return ufl.dot(w, n)

    def normal_stress(w):
        return ufl.dot(ufl.dot(stress(w, mu, lmbda_L), n_facet), n)

    friction = None
    if cfg.frictional:
        fr = cfg.friction
        assert fr is not None

        def tangential(w):
            return w - ufl.dot(w, n) * n

        def shear(w):
            t = ufl.dot(stress(w, mu, lmbda_L), n_facet)
            return t - ufl.dot(t, n) * n

        u_prev = scene.history.get("u_prev")
        if u_prev is None:
            u_prev = fem.Function(V)
        friction = FrictionLaw(
            tangential,
            shear,
            u_prev,
            threshold=(
                coefficient(fr.threshold, scene) if fr.law == "tresca" and fr.threshold else None
            ),
            coefficient=fr.coefficient if fr.law == "coulomb" else None,
        )
    assert cfg.model.E is not None
    E = fem.Constant(msh, PETSc.ScalarType(cfg.model.E))  # type: ignore[operator]
    return (
        UnilateralContact(
            problem.u_h,
            K,
            b,
            problem.bcs,
            data.ds(scene.boundary.ids_with_role("contact")),
            along_n,
            g,
            E,
            traction=normal_stress,
            near_nullspace=nullspace,
            friction=friction,
        ),
        made,
    )


def pair_scale(scene: Scene, problem: DiscreteProblem) -> np.ndarray:
    """s_i = E/h at the constrained nodes of a scene with mortar pairs: E = μ(3λ + 2μ)/(λ + μ)
    of each body's material, h the diameter of the slave facets' cells (and of a rigid
    obstacle's contact facets)."""
    cfg, bnd = scene.config, scene.boundary
    ids = [bnd.ids[pair.slave] for pair in cfg.pairs or ()]
    if cfg.obstacle is not None:
        ids += list(bnd.ids_with_role("contact"))
    mu, lmbda_L = problem.data.mu, problem.data.lmbda_L
    E = mu * (3 * lmbda_L + 2 * mu) / (lmbda_L + mu)
    return mortar_scale(problem, problem.data.ds(tuple(ids)), E)


def solve_baseline(
    scene: Scene,
    problem: DiscreteProblem,
    u0: fem.Function,
    opts: SolverOptions,
    verbose: bool,
    timers: dict,
    clock: Stopwatch,
) -> Result:
    """Solve ``scene`` by ``opts.method`` from ``u0`` (a function of ``problem.V``; the
    Dirichlet values are put in); never raises on divergence."""
    u = problem.u_h
    u.x.array[:] = u0.x.array
    if scene.config.pairs:  # the Dirichlet values in displacements, the solve in unknowns
        assert problem.data.u_bcs is not None  # a mortar set's
        for bc in problem.data.u_bcs:
            bc.set(u.x.array)
        u.x.scatter_forward()
        return solve_nodal(problem, pair_scale(scene, problem), opts, verbose, timers, clock)
    for bc in problem.bcs:
        bc.set(u.x.array)
    u.x.scatter_forward()
    contact, made = unilateral_contact(scene, problem)
    try:
        return solve_enforced(problem, contact, opts, verbose, timers, clock)
    finally:
        destroy(*made)
