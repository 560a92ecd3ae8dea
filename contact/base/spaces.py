"""Function spaces, their collapsed components and zero functions, made once per mesh.

A finite-strain problem of mortar pairs is built anew at each coupling of its fixed point
(:mod:`contact.drivers.recouple`), on the same mesh: the same vector space, its components
collapsed for the component-wise conditions, the DG0 space of the materials and many zero
functions on them.  Each of these is collective — a new dof map and index map, and for a
function a new ghost scatter, whose neighbourhood communicator MPI builds with a collective
call.  On ranks that share cores every such call waits for the others' time slices, and
costs hundreds of times a copy of a function.  So a space is made once per mesh and element
(:func:`functionspace`; an element named by a tuple such as ``("Lagrange", 1)`` and the same
element given as a UFL element are one space), a component once per space
(:func:`collapsed`), its DoF coordinates once per space (:func:`dof_coordinates`), and a zero
function is a copy of one zero function per space (:func:`zero_function`; a nodal vector
likewise, :func:`zero_vector`), whose ghost scatter it shares.

The caches live on the mesh and space objects themselves (attributes ``_contact_spaces`` and
``_contact_cache``), so they go with them; ``CACHE = False`` makes every call build afresh.

**PETSc's inner communicator.**  The PETSc vectors of a space's functions (``x.petsc_vec``,
assembled vectors) live on the communicator of the space's index map.  PETSc attaches to it
an inner communicator, duplicated (a collective call) when the first PETSc object on it is
made and freed when the last one is destroyed.  A function's vector is destroyed when its
wrapper dies (``dolfinx.la.Vector.__del__``), and a function dies when Python's cyclic
collector frees a cycle it is in — UFL's algorithms leave such cycles behind (a
``MultiFunction`` holds its own bound methods; ``ufl.action``'s replacer holds the
function) — at moments that differ from rank to rank.  A space that lives across problems
(this cache) can so lose its inner communicator on one rank and not on the other: the next
vector on it duplicates the communicator on that rank only, and the ranks wait for each
other forever.  So each cached space holds one empty PETSc vector on its index map's
communicator for as long as it lives (made with the cache, at the same program point on
every rank): the inner communicator is made once and never freed while the space is in use.
"""

from __future__ import annotations

from typing import Any

import basix.ufl
import numpy as np
from dolfinx import fem, la, mesh
from petsc4py import PETSc

#: reuse spaces, collapsed components and zero functions (module doc); False: build afresh
CACHE = True
#: a space asked for by a tuple (``("Lagrange", 1)``) is the one asked for by the equal UFL
#: element (refinement's prolongation asks by element, a scene's builder by tuple); False:
#: cached by the key as given, the old path (two spaces)
ELEMENT_KEYS = True


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
    if ELEMENT_KEYS and isinstance(element, tuple):
        element = _ufl_element(msh, element)
    spaces = msh.__dict__.setdefault("_contact_spaces", {})
    if element not in spaces:
        spaces[element] = fem.functionspace(msh, element)
        _cache(spaces[element])  # its communicator kept (module doc)
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
        _cache(S)  # its communicator kept (module doc)
        cache[("sub", k)] = (S, np.asarray(dofs))
    return cache[("sub", k)]


def dof_coordinates(V: fem.FunctionSpace) -> np.ndarray:
    """``V.tabulate_dof_coordinates()``, computed once per space (not writable; not
    collective).

    Args:
        V: The space.

    Returns:
        The coordinates of V's DoF points, local ones with ghosts, shape (n, 3).
    """
    if not CACHE:
        return V.tabulate_dof_coordinates()
    X = V.__dict__.get("_contact_coordinates")
    if X is None:
        X = V.__dict__["_contact_coordinates"] = V.tabulate_dof_coordinates()
        X.flags.writeable = False
    return X


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
    """V's cache, made on first use with a :class:`_Communicator` of V's index map (module
    doc).  Collective when made."""
    cache = V.__dict__.get("_contact_cache")
    if cache is None:
        cache = V.__dict__["_contact_cache"] = {
            "communicator": _Communicator(V.dofmap.index_map.comm)
        }
    return cache


class _Communicator:
    """An empty PETSc vector on ``comm``: PETSc's inner communicator of ``comm`` is
    duplicated when this is made (collective) and kept while this lives; destroyed
    explicitly (at once, not queued for a collective clean-up) when this dies, with the
    space whose cache holds it."""

    def __init__(self, comm: Any) -> None:
        self.vec = PETSc.Vec().createMPI((0, PETSc.DECIDE), comm=comm)

    def __del__(self) -> None:
        self.vec.destroy()


def _ufl_element(msh: mesh.Mesh, element: tuple) -> Any:
    """The UFL element ``fem.functionspace(msh, element)`` makes of the tuple ``element``."""
    e = fem.ElementMetaData(*element)
    return basix.ufl.element(
        e.family,
        msh.basix_cell(),
        e.degree,
        shape=e.shape,
        symmetry=e.symmetry,
        dtype=msh.geometry.x.dtype,
    )


def _hashable(key: Any) -> bool:
    try:
        hash(key)
    except TypeError:
        return False
    return True
