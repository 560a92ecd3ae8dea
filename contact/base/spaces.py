"""Function spaces, their collapsed components and zero functions, made once per mesh.

A finite-strain problem of mortar pairs is built anew at each coupling of its fixed point
(:mod:`contact.drivers.recouple`), on the same mesh: the same vector space, its components
collapsed for the component-wise conditions, the DG0 space of the materials and many zero
functions on them.  Each of these is collective — a new dof map and index map, and for a
function a new ghost scatter, whose neighbourhood communicator MPI builds with a collective
call.  On ranks that share cores every such call waits for the others' time slices, and
costs hundreds of times a copy of a function.  So a space is made once per mesh and element
(:func:`functionspace`), a component once per space (:func:`collapsed`), and a zero function
is a copy of one zero function per space (:func:`zero_function`; a nodal vector likewise,
:func:`zero_vector`), whose ghost scatter it shares.

The caches live on the mesh and space objects themselves (attributes ``_contact_spaces`` and
``_contact_cache``), so they go with them; ``CACHE = False`` makes every call build afresh.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from dolfinx import fem, la, mesh

#: reuse spaces, collapsed components and zero functions (module doc); False (the default):
#: build afresh.  Off because with it on the two-body Cattaneo–Mindlin load path on 2 ranks
#: (configs/two_body_cattaneo_2d.yaml, tests/test_bodies.py) waits forever in the creation of
#: a ghosted PETSc vector while assembling a grid-sequencing level: the ranks' collective
#: calls no longer match.  With Python's cyclic collector off the run completes, so the
#: likely cause is PETSc objects on the cached spaces' communicators freed by the collector
#: at different moments on different ranks (PETSc's inner communicator then freed and
#: duplicated again, a collective call, on one rank only)
CACHE = False


def functionspace(msh: mesh.Mesh, element: Any) -> fem.FunctionSpace:
    """``fem.functionspace(msh, element)``, made once per mesh and element (collective when
    made).

    Args:
        msh: The mesh.
        element: The element as ``fem.functionspace`` takes it: a tuple such as
            ``("Lagrange", 1, (2,))`` (hashable; anything else is not cached).

    Returns:
        The space.
    """
    if not CACHE or not _hashable(element):
        return fem.functionspace(msh, element)
    spaces = msh.__dict__.setdefault("_contact_spaces", {})
    if element not in spaces:
        spaces[element] = fem.functionspace(msh, element)
    return spaces[element]


def collapsed(V: fem.FunctionSpace, k: int) -> tuple[fem.FunctionSpace, np.ndarray]:
    """``V.sub(k).collapse()`` made once per space: the component's own space and the map of
    its DoFs to V's (the map must not be written to).

    Args:
        V: A blocked (vector) space.
        k: The component.

    Returns:
        (the collapsed space, its DoFs' indices in V).
    """
    if not CACHE:
        S, dofs = V.sub(k).collapse()
        return S, np.asarray(dofs)
    cache = _cache(V)
    if ("sub", k) not in cache:
        S, dofs = V.sub(k).collapse()
        cache[("sub", k)] = (S, np.asarray(dofs))
    return cache[("sub", k)]


def zero_function(V: fem.FunctionSpace, name: str | None = None) -> fem.Function:
    """A new zero function on V: a copy of one zero function of V, sharing its ghost scatter
    (no collective call once that one exists).

    Args:
        V: The space.
        name: The function's name (dolfinx's default if None).

    Returns:
        The function, all entries (owned and ghost) zero.
    """
    if not CACHE:
        return fem.Function(V) if name is None else fem.Function(V, name=name)
    cache = _cache(V)
    if "zero" not in cache:
        cache["zero"] = fem.Function(V)
    out = cache["zero"].copy()
    if name is not None:
        out.name = name
    return out


def zero_vector(V: fem.FunctionSpace, bs: int = 1) -> la.Vector:
    """A new zero vector of block size ``bs`` on V's index map (a nodal field of V's nodes):
    a copy of one such vector per space and block size, sharing its ghost scatter.

    Args:
        V: The space whose ``dofmap.index_map`` the vector lives on.
        bs: The block size (values per index).

    Returns:
        The vector, all entries (owned and ghost) zero.
    """
    if not CACHE:
        return la.vector(V.dofmap.index_map, bs)
    cache = _cache(V)
    if ("vector", bs) not in cache:
        cache[("vector", bs)] = la.vector(V.dofmap.index_map, bs)
    template = cache[("vector", bs)]._cpp_object
    return la.Vector(type(template)(template))


def _cache(V: fem.FunctionSpace) -> dict:
    return V.__dict__.setdefault("_contact_cache", {})


def _hashable(key: Any) -> bool:
    try:
        hash(key)
    except TypeError:
        return False
    return True
