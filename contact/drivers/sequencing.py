"""Grid sequencing of a single solve (docs/theory.md §8).

From a cold start semismooth Newton needs as many active-set steps as the free boundary
needs to cross the contact zone from where the first step puts it, up to O(1/h) (a band of
cells per step where the zone is wide; docs/theory.md §8.2).  Solving the same problem on
coarser meshes first and starting each finer solve from the coarser solution (what PETSc's
``-snes_grid_sequence`` does for ex9, and nested iteration does in the adaptive loop)
leaves only local corrections on the finest mesh: O(1) Newton steps there, and coarse
levels that cost a fraction of one fine step each.

A :class:`Hierarchy` holds the coarser levels of a problem, coarsest first: how to build
each level's problem (the same builder on a coarser mesh), how to solve it, and how to
carry a solution from one level to the next — by the exact prolongation of nested
refinement (:func:`prolong_chain`) or by locating the finer DoF points in the coarser mesh
(:func:`point_transfer`).  :func:`initial_guess` solves the levels and returns the last
solution on the fine space; :func:`hierarchy` makes the hierarchy of a user's builder on a
list of meshes or domains.  Every coarse solve is an ordinary solve (its own linear solver
choice, counted in ``Result.sequence``); the coarse Newton tolerance is
:data:`COARSE_RTOL` (a guess only needs the coarse active set, not round-off).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from dolfinx import fem
from dolfinx.mesh import MeshTags

from ..adaptivity.transfer import prolong
from ..base.buckets import box_point_pairs
from ..models.discrete import discrete
from ..solvers.result import Result

# measured (bench_linear / bench_cost): below this the coarse levels cost more than they save
AUTO_MIN_DOFS = 4_000
# the same for a nonlinear (hyperelastic) body in 2D, whose coarse solves take as many Newton
# steps as the fine ones they save (bench_hyperelastic.py sequence)
AUTO_MIN_DOFS_NONLINEAR = 16_000
COARSEST_DOFS = 1_000  # auto: the coarsest level keeps at least this many DoFs
COARSE_RTOL = 1e-6  # Newton's relative tolerance on the coarse levels
ANCESTOR_RATIO = 4  # a refined mesh's coarse levels: ancestors with ≥ 4× fewer DoFs each
SIZE_CLASS = 2.0  # point location: cell extents within one size class differ by < 2×


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
        """The level's linear solves: Newton's and polishing's."""
        return self.newton_iterations + self.polish_solves


@dataclass
class Hierarchy:
    """The coarser levels of a problem for grid sequencing, coarsest first.

    A level is whatever a builder works on (a mesh, a :class:`~contact.adaptivity.refine.Domain`,
    a scene); the hierarchy knows it through four callables.

    Args:
        levels: one callable per coarse level, coarsest first, returning (level, its problem);
            a ``ValueError`` (e.g. a boundary part too thin for that mesh) skips the level.
        solve: ``solve(level, problem, u0)``: the level's solve (u0 None: its cold start).
        transfer: ``transfer(u, coarse, fine, V)``: a coarser level's solution on the space V
            of a finer level.
        fine: the fine level (the problem being sequenced).
        start: ``start(level, problem)``: the coarsest solved level's guess (e.g. a load
            step's previous solution), or None.
        note: why there are fewer levels than asked, or none ('' if nothing to say).

    Example:
        >>> import contact, numpy as np, ufl
        >>> from dolfinx import fem, mesh
        >>> from mpi4py import MPI
        >>> def build(msh):  # −Δu = 10 in Ω, u = 0 on ∂Ω, u ≤ 0.05
        ...     V = fem.functionspace(msh, ("Lagrange", 1))
        ...     u, v = fem.Function(V), ufl.TestFunction(V)
        ...     F = ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx - 10 * v * ufl.dx
        ...     edge = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
        ...     bc = fem.dirichletbc(0.0, fem.locate_dofs_topological(V, 1, edge), V)
        ...     cap = contact.Unilateral(0.05)
        ...     return contact.ComplementarityProblem.from_residual(F, u, cap, [bc])
        >>> from contact.drivers.sequencing import transfer
        >>> coarse = mesh.create_unit_square(MPI.COMM_WORLD, 8, 8)
        >>> fine = build(mesh.create_unit_square(MPI.COMM_WORLD, 32, 32))
        >>> levels = contact.Hierarchy(
        ...     [lambda: (coarse, build(coarse).problem)],
        ...     solve=lambda level, problem, u0: contact.solve(problem, u0=u0, rtol=1e-6),
        ...     transfer=transfer,
        ...     fine=fine,
        ... )
        >>> result = contact.solve(fine, coarse=levels)
        >>> result.converged, [level.dofs for level in result.sequence]
        (True, [81])
        >>> fine.close()
    """

    levels: Sequence[Callable[[], tuple[Any, Any]]]
    solve: Callable[[Any, Any, fem.Function | None], Result]
    transfer: Callable[[fem.Function, Any, Any, fem.FunctionSpace], fem.Function]
    fine: Any
    start: Callable[[Any, Any], fem.Function | None] | None = None
    note: str = ""
    #: whether the levels' solution replaces a given guess too (a frictional load step's
    #: history solved on the coarse levels moves the stick/slip front there)
    replaces_guess: bool = False


def levels_wanted(
    option: str | int, fine_dofs: int, auto_min_dofs: int | None = AUTO_MIN_DOFS
) -> int | None:
    """Return how many coarse levels to try for a ``solver.sequence`` option.

    Number of coarse levels to try for ``solver.sequence`` = ``option`` (``auto``, ``off``
    or a number): 0, a number, or None (as many as ``auto`` allows).  ``auto``
    sequences from ``auto_min_dofs`` fine DoFs on (None: never).
    """
    if option == "off" or option == 0:
        return 0
    if option == "auto":
        return None if auto_min_dofs is not None and fine_dofs >= auto_min_dofs else 0
    return int(option)


def initial_guess(
    h: Hierarchy, V: fem.FunctionSpace, verbose: bool = False, label: str = ""
) -> tuple[fem.Function | None, list[CoarseLevel], str]:
    """Solve the coarse levels of a hierarchy and return the fine level's guess.

    Solve the levels of ``h``, coarsest first, each from the coarser solution carried over
    (the first from ``h.start``, or its cold start); return the last coarse solution on the
    fine space V (None if no level converged), the levels and the note.  ``label`` names
    the method in verbose lines.
    """
    comm = V.mesh.comm
    note = h.note
    if note and verbose and comm.rank == 0:
        print(f"  {note}", flush=True)
    levels: list[CoarseLevel] = []
    u, prev = None, None
    for k, build in enumerate(h.levels, start=1):
        t0 = time.perf_counter()
        try:
            level, problem = build()
        except ValueError as err:  # e.g. a boundary part too thin for the coarse mesh
            note = f"grid sequencing: coarse level {k} skipped ({err})"
            continue
        u0: fem.Function | None = None
        if u is not None and prev is not None:
            u0 = h.transfer(u, prev, level, problem.V)
        elif h.start is not None:
            u0 = h.start(level, problem)
        r = h.solve(level, problem, u0)
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
        if verbose and comm.rank == 0:
            lv = levels[-1]
            solves = (
                f"{lv.newton_iterations}+{lv.polish_solves}"
                if lv.polish_solves
                else f"{lv.newton_iterations}"
            )
            print(
                f"  sequence {k}/{len(h.levels)}: {lv.dofs:9d} DoFs  {label} {solves} its "
                f"({lv.linear})  {lv.seconds:.2f} s",
                flush=True,
            )
        if not r.converged:  # a bad coarse solution is no guess: restart from the next level
            u, prev = None, None
            continue
        u, prev = solution, level
    if u is None or prev is None:
        if levels:  # every coarse solve failed (e.g. cells inverted at a large first load)
            note = (
                f"grid sequencing: none of the {len(levels)} coarse level(s) converged; cold start"
            )
            if verbose and comm.rank == 0:
                print(f"  {note}", flush=True)
        return None, levels, note
    return h.transfer(u, prev, h.fine, V), levels, note


def hierarchy(
    build: Callable[[Any], Any],
    levels: Sequence[Any],
    fine: Any,
    solve: Callable[[Any, fem.Function | None], Result],
) -> Hierarchy:
    """Return the hierarchy of a user's builder over coarser levels.

    The hierarchy of a user's builder: ``build(level)`` on each of ``levels`` (meshes or
    domains, coarsest first, all coarser than ``fine``), each solved by ``solve(problem,
    u0)``, solutions carried by :func:`transfer` (exact prolongation along a chain of
    refinements, point location otherwise).
    """

    def built(level: Any) -> Callable[[], tuple[Any, Any]]:
        return lambda: (level, discrete(build(level)))

    return Hierarchy(
        [built(level) for level in levels],
        lambda level, problem, u0: solve(problem, u0),
        transfer,
        fine,
    )


def transfer(u: fem.Function, coarse: Any, fine: Any, V: fem.FunctionSpace) -> fem.Function:
    """Return a coarser level's solution on a finer level's space.

    A coarser level's solution ``u`` on a finer level's space V: exact along a chain of
    refinements (``fine`` a domain refined from ``coarse``: :func:`prolong_chain`), else
    by point location (:func:`point_transfer`, P1).
    """
    if _mesh(coarse) in (_mesh(level) for level in _chain(fine)):
        return prolong_chain(u, coarse, fine, V)
    return point_transfer(u, V)


def _mesh(level: Any) -> Any:
    """A level's mesh (a mesh is its own)."""
    return getattr(level, "mesh", level)


def _chain(level: Any) -> list:
    """``level`` and the levels it was refined from (its ``parent`` chain), finest first."""
    out = [level]
    while getattr(out[-1], "parent", None) is not None:
        out.append(out[-1].parent[0])
    return out


def ancestors(level: Any, ratio: int, floor: int, bs: int) -> list:
    """Return the coarse levels of a refined level: its ancestors, finest first.

    The levels ``level`` was refined from (its ``parent`` chain), finest first, each with
    ≥ ``ratio`` times fewer DoFs (P1, block size ``bs``) than the one chosen before it and
    ≥ ``floor`` DoFs: the coarse levels of a refined mesh (adaptive hierarchies grow slowly:
    every ``ratio``× in DoFs).
    """
    out, last = [], _dofs(level, bs)
    for s in _chain(level)[1:]:
        n = _dofs(s, bs)
        if n < floor:
            break
        if n * ratio <= last:
            out.append(s)
            last = n
    return out


def _dofs(level: Any, bs: int) -> int:
    """P1 DoFs of a level's mesh (vertices × block size)."""
    return _mesh(level).geometry.index_map().size_global * bs


def prolong_chain(u: fem.Function, coarse: Any, fine: Any, V: fem.FunctionSpace) -> fem.Function:
    """Prolong ``u`` through the refinements from ``coarse`` down to ``fine``.

    Prolong ``u`` through the refinements from ``coarse`` down to ``fine`` (levels with a
    ``mesh`` and a ``parent`` = (the level refined, parent cells); exact for nested
    Lagrange spaces).
    """
    chain = []
    s = fine
    while _mesh(s) is not _mesh(coarse):  # a level is its mesh (it may carry other options)
        chain.append(s)
        assert s.parent is not None  # coarse is an ancestor of fine
        s = s.parent[0]
    for child in reversed(chain):
        assert child.parent is not None
        u = prolong(u, child.mesh, child.parent[1])
    if u.function_space.mesh is not _mesh(fine):  # pragma: no cover - chain ends on fine
        raise RuntimeError("grid sequencing: the refinement chain does not end on the fine mesh")
    out = fem.Function(V)
    out.x.array[:] = u.x.array
    return out


def point_transfer(
    u: fem.Function,
    V: fem.FunctionSpace,
    coarse_bodies: MeshTags | None = None,
    fine_bodies: MeshTags | None = None,
) -> fem.Function:
    """Return a P1 function on another simplicial mesh's P1 space, by point location.

    The P1 function ``u`` on another simplicial mesh's P1 space V, by locating every DoF
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
    per point and is orders of magnitude slower here (demos/RESULTS.md §10).
    """
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
    """Return the barycentric coordinates of points in their cells.

    Barycentric coordinates (n, d+1) of ``points`` (n, d) in ``cells`` (n) of the
    simplices ``verts`` (cells, d+1, d) with inverse edge matrices ``inv``.
    """
    dp = points - verts[cells, 0]
    inv_c = inv[cells]
    lam = sum(inv_c[:, :, j] * dp[:, j, None] for j in range(dp.shape[1]))
    return np.column_stack([1.0 - lam.sum(axis=1), lam])


def _locate(
    verts: np.ndarray, inv: np.ndarray, points: np.ndarray, grow: float = 0.1
) -> np.ndarray:
    """Return for each point the simplex that contains it, or the one it is least outside of.

    For each point the index of the simplex (of ``verts``) that contains it, or the one
    it is least outside of among those whose bounding box, grown by ``grow`` buckets, holds
    it (points no box holds are located again with boxes grown by one more bucket).

    A graded mesh has cells from h_contact to h: the cells are sorted into classes whose
    extents lie within a factor 2 (:data:`SIZE_CLASS`), and each class gets buckets of
    half its mean extent over its own bounding box, so a cell spans a few buckets of its
    class whatever the others' sizes (one grid of the mean size made a large cell span
    ~10⁶ buckets: 70 s for sphere_on_block's 480k points).
    """
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
    """Return the (point, cell) pairs whose grown bounding boxes overlap.

    (point, cell) pairs: every point with each of ``cells`` whose bounding box (``lo_c``,
    ``hi_c``), grown by ``grow`` buckets, overlaps the point's bucket; buckets of half the
    cells' mean extent over their common bounding box
    (:func:`~contact.base.buckets.box_point_pairs`).
    """
    point_of, box_of = box_point_pairs(lo_c[cells], hi_c[cells], points, grow)
    return point_of, cells[box_of]


def weighted_solves(levels: list[CoarseLevel], fine_dofs: int) -> float:
    """Σ over the coarse levels of linear solves × DoFs / fine DoFs (work in fine solves)."""
    return sum(lv.linear_solves * lv.dofs for lv in levels) / max(fine_dofs, 1) if levels else 0.0


__all__ = [
    "AUTO_MIN_DOFS",
    "COARSEST_DOFS",
    "CoarseLevel",
    "Hierarchy",
    "hierarchy",
    "initial_guess",
    "point_transfer",
    "prolong_chain",
    "transfer",
    "weighted_solves",
]
