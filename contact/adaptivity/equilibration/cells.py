"""The cell table: per cell, the raw data a vertex-patch problem needs, as plain NumPy rows.

A row holds the cell's global index, its vertices (global indices, owning ranks and
coordinates), the coefficients of u_h, the data f and k at the cell quadrature points of
:mod:`.reference`, the kind of each facet (facet j is opposite vertex j), the boundary
flux data at the facet quadrature points and the coefficients of the discrete multiplier
λ_h (:mod:`.multiplier`).
Everything downstream is computed from rows, so a rank can solve the patch of a vertex
whose cells live on other ranks once it has received their rows (:func:`complete`), and
send back what it computed for them (:func:`return_to_owners`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .reference import Reference

INTERIOR, DIRICHLET, FLUX, CONTACT = 0, 1, 2, 3  # facet kinds (FLUX: Neumann / natural)


@dataclass
class CellTable:
    """Rows of cells (see the module docstring); all arrays share the first axis."""

    gcell: np.ndarray  # (n,) int64 global cell index
    gvert: np.ndarray  # (n, d+1) int64 global vertex indices
    vowner: np.ndarray  # (n, d+1) int32 rank owning each vertex
    x: np.ndarray  # (n, d+1, d) vertex coordinates
    U: np.ndarray  # (n, nu) coefficients of u_h (the element's local order)
    f: np.ndarray  # (n, nq) f at the cell quadrature points
    k: np.ndarray  # (n, nq) k at the cell quadrature points
    kind: np.ndarray  # (n, d+1) int8 facet kinds
    t: np.ndarray  # (n, d+1, nqf) flux data on FLUX / CONTACT facets (0 elsewhere)
    lam: np.ndarray  # (n, nu) coefficients of λ_h in the element of u_h (0 without one)
    tau: np.ndarray  # (n, nq, d) the target flux at the points (the lowest-order flux: at
    # the centroid only, (n, 1, d): only its cell mean enters), or (n, 0, d): k∇u_h
    # (n, d+1 facets, d+1 vertices, nf): the multiplier's share of each vertex on each
    # contact facet, per reference measure (FluxData.multiplier_rule), or (n, 0): from lam
    cmom: np.ndarray

    def __len__(self) -> int:
        return len(self.gcell)

    def take(self, rows: np.ndarray) -> CellTable:
        return CellTable(**{fl.name: getattr(self, fl.name)[rows] for fl in fields(self)})

    @staticmethod
    def concatenate(tables: list[CellTable]) -> CellTable:
        return CellTable(
            **{
                fl.name: np.concatenate([getattr(t, fl.name) for t in tables])
                for fl in fields(CellTable)
            }
        )


@dataclass
class FluxData:
    """What the flux reconstruction is given, as DOLFINx objects and UFL.

    ``dirichlet``, ``neumann`` and ``contact`` are facet tag values of ``facet_tags``; the
    exterior facets no tag names carry the flux 0 (natural).  ``neumann`` and ``contact``
    map a tag to the prescribed part of the flux σ·n there (t on Γ_N; t_C on Γ_C, where the
    multiplier λ is added).  ``lmbda_h`` is the discrete multiplier λ_h (a Lagrange
    function, on Γ_C including its ends on Γ_D, or in Ω; :mod:`.multiplier`).  ``target``
    is the flux σ_h is fitted to in each patch (default k∇u_h; a better one, e.g. k∇ of a
    feasible correction of u_h, only changes how close σ_h comes, not its constraints)."""

    u_h: fem.Function
    f: ufl.core.expr.Expr
    k: ufl.core.expr.Expr
    facet_tags: dmesh.MeshTags
    dirichlet: tuple = ()
    neumann: dict | None = None
    contact: dict | None = None
    lmbda_h: fem.Function | None = None
    target: ufl.core.expr.Expr | None = None
    #: an object that gives the multiplier's shares itself (hp: a degree per contact facet),
    #: with ``moments(cells, kind, ref)`` → (n, d+1, d+1, nf) per reference measure (the
    #: ``shares`` of :mod:`.multiplier`) and ``function()`` → λ̃_h (UFL, on Γ_C); None: from
    #: ``lmbda_h`` in the element of u_h
    multiplier_rule: Any = None


def _facet_kinds(msh: dmesh.Mesh, data: FluxData) -> tuple[np.ndarray, dict]:
    """(local cells, d+1) facet kinds, and for FLUX/CONTACT facets the tag they carry."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    msh.topology.create_connectivity(tdim, tdim - 1)
    c2f = msh.topology.connectivity(tdim, tdim - 1).array.reshape(-1, tdim + 1)
    n_facets = (
        msh.topology.index_map(tdim - 1).size_local + msh.topology.index_map(tdim - 1).num_ghosts
    )
    facet_kind = np.zeros(n_facets, dtype=np.int8)
    facet_tag = np.full(n_facets, -1, dtype=np.int64)
    facet_kind[dmesh.exterior_facet_indices(msh.topology)] = FLUX
    tags = data.facet_tags
    for values, kind in (
        (data.neumann or {}, FLUX),
        (data.contact or {}, CONTACT),
        (data.dirichlet, DIRICHLET),
    ):
        for v in values:
            facets = tags.indices[tags.values == v]
            facet_kind[facets] = kind
            facet_tag[facets] = v
    return facet_kind[c2f], facet_tag[c2f]


#: a block's vertex coordinates through the geometry node of each vertex (kept by
#: :class:`CellSource`, one int per vertex); False: through the geometry's cell dofmap, which
#: DOLFINx copies whole on every access (the plain path, the same coordinates)
VERTEX_NODES = True

#: compile each data expression of a table once (:class:`BoundaryRows` keeps them for its
#: blocks); False: once per block, the plain path (the same numbers)
KEEP_EXPRESSIONS = True


def _at_points(
    expr, one: fem.Function, X: np.ndarray, cells: np.ndarray, compiled: dict | None = None
) -> np.ndarray:
    """The UFL expression at the reference points X of ``cells``: (len(cells), len(X), …).
    The expression is multiplied by ``one``, a DG0 function 1, so that DOLFINx ties it to
    the mesh even when it is constant after differentiation (e.g. −div ∇ of a linear
    function).  ``compiled``: the ``fem.Expression`` of (expr, X) is kept there and taken
    from there (None: compiled here)."""
    if isinstance(expr, fem.Constant | int | float):  # the same on every rank: no compile
        value = np.asarray(expr.value if isinstance(expr, fem.Constant) else expr, np.float64)
        return np.broadcast_to(value, (len(cells), len(X)) + value.shape)  # read-only, no memory
    msh = one.function_space.mesh
    key = (id(expr), X.tobytes())
    if compiled is None or key not in compiled:
        product = one * ufl.as_ufl(expr)  # collective: compiled (also for no cells)
        shape = tuple(product.ufl_shape)
        # UFL's zero: nothing left to tie to the mesh
        zero = isinstance(product, ufl.constantvalue.Zero)
        made = (None if zero else fem.Expression(product, X), shape)
        if compiled is None:
            compiled = {}
        compiled[key] = made
    kernel, shape = compiled[key]
    if kernel is None:
        return np.zeros((len(cells), len(X)) + shape)
    values = np.asarray(kernel.eval(msh, cells))
    return values.reshape((len(cells), len(X)) + shape)


@dataclass
class BoundaryRows:
    """The two largest columns of a cell table, ``t`` and ``tau``, computed for given rows
    only (:meth:`fill`): a table built with ``deferred=True`` has them empty, so that the
    patches can be solved a block of vertices at a time with only that block's rows whole
    (:func:`.flux.reconstruct_flux`)."""

    data: FluxData
    ref: Reference
    one: fem.Function  # DG0, 1: ties the expressions to the mesh (_at_points)
    tag: np.ndarray  # (owned cells, d+1) the tag of each FLUX / CONTACT facet, else -1
    #: the compiled expressions, kept for the next rows (:func:`_at_points`)
    compiled: dict = field(default_factory=dict)

    def fill(self, rows: CellTable, cells: np.ndarray) -> CellTable:
        """``rows`` (the table's rows of the owned local ``cells``) with t and τ."""
        cells = cells.astype(np.int32, copy=False)
        keep = self.compiled if KEEP_EXPRESSIONS else None
        t, tau = _boundary_columns(self.data, self.ref, self.one, self.tag[cells], cells, keep)
        rows.t, rows.tau = t, tau
        return rows


def _boundary_columns(
    data: FluxData,
    ref: Reference,
    one: fem.Function,
    tag: np.ndarray,
    cells: np.ndarray,
    compiled: dict | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The columns t (flux data at the facet points) and τ (the target flux) of ``cells``
    (owned local indices; ``tag`` their rows of facet tags; ``compiled``: of
    :func:`_at_points`)."""
    d = ref.d
    t = np.zeros((len(cells), d + 1, len(ref.wS)))
    XF = ref.XF.reshape(-1, d)
    for values in (data.neumann or {}, data.contact or {}):
        for v, expr in values.items():
            rows = np.flatnonzero(np.any(tag == v, axis=1)).astype(np.int32)
            vals = _at_points(expr, one, XF, cells[rows], compiled)
            vals = vals.reshape(len(rows), d + 1, len(ref.wS))
            hit = tag[rows] == v
            t[rows[:, None].repeat(d + 1, 1)[hit], np.nonzero(hit)[1]] = vals[hit]
    centroid = np.full((1, d), 1.0 / (d + 1))
    tau = (
        np.zeros((len(cells), 0, d))
        if data.target is None
        else _at_points(data.target, one, centroid if ref.lowest else ref.X, cells, compiled)
    )
    return t, tau


def local_table(
    data: FluxData, ref: Reference, dg0: fem.FunctionSpace | None = None
) -> tuple[CellTable, int]:
    """The rows of this rank's owned cells (and their number); ``dg0``: the mesh's DG0 space,
    if the caller has it.  Collective (the data expressions are compiled)."""
    table, n_owned, _ = deferred_table(data, ref, dg0, deferred=False)
    return table, n_owned


def deferred_table(
    data: FluxData, ref: Reference, dg0: fem.FunctionSpace | None = None, deferred: bool = True
) -> tuple[CellTable, int, BoundaryRows]:
    """:func:`local_table` with t and τ left empty (``deferred``), and the
    :class:`BoundaryRows` that computes them for given rows.  Collective."""
    source = cell_source(data, ref, dg0)
    n_owned = len(source)
    table = source.rows(np.arange(n_owned, dtype=np.int32), boundary=not deferred, whole=True)
    return table, n_owned, source.boundary


@dataclass
class CellSource:
    """The rows of this rank's owned cells, made for given cells when asked (:meth:`rows`):
    what a whole :class:`CellTable` holds for every cell at once (the data at the quadrature
    points, the coordinates, the coefficients of u_h and λ_h: ~200 bytes per cell for P1 in
    2D) is then only ever whole for one block of cells.  It keeps per cell only the local
    vertices and the facet kinds and tags."""

    data: FluxData
    ref: Reference
    boundary: BoundaryRows  # t and τ of given rows (its ``one`` ties expressions to the mesh)
    c2v: np.ndarray  # (owned cells, d+1) local vertex indices
    owners: np.ndarray  # (local vertices,) the rank owning each
    kind: np.ndarray  # (owned cells, d+1) facet kinds
    lam: fem.Function | None  # λ_h interpolated into the element of u_h, or None
    #: (local vertices,) the geometry node of each (affine cells: node j of a cell is its
    #: vertex j), or None: read from the geometry's dofmap (:data:`VERTEX_NODES`)
    nodes: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.c2v)

    def rows(
        self, cells: np.ndarray, boundary: bool = True, whole: bool = False, points: bool = True
    ) -> CellTable:
        """The table's rows of the owned local ``cells`` (with t and τ unless not
        ``boundary``: then empty, as :func:`deferred_table` leaves them; f and k at the
        points unless not ``points``: then empty).  The data at the points are contiguous
        arrays, as rows taken from a whole table are, unless ``whole`` (the whole table: a
        constant's is a read-only broadcast view, no memory)."""
        data, ref = self.data, self.ref
        V = data.u_h.function_space
        msh = V.mesh
        d = msh.topology.dim
        cells = np.asarray(cells, dtype=np.int32)
        c2v = self.c2v[cells]
        vmap = msh.topology.index_map(0)
        gvert = vmap.local_to_global(c2v.ravel()).reshape(c2v.shape)
        gcell = msh.topology.index_map(d).local_to_global(cells)
        nodes = msh.geometry.dofmaps[0][cells] if self.nodes is None else self.nodes[c2v]
        x = msh.geometry.x[:, :d][nodes]  # (n, d+1, d), contiguous
        dofs = V.dofmap.list[cells]
        U = data.u_h.x.array[dofs]
        keep = self.boundary.compiled if KEEP_EXPRESSIONS else None
        one = self.boundary.one
        if points:
            f = _at_points(data.f, one, ref.X, cells, keep)
            k = _at_points(data.k, one, ref.X, cells, keep)
            if not whole:  # the patch kernels' NumPy sums see the strides
                f, k = np.ascontiguousarray(f), np.ascontiguousarray(k)
        else:
            f = k = np.zeros((len(cells), 0))
        kind = self.kind[cells]
        if boundary:
            t, tau = _boundary_columns(data, ref, one, self.boundary.tag[cells], cells, keep)
        else:
            t, tau = np.zeros((len(cells), d + 1, 0)), np.zeros((len(cells), 0, d))
        lam = np.zeros_like(U) if self.lam is None else self.lam.x.array[dofs]
        cmom = (
            np.zeros((len(cells), 0))
            if data.multiplier_rule is None
            else data.multiplier_rule.moments(cells, kind, ref)
        )
        return CellTable(
            gcell.astype(np.int64),
            gvert.astype(np.int64),
            self.owners[c2v],
            x,
            U,
            f,
            k,
            kind,
            t,
            lam,
            tau,
            cmom,
        )


def cell_source(data: FluxData, ref: Reference, dg0: fem.FunctionSpace | None = None) -> CellSource:
    """The :class:`CellSource` of this rank's owned cells.  Collective (λ_h is interpolated
    into the element of u_h)."""
    u_h = data.u_h
    V = u_h.function_space
    msh = V.mesh
    d = msh.topology.dim
    n_owned = msh.topology.index_map(d).size_local
    geometry = msh.geometry.dofmaps[0]
    if geometry.shape[1] != d + 1:
        raise ValueError("the equilibrated estimator needs affine (P1-geometry) simplex meshes")
    msh.topology.create_connectivity(d, 0)
    c2v = msh.topology.connectivity(d, 0).array.reshape(-1, d + 1)[:n_owned]
    vmap = msh.topology.index_map(0)
    nodes = None
    if VERTEX_NODES:
        nodes = np.zeros(vmap.size_local + vmap.num_ghosts, dtype=geometry.dtype)
        nodes[c2v] = geometry[:n_owned]
    del geometry
    owners = np.concatenate([np.full(vmap.size_local, msh.comm.rank, dtype=np.int32), vmap.owners])
    one = fem.Function(dg0 or fem.functionspace(msh, ("DG", 0)))
    one.x.array[:] = 1.0
    kind, tag = _facet_kinds(msh, data)
    kind, tag = kind[:n_owned], tag[:n_owned]
    lam = None
    if data.lmbda_h is not None:
        lam = fem.Function(V)
        lam.interpolate(data.lmbda_h)
    return CellSource(data, ref, BoundaryRows(data, ref, one, tag), c2v, owners, kind, lam, nodes)


# ---------------------------------------------------------------------------------------
# parallel completion of the vertex patches
# ---------------------------------------------------------------------------------------
def _exchange(comm: MPI.Comm, dest: np.ndarray, arrays: list[np.ndarray]) -> list[np.ndarray]:
    """Send row r of each array to rank dest[r]; returns the received rows (all ranks)."""
    order = np.argsort(dest, kind="stable")
    counts = np.bincount(dest, minlength=comm.size).astype(np.int64)
    recv_counts = np.empty_like(counts)
    comm.Alltoall(counts, recv_counts)
    out = []
    for a in arrays:
        a = np.ascontiguousarray(a[order])
        width = int(np.prod(a.shape[1:], dtype=np.int64))
        buf = np.empty((int(recv_counts.sum()),) + a.shape[1:], dtype=a.dtype)
        mpitype = MPI._typedict[a.dtype.char]
        comm.Alltoallv([a, counts * width, mpitype], [buf, recv_counts * width, mpitype])
        out.append(buf)
    return out


def complete(comm: MPI.Comm, table: CellTable, source: np.ndarray) -> tuple[CellTable, np.ndarray]:
    """This rank's rows plus the rows of every other rank's cells that touch a vertex this
    rank owns: afterwards each owned vertex has its whole patch here.  Returns the work
    table (this rank's rows first, in order) and the rank owning each of its rows."""
    if comm.size == 1:
        return table, source
    rows, cols = np.nonzero(table.vowner != comm.rank)
    pairs = np.unique(np.column_stack([rows, table.vowner[rows, cols]]).astype(np.int64), axis=0)
    pairs = pairs.reshape(-1, 2)
    sent = table.take(pairs[:, 0])
    arrays = [getattr(sent, fl.name) for fl in fields(CellTable)] + [source[pairs[:, 0]]]
    *received, src = _exchange(comm, pairs[:, 1], arrays)
    return CellTable.concatenate([table, CellTable(*received)]), np.concatenate([source, src])


def return_to_owners(
    comm: MPI.Comm,
    gcell: np.ndarray,
    source: np.ndarray,
    values: np.ndarray,
    n_owned: int,
    offset: int,
) -> np.ndarray:
    """Sum the rows of ``values`` (one per work row) into the cells' owners: returns the
    (n_owned, …) sums of this rank's cells, whose global indices are offset … offset +
    n_owned − 1 in the order of the first n_owned work rows."""
    if comm.size == 1:
        return values[:n_owned]
    out = values[:n_owned].copy()
    remote = np.arange(n_owned, len(gcell))
    g, v = _exchange(comm, source[remote].astype(np.int64), [gcell[remote], values[remote]])
    np.add.at(out, g - offset, v)
    return out
