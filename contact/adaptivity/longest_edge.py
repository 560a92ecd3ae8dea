"""``dolfinx.mesh.refine`` with a refined mesh that does not depend on the partition.

DOLFINx refines by Plaza and Carey's algorithm: an edge marked in a face marks that face's
longest edge too, and the longest edge of each face of a tetrahedron decides how the
tetrahedron is cut.  Of two edges of a face with *exactly* the same length DOLFINx takes,
in 3D, the one opposite the vertex of larger global index — and global vertex indices
depend on the partition, so the same marked cells would give other meshes on other numbers
of ranks.  Such ties are common: a mesh mirror-symmetric about a plane (gmsh meshes the
octant of a sphere symmetrically about x = y), isosceles faces on a symmetry plane, the
halves of a bisected right angle.  In 2D the tie goes to the first edge in the cell's own
vertex order, which the partition does not change.

Here DOLFINx compares lengths without ties.  A mesh with a tied face is refined with every
vertex displaced by δ(x) = ε h_min r(x), where r(x) ∈ [−1, 1)³ is a hash of the bits of the
vertex's coordinates (the same vertex, the same δ on any partition), h_min the shortest
edge of the mesh and ε = :data:`DISPLACEMENT`; a draw leaving two longest edges of a face
within a relative :data:`TIE` of each other is replaced by the next.  Then every vertex of
the refined mesh is put back where it belongs: an old vertex at its coordinates, a new one
at the midpoint (x_a + x_b)/2 of its parent edge, bit for bit as DOLFINx computes it.  The
displacement decides only between edges whose lengths agree to within about 2 ε h_min —
either is a valid longest edge — and the refined mesh is otherwise the one
``dolfinx.mesh.refine`` makes.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .transfer import creators, pull

#: the displacement, in units of the mesh's shortest edge
DISPLACEMENT = 1e-3
#: two displaced lengths closer than this (relative) count as a tie: a few units of round-off
#: (DOLFINx sums the squares in an order of its own) well inside the displacement's effect
TIE = 1e-13
#: draws of the displacement before DOLFINx's own rule decides what ties are left, with a
#: warning (a draw leaves a face of longest edge L tied with a probability of about
#: 2 TIE L / (DISPLACEMENT h_min))
DRAWS = 16

#: the ten points of a refined tetrahedron: its vertices, then its edges' midpoints
_POINTS = [[0], [1], [2], [3], [0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]


def refine(
    msh: dmesh.Mesh, edges: np.ndarray, partitioner: Any
) -> tuple[dmesh.Mesh, np.ndarray, np.ndarray]:
    """``dolfinx.mesh.refine`` of ``edges`` with parent cells and facets, whose refined mesh
    is the same on any number of ranks (collective).

    Args:
        msh: the mesh (affine simplices); its coordinates are unchanged on return.
        edges: local indices of the edges to split.
        partitioner: as ``dolfinx.mesh.refine``'s.

    Returns:
        (refined mesh, parent cell of each created cell, parent facets), as
        ``dolfinx.mesh.refine`` with ``RefinementOption.parent_cell_and_facet``.
    """
    option = dmesh.RefinementOption.parent_cell_and_facet
    shift = displacement(msh) if msh.topology.dim == 3 else None
    if shift is None:
        return dmesh.refine(msh, edges, partitioner=partitioner, option=option)
    x = msh.geometry.x
    true = x.copy()
    moved = true + shift
    try:
        x[:] = moved
        new, parent_cell, parent_facet = dmesh.refine(
            msh, edges, partitioner=partitioner, option=option
        )
    finally:
        x[:] = true
    _put_back(new, parent_cell, msh.geometry.dofmaps[0], true, moved)
    return new, parent_cell, parent_facet


def displacement(msh: dmesh.Mesh) -> np.ndarray | None:
    """δ(x) of every geometry node (the shape of ``msh.geometry.x``), the first draw that
    leaves no face with two longest edges within :data:`TIE` of each other; None if the
    mesh has no such face as it is (collective: the same answer on every rank)."""
    comm = msh.comm
    x = msh.geometry.x
    a, b = _edge_nodes(msh)
    owned = msh.topology.index_map(2).size_local
    f2e = msh.topology.connectivity(2, 1).array.reshape(-1, 3)[:owned]

    def ties(lengths: np.ndarray) -> int:  # over all ranks, each face counted by its owner
        sides = np.sort(lengths[f2e], axis=1)
        local = int(np.count_nonzero(sides[:, 2] - sides[:, 1] <= TIE * sides[:, 2]))
        return comm.allreduce(local, op=MPI.SUM)

    lengths = _lengths(x, a, b)
    if not ties(lengths):
        return None
    scale = DISPLACEMENT * comm.allreduce(float(lengths.min(initial=np.inf)), op=MPI.MIN)
    for draw in range(DRAWS):
        shift = scale * coordinate_hash(x, draw)
        left = ties(_lengths(x + shift, a, b))
        if not left:
            return shift
    if comm.rank == 0:
        warnings.warn(
            f"refinement: {left} face(s) keep two longest edges of equal length after "
            f"{DRAWS} draws; their cut may depend on the number of ranks",
            stacklevel=2,
        )
    return shift


def _edge_nodes(msh: dmesh.Mesh) -> tuple[np.ndarray, np.ndarray]:
    """The geometry nodes at the two ends of every local edge (ghosts included)."""
    top = msh.topology
    tdim = top.dim
    for dim in (1, 2):
        top.create_entities(dim)
    top.create_connectivity(2, 1)
    top.create_connectivity(1, 0)
    top.create_connectivity(tdim, 0)
    c2v = top.connectivity(tdim, 0).array.reshape(-1, tdim + 1)
    node = np.empty(top.index_map(0).size_local + top.index_map(0).num_ghosts, dtype=np.int64)
    node[c2v.ravel()] = msh.geometry.dofmaps[0].ravel()  # affine: a cell's nodes are its vertices
    e2v = top.connectivity(1, 0).array.reshape(-1, 2)
    return node[e2v[:, 0]], node[e2v[:, 1]]


def _lengths(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sqrt(((x[a] - x[b]) ** 2).sum(axis=1))


def coordinate_hash(x: np.ndarray, draw: int) -> np.ndarray:
    """r(x) ∈ [−1, 1)³ per row of ``x``: SplitMix64 of the coordinates' bits (−0.0 read as
    0.0), so equal coordinates give equal values on any rank.

    Args:
        x: points, one per row.
        draw: which of independent hashes (another draw, other values).

    Returns:
        One value in [−1, 1) per coordinate of each point, as ``x``'s shape.
    """
    bits = np.ascontiguousarray(x + 0.0).view(np.uint64)
    key = np.full(len(x), np.uint64(draw), dtype=np.uint64)
    for j in range(bits.shape[1]):
        key = _mix(key ^ bits[:, j])
    out = np.empty(x.shape)
    for j in range(x.shape[1]):
        key = _mix(key)
        out[:, j] = (key >> np.uint64(11)).astype(np.float64) * 2.0**-52 - 1.0
    return out


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64's step (Steele, Lea and Flood 2014), modulo 2⁶⁴."""
    z = z + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def _put_back(
    new: dmesh.Mesh,
    parent_cell: np.ndarray,
    old_nodes: np.ndarray,
    true: np.ndarray,
    moved: np.ndarray,
) -> None:
    """Move every geometry node of the refined mesh ``new`` from where the displaced mesh put
    it to where it belongs (collective): the rank that created a cell knows its parent, and
    the node is the parent's vertex or edge midpoint nearest to it (the ten points of a
    tetrahedron lie at least half its shortest edge apart, the displacement 10⁻³ of it)."""
    rank, index = creators(new, len(parent_cell))
    dofmap = new.geometry.dofmaps[0]
    X = new.geometry.x
    cell_of = np.empty(len(X), dtype=np.int64)  # a local cell holding each node
    cell_of[dofmap.ravel()] = np.arange(dofmap.size) // dofmap.shape[1]

    def where(i: np.ndarray, at: np.ndarray) -> np.ndarray:  # on the creating rank
        nodes = old_nodes[parent_cell[i]]
        best = np.full(len(i), np.inf)
        out = np.empty_like(at)
        for ends in _POINTS:
            # the parent's vertices, then its edges' midpoints, as displaced and as they are
            point, exact = (
                y[nodes[:, ends[0]]]
                if len(ends) == 1
                else (y[nodes[:, ends[0]]] + y[nodes[:, ends[1]]]) / 2
                for y in (moved, true)
            )
            dist = ((point - at) ** 2).sum(axis=1)
            nearer = dist < best
            best[nearer] = dist[nearer]
            out[nearer] = exact[nearer]
        return out

    X[:] = pull(new.comm, rank[cell_of], [index[cell_of], X.copy()], where, (3,), np.float64)
