"""A domain reduced to what makes it: its cells, vertices and geometry.

A dolfinx mesh carries, besides its cells' vertices and its geometry, every entity and
connectivity computed on it so far: the facets, facet → vertex, facet → cell, cell → facet,
…, on a triangle mesh about twice the memory of the cells and the geometry.  Each of them is
a function of the cells' vertices (dolfinx numbers the entities of a dimension from the
cells' vertices and the vertex index map alone), so a mesh holding only its cells, its
vertex and cell index maps and its geometry can compute them again, the same entity for
entity, on any number of ranks.  :func:`bare` makes such a copy of a domain, its tags kept
as arrays; :meth:`BareDomain.whole` gives the domain back, its mesh's connectivities
computed again and its tags made again on it.  The adaptive loop holds the level before the
one it solves so (``contact.drivers.adaptive.Level.stow``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ufl
from dolfinx import cpp
from dolfinx import mesh as dmesh

from .refine import Domain


@dataclass
class Tags:
    """The arrays of a set of mesh tags (:func:`dolfinx.mesh.meshtags`), kept off its mesh."""

    dim: int
    indices: np.ndarray
    values: np.ndarray
    name: str

    @classmethod
    def of(cls, tags: dmesh.MeshTags) -> Tags:
        """Return the arrays of ``tags`` (copies)."""
        return cls(tags.dim, tags.indices.copy(), tags.values.copy(), tags.name)

    def on(self, msh: dmesh.Mesh) -> dmesh.MeshTags:
        """Return the tags made again on ``msh`` (whose entities of ``dim`` exist)."""
        made = dmesh.meshtags(msh, self.dim, self.indices, self.values)
        made.name = self.name
        return made


@dataclass
class BareDomain:
    """A :class:`~contact.adaptivity.refine.Domain` whose mesh keeps its cells only.

    Attributes:
        mesh: The mesh with its cells' vertices, its vertex and cell index maps and its
            geometry, and no other entity or connectivity.
        connectivities: The (d₀, d₁) of the connectivities the original mesh had.
        permutations: Whether the original mesh had its entity permutations.
        facets: The domain's facet tags, or None.
        cells: The domain's cell tags, or None.
        tags: Its other facet tags, by name.
        snap: Its ``snap``.
    """

    mesh: dmesh.Mesh
    connectivities: list[tuple[int, int]]
    permutations: bool
    facets: Tags | None = None
    cells: Tags | None = None
    tags: dict[str, Tags] = field(default_factory=dict)
    snap: Callable[[Domain, Domain], None] | None = None

    def whole(self) -> Domain:
        """Return the domain whole again, the same entity for entity as before :func:`bare`.

        Its mesh's entities and connectivities are computed again, its entity permutations
        if it had them, and its tags made again on it.  Collective.
        """
        msh = self.mesh
        topology = msh.topology
        for d0, d1 in self.connectivities:
            if present(topology, d0, d1):
                continue
            if d1 == 0:  # the entities of dimension d0 themselves (d0 is neither 0 nor tdim)
                topology.create_entities(d0)
            else:
                topology.create_connectivity(d0, d1)
        if self.permutations:
            topology.create_entity_permutations()
        return Domain(
            msh,
            facets=None if self.facets is None else self.facets.on(msh),
            cells=None if self.cells is None else self.cells.on(msh),
            tags={name: t.on(msh) for name, t in self.tags.items()},
            snap=self.snap,
        )


def present(topology: dmesh.Topology, d0: int, d1: int) -> bool:
    """Whether ``topology`` has its (d0, d1) connectivity."""
    try:
        return topology.connectivity(d0, d1) is not None
    except RuntimeError:  # dolfinx raises for one not computed
        return False


def bare(domain: Domain) -> BareDomain | None:
    """Return ``domain`` as a :class:`BareDomain`, or None where it cannot be made whole again.

    The bare mesh shares the original's cells, index maps and geometry; once the original
    mesh is dropped, the memory of its other entities and connectivities is free.  None for
    a domain that carries functions (``Domain.functions``: they live on the original mesh),
    is linked to a parent (grid sequencing may solve on it) or whose mesh has no UFL domain
    (it builds no forms).  The copy has a UFL domain of its own.  Collective.
    """
    if domain.functions or domain.parent is not None:
        return None
    msh = domain.mesh
    topology = msh.topology
    tdim = topology.dim
    kept = [
        (d0, d1) for d0 in range(tdim + 1) for d1 in range(tdim + 1) if present(topology, d0, d1)
    ]
    try:
        topology._cpp_object.get_cell_permutation_info()
        permutations = True
    except RuntimeError:
        permutations = False
    native = topology._cpp_object
    cells = cpp.mesh.Topology(
        native.cell_type,
        native.index_map(0),
        native.index_map(tdim),
        native.connectivity(tdim, 0),
        np.array(native.original_cell_index, dtype=np.int64),
    )
    mesh_type: Any = (
        cpp.mesh.Mesh_float32 if msh.geometry.x.dtype == np.float32 else cpp.mesh.Mesh_float64
    )
    # a UFL domain of its own: dolfinx points a UFL domain at the mesh made with it (its
    # cargo), and forms on the original mesh must still find the original
    original = msh.ufl_domain()
    if original is None:  # a mesh without a UFL domain builds no forms: nothing to restore
        return None
    domain_ufl = ufl.Mesh(original.ufl_coordinate_element())
    copy = dmesh.Mesh(mesh_type(msh.comm, cells, msh._cpp_object.geometry), domain_ufl)
    return BareDomain(
        copy,
        kept,
        permutations,
        facets=None if domain.facets is None else Tags.of(domain.facets),
        cells=None if domain.cells is None else Tags.of(domain.cells),
        tags={name: Tags.of(t) for name, t in domain.tags.items()},
        snap=domain.snap,
    )
