"""The interface of a multi-body solve (docs/theory.md §1.5, §7): the pressure seen from both sides
(the master side's: :func:`contact.models.mortar.master_pressure`), the forces each body
feels and their balance, the reactions, the Hertz values of the effective radius.  The
interface terms of the estimator are :func:`contact.adaptivity.estimate.interface_terms`.

Sign convention: λ = σ_nn ≤ 0 in compression on both sides.  On the slave side λ_i =
R̃_i / D_ii at the slave nodes (the multiplier); on the master side the same traction,
transported by the mortar matrix and lumped,

    λ^m_j = (Σ_i M_ij λ_i) / w_j,    w_j = ∫_{Γ_m} φ_j ds,

which is the pressure at master node j when the slave surface covers its support (a
uniform pressure is seen exactly on both sides).
"""

from __future__ import annotations

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..solvers import Result, owned_residual
from .posed import Posed
from .resultants import contact_resultants, nodal_gap, whole_body


def effective_modulus(materials: list[tuple[float, float]]) -> float:
    """E* of two bodies: 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂ (docs/theory.md §7)."""
    return 1.0 / sum((1.0 - nu**2) / E for E, nu in materials)


def pair_bodies(posed: Posed, index: int) -> list[str]:
    """Names of the bodies of pair ``index``'s slave and master surfaces (from the cells
    of their facets)."""
    msh, bnd, comm = posed.mesh, posed.boundary, posed.comm
    pairs = posed.pairs
    assert posed.bodies is not None and pairs and posed.materials  # a pair joins two bodies
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    names = list(posed.materials)
    out = []
    for part in pairs[index]:  # slave, master
        facets = bnd.tags.indices[bnd.tags.values == bnd.ids[part]]
        local = (
            int(posed.bodies.values[f2c.array[f2c.offsets[facets[:1]]]][0]) if len(facets) else 0
        )
        out.append(names[comm.allreduce(local, op=MPI.MAX) - 1])
    return out


def interface_resultants(posed: Posed, result: Result) -> dict:
    """The forces of a multi-body solve, each of the whole bodies when symmetry planes cut
    them (:func:`contact.post.resultants.whole_body`; collective):

    * ``interface_force_slave`` / ``_master``: the result's ``interface_forces``, Σ over
      the surfaces' nodes of the residual a(u_h, v) − L(v) (the force each body's surface
      needs from the other; the DoFs with a Dirichlet or symmetry condition left out,
      :meth:`contact.models.mortar.Coupling.surface_forces`), summed over all pairs; their
      sum vanishes when action equals reaction: ``interface_balance_error`` =
      |F_s·n + F_m·n| / |F_s·n| along the normal n at the first point of contact;
    * ``reactions``: per Dirichlet part, Σ of the residual over its DoFs (a vector);
    * ``contact_force`` (:attr:`Result.contact_force`: the size of the whole bodies'
      normal contact force on the slave side, |N̄| m with N = Σ_i D_ii p_i n_i,
      :meth:`contact.models.contacts.BodiesProblem.contact_force`), ``peak_pressure``
      max_i p_i on the slave nodes, ``min_gap``,
      ``mortar_coverage`` (min_i Σ_j M_ij / D_ii) and, with a rigid obstacle too,
      ``obstacle_force`` Σ_i w_i λ_i n_i (the obstacle's force on the body, a vector).

    The Hertz values come from a declared ``reference`` (:mod:`contact.post.reference`)."""
    comm = posed.comm
    p = result.problem
    V = p.V
    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local
    data = p.data
    assert data.reaction_form is not None and data.normals is not None
    if result.interface_forces is None:
        raise ValueError("interface_resultants: a result of contact.solve (interface_forces)")
    full = dolfinx.fem.petsc.assemble_vector(data.reaction_form)
    full.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
    residual = full.array_r.reshape(-1, bs).copy()
    full.destroy()
    n0 = np.asarray(p.data.n)
    F_s, F_m = result.interface_forces
    reactions = {}
    tdim = posed.mesh.topology.dim
    bnd = posed.boundary
    for name, role in bnd.roles.items():
        if role == "dirichlet":
            facets = bnd.tags.indices[bnd.tags.values == bnd.ids[name]]
            dofs = fem.locate_dofs_topological(V, tdim - 1, facets)
            dofs = dofs[dofs < n_owned]
            reactions[name] = whole_body(p, comm.allreduce(residual[dofs].sum(axis=0), op=MPI.SUM))

    con = p.constraint
    slaves, rigid = slice(0, p.data.pair_nodes), slice(p.data.pair_nodes, None)
    pressure = p.pressure(owned_residual(result))
    gap = nodal_gap(result)
    out = {
        "contact_force": result.contact_force,
        "peak_pressure": comm.allreduce(float(np.max(pressure[slaves], initial=0.0)), op=MPI.MAX),
        "interface_force_slave": whole_body(p, F_s),
        "interface_force_master": whole_body(p, F_m),
        "interface_balance_error": abs(F_s @ n0 + F_m @ n0) / max(abs(F_s @ n0), 1e-300),
        "reactions": reactions,
        "contact_normal": n0.tolist(),
        "symmetric_copies": p.symmetry.copies,
        "mortar_coverage": min((c.coverage for c in data.couplings or []), default=1.0),
        "min_gap": comm.allreduce(float(gap.min(initial=np.inf)), op=MPI.MIN),
    }
    if posed.obstacle is not None:
        out["obstacle_force"] = whole_body(
            p,
            comm.allreduce((con.w[rigid] * -pressure[rigid]) @ data.normals[rigid], op=MPI.SUM),
        )
    return out


def output_dofs(problem, nodes: np.ndarray) -> np.ndarray:
    """The output-space DoFs (of λ_h, the gap) of local nodes."""
    bs = problem.V.dofmap.index_map_bs
    s_of_node = np.empty(len(problem.output.map), dtype=np.int64)
    s_of_node[problem.output.map // bs] = np.arange(len(problem.output.map))
    return s_of_node[nodes]


def resultants(posed: Posed, result: Result) -> dict | None:
    """Contact force, reaction, balance, peak pressure of an elasticity run (None for
    scalar models; :mod:`.resultants`; with contact pairs the forces on both sides
    of each interface and the reactions, :func:`interface_resultants`)."""
    if not posed.elastic:
        return None
    if posed.pairs:
        return interface_resultants(posed, result)
    return contact_resultants(posed, result)
