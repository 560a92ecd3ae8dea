"""A scene's coarser levels for grid sequencing of a single solve (``solver.sequence``;
docs/theory.md §8, :mod:`.sequencing`), coarsest first:

* built-in meshes (rectangle, unit_square, box, lshape): the same mesh type with
  cells / 2^k (``mesh.map`` applied on every level); the solution is carried to the next
  level by multilinear interpolation of the coarse nodal values on the structured grid
  (:class:`GridTransfer`: P1, exact for nested levels where the coarse mesh's diagonals
  line up, a second-order accurate guess otherwise, and the same on every MPI rank);
* ``quarter_disk`` / ``sphere_octant`` and the two-body ``half_disks`` / ``sphere_on_block``:
  gmsh with mesh sizes h·2^k and h_contact·2^k, carried over by locating the fine DoF
  points in the coarse mesh (:func:`~.sequencing.point_transfer`; with several bodies each
  body's points in that body's coarse cells only, so a point of one body's contact surface
  never takes the other body's displacement), the mortar coupling built anew on every level;
* a scene made by :func:`contact.refine`: the scenes it was refined from (those whose
  DoFs fall by ≥ 4× from one chosen level to the next), carried over by
  the exact prolongation of nested refinement (:func:`~.sequencing.prolong_chain`);
* a scene of degree p > 1 (``mesh.degree``): the same scene at P1 on the same mesh (about
  p^dim times fewer DoFs; P1's own coarse levels above before it), its solution
  interpolated exactly into P_p — the only level where the mesh has no coarser one (not
  on curved cells, ``mesh.geometry_degree: 2``, which carry P2 alone: a cold start);
* a user's ``.msh`` file, several bodies on any other mesh (at P1): no coarser mesh — a
  cold start, reported in ``Result.sequence_note``.

A frictional load step after the first carries its history to the coarse levels: the
previous step's displacement u_prev (from which the slip increments are measured) is
interpolated onto each coarse mesh (:func:`restrict`), the coarsest solve starts from it,
and each finer level from the coarser solution as above — the stick/slip front moves
across the contact zone on the coarse meshes, where a fine Newton iteration moves it by
about one node per step.  The coarse meshes of a scene are built once and kept for its later
steps (:func:`_with_mesh`).  A refined scene with history (an adaptive load step) starts
from the step before.

``auto`` sequences when the finest level has at least
:data:`~.sequencing.AUTO_MIN_DOFS` DoFs (a hyperelastic body in 2D:
:data:`~.sequencing.AUTO_MIN_DOFS_NONLINEAR`; in 3D, where it is not measured, never), with as
many levels as keep the coarsest at ≥ :data:`~.sequencing.COARSEST_DOFS`; an integer N asks
for N coarser levels; ``off`` starts cold.  A hyperelastic load step is sequenced only
without a previous solution (its first step; the later ones start from the tangent
predictor).  Hyperelastic bodies in contact through pairs solve each coarse level's own
fixed point of couplings (:func:`contact.setup.run.solve_coupled`).
"""

from __future__ import annotations

import dataclasses
import functools
import weakref
from collections.abc import Callable

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from ..drivers.sequencing import (
    ANCESTOR_RATIO,
    AUTO_MIN_DOFS,
    AUTO_MIN_DOFS_NONLINEAR,
    COARSE_RTOL,
    COARSEST_DOFS,
    Hierarchy,
    ancestors,
    levels_wanted,
    point_transfer,
    prolong_chain,
)
from ..solvers.problem import DiscreteProblem
from .build import build_problem
from .scene import Scene
from .scene_config import MeshConfig, SolverConfig

BUILT_IN = ("rectangle", "unit_square", "box", "lshape")
#: the gmsh-built meshes, whose sizes h and h_contact give the coarse levels
GMSH_BUILT = ("quarter_disk", "sphere_octant", "half_disks", "sphere_on_block")


def _dofs(scene: Scene, bs: int) -> int:
    """P1 DoFs of a scene's mesh (vertices × block size)."""
    return scene.mesh.geometry.index_map().size_global * bs


def plan(scene: Scene, option, bs: int, degree: int) -> tuple[list[Callable[[], Scene]], str]:
    """Builders of the coarse scenes (coarsest first) and a note ('' or why there are
    fewer levels than asked / none).

    At degree p > 1 the finest coarse level is the scene at P1 on the same mesh (about
    p^dim times fewer DoFs), itself after P1's own coarse levels (:func:`_degree_plan`)."""
    dim = scene.mesh.topology.dim
    fine_dofs = _dofs(scene, bs) * degree**dim  # P1 DoFs × p^dim ≈ the P_p DoFs
    wanted = levels_wanted(option, fine_dofs, auto_min_dofs(scene.config.model.type, dim))
    if wanted == 0:
        return [], ""
    limit = wanted if wanted is not None else 64
    floor = COARSEST_DOFS if wanted is None else 1
    ratio = 2**dim

    if scene.parent is not None and scene.history:
        return [], "grid sequencing: a refined scene's history stays on its mesh; warm start"
    if scene.parent is not None:  # adaptive hierarchies grow slowly: every 4× in DoFs
        chain = ancestors(scene, ANCESTOR_RATIO, floor, bs)[:limit]
        return [functools.partial(_same, s) for s in reversed(chain)], ""
    if degree != 1:
        if scene.config.mesh.geometry_degree != 1:  # curved cells carry isoparametric P2 only
            return [], "grid sequencing: curved cells (mesh.geometry_degree 2) need P2; cold start"
        return _degree_plan(scene, wanted, bs)
    kind = scene.config.mesh.type
    if scene.bodies is not None and kind not in GMSH_BUILT:
        return [], (
            f"grid sequencing: several bodies on a {kind} mesh have no coarser mesh; cold start"
        )
    if kind in BUILT_IN:
        cells = list(_grid_axes(scene.config.mesh))
        builders: list[Callable[[], Scene]] = []
        for k in range(1, limit + 1):
            coarse = tuple(c // 2**k for c in cells)
            if min(coarse) < 1 or fine_dofs / ratio**k < floor:
                break
            builders.append(functools.partial(_with_mesh, scene, {"cells": coarse}))
        note = (
            ""
            if wanted is None or len(builders) == wanted
            else f"grid sequencing: only {len(builders)} coarser level(s) of {cells} cells exist"
        )
        return builders[::-1], note
    if kind in GMSH_BUILT:
        m = scene.config.mesh
        assert m.h is not None and m.h_contact is not None and m.zone is not None
        builders = []
        for k in range(1, limit + 1):
            h, hc = m.h * 2**k, m.h_contact * 2**k
            if hc > m.zone or fine_dofs / ratio**k < floor:
                break
            builders.append(functools.partial(_with_mesh, scene, {"h": h, "h_contact": min(hc, h)}))
        return builders[::-1], ""
    return [], "grid sequencing: a mesh file has no coarser mesh; cold start"


def _degree_plan(
    scene: Scene, wanted: int | None, bs: int
) -> tuple[list[Callable[[], Scene]], str]:
    """The coarse levels of a scene of degree p > 1: P1's coarse levels, then P1 on the
    scene's own mesh.

    A P1 solution interpolates exactly into P_p on the same mesh (:func:`transfer`), so the
    P_p Newton iteration starts from the P1 active set and displacement and has only the
    local corrections of the higher degree left (where no coarser mesh exists — a mesh
    file, several bodies on a built-in mesh — this is the only level).  ``wanted``: the
    number of coarse levels asked (None: ``auto``); the P1 levels below the same-mesh one
    follow P1's own ``auto`` rule on the mesh's P1 DoFs.
    """
    p1 = _with_degree(scene, 1)
    below, note = plan(p1, "auto" if wanted is None else wanted - 1, bs, 1)
    if note.endswith("; cold start"):  # only the P1 level on the same mesh starts cold
        note = note.removesuffix("; cold start") + "; P1 on the same mesh starts cold"
    return [*below, functools.partial(_same, p1)], note


def _with_degree(scene: Scene, degree: int) -> Scene:
    """The scene with another ``mesh.degree`` on the same mesh (its tags and bodies)."""
    return dataclasses.replace(scene, config=scene.config.with_mesh(degree=degree))


def auto_min_dofs(model: str, dim: int) -> int | None:
    """The fine DoFs from which ``solver.sequence: auto`` sequences a ``model`` scene in
    ``dim`` dimensions (None: never)."""
    if model != "hyperelastic":
        return AUTO_MIN_DOFS
    return AUTO_MIN_DOFS_NONLINEAR if dim == 2 else None


def _same(scene: Scene) -> Scene:
    """``scene`` itself (the builder of a level that exists already)."""
    return scene


#: the coarse meshes built for a fine mesh (a load path solves every step on the same mesh):
#: fine mesh → {the coarse mesh section: (mesh, facet tags, cell tags)}
_COARSE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _with_mesh(scene: Scene, changes: dict) -> Scene:
    """The scene with other mesh parameters (a coarse level) at the scene's time; the mesh
    is built once per fine mesh and kept while that mesh lives."""
    from .meshes import build_mesh, tag_bodies, tag_boundaries

    cfg = scene.config.with_mesh(**changes)
    built = _COARSE.setdefault(scene.mesh, {})
    key = repr(cfg.mesh)
    if key not in built:
        built[key] = build_mesh(cfg, scene.comm)
    msh, tags, cell_tags = built[key]
    from .surfaces import snapping

    bodies = tag_bodies(msh, cfg, cell_tags)
    boundary = tag_boundaries(msh, cfg, tags, bodies)
    return Scene(
        cfg,
        msh,
        boundary,
        time=scene.time,
        bodies=bodies,
        surfaces=tags,
        snap=snapping(cfg, boundary),
        budget=scene.budget,
    )


def scene_hierarchy(
    scene: Scene, V: fem.FunctionSpace, opts: SolverConfig, solve: Callable
) -> Hierarchy:
    """The coarse levels of ``opts.sequence`` (``opts``: the fine solve's solver section with
    its call's overrides) as a :class:`~.sequencing.Hierarchy`: each a scene on a coarser mesh
    whose solver section has no sequencing and :data:`~.sequencing.COARSE_RTOL`, solved by
    ``solve`` (:func:`contact.setup.run.solve`), a load step's history restricted to it
    (its coarsest level starts from the previous step's solution, and the levels' solution
    replaces a frictional step's guess)."""
    bs = V.dofmap.index_map_bs
    degree = V.element.basix_element.degree
    builders, note = plan(scene, opts.sequence, bs, degree)
    coarse_solver = opts.model_copy(update={"sequence": "off", "rtol": COARSE_RTOL})
    u_prev = scene.history.get("u_prev")
    if u_prev is not None and degree != 1:  # the coarse levels are P1: restrict through P1
        u_prev = _on_space(u_prev, fem.functionspace(scene.mesh, ("Lagrange", 1, V.value_shape)))

    def level(build: Callable[[], Scene]) -> tuple[Scene, DiscreteProblem]:
        coarse = build()
        coarse = dataclasses.replace(
            coarse, config=coarse.config.model_copy(update={"solver": coarse_solver})
        )
        if u_prev is not None:  # a load step's history, on the coarse mesh
            coarse.history = {"u_prev": restrict(u_prev, scene, coarse)}
        return coarse, build_problem(coarse)

    def start(coarse: Scene, problem: DiscreteProblem) -> fem.Function | None:
        if u_prev is None:
            return None
        u0 = fem.Function(problem.V)  # the coarsest level starts from the previous step
        u0.x.array[:] = coarse.history["u_prev"].x.array
        return u0

    return Hierarchy(
        [functools.partial(level, build) for build in builders],
        lambda coarse, problem, u0: solve(coarse, problem=problem, u0=u0, verbose=False),
        transfer,
        scene,
        start,
        note,
        replaces_guess=bool(scene.history),
    )


def transfer(
    u: fem.Function, coarse: Scene, fine: Scene, V: fem.FunctionSpace | None = None
) -> fem.Function:
    """The coarse solution ``u`` on the fine scene's space (same element)."""
    V = V or fem.functionspace(fine.mesh, u.function_space.ufl_element())
    if coarse.mesh is fine.mesh:  # a lower degree on the same mesh: nested spaces
        return _on_space(u, V)
    if fine.parent is not None:
        return prolong_chain(u, coarse, fine, V)
    if fine.config.mesh.type in BUILT_IN:
        return GridTransfer(coarse).apply(u, fine, V)
    return point_transfer(u, V, coarse.bodies, fine.bodies)


def restrict(u: fem.Function, fine: Scene, coarse: Scene) -> fem.Function:
    """A fine solution ``u`` (the previous load step's) interpolated onto the coarse scene's
    mesh (same element): on built-in meshes the coarse vertices are grid points of the fine
    grid (:class:`GridTransfer`: exact), on gmsh meshes the coarse points are located in
    the fine cells (:func:`point_transfer`)."""
    V = fem.functionspace(coarse.mesh, u.function_space.ufl_element())
    if coarse.mesh is fine.mesh:
        return _on_space(u, V)
    if fine.config.mesh.type in BUILT_IN:
        return GridTransfer(fine).apply(u, coarse, V)
    return point_transfer(u, V, fine.bodies, coarse.bodies)


def _on_space(u: fem.Function, V: fem.FunctionSpace) -> fem.Function:
    """``u`` interpolated into V, a Lagrange space on u's mesh (exact from a lower degree)."""
    out = fem.Function(V)
    out.interpolate(u)
    return out


class GridTransfer:
    """Multilinear interpolation between structured built-in meshes of one scene.

    The input numbering of ``create_rectangle`` / ``create_box`` /
    :func:`contact.setup.meshes.lshape` is that of a grid
    (``geometry.input_global_indices``), so every vertex knows its grid position (i, j[, k])
    whatever ``mesh.map`` did to its coordinates.  The coarse P1 nodal values are summed
    into one grid array on every rank (each vertex from its owner), and every fine vertex
    takes the multilinear interpolant at its position in coarse cell units.  Crossed meshes'
    cell-centre vertices are left out of the coarse grid (the corners alone define the
    interpolant) and interpolated like any other fine point."""

    def __init__(self, coarse: Scene):
        self.coarse = coarse

    def apply(self, u: fem.Function, fine: Scene, V: fem.FunctionSpace) -> fem.Function:
        cs, comm = self.coarse, fine.comm
        bs = V.dofmap.index_map_bs
        n_c = _grid_cells(cs.config.mesh)
        n_f = _grid_cells(fine.config.mesh)
        shape = tuple(n + 1 for n in n_c)
        # coarse grid array: owned vertices only, summed over ranks
        Vc = u.function_space
        pos_c = _dof_positions(cs, Vc)
        owned = Vc.dofmap.index_map.size_local
        ints = np.rint(pos_c[:owned]).astype(np.int64)
        on_grid = np.all(np.abs(pos_c[:owned] - ints) < 1e-9, axis=1)
        flat = np.ravel_multi_index(tuple(ints[on_grid].T), shape)
        grid = np.zeros((int(np.prod(shape)), bs))
        grid[flat] = u.x.array[: owned * bs].reshape(owned, bs)[on_grid]
        comm.Allreduce(MPI.IN_PLACE, grid, op=MPI.SUM)
        grid = grid.reshape(*shape, bs)
        # fine points in coarse cell units, multilinear weights
        xi = _dof_positions(fine, V) * (np.array(n_c, dtype=float) / np.array(n_f, dtype=float))
        out = fem.Function(V)
        out.x.array[:] = _multilinear(grid, xi, np.array(n_c)).ravel()
        return out


def _multilinear(grid: np.ndarray, xi: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Values of the multilinear interpolant of ``grid`` (shape (n+1)..., bs) at ``xi``
    (points × dim, in cell units)."""
    dim = xi.shape[1]
    i0 = np.clip(np.floor(xi).astype(np.int64), 0, n - 1)
    t = xi - i0
    out = np.zeros((len(xi), grid.shape[-1]))
    for corner in np.ndindex(*(2,) * dim):
        c = np.array(corner)
        w = np.prod(np.where(c == 1, t, 1.0 - t), axis=1)
        idx = tuple((i0 + c).T)
        out += w[:, None] * grid[idx]
    return out


def _grid_axes(m: MeshConfig) -> tuple[int, ...]:
    """The cell counts of a built-in mesh (one per axis; lshape: one, per unit length)."""
    assert isinstance(m.cells, tuple)  # the loader makes them a tuple for these types
    return m.cells


def _grid_cells(m: MeshConfig) -> list[int]:
    """Cells per axis of the structured grid under a built-in mesh (lshape: the 2n × 2n
    grid of its bounding box)."""
    if m.type == "lshape":
        return [2 * _grid_axes(m)[0]] * 2
    return list(_grid_axes(m))


def _dof_positions(scene: Scene, V: fem.FunctionSpace) -> np.ndarray:
    """Grid position (in cell units) of every local P1 DoF of V (owned and ghost)."""
    msh = scene.mesh
    dim = msh.topology.dim
    node_pos = _node_positions(scene)
    n_dofs = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    node_of_dof = np.empty(n_dofs, dtype=np.int64)
    node_of_dof[V.dofmap.list.ravel()] = msh.geometry.dofmaps[0][:, : dim + 1].ravel()
    return node_pos[node_of_dof]


def _node_positions(scene: Scene) -> np.ndarray:
    """Grid position of every local geometry node, from its input index."""
    m = scene.config.mesh
    idx = np.asarray(scene.mesh.geometry.input_global_indices, dtype=np.int64)
    if m.type == "lshape":
        n = _grid_axes(m)[0]
        used = _lshape_vertices(n)
        a, b = np.divmod(used[idx], 2 * n + 1)
        return np.column_stack([a, b]).astype(float)
    cells = list(_grid_axes(m))
    if len(cells) == 2:
        nx, ny = cells
        corners = (nx + 1) * (ny + 1)
        iy, ix = np.divmod(np.minimum(idx, corners - 1), nx + 1)
        pos = np.column_stack([ix, iy]).astype(float)
        centre = idx >= corners  # crossed: cell centres after the corners
        cy, cx = np.divmod(idx[centre] - corners, nx)
        pos[centre] = np.column_stack([cx + 0.5, cy + 0.5])
        return pos
    nx, ny, nz = cells
    iz, rest = np.divmod(idx, (nx + 1) * (ny + 1))
    iy, ix = np.divmod(rest, nx + 1)
    return np.column_stack([ix, iy, iz]).astype(float)


def _lshape_vertices(n: int) -> np.ndarray:
    """The vertex ids a * (2n + 1) + b that :func:`contact.setup.meshes.lshape` keeps, in its
    input order (sorted)."""
    i, j = np.meshgrid(np.arange(2 * n), np.arange(2 * n), indexing="ij")
    keep = ~((i >= n) & (j < n))
    i, j = i[keep], j[keep]
    corners = np.concatenate(
        [a * (2 * n + 1) + b for a, b in ((i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1))]
    )
    return np.unique(corners)
