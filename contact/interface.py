"""The interface of a multi-body solve (SPEC §1.5, §5, §7): the pressure seen from both
sides, the forces each body feels and their balance, the reactions, the Hertz values of
the effective radius, and the interface terms of the estimator.

Sign convention: λ = σ_nn ≤ 0 in compression on both sides.  On the slave side λ_i =
R̃_i / D_ii at the slave nodes (the multiplier); on the master side the same traction,
transported by the mortar matrix and lumped,

    λ^m_j = (Σ_i M_ij λ_i) / w_j,    w_j = ∫_{Γ_m} φ_j ds,

which is the pressure at master node j when the slave surface covers its support (a
uniform pressure is seen exactly on both sides).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc
import ufl
from dolfinx import fem, la
from dolfinx import mesh as dmesh

from .scene import Scene
from .solvers import Result


def master_pressure(result: Result) -> fem.Function:
    """λ^m on the output space (nodal; 0 away from the master surfaces), named
    ``lambda_master``."""
    p = result.problem
    V, S = p.V, p.output_space
    bs = V.dofmap.index_map_bs
    imap = V.dofmap.index_map
    n_owned = imap.size_local
    node_of_s = p.output_map // bs
    lam_nodes = PETSc.Vec().createMPI((n_owned, imap.size_global), comm=V.mesh.comm)
    owned_s = node_of_s < n_owned
    lam_nodes.array[node_of_s[owned_s]] = result.lmbda_h.x.array[owned_s]
    out = la.vector(imap, 1)
    weight = np.zeros(n_owned + imap.num_ghosts)
    y = lam_nodes.duplicate()
    for coupling in p.data["couplings"]:
        coupling.M.multTranspose(lam_nodes, y)                       # Σ_i M_ij λ_i
        out.array[:n_owned] += y.array_r
        weight += coupling.master_weights.array
    out.scatter_forward()
    with np.errstate(divide="ignore", invalid="ignore"):
        values = np.where(weight > 0, out.array / np.where(weight > 0, weight, 1.0), 0.0)
    fn = fem.Function(S, name="lambda_master")
    fn.x.array[:] = values[node_of_s]
    for vec in (lam_nodes, y):
        vec.destroy()
    return fn


def interface_terms(scene: Scene, result: Result, w, n, h_E, T) -> dict[str, ufl.Form]:
    """Estimator terms on the pairs' surfaces (SPEC §5 with both sides measured): on the
    slave surface h_E ‖λ_h − T·n‖² (consistency), h_E ‖T − (T·n) n‖² (tangential,
    frictionless), ‖λ_h⁺‖² (sign) and |min(λ_h, 0) g_h| (complementarity, g_h the nodal
    gap); on the master surface h_E ‖λ^m − T·n‖² (consistency_master) and the tangential
    term.  T = σ(u_h) n, n the outward normal of the facet's own body."""
    p = result.problem
    ds, bnd = p.data["ds"], scene.boundary
    lam, gap = result.lmbda_h, result.gap
    lam_m = master_pressure(result)
    Tn = ufl.dot(T, n)
    Tt = T - Tn * n
    zero = fem.Constant(scene.mesh, 0.0) * w * ufl.dx(domain=scene.mesh)
    terms = {"consistency_master": zero}
    slave_ids = [bnd.ids[pair["slave"]] for pair in scene.cfg["pairs"]]
    master_ids = [bnd.ids[pair["master"]] for pair in scene.cfg["pairs"]]
    extra = {"consistency": zero, "tangential": zero, "sign": zero, "complementarity": zero}
    for i in slave_ids:
        extra["consistency"] += h_E * (lam - Tn) ** 2 * w * ds(i)
        extra["tangential"] += h_E * ufl.inner(Tt, Tt) * w * ds(i)
        extra["sign"] += ufl.max_value(lam, 0) ** 2 * w * ds(i)
        extra["complementarity"] += abs(ufl.min_value(lam, 0) * gap) * w * ds(i)
    for i in master_ids:
        terms["consistency_master"] += h_E * (lam_m - Tn) ** 2 * w * ds(i)
        extra["tangential"] += h_E * ufl.inner(Tt, Tt) * w * ds(i)
    return {**extra, **terms}


def effective_modulus(materials: list[tuple[float, float]]) -> float:
    """E* of two bodies: 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂ (SPEC §7)."""
    return 1.0 / sum((1.0 - nu**2) / E for E, nu in materials)


def pair_bodies(scene: Scene, index: int) -> list[str]:
    """Names of the bodies of pair ``index``'s slave and master surfaces (from the cells
    of their facets)."""
    msh, bnd, comm = scene.mesh, scene.boundary, scene.comm
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    names = list(scene.cfg["bodies"])
    out = []
    for side in ("slave", "master"):
        facets = bnd.tags.indices[bnd.tags.values == bnd.ids[scene.cfg["pairs"][index][side]]]
        local = int(scene.bodies.values[f2c.array[f2c.offsets[facets[:1]]]][0]) if len(facets) else 0
        out.append(names[comm.allreduce(local, op=MPI.MAX) - 1])
    return out


def interface_resultants(scene: Scene, result: Result) -> dict:
    """Forces and Hertz figures of a multi-body solve (pair 0 for the Hertz values).

    * ``interface_force_slave`` / ``_master``: Σ over the pair's owned nodes of the residual
      a(u_h, v) − L(v) (the force each body's surface needs from the other; the DoFs with a
      Dirichlet or symmetry condition left out), summed over all pairs; their sum vanishes
      when action equals reaction: ``interface_balance_error`` = |F_s·n0 + F_m·n0| / |F_s·n0|
      along the normal n0 at the first point of contact;
    * ``reactions``: per Dirichlet part, Σ of the residual over its DoFs (a vector);
    * ``contact_force`` P = copies × Σ_i D_ii |λ_i| (n_i·n0) (copies = 2^symmetry planes),
      the half-width (2D) / radius (3D) of the active set around the first point of contact,
      the peak pressure max |λ_i|, and with a Hertz radius the Hertz values for E* of the
      two bodies (``hertz_a``, ``hertz_p0``, ``a_error``, ``p0_error``)."""
    from .hertz import _profile, contact_extent, hertz_radius, hertz_values
    from .models.obstacles import first_contact_point

    comm = scene.comm
    p = result.problem
    V = p.V
    bs = V.dofmap.index_map_bs
    gdim = scene.mesh.geometry.dim
    n_owned = V.dofmap.index_map.size_local
    full = dolfinx.fem.petsc.assemble_vector(p.data["reaction_form"])
    full.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    residual = full.array_r.reshape(-1, bs).copy()
    full.destroy()
    fixed = np.zeros(n_owned * bs, dtype=bool)
    for bc in p.data["u_bcs"]:
        dofs = bc.dof_indices()[0]
        fixed[dofs[dofs < n_owned * bs]] = True
    fixed = fixed.reshape(-1, bs)
    free_res = np.where(fixed, 0.0, residual)

    con = p.constraint
    slaves = slice(0, p.data["pair_nodes"])         # the slave nodes (an obstacle's nodes follow)
    nodes = con.dofs[slaves] // bs
    X = V.tabulate_dof_coordinates()[nodes, :gdim]
    origin = first_contact_point(comm, X, con.g[slaves])
    normals = p.data["normals"][slaves]
    n0 = np.asarray(interface_normal(comm, X, normals, origin))

    from .models.mortar import part_facets, surface_facets
    F_s, F_m = np.zeros(gdim), np.zeros(gdim)
    for index, pair in enumerate(scene.cfg["pairs"]):
        for side, F in (("slave", F_s), ("master", F_m)):
            facets = surface_facets(V, part_facets(scene.boundary, pair[side]))
            mark = la.vector(V.dofmap.index_map, 1)
            mark.array[np.unique(facets.nodes)] = 1.0
            mark.scatter_reverse(la.InsertMode.add)
            owned = np.flatnonzero(mark.array[:n_owned] > 0)
            F += comm.allreduce(free_res[owned].sum(axis=0), op=MPI.SUM)
    reactions = {}
    tdim = scene.mesh.topology.dim
    for name, role in scene.boundary.roles.items():
        if role == "dirichlet":
            facets = scene.boundary.tags.indices[scene.boundary.tags.values == scene.boundary.ids[name]]
            dofs = fem.locate_dofs_topological(V, tdim - 1, facets)
            dofs = dofs[dofs < n_owned]
            reactions[name] = comm.allreduce(residual[dofs].sum(axis=0), op=MPI.SUM).tolist()

    lam = con.sign * (result.lmbda_h.x.array[output_dofs(p, nodes)])       # λ_i at the slave nodes
    copies = 2 ** len(_symmetry_axes(scene, X))
    force = copies * comm.allreduce(float(np.sum(con.w[slaves] * -lam * (normals @ n0))), op=MPI.SUM)
    balance = abs(F_s @ n0 + F_m @ n0) / max(abs(F_s @ n0), 1e-300)
    rel = X - origin
    rho = np.linalg.norm(rel - np.outer(rel @ n0, n0), axis=1)
    a = contact_extent(comm, rho, result.active_mask[slaves])
    p0 = comm.allreduce(float(np.max(-lam, initial=0.0)), op=MPI.MAX)
    out = {"contact_half_width" if gdim == 2 else "contact_radius": a, "peak_pressure": p0,
           "contact_force": force, "interface_force_slave": F_s.tolist(), "interface_force_master": F_m.tolist(),
           "interface_balance_error": balance, "reactions": reactions,
           "contact_normal": n0.tolist(), "symmetric_copies": copies,
           "mortar_coverage": min(c.coverage for c in p.data["couplings"]),
           "min_gap": comm.allreduce(float(np.min(result.gap.x.array[p.output_nodes], initial=np.inf)), op=MPI.MIN),
           "pressure_profile": _profile(comm, rho, -lam)}
    rigid = slice(p.data["pair_nodes"], None)
    if scene.cfg.get("obstacle"):  # Σ_i w_i λ_i n_i over the obstacle's contact nodes (a vector)
        lam_o = result.lmbda_h.x.array[output_dofs(p, con.dofs[rigid] // bs)]
        out["obstacle_force"] = comm.allreduce((con.w[rigid] * lam_o) @ p.data["normals"][rigid], op=MPI.SUM).tolist()
    R = hertz_radius(scene.cfg)
    if R is not None:
        bodies = scene.cfg["bodies"]
        E_star = effective_modulus([(bodies[b]["E"], bodies[b]["nu"]) for b in pair_bodies(scene, 0)])
        a_H, p0_H = hertz_values(R, E_star, force, gdim)
        out.update({"hertz_radius": R, "hertz_E_star": E_star, "hertz_a": a_H, "hertz_p0": p0_H,
                    "a_error": a / a_H - 1.0, "p0_error": p0 / p0_H - 1.0, "a_over_R": a / R})
    return out


def output_dofs(problem, nodes: np.ndarray) -> np.ndarray:
    """The output-space DoFs (of λ_h, the gap) of local nodes."""
    bs = problem.V.dofmap.index_map_bs
    s_of_node = np.empty(len(problem.output_map), dtype=np.int64)
    s_of_node[problem.output_map // bs] = np.arange(len(problem.output_map))
    return s_of_node[nodes]


def _symmetry_axes(scene: Scene, X: np.ndarray) -> set[int]:
    """The coordinate axes k of the symmetry planes x_k = c that pass through a contact node
    (rows of X, this rank's): the planes that mirror the contact zone, each counted once
    however many bodies it cuts (a support plane away from the interface is not one)."""
    from .models.elasticity import _facet_normal_axis

    bnd, msh, comm = scene.boundary, scene.mesh, scene.comm
    tdim = msh.topology.dim
    scale = comm.allreduce(float(np.max(np.abs(msh.geometry.x), initial=0.0)), op=MPI.MAX)
    axes = set()
    for name, role in bnd.roles.items():
        if role != "symmetry":
            continue
        facets = bnd.tags.indices[bnd.tags.values == bnd.ids[name]]
        k = _facet_normal_axis(scene, name, facets)
        nodes = dmesh.entities_to_geometry(msh, tdim - 1, facets[:1]).ravel()
        local = float(msh.geometry.x[nodes[0], k]) if len(nodes) else np.nan
        c = next(v for v in comm.allgather(local) if not np.isnan(v))
        if comm.allreduce(bool(np.any(np.abs(X[:, k] - c) <= 1e-10 * max(scale, 1.0))), op=MPI.LOR):
            axes.add(k)
    return axes



def slave_table(scene: Scene, result: Result) -> list[dict]:
    """One row per slave node (all ranks, on rank 0; empty elsewhere), sorted by ``s``:
    coordinates, ``s`` the signed distance from the first point of contact along the
    surface's tangent (2D) or the in-plane distance from it (3D), the pressure λ_n (≤ 0 in
    compression), the gap g_i − x_i,n and the 0/1 active flag — the rows of contact.csv."""
    from .models.obstacles import first_contact_point

    comm = scene.comm
    p = result.problem
    bs = p.V.dofmap.index_map_bs
    gdim = scene.mesh.geometry.dim
    con = p.constraint
    slaves = slice(0, p.data["pair_nodes"])
    nodes = con.dofs[slaves] // bs
    X = p.V.tabulate_dof_coordinates()[nodes, :gdim]
    s_dofs = output_dofs(p, nodes)
    origin = first_contact_point(comm, X, con.g[slaves])
    n0 = np.asarray(interface_normal(comm, X, p.data["normals"][slaves], origin))
    rel = X - origin
    tangential = rel - np.outer(rel @ n0, n0)
    if gdim == 2:
        s = tangential @ np.array([-n0[1], n0[0]])
    else:
        s = np.linalg.norm(tangential, axis=1)
    cols = np.c_[X, s, result.lmbda_h.x.array[s_dofs], result.gap.x.array[s_dofs],
                 result.active_mask[slaves].astype(float)]
    parts = comm.gather(cols, root=0)
    if comm.rank != 0:
        return []
    data = np.vstack(parts)
    data = data[np.argsort(data[:, gdim])]
    names = list("xyz"[:gdim]) + ["s", "lambda_n", "gap", "active"]
    return [{k: (int(v) if k == "active" else float(v)) for k, v in zip(names, row)} for row in data]


def interface_normal(comm: MPI.Comm, X: np.ndarray, normals: np.ndarray, origin: np.ndarray) -> list[float]:
    """The slave normal at the node nearest to ``origin`` (the same on every rank)."""
    local = (float(np.min(np.linalg.norm(X - origin, axis=1))), normals[np.argmin(np.linalg.norm(X - origin, axis=1))].tolist()) \
        if len(X) else (np.inf, None)
    return min(comm.allgather(local), key=lambda t: t[0])[1]
