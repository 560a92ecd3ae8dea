"""What a solve's figures need of the problem beyond its :class:`~contact.solvers.Result`.

The functions of :mod:`contact.post` take a :class:`Posed` record and a result: the mesh and
its tagged boundary parts, the contact pairs and the bodies' materials, the declared exact
solution, reference and friction coefficient, a rigid obstacle's approach.  A YAML scene
builds its record with :func:`contact.setup.posed.posed_of` (a level's or a load step's once:
``level.posed``); any object with these attributes will do.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI


class Parts(Protocol):
    """The tagged boundary parts: ``ids[name]`` the tag value of a part, ``roles[name]`` its
    role (dirichlet, neumann, contact, symmetry, interface, natural)."""

    tags: dmesh.MeshTags
    ids: dict[str, int]
    roles: dict[str, str]

    def ids_with_role(self, role: str) -> tuple[int, ...]:
        """The tag values of all parts with ``role``."""
        ...

    def facets(self, role: str) -> np.ndarray:
        """Local facet indices of all parts with ``role``."""
        ...


class Posed(Protocol):
    """The problem a result solves, as its figures need it.

    Attributes:
        mesh: The mesh solved on (all bodies in one mesh).
        boundary: Its tagged boundary parts.
        bodies: Cell tags k + 1 of the k-th body (several bodies), else None.
        elastic: Whether the unknown is a displacement (elasticity) or a scalar.
        pairs: The (slave, master) part names of each contact pair; empty without pairs.
        materials: Young's modulus E and Poisson's ratio ν of each body by name, in the
            order of the cell tags (one unnamed entry for a single elastic body; empty for
            a scalar model).
        obstacle: The rigid obstacle as declared (``type``, and ``normal`` of a plane or
            ``center`` of a ball or cylinder), else None.
        exact: The declared exact solution as a UFL expression on the mesh (a vector for
            elasticity), else None.
        exact_values: Its components as NumPy functions of the points x (3, n), one per
            declared expression; empty without an exact solution.
        reference: The declared reference (``type``, ``radius``), else None.
        coefficient: Coulomb's friction coefficient F, else None.
        approach: For a load path against one rigid obstacle, its approach a(t) = g_0(X) −
            g_t(X) at a point X since t = 0 (:mod:`contact.post.load_curve`), else None.
        translation: Then also the obstacle's translation since t = 0 (gdim components),
            else None.
        conditions: What the problem poses beyond its parts, for the summary (the exterior
            facets in no part, and where a declared exact solution misses a boundary
            condition); collective.
    """

    # read-only: a frozen record satisfies it
    @property
    def mesh(self) -> dmesh.Mesh: ...  # noqa: D102
    @property
    def boundary(self) -> Parts: ...  # noqa: D102
    @property
    def bodies(self) -> dmesh.MeshTags | None: ...  # noqa: D102
    @property
    def elastic(self) -> bool: ...  # noqa: D102
    @property
    def pairs(self) -> tuple[tuple[str, str], ...]: ...  # noqa: D102
    @property
    def materials(self) -> Mapping[str, tuple[float, float]]: ...  # noqa: D102
    @property
    def obstacle(self) -> Any: ...  # noqa: D102
    @property
    def exact(self) -> Any: ...  # noqa: D102
    @property
    def exact_values(self) -> tuple[Callable[[np.ndarray], np.ndarray], ...]: ...  # noqa: D102
    @property
    def reference(self) -> Any: ...  # noqa: D102
    @property
    def coefficient(self) -> float | None: ...  # noqa: D102
    @property
    def approach(self) -> Callable[[np.ndarray], float] | None: ...  # noqa: D102
    @property
    def translation(self) -> Callable[[], list[float]] | None: ...  # noqa: D102
    @property
    def conditions(self) -> Callable[[], dict[str, Any]]: ...  # noqa: D102

    @property
    def comm(self) -> MPI.Comm:
        """The mesh's communicator."""
        ...
