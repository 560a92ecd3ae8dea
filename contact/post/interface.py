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

from .resultants import nodal_gap, whole_body
from ..setup.scene import Scene
from ..solvers import Result, owned_residual


def to_master(result: Result, values: np.ndarray) -> np.ndarray:
    """Nodal data of the slave nodes carried to the master nodes the way the mortar
    coupling carries forces, (Σ_i M_ij v_i) / ∫ φ_j^m, per component: ``values`` (local
    nodes, k) → (local nodes, k), 0 off the master surfaces (owned and ghost entries)."""
    p = result.problem
    imap = p.V.dofmap.index_map
    n_owned = imap.size_local
    k = values.shape[1]
    v = PETSc.Vec().createMPI((n_owned, imap.size_global), comm=p.V.mesh.comm)
    y = v.duplicate()
    out = la.vector(imap, k)
    arr = out.array.reshape(-1, k)
    weight = np.zeros(n_owned + imap.num_ghosts)
    for coupling in p.data["couplings"]:
        weight += coupling.master_weights.array
    for comp in range(k):
        v.array[:] = values[:n_owned, comp]
        for coupling in p.data["couplings"]:
            coupling.M.multTranspose(v, y)                           # Σ_i M_ij v_i
            arr[:n_owned, comp] += y.array_r
    out.scatter_forward()
    for vec in (v, y):
        vec.destroy()
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(weight[:, None] > 0, arr / np.where(weight > 0, weight, 1.0)[:, None], 0.0)


def master_pressure(result: Result) -> fem.Function:
    """λ^m on the output space (nodal; 0 away from the master surfaces), named
    ``lambda_master``."""
    p = result.problem
    S, bs = p.output_space, p.V.dofmap.index_map_bs
    node_of_s = p.output_map // bs
    lam_nodes = np.zeros((len(node_of_s), 1))
    lam_nodes[node_of_s, 0] = result.lmbda_h.x.array
    fn = fem.Function(S, name="lambda_master")
    fn.x.array[:] = to_master(result, lam_nodes)[node_of_s, 0]
    return fn


def _master_vector(result: Result, fn: fem.Function) -> fem.Function:
    """A vector nodal function (on V) of the slave nodes carried to the master nodes."""
    bs = fn.function_space.dofmap.index_map_bs
    out = fem.Function(fn.function_space)
    out.x.array[:] = to_master(result, fn.x.array.reshape(-1, bs)).ravel()
    return out


def interface_terms(scene: Scene, result: Result, w, n, h_E, T) -> dict[str, ufl.Form]:
    """Estimator terms on the pairs' surfaces (SPEC §5 with both sides measured): on the
    slave surface h_E ‖λ_h − T·n‖² (consistency), h_E ‖T_t‖² (tangential, frictionless;
    with friction h_E ‖T_t − λ_t‖² and the terms ‖(|λ_t| − ρ)⁺‖², ∫ |ρ|s_t| + λ_t·s_t| of
    SPEC §1.4, s_t the nodal relative slip increment), ‖λ_h⁺‖² (sign) and |min(λ_h, 0) g_h|
    (complementarity, g_h the nodal gap); on the master surface h_E ‖λ^m − T·n‖²
    (consistency_master) and h_E ‖T_t‖² (with friction h_E ‖T_t + λ_t^m‖², λ_t carried over
    like the pressure).  T = σ(u_h) n, n the outward normal of the facet's own body,
    T_t = T − (T·n) n."""
    p = result.problem
    ds, bnd = p.data["ds"], scene.boundary
    lam = result.lmbda_h
    gap = result.gap.copy()                 # the nodal gap, NaN off the constrained nodes → 0
    gap.x.array[np.isnan(gap.x.array)] = 0.0
    lam_m = master_pressure(result)
    Tn = ufl.dot(T, n)
    Tt = T - Tn * n
    zero = fem.Constant(scene.mesh, 0.0) * w * ufl.dx(domain=scene.mesh)
    terms = {"consistency_master": zero}
    slave_ids = [bnd.ids[pair["slave"]] for pair in scene.cfg["pairs"]]
    master_ids = [bnd.ids[pair["master"]] for pair in scene.cfg["pairs"]]
    extra = {"consistency": zero, "tangential": zero, "sign": zero, "complementarity": zero}
    Tt_s, Tt_m = Tt, Tt
    if result.friction is not None:   # the tangential traction is λ_t on the slave side, −λ_t^m on the master side
        from .friction_resultants import surface_functions

        lam_t, slip = surface_functions(result)[:2]
        Tt_s, Tt_m = Tt - lam_t, Tt + _master_vector(result, lam_t)
        rho = friction_bound(scene, lam)
        extra.update(friction_bound=zero, slip=zero)
    for i in slave_ids:
        extra["consistency"] += h_E * (lam - Tn) ** 2 * w * ds(i)
        extra["tangential"] += h_E * ufl.inner(Tt_s, Tt_s) * w * ds(i)
        extra["sign"] += ufl.max_value(lam, 0) ** 2 * w * ds(i)
        extra["complementarity"] += abs(ufl.min_value(lam, 0) * gap) * w * ds(i)
        if result.friction is not None:   # Hild–Lleras: the bound and the slip's direction
            extra["friction_bound"] += ufl.max_value(ufl.sqrt(ufl.inner(lam_t, lam_t)) - rho, 0) ** 2 * w * ds(i)
            extra["slip"] += abs(rho * ufl.sqrt(ufl.inner(slip, slip)) + ufl.inner(lam_t, slip)) * w * ds(i)
    for i in master_ids:
        terms["consistency_master"] += h_E * (lam_m - Tn) ** 2 * w * ds(i)
        extra["tangential"] += h_E * ufl.inner(Tt_m, Tt_m) * w * ds(i)
    return {**extra, **terms}


def friction_bound(scene: Scene, lam: fem.Function):
    """ρ of the scene's friction law on the slave surface (UFL): Coulomb F·(−λ_h)⁺, Tresca
    the threshold expression s(x, t)."""
    cfg = scene.cfg["friction"]
    if cfg["law"] == "coulomb":
        return cfg["coefficient"] * ufl.max_value(-lam, 0)
    from ..setup import expressions

    return expressions.to_ufl(cfg["threshold"], scene.mesh, scene.cfg["constants"], t=scene.t_constant)


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
    """The forces of a multi-body solve, each of the whole bodies when symmetry planes cut
    them (:func:`contact.post.resultants.whole_body`; collective):

    * ``interface_force_slave`` / ``_master``: Σ over the surfaces' owned nodes of the
      residual a(u_h, v) − L(v) (the force each body's surface needs from the other; the
      DoFs with a Dirichlet or symmetry condition left out), summed over all pairs; their
      sum vanishes when action equals reaction: ``interface_balance_error`` =
      |F_s·n + F_m·n| / |F_s·n| along the normal n at the first point of contact;
    * ``reactions``: per Dirichlet part, Σ of the residual over its DoFs (a vector);
    * ``contact_force`` (:attr:`Result.contact_force`: m Σ_i D_ii p_i (n_i·n), m the
      symmetric copies), ``peak_pressure`` max_i p_i on the slave nodes, ``min_gap``,
      ``mortar_coverage`` (min_i Σ_j M_ij / D_ii) and, with a rigid obstacle too,
      ``obstacle_force`` Σ_i w_i λ_i n_i (the obstacle's force on the body, a vector).

    The Hertz values come from a declared ``reference`` (:mod:`contact.post.reference`)."""
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
    free_res = np.where(fixed.reshape(-1, bs), 0.0, residual)
    n0 = np.asarray(p.data["n"])

    from ..models.mortar import part_facets, surface_facets
    F_s, F_m = np.zeros(gdim), np.zeros(gdim)
    for pair in scene.cfg["pairs"] or []:
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
            reactions[name] = whole_body(p, comm.allreduce(residual[dofs].sum(axis=0), op=MPI.SUM))

    con = p.constraint
    slaves, rigid = slice(0, p.data["pair_nodes"]), slice(p.data["pair_nodes"], None)
    pressure = p.pressure(owned_residual(result))
    gap = nodal_gap(result)
    out = {"contact_force": result.contact_force, "peak_pressure": comm.allreduce(
               float(np.max(pressure[slaves], initial=0.0)), op=MPI.MAX),
           "interface_force_slave": whole_body(p, F_s), "interface_force_master": whole_body(p, F_m),
           "interface_balance_error": abs(F_s @ n0 + F_m @ n0) / max(abs(F_s @ n0), 1e-300),
           "reactions": reactions, "contact_normal": n0.tolist(), "symmetric_copies": p.symmetric_copies,
           "mortar_coverage": min((c.coverage for c in p.data["couplings"]), default=1.0),
           "min_gap": comm.allreduce(float(gap.min(initial=np.inf)), op=MPI.MIN)}
    if scene.cfg.get("obstacle"):
        out["obstacle_force"] = whole_body(p, comm.allreduce((con.w[rigid] * -pressure[rigid])
                                                             @ p.data["normals"][rigid], op=MPI.SUM))
    return out


def output_dofs(problem, nodes: np.ndarray) -> np.ndarray:
    """The output-space DoFs (of λ_h, the gap) of local nodes."""
    bs = problem.V.dofmap.index_map_bs
    s_of_node = np.empty(len(problem.output_map), dtype=np.int64)
    s_of_node[problem.output_map // bs] = np.arange(len(problem.output_map))
    return s_of_node[nodes]
