"""Resultants of an elastic contact solve: the numbers every elastic contact scene reports.

* contact force  F = m Σ_i w_i p_i (n_i · n)  (``Result.contact_force``: p_i = −λ_n,i the nodal
  pressure, w_i the lumped weights, n_i the nodal normals, n the normal at the first point of
  contact, m the symmetric copies the modelled part stands for);
* reaction on the Dirichlet boundary along n: the sum of the residual a(u_h, v) − L(v) over
  its DoFs, times m — equal to F at equilibrium (``force_balance_error`` = |R − F| / F);
* peak pressure max_i p_i and the smallest gap min_i (g_i − u_i·n_i) (≥ 0: no penetration).

Units: forces per unit thickness (N/m) in 2D plane strain, forces (N) in 3D; pressures in
the unit of E.  Reference solutions (Hertz, ...) are compared in :mod:`contact.reference`.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc

from .scene import Scene
from .solvers import Result, owned_residual


def reaction_force(result: Result, k: int) -> float:
    """Component k of the reaction on the Dirichlet boundary, summed over all ranks and
    multiplied by the symmetric copies (collective).  The Dirichlet DoFs are those of the
    condition on u (a multi-body problem's ``u_bcs``; its ``bcs`` act on the unknowns
    x = Q⁻¹u, symmetry and slave axes included)."""
    p = result.problem
    full = dolfinx.fem.petsc.assemble_vector(p.data["reaction_form"])
    full.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    bs = p.V.dofmap.index_map_bs
    n_owned = p.V.dofmap.index_map.size_local * bs
    dofs = p.data.get("u_bcs", p.bcs)[0].dof_indices()[0]
    dofs = dofs[(dofs < n_owned) & (dofs % bs == k)]
    local = float(np.sum(full.array_r[dofs]))
    full.destroy()
    return p.symmetric_copies * p.V.mesh.comm.allreduce(local, op=MPI.SUM)


def nodal_gap(result: Result) -> np.ndarray:
    """g_i − (Qᵀu)_i, the gap at the owned constrained nodes (≥ 0 when feasible)."""
    p = result.problem
    con = p.constraint
    unknowns = p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, unknowns)
    gap = con.sign * (con.g - unknowns.array_r[con.dofs])
    unknowns.destroy()
    return gap


def contact_resultants(scene: Scene, result: Result) -> dict:
    """Contact force, reaction, force balance, peak pressure and smallest gap (collective)."""
    comm = scene.comm
    p = result.problem
    n = np.asarray(p.data["n"])                       # contact normal at the first point of contact
    reaction = abs(reaction_force(result, int(np.argmax(np.abs(n)))))
    force = result.contact_force
    pressure = p.pressure(owned_residual(result))
    return {"contact_force": force, "reaction_force": reaction,
            "force_balance_error": abs(reaction - force) / max(force, 1e-300),
            "peak_pressure": comm.allreduce(float(np.max(pressure, initial=0.0)), op=MPI.MAX),
            "symmetric_copies": p.symmetric_copies,
            "min_gap": comm.allreduce(float(nodal_gap(result).min(initial=np.inf)), op=MPI.MIN)}
