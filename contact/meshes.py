"""Meshes and boundary parts of a scene.

Built-in meshes need nothing but DOLFINx: ``rectangle``/``unit_square`` and ``box``
(structured simplices) and ``lshape`` (Ω = (−1,1)² ∖ [0,1]×[−1,0], SPEC §7 D, built from
NumPy arrays).  Only ``gmsh`` scenes import gmsh, to read a ``.msh`` file with physical
tags.  A built-in mesh may be deformed by ``mesh.map`` (:func:`map_geometry`) before its
boundary parts are tagged.  Boundary parts become one facet ``MeshTags`` whose values are
the part ids.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

import basix.ufl
import ufl
from dolfinx import mesh as dmesh

from . import expressions
from .config import ConfigError

_DIAGONALS = {"left": dmesh.DiagonalType.left, "right": dmesh.DiagonalType.right,
              "crossed": dmesh.DiagonalType.crossed, "left/right": dmesh.DiagonalType.left_right,
              "right/left": dmesh.DiagonalType.right_left}


NATURAL = "(natural)"  # name of the part of unmarked exterior facets


@dataclass
class Boundary:
    """Facet tags of the scene's boundary parts: ``ids[name]`` is the tag value of a part,
    ``roles[name]`` its role (dirichlet, neumann, contact, or natural for the exterior
    facets no part selects: k ∂u/∂n = 0)."""

    tags: dmesh.MeshTags
    ids: dict[str, int]
    roles: dict[str, str]

    def ids_with_role(self, role: str) -> tuple[int, ...]:
        return tuple(self.ids[n] for n, r in self.roles.items() if r == role)

    def facets(self, role: str) -> np.ndarray:
        """Local facet indices of all parts with ``role``."""
        ids = self.ids_with_role(role)
        return np.sort(self.tags.indices[np.isin(self.tags.values, ids)]).astype(np.int32)


def mesh_dimension(cfg: dict) -> int | None:
    """The geometric dimension of the scene's mesh, from its type (None for a gmsh file)."""
    return {"rectangle": 2, "unit_square": 2, "lshape": 2, "quarter_disk": 2,
            "box": 3, "sphere_octant": 3}.get(cfg["mesh"]["type"])


def build_mesh(cfg: dict, comm: MPI.Comm = MPI.COMM_WORLD) -> tuple[dmesh.Mesh, dmesh.MeshTags | None]:
    """The mesh described by ``cfg['mesh']`` (mapped by ``mesh.map`` if given); for gmsh
    files also their facet tags."""
    msh, tags = _built_mesh(cfg, comm)
    if cfg["mesh"].get("map") is not None:
        map_geometry(msh, cfg["mesh"]["map"], cfg["constants"])
    return msh, tags


def map_geometry(msh: dmesh.Mesh, exprs: list[str], constants: dict[str, float] | None = None,
                 key: str = "mesh.map", tol: float = 1e-12) -> None:
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
        first = [old[:gdim, _geometry_nodes(msh)[bad[0]]].mean(axis=1)] if len(bad) else []
        where = next(p for p in comm.allgather(first) if p)[0]
        at = ", ".join(f"{c} = {v:.4g}" for c, v in zip("xyz", where))
        total = msh.topology.index_map(msh.topology.dim).size_global
        raise ConfigError(f"{key}: the map inverts or flattens {n_bad} of {total} cells (Jacobian "
                          f"determinant ≤ 0), e.g. the cell at {at} (unmapped)")


def _geometry_nodes(msh: dmesh.Mesh) -> np.ndarray:
    """The vertex geometry nodes of each cell (local cells, ghosts included)."""
    return msh.geometry.dofmaps[0][:, : msh.topology.dim + 1]


def signed_volumes(msh: dmesh.Mesh) -> np.ndarray:
    """det(x_1 − x_0, …, x_d − x_0) of each simplex (d! times its signed volume, in the
    mesh's length unit to the power d), local cells with ghosts."""
    gdim = msh.geometry.dim
    P = msh.geometry.x[_geometry_nodes(msh)][:, :, :gdim]
    return np.linalg.det(P[:, 1:] - P[:, :1])


def collapsed_cells(msh: dmesh.Mesh, before: np.ndarray, tol: float = 1e-12) -> tuple[np.ndarray, int]:
    """The owned cells a move of the geometry nodes inverted or flattened, and their number
    over all ranks (collective).

    ``before`` is :func:`signed_volumes` before the move; with J_T = det_after / det_before
    the cell's (mean) Jacobian determinant of the move, a cell is bad if
    J_T ≤ tol · max_T |J_T| (maximum over all ranks).
    """
    jac = signed_volumes(msh) / before
    owned = msh.topology.index_map(msh.topology.dim).size_local
    scale = msh.comm.allreduce(float(np.max(np.abs(jac[:owned]), initial=0.0)), op=MPI.MAX)
    bad = np.flatnonzero(jac[:owned] <= tol * scale)
    return bad, msh.comm.allreduce(len(bad), op=MPI.SUM)


def _built_mesh(cfg: dict, comm: MPI.Comm) -> tuple[dmesh.Mesh, dmesh.MeshTags | None]:
    """The mesh of ``cfg['mesh']`` as built, before any map."""
    m = cfg["mesh"]
    kind = m["type"]
    if kind in ("rectangle", "unit_square"):
        corners = m["corners"] if kind == "rectangle" else [[0.0, 0.0], [1.0, 1.0]]
        return dmesh.create_rectangle(comm, [np.array(c, dtype=float) for c in corners], m["cells"],
                                      cell_type=dmesh.CellType.triangle,
                                      diagonal=_DIAGONALS[m["diagonal"]]), None
    if kind == "box":
        return dmesh.create_box(comm, [np.array(c, dtype=float) for c in m["corners"]], m["cells"],
                                cell_type=dmesh.CellType.tetrahedron), None
    if kind == "lshape":
        return lshape(comm, m["cells"][0], m["diagonal"]), None
    if kind in ("quarter_disk", "sphere_octant"):  # gmsh, built from the parameters
        from . import geometry

        build = geometry.quarter_disk if kind == "quarter_disk" else geometry.sphere_octant
        return build(comm, m["radius"], m["h"], m["h_contact"], m["zone"])
    return _read_gmsh(m["file"], comm)


def lshape(comm: MPI.Comm, n: int, diagonal: str = "right") -> dmesh.Mesh:
    """Structured triangulation of (−1,1)² ∖ [0,1]×[−1,0] with ``n`` cells per unit length."""
    if comm.rank == 0:
        h = 1.0 / n
        i, j = np.meshgrid(np.arange(2 * n), np.arange(2 * n), indexing="ij")
        i, j = i.ravel(), j.ravel()
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
    return dmesh.create_mesh(comm, cells, element, X,
                             partitioner=dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet, 2))


def _read_gmsh(path: str, comm: MPI.Comm) -> tuple[dmesh.Mesh, dmesh.MeshTags | None]:
    return gmsh_to_mesh(comm, lambda gmsh: gmsh.merge(path), f"mesh.file: cannot read {path!r} as a gmsh mesh")


def gmsh_to_mesh(comm: MPI.Comm, build, error: str, gdim: int | None = None
                 ) -> tuple[dmesh.Mesh, dmesh.MeshTags | None]:
    """Run ``build(gmsh)`` on rank 0 (gmsh's terminal output off) and distribute the mesh
    with its physical groups; the geometric dimension is the model's unless given.  Any
    failure is one ConfigError line ``<error>: <gmsh's message>``, raised on every rank."""
    import gmsh  # only for gmsh scenes
    from dolfinx.io import gmsh as gmshio

    problem = None
    if comm.rank == 0:
        gmsh.initialize(interruptible=False)
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("scene")
        try:
            build(gmsh)
            gdim = gdim or gmsh.model.getDimension()
        except Exception as err:  # gmsh reports its errors as generic exceptions
            problem = str(err) or type(err).__name__
    problem, gdim = comm.bcast((problem, gdim), root=0)
    try:
        if problem is None:
            data = gmshio.model_to_mesh(gmsh.model if comm.rank == 0 else None, comm, 0, gdim=gdim,
                                        partitioner=dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet, 2))
    except Exception as err:  # e.g. no physical groups (raised on every rank)
        problem = str(err)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    if problem is not None:
        raise ConfigError(f"{error}: {' '.join(problem.split())}")
    return data.mesh, data.facet_tags


def tag_boundaries(msh: dmesh.Mesh, cfg: dict, file_tags: dmesh.MeshTags | None = None) -> Boundary:
    """Mark every boundary part of ``cfg['boundaries']`` on the exterior facets.

    A ``where`` predicate selects exterior facets all of whose vertices satisfy it; a
    ``tag`` selects the gmsh physical facet group.  A part selecting no facet anywhere, an
    unknown tag, or two parts sharing a facet are ConfigErrors.  Exterior facets left
    unmarked carry the natural condition k ∂u/∂n = 0.
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
    for name, part in cfg["boundaries"].items():
        if part["tag"] is not None:
            if file_tags is None or part["tag"] not in file_ids:
                known = ", ".join(map(str, sorted(file_ids))) or "none"
                raise ConfigError(f"boundaries.{name}.tag: tag {part['tag']} does not exist in the mesh file (facet tags: {known})")
            pid = part["tag"]
            facets = file_tags.indices[file_tags.values == pid]
        else:
            pid = next_id
            next_id += 1
            pred = expressions.to_numpy(part["where"], cfg["constants"])
            facets = dmesh.locate_entities_boundary(msh, tdim - 1, lambda x: pred(x).astype(bool))
            facets = np.intersect1d(facets, exterior)
        if comm.allreduce(len(facets), op=MPI.SUM) == 0:
            what = f"where {part['where']!r}" if part["tag"] is None else f"tag {part['tag']}"
            raise ConfigError(f"boundaries.{name}: {what} selects no boundary facet")
        ids[name], roles[name] = pid, part["role"]
        chunks.append((facets.astype(np.int32), np.full(len(facets), pid, dtype=np.int32), name))
    all_facets = np.concatenate([c[0] for c in chunks])
    uniq, counts = np.unique(all_facets, return_counts=True)
    shared = comm.allreduce(int(np.sum(counts > 1)), op=MPI.SUM)
    if shared:
        dup = uniq[counts > 1]
        names = [c[2] for c in chunks if np.isin(c[0], dup).any()] if len(dup) else []
        names = comm.allreduce(names, op=MPI.SUM)
        pair = " and ".join(sorted(set(names))[:2]) or "two parts"
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
