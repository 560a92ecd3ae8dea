"""Hyperelastic bodies (finite strain) against a rigid plane, frictionless (issue 31).

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

Not in this model (yet): curved obstacles (a gap that is nonlinear in u: normal and gap
updated each Newton step), friction, several bodies, the adaptive loop.  The configuration
refuses them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..base.lifetime import destroy
from ..setup.checks import check_scene_data
from ..setup.scene import Scene
from .elasticity import body_fields, elastic_setting, lame
from .forms import ResidualProblem
from .obstacles import plane_contact

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


def hyperelastic_problem(scene: Scene) -> ResidualProblem:
    """The frictionless contact problem of a hyperelastic body against the scene's rigid
    plane (module doc): R(u; v) and K_T = ∂R/∂u from the energy, the plane's nodal bound."""
    t0 = time.perf_counter()
    check_scene_data(scene)
    model = scene.config.model
    assert model.E is not None and model.law is not None  # required by the loader
    mu, lmbda_L = lame(model.E, model.nu)
    s = elastic_setting(scene)
    V, msh = s.V, scene.mesh
    u_h = fem.Function(V, name="u_h")
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    # P1: F is constant per cell, any rule is exact; P2: degree 2p for the nonpolynomial ψ
    degree = scene.config.mesh.degree
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 2 * degree})
    energy = strain_energy(deformation_gradient(u_h), model.law, mu, lmbda_L) * dx
    R = ufl.derivative(energy, u_h, v) - s.L_ufl
    F_form, J_form = fem.form(R), fem.form(ufl.derivative(R, u_h, du))
    K, b = ResidualProblem.matrices(J_form, s.bcs)
    contact = plane_contact(scene, V, K, b, s.fixed, s.data["ds"])
    kind: type[ResidualProblem] = ResidualProblem
    K_T: PETSc.Mat | None = None  # the tangent in u when K holds K̃ instead
    if "K" in contact:  # a tilted plane: x = Qᵀ u, K̃ = Qᵀ K_T Q (its pattern) replaces K
        b.destroy()
        kind, K_T = RotatedResidualProblem, K
        K, b = contact.pop("K"), contact.pop("b")
    con = contact.pop("constraint")

    law = model.law

    def stresses(u):
        return piola_and_cauchy(u, law, mu, lmbda_L)

    data = {
        **s.data,
        "exact": None,
        "reaction_form": F_form,
        "stresses": stresses,
        "law": model.law,
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
    )
    if isinstance(problem, RotatedResidualProblem):
        problem.K_T = K_T
    return problem


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

    def destroy(self) -> None:
        super().destroy()
        destroy(self.K_T, self._R)


def negative_eigenvalues(result) -> int:
    """The number of negative eigenvalues of the tangent K_T(u_h) on the free unknowns (the
    Dirichlet rows and the active contact nodes held), from the inertia of its Cholesky
    factorization (MUMPS, LDLᵀ; collective).  0: u_h is a stable equilibrium of the
    constrained problem; > 0: K_T lost positive definiteness — past a limit point, or
    St Venant–Kirchhoff in strong compression (its energy is not convex) — and the
    solution may be unstable (buckling, localisation).  One factorization per call."""
    p = result.problem
    x = p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, x)
    p.linearize(x)
    A = p.K.duplicate(copy=True)
    lo = A.getOwnershipRange()[0]
    A.zeroRowsColumns((p.constraint.dofs[result.active_mask] + lo).astype(PETSc.IntType), diag=1.0)
    A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    ksp = PETSc.KSP().create(A.getComm())
    try:
        ksp.setOperators(A)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("cholesky")
        pc.setFactorSolverType("mumps")
        pc.setFactorSetUpSolverType()
        factor = pc.getFactorMatrix()
        factor.setMumpsIcntl(13, 1)  # the root node without ScaLAPACK: the global inertia
        factor.setMumpsIcntl(24, 1)  # null pivots detected (a singular K_T counts as zero)
        pc.setUp()
        negative, _, _ = factor.getInertia()
    finally:
        ksp.destroy()
        A.destroy()
        x.destroy()
    return int(negative)


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
