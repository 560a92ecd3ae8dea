"""What refinement carries from a mesh to its refined child (``dolfinx.mesh.refine`` with
parent cells and facets): the child cells' creation order, functions (nested iteration, exact
for nested Lagrange spaces), cell tags and facet tags.  Used by the adaptive loop and by grid
sequencing through a refinement chain."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from dolfinx import fem, la
from dolfinx import mesh as dmesh


def created_cells(new: dmesh.Mesh, n_created: int) -> tuple[np.ndarray, np.ndarray]:
    """(owned local cells of the refined mesh, their index in this rank's creation order).

    ``dolfinx.mesh.refine`` lists per-child data (``parent_cell``, ``parent_facet``) in the
    order the cells were created; ``original_cell_index`` maps that global creation order to
    the new mesh's own numbering.  Cells not created on this rank are left out."""
    n_local = new.topology.index_map(new.topology.dim).size_local
    offset = new.comm.exscan(n_created) or 0  # global creation index -> this rank's list
    created = np.array(new.topology.original_cell_index[:n_local], dtype=np.int64) - offset
    ok = (created >= 0) & (created < n_created)
    return np.flatnonzero(ok), created[ok]


def prolong(u_h: fem.Function, new: dmesh.Mesh, parent_cell: np.ndarray) -> fem.Function:
    """u_h on the refined mesh ``new`` (same element): every child cell lies in its parent,
    so a node x of child cell c takes u_h evaluated in parent(c) — exact for the nested
    Lagrange spaces of refinement (u0 = u_h as functions), with no point search.

    If some owned DoF lies in no owned child cell (a partition corner case), the general
    ``interpolate_nonmatching`` (a point search through the old mesh) is used instead."""
    V = fem.functionspace(new, u_h.function_space.ufl_element())
    u0 = fem.Function(V, name="u0")
    cells, created = created_cells(new, len(parent_cell))
    cell_dofs = V.dofmap.list[cells]
    dofs, first = np.unique(cell_dofs.ravel(), return_index=True)
    n_owned = V.dofmap.index_map.size_local
    if new.comm.allreduce(int(np.count_nonzero(dofs < n_owned)) < n_owned, op=MPI.LOR):
        tdim = new.topology.dim
        all_cells = np.arange(new.topology.index_map(tdim).size_local + new.topology.index_map(tdim).num_ghosts,
                              dtype=np.int32)
        u0.interpolate_nonmatching(u_h, all_cells, fem.create_interpolation_data(V, u_h.function_space, all_cells))
        return u0
    parents = np.repeat(parent_cell[created], cell_dofs.shape[1])[first].astype(np.int32)
    values = u_h.eval(V.tabulate_dof_coordinates()[dofs], parents)       # (n, bs)
    bs = V.dofmap.index_map_bs
    u0.x.array[(dofs[:, None] * bs + np.arange(bs)).ravel()] = values.reshape(len(dofs), bs).ravel()
    u0.x.scatter_forward()
    return u0


def transfer_cell_tags(tags: dmesh.MeshTags, new: dmesh.Mesh, parent_cell: np.ndarray) -> dmesh.MeshTags:
    """Cell tags on the refined mesh, on every local cell (ghosts included): a child cell
    inherits its parent's value (the owners set theirs, the ghosts receive them)."""
    tdim = new.topology.dim
    old_value = np.zeros(tags.topology.index_map(tdim).size_local + tags.topology.index_map(tdim).num_ghosts)
    old_value[tags.indices] = tags.values
    imap = new.topology.index_map(tdim)
    vec = la.vector(imap, 1)
    cells, created = created_cells(new, len(parent_cell))
    vec.array[cells] = old_value[parent_cell[created]]
    vec.scatter_forward()
    n_all = imap.size_local + imap.num_ghosts
    return dmesh.meshtags(new, tdim, np.arange(n_all, dtype=np.int32), np.rint(vec.array[:n_all]).astype(np.int32))


def transfer_facet_tags(tags: dmesh.MeshTags, new: dmesh.Mesh, parent_cell: np.ndarray,
                        parent_facet: np.ndarray) -> dmesh.MeshTags:
    """Facet tags on the refined mesh: a child facet inherits the tag of the parent facet it
    lies in.  (``dolfinx.mesh.transfer_meshtag`` refuses ghosted meshes, and the estimator's
    interior-facet integrals need ghosts; this is the same rule, vectorised in NumPy.)

    ``parent_facet[c * nf + j]`` is the parent cell's local facet containing local facet j
    of child cell c, or −1 for facets inside the parent; c counts cells in the order they
    were created, which the new mesh's ``original_cell_index`` maps to its own numbering.
    """
    old = tags.topology
    tdim = new.topology.dim
    old_c2f = old.connectivity(tdim, tdim - 1)
    new.topology.create_connectivity(tdim, tdim - 1)
    new_c2f = new.topology.connectivity(tdim, tdim - 1)
    nf = len(new_c2f.links(0)) if new_c2f.num_nodes else tdim + 1
    old_value = np.full(old.index_map(tdim - 1).size_local + old.index_map(tdim - 1).num_ghosts, -1, dtype=np.int32)
    old_value[tags.indices] = tags.values
    n_new = len(parent_cell)
    pf = np.asarray(parent_facet, dtype=np.int64).reshape(n_new, nf)
    cells, created = created_cells(new, n_new)
    child, local = np.nonzero(pf[created] >= 0)
    parents = old_c2f.array.reshape(-1, nf)[parent_cell[created[child]], pf[created[child], local]]
    values = old_value[parents]
    new_facets = new_c2f.array.reshape(-1, nf)[cells[child], local]
    keep = values >= 0
    facets, first = np.unique(new_facets[keep], return_index=True)
    return dmesh.meshtags(new, tdim - 1, facets.astype(np.int32), values[keep][first].astype(np.int32))
