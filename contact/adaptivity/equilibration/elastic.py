"""An upper bound of the energy error for linear elasticity against a rigid plane,
frictionless or with Tresca friction (docs/theory.md §1.3–1.4, §9.2), from the weakly
symmetric equilibrated stress of :mod:`.stress`.

Notation: |||v|||² = a(v, v) = ∫ C ε(v) : ε(v) (C ε = 2μ ε + λ_L tr ε I, plane strain in 2D),
e = u − u_h, n the obstacle's normal (towards it), g the gap, λ ≤ 0 the contact pressure
(σ(u)ν = λ n + λ_t on Γ_C), ρ the Tresca bound, s_t = (u − u_prev)_t the slip of the step.
σ_h (:mod:`.stress`) has −div σ_h = Π_p f, σ_h ν = Π_p t on Γ_N, λ̃_h n + λ̃_t on Γ_C, zero
in the free components elsewhere, and weakly symmetric rows.  Per cell T

    F_T = ‖C^{-1/2}(sym σ_h − C ε(u_h))‖_T,   Y_T = ‖skw σ_h‖_T,   osc_T (:class:`.stress.Stress`),
    A = (Σ F_T²)^{1/2} + C_K (2μ)^{-1/2} (Σ Y_T²)^{1/2}
        + (1 + C_K²)^{1/2} (2μ)^{-1/2} (Σ osc_T²)^{1/2},

C_K the Korn-type constant of :mod:`.korn` (‖skw ∇v‖ ≤ C_K ‖ε(v)‖ on H¹ functions vanishing
where u is prescribed).  With w ≥ (u_h·n − g) on Γ_C (w = 0 on Γ_D) its lifting W = |||w n|||,
D = |||e_D||| (the Dirichlet interpolation, as in :mod:`.bound`), and

    B   = ∫_{Γ_C} (−λ̃_h)(w − (u_h·n − g)) ≥ 0,
    B_t = ∫_{Γ_C} ρ |s_t,h| + λ̃_t·s_t,h ≥ 0       (Tresca; 0 without friction),

each of η_1 = R(A + W + D, A(W + D) + B + B_t) and η_2 = R(A_s + D, A_s D + B + B_t) + W
bounds |||u − u_h||| (R(S, P) = ½(S + (S² + 4P)^{1/2}), A_s: A with u_h − w n), and η is
the smaller.

Proof.  For v = u_D on Γ_D (componentwise on symmetry planes), integrating by parts against
σ_h and with σ(u) symmetric,

    |||u − v|||² = ∫ (sym σ_h − C ε(v)) : ε(u − v) − ∫ skw σ_h : skw ∇(u − v)
                   + (f − Π_p f, u − v) + ⟨t − Π_p t, u − v⟩_{Γ_N}
                   + ⟨λ − λ̃_h, (u − v)·n⟩_{Γ_C} + ⟨λ_t − λ̃_t, (u − v)_t⟩_{Γ_C}.

The first term is ≤ F |||u − v|||; the second ≤ Y C_K ‖ε(u − v)‖ ≤ Y C_K (2μ)^{-1/2} |||u − v|||
(2μ‖ε‖² ≤ a); the oscillations (orthogonal to P_p ⊃ the rigid motions, cell by cell) are
≤ Σ osc_T ‖∇(u − v)‖_T (Poincaré and the trace inequality of :func:`.flux._oscillation`,
per component) and ‖∇z‖² = ‖ε(z)‖² + ‖skw ∇z‖² ≤ (1 + C_K²)‖ε(z)‖².  The normal contact
term is the scalar one of :mod:`.bound` for the component u·n ≤ g.  The tangential one,
with |λ_t| ≤ ρ, λ_t·s_t + ρ|s_t| = 0 and |λ̃_t| ≤ ρ:  ⟨λ_t − λ̃_t, s_t − s_t,h⟩ ≤ −∫ρ|s_t| +
∫ρ|s_t,h| + ∫|λ̃_t||s_t| + ⟨λ̃_t, s_t,h⟩ ≤ B_t.  Then (i) and (ii) follow as in :mod:`.bound`. ∎

What is not guaranteed: C_K is a Rayleigh–Ritz value (from below, :mod:`.korn`); it weighs
the asymmetry, which the weak symmetry makes small, and the data oscillation (zero for
data in P_p).  The Tresca bound enters through its nodal interpolant ρ_h and the discrete
law gives |λ_t,h| ≤ ρ_h at the nodes: exact when ρ is linear between contact nodes.  As
for the scalar bound: the Dirichlet datum through D, quadrature of the data, and the
algebraic residual (:attr:`.stress.Stress.defect`, reported).

η_T² = A_T² + W_T² + D_T² + B_T + B_t,T with A_T = F_T + C_K (2μ)^{-1/2} Y_T + (1 +
C_K²)^{1/2}(2μ)^{-1/2} osc_T, a DG0 form (marking unchanged); η is the bound.
"""

from __future__ import annotations

import time

import numpy as np
import ufl
from dolfinx import fem

from ...setup.scene import Scene
from ...solvers import Result
from .bound import Bound, _bernstein_lifting, _cellwise, _root, indicators
from .korn import korn_constant
from .stress import StressData, reconstruct_stress

#: the weight κ of ‖skw σ‖² in the patch problems (:mod:`.stress`, ``skew_weight``), in
#: units of C_K²/(2μ), the factor of ‖skw σ_h‖² in A².  The Tresca scene's effectivity on
#: levels 3–7 (configs/friction_tresca_manufactured.yaml, Dörfler 0.5): 1 → 1.56–1.67,
#: 4 → 1.43–1.54, 16 → 1.40–1.53, 64 → 1.37–1.54 (the flux misfit grows as the asymmetry
#: shrinks); hertz_2d 8k–10k DoFs at 16: 1.12–1.13 against a reference 4× finer
SKEW = 16.0

TERMS = (
    "flux",
    "asymmetry",
    "oscillation",
    "complementarity",
    "friction",
    "feasibility",
    "dirichlet",
)


def stress_data(scene: Scene, result: Result) -> StressData:
    """The inputs of :func:`.stress.reconstruct_stress` for a solve of an elastic scene
    against a rigid plane (its boundary parts and the problem's data; no configuration)."""
    p, bnd = result.problem, scene.boundary
    if "normals" in p.data or "n" not in p.data or "mu" not in p.data:
        raise ValueError(
            "estimator: equilibrated for elasticity needs one body against a rigid plane"
        )
    d = scene.mesh.topology.dim
    dirichlet = [list(bnd.ids_with_role("dirichlet")) for _ in range(d)]
    planes = [n for n, role in bnd.roles.items() if role == "symmetry"]
    for name, axis in zip(planes, p.symmetry_axes):
        dirichlet[axis].append(bnd.ids[name])
    lam_t = None
    if result.friction is not None:
        from ...solvers.friction import surface_functions

        lam_t = surface_functions(result)[0]
    return StressData(
        result.u_h,
        p.data["f"],
        float(p.data["mu"]),
        float(p.data["lmbda_L"]),
        bnd.tags,
        tuple(tuple(ids) for ids in dirichlet),
        neumann={i: p.data["t"] for i in bnd.ids_with_role("neumann")},
        contact=bnd.ids_with_role("contact"),
        normal=np.asarray(p.data["n"], dtype=float),
        lmbda_h=result.lmbda_h,
        lmbda_t=lam_t,
    )


def elastic_bound(scene: Scene, result: Result) -> Bound:
    """The bound of the module docstring for a solve of an elastic scene (collective)."""
    seconds = {}
    t0 = time.perf_counter()
    korn = korn_constant(result.problem.V, result.problem.bcs)
    seconds["korn"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    data = stress_data(scene, result)
    data.skew_weight = SKEW * korn**2 / (2.0 * data.mu)
    stress = reconstruct_stress(data)
    seconds["stress"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    msh = scene.mesh
    d = msh.topology.dim
    u_h, mu, lam = result.u_h, data.mu, data.lmbda_L
    DG0 = fem.functionspace(msh, ("DG", 0))
    v = ufl.TestFunction(DG0)
    p = u_h.function_space.element.basix_element.degree
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 2 * p + 4})
    n = ufl.as_vector(data.normal.tolist())
    w, W_form, B_form = _normal_lifting(scene, result, n, stress.lmbda, v)
    sigma_h = stress.sigma
    sym, skw = ufl.sym(sigma_h), ufl.skew(sigma_h)
    c_lam = lam / (2.0 * mu + d * lam)

    def compliance(X):  # ∫ C⁻¹ X : X
        return (ufl.inner(X, X) - c_lam * ufl.tr(X) ** 2) / (2.0 * mu)

    def stress_of(z):
        e = ufl.sym(ufl.grad(z))
        return 2.0 * mu * e + lam * ufl.tr(e) * ufl.Identity(d)

    q = sym - stress_of(u_h)
    q_s = q + stress_of(w * n)  # s_h = u_h − w n
    local = {
        "F": _cellwise(compliance(q) * v * dx),
        "Fs": _cellwise(compliance(q_s) * v * dx),
        "Y": _cellwise(ufl.inner(skw, skw) * v * dx),
        "W2": W_form,
        "B": B_form,
        "Bt": _friction(scene, result, stress, v),
        "D2": _dirichlet(scene, result, v, stress_of),
    }
    local = {name: np.maximum(val, 0.0) for name, val in local.items()}
    k_as = korn / np.sqrt(2.0 * mu)
    k_osc = np.sqrt(1.0 + korn**2) / np.sqrt(2.0 * mu)
    comm = msh.comm
    total = {
        name: comm.allreduce(float(np.sum(val)))
        for name, val in (
            ("flux", local["F"]),
            ("flux_s", local["Fs"]),
            ("asymmetry", k_as**2 * local["Y"]),
            ("oscillation", k_osc**2 * stress.osc**2),
            ("complementarity", local["B"]),
            ("friction", local["Bt"]),
            ("feasibility", local["W2"]),
            ("dirichlet", local["D2"]),
        )
    }
    extra = np.sqrt(total["asymmetry"]) + np.sqrt(total["oscillation"])
    A = np.sqrt(total["flux"]) + extra
    As = np.sqrt(total["flux_s"]) + extra
    B = total["complementarity"] + total["friction"]
    W, D = np.sqrt(total["feasibility"]), np.sqrt(total["dirichlet"])
    direct = _root(A + W + D, A * (W + D) + B)
    feasible = _root(As + D, As * D + B) + W
    eta = min(direct, feasible)
    F_T = np.sqrt(local["F"] if direct <= feasible else local["Fs"])
    A_T = F_T + k_as * np.sqrt(local["Y"]) + k_osc * stress.osc
    eta_T = indicators(DG0, A_T**2, local["W2"], local["D2"], local["B"], local["Bt"])
    seconds["terms"] = time.perf_counter() - t0
    terms = {name: total[name] for name in TERMS}
    parts = {
        "A": A,
        "A_s": As,
        "B": B,
        "W": W,
        "D": D,
        "korn": korn,
        "direct": direct,
        "feasible": feasible,
        "defect": stress.defect,
    }
    return Bound(float(eta), eta_T, terms, parts, stress, {**stress.seconds, **seconds})


def _normal_lifting(scene: Scene, result: Result, n, lmbda, v):
    """w (the smallest nodal lifting of (u_h·n − g)⁺ on Γ_C, :func:`.bound._bernstein_lifting`),
    the DG0 vectors of W_T² = ‖C^{1/2} ε(w n)‖²_T and of B_T."""
    p = result.problem
    S = p.output_space
    u_n, g_h = fem.Function(S), fem.Function(S)
    u_n.interpolate(fem.Expression(ufl.dot(result.u_h, n), S.element.interpolation_points))
    g_h.interpolate(fem.Expression(p.data["g_ufl"], S.element.interpolation_points))
    w = _bernstein_lifting(scene, u_n, g_h)
    mu, lam = float(p.data["mu"]), float(p.data["lmbda_L"])
    e = ufl.sym(ufl.grad(w * n))
    dx = ufl.Measure("dx", domain=scene.mesh)
    W2 = _cellwise((2.0 * mu * ufl.inner(e, e) + lam * ufl.tr(e) ** 2) * v * dx)
    ds = p.data["ds"]
    gap = ufl.dot(result.u_h, n) - p.data["g_ufl"]
    B = np.zeros_like(W2)
    if lmbda is not None:
        contact = scene.boundary.ids_with_role("contact")
        B = _cellwise(sum((-lmbda) * (w - gap) * v * ds(i) for i in contact))
    return w, W2, B


def _friction(scene: Scene, result: Result, stress, v) -> np.ndarray:
    """B_t,T = ∫_{∂T ∩ Γ_C} ρ_h |s_t,h| + λ̃_t·s_t,h (zero without friction)."""
    ds = result.problem.data["ds"]
    n_cells = scene.mesh.topology.index_map(scene.mesh.topology.dim).size_local
    if result.friction is None:
        return np.zeros(n_cells)
    from ...solvers.friction import surface_functions

    lam_t, slip, _, rho = surface_functions(result)
    form = sum(
        (rho * ufl.sqrt(ufl.inner(slip, slip)) + ufl.inner(lam_t, slip)) * v * ds(i)
        for i in scene.boundary.ids_with_role("contact")
    )
    return _cellwise(form)


def _dirichlet(scene: Scene, result: Result, v, stress_of) -> np.ndarray:
    """D_T² = a(e_D, e_D)_T, e_D ∈ P_{p+1}^d equal to I_{p+1}u_D − u_h at the Γ_D DoFs off Γ_C
    (zero elsewhere; zero without a datum ``u_D`` in the problem's data)."""
    p = result.problem
    msh = scene.mesh
    n_cells = msh.topology.index_map(msh.topology.dim).size_local
    u_D = p.data.get("u_D")
    if u_D is None:
        return np.zeros(n_cells)
    u_h = result.u_h
    tdim = msh.topology.dim
    deg = u_h.function_space.element.basix_element.degree + 1
    V2 = fem.functionspace(msh, ("Lagrange", deg, (msh.geometry.dim,)))
    bnd = scene.boundary
    dofs = np.setdiff1d(
        fem.locate_dofs_topological(V2, tdim - 1, bnd.facets("dirichlet")),
        fem.locate_dofs_topological(V2, tdim - 1, bnd.facets("contact")),
    )
    e_D, u2, d2 = fem.Function(V2), fem.Function(V2), fem.Function(V2)
    u2.interpolate(u_h)
    if isinstance(u_D, fem.Constant):
        d2.x.array.reshape(-1, msh.geometry.dim)[:] = u_D.value
    else:
        d2.interpolate(fem.Expression(u_D, V2.element.interpolation_points))
    bs = V2.dofmap.index_map_bs
    idx = (dofs[:, None] * bs + np.arange(bs)).ravel()
    e_D.x.array[idx] = d2.x.array[idx] - u2.x.array[idx]
    e_D.x.scatter_forward()
    e = ufl.sym(ufl.grad(e_D))
    dx = ufl.Measure("dx", domain=msh)
    return _cellwise(ufl.inner(stress_of(e_D), e) * v * dx)
