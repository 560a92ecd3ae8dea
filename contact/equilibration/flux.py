"""Equilibrated flux reconstruction (Ern & Vohralík 2015) for a scalar problem with a
contact multiplier: the public entry point :func:`reconstruct_flux`.

Given u_h ∈ P_p, the data f, k, t (Γ_N), t_C (Γ_C) and where the multiplier lives (Γ_C,
Ω or nowhere), it returns σ_h ∈ RT_p with, exactly up to round-off,

    −div σ_h = Π_p f + λ̃_h     in every cell   (λ̃_h = 0 unless the multiplier is in Ω),
    σ_h·n = Π_p t   on Γ_N,    σ_h·n = Π_p t_C + λ̃_h   on Γ_C,    σ_h·n = 0 on other
    exterior facets but Γ_D,

where λ̃_h = Σ_a c_a ψ_a is the P1 function of the patches' multiplier shares c_a (the
lumped nodal multiplier; :mod:`.patches`).  It does not look at a configuration: the
inputs are DOLFINx functions, UFL expressions and facet tags (:class:`FluxData`), so the
same reconstruction serves other models (row-wise for elasticity).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

import basix.ufl
from dolfinx import fem

from .cells import CellTable, FluxData, complete, local_table, return_to_owners
from .patches import solve_patches
from .reference import Reference, reference

__all__ = ["Flux", "FluxData", "reconstruct_flux"]


@dataclass
class Flux:
    """The reconstruction: σ_h (RT_p), λ̃_h (P1), the local data oscillation ‖f − Π_p f‖_T
    (DG0) and of the boundary data Σ_F C_F ‖t − Π_p t‖_F, the projected balance defect
    (algebraic residual), and timings (seconds)."""

    sigma_h: fem.Function
    lmbda: fem.Function
    osc_f: np.ndarray    # (owned cells,) ‖f − Π_p f‖_T
    osc_t: np.ndarray    # (owned cells,) Σ_{F ⊂ ∂T ∩ (Γ_N ∪ Γ_C)} C_{T,F} ‖t − Π_p t‖_F / h_T
    defect: float
    seconds: dict = field(default_factory=dict)


def reconstruct_flux(data: FluxData, multiplier: str | None = None, sign: float = 0.0) -> Flux:
    """σ_h of the module docstring.  ``multiplier``: None, "facets" (λ on the ``contact``
    facets, Signorini) or "cells" (λ in Ω, obstacle); ``sign``: the sign λ̃ must have
    (−1: ≤ 0, +1: ≥ 0, 0: any).  Collective."""
    if multiplier not in (None, "facets", "cells"):
        raise ValueError(f"multiplier: expected None, 'facets' or 'cells', got {multiplier!r}")
    V = data.u_h.function_space
    msh = V.mesh
    d = msh.topology.dim
    p = V.element.basix_element.degree
    ref = reference(d, p)
    comm = msh.comm
    seconds = {}
    t0 = time.perf_counter()
    table, n_owned = local_table(data, ref)
    owner_rank = np.full(n_owned, comm.rank)
    work, source = complete(comm, table, owner_rank)
    seconds["gather"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    vmap = msh.topology.index_map(0)
    owned_vertices = np.arange(*vmap.local_range, dtype=np.int64)
    out = solve_patches(work, owned_vertices, ref, multiplier, sign)
    seconds["patches"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    offset = msh.topology.index_map(d).local_range[0]
    alpha = return_to_owners(comm, work.gcell, source, out.alpha, n_owned, offset)
    sigma_h = _rt_function(msh, ref, table, alpha)
    lmbda = _p1_function(msh, out.vertices - vmap.local_range[0], out.c)
    osc_f, osc_t = _oscillation(table, ref)
    seconds["assemble"] = time.perf_counter() - t0
    defect = comm.allreduce(out.defect)
    return Flux(sigma_h, lmbda, osc_f, osc_t, defect, seconds)


def _rt_function(msh, ref: Reference, table: CellTable, alpha: np.ndarray) -> fem.Function:
    """σ_h as a function of RT_p: the Piola-mapped coefficients evaluated in a vector DG_{p+1}
    space (exact: RT_p ⊂ P_{p+1}), then interpolated into RT_p by DOLFINx."""
    d, p = ref.d, ref.p
    W = fem.functionspace(msh, ("DG", p + 1, (d,)))
    W0 = fem.functionspace(msh, ("DG", p + 1))
    points = W0.element.basix_element.points
    phi = _rt_element(d, p).tabulate(0, points)[0]                     # (npts, m, d)
    x = table.x
    J = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
    det = np.linalg.det(J)
    ref_vals = np.einsum("qmd,nm->nqd", phi, alpha)
    vals = np.einsum("nij,nqj->nqi", J, ref_vals) / det[:, None, None]
    sigma_dg = fem.Function(W)
    n = len(alpha)
    dofs = W0.dofmap.list[:n]
    sigma_dg.x.array.reshape(-1, d)[dofs] = vals
    sigma_dg.x.scatter_forward()
    RT = fem.functionspace(msh, basix.ufl.element("RT", msh.basix_cell(), p + 1,
                                                  basix.LagrangeVariant.legendre))
    sigma_h = fem.Function(RT, name="sigma_h")
    sigma_h.interpolate(sigma_dg)
    sigma_h.x.scatter_forward()
    return sigma_h


def _rt_element(d: int, p: int):
    import basix

    from .reference import CELLS

    return basix.create_element(basix.ElementFamily.RT, CELLS[d], p + 1, basix.LagrangeVariant.legendre)


def _p1_function(msh, local_vertices: np.ndarray, values: np.ndarray) -> fem.Function:
    """The P1 function with the given values at owned vertices (local indices)."""
    V1 = fem.functionspace(msh, ("Lagrange", 1))
    d = msh.topology.dim
    c2v = msh.topology.connectivity(d, 0).array
    vertex_dof = np.empty(msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts, dtype=np.int32)
    vertex_dof[c2v] = V1.dofmap.list.ravel()
    out = fem.Function(V1, name="lambda_tilde")
    out.x.array[vertex_dof[local_vertices]] = values
    out.x.scatter_forward()
    return out


def _oscillation(table: CellTable, ref: Reference) -> tuple[np.ndarray, np.ndarray]:
    """‖f − Π_p f‖_T and Σ_F C_F ‖t − Π_p t‖_F / h_T of the table's cells (see :class:`Flux`)."""
    from .operators import det_inv

    x = table.x
    J = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
    absdet = np.abs(det_inv(J)[0])
    Q, w = ref.Q, ref.w
    coef = table.f @ (w[:, None] * Q.T)                                # reference moments
    rest = table.f - coef @ Q                                           # f − Π_p f at the points
    osc_f = np.sqrt(np.maximum(absdet * (rest**2 @ w), 0.0))
    q, wS = ref.q, ref.wS
    tc = table.t @ (wS[:, None] * q.T)
    trest = table.t - tc @ q                                            # (n, D, nqf)
    D = ref.d + 1
    osc_t = np.zeros(len(table))
    vol = absdet / np.prod(np.arange(1, ref.d + 1))
    for j in range(D):
        E = x[:, [v for v in range(D) if v != j]]
        E = E[:, 1:] - E[:, :1]
        size = np.sqrt(np.abs(np.linalg.det(np.einsum("nad,nbd->nab", E, E))))    # |F| / |F̂|
        area = size / np.prod(np.arange(1, ref.d))
        norm = np.sqrt(size * (trest[:, j] ** 2 @ wS))
        # ‖v − v̄_F‖_F² ≤ (|F|/|T|) h_T² (1/π² + 2/(dπ)) ‖∇v‖_T²  (module bound.py)
        osc_t += np.sqrt(area / vol * (1 / np.pi**2 + 2 / (ref.d * np.pi))) * norm
    return osc_f, osc_t
