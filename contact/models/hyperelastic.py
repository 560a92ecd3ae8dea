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

Not in this model (yet): several bodies, the adaptive loop.  The configuration refuses
them.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import basix
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base.lifetime import destroy
from ..setup.checks import check_scene_data
from ..setup.scene import Scene
from ..solvers.current import nodal_geometry
from ..solvers.krylov_curvature import lanczos_negative
from ..solvers.linear import mumps_ksp
from ..solvers.problem import Constraint, NodeBlockMatrix
from .elasticity import body_fields, elastic_setting, lame
from .forms import ResidualProblem
from .obstacles import current_contact, plane_contact, scene_obstacle

LAWS = ("neo_hookean", "saint_venant_kirchhoff")


def deformation_gradient(u) -> ufl.core.expr.Expr:
    """F = I + ∇u as a 3 × 3 tensor (2D: plane strain, F_33 = 1)."""
    gdim = len(u)
    F = ufl.Identity(gdim) + ufl.grad(u)
    if gdim == 3:
        return F
    return ufl.as_matrix([[F[0, 0], F[0, 1], 0], [F[1, 0], F[1, 1], 0], [0, 0, 1]])


def strain_energy(F, law: str, mu, lmbda_L) -> ufl.core.expr.Expr:
    """ψ(F) per unit reference volume (the module doc's laws; F 3 × 3)."""
    C = F.T * F
    if law == "neo_hookean":
        lnJ = ufl.ln(ufl.det(F))
        return mu / 2 * (ufl.tr(C) - 3 - 2 * lnJ) + lmbda_L / 2 * lnJ**2
    if law == "saint_venant_kirchhoff":
        E = (C - ufl.Identity(3)) / 2
        return lmbda_L / 2 * ufl.tr(E) ** 2 + mu * ufl.inner(E, E)
    raise ValueError(f"model.law: expected one of {', '.join(LAWS)}, got {law!r}")


def piola_and_cauchy(u, law: str, mu, lmbda_L) -> tuple:
    """(P, σ): the first Piola–Kirchhoff stress P = ∂ψ/∂F (gdim × gdim, for the residual's
    tractions in the reference configuration) and the Cauchy stress σ = J⁻¹ P Fᵀ (3 × 3,
    σ_33 ≠ 0 in plane strain), both in the unit of E."""
    gdim = len(u)
    F = ufl.variable(deformation_gradient(u))
    P = ufl.diff(strain_energy(F, law, mu, lmbda_L), F)
    sigma = P * F.T / ufl.det(F)
    return ufl.as_matrix([[P[i, j] for j in range(gdim)] for i in range(gdim)]), sigma


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


def hyperelastic_problem(scene: Scene, frictional: bool = False) -> ResidualProblem:
    """The contact problem of a hyperelastic body against the scene's rigid obstacle (module
    doc): R(u; v) and K_T = ∂R/∂u from the energy; a plane's nodal bound, or — for a circle
    or sphere, and with friction (``frictional``: the caller adds the friction set) — the
    gap of the deformed point on the current configuration."""
    t0 = time.perf_counter()
    check_scene_data(scene)
    model = scene.config.model
    assert model.E is not None and model.law is not None  # required by the loader
    mu, lmbda_L = lame(model.E, model.nu)
    s = elastic_setting(scene)
    V, msh = s.V, scene.mesh
    u_h = fem.Function(V, name="u_h")
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    # P1: F is constant per cell, one point is exact; P2: degree 2p for the nonpolynomial ψ
    degree = scene.config.mesh.degree
    quadrature = quadrature_degree(degree)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": quadrature})
    energy = strain_energy(deformation_gradient(u_h), model.law, mu, lmbda_L) * dx
    R = ufl.derivative(energy, u_h, v) - s.L_ufl
    F_form, J_form = fem.form(R), fem.form(ufl.derivative(R, u_h, du))
    potential = fem.form(energy - ufl.action(s.L_ufl, u_h))  # Π(u) = ∫ ψ dX − L(u)
    min_jacobian = jacobian_check(u_h, quadrature)
    K, b = ResidualProblem.matrices(J_form, s.bcs)
    obstacle = scene_obstacle(scene)
    kind: type[ResidualProblem] = ResidualProblem
    if obstacle.kind == "plane" and not frictional:
        contact = plane_contact(scene, V, K, b, s.fixed, s.data["ds"])
    else:
        contact = current_contact(scene, V, s.fixed, s.data["ds"], obstacle)
        kind = CurrentResidualProblem
    K_T: PETSc.Mat | None = None  # the tangent in u when K holds K̃ instead
    if "K" in contact:  # a tilted plane: x = Qᵀ u, K̃ = Qᵀ K_T Q (its pattern) replaces K
        b.destroy()
        kind, K_T = RotatedResidualProblem, K
        K, b = contact.pop("K"), contact.pop("b")
    con = contact.pop("constraint")

    law = model.law

    def stresses(u):
        return piola_and_cauchy(u, law, mu, lmbda_L)

    contact_ds = s.data["ds"](scene.boundary.ids_with_role("contact"))
    data = {
        **s.data,
        "exact": None,
        "reaction_form": F_form,
        "stresses": stresses,
        "law": model.law,
        "deformed_area": fem.form(deformed_area(u_h, v, contact_ds)),
        **contact.pop("data"),
    }
    problem = kind(
        V,
        u_h,
        s.bcs,
        K,
        b,
        con,
        data=data,
        **contact,
        **body_fields(s, contact.get("basis")),
        assembly_time=time.perf_counter() - t0,
        F_form=F_form,
        J_form=J_form,
        energy_form=potential,
        min_jacobian=min_jacobian,
    )
    if isinstance(problem, RotatedResidualProblem):
        problem.K_T = K_T
    return problem


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


@dataclass
class RotatedResidualProblem(ResidualProblem):
    """The residual problem in rotated unknowns x = Qᵀ u (Q orthogonal and block-diagonal:
    the contact nodes of a tilted plane on their (n, t) axes, the others unrotated, as in
    :func:`contact.models.obstacles.plane_contact`):

        R̃(x) = Qᵀ R(Q x),     K̃(x) = Qᵀ K_T(Q x) Q,

    so that u·n ≤ g is a bound on one unknown per contact node.  K̃ is written into ``K``
    (MatPtAP reusing its pattern: the solvers keep their references to it)."""

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
        """out = Qᵀ R(Q x)."""
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
        super().destroy()
        destroy(self.K_T, self._R)


@dataclass
class CurrentResidualProblem(ResidualProblem):
    """The residual problem with contact on the current configuration
    (:mod:`contact.solvers.current`, ``current`` set): the unknowns are the displacements,
    a contact node's residual block is read in the frame of its current normal ñ(x_i).
    The nodal quantities below are those of the iterate in ``u_h`` (the residual ``r``
    passed in is R(u_h), as :func:`contact.solvers.owned_residual` gives it)."""

    def _rows(self) -> np.ndarray:
        bs = self.V.dofmap.index_map_bs
        return self.current.nodes[:, None] * bs + np.arange(bs)

    def multiplier(self, r: np.ndarray) -> np.ndarray:
        """λ_i = ñ_i·R_i / w_i (≤ 0 in contact): the normal nodal force per reference area."""
        rows = self._rows()
        geo = nodal_geometry(self.current, self.u_h.x.array[rows])
        return np.einsum("ka,ka->k", geo.frames[:, :, 0], r[rows]) / self.constraint.w

    def pressure(self, r: np.ndarray) -> np.ndarray:
        """The nominal contact pressure p_i = −λ_i (force per reference area, ≥ 0)."""
        return -self.multiplier(r)

    def nodal_gap(self, x: np.ndarray) -> np.ndarray:
        """g(X_i + u_i): the gap of the deformed contact node (x holds the displacements)."""
        cc = self.current
        return cc.surface.project(cc.X + x[self._rows()])[0]

    def gap_output(self, x: np.ndarray) -> fem.Function:
        """The current gap g(X_i + u_i) at the contact nodes, NaN elsewhere."""
        gap = self.nodal_output("gap", self.nodal_gap(x))
        on = self.nodal_output("on", np.ones(len(self.constraint.dofs)))
        gap.x.array[on.x.array < 0.5] = np.nan
        return gap

    def constrained_hessian(self, x: PETSc.Vec, active: np.ndarray) -> tuple[PETSc.Mat, np.ndarray]:
        """(Ã, held rows): the Hessian of the Lagrangian L = Π + Σ_i μ_i g_i(u) at the
        solution x, on the tangent space of the active constraints — what decides the
        stability of a constrained equilibrium (:func:`negative_eigenvalues`).  With
        μ_i = ñ_i·R_i (= w_i λ_i ≤ 0; R_i = μ_i ñ_i at a frictionless solution) and
        ∇²g = −Dn,

            ∇²L = K_T − Σ_{i active} μ_i P_i Dn_i P_i,

        (against a circle or sphere −μ Dn = −w p (I − n nᵀ)/|x − c|: a convex obstacle
        softens the body's tangential motion — it can roll off), rotated to the active nodes'
        current frames, Ã = Qᵀ ∇²L Q; the held rows are their normal unknowns.  A new
        matrix (the caller destroys it); K becomes K_T(x)."""
        cc, bs = self.current, self.V.dofmap.index_map_bs
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
        """F = −m_n Σ_i R_i·n: the resultant of the nodal contact forces along the normal n
        at the first point of contact (m_n the mirror images pressing along n,
        :meth:`~contact.solvers.problem.DiscreteProblem.copies_along`; frictionless:
        Σ w_i p_i ñ_i·n)."""
        n = np.asarray(self.data["n"], dtype=float)
        local = -float(np.sum(r[self._rows()][:, : len(n)] @ n))
        return self.copies_along(n) * self.V.mesh.comm.allreduce(local, op=MPI.SUM)


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
        output_space=problem.output_space,
        output_map=problem.output_map,
        output_bound=problem.output_bound,
        lambda_sign=1.0,
        basis=basis,
        data={**problem.data, "normals": normals},
        F_form=problem.F_form,
        J_form=problem.J_form,
        symmetric_copies=problem.symmetric_copies,
        symmetry_axes=problem.symmetry_axes,
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
        negative, _, _ = pc.getFactorMatrix().getInertia()
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
