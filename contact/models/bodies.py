"""Several elastic bodies in one mesh, in contact through mortar pairs (docs/theory.md §1.5).

The bodies are the disconnected components of one DOLFINx mesh, told apart by the cell
tags of :func:`contact.setup.meshes.tag_bodies`; one vector P1 space carries them all, so the
elastic assembly of :mod:`contact.models.elasticity` applies unchanged with Lamé
parameters that are DG0 functions (E_k, ν_k of body k).  Each pair of ``pairs`` couples a
slave surface to a master surface (:mod:`contact.models.mortar`); with the change of
basis u = Q x of :mod:`contact.models.basis`,

    K̃ = Qᵀ K Q,   b̃ = Qᵀ b,   x_{i,n} ≤ g_i  (slave node i),   λ_i = R̃_i / D_ii,

where the Dirichlet and symmetry conditions are imposed again on the unknowns x (a master
node's fixed component is coupled into the slave rows; ``zeroRowsColumns`` with the
prescribed values lifts it), so every solver applies unchanged: the problem is a bound on
single unknowns.  A rigid obstacle may take part too (its contact nodes rotated to their
(n, t) frames, :func:`obstacle_nodes`), and friction (:mod:`contact.models.friction`) acts on
the tangential unknowns of the same frames: for a slave node, its slip relative to the
master.  Units: E in Pa (any consistent unit), λ a pressure, D_ii a length (2D) or an area
(3D).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from ..base.lifetime import destroy
from ..setup.checks import check_scene_data
from ..setup.scene import Scene
from ..solvers.floating import floating_bodies
from ..solvers.problem import Constraint, DiscreteProblem
from . import mortar
from .basis import change_of_basis, node_frames
from .elasticity import elastic_system, lame, reaction_form, rigid_body_modes
from .problem import contact_ends, coordinate_scale


def materials(scene: Scene) -> tuple[fem.Function, fem.Function, fem.Function]:
    """DG0 Lamé parameters μ, λ_L of each cell's body and the DG0 ``body`` number (1, 2, …
    in the order of the bodies section; the output tells the bodies apart by it)."""
    msh, tags = scene.mesh, scene.bodies
    assert tags is not None  # a scene of several bodies has its body tags
    W = fem.functionspace(msh, ("DG", 0))
    mu, lmbda_L, body = (fem.Function(W, name=name) for name in ("mu", "lmbda_L", "body"))
    bodies = scene.config.bodies
    assert bodies is not None  # a scene with bodies
    values = [lame(b.E, b.nu) for b in bodies.values()]
    k = tags.values - 1
    dofs = W.dofmap.list[tags.indices].ravel()
    mu.x.array[dofs] = np.array([v[0] for v in values])[k]
    lmbda_L.x.array[dofs] = np.array([v[1] for v in values])[k]
    body.x.array[dofs] = tags.values
    return mu, lmbda_L, body


def bodies_problem(scene: Scene) -> DiscreteProblem:
    """The multi-body contact problem of ``scene``: elasticity with one material per body,
    mortar pairs (and a rigid obstacle's nodes) as the change of basis u = Q x."""
    t0 = time.perf_counter()
    check_scene_data(scene)  # every datum finite where it is used (ConfigError)
    mu, lmbda_L, body = materials(scene)
    system = elastic_system(scene, mu, lmbda_L)
    V, K, b = system.V, system.K, system.b
    bs = V.dofmap.index_map_bs
    mortar.check_disjoint(scene, V)
    couplings = [
        mortar.couple(scene, V, i, system.fixed) for i in range(len(scene.config.pairs or []))
    ]
    rigid = obstacle_nodes(scene, V, system) if scene.config.obstacle else None
    sets = couplings + ([rigid] if rigid is not None else [])

    nodes = np.concatenate([c.nodes for c in sets]).astype(np.int32)
    offsets = np.cumsum([0] + [len(c.nodes) for c in couplings])
    frames = np.concatenate([c.frames for c in sets]).reshape(-1, bs, bs)
    projectors = np.concatenate([c.projectors for c in sets]).reshape(-1, bs, bs)
    coupling = (
        np.concatenate([c.rows + o for c, o in zip(couplings, offsets)] + [np.zeros(0, int)]),
        np.concatenate([c.cols for c in couplings] + [np.zeros(0, int)]),
        np.concatenate([c.c for c in couplings] + [np.zeros(0)]),
    )
    Q, Q_inv = change_of_basis(V, K, nodes, frames, coupling, projectors)
    Kt = K.PtAP(Q)  # K̃ = Qᵀ K Q
    bt = b.duplicate()
    Q.multTranspose(b, bt)  # b̃ = Qᵀ b
    destroy(K, b)
    bcs = dirichlet_on_unknowns(
        V, system.bcs, nodes, frames, [a for c in sets for a in c.absolute], Kt, bt
    )

    u_h = fem.Function(V, name="u_h")
    S, collapsed = V.sub(0).collapse()
    s_to_v = np.asarray(collapsed, dtype=np.int32).ravel()
    v_to_s = np.empty(len(s_to_v), dtype=np.int32)
    v_to_s[s_to_v // bs] = np.arange(len(s_to_v), dtype=np.int32)
    gap = np.concatenate([c.gap for c in sets])
    on = la.vector(V.dofmap.index_map, 2)  # (slave marker, bound) per node
    on.array.reshape(-1, 2)[nodes] = np.c_[np.ones(len(nodes)), gap]
    on.scatter_forward()
    marker, bound_nodes = on.array.reshape(-1, 2).T
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = bound_nodes[s_to_v // bs]
    slave_nodes = np.flatnonzero(marker > 0)
    ends = np.concatenate([c.ends for c in sets]).astype(np.int32)
    end_dofs, end_neighbours = contact_ends(
        V, (ends * bs).astype(np.int32), np.concatenate([slave_nodes, ends]) * bs, ends * bs
    )
    con = Constraint(
        (nodes * bs).astype(np.int32),
        gap,
        np.concatenate([c.D for c in sets]),
        1.0,
        coordinate_scale(scene.mesh),
    )
    normals = np.concatenate([c.normals for c in sets])
    pair_nodes = int(offsets[-1])  # the first pair_nodes constrained nodes are slave nodes
    X = V.tabulate_dof_coordinates()[nodes, : scene.mesh.geometry.dim]
    on_pairs = slice(0, pair_nodes) if couplings else slice(None)
    mirrors = tuple(sorted(symmetry_axes(scene, X[on_pairs])))
    data = {
        **system.data,
        **(rigid.data if rigid is not None else {}),
        "reaction_form": reaction_form(system, u_h),
        "u_bcs": system.bcs,
        "body": body,
        "couplings": couplings,
        "normals": normals,
        "frames": frames,
        "pair_nodes": pair_nodes,
        # the contact normal at the first point of contact (of the pairs, if any)
        "n": first_contact_normal(scene.comm, X[on_pairs], gap[on_pairs], normals[on_pairs]),
    }
    return BodiesProblem(
        V,
        u_h,
        bcs,
        Kt,
        bt,
        con,
        data=data,
        end_dofs=end_dofs,
        end_neighbours=end_neighbours,
        output_space=S,
        output_map=s_to_v,
        output_bound=bound,
        lambda_sign=1.0,
        basis=Q,
        basis_inverse=Q_inv,
        output_nodes=v_to_s[slave_nodes],
        symmetric_copies=2 ** len(mirrors),
        symmetry_axes=mirrors,
        near_nullspace=rigid_body_modes(V, inverse=Q_inv),
        floating=floating_bodies(V, system.fixed, scene.bodies, list(scene.config.bodies or ())),
        assembly_time=time.perf_counter() - t0,
    )


class BodiesProblem(DiscreteProblem):
    """The multi-body problem: its contact force is the one the pairs transmit (the slave
    nodes' pressures; an obstacle's nodes, if any, are left out)."""

    def contact_force(self, r: np.ndarray) -> float:
        """F = m_n Σ_{slave i} D_ii p_i (n_i · n) over all ranks (collective): p_i = −λ_i
        the interface pressure, n the normal at the first point of contact, m_n the mirror
        images pressing along n (:meth:`DiscreteProblem.copies_along`;
        :meth:`DiscreteProblem.contact_force` over all nodes without pairs)."""
        if not self.data["couplings"]:
            return super().contact_force(r)
        on = slice(0, self.data["pair_nodes"])
        local = float(
            np.sum(
                self.constraint.w[on]
                * self.pressure(r)[on]
                * (self.data["normals"][on] @ self.data["n"])
            )
        )
        return self.copies_along() * self.V.mesh.comm.allreduce(local, op=MPI.SUM)


def first_contact_normal(
    comm: MPI.Comm, X: np.ndarray, gap: np.ndarray, normals: np.ndarray
) -> np.ndarray:
    """The contact normal at the first point of contact (the node with the smallest initial
    gap, ties broken by coordinates: :func:`~contact.models.obstacles.first_contact_point`),
    the same on every rank."""
    from .obstacles import first_contact_row

    return first_contact_row(comm, X, gap, normals)


def symmetry_axes(scene: Scene, X: np.ndarray) -> set[int]:
    """The coordinate axes k of the symmetry planes x_k = c that pass through a contact node
    (rows of X, this rank's): the planes that mirror the contact zone, each counted once
    however many bodies it cuts (a support plane away from the interface is not one)."""
    from .elasticity import _facet_normal_axis

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


@dataclass
class ObstacleNodes:
    """The rigid obstacle's contact nodes in a multi-body scene (owned, constrained), with
    the fields a mortar :class:`~contact.models.mortar.Coupling` has for its slave nodes."""

    nodes: np.ndarray
    D: np.ndarray  # lumped weights w_i = ∫_{Γ_C} φ_i ds
    normals: np.ndarray
    frames: np.ndarray
    projectors: np.ndarray
    absolute: list
    gap: np.ndarray
    ends: np.ndarray
    data: dict


def obstacle_nodes(scene: Scene, V: fem.FunctionSpace, system) -> ObstacleNodes:
    """The obstacle's contact nodes rotated to their (n, t) frames (symmetry-fixed
    components kept as absolute axes, as for slave nodes), none of them a node of a pair."""
    from ..base.errors import ConfigError
    from .obstacles import _contact_nodes, first_contact_point, obstacle_shape
    from .problem import lumped_weights

    normal, gap_of, n_ufl, g_ufl = obstacle_shape(scene)
    bs, gdim, comm = V.dofmap.index_map_bs, scene.mesh.geometry.dim, scene.comm
    S, _, v_dofs, s_dofs = _contact_nodes(V, 0, scene.boundary.facets("contact"))
    nodes = v_dofs // bs
    owned = nodes < V.dofmap.index_map.size_local
    nodes, s_dofs = nodes[owned], s_dofs[owned]
    fixed = np.isin(nodes[:, None] * bs + np.arange(bs), system.fixed)
    full = fixed.all(axis=1)
    X = S.tabulate_dof_coordinates()[:, :gdim]
    g = gap_of(X[s_dofs])
    if comm.allreduce(
        int(np.sum(g[~full] < -1e-12 * max(1.0, float(np.max(np.abs(X), initial=0.0))))), op=MPI.SUM
    ):
        raise ConfigError("obstacle: contact nodes lie inside the obstacle (negative initial gap)")
    n, frames, projectors, absolute, bad = node_frames(normal(X[s_dofs[~full]]), fixed[~full], bs)
    if comm.allreduce(int(bad.sum()), op=MPI.SUM):
        raise ConfigError(
            "obstacle: a contact node has a symmetry condition along the obstacle's normal"
        )
    w = lumped_weights(S, system.data["ds"](scene.boundary.ids_with_role("contact")))[s_dofs[~full]]
    first = first_contact_point(comm, X[s_dofs], g)
    return ObstacleNodes(
        nodes[~full],
        w,
        n,
        frames,
        projectors,
        absolute,
        g[~full],
        nodes[full],
        {"n": normal(first[None, :])[0], "n_ufl": n_ufl, "g_ufl": g_ufl},
    )


def dirichlet_on_unknowns(
    V: fem.FunctionSpace,
    bcs: list,
    nodes: np.ndarray,
    frames: np.ndarray,
    absolute: list,
    Kt: PETSc.Mat,
    bt: PETSc.Vec,
) -> list:
    """The Dirichlet and symmetry conditions as conditions on the unknowns x = Q⁻¹ u, imposed
    on K̃ and b̃ (rows and columns identity, the prescribed values lifted into b̃), and
    returned as DirichletBCs on x (one per component) for the solvers' initial guess.

    A fixed component u_k of a slave node whose frame keeps e_k as its axis 1 + m
    (``absolute``) is the unknown x_{1+m} = ±u_k; every other fixed DoF keeps its index
    (Q's row there is the identity).  Only owned DoFs are listed."""
    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local * bs
    values = fem.Function(V)
    for bc in bcs:
        bc.set(values.x.array)
    fixed = np.unique(np.concatenate([bc.dof_indices()[0] for bc in bcs]))
    fixed = fixed[fixed < n_owned]
    x_values = np.zeros(n_owned)
    is_fixed = np.zeros(n_owned, dtype=bool)
    is_fixed[fixed] = True
    x_values[fixed] = values.x.array[fixed]
    for node, R, axes in zip(nodes, frames, absolute):
        if not axes:
            continue
        block = slice(node * bs, node * bs + bs)
        u_fixed = np.where(is_fixed[block], values.x.array[block], 0.0)
        is_fixed[block] = False
        x_values[block] = 0.0
        for m in range(len(axes)):
            is_fixed[node * bs + 1 + m] = True
            x_values[node * bs + 1 + m] = R[:, 1 + m] @ u_fixed
    dofs = np.flatnonzero(is_fixed).astype(np.int32)
    xbar = bt.duplicate()
    xbar.set(0.0)
    xbar.array_w[dofs] = x_values[dofs]
    lo = bt.getOwnershipRange()[0]
    Kt.zeroRowsColumns((lo + dofs).astype(PETSc.IntType), diag=1.0, x=xbar, b=bt)  # type: ignore[arg-type]
    xbar.destroy()
    return [_component_bc(V, k, dofs[dofs % bs == k], x_values) for k in range(bs)]


def _component_bc(
    V: fem.FunctionSpace, k: int, dofs: np.ndarray, values: np.ndarray
) -> fem.DirichletBC:
    """x_j = values[j] on the (unrolled, owned) DoFs ``dofs`` of component k, as a DirichletBC
    on V.sub(k): ``fem.dirichletbc(g, dofs)`` on the blocked V would read the indices as
    node (block) numbers and fix other DoFs."""
    S, collapsed = V.sub(k).collapse()
    imap = V.dofmap.index_map
    n = (imap.size_local + imap.num_ghosts) * V.dofmap.index_map_bs
    v_to_s = np.full(n, -1, dtype=np.int32)
    s_to_v = np.asarray(collapsed, dtype=np.int32).ravel()
    v_to_s[s_to_v] = np.arange(len(s_to_v), dtype=np.int32)
    g = fem.Function(S)
    g.x.array[v_to_s[dofs]] = values[dofs]
    return fem.dirichletbc(g, [dofs.astype(np.int32), v_to_s[dofs]], V.sub(k))  # type: ignore[arg-type]
