"""Meshes and boundary parts of a scene.

Built-in meshes need nothing but DOLFINx: ``rectangle``/``unit_square`` and ``box``
(structured simplices), ``lshape`` (Ω = (−1,1)² ∖ [0,1]×[−1,0], docs/theory.md §7 D) and
``ring`` (an annulus in polar coordinates), built from NumPy arrays.  Only ``gmsh`` scenes
import gmsh, to read a ``.msh`` file with physical tags
(:func:`contact.setup.geometry.gmsh_to_mesh`, which also builds the parametric gmsh meshes
of :mod:`contact.setup.geometry`).  A built-in mesh may be deformed by ``mesh.map``
(:func:`map_geometry`) before its boundary parts are tagged.  Boundary parts become one
facet ``MeshTags`` whose values are the part ids.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import basix.ufl
import numpy as np
import ufl
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..base import expressions
from ..base.errors import ConfigError
from .geometry import (
    collapsed_cells,
    gmsh_to_mesh,
    half_disks,
    quarter_disk,
    signed_volumes,
    sphere_octant,
    sphere_on_block,
    vertex_nodes,
)
from .scene_config import Block, MeshConfig, SceneConfig

_DIAGONALS = {
    "left": dmesh.DiagonalType.left,
    "right": dmesh.DiagonalType.right,
    "crossed": dmesh.DiagonalType.crossed,
    "left/right": dmesh.DiagonalType.left_right,
    "right/left": dmesh.DiagonalType.right_left,
}


NATURAL = "(natural)"  # name of the part of unmarked exterior facets


@dataclass
class Boundary:
    """Facet tags of the scene's boundary parts: ``ids[name]`` is the tag value of a part,
    ``roles[name]`` its role (dirichlet, neumann, contact, symmetry, interface, or natural:
    k ∂u/∂n = 0, for the parts declared so and for the exterior facets no part selects,
    the part named :data:`NATURAL`)."""

    tags: dmesh.MeshTags
    ids: dict[str, int]
    roles: dict[str, str]

    def ids_with_role(self, role: str) -> tuple[int, ...]:
        return tuple(self.ids[n] for n, r in self.roles.items() if r == role)

    def facets(self, role: str) -> np.ndarray:
        """Local facet indices of all parts with ``role``."""
        ids = self.ids_with_role(role)
        return np.sort(self.tags.indices[np.isin(self.tags.values, ids)]).astype(np.int32)


def mesh_dimension(cfg: SceneConfig) -> int | None:
    """The geometric dimension of the scene's mesh, from its type (None for a gmsh file)."""
    mesh = cfg.mesh
    if mesh.type == "blocks":
        assert mesh.blocks  # required for this type (checked at load)
        return len(mesh.blocks[0].corners[0])
    return {
        "rectangle": 2,
        "unit_square": 2,
        "lshape": 2,
        "quarter_disk": 2,
        "half_disks": 2,
        "box": 3,
        "sphere_octant": 3,
        "sphere_on_block": 3,
        "ring": 2,
    }.get(mesh.type)


def build_mesh(
    cfg: SceneConfig, comm: MPI.Comm = MPI.COMM_WORLD
) -> tuple[dmesh.Mesh, dmesh.MeshTags | None, dmesh.MeshTags | None]:
    """The mesh described by ``cfg.mesh`` (mapped by ``mesh.map`` if given), its facet
    tags (gmsh files and builders) and cell tags (gmsh physical volumes / surfaces, the
    block numbers of mesh type blocks), ``None`` where the mesh has none."""
    msh, tags, cells = _built_mesh(cfg, comm)
    if cfg.mesh.map is not None:
        map_geometry(msh, cfg.mesh.map, cfg.constants)
    return msh, tags, cells


def map_geometry(
    msh: dmesh.Mesh,
    exprs: Sequence[str],
    constants: Mapping[str, float] | None = None,
    key: str = "mesh.map",
    tol: float = 1e-12,
) -> None:
    """Move every geometry node x of ``msh`` to Φ(x) = (exprs[0], exprs[1](, exprs[2]))(x).

    The expressions are in the coordinates x, y, z of the mesh as built and give the new
    coordinates in the same length unit.  Each rank maps its owned and ghost nodes with the
    same formula, so the partition stays consistent.  The map must keep every cell's
    orientation: with J_T = det(x'_1 − x'_0, …)/det(x_1 − x_0, …) the cell's (mean)
    Jacobian determinant of Φ, every cell needs J_T > tol · max_T |J_T| (counted over all
    ranks).  Non-finite coordinates (e.g. ``log(x)`` at x = 0), inverted (J_T < 0) or
    flattened (J_T ≈ 0) cells raise one ConfigError line on every rank, naming ``key``.
    """
    comm, gdim = msh.comm, msh.geometry.dim
    X = msh.geometry.x
    old = X.T.copy()
    new = np.array([expressions.to_numpy(e, constants or {})(old) for e in exprs])
    n_owned = msh.geometry.index_map().size_local
    for i, coord in enumerate(new):
        bad = comm.allreduce(int(np.sum(~np.isfinite(coord[:n_owned]))), op=MPI.SUM)
        if bad:
            total = msh.geometry.index_map().size_global
            raise ConfigError(f"{key}[{i}]: not a finite number at {bad} of {total} vertices")
    before = signed_volumes(msh)
    X[:, :gdim] = new.T
    bad, n_bad = collapsed_cells(msh, before, tol)
    if n_bad:
        first = [old[:gdim, vertex_nodes(msh)[bad[0]]].mean(axis=1)] if len(bad) else []
        where = next(p for p in comm.allgather(first) if p)[0]
        at = ", ".join(f"{c} = {v:.4g}" for c, v in zip("xyz", where))
        total = msh.topology.index_map(msh.topology.dim).size_global
        raise ConfigError(
            f"{key}: the map inverts or flattens {n_bad} of {total} cells (Jacobian "
            f"determinant ≤ 0), e.g. the cell at {at} (unmapped)"
        )


Tags = dmesh.MeshTags | None


def _built_mesh(cfg: SceneConfig, comm: MPI.Comm) -> tuple[dmesh.Mesh, Tags, Tags]:
    """The mesh of ``cfg.mesh`` as built, before any map: (mesh, facet tags, cell tags)."""
    m = cfg.mesh
    kind = m.type
    # structured types: one cell count per axis (lshape: one), made a tuple by the loader
    cells = m.cells if isinstance(m.cells, tuple) else (m.cells,)
    if kind in ("rectangle", "unit_square"):
        corners = m.corners if kind == "rectangle" else ((0.0, 0.0), (1.0, 1.0))
        assert corners is not None  # the loader fills in the default
        return (
            dmesh.create_rectangle(
                comm,
                [np.array(c, dtype=float) for c in corners],
                cells,
                cell_type=dmesh.CellType.triangle,
                diagonal=_DIAGONALS[m.diagonal],
            ),
            None,
            None,
        )
    if kind == "box":
        assert m.corners is not None  # the loader fills in the default
        box = dmesh.create_box(
            comm,
            [np.array(c, dtype=float) for c in m.corners],
            cells,
            cell_type=dmesh.CellType.tetrahedron,
        )
        return box, None, None
    if kind == "lshape":
        return lshape(comm, cells[0], m.diagonal), None, None
    if kind == "blocks":
        assert m.blocks  # required for this type (checked at load)
        return blocks(comm, m.blocks, m.diagonal)
    if kind == "ring":
        assert m.radius is not None and m.inner_radius is not None  # checked at load
        return ring(comm, m.inner_radius, m.radius, cells, m.diagonal)
    if kind == "gmsh":
        assert m.file is not None  # required for this type (checked at load)
        return _read_gmsh(m.file, comm)
    radius, h, h_contact, zone = _sizes(m)  # the parametric gmsh bodies
    if kind in ("quarter_disk", "sphere_octant"):
        build = quarter_disk if kind == "quarter_disk" else sphere_octant
        return (*build(comm, radius, h, h_contact, zone), None)
    if kind == "half_disks":
        radius2, overlap = m.radius2 or radius, m.overlap or 0.0
        return half_disks(comm, radius, radius2, h, h_contact, zone, overlap, m.geometry_degree)
    assert m.block is not None  # sphere_on_block's (checked at load)
    return sphere_on_block(comm, radius, m.block, h, h_contact, zone, m.geometry_degree)


def _sizes(m: MeshConfig) -> tuple[float, float, float, float]:
    """radius, h, h_contact, zone of a parametric gmsh mesh (required: checked at load)."""
    assert m.radius is not None and m.h is not None
    assert m.h_contact is not None and m.zone is not None
    return m.radius, m.h, m.h_contact, m.zone


def lshape(comm: MPI.Comm, n: int, diagonal: str = "right") -> dmesh.Mesh:
    """Structured triangulation of (−1,1)² ∖ [0,1]×[−1,0] with ``n`` cells per unit length."""
    if comm.rank == 0:
        h = 1.0 / n
        grid_i, grid_j = np.meshgrid(np.arange(2 * n), np.arange(2 * n), indexing="ij")
        i, j = grid_i.ravel(), grid_j.ravel()
        keep = ~((i >= n) & (j < n))  # drop the squares of the cut quadrant x > 0, y < 0
        i, j = i[keep], j[keep]
        vid = lambda a, b: a * (2 * n + 1) + b  # noqa: E731
        v00, v10, v01, v11 = vid(i, j), vid(i + 1, j), vid(i, j + 1), vid(i + 1, j + 1)
        if diagonal in ("left", "right/left"):
            tris = np.vstack([np.c_[v00, v10, v01], np.c_[v10, v11, v01]])
        else:
            tris = np.vstack([np.c_[v00, v10, v11], np.c_[v00, v11, v01]])
        used, cells = np.unique(tris, return_inverse=True)
        X = np.c_[(used // (2 * n + 1)) * h - 1.0, (used % (2 * n + 1)) * h - 1.0]
        cells = cells.reshape(-1, 3).astype(np.int64)
    else:
        X, cells = np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    element = ufl.Mesh(basix.ufl.element("Lagrange", "triangle", 1, shape=(2,)))
    return dmesh.create_mesh(
        comm,
        cells,
        element,
        X,
        partitioner=dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet, 2),  # type: ignore[call-arg]
    )


def blocks(
    comm: MPI.Comm, specs: Sequence[Block], diagonal: str = "right"
) -> tuple[dmesh.Mesh, None, dmesh.MeshTags]:
    """Structured blocks meshed independently into one mesh (disconnected components, no
    shared nodes, so their meshes need not match where they touch): triangles (2D, each
    rectangle split along its ``diagonal``, left or right) or tetrahedra (3D, six per box,
    Kuhn's subdivision along the main diagonal).  Built on rank 0 and distributed; the cell
    tag of block k (in the order given) is k + 1."""
    gdim = len(specs[0].corners[0])
    if comm.rank == 0:
        points, simplices, offset = [], [], 0
        for spec in specs:
            X, T = _structured(np.asarray(spec.corners, dtype=float), spec.cells, diagonal)
            points.append(X)
            simplices.append(T + offset)
            offset += len(X)
        counts = [len(T) for T in simplices]
        X, cells = np.vstack(points), np.vstack(simplices).astype(np.int64)
    else:
        X, cells, counts = np.zeros((0, gdim)), np.zeros((0, gdim + 1), dtype=np.int64), None
    counts = comm.bcast(counts, root=0)
    msh = _simplices(comm, X, cells)
    tdim = msh.topology.dim
    n_all = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    original = np.asarray(msh.topology.original_cell_index[:n_all])
    block = np.searchsorted(np.cumsum(counts), original, side="right") + 1
    return (
        msh,
        None,
        dmesh.meshtags(msh, tdim, np.arange(n_all, dtype=np.int32), block.astype(np.int32)),
    )


def ring(
    comm: MPI.Comm, inner: float, outer: float, cells: Sequence[int], diagonal: str = "right"
) -> tuple[dmesh.Mesh, None, dmesh.MeshTags]:
    """The annulus ``inner`` < |x| < ``outer`` centred at the origin, structured in polar
    coordinates: ``cells`` = (n_θ, n_r) quadrilaterals around and across, each cut into two
    triangles along its ``diagonal`` (left or right), the last column closing onto the
    first (one connected body, no seam).  The vertices lie on the circles, so the polygonal
    boundaries are inscribed in them.  Built on rank 0 and distributed; every cell has tag
    1 (one body)."""
    n_t, n_r = cells
    if comm.rank == 0:
        theta = 2.0 * np.pi * np.arange(n_t) / n_t
        r = np.linspace(inner, outer, n_r + 1)
        X = np.stack(
            [np.outer(np.cos(theta), r).ravel(), np.outer(np.sin(theta), r).ravel()], axis=1
        )
        i, j = (a.ravel() for a in np.meshgrid(np.arange(n_t), np.arange(n_r), indexing="ij"))
        node = lambda a, b: (a % n_t) * (n_r + 1) + b  # noqa: E731
        v00, v10, v01, v11 = node(i, j), node(i + 1, j), node(i, j + 1), node(i + 1, j + 1)
        if diagonal == "left":
            T = np.vstack([np.c_[v00, v10, v01], np.c_[v10, v11, v01]])
        else:
            T = np.vstack([np.c_[v00, v10, v11], np.c_[v00, v11, v01]])
        T = T.astype(np.int64)
    else:
        X, T = np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    msh = _simplices(comm, X, T)
    tdim = msh.topology.dim
    n_all = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    ones = np.ones(n_all, dtype=np.int32)
    return msh, None, dmesh.meshtags(msh, tdim, np.arange(n_all, dtype=np.int32), ones)


def _simplices(comm: MPI.Comm, X: np.ndarray, cells: np.ndarray) -> dmesh.Mesh:
    """The P1 simplex mesh of vertices X and ``cells`` given on rank 0 (empty on the
    others), distributed over ``comm`` with shared-facet ghosts."""
    gdim = X.shape[1]
    shape = "triangle" if gdim == 2 else "tetrahedron"
    element = ufl.Mesh(basix.ufl.element("Lagrange", shape, 1, shape=(gdim,)))
    return dmesh.create_mesh(
        comm,
        cells,
        element,
        X,
        partitioner=dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet, 2),  # type: ignore[call-arg]
    )


def _structured(
    corners: np.ndarray, n: Sequence[int], diagonal: str
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and simplices of one structured block with ``n`` cells per direction."""
    axes = [np.linspace(lo, hi, k + 1) for lo, hi, k in zip(corners[0], corners[1], n)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(n))
    ijk = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), axis=-1).reshape(
        -1, len(n)
    )
    strides = np.cumprod([1] + [k + 1 for k in n[::-1]])[::-1][1:]  # vertex (i, j[, k]) → index
    corner = lambda *offs: (ijk + np.array(offs)) @ strides  # noqa: E731
    if len(n) == 2:
        v00, v10, v01, v11 = corner(0, 0), corner(1, 0), corner(0, 1), corner(1, 1)
        if diagonal == "left":
            return X, np.vstack([np.c_[v00, v10, v01], np.c_[v10, v11, v01]])
        return X, np.vstack([np.c_[v00, v10, v11], np.c_[v00, v11, v01]])
    v = {b: corner(b & 1, (b >> 1) & 1, (b >> 2) & 1) for b in range(8)}  # vertex b = i + 2j + 4k
    tets = ((0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7))
    return X, np.vstack([np.c_[tuple(v[b] for b in t)] for t in tets])


def _read_gmsh(
    path: str, comm: MPI.Comm
) -> tuple[dmesh.Mesh, dmesh.MeshTags | None, dmesh.MeshTags | None]:
    return gmsh_to_mesh(
        comm,
        lambda gmsh: gmsh.merge(path),
        f"mesh.file: cannot read {path!r} as a gmsh mesh",
        cells=True,
    )


def tag_bodies(
    msh: dmesh.Mesh, cfg: SceneConfig, cell_tags: dmesh.MeshTags | None = None
) -> dmesh.MeshTags | None:
    """Cell tags of the scene's ``bodies`` (value k + 1 for the k-th body, on every local
    cell, ghosts included), or None for a scene without bodies.  A body takes the cells of
    a mesh cell tag (``tag``) or those whose midpoint satisfies ``where``.  A body with no
    cell, an unknown tag, a cell in two bodies or in none is a ConfigError."""
    bodies = cfg.bodies
    if not bodies:
        return None
    comm, tdim = msh.comm, msh.topology.dim
    n_all = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    file_ids = set()
    if cell_tags is not None:
        file_ids = set(int(v) for v in np.concatenate(comm.allgather(np.unique(cell_tags.values))))
    midpoints = None
    n_owned = msh.topology.index_map(tdim).size_local
    value = np.zeros(n_all, dtype=np.int32)
    for k, (name, body) in enumerate(bodies.items()):
        if body.tag is not None:
            if body.tag not in file_ids:
                known = ", ".join(map(str, sorted(file_ids))) or "none"
                raise ConfigError(
                    f"bodies.{name}.tag: tag {body.tag} does not exist in the mesh (cell "
                    f"tags: {known})"
                )
            assert cell_tags is not None  # file_ids are its values
            cells = cell_tags.indices[cell_tags.values == body.tag]
        else:
            if midpoints is None:
                midpoints = dmesh.compute_midpoints(msh, tdim, np.arange(n_all, dtype=np.int32))
            assert body.where is not None  # one of tag / where (checked at load)
            pred = expressions.to_numpy(body.where, cfg.constants)
            cells = np.flatnonzero(pred(midpoints.T).astype(bool))
        if comm.allreduce(int(np.count_nonzero(cells < n_owned)), op=MPI.SUM) == 0:
            what = f"where {body.where!r}" if body.tag is None else f"tag {body.tag}"
            raise ConfigError(f"bodies.{name}: {what} selects no cell")
        twice = comm.allreduce(int(np.count_nonzero(value[cells[cells < n_owned]])), op=MPI.SUM)
        if twice:
            raise ConfigError(f"bodies.{name}: {twice} of its cells belong to an earlier body too")
        value[cells] = k + 1
    orphans = comm.allreduce(int(np.count_nonzero(value[:n_owned] == 0)), op=MPI.SUM)
    if orphans:
        raise ConfigError(f"bodies: {orphans} cells belong to no body (each cell needs a material)")
    return dmesh.meshtags(msh, tdim, np.arange(n_all, dtype=np.int32), value)


def body_facets(
    msh: dmesh.Mesh, bodies: dmesh.MeshTags, body: int, facets: np.ndarray
) -> np.ndarray:
    """The exterior ``facets`` whose cell belongs to body number ``body`` (1-based)."""
    tdim = msh.topology.dim
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    first_cell = f2c.array[f2c.offsets[facets]]
    return facets[bodies.values[first_cell] == body]


def tag_boundaries(
    msh: dmesh.Mesh,
    cfg: SceneConfig,
    file_tags: dmesh.MeshTags | None = None,
    bodies: dmesh.MeshTags | None = None,
) -> Boundary:
    """Mark every boundary part of ``cfg.boundaries`` on the exterior facets.

    A ``where`` predicate selects exterior facets all of whose vertices satisfy it; a
    ``tag`` selects the gmsh physical facet group (with ``where`` too: those of its facets
    that satisfy it); ``body`` keeps only the facets of that body's cells (``bodies``:
    :func:`tag_bodies`).  A part selecting no facet anywhere, an unknown tag, or two parts sharing a
    facet are ConfigErrors.  Exterior facets left unmarked carry the natural condition k ∂u/∂n = 0
    (the part :data:`NATURAL`, reported by :func:`contact.setup.untagged.untagged_boundary`).
    """
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    exterior = dmesh.exterior_facet_indices(msh.topology)
    comm = msh.comm
    file_ids = set()
    if file_tags is not None:
        file_ids = set(int(v) for v in np.concatenate(comm.allgather(np.unique(file_tags.values))))
    next_id = max(file_ids, default=0) + 1
    ids, roles, chunks = {}, {}, []
    for name, part in cfg.boundaries.items():
        facets = exterior
        if part.tag is not None:
            if file_tags is None or part.tag not in file_ids:
                known = ", ".join(map(str, sorted(file_ids))) or "none"
                raise ConfigError(
                    f"boundaries.{name}.tag: tag {part.tag} does not exist in the mesh "
                    f"file (facet tags: {known})"
                )
            facets = file_tags.indices[file_tags.values == part.tag]
        if part.where is not None:
            pred = expressions.to_numpy(part.where, cfg.constants)
            located = dmesh.locate_entities_boundary(
                msh, tdim - 1, lambda x, pred=pred: pred(x).astype(bool)
            )
            facets = np.intersect1d(facets, located)
        if part.body is not None:  # a body of the scene's bodies (checked at load)
            assert bodies is not None and cfg.bodies is not None
            facets = body_facets(msh, bodies, list(cfg.bodies).index(part.body) + 1, facets)
        if part.tag is not None and part.where is None and part.body is None:
            pid = part.tag  # the whole gmsh group keeps its tag
        else:
            pid = next_id
            next_id += 1
        if comm.allreduce(len(facets), op=MPI.SUM) == 0:
            what = " and ".join(
                ([f"tag {part.tag}"] if part.tag is not None else [])
                + ([f"where {part.where!r}"] if part.where is not None else [])
            )
            what += f" on body {part.body}" if part.body is not None else ""
            raise ConfigError(f"boundaries.{name}: {what} selects no boundary facet")
        ids[name], roles[name] = pid, part.role
        chunks.append((facets.astype(np.int32), np.full(len(facets), pid, dtype=np.int32), name))
    all_facets = np.concatenate([c[0] for c in chunks])
    uniq, counts = np.unique(all_facets, return_counts=True)
    shared = comm.allreduce(int(np.sum(counts > 1)), op=MPI.SUM)
    if shared:
        # The first two parts, in the order of boundaries, that share a facet on any rank.
        pairs = [
            (i, j)
            for i in range(len(chunks))
            for j in range(i + 1, len(chunks))
            if np.intersect1d(chunks[i][0], chunks[j][0]).size
        ]
        i, j = min(comm.allreduce(pairs, op=MPI.SUM))
        pair = f"{chunks[i][2]} and {chunks[j][2]}"
        raise ConfigError(f"boundaries: {pair} share {shared} facet(s); parts must not overlap")
    # Exterior facets of no part: the natural condition k ∂u/∂n = 0, tagged so that the
    # estimator sees them as Neumann edges with t = 0.
    free = np.setdiff1d(exterior, all_facets).astype(np.int32)
    if comm.allreduce(len(free), op=MPI.SUM):
        ids[NATURAL], roles[NATURAL] = next_id, "natural"
        all_facets = np.concatenate([all_facets, free])
        chunks.append((free, np.full(len(free), next_id, dtype=np.int32), NATURAL))
    values = np.concatenate([c[1] for c in chunks])
    order = np.argsort(all_facets)
    tags = dmesh.meshtags(msh, tdim - 1, all_facets[order], values[order])
    return Boundary(tags, ids, roles)
