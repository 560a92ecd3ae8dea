"""The exterior facets that belong to no boundary part, reported on every run.

A boundary part's ``where`` predicate selects the exterior facets *all* of whose vertices
satisfy it (as DOLFINx's ``locate_entities_boundary``).  A facet with one vertex on each
side of a predicate's edge — at a corner where two parts meet, e.g. ``y > 1e-10`` beside
``y < 1e-10`` — is then in neither part, and the problem solved there is the natural
condition k ∂u/∂n = 0 (elasticity: σ(u) n = 0), whatever the scene meant.  So that this is
always a visible choice, :func:`untagged_boundary` measures those facets — their number,
total measure (length in 2D, area in 3D) and where they are (bounding box, and the parts
they touch) — for the one line the command line prints on every run and for
``summary.json``; the Python API gives the same line as a warning (:func:`warn_untagged`).
Parts declared with ``role: natural`` are a choice made in the scene and are not counted.
"""

from __future__ import annotations

import warnings
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from dolfinx import la
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..base.errors import ContactWarning
from .meshes import NATURAL, Boundary

if TYPE_CHECKING:
    from .scene import Scene


@dataclass(frozen=True)
class Untagged:
    """Exterior facets in no boundary part: ``facets`` (global count, each facet once over
    the ranks), ``measure`` (their total length in 2D, area in 3D, in the mesh's unit),
    the corners ``lower``, ``upper`` of their bounding box (None without any), and the
    names of the parts that share a vertex with them (``next_to``)."""

    facets: int
    measure: float
    lower: tuple[float, ...] | None = None
    upper: tuple[float, ...] | None = None
    next_to: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        """The report as JSON data (``summary.json``'s ``untagged_boundary``)."""
        where = None
        if self.lower is not None and self.upper is not None:
            where = {"lower": list(self.lower), "upper": list(self.upper)}
        return {
            "facets": self.facets,
            "measure": self.measure,
            "where": where,
            "next_to": list(self.next_to),
        }

    def line(self, elastic: bool = False) -> str:
        """One line (≤ 300 characters) for the run's log: the count, measure and place of the
        untagged facets and the condition they carry (``elastic``: traction-free), or that
        there are none."""
        if not self.facets:
            return "boundary: every exterior facet is in a boundary part"
        assert self.lower is not None and self.upper is not None
        scale = max(1.0, *(abs(v) for v in self.lower + self.upper))
        show = lambda v: f"{0.0 if abs(v) < 1e-10 * scale else v:.4g}"  # noqa: E731
        box = ", ".join(
            f"{c} ∈ [{show(lo)}, {show(hi)}]" for c, lo, hi in zip("xyz", self.lower, self.upper)
        )
        condition = "σ(u)n = 0" if elastic else "k ∂u/∂n = 0"
        unit = "length" if len(self.lower) == 2 else "area"
        text = (
            f"boundary: {self.facets} exterior facet(s) ({unit} {self.measure:.4g}) in no part "
            f"carry the natural condition {condition}: {box}"
        )
        hint = " (declare them with role: natural, or widen a part's where)"
        for shown in (4, 2, 0):  # as many neighbouring parts as fit
            names = list(self.next_to[:shown]) + (["…"] if len(self.next_to) > shown else [])
            near = f", next to {', '.join(names)}" if names else ""
            if len(text + near + hint) <= LINE:
                break
        return text + near + hint


#: the longest line :meth:`Untagged.line` gives (the CLI adds "contact: ", 9 characters)
LINE = 290


def untagged_boundary(msh: dmesh.Mesh, boundary: Boundary) -> Untagged:
    """The exterior facets of ``msh`` that no part of ``boundary`` selects (the facets
    :func:`contact.setup.meshes.tag_boundaries` tags as the part ``(natural)``).

    Collective.  Counts and measures sum the owned facets of every rank, so ghost facets are
    not counted twice and the report is the same on any number of ranks."""
    comm, tdim = msh.comm, msh.topology.dim
    pid = boundary.ids.get(NATURAL)
    facets = np.zeros(0, dtype=np.int32)
    if pid is not None:
        facets = boundary.tags.find(pid)
        facets = facets[facets < msh.topology.index_map(tdim - 1).size_local]
    count = comm.allreduce(len(facets), op=MPI.SUM)
    if count == 0:
        return Untagged(0, 0.0)
    gdim = msh.geometry.dim
    nodes = dmesh.entities_to_geometry(msh, tdim - 1, facets)
    X = msh.geometry.x[nodes][:, :, :gdim]  # (facets, vertices, gdim); affine facets
    if tdim == 2:
        sizes = np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
    else:
        edges = np.zeros((len(X), 3))
        edges[:, :gdim] = X[:, 1] - X[:, 0]
        other = np.zeros((len(X), 3))
        other[:, :gdim] = X[:, 2] - X[:, 0]
        sizes = 0.5 * np.linalg.norm(np.cross(edges, other), axis=1)
    measure = comm.allreduce(float(sizes.sum()), op=MPI.SUM)
    points = X.reshape(-1, gdim)
    lower, upper = np.full(gdim, np.inf), np.full(gdim, -np.inf)
    if len(points):
        lower, upper = points.min(axis=0), points.max(axis=0)
    comm.Allreduce(MPI.IN_PLACE, lower, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, upper, op=MPI.MAX)
    return Untagged(
        count,
        measure,
        tuple(float(v) for v in lower),
        tuple(float(v) for v in upper),
        _neighbours(msh, boundary, facets),
    )


#: the meshes of the scenes whose untagged facets were reported (the scenes loaded, not
#: those refined from them): :func:`warn_untagged` warns once per scene
_REPORTED: weakref.WeakSet = weakref.WeakSet()


def _loaded(scene: Scene) -> Scene:
    """The scene ``scene`` was refined from (itself if loaded)."""
    while scene.parent is not None:
        scene = scene.parent[0]
    return scene


def mark_reported(scene: Scene) -> None:
    """Record that the untagged facets of ``scene`` (and of the scenes refined from the same
    loaded scene) were reported: the command line printed its line, so the public API it
    calls gives no warning."""
    _REPORTED.add(_loaded(scene).mesh)


def report_as(refined: Scene, scene: Scene) -> None:
    """Count the untagged facets of ``refined``, a refinement of ``scene`` not linked to it
    (no ``parent``), as reported where those of ``scene`` were."""
    if _loaded(scene).mesh in _REPORTED:
        _REPORTED.add(refined.mesh)


def warn_untagged(scene: Scene) -> None:
    """Warn once per scene when exterior facets are in no boundary part.

    The line :meth:`Untagged.line` of ``scene`` as a :class:`ContactWarning` on rank 0, the
    first time the public API (``contact.solve``, ``adapt``, ``run_load_path``,
    ``estimate``, ``refine``) is called with the scene or with a scene refined from it (the
    parts, and so the facets in none, are those of the scene loaded), unless the command
    line reported them (:func:`mark_reported`).  Collective on that first call; the later
    ones cost nothing.

    Args:
        scene: the scene a public function was called with.
    """
    if _loaded(scene).mesh in _REPORTED:
        return
    mark_reported(scene)
    untagged = untagged_boundary(scene.mesh, scene.boundary)
    if untagged.facets and scene.comm.rank == 0:
        warnings.warn(untagged.line(scene.config.elastic), ContactWarning, stacklevel=3)


def _neighbours(msh: dmesh.Mesh, boundary: Boundary, facets: np.ndarray) -> tuple[str, ...]:
    """The names of the parts with a facet that shares a vertex with one of ``facets``
    (owned facets of the untagged part).  Every rank marks the vertices of its tagged facets
    part by part in a vector over the vertex index map; a reverse scatter (add) and a forward
    scatter give every rank the marks of its vertices from all ranks."""
    tdim = msh.topology.dim
    names = [n for n in boundary.ids if n != NATURAL]
    if not names:
        return ()
    msh.topology.create_connectivity(tdim - 1, 0)
    f2v = msh.topology.connectivity(tdim - 1, 0)
    corners = np.arange(tdim)  # a simplex facet has tdim vertices

    def vertices(of: np.ndarray) -> np.ndarray:
        return f2v.array[(f2v.offsets[of][:, None] + corners).ravel()]

    marks = la.vector(msh.topology.index_map(0), bs=len(names))
    for k, name in enumerate(names):
        marks.array[vertices(boundary.tags.find(boundary.ids[name])) * len(names) + k] = 1.0
    marks.scatter_reverse(la.InsertMode.add)
    marks.scatter_forward()
    near = np.zeros(len(names), dtype=np.int32)
    if len(facets):
        near[:] = (marks.array.reshape(-1, len(names))[vertices(facets)] > 0).any(axis=0)
    msh.comm.Allreduce(MPI.IN_PLACE, near, op=MPI.MAX)
    return tuple(n for n, hit in zip(names, near) if hit)
