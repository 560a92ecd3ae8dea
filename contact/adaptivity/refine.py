"""REFINE (docs/theory.md §6): refine the marked cells and carry a domain over.

The marked cells' edges refined (``dolfinx.mesh.refine``), a :class:`Domain` carried to the
new mesh (its tags and functions, the nested-iteration guess, curved boundaries snapped to
their exact surfaces), and the refined mesh's partition.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from mpi4py import MPI

from . import longest_edge
from .transfer import prolong, transfer_cell_tags, transfer_facet_tags


@dataclass
class Domain:
    """A mesh and what refinement carries from it to its refined children.

    Args:
        mesh: the mesh.
        facets: facet tags (the boundary parts a problem's measures read), or None.
        cells: cell tags (bodies, materials), or None.
        tags: more facet tags carried along by name (e.g. the curved surfaces a mesh
            generator tagged).
        functions: functions on the mesh carried along by prolongation (e.g. a load step's
            previous displacement).
        snap: called after each refinement as ``snap(parent, child)``: moves the child's new
            boundary vertices onto exact surfaces (None: they stay at edge midpoints).
        parent: (the domain this one was refined from, the parent cell of each new cell),
            or None: the coarser domains grid sequencing may solve on first.

    Example:
        >>> import contact, numpy as np
        >>> from dolfinx import mesh
        >>> from mpi4py import MPI
        >>> domain = contact.Domain(mesh.create_unit_square(MPI.COMM_WORLD, 4, 4))
        >>> owned = domain.mesh.topology.index_map(2).size_local
        >>> fine, _ = contact.refine(domain, np.arange(owned, dtype=np.int32))
        >>> fine.mesh.topology.index_map(2).size_global, fine.parent[0] is domain
        (128, True)
    """

    mesh: dmesh.Mesh
    facets: dmesh.MeshTags | None = None
    cells: dmesh.MeshTags | None = None
    tags: dict[str, dmesh.MeshTags] = field(default_factory=dict)
    functions: dict[str, fem.Function] = field(default_factory=dict)
    snap: Callable[[Domain, Domain], None] | None = None
    parent: tuple[Domain, np.ndarray] | None = None

    @property
    def comm(self) -> MPI.Comm:
        """The mesh's communicator."""
        return self.mesh.comm


def incident_edges(msh: dmesh.Mesh, cells: np.ndarray) -> np.ndarray:
    """Return the local edges of the local cells ``cells``, the mesh's edges made if need be.

    What :func:`refine` splits and :func:`next_dofs_bound` counts: a caller that needs both
    (the adaptive loop) finds them once and hands them to each.

    Args:
        msh: the mesh.
        cells: local cell indices.

    Returns:
        The local indices of the edges of these cells, each once (int32).
    """
    msh.topology.create_entities(1)
    cells = np.asarray(cells, dtype=np.int32)
    return dmesh.compute_incident_entities(msh.topology, cells, msh.topology.dim, 1)


#: the refusal to refine curved cells: dolfinx's refinement splits the vertex simplices
#: and knows nothing of the edge nodes of a quadratic geometry
CURVED_CELLS = (
    "adapt.max_levels: curved cells (mesh.geometry_degree: 2) are not refined; use 1 "
    "(a single level) or mesh.geometry_degree: 1"
)


def refine(
    domain: Domain,
    cells: np.ndarray,
    u_h: fem.Function | None = None,
    rebalance: bool = True,
    *,
    timings: dict[str, float] | None = None,
    edges: np.ndarray | None = None,
) -> tuple[Domain, fem.Function | None]:
    """Refine the marked cells and carry the domain over (the REFINE step).

    Refine the marked cells' edges (conforming, ``dolfinx.mesh.refine``), carry the
    domain's tags to the new mesh, interpolate ``u_h`` onto it (nested iteration), prolong
    the domain's functions, and snap the new boundary vertices (:attr:`Domain.snap`).

    The interpolation comes first: it evaluates u_h at the new nodes where dolfinx put
    them, inside the old mesh; a snapped node then keeps that value (u0(π(x)) = u_h(x),
    the surface shifts by at most the sagitta h²/(8R) of the old edge). Collective.

    The refined mesh does not depend on the number of ranks: a face's longest edge among
    edges of equal length is chosen by the coordinates, not by DOLFINx's
    partition-dependent vertex numbers (:mod:`.longest_edge`).

    Args:
        domain: the domain to refine.
        cells: owned local cell indices to refine (as :func:`~.mark.mark` returns them).
        u_h: a function on the domain's mesh to carry over (nested iteration), or None.
        rebalance: in parallel, redistribute the refined mesh evenly over the ranks
            (:func:`refine_partitioner`; the mesh itself does not depend on it).
        timings: if given, receives the seconds of the parts: ``mesh`` (the marked edges
            and ``dolfinx.mesh.refine`` with the redistribution and the ghost layer),
            ``transfer`` (tags and functions carried over) and ``snap``.
        edges: the marked cells' edges, :func:`incident_edges` of ``cells``, where the
            caller has found them already (else found here).

    Returns:
        (the refined domain, u_h on it or None).  Cells that are not owned indices, or a
        ``u_h`` on another mesh, are a ValueError (on every rank), and so is a mesh of
        curved cells (a coordinate element of degree > 1: :data:`CURVED_CELLS`).
    """
    if domain.mesh.geometry.cmaps[0].degree > 1:
        raise ValueError(CURVED_CELLS)
    cells = _owned_cells(domain, cells)
    if u_h is not None and (
        not isinstance(u_h, fem.Function) or u_h.function_space.mesh is not domain.mesh
    ):
        raise ValueError("u_h: expected a dolfinx.fem.Function on the domain's mesh")
    if not isinstance(rebalance, bool):
        raise ValueError(f"rebalance: expected true or false, got {rebalance!r}")
    msh = domain.mesh
    tdim = msh.topology.dim
    clock = [time.perf_counter()]  # the start, then the end of each part
    if edges is None:
        edges = incident_edges(msh, cells)
    new, parent_cell, parent_facet = longest_edge.refine(
        msh, edges, refine_partitioner(msh, rebalance)
    )
    clock.append(time.perf_counter())
    new.topology.create_entities(tdim - 1)
    new.topology.create_connectivity(tdim - 1, tdim)

    def facet_tags(tags: dmesh.MeshTags) -> dmesh.MeshTags:
        return transfer_facet_tags(tags, new, parent_cell, parent_facet)

    child = Domain(
        new,
        None if domain.facets is None else facet_tags(domain.facets),
        None if domain.cells is None else transfer_cell_tags(domain.cells, new, parent_cell),
        {name: facet_tags(tags) for name, tags in domain.tags.items()},
        {name: prolong(fn, new, parent_cell) for name, fn in domain.functions.items()},
        domain.snap,
        (domain, parent_cell),
    )
    u0 = None if u_h is None else prolong(u_h, new, parent_cell)
    clock.append(time.perf_counter())
    if domain.snap is not None:
        domain.snap(domain, child)
    clock.append(time.perf_counter())
    if timings is not None:
        timings.update(zip(("mesh", "transfer", "snap"), np.diff(clock).tolist()))
    return child, u0


def next_dofs_bound(
    msh: dmesh.Mesh, cells: np.ndarray, V: fem.FunctionSpace, edges: np.ndarray | None = None
) -> int | None:
    """Return a lower bound of the DoFs after refining ``cells``.

    P1: one new vertex per marked edge (refinement may split more edges for conformity);
    None for P2.  An edge counts once, on its owning rank, whichever rank's cells marked it
    (the same bound on any number of ranks).  ``edges``: the cells' edges
    (:func:`incident_edges`) where the caller has found them already.
    """
    if V.element.basix_element.degree != 1:
        return None
    if edges is None:
        edges = incident_edges(msh, cells)
    imap = msh.topology.index_map(1)
    marked = la.vector(imap, dtype=np.int32)
    marked.array[edges] = 1
    marked.scatter_reverse(la.InsertMode.add)  # ghost edges' marks to their owners
    owned = int(np.count_nonzero(marked.array[: imap.size_local]))
    vertices = msh.topology.index_map(0).size_global
    return V.dofmap.index_map_bs * (vertices + msh.comm.allreduce(owned, op=MPI.SUM))


def refine_partitioner(msh: dmesh.Mesh, rebalance: bool = True) -> Any:
    """``dolfinx.mesh.refine``'s partitioner.

    * serial: ``None`` (no ghost layer to build: 40 % faster; demos/RESULTS.md §10);
    * parallel, ``rebalance``: dolfinx's graph partitioner, which spreads the refined mesh
      evenly over the ranks — refinement concentrated in one rank's part of the domain
      would otherwise leave that rank with most of the work (problem A: 1.15× its share
      of the DoFs at 1.23M; hertz_3d 1.30× at 865k);
    * parallel, not ``rebalance``: the identity partitioner (children stay on their parent's
      rank).

    Both parallel ones rebuild the ghost layer the estimator's interior-facet jumps need.
    """
    if msh.comm.size == 1:
        return None
    if rebalance:
        return dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet, 2)  # type: ignore[call-arg]
    return dmesh.IdentityPartitionerPlaceholder()


def _owned_cells(domain: Domain, cells: Any) -> np.ndarray:
    """``cells`` as int32 owned local cell indices; ValueError (collective) otherwise."""
    arr = np.asarray(cells)
    comm = domain.comm
    n_owned = domain.mesh.topology.index_map(domain.mesh.topology.dim).size_local
    problem: str | None
    if arr.ndim != 1 or (arr.size and not np.issubdtype(arr.dtype, np.integer)):
        problem = (
            f"expected a 1D array of integer cell indices, got {arr.dtype} with shape {arr.shape}"
        )
    else:
        bad = arr[(arr < 0) | (arr >= n_owned)]
        problem = (
            f"{len(bad)} index(es) outside the owned cells 0 … {n_owned - 1}, e.g. {bad[0]}"
            if len(bad)
            else None
        )
    problems = [p for p in comm.allgather(problem) if p]
    if problems:
        raise ValueError(
            f"cells: {problems[0]} (owned local cell indices, as contact.mark returns them)"
        )
    return arr.astype(np.int32)
