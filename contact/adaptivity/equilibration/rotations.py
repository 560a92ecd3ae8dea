"""The as-moments of the stress patches (:mod:`.stress`): how each vertex patch's net
asymmetry is split over its cells so that every cell's adds up to zero.

A patch ω_a whose facets are all prescribed must carry ∫_{ω_a} as σ_a = R_a, its rotational
balance (R_a = Σ_T r_{a,T}, r_{a,T} the cell parts of :func:`.stress._rotation_moments`): the
residual of the discrete equation against ψ_a W(x − x_a), zero for the exact solution but
not for u_h ∈ P_1.  Σ_a R_a = 0 (Σ_a ψ_a (x − x_a) = 0), but patch by patch it is not: left
in the patch, each σ_a is asymmetric by O(R_a) and so is σ_h (on hertz_2d and the Tresca
scene 99 % of ‖as σ_h‖ was such cell means).  The split

    ∫_T as σ_a = m_{a,T},   Σ_{T ⊂ ω_a} m_{a,T} = R_a (a's patch closed),
                            Σ_{a ∈ T} m_{a,T} = 0   (every cell),

of least Σ m_{a,T}² / |T| is m_{a,T} = |T| (φ_a − φ̄_T) (φ̄_T the mean over T's vertices),
with φ = 0 at the vertices of a free facet (Γ_D, a symmetry plane: no balance to meet) and

    Σ_{T ∋ a} |T| (φ_a − φ̄_T) = R_a   at the other vertices,

a graph Laplacian L = (d + 1)(M_vertex − M_centroid) (the P_1 mass matrices with the vertex
and the one-point rule), positive definite once a free vertex holds each component.  One
sparse solve (MUMPS) per estimate, for each component of as (1 in 2D, 3 in 3D).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx.fem import petsc as fem_petsc
from petsc4py import PETSc


def spread(msh, free_facets: np.ndarray, area: np.ndarray, r: np.ndarray) -> np.ndarray:
    """m (n_owned cells, d + 1 vertices, k) of the module docstring from the cell parts ``r``
    (same shape) of the owned cells, ``area`` their measures (n_owned,), and the local
    facets ``free_facets`` whose vertices are free (collective)."""
    tdim = msh.topology.dim
    V = fem.functionspace(msh, ("Lagrange", 1))
    n_own = len(area)
    dofs = V.dofmap.list[:n_own]  # the cell's vertices in its local order
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    vertex = ufl.dx(domain=msh, metadata={"quadrature_rule": "vertex", "quadrature_degree": 1})
    centroid = ufl.dx(domain=msh, metadata={"quadrature_degree": 0})
    form = fem.form((tdim + 1) * (u * v * vertex - u * v * centroid))
    free = fem.locate_dofs_topological(V, tdim - 1, free_facets)
    bc = fem.dirichletbc(np.float64(0.0), free, V)
    L = fem_petsc.assemble_matrix(form, bcs=[bc], diag=1.0)
    L.assemble()
    ksp = PETSc.KSP().create(msh.comm)
    ksp.setOperators(L)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    out = np.zeros_like(r)
    b = la.vector(V.dofmap.index_map, V.dofmap.index_map_bs)
    phi = fem.Function(V)
    for k in range(r.shape[2]):
        b.array[:] = 0.0
        np.add.at(b.array, dofs.ravel(), r[:, :, k].ravel())
        b.scatter_reverse(la.InsertMode.add)
        b.array[free] = 0.0
        owned = b.array[: V.dofmap.index_map.size_local]
        rhs = PETSc.Vec().createWithArray(owned, comm=msh.comm)  # type: ignore[arg-type]
        sol = phi.x.petsc_vec
        ksp.solve(rhs, sol)
        rhs.destroy()
        phi.x.scatter_forward()
        vals = phi.x.array[dofs]  # (n, d + 1)
        out[:, :, k] = area[:, None] * (vals - vals.mean(axis=1, keepdims=True))
    ksp.destroy()
    L.destroy()
    return out
