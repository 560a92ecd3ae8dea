"""A guaranteed upper bound of the energy error for the scalar Signorini and obstacle
problems (SPEC §1.1–1.2, §9), from an equilibrated flux (:func:`.flux.reconstruct_flux`).

Notation: |||v|||² = ∫_Ω k |∇v|², e = u − u_h, σ_h ∈ RT_p the reconstructed flux with

    −div σ_h = Π_p f (+ λ̃_h for the obstacle),   σ_h·n = Π_p t on Γ_N,   σ_h·n = Π_p t_C + λ̃_h
    on Γ_C,

λ̃_h = Σ_a c_a ψ_a ∈ P1 the discrete multiplier (c_a the lumped nodal multiplier λ_a of the
discrete problem, of the admissible sign σλ̃_h ≤ 0; σ = +1 for u ≤ g, −1 for u ≥ ψ).

**Theorem.**  Let, per cell T,

    A_T = ‖k^{-1/2}(σ_h − k∇u_h)‖_T + osc_T                  (osc_T: :class:`.flux.Flux`)

and A = (Σ_T A_T²)^{1/2}; let w ∈ H¹(Ω), w = 0 on Γ_D, with σ(u_h − g) ≤ w on Γ_C
(Signorini) or in Ω (obstacle), W = |||w|||, and

    B = ∫_{Γ_C or Ω} (−σλ̃_h)(w − σ(u_h − g)) ≥ 0.

If u_h = u_D on Γ_D and g ∈ P_p on each contact facet (Signorini; the discrete problem
sees g through its interpolant g_h), then

    |||u − u_h||| ≤ η := ½ (S + (S² + 4P)^{1/2}),   S = A + W,   P = A W + B,

with no unknown constant.  Proof (Braess, Numer. Math. 101, 2005; Weiss & Wohlmuth,
Math. Comp. 78, 2009; Ern & Vohralík, SINUM 53, 2015): integrating by parts against σ_h,

    |||e|||² = (f − Π_p f, e) + ⟨t − Π_p t, e⟩_{Γ_N ∪ Γ_C} + (σ_h − k∇u_h, ∇e) + ⟨λ − λ̃_h, e⟩,

where ⟨·,·⟩ is on Γ_C (Signorini) or Ω (obstacle) and λ the exact multiplier.  The first
three terms are ≤ Σ_T A_T |||e|||_T ≤ A |||e||| (Cauchy–Schwarz per cell: the oscillations
are orthogonal to constants, Poincaré h_T/π on convex cells, the trace inequality of
:func:`.flux._oscillation`).  With σλ ≤ 0, σλ̃_h ≤ 0, σ(u − g) ≤ 0 and λ(u − g) = 0:

    ⟨λ − λ̃_h, u − u_h⟩ = −⟨λ, u_h − g⟩ − ⟨λ̃_h, u − g⟩ + ⟨λ̃_h, u_h − g⟩
                        ≤ ⟨−σλ, w⟩ + ⟨σλ̃_h, σ(u_h − g)⟩,

and the weak equation tested with w (w = 0 on Γ_D) gives ⟨λ, w⟩ = (k∇e, ∇w) + (k∇u_h − σ_h,
∇w) + (Π_p f − f, w) + ⟨Π_p t − t, w⟩ + ⟨λ̃_h, w⟩, so ⟨−σλ, w⟩ ≤ (|||e||| + A) W + ⟨−σλ̃_h, w⟩.
Altogether |||e|||² ≤ (A + W)|||e||| + A W + B, a quadratic inequality whose root is η.
The complementarity B vanishes where the discrete contact is exact and is ∫ (−λ̃_h)(g − u_h)
over the facets (cells) where the free boundary crosses.  W = 0 whenever u_h is feasible;
here w is the smallest nodal lifting with σ(u_h − g_h) ≤ w: for P1 the nodal values
max(σ(u_h − g_h), 0), for P2 on a segment also the midpoint value that makes the Bernstein
coefficients of w − σ(u_h − g_h) non-negative (the obstacle: w = (σ(u_h − ψ))⁺ with the
exact ψ, by quadrature).  The Dirichlet datum: if u_D ∉ P_p on Γ_D the discrete u_h only
interpolates it; the bound above is then completed by D = |||e_D||| with e_D the P_{p+1}
function equal to I_{p+1}u_D − u_h at the DoFs on Γ_D (zero elsewhere, and on Γ_C),
S = A + W + D, P = A (W + D) + B (e − e_D vanishes on Γ_D for u_D ∈ P_{p+1}; otherwise D
stands for the Dirichlet error, of higher order).

The indicators η_T² = A_T² + W_T² + D_T² + B_T are DG0 forms (so marking is unchanged);
η is the bound above, not (Σ η_T²)^{1/2}.  The terms reported are the totals Σ_T of
‖k^{-1/2}(σ_h − k∇u_h)‖²_T ("flux"), osc_T² ("oscillation"), B ("complementarity"), W²
("feasibility") and D² ("dirichlet").
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

import ufl
from dolfinx import fem, la

from .. import expressions
from ..scene import Scene
from ..solvers import Result
from .flux import Flux, FluxData, reconstruct_flux

TERMS = ("flux", "oscillation", "complementarity", "feasibility", "dirichlet")


@dataclass
class Bound:
    """η (the guaranteed bound), η_T (DG0), the totals of the terms, the parts A, B, W, D of
    the theorem, the flux and timings (seconds)."""

    eta: float
    eta_T: fem.Function
    terms: dict
    parts: dict
    flux: Flux
    seconds: dict = field(default_factory=dict)


def flux_data(scene: Scene, result: Result) -> tuple[FluxData, str, float]:
    """The inputs of :func:`reconstruct_flux` for a scalar scene: (data, multiplier, sign)."""
    model = scene.cfg["model"]["type"]
    if model not in ("signorini", "obstacle"):
        raise ValueError(f"estimator: equilibrated works for the scalar models, not model type {model!r}")
    p, bnd = result.problem, scene.boundary
    data = p.data
    contact = {i: data["t_C"] for i in bnd.ids_with_role("contact")}
    flux = FluxData(result.u_h, data["f"], data["k"], bnd.tags, dirichlet=bnd.ids_with_role("dirichlet"),
                    neumann={i: data["t"] for i in bnd.ids_with_role("neumann")}, contact=contact,
                    lmbda_h=result.lmbda_h)
    return flux, ("cells" if model == "obstacle" else "facets"), -p.constraint.sign


def guaranteed_bound(scene: Scene, result: Result) -> Bound:
    """The bound of the module docstring for a solve of a scalar scene (collective)."""
    seconds = {}
    t0 = time.perf_counter()
    data, multiplier, sign = flux_data(scene, result)
    sigma = -sign            # the constraint sign: σ(u − g) ≤ 0
    msh = scene.mesh
    u_h, k = result.u_h, data.k
    DG0 = fem.functionspace(msh, ("DG", 0))
    v = ufl.TestFunction(DG0)
    lift = _feasibility(scene, result, sigma, k, v)
    grad_w = lift.grad
    data.target = k * (ufl.grad(u_h) - sigma * grad_w)       # k∇s_h: fit σ_h to the feasible s_h
    flux = reconstruct_flux(data, multiplier, sign)
    seconds["flux"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    p = _degree(u_h)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 2 * p + 6})
    B_form = lift.complementarity(flux.lmbda)
    q = flux.sigma_h - k * ufl.grad(u_h)
    q_s = q + sigma * k * grad_w              # σ_h − k∇s_h, s_h = u_h − σ w feasible
    local = {"F": _cellwise(ufl.inner(q, q) / k * v * dx), "Fs": _cellwise(ufl.inner(q_s, q_s) / k * v * dx),
             "W2": _cellwise(k * ufl.inner(grad_w, grad_w) * v * dx), "B": _cellwise(B_form),
             "D2": _dirichlet(scene, result, v, k)}
    local = {name: np.maximum(val, 0.0) for name, val in local.items()}
    cross = msh.comm.allreduce(float(np.sum(_cellwise(lift.cross))), op=MPI.SUM) if lift.cross else np.inf
    A_T, As_T = np.sqrt(local["F"]) + flux.osc, np.sqrt(local["Fs"]) + flux.osc
    comm = msh.comm
    total = {name: comm.allreduce(float(np.sum(val)), op=MPI.SUM) for name, val in
             (("A2", A_T**2), ("As2", As_T**2), ("flux", local["F"]), ("oscillation", flux.osc**2),
              ("complementarity", local["B"]), ("feasibility", local["W2"]), ("dirichlet", local["D2"]))}
    A, As, B = np.sqrt(total["A2"]), np.sqrt(total["As2"]), total["complementarity"]
    W, D = np.sqrt(total["feasibility"]), np.sqrt(total["dirichlet"])
    direct = _root(A + W + D, A * (W + D) + B)
    s_bound = _root(As + D, As * D + B)     # |||u − s_h|||
    feasible = s_bound + W
    split = np.sqrt(max(s_bound**2 + 2 * cross + W**2, 0.0))
    eta = min(direct, feasible, split)
    eta_T = fem.Function(DG0, name="eta_T")
    n = len(A_T)
    eta_T.x.array[:n] = np.sqrt((A_T if direct <= feasible else As_T) ** 2 + local["W2"] + local["D2"] + local["B"])
    eta_T.x.scatter_forward()
    seconds["terms"] = time.perf_counter() - t0
    terms = {name: total[name] for name in TERMS}
    parts = {"A": A, "A_s": As, "B": B, "W": W, "D": D, "X": cross, "direct": direct, "feasible": feasible,
             "split": split, "defect": flux.defect}
    return Bound(float(eta), eta_T, terms, parts, flux, {**flux.seconds, **seconds})


def _root(S: float, P: float) -> float:
    """The positive root bound of x² ≤ S x + P: x ≤ ½ (S + (S² + 4P)^{1/2})."""
    return 0.5 * (S + np.sqrt(S**2 + 4 * P))


def _degree(u_h: fem.Function) -> int:
    return u_h.function_space.element.basix_element.degree


def _cellwise(form) -> np.ndarray:
    """The owned entries of a DG0 form's vector (interior-facet terms summed over ranks)."""
    vec = fem.assemble_vector(fem.form(form))
    vec.scatter_reverse(la.InsertMode.add)
    return vec.array[: vec.index_map.size_local].copy()


@dataclass
class _Lifting:
    """w of the module docstring: its gradient, λ̃ ↦ the DG0 form of B_T, and (obstacle) the
    DG0 form of the cross term X, or None."""

    grad: object
    complementarity: object
    cross: object = None


def _feasibility(scene: Scene, result: Result, sigma: float, k, w_test) -> _Lifting:
    u_h = result.u_h
    msh = scene.mesh
    if scene.cfg["model"]["type"] == "obstacle":
        psi = expressions.to_ufl(scene.cfg["data"]["psi"], msh, scene.cfg["constants"], t=scene.t_constant)
        f = result.problem.data["f"]
        s = sigma * (u_h - psi)
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 2 * _degree(u_h) + 6})   # kinks
        w = ufl.conditional(ufl.gt(s, 0), s, 0)
        grad_w = ufl.conditional(ufl.gt(s, 0), ufl.grad(s), ufl.zero(msh.geometry.dim))
        L = -ufl.div(k * ufl.grad(psi)) - f                     # Lewy–Stampacchia: 0 ≤ −σλ ≤ (−σL)⁺
        grad_s = ufl.grad(u_h) - sigma * grad_w
        cross = (-sigma * f * w + ufl.max_value(-sigma * L, 0) * w + sigma * k * ufl.inner(grad_s, grad_w)) * w_test * dx
        return _Lifting(grad_w, lambda lmbda: (-sigma * lmbda) * ufl.conditional(ufl.lt(s, 0), -s, 0) * w_test * dx,
                        cross)
    g_h = result.problem.data["g_h"]
    w = _bernstein_lifting(scene, u_h, g_h)
    ds = result.problem.data["ds"]
    contact = scene.boundary.ids_with_role("contact")
    return _Lifting(ufl.grad(w), lambda lmbda: sum((-lmbda) * (w - (u_h - g_h)) * w_test * ds(i) for i in contact))


def _bernstein_lifting(scene: Scene, u_h: fem.Function, g_h: fem.Function) -> fem.Function:
    """The smallest nodal w ∈ V with u_h − g_h ≤ w on Γ_C and w = 0 on Γ_D: vertex values
    max(u_h − g_h, 0); for P2 the midpoint value m of a contact facet with vertex values
    w_0, w_1 is max(0, d_m + (w_0 − d_0 + w_1 − d_1)/4) (d = u_h − g_h), which makes the
    Bernstein coefficients of w − d on the facet non-negative."""
    V = u_h.function_space
    msh = V.mesh
    tdim = msh.topology.dim
    bnd = scene.boundary
    w = fem.Function(V, name="w")
    dvals = u_h.x.array - g_h.x.array
    facets = bnd.facets("contact")
    msh.topology.create_connectivity(tdim - 1, tdim)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    c2f = msh.topology.connectivity(tdim, tdim - 1).array.reshape(-1, tdim + 1)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32) if len(facets) else np.zeros(0, np.int32)
    local = np.argmax(c2f[cells] == facets[:, None], axis=1) if len(facets) else np.zeros(0, int)
    layout = V.dofmap.dof_layout
    closure = np.array([layout.entity_closure_dofs(tdim - 1, j) for j in range(tdim + 1)])
    fdofs = V.dofmap.list[cells[:, None], closure[local]] if len(facets) else np.zeros((0, closure.shape[1]), int)
    nv = tdim                                         # vertex DoFs of a facet come first
    vdofs = np.unique(fdofs[:, :nv])
    w.x.array[vdofs] = np.maximum(dvals[vdofs], 0.0)
    if fdofs.shape[1] > nv:                           # P2 on segments: one midpoint per facet
        d0, d1, dm = dvals[fdofs[:, 0]], dvals[fdofs[:, 1]], dvals[fdofs[:, 2]]
        w0, w1 = w.x.array[fdofs[:, 0]], w.x.array[fdofs[:, 1]]
        w.x.array[fdofs[:, 2]] = np.maximum(0.0, dm + (w0 - d0 + w1 - d1) / 4)
    dirichlet = fem.locate_dofs_topological(V, tdim - 1, bnd.facets("dirichlet"))
    w.x.array[dirichlet] = 0.0
    return w


def _dirichlet(scene: Scene, result: Result, w_test, k) -> np.ndarray:
    """D_T² = ∫_T k |∇e_D|² of the module docstring (zero without a Dirichlet part)."""
    from ..models.problem import interpolate_expression

    u_h = result.u_h
    msh = scene.mesh
    tdim = msh.topology.dim
    bnd = scene.boundary
    V2 = fem.functionspace(msh, ("Lagrange", _degree(u_h) + 1))
    dofs = np.setdiff1d(fem.locate_dofs_topological(V2, tdim - 1, bnd.facets("dirichlet")),
                        fem.locate_dofs_topological(V2, tdim - 1, bnd.facets("contact")))
    e_D = fem.Function(V2)
    u2 = fem.Function(V2)
    u2.interpolate(u_h)
    e_D.x.array[dofs] = interpolate_expression(V2, scene.cfg["data"]["u_D"], scene).x.array[dofs] - u2.x.array[dofs]
    e_D.x.scatter_forward()
    dx = ufl.Measure("dx", domain=msh)
    return _cellwise(k * ufl.inner(ufl.grad(e_D), ufl.grad(e_D)) * w_test * dx)
