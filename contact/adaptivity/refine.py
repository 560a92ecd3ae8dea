"""REFINE (docs/theory.md §6): refine the marked cells and carry the scene over.

REFINE (docs/theory.md §6): the marked cells' edges refined (``dolfinx.mesh.refine``), the
scene carried to the new mesh (tags, history, nested-iteration guess, curved boundaries
snapped to their exact surfaces), and the refined mesh's partition.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..setup.geometry import builder_surfaces
from ..setup.meshes import Boundary
from ..setup.scene import Scene
from ..setup.surfaces import boundary_surfaces, warn_undeclared_curves
from . import longest_edge
from .transfer import prolong, transfer_cell_tags, transfer_facet_tags


def refine(
    scene: Scene,
    cells: np.ndarray,
    u_h: fem.Function | None = None,
    rebalance: bool | None = None,
    *,
    timings: dict[str, float] | None = None,
) -> tuple[Scene, fem.Function | None]:
    """Refine the marked cells and carry the scene over (the REFINE step).

    The marked cells' edges are refined (conforming, ``dolfinx.mesh.refine``), the boundary
    tags carried to the new mesh, ``u_h`` interpolated onto it (nested iteration), and the
    vertices of a curved boundary part moved onto its exact surface (the built-in Hertz
    meshes and parts that declare a ``surface``; other parts keep dolfinx's midpoints — a
    gmsh contact part that looks curved gets a one-line warning). The refined scene keeps
    the pseudo-time, and the functions of ``scene.history`` (a load step's state from the
    previous step) are prolonged with u_h. The two-body builders (``half_disks``,
    ``sphere_on_block``) snap their curved surfaces by the mesh's own facet tags
    (``scene.surfaces``), whatever parts the scene cut them into, and the body tags
    (``scene.bodies``) follow the cells.

    The interpolation comes first: it evaluates u_h at the new nodes where dolfinx put
    them, inside the old mesh; a snapped node then keeps that value (u0(π(x)) = u_h(x),
    the surface shifts by at most the sagitta h²/(8R) of the old edge). Collective.

    The refined mesh does not depend on the number of ranks: a face's longest edge among
    edges of equal length is chosen by the coordinates, not by DOLFINx's
    partition-dependent vertex numbers (:mod:`.longest_edge`).

    Args:
        scene: The scene to refine.
        cells: Owned local cell indices, as :func:`contact.mark` returns them.
        u_h: A function on the scene's mesh to carry over (e.g. ``result.u_h``), or None.
        rebalance: In parallel, redistribute the refined mesh evenly over the ranks
            (default: the scene's ``adapt.rebalance``, true); the mesh itself does not
            depend on it.
        timings: If given, receives the seconds of the parts: ``mesh`` (the marked edges
            and ``dolfinx.mesh.refine`` itself, with the redistribution, the ghost layer
            and the ties), ``transfer`` (facets, tags and functions carried over) and
            ``snap`` (curved boundaries).

    Returns:
        The refined scene (its ``parent`` the scene and the parent cells) and ``u_h``
        interpolated onto it (None if ``u_h`` was None).

    Raises:
        ValueError: On every rank, if ``cells`` are not owned local cell indices or
            ``u_h`` is not a function on the scene's mesh.

    Example:
        >>> import contact
        >>> scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["adapt=none"])
        >>> result = contact.solve(scene, verbose=False)
        >>> cells = contact.mark(contact.estimate(scene, result).eta_T, "uniform")
        >>> fine, u0 = contact.refine(scene, cells, result.u_h)
        >>> cells_of = lambda s: s.mesh.topology.index_map(2).size_global
        >>> cells_of(fine), cells_of(scene)
        (1024, 256)
    """
    cells = _owned_cells(scene, cells)
    if u_h is not None and (
        not isinstance(u_h, fem.Function) or u_h.function_space.mesh is not scene.mesh
    ):
        raise ValueError(
            "u_h: expected a dolfinx.fem.Function on the scene's mesh (e.g. result.u_h of "
            "contact.solve on this scene)"
        )
    if rebalance is None:
        adapt = scene.config.adapt
        rebalance = adapt.rebalance if adapt is not None else True
    if not isinstance(rebalance, bool):
        raise ValueError(f"rebalance: expected true or false, got {rebalance!r}")
    msh = scene.mesh
    tdim = msh.topology.dim
    clock = [time.perf_counter()]  # the start, then the end of each part
    msh.topology.create_entities(1)
    edges = dmesh.compute_incident_entities(msh.topology, cells, tdim, 1)
    new, parent_cell, parent_facet = longest_edge.refine(
        msh, edges, refine_partitioner(msh, rebalance)
    )
    clock.append(time.perf_counter())
    new.topology.create_entities(tdim - 1)
    new.topology.create_connectivity(tdim - 1, tdim)
    tags = transfer_facet_tags(scene.boundary.tags, new, parent_cell, parent_facet)
    history = {name: prolong(fn, new, parent_cell) for name, fn in scene.history.items()}
    bodies = None if scene.bodies is None else transfer_cell_tags(scene.bodies, new, parent_cell)
    surfaces = (
        None
        if scene.surfaces is None
        else transfer_facet_tags(scene.surfaces, new, parent_cell, parent_facet)
    )
    child = Scene(
        scene.config,
        new,
        Boundary(tags, dict(scene.boundary.ids), dict(scene.boundary.roles)),
        time=scene.time,
        history=history,
        previous_time=scene.previous_time,
        bodies=bodies,
        surfaces=surfaces,
        parent=(scene, parent_cell),
    )
    u0 = None if u_h is None else prolong(u_h, new, parent_cell)
    clock.append(time.perf_counter())
    warn_undeclared_curves(scene.config, scene.mesh, scene.boundary)
    for surface in boundary_surfaces(scene.config, scene.mesh.geometry.dim, scene.boundary):
        surface.snap(new, tags)
    # by the mesh's own tags of its curved surfaces
    for surface in builder_surfaces(scene.config.mesh):
        assert surfaces is not None  # a mesh builder with curved surfaces tags them
        surface.snap(new, surfaces)
    clock.append(time.perf_counter())
    if timings is not None:
        timings.update(zip(("mesh", "transfer", "snap"), np.diff(clock).tolist()))
    return child, u0


def next_dofs_bound(scene: Scene, cells: np.ndarray, V: fem.FunctionSpace) -> int | None:
    """Return a lower bound of the DoFs after refining ``cells``.

    A lower bound of the DoFs after refining ``cells`` (P1: one new vertex per marked edge;
    refinement may split more edges for conformity), or None for P2.  An edge counts once,
    on its owning rank, whichever rank's cells marked it (the same bound on any number of
    ranks).
    """
    if V.element.basix_element.degree != 1:
        return None
    msh = scene.mesh
    tdim = msh.topology.dim
    msh.topology.create_entities(1)
    edges = dmesh.compute_incident_entities(msh.topology, cells.astype(np.int32), tdim, 1)
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


def _owned_cells(scene: Scene, cells: Any) -> np.ndarray:
    """``cells`` as int32 owned local cell indices; ValueError (collective) otherwise."""
    arr = np.asarray(cells)
    comm = scene.comm
    n_owned = scene.mesh.topology.index_map(scene.mesh.topology.dim).size_local
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
