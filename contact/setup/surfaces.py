"""Exact surfaces of boundary parts, so that refinement follows the geometry, not the chords.

``dolfinx.mesh.refine`` puts new vertices at edge midpoints: a curved boundary keeps the
coarse polygon and quantities along it (the contact pressure) drift with every level.  A
boundary part may declare the surface it lies on,

    boundaries:
      arc: {role: contact, tag: 1, surface: {type: circle, center: [0, 1], radius: 1}}
                                    # sphere: center [x, y, z]; cylinder: + axis [ax, ay, az]

and :func:`boundary_surfaces` gives a :class:`contact.setup.geometry.CurvedBoundary` per such part
(and for tag 1 of the built-in ``quarter_disk`` / ``sphere_octant``), whose ``snap`` moves
the refined mesh's vertices of that part onto the surface.  :func:`looks_curved` tells a
polygonal contact boundary from a discretized curve, for the one-line warning a gmsh
scene without a declared surface gets when it is refined.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from dolfinx import mesh as dmesh

from ..base.errors import ConfigError, ContactWarning
from .geometry import CurvedBoundary, builder_surfaces, curved_boundary
from .meshes import Boundary
from .scene_config import SceneConfig, SurfaceSpec

if TYPE_CHECKING:
    from ..adaptivity.refine import Domain

#: a ridge (vertex in 2D, edge in 3D) between two facets bends if their normals differ by more
BEND = 1e-4  # radians
_checked: dict[tuple, bool] = {}


def declared_surface(name: str, spec: SurfaceSpec, gdim: int, tag: int) -> CurvedBoundary:
    """The CurvedBoundary of ``boundaries.<name>.surface`` on a ``gdim``-dimensional mesh;
    a ConfigError naming the key if it does not fit."""
    key = f"boundaries.{name}.surface"
    want = {"circle": 2, "sphere": 3, "cylinder": 3}[spec.type]
    if gdim != want:
        raise ConfigError(f"{key}.type: a {spec.type} needs a {want}D mesh, this one is {gdim}D")
    centre = spec.center
    if len(centre) != gdim:
        raise ConfigError(f"{key}.center: needs {gdim} coordinates, got {len(centre)}")
    axis = spec.axis
    if (axis is not None) != (spec.type == "cylinder"):
        raise ConfigError(
            f"{key}.axis: "
            + (
                "required for a cylinder"
                if axis is None
                else f"only for a cylinder, not a {spec.type}"
            )
        )
    if axis is not None and (len(axis) != 3 or not np.any(axis)):
        raise ConfigError(f"{key}.axis: must be a non-zero vector of 3 numbers, got {list(axis)!r}")
    return CurvedBoundary(
        centre=tuple(float(c) for c in centre),
        radius=float(spec.radius),
        tag=tag,
        axis=None if axis is None else tuple(float(a) for a in axis),
    )


def boundary_surfaces(cfg: SceneConfig, gdim: int, boundary: Boundary) -> list[CurvedBoundary]:
    """The exact surfaces refinement snaps to, in ``gdim`` dimensions: the built-in Hertz
    meshes' curved tag, and every part of ``boundary`` with a declared ``surface``."""
    out = [s for s in (curved_boundary(cfg.mesh),) if s is not None]
    for name, part in cfg.boundaries.items():
        if part.surface is not None:
            out.append(declared_surface(name, part.surface, gdim, boundary.ids[name]))
    return out


def snapping(cfg: SceneConfig, boundary: Boundary) -> Callable[[Domain, Domain], None]:
    """Return how a refinement of the scene's mesh keeps to its curved surfaces.

    The ``snap(parent, child)`` of a :class:`~contact.adaptivity.refine.Domain`: after a
    refinement it moves the child's new vertices on each part with a declared ``surface``
    (and on the built-in Hertz meshes' curved tag) onto that surface, and on the surfaces
    the mesh builder tagged (``child.tags["surfaces"]``) onto theirs; a gmsh contact part
    that looks curved but declares no surface gets its one warning line.  Built once per
    scene from its configuration and boundary parts (ids and roles do not change under
    refinement).

    Args:
        cfg: The scene's configuration.
        boundary: The scene's boundary parts (their ids and roles are kept).

    Returns:
        The snapping, collective.
    """
    ids, roles = dict(boundary.ids), dict(boundary.roles)
    built = builder_surfaces(cfg.mesh)

    def snap(parent: Domain, child: Domain) -> None:
        assert parent.facets is not None and child.facets is not None  # a scene's boundary
        tagged = Boundary(parent.facets, ids, roles)
        warn_undeclared_curves(cfg, parent.mesh, tagged)
        for surface in boundary_surfaces(cfg, parent.mesh.geometry.dim, tagged):
            surface.snap(child.mesh, child.facets)
        for surface in built:  # by the mesh's own tags of its curved surfaces
            surface.snap(child.mesh, child.tags["surfaces"])

    return snap


def ridge_angles(facets: np.ndarray) -> np.ndarray:
    """Angles (radians, in [0, π/2]) between the normals of boundary facets that share a
    ridge: ``facets`` (m, d, d) holds the d vertices of each facet in d dimensions (segments
    in 2D, triangles in 3D); ridges are their shared vertices (2D) or edges (3D)."""
    if len(facets) == 0:
        return np.zeros(0)
    d = facets.shape[1]
    if d == 2:
        t = facets[:, 1] - facets[:, 0]
        normals = np.c_[-t[:, 1], t[:, 0]]
    else:
        normals = np.cross(facets[:, 1] - facets[:, 0], facets[:, 2] - facets[:, 0])
    normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    scale = float(np.max(np.abs(facets))) or 1.0
    keys = np.round(facets / scale, 9)
    owners: dict[tuple, list[int]] = {}
    for f in range(len(facets)):
        verts = [tuple(v) for v in keys[f]]
        ridges = (
            verts
            if d == 2
            else [tuple(sorted((verts[i], verts[j]))) for i, j in ((0, 1), (1, 2), (0, 2))]
        )
        for r in ridges:
            owners.setdefault(r, []).append(f)
    pairs = np.array([fs for fs in owners.values() if len(fs) == 2], dtype=int).reshape(-1, 2)
    cos = np.abs(np.sum(normals[pairs[:, 0]] * normals[pairs[:, 1]], axis=1))
    return np.arccos(np.clip(cos, 0.0, 1.0))


def looks_curved(msh: dmesh.Mesh, boundary: Boundary, name: str) -> bool:
    """Whether part ``name`` of ``boundary`` looks like a discretized curve or curved surface:
    most of its ridges bend (a polygon or polyhedron bends at a few corners only).  Collective."""
    tdim = msh.topology.dim
    facets = boundary.tags.find(boundary.ids[name])
    facets = facets[facets < msh.topology.index_map(tdim - 1).size_local]
    nodes = dmesh.entities_to_geometry(msh, tdim - 1, facets)[:, :tdim]
    parts = msh.comm.gather(msh.geometry.x[nodes][:, :, :tdim], root=0)
    curved = None
    if msh.comm.rank == 0:
        angles = ridge_angles(np.concatenate(parts))
        curved = bool(len(angles) >= 3 and np.mean(angles > BEND) > 0.5)
    return msh.comm.bcast(curved, root=0)


def warn_undeclared_curves(cfg: SceneConfig, msh: dmesh.Mesh, boundary: Boundary) -> None:
    """Warn once per gmsh file and part when a contact part of a gmsh mesh looks curved and
    declares no ``surface``: refinement keeps its chords (collective; rank 0 warns)."""
    if cfg.mesh.type != "gmsh":
        return
    for name, part in cfg.boundaries.items():
        key = (cfg.mesh.file, name)
        if part.role != "contact" or part.surface is not None or key in _checked:
            continue
        _checked[key] = looks_curved(msh, boundary, name)
        if _checked[key] and msh.comm.rank == 0:
            warnings.warn(
                f"boundaries.{name}: the contact boundary of {cfg.mesh.file} looks curved "
                "but declares no surface; refinement keeps its chords (declare "
                "boundaries."
                f"{name}.surface: {{type: circle|sphere|cylinder, center, radius}})",
                ContactWarning,
                stacklevel=2,
            )
