"""Grid sequencing of a single solve (``solver.sequence``; docs/theory.md §8).

From a cold start semismooth Newton needs about log₂(1/h) active-set steps: the first
steps move the free boundary across the whole contact zone.  Solving the same scene on
coarser meshes first and starting each finer solve from the coarser solution (what PETSc's
``-snes_grid_sequence`` does for ex9, and nested iteration does in the adaptive loop)
leaves only local corrections on the finest mesh: O(1) Newton steps there, and coarse
levels that cost a fraction of one fine step each.  The levels, coarsest first:

* built-in meshes (rectangle, unit_square, box, lshape): the same mesh type with
  cells / 2^k (``mesh.map`` applied on every level); the solution is carried to the next
  level by multilinear interpolation of the coarse nodal values on the structured grid
  (:class:`GridTransfer`: P1, exact for nested levels where the coarse mesh's diagonals
  line up, a second-order accurate guess otherwise, and the same on every MPI rank);
* ``quarter_disk`` / ``sphere_octant`` and the two-body ``half_disks`` / ``sphere_on_block``:
  gmsh with mesh sizes h·2^k and h_contact·2^k, carried over by locating the fine DoF
  points in the coarse mesh (:func:`point_transfer`; with several bodies each body's
  points in that body's coarse cells only, so a point of one body's contact surface never
  takes the other body's displacement), the mortar coupling built anew on every level;
* a scene made by :func:`contact.refine`: the scenes it was refined from (those whose
  DoFs fall by ≥ 4× from one chosen level to the next), carried over by
  the exact prolongation of nested refinement (:func:`contact.adaptivity.transfer.prolong`);
* a user's ``.msh`` file (and P2 on a built-in mesh), several bodies on any other mesh:
  no coarser mesh — a cold start, reported in ``Result.sequence_note``.

``auto`` sequences when the finest level has at least :data:`AUTO_MIN_DOFS` DoFs, with as
many levels as keep the coarsest at ≥ :data:`COARSEST_DOFS`; an integer N asks for N
coarser levels; ``off`` starts cold.  Every coarse solve is an ordinary solve (its own
linear solver choice, counted in ``Result.sequence``); the coarse Newton tolerance is
:data:`COARSE_RTOL` (a guess only needs the coarse active set, not round-off).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from dolfinx.mesh import MeshTags
from mpi4py import MPI

from ..base.errors import ConfigError
from ..models import build_problem
from ..setup.scene import Scene
from ..setup.scene_config import MeshConfig, SolverConfig

# measured (bench_linear / bench_cost): below this the coarse levels cost more than they save
AUTO_MIN_DOFS = 4_000
COARSEST_DOFS = 1_000  # auto: the coarsest level keeps at least this many DoFs
COARSE_RTOL = 1e-6  # Newton's relative tolerance on the coarse levels
ANCESTOR_RATIO = 4  # a refined scene's coarse levels: ancestors with ≥ 4× fewer DoFs each
BUILT_IN = ("rectangle", "unit_square", "box", "lshape")
SIZE_CLASS = 2.0  # point location: cell extents within one size class differ by < 2×
#: the gmsh-built meshes, whose sizes h and h_contact give the coarse levels
GMSH_BUILT = ("quarter_disk", "sphere_octant", "half_disks", "sphere_on_block")


@dataclass
class CoarseLevel:
    """One coarse solve of a sequence: its size, cost and outcome."""

    dofs: int
    newton_iterations: int
    polish_solves: int
    krylov_iterations: int
    linear: str
    seconds: float
    converged: bool

    @property
    def linear_solves(self) -> int:
        return self.newton_iterations + self.polish_solves


def _dofs(scene: Scene, bs: int) -> int:
    """P1 DoFs of a scene's mesh (vertices × block size)."""
    return scene.mesh.geometry.index_map().size_global * bs


def _levels_wanted(option, fine_dofs: int, dim: int) -> int | None:
    """Number of coarse levels to try (None: as many as ``auto`` allows)."""
    if option == "off" or option == 0:
        return 0
    if option == "auto":
        return None if fine_dofs >= AUTO_MIN_DOFS else 0
    return int(option)


def plan(scene: Scene, option, bs: int, degree: int) -> tuple[list[Callable[[], Scene]], str]:
    """Builders of the coarse scenes (coarsest first) and a note ('' or why there are
    fewer levels than asked / none)."""
    fine_dofs = _dofs(scene, bs)
    dim = scene.mesh.topology.dim
    wanted = _levels_wanted(option, fine_dofs, dim)
    if wanted == 0:
        return [], ""
    limit = wanted if wanted is not None else 64
    floor = COARSEST_DOFS if wanted is None else 1
    ratio = 2**dim

    if scene.config.frictional:
        return (
            [],
            "grid sequencing: not for frictional scenes (slip depends on the load history); "
            "cold start",
        )
    if scene.parent is not None:  # adaptive hierarchies grow slowly: every 4× in DoFs
        chain = _ancestors(scene, ANCESTOR_RATIO, floor, bs)[:limit]
        return [functools.partial(_same, s) for s in reversed(chain)], ""
    kind = scene.config.mesh.type
    if scene.bodies is not None and kind not in GMSH_BUILT:
        return [], (
            f"grid sequencing: several bodies on a {kind} mesh have no coarser mesh; cold start"
        )
    if degree != 1 and kind in BUILT_IN:
        return [], "grid sequencing needs P1 (mesh.degree: 1); cold start"
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


def _ancestors(scene: Scene, ratio: int, floor: int, bs: int) -> list[Scene]:
    """The scenes ``scene`` was refined from, finest first, each with ≥ ``ratio`` times
    fewer DoFs than the one chosen before it and ≥ ``floor`` DoFs."""
    out, last = [], _dofs(scene, bs)
    assert scene.parent is not None  # called for a refined scene
    s: Scene | None = scene.parent[0]
    while s is not None:
        n = _dofs(s, bs)
        if n < floor:
            break
        if n * ratio <= last:
            out.append(s)
            last = n
        s = s.parent[0] if s.parent is not None else None
    return out


def _same(scene: Scene) -> Scene:
    """``scene`` itself (the builder of a level that exists already)."""
    return scene


def _with_mesh(scene: Scene, changes: dict) -> Scene:
    """The scene with other mesh parameters (a coarse level)."""
    from ..setup.meshes import build_mesh, tag_bodies, tag_boundaries

    cfg = scene.config.with_mesh(**changes)
    msh, tags, cell_tags = build_mesh(cfg, scene.comm)
    bodies = tag_bodies(msh, cfg, cell_tags)
    return Scene(
        cfg,
        msh,
        tag_boundaries(msh, cfg, tags, bodies),
        time=scene.time,
        bodies=bodies,
        surfaces=tags,
    )


def initial_guess(
    scene: Scene, V: fem.FunctionSpace, opts: SolverConfig, solve: Callable, verbose: bool
) -> tuple[fem.Function | None, list[CoarseLevel], str]:
    """Solve the coarse levels of ``opts.sequence`` (``opts``: the fine solve's solver
    section with its call's overrides; the coarse solves take it with no sequencing and
    :data:`COARSE_RTOL`); return the last coarse solution on the fine space V (None if
    there is no coarse level), the levels and a note."""
    bs = V.dofmap.index_map_bs
    degree = V.element.basix_element.degree
    builders, note = plan(scene, opts.sequence, bs, degree)
    if note and verbose and scene.comm.rank == 0:
        print(f"  {note}", flush=True)
    levels: list[CoarseLevel] = []
    u, prev = None, None
    coarse_solver = opts.model_copy(update={"sequence": "off", "rtol": COARSE_RTOL})
    for k, build in enumerate(builders, start=1):
        t0 = time.perf_counter()
        try:
            coarse = build()
            coarse = dataclasses.replace(
                coarse, config=coarse.config.model_copy(update={"solver": coarse_solver})
            )
            problem = build_problem(coarse)
        except ConfigError as err:  # e.g. a boundary part too thin for the coarse mesh
            note = f"grid sequencing: coarse level {k} skipped ({err})"
            continue
        u0: fem.Function | None = None
        if u is not None and prev is not None:
            u0 = transfer(u, prev, coarse, problem.V)
        r = solve(coarse, problem=problem, u0=u0, verbose=False)
        levels.append(
            CoarseLevel(
                r.dofs,
                r.iterations,
                r.polish_solves,
                r.krylov_iterations,
                r.linear,
                time.perf_counter() - t0,
                bool(r.converged),
            )
        )
        solution = r.u_h
        r.release()  # the coarse problem's PETSc objects: only u_h goes on
        if verbose and scene.comm.rank == 0:
            lv = levels[-1]
            solves = (
                f"{lv.newton_iterations}+{lv.polish_solves}"
                if lv.polish_solves
                else f"{lv.newton_iterations}"
            )
            print(
                f"  sequence {k}/{len(builders)}: {lv.dofs:9d} DoFs  {opts.method} {solves} its "
                f"({lv.linear})  {lv.seconds:.2f} s",
                flush=True,
            )
        if not r.converged:  # a bad coarse solution is no guess: restart from the next level
            u, prev = None, None
            continue
        u, prev = solution, coarse
    if u is None or prev is None:
        return None, levels, note
    return transfer(u, prev, scene, V), levels, note


def transfer(
    u: fem.Function, coarse: Scene, fine: Scene, V: fem.FunctionSpace | None = None
) -> fem.Function:
    """The coarse solution ``u`` on the fine scene's space (same element)."""
    V = V or fem.functionspace(fine.mesh, u.function_space.ufl_element())
    if fine.parent is not None:
        return _prolong_chain(u, coarse, fine, V)
    if fine.config.mesh.type in BUILT_IN:
        return GridTransfer(coarse).apply(u, fine, V)
    return point_transfer(u, V, coarse.bodies, fine.bodies)


def _prolong_chain(
    u: fem.Function, coarse: Scene, fine: Scene, V: fem.FunctionSpace
) -> fem.Function:
    """Prolong through the refinements from ``coarse`` down to ``fine`` (exact for nested
    Lagrange spaces)."""
    from ..adaptivity.transfer import prolong

    chain = []
    s = fine
    while s.mesh is not coarse.mesh:  # a level is its mesh (its scene may carry other options)
        chain.append(s)
        assert s.parent is not None  # coarse is an ancestor of fine
        s = s.parent[0]
    for child in reversed(chain):
        assert child.parent is not None
        u = prolong(u, child.mesh, child.parent[1])
    if u.function_space.mesh is not fine.mesh:  # pragma: no cover - chain ends on fine
        raise RuntimeError("grid sequencing: the refinement chain does not end on the scene")
    out = fem.Function(V)
    out.x.array[:] = u.x.array
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


def point_transfer(
    u: fem.Function,
    V: fem.FunctionSpace,
    coarse_bodies: MeshTags | None = None,
    fine_bodies: MeshTags | None = None,
) -> fem.Function:
    """The P1 function ``u`` on another simplicial mesh's P1 space V, by locating every DoF
    point of V in u's mesh (for meshes of one geometry that are not nested, e.g. gmsh
    meshes of two sizes).  With the cell tags of the bodies of both meshes
    (``Scene.bodies``), a point of body k is located among body k's coarse cells only:
    where two bodies touch, the nearest coarse cell may be the other body's.

    Every rank gathers the coarse cells (vertex coordinates and nodal values: a coarse
    level is a fraction of the fine one) and sorts them into a uniform grid of buckets of
    about one cell each; a point is tested against the cells of its bucket by barycentric
    coordinates (NumPy, no per-point Python) and takes the interpolant of the cell where
    its smallest barycentric coordinate is largest — the containing cell, or for a point
    just outside a curved boundary's coarse polygon the nearest one (linear
    extrapolation).  ``interpolate_nonmatching`` does the same through a collision search
    per point and is orders of magnitude slower here (demos/RESULTS.md §10)."""
    Vc = u.function_space
    msh, comm = Vc.mesh, V.mesh.comm
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    bs = Vc.dofmap.index_map_bs
    n_cells = msh.topology.index_map(tdim).size_local
    dofs = Vc.dofmap.list[:n_cells]
    X = Vc.tabulate_dof_coordinates()[:, :gdim]
    verts = X[dofs]  # (cells, tdim+1, gdim)
    vals = u.x.array.reshape(-1, bs)[dofs]  # (cells, tdim+1, bs)
    points = V.tabulate_dof_coordinates()[:, :gdim]
    cell_body = np.zeros(n_cells, dtype=np.int32)  # 0: one body
    point_body = np.zeros(len(points), dtype=np.int32)
    if coarse_bodies is not None and fine_bodies is not None:
        cell_body[:] = _cell_values(coarse_bodies, n_cells)
        point_body[V.dofmap.list] = _cell_values(fine_bodies, len(V.dofmap.list))[:, None]
    if comm.size > 1:
        verts = np.concatenate(comm.allgather(verts))
        vals = np.concatenate(comm.allgather(vals))
        cell_body = np.concatenate(comm.allgather(cell_body))
    inv = np.linalg.inv(np.transpose(verts[:, 1:] - verts[:, :1], (0, 2, 1)))  # barycentric maps
    cell = np.empty(len(points), dtype=np.int64)
    for body in np.unique(point_body):
        mine, cells = np.flatnonzero(point_body == body), np.flatnonzero(cell_body == body)
        cell[mine] = cells[_locate(verts[cells], inv[cells], points[mine])]
    lam = _barycentric(verts, inv, cell, points)
    out = fem.Function(V)
    out.x.array[:] = np.einsum("pv,pvb->pb", lam, vals[cell]).ravel()
    return out


def _cell_values(tags: MeshTags, n: int) -> np.ndarray:
    """The tag values of local cells 0 … n − 1 (every one of them tagged)."""
    values = np.zeros(n, dtype=np.int32)
    inside = tags.indices < n
    values[tags.indices[inside]] = tags.values[inside]
    return values


def _barycentric(
    verts: np.ndarray, inv: np.ndarray, cells: np.ndarray, points: np.ndarray
) -> np.ndarray:
    """Barycentric coordinates (n, d+1) of ``points`` (n, d) in ``cells`` (n) of the
    simplices ``verts`` (cells, d+1, d) with inverse edge matrices ``inv``."""
    dp = points - verts[cells, 0]
    inv_c = inv[cells]
    lam = sum(inv_c[:, :, j] * dp[:, j, None] for j in range(dp.shape[1]))
    return np.column_stack([1.0 - lam.sum(axis=1), lam])


def _locate(
    verts: np.ndarray, inv: np.ndarray, points: np.ndarray, grow: float = 0.1
) -> np.ndarray:
    """For each point the index of the simplex (of ``verts``) that contains it, or the one
    it is least outside of among those whose bounding box, grown by ``grow`` buckets, holds
    it (points no box holds are located again with boxes grown by one more bucket).

    A graded mesh has cells from h_contact to h: the cells are sorted into classes whose
    extents lie within a factor 2 (:data:`SIZE_CLASS`), and each class gets buckets of
    half its mean extent over its own bounding box, so a cell spans a few buckets of its
    class whatever the others' sizes (one grid of the mean size made a large cell span
    ~10⁶ buckets: 70 s for sphere_on_block's 480k points)."""
    lo_c, hi_c = verts.min(axis=1), verts.max(axis=1)
    extent = np.max(hi_c - lo_c, axis=1)
    smallest = max(float(extent.min(initial=1.0)), 1e-300)
    size_class = np.floor(np.log(np.maximum(extent, smallest) / smallest) / np.log(SIZE_CLASS))
    pairs = [
        _bucket_candidates(lo_c, hi_c, np.flatnonzero(size_class == k), points, grow)
        for k in np.unique(size_class)
    ]
    point_of = np.concatenate([p for p, _ in pairs] + [np.zeros(0, dtype=np.int64)])
    cand = np.concatenate([c for _, c in pairs] + [np.zeros(0, dtype=np.int64)])
    order = np.argsort(point_of, kind="stable")
    point_of, cand = point_of[order], cand[order]
    n_cand = np.bincount(point_of, minlength=len(points))
    lost = np.flatnonzero(n_cand == 0)
    if len(lost) and grow >= 4:  # pragma: no cover - the coarse mesh covers the fine one
        raise RuntimeError(
            "grid sequencing: a point of the fine mesh lies far outside the coarse mesh"
        )
    chosen = np.empty(len(points), dtype=np.int64)
    if len(cand):
        score = _barycentric(verts, inv, cand, points[point_of]).min(axis=1)
        group = np.flatnonzero(np.r_[True, point_of[1:] != point_of[:-1]])  # one group a point
        best = np.maximum.reduceat(score, group)
        hit = np.flatnonzero(score >= np.repeat(best, np.diff(np.r_[group, len(point_of)])))
        chosen[point_of[hit[::-1]]] = cand[hit[::-1]]  # the first best candidate of each point
    if len(lost):
        chosen[lost] = _locate(verts, inv, points[lost], grow + 1.0)
    return chosen


def _bucket_candidates(
    lo_c: np.ndarray, hi_c: np.ndarray, cells: np.ndarray, points: np.ndarray, grow: float
) -> tuple[np.ndarray, np.ndarray]:
    """(point, cell) pairs: every point with each of ``cells`` whose bounding box (``lo_c``,
    ``hi_c``), grown by ``grow`` buckets, overlaps the point's bucket; buckets of half the
    cells' mean extent over their common bounding box (at most ~4 buckets a cell)."""
    lo_k, hi_k = lo_c[cells], hi_c[cells]
    dim = lo_c.shape[1]
    size = max(0.5 * float(np.mean(hi_k - lo_k)), 1e-300)
    lo, hi = lo_k.min(axis=0) - grow * size, hi_k.max(axis=0) + grow * size
    size = max(size, float(np.prod(hi - lo) / (4 * len(cells))) ** (1 / dim))
    shape = np.maximum(np.ceil((hi - lo) / size).astype(np.int64), 1)
    # every cell into the buckets its grown box overlaps
    first = np.clip(np.floor((lo_k - lo) / size - grow).astype(np.int64), 0, shape - 1)
    last = np.clip(np.floor((hi_k - lo) / size + grow).astype(np.int64), 0, shape - 1)
    span = last - first + 1
    count = np.prod(span, axis=1)
    cell_of = np.repeat(np.arange(len(cells)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    offset = np.empty((len(cell_of), dim), dtype=np.int64)
    for axis in range(dim - 1, -1, -1):
        k, offset[:, axis] = np.divmod(k, span[cell_of, axis])
    bucket = np.ravel_multi_index(tuple((first[cell_of] + offset).T), shape)
    order = np.argsort(bucket, kind="stable")
    bucket, cell_of = bucket[order], cell_of[order]
    start = np.searchsorted(bucket, np.arange(np.prod(shape) + 1))
    # the points inside the class's box, with the cells of their bucket
    inside = np.flatnonzero(np.all((points >= lo) & (points <= hi), axis=1))
    at = np.clip(np.floor((points[inside] - lo) / size).astype(np.int64), 0, shape - 1)
    pb = np.ravel_multi_index(tuple(at.T), shape)
    n_cand = start[pb + 1] - start[pb]
    point_of = np.repeat(inside, n_cand)
    j = np.arange(n_cand.sum()) - np.repeat(np.cumsum(n_cand) - n_cand, n_cand)
    return point_of, cells[cell_of[np.repeat(start[pb], n_cand) + j]]


def weighted_solves(levels: list[CoarseLevel], fine_dofs: int) -> float:
    """Σ over the coarse levels of linear solves × DoFs / fine DoFs (work in fine solves)."""
    return sum(lv.linear_solves * lv.dofs for lv in levels) / max(fine_dofs, 1) if levels else 0.0


__all__ = [
    "AUTO_MIN_DOFS",
    "COARSEST_DOFS",
    "CoarseLevel",
    "GridTransfer",
    "initial_guess",
    "plan",
    "transfer",
    "weighted_solves",
]
