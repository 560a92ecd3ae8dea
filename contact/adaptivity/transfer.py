"""What refinement carries from a mesh to its refined child (``dolfinx.mesh.refine`` with
parent cells and facets): functions (nested iteration, exact for nested Lagrange spaces),
cell tags and facet tags.  Used by the adaptive loop and by grid sequencing through a
refinement chain.

Who knows a child's parent: ``dolfinx.mesh.refine`` creates each child cell on its parent's
rank and lists per-child data (``parent_cell``, ``parent_facet``) there, in creation order.
The partitioner then decides where the child lives: the identity partitioner keeps it on
the creating rank, a graph partitioner may move it (to rebalance the work).  Either way the
new mesh's ``original_cell_index`` is the child's global creation index, so every rank can
name the creating rank of each of its cells and *pull* what it needs from there
(:func:`pull`: one ``Alltoallv`` out, one back).  With the identity partitioner every
request is local."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..base import spaces

#: facet tags: only the children of parents with a tagged facet look their facets up;
#: False: every child, the plain path (the same tags)
TAGGED_PARENTS_ONLY = True
#: on one rank ``pull`` answers the requests in place (every creating rank is this one);
#: False: through the two ``Alltoallv`` as on many ranks, the old path (the same replies)
LOCAL_PULL = True
#: ``prolong`` takes its space and DoF points from ``contact.base.spaces`` (made once per
#: mesh: the level built next on the refined mesh finds them); False: a space and points of
#: its own, the old path (the same values)
SHARED_SPACE = True


def creators(new: dmesh.Mesh, n_created: int) -> tuple[np.ndarray, np.ndarray]:
    """(creating rank, index in that rank's creation list) of every local cell of the
    refined mesh ``new``, ghosts included; ``n_created`` = ``len(parent_cell)`` on this
    rank.  Collective."""
    # global creation index of each rank's first
    offsets = np.cumsum([0, *new.comm.allgather(int(n_created))])
    g = np.asarray(new.topology.original_cell_index, dtype=np.int64)
    rank = np.searchsorted(offsets, g, side="right") - 1
    return rank, g - offsets[rank]


def _exchange(
    comm: MPI.Comm, rows: np.ndarray, counts: np.ndarray, rcounts: np.ndarray
) -> np.ndarray:
    """Alltoallv of ``rows`` (grouped by destination, ``counts[r]`` rows to rank r);
    returns the ``rcounts.sum()`` rows received, grouped by source."""
    rows = np.ascontiguousarray(rows)
    width = int(np.prod(rows.shape[1:], dtype=np.int64))
    out = np.empty((int(rcounts.sum()), *rows.shape[1:]), dtype=rows.dtype)
    comm.Alltoallv([rows, counts * width], [out, rcounts * width])
    return out


def pull(
    comm: MPI.Comm,
    dest: np.ndarray,
    requests: list[np.ndarray],
    answer: Callable[..., np.ndarray],
    shape: tuple[int, ...],
    dtype: type,
) -> np.ndarray:
    """Row i of each array of ``requests`` goes to rank ``dest[i]``, which replies
    ``answer(*received)`` (one row of ``shape`` and ``dtype`` per request); returns the
    replies in the order of the requests.  Collective."""
    if LOCAL_PULL and comm.size == 1:  # every request is this rank's: answered in place
        if not len(dest):
            return np.empty((0, *shape), dtype=dtype)
        return np.asarray(answer(*requests), dtype=dtype).reshape(-1, *shape)
    order = np.argsort(dest, kind="stable")
    counts = np.bincount(dest, minlength=comm.size).astype(np.int64)
    rcounts = np.asarray(comm.alltoall(counts.tolist()), dtype=np.int64)
    received = [_exchange(comm, a[order], counts, rcounts) for a in requests]
    reply = np.asarray(answer(*received) if rcounts.sum() else np.empty((0, *shape)), dtype=dtype)
    back = _exchange(comm, reply.reshape(-1, *shape), rcounts, counts)
    out = np.empty_like(back)
    out[order] = back
    return out


def prolong(u_h: fem.Function, new: dmesh.Mesh, parent_cell: np.ndarray) -> fem.Function:
    """u_h on the refined mesh ``new`` (same element): every child cell lies in its parent,
    so a node x of child cell c takes u_h evaluated in parent(c) on c's creating rank —
    exact for the nested Lagrange spaces of refinement (u0 = u_h as functions), with no
    point search.  Each owned DoF asks once, through one local cell (ghosts
    included) that holds it (any one: only a continuous space shares DoFs between cells)."""
    element = u_h.function_space.ufl_element()
    V = spaces.functionspace(new, element) if SHARED_SPACE else fem.functionspace(new, element)
    u0 = fem.Function(V, name="u0")
    rank, index = creators(new, len(parent_cell))
    cell_dofs = V.dofmap.list
    cell_of = np.full(
        V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts, -1, dtype=np.int64
    )
    # a cell holding it
    cell_of[cell_dofs.ravel()] = np.repeat(np.arange(len(cell_dofs)), cell_dofs.shape[1])
    dofs = np.flatnonzero(cell_of[: V.dofmap.index_map.size_local] >= 0)
    cell = cell_of[dofs]
    bs = V.dofmap.index_map_bs

    def evaluate(i: np.ndarray, x: np.ndarray) -> np.ndarray:  # on the creating rank
        return u_h.eval(x, parent_cell[i].astype(np.int32))

    values = pull(
        new.comm,
        rank[cell],
        [
            index[cell],
            (spaces.dof_coordinates(V) if SHARED_SPACE else V.tabulate_dof_coordinates())[dofs],
        ],
        evaluate,
        (bs,),
        np.float64,
    )
    u0.x.array[(dofs[:, None] * bs + np.arange(bs)).ravel()] = values.ravel()
    u0.x.scatter_forward()
    return u0


def transfer_cell_tags(
    tags: dmesh.MeshTags, new: dmesh.Mesh, parent_cell: np.ndarray
) -> dmesh.MeshTags:
    """Cell tags on the refined mesh, on every local cell (ghosts included): a child cell
    inherits its parent's value."""
    tdim = new.topology.dim
    old_value = np.zeros(
        tags.topology.index_map(tdim).size_local + tags.topology.index_map(tdim).num_ghosts,
        dtype=np.int32,
    )
    old_value[tags.indices] = tags.values
    rank, index = creators(new, len(parent_cell))
    values = pull(new.comm, rank, [index], lambda i: old_value[parent_cell[i]], (), np.int32)
    return dmesh.meshtags(new, tdim, np.arange(len(values), dtype=np.int32), values)


def transfer_facet_tags(
    tags: dmesh.MeshTags, new: dmesh.Mesh, parent_cell: np.ndarray, parent_facet: np.ndarray
) -> dmesh.MeshTags:
    """Facet tags on the refined mesh: a child facet inherits the tag of the parent facet it
    lies in; the facets of the owned cells are tagged.  (``dolfinx.mesh.transfer_meshtag``
    refuses ghosted meshes, and the estimator's interior-facet integrals need ghosts; this
    is the same rule, vectorised in NumPy.)

    ``parent_facet[c * nf + j]`` is the parent cell's local facet containing local facet j
    of child cell c, or −1 for facets inside the parent; c counts the cells in the order
    their rank created them (refinement keeps a cell's vertex order, so its local facet j
    is the same wherever the partitioner puts it)."""
    old = tags.topology
    tdim = new.topology.dim
    old_c2f = old.connectivity(tdim, tdim - 1)
    nf = tdim + 1  # simplices
    old_value = np.full(
        old.index_map(tdim - 1).size_local + old.index_map(tdim - 1).num_ghosts, -1, dtype=np.int32
    )
    old_value[tags.indices] = tags.values
    pf = np.asarray(parent_facet, dtype=np.int64).reshape(-1, nf)
    old_facets = old_c2f.array.reshape(-1, nf)

    # the parents with a tagged facet: only their children can inherit a tag
    tagged = np.any(old_value[old_facets] >= 0, axis=1) if TAGGED_PARENTS_ONLY else None

    def parent_tags(i: np.ndarray) -> np.ndarray:  # on the creating rank: (n, nf)
        if tagged is None:
            local = pf[i]
            facets = np.take_along_axis(old_facets[parent_cell[i]], np.maximum(local, 0), axis=1)
            return np.where(local >= 0, old_value[facets], -1)
        out = np.full((len(i), nf), -1, dtype=np.int32)
        hit = np.flatnonzero(tagged[parent_cell[i]])
        local = pf[i[hit]]
        facets = np.take_along_axis(old_facets[parent_cell[i[hit]]], np.maximum(local, 0), axis=1)
        out[hit] = np.where(local >= 0, old_value[facets], -1)
        return out

    n_owned = new.topology.index_map(tdim).size_local
    rank, index = creators(new, len(parent_cell))
    values = pull(new.comm, rank[:n_owned], [index[:n_owned]], parent_tags, (nf,), np.int32)
    new.topology.create_connectivity(tdim, tdim - 1)
    new_facets = new.topology.connectivity(tdim, tdim - 1).array.reshape(-1, nf)[:n_owned]
    keep = values >= 0
    facets, first = np.unique(new_facets[keep], return_index=True)
    return dmesh.meshtags(new, tdim - 1, facets.astype(np.int32), values[keep][first])
