"""The contact surface Γ_C of an elastic solve, node by node, and its resultants.

For every contact node i (weight w_i = ∫_{Γ_C} φ_i, a length in 2D, an area in 3D): its
coordinates, its position along Γ_C, the contact pressure λ_n,i ≤ 0 (stress), the gap,
and for friction the tangential traction λ_t,i on the body (stress, a vector in global
axes), the friction bound ρ_i, the slip increment s_t,i of the load step (length) and the
status separated / stick / slip.  Position: in 2D the signed distance from the first point
of contact x_0 (smallest initial gap; the w-weighted centre of the nodes that share it, e.g.
of a flat face on a plane) along the tangent t_0 = (−n_y, n_x) of the obstacle's normal there
(for a plane y = 0 with the body above: the x coordinate); in 3D the distance from x_0 in
the tangent plane.

Resultants (of the modelled part; symmetric copies are not added): the normal force
Σ w_i λ_n,i, the tangential force Σ w_i λ_t,i (vector), the contact force on the body
Σ w_i (λ_n,i n_i + λ_t,i) (vector; with no body or Neumann load it balances the Dirichlet
reaction), the Dirichlet reaction (the unconstrained residual a(u_h, v) − L(v) summed over
the Dirichlet DoFs, per component: the force the support exerts on the body), and the
measures Σ w_i of the stick, slip and separated sets (2D: lengths; the number of stick
zones, maximal runs of stick nodes along Γ_C, and their extent).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc
from dolfinx import fem

from .scene import Scene
from .solvers import Result, owned_residual

STATUS = ("separated", "stick", "slip")


def nodal_surface(scene: Scene, result: Result) -> dict:
    """Owned contact nodes: coordinates X, position, normals n_i, w, λ_n, gap and (with
    friction) λ_t (vector), ρ, slip (vector), status codes."""
    p = result.problem
    con, comm = p.constraint, scene.comm
    gdim, bs = scene.mesh.geometry.dim, p.V.dofmap.index_map_bs
    X = p.V.tabulate_dof_coordinates()[con.dofs // bs, :gdim]
    n0 = np.asarray(p.data["n"], dtype=float)
    rel = X - contact_origin(comm, X, con.sign * con.g, con.w)
    if gdim == 2:
        position = rel @ np.array([-n0[1], n0[0]])
    else:
        position = np.linalg.norm(rel - np.outer(rel @ n0, n0), axis=1)
    normals = p.data["normals"] if "normals" in p.data else np.tile(n0, (len(con.dofs), 1))
    out = {"X": X, "position": position, "normals": normals, "w": con.w}
    fr = result.friction
    if fr is not None:
        out.update(lambda_n=fr["lambda_n"], gap=fr["gap"], lambda_t=fr["lambda_t_vec"], rho=fr["rho"],
                   slip=fr["slip_vec"], status=fr["status"])
    else:
        x = p.b.duplicate()
        p.to_unknowns(result.u_h.x.petsc_vec, x)
        out.update(lambda_n=p.lambda_sign * owned_residual(result)[con.dofs] / con.w,
                   gap=con.sign * (con.g - x.array_r[con.dofs]))
        x.destroy()
    return out


def contact_origin(comm: MPI.Comm, X: np.ndarray, gap: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The first point of contact: the node of smallest initial gap, or the w-weighted
    centroid Σ w_i x_i / Σ w_i of all nodes that share it (a flat face on a plane: its centre,
    whatever the mesh), over all ranks."""
    lowest = comm.allreduce(float(gap.min(initial=np.inf)), op=MPI.MIN)
    scale = max(1.0, comm.allreduce(float(np.max(np.abs(X), initial=0.0)), op=MPI.MAX))
    tied = gap <= lowest + 1e-12 * scale
    total = comm.allreduce(w[tied] @ X[tied] if tied.any() else np.zeros(X.shape[1]), op=MPI.SUM)
    return total / comm.allreduce(float(w[tied].sum()), op=MPI.SUM)


def surface_rows(scene: Scene, result: Result) -> list[dict] | None:
    """One row per contact node, sorted by position (rank 0; None on other ranks)."""
    nodal = nodal_surface(scene, result)
    gdim = scene.mesh.geometry.dim
    cols = {"x": nodal["X"][:, 0], "y": nodal["X"][:, 1], **({"z": nodal["X"][:, 2]} if gdim == 3 else {}),
            "position": nodal["position"], "weight": nodal["w"], "lambda_n": nodal["lambda_n"], "gap": nodal["gap"]}
    if "status" in nodal:
        axes = "xyz"[:gdim]
        if gdim == 2:   # the tangential components along t_0 of the position
            t0 = np.array([-result.problem.data["n"][1], result.problem.data["n"][0]])
            cols.update(lambda_t=nodal["lambda_t"] @ t0, slip=nodal["slip"] @ t0)
        else:
            cols.update({f"lambda_t_{a}": nodal["lambda_t"][:, i] for i, a in enumerate(axes)})
            cols.update({f"slip_{a}": nodal["slip"][:, i] for i, a in enumerate(axes)})
        cols.update(lambda_t_norm=np.linalg.norm(nodal["lambda_t"], axis=1), bound=nodal["rho"],
                    slip_norm=np.linalg.norm(nodal["slip"], axis=1), status=nodal["status"].astype(float))
    names = list(cols)
    parts = scene.comm.gather(np.column_stack([cols[k] for k in names]) if len(nodal["w"]) else
                              np.zeros((0, len(names))), root=0)
    if scene.comm.rank != 0:
        return None
    data = np.vstack(parts)
    data = data[np.lexsort((np.round(data[:, 1], 12), np.round(data[:, 0], 12), np.round(data[:, names.index("position")], 12)))]
    rows = [dict(zip(names, map(float, r))) for r in data]
    for r in rows:
        if "status" in r:
            r["status"] = STATUS[int(r["status"])]
    return rows


def reaction_force(result: Result) -> np.ndarray:
    """The Dirichlet reaction per component: Σ over the Dirichlet DoFs of the unconstrained
    residual a(u_h, v) − L(v) (the force the support exerts on the body)."""
    p = result.problem
    bs = p.V.dofmap.index_map_bs
    vec = dolfinx.fem.petsc.assemble_vector(p.data["reaction_form"])
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    dofs = p.bcs[0].dof_indices()[0]
    dofs = dofs[dofs < vec.getLocalSize()]
    local = np.bincount(dofs % bs, weights=vec.array_r[dofs], minlength=bs)
    vec.destroy()
    return np.asarray(p.V.mesh.comm.allreduce(local, op=MPI.SUM))


def surface_figures(scene: Scene, result: Result) -> dict:
    """The resultants and zone measures of the module doc (collective)."""
    comm = scene.comm
    nodal = nodal_surface(scene, result)
    w, lam_n = nodal["w"], nodal["lambda_n"]

    def total(values):
        return comm.allreduce(np.asarray(values, dtype=float).sum(axis=0), op=MPI.SUM)

    contact = w[:, None] * lam_n[:, None] * nodal["normals"]
    out = {"normal_force": float(total(w * lam_n)), "reaction_force": reaction_force(result).tolist()}
    if "status" in nodal:
        tangential = w[:, None] * nodal["lambda_t"]
        contact = contact + tangential
        out["tangential_force"] = np.atleast_1d(total(tangential)).tolist()
        out["friction_ratio"] = float(np.linalg.norm(out["tangential_force"]) / max(abs(out["normal_force"]), 1e-300))
        for code, name in enumerate(STATUS):
            mine = nodal["status"] == code
            out[f"{name}_nodes"] = comm.allreduce(int(mine.sum()), op=MPI.SUM)
            out[f"{name}_measure"] = float(total(w[mine]))
        out["max_slip"] = comm.allreduce(float(np.max(np.linalg.norm(nodal["slip"], axis=1), initial=0.0)), op=MPI.MAX)
        if scene.mesh.geometry.dim == 2:
            out.update(_stick_zones(comm, nodal["position"], nodal["status"]))
    out["contact_force"] = np.atleast_1d(total(contact)).tolist()
    return out


def _stick_zones(comm: MPI.Comm, position: np.ndarray, status: np.ndarray) -> dict:
    """2D: the number of stick zones (maximal runs of stick nodes along Γ_C) and the
    positions of the first and last stick node."""
    parts = comm.allgather(np.c_[position, status])
    data = np.vstack(parts)
    data = data[np.argsort(data[:, 0], kind="stable")]
    stick = data[:, 1] == 1
    zones = int(np.sum(stick[1:] & ~stick[:-1]) + (stick[0] if len(stick) else 0))
    ends = [float(data[stick, 0].min()), float(data[stick, 0].max())] if stick.any() else []
    return {"stick_zones": zones, "stick_extent": ends}


def surface_functions(result: Result) -> list[fem.Function]:
    """Nodal fields for ParaView: λ_t and the slip increment (vectors in global axes, on the
    displacement space), the status (0 separated, 1 stick, 2 slip; −1 off Γ_C) and the
    friction bound ρ (on the scalar output space)."""
    p, fr = result.problem, result.friction
    V, con = p.V, p.constraint
    bs = V.dofmap.index_map_bs
    nodes = con.dofs // bs
    out = []
    for name, values in (("lambda_t", fr["lambda_t_vec"]), ("slip", fr["slip_vec"])):
        fn = fem.Function(V, name=name)
        fn.x.array[(nodes[:, None] * bs + np.arange(values.shape[1])).ravel()] = values.ravel()
        fn.x.scatter_forward()
        out.append(fn)
    for name, values, off in (("status", fr["status"].astype(float), -1.0), ("bound", fr["rho"], 0.0)):
        fn = fem.Function(V)
        fn.x.array[:] = off
        fn.x.array[con.dofs] = values
        fn.x.scatter_forward()
        S = p.output_space or V
        scalar = fem.Function(S, name=name)
        scalar.x.array[:] = fn.x.array if p.output_map is None else fn.x.array[p.output_map]
        out.append(scalar)
    return out
