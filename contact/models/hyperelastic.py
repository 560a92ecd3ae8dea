"""Hyperelastic bodies (finite strain) against rigid obstacles (issue 31).

In the reference configuration Ω (coordinates X, displacement u, deformation gradient
F = I + ∇u, C = FᵀF, J = det F, E = ½(C − I)) the body stores the strain energy

    neo-Hookean (compressible):   ψ = μ/2 (tr C − 3 − 2 ln J) + λ_L/2 (ln J)²,
    St Venant–Kirchhoff:          ψ = λ_L/2 (tr E)² + μ E:E,

μ, λ_L the Lamé parameters of E and ν (both laws reduce to linear elasticity for small
strain).  2D is plane strain: F is embedded in 3 × 3 with F_33 = 1.  SVK is not convex:
its tangent loses positive definiteness in strong compression (uniaxially at a stretch
below 1/√3).  With the total potential Π(u) = ∫_Ω ψ(F) dX − L(u), L(v) = ∫ f·v dX +
∫_{Γ_N} t·v dS (dead loads per reference volume / area), the discrete residual and its
tangent are UFL derivatives of the energy,

    R(u; v) = ∂Π/∂u [v] = ∫ P(F) : ∇v dX − L(v),     K_T(u) = ∂R/∂u,     P = ∂ψ/∂F,

re-assembled at every Newton iterate (:class:`contact.models.forms.ResidualProblem`).

Contact with a rigid plane through p with unit normal ν (pointing towards the body): the
deformed point x = X + u stays on the body's side, (X + u − p)·ν ≥ 0, i.e.

    u·n ≤ g(X) = (X − p)·ν,   n = −ν,

which is *affine in u* — the same nodal bound as in linear elasticity
(:func:`contact.models.obstacles.plane_contact`), on the current configuration and exact
for any deformation and any sliding along the plane.  So the complementarity problem
R_i(u) = w_i λ_i on the contact nodes keeps the structure every solver here needs:
semismooth Newton with H = diag(s) K_T(x) + diag(d), and PETSc's VI solvers (the bound is
a box constraint).  λ_i is a force per *reference* area (nominal pressure).

A plane whose normal is not a coordinate direction rotates the contact nodes to their
(n, t) axes, u = Q x, as the linear model does: R̃(x) = Qᵀ R(Q x), K̃ = Qᵀ K_T Q
(:class:`RotatedResidualProblem`).

A circle or sphere — and any obstacle once there is friction — is met on the current
configuration instead (:func:`contact.models.obstacles.current_contact`,
:mod:`contact.solvers.current`): the gap g(X + u) of the deformed node is nonlinear in u,
the normal and the node's (n, t) frame follow the obstacle's closest point at every Newton
iterate (large sliding), the unknowns stay u and the contact node's residual block is read
in its current frame; the generalized Jacobian H = B K_T + D carries the obstacle's
curvature term (:class:`CurrentResidualProblem`).  Friction there is the linear model's
HSW / projection law on the current tangent plane, the slip the increment of the deformed
position along it.  :func:`linearized_problem` (the gap linearized at an iterate: a bound
again) gives an independent solver of the same problem through PETSc's VI solvers.

The residual estimator of the adaptive loop (:mod:`contact.adaptivity.estimate`) is written
in the reference configuration with P(u_h) and, on the current configuration, the contact
terms measured with the normal and gap of the deformed point.  Grid sequencing
(:mod:`contact.setup.levels`) solves a load path's first step on coarser meshes first.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import basix
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..solvers.current import nodal_geometry
from ..solvers.krylov_curvature import lanczos_negative
from ..solvers.linear import factor_inertia, mumps_ksp
from ..solvers.problem import Constraint, NodeBlockMatrix, Output
from .forms import CurrentResidualProblem, RotatedResidualProblem
from .physics import deformation_gradient, lame, strain_energy


def deformed_area(u, v, measure) -> ufl.Form:
    """L(v) = ∫ v·(1, …, 1) da over ``measure`` in the deformed configuration: each
    component's entry is the lumped current area w_i^cur = ∫ φ_i da of node i, with Nanson's
    formula da = J |F⁻ᵀ N| dA (F = I + ∇u, gdim × gdim: in plane strain a length per unit
    thickness, the out-of-plane stretch being 1; N the reference unit normal).  P1: F is
    constant per cell, the default quadrature is exact."""
    gdim = len(u)
    F = ufl.Identity(gdim) + ufl.grad(u)
    n = ufl.inv(F).T * ufl.FacetNormal(u.function_space.mesh)
    return ufl.dot(v, ufl.as_vector([1.0] * gdim)) * ufl.det(F) * ufl.sqrt(ufl.dot(n, n)) * measure


def hyperelastic_forms(
    u: fem.Function, law: str, mu, lmbda_L, load: ufl.Form, degree: int
) -> tuple[ufl.Form, ufl.Form, ufl.Form]:
    """(R, J, Π) of a hyperelastic body (module doc) written in the displacement ``u``:
    R(u; v) = ∂Π/∂u [v] = ∫ P(F) : ∇v dX − L(v), its derivative J = ∂R/∂u, and the total
    potential Π(u) = ∫ ψ(F) dX − L(u); ``load`` L(v) (dead loads), ``degree`` the
    quadrature degree of ψ (:func:`quadrature_degree`)."""
    V = u.function_space
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    dx = ufl.Measure("dx", domain=V.mesh, metadata={"quadrature_degree": degree})
    energy = strain_energy(deformation_gradient(u), law, mu, lmbda_L) * dx
    R = ufl.derivative(energy, u, v) - load
    return R, ufl.derivative(R, u, du), energy - ufl.action(load, u)


def quadrature_degree(degree: int) -> int:
    """The quadrature degree of the strain energy and its derivatives on Lagrange elements of
    ``degree``: P1's F = I + ∇u is constant on each cell, so one point (degree 0) integrates
    ψ(F), P(F) : ∇v and their tangent exactly (the degree 2 rule's four points in 3D cost four
    times as much for the same numbers); P2: 2p = 4 for the nonpolynomial ψ."""
    return 0 if degree == 1 else 2 * degree


def jacobian_check(u: fem.Function, degree: int) -> Callable[[], float]:
    """A function returning min J, J = det F of ``u`` (its current values) at the points of
    the quadrature rule of ``degree`` on every owned cell, over all ranks (collective): a
    deformation is admissible where J > 0."""
    msh = u.function_space.mesh
    cell = msh.basix_cell()
    points, _ = basix.make_quadrature(cell, degree)
    expr = fem.Expression(ufl.det(deformation_gradient(u)), np.asarray(points))
    cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)

    def min_jacobian() -> float:
        local = float(np.min(expr.eval(msh, cells), initial=np.inf))
        return msh.comm.allreduce(local, op=MPI.MIN)

    return min_jacobian


def linearized_problem(problem: CurrentResidualProblem) -> RotatedResidualProblem:
    """The same body with the obstacle's gap linearized at the displacement u^k in
    ``problem.u_h``: each contact node i meets the plane tangent to the obstacle at the
    closest point of its deformed position x_i^k = X_i + u_i^k,

        ñ_i^k · u_i ≤ g(x_i^k) + ñ_i^k · u_i^k,

    a bound on the rotated unknown x_i,0 (u = Q_k x, Q_k the frames of the normals ñ^k), so
    that PETSc's VI solvers apply (:class:`RotatedResidualProblem`, K_T re-assembled as
    usual).  A fixed point u^{k+1} = u^k of this sequence solves the problem on the current
    configuration: the linearized gap is then g(X + u) itself, and the multiplier acts along
    ñ(X + u).  An independent solver of the same discrete problem (sequential linearization;
    tests and benchmarks).  Contact nodes with a fixed component are refused (their
    rotated unknowns would not carry the Dirichlet values).  ``u_h`` is shared."""
    cc = problem.current
    assert cc is not None, "a problem with contact on the current configuration"
    if np.any(cc.fixed):
        raise ValueError("linearized_problem: contact nodes with fixed components")
    bs = problem.V.dofmap.index_map_bs
    rows = problem._rows()
    u = problem.u_h.x.array[rows]
    geo = nodal_geometry(cc, u)
    K_T = problem.K.duplicate(copy=True)
    Q = NodeBlockMatrix(K_T, bs)
    blocks = Q.identity()
    blocks[cc.nodes] = geo.frames
    basis = Q.set(blocks)
    normals = geo.frames[:, :, 0]
    con = problem.constraint
    bound = geo.g + np.einsum("ka,ka->k", normals, u)
    constraint = Constraint(con.dofs, bound, con.w, 1.0, con.scale)
    out = RotatedResidualProblem(
        problem.V,
        problem.u_h,
        problem.bcs,
        K_T.PtAP(basis),
        problem.b.duplicate(),
        constraint,
        basis=basis,
        output=Output(problem.output.space, problem.output.map, problem.output.bound),
        symmetry=problem.symmetry,
        data=replace(problem.data, normals=normals),
        F_form=problem.F_form,
        J_form=problem.J_form,
    )
    out.b.set(0.0)
    out.K_T = K_T
    return out


def negative_eigenvalues(result) -> int:
    """The number of negative eigenvalues of the tangent K_T(u_h) on the free unknowns (the
    Dirichlet rows and the active contact nodes held), from the inertia of its Cholesky
    factorization (MUMPS, LDLᵀ; collective).  On the current configuration the Hessian of
    the Lagrangian in the active nodes' current frames, their normal unknowns held
    (:meth:`CurrentResidualProblem.constrained_hessian`).  0: u_h is a stable equilibrium of the
    constrained problem; > 0: K_T lost positive definiteness — past a limit point, or
    St Venant–Kirchhoff in strong compression (its energy is not convex) — and the
    solution may be unstable (buckling, localisation).  One factorization per call — or,
    where the solve itself did not factorize (``result.linear`` not ``direct``: CG + GAMG
    on a large 3D body), the Lanczos estimate of one CG + GAMG solve
    (:func:`contact.solvers.krylov_curvature.lanczos_negative`): then 1 means "at least
    one" and 0 that none was seen."""
    p = result.problem
    x = p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, x)
    if isinstance(p, CurrentResidualProblem):  # the constraint's normal and curvature
        A, held = p.constrained_hessian(x, result.active_mask)
    else:
        p.linearize(x)
        A, held = p.K.duplicate(copy=True), p.constraint.dofs[result.active_mask]
    lo = A.getOwnershipRange()[0]
    A.zeroRowsColumns((held + lo).astype(PETSc.IntType), diag=1.0)  # type: ignore[arg-type]
    A.setOption(PETSc.Mat.Option.SYMMETRIC, True)  # type: ignore[arg-type]
    if getattr(result, "linear", "direct") != "direct":
        try:
            tdim = p.V.mesh.topology.dim
            return lanczos_negative(A, p.near_nullspace, tdim, "contact_stability_")
        finally:
            A.destroy()
            x.destroy()
    ksp = mumps_ksp(A, "cholesky")  # LDLᵀ: its inertia over all ranks
    try:
        pc = ksp.getPC()
        pc.setUp()
        negative, _, _ = factor_inertia(pc)
    finally:
        ksp.destroy()
        A.destroy()
        x.destroy()
    return int(negative)


def min_det_F(result) -> float:
    """The smallest det F of a result's u_h (over the quadrature points of every cell and
    all ranks; collective): ≤ 0 means the solution inverts matter."""
    p = result.problem
    x = p.b.duplicate()
    try:
        p.to_unknowns(result.u_h.x.petsc_vec, x)
        p.admissible(x)  # puts x into u_h
        return p.min_jacobian()
    finally:
        x.destroy()


def uniaxial_stretch(
    law: str, E: float, nu: float, stretch: float, gdim: int
) -> tuple[float, float]:
    """Homogeneous uniaxial compression (or tension) along one axis to ``stretch`` with
    traction-free lateral faces: (lateral stretch λ_1, nominal stress P_22 along the axis),
    P_22 < 0 in compression.  gdim = 2: plane strain, F = diag(λ_1, stretch, 1); gdim = 3:
    F = diag(λ_1, λ_1, stretch).  λ_1 solves P_11(λ_1) = 0 by Newton's method (a scalar
    root; the reference values of the compression test)."""
    mu, lm = lame(E, nu)
    m = gdim - 1  # lateral directions that stretch

    def stress(l1: float) -> tuple[float, float, float]:
        """(P_11, dP_11/dλ_1, P_22)."""
        if law == "neo_hookean":  # P = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ
            lnJ = m * np.log(l1) + np.log(stretch)
            P11 = mu * (l1 - 1 / l1) + lm * lnJ / l1
            dP11 = mu * (1 + 1 / l1**2) + lm * (m - lnJ) / l1**2
            return P11, dP11, mu * (stretch - 1 / stretch) + lm * lnJ / stretch
        # SVK: P = F S, S = λ tr E I + 2μ E
        E1, E2 = (l1**2 - 1) / 2, (stretch**2 - 1) / 2
        trE = m * E1 + E2
        P11 = l1 * (lm * trE + 2 * mu * E1)
        dP11 = (lm * trE + 2 * mu * E1) + l1 * (lm * m * l1 + 2 * mu * l1)
        return P11, dP11, stretch * (lm * trE + 2 * mu * E2)

    l1 = 1.0
    for _ in range(100):
        P11, dP11, _ = stress(l1)
        step = P11 / dP11
        l1 -= step
        if abs(step) <= 1e-15 * l1:
            break
    else:
        raise RuntimeError("uniaxial_stretch: Newton's method did not converge")
    return l1, stress(l1)[2]
