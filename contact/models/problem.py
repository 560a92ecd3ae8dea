"""What every builder of a discrete problem shares
(:class:`~contact.solvers.problem.DiscreteProblem`): K and the lifted load b, lumped
weights, the ends of Γ_C, the size of the coordinates, the first point of contact."""

from __future__ import annotations

from typing import Any

import basix
import dolfinx.fem.petsc
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base import indices


def coordinate_scale(msh: Any) -> float:
    """max |X| over the vertex coordinates of every rank (the same on any partition)."""
    X = msh.geometry.x[:, : msh.geometry.dim]
    return msh.comm.allreduce(float(np.max(np.abs(X), initial=0.0)), op=MPI.MAX)


def contact_ends(
    V: fem.FunctionSpace, owned: np.ndarray, candidates: np.ndarray, dirichlet: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Owned contact DoFs that are Dirichlet DoFs too, and for each the nearest contact DoF
    that is not (owned or ghost).  A loop over the few ends only."""
    ends = np.intersect1d(owned, dirichlet).astype(np.int32)
    free = indices.setdiff(candidates, dirichlet)
    if len(ends) == 0 or len(free) == 0:
        return np.zeros(0, np.int32), np.zeros(0, np.int32)
    X = V.tabulate_dof_coordinates()
    nearest = [free[np.argmin(np.linalg.norm(X[free] - X[e], axis=1))] for e in ends]
    return ends, np.asarray(nearest, dtype=np.int32)


#: vector-valued K through dolfinx's block CSR matrix (:func:`assemble_matrix`); False: PETSc's
#: MatSetValues as before (kept to measure the difference)
BLOCK_CSR = True


def assemble_matrix(a: fem.Form, bcs: list) -> PETSc.Mat:
    """K of the bilinear form ``a`` (PETSc AIJ) with the Dirichlet rows and columns of
    ``bcs`` replaced by identity.

    A vector-valued space (block size bs > 1, elasticity) is assembled into dolfinx's block
    CSR matrix — one insertion per bs × bs block where PETSc's AIJ takes bs² scalar ones —,
    handed to PETSc as BAIJ from its arrays and converted to AIJ (which GAMG needs): the
    same matrix (relative difference ≤ 1e-16), 1.3× faster in serial and as fast on 2 ranks
    (3D elasticity, ``python demos/bench/bench_kernels.py``, demos/results/kernels*.csv;
    timings: demos/RESULTS.md §10).  Scalar spaces are assembled by PETSc directly."""
    bs = a.function_spaces[0].dofmap.index_map_bs
    if not BLOCK_CSR or bs == 1:
        K = dolfinx.fem.petsc.assemble_matrix(a, bcs=bcs)
        K.assemble()
        return K
    A = fem.assemble_matrix(a, bcs=bcs)  # block CSR, ghost rows not yet summed
    A.scatter_reverse()
    n = A.index_map(0).size_local  # owned block rows
    indptr = A.indptr[: n + 1].astype(PETSc.IntType)
    cols = (
        A.index_map(1)
        .local_to_global(A.indices[: indptr[-1]].astype(np.int32))
        .astype(PETSc.IntType)
    )
    values = A.data[: indptr[-1] * bs * bs]  # row-major bs × bs blocks
    comm = a.mesh.comm
    sizes = ((n * bs, None), (n * bs, None))
    B = PETSc.Mat().createBAIJ(sizes, bs, csr=(indptr, cols, values), comm=comm)  # type: ignore[arg-type]
    B.assemble()
    converted = B.convert("aij")
    # a copy: with PETSc 3.25 the converted matrix still refers to B's memory (using it
    # after B.destroy() is a segmentation fault, serial and parallel)
    K = converted.copy()
    converted.destroy()
    B.destroy()
    return K


def assemble_system(a: fem.Form, L: fem.Form, bcs: list) -> tuple[PETSc.Mat, PETSc.Vec]:
    """K with Dirichlet rows and columns replaced by identity (:func:`assemble_matrix`), and
    the lifted load b, so that R(u) = K u − b is the residual for any u carrying the
    Dirichlet values."""
    K = assemble_matrix(a, bcs)
    b = dolfinx.fem.petsc.assemble_vector(L)
    dolfinx.fem.petsc.apply_lifting(b, [a], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
    dolfinx.fem.petsc.set_bc(b, bcs)
    return K, b


def lumped_weights(
    V: fem.FunctionSpace, measure: ufl.Measure, component: int | None = None
) -> np.ndarray:
    """w_i = ∫ φ_i over ``measure`` for the owned DoFs (ghost contributions summed); for a
    vector space, of the DoFs of one ``component`` (0 at the others).

    P2 on triangles or tetrahedra (the cells of an obstacle problem, ``dx``; the triangles
    of a 3D boundary, ``ds``): the P2 vertex functions integrate to 0 over a triangle and to
    −|T|/20 over a tetrahedron, so a vertex would carry no weight or a negative one.  There
    w_i is the P1-iso-P2 lumped mass instead: the integral of the P1 hat of node i on the
    simplex split at its edge midpoints (4 triangles; 8 tetrahedra, the inner octahedron's
    volume shared equally by its 6 vertices, the mean over its three diagonal splits), i.e.
    the positive nodal rule of :func:`iso_p2_rule` — |T|/12 at the vertices and |T|/4 at the
    edge midpoints of a triangle, |T|/32 and 7|T|/48 on a tetrahedron —, exact for affine
    functions.  Units: those of the measure (area on Γ_C, volume in Ω), so λ_i = R_i / w_i
    is a density (a pressure, a flux per area or volume).  The discrete solution does not
    depend on positive weights (R_i ≥ 0, σ(g_i − u_i) ≥ 0, R_i (g_i − u_i) = 0 is the same
    for any w_i > 0); they give λ_h and the contact measure Σ_{i active} w_i.  A uniform
    density p gives the nodal forces p ∫ φ_i, so λ_h alternates between the vertices (≤ 0)
    and the edge midpoints of a patch in full contact, while the total Σ R_i is exact."""
    rule = iso_p2_rule(V, measure)
    if rule is not None:
        points, weights = rule
        measure = measure.reconstruct(
            metadata={
                "quadrature_rule": "custom",
                "quadrature_points": points,
                "quadrature_weights": weights,
            }
        )
    return _nodal_integrals(V, measure, component)


def _nodal_integrals(
    V: fem.FunctionSpace, measure: ufl.Measure, component: int | None = None
) -> np.ndarray:
    """∫ φ_i over ``measure`` (with its quadrature) for the owned DoFs, ghosts summed."""
    v = ufl.TestFunction(V)
    w = dolfinx.fem.petsc.assemble_vector(
        fem.form((v if component is None else v[component]) * measure)
    )
    add, reverse = PETSc.InsertMode.ADD, PETSc.ScatterMode.REVERSE
    w.ghostUpdate(addv=add, mode=reverse)  # type: ignore[arg-type]
    out = w.array.copy()
    w.destroy()
    return out


#: the P1-iso-P2 fractions of a simplex's measure that each vertex and each edge midpoint
#: carries, by the simplex's dimension (:func:`lumped_weights`): on a triangle the P1 hats
#: of its 4 subtriangles, on a tetrahedron those of its 8 subtetrahedra (the octahedron's
#: share 1/2 split equally among its 6 vertices); n_vertices · vertex + n_edges · edge = 1
ISO_P2_FRACTIONS = {2: (1.0 / 12, 1.0 / 4), 3: (1.0 / 32, 7.0 / 48)}


def iso_p2_weights(dim: int) -> tuple[np.ndarray, np.ndarray]:
    """The P1-iso-P2 rule on the reference simplex of dimension ``dim`` (2 or 3): its P2
    nodes (vertices, then edge midpoints in basix's edge order) and weights (they sum to
    the reference measure 1/2 or 1/6)."""
    cell = basix.CellType.triangle if dim == 2 else basix.CellType.tetrahedron
    vertices = np.asarray(basix.geometry(cell))
    edges = basix.topology(cell)[1]
    points = np.vstack([vertices, [0.5 * (vertices[a] + vertices[b]) for a, b in edges]])
    vertex, edge = ISO_P2_FRACTIONS[dim]
    volume = 0.5 if dim == 2 else 1.0 / 6
    weights = volume * np.array([vertex] * len(vertices) + [edge] * len(edges))
    return points, weights


def iso_p2_rule(V: fem.FunctionSpace, measure: ufl.Measure) -> tuple | None:
    """(points, weights) of :func:`iso_p2_weights` when V is P2 and ``measure`` integrates
    over triangles or tetrahedra (the cells of a 2D or 3D mesh, the facets of a tetrahedral
    one), else None (:func:`lumped_weights`)."""
    if V.ufl_element().embedded_superdegree != 2:
        return None
    cell = V.mesh.topology.cell_name()
    kind = measure.integral_type()
    if kind == "cell" and cell in ("triangle", "tetrahedron"):
        return iso_p2_weights(V.mesh.topology.dim)
    if kind == "exterior_facet" and cell == "tetrahedron":
        return iso_p2_weights(2)
    return None


def active_weights(V: fem.FunctionSpace) -> np.ndarray:
    """The measure m_i each owned DoF of V stands for in the measure of an obstacle
    problem's contact set, |A_h| = Σ_{i ∈ A} m_i over the active nodes A (units of volume:
    area in 2D).

    P1: m_i = w_i, the lumped weights.  P2 on triangles or tetrahedra: m_i = Σ_{T ∋ i} |T| /
    n_e at the edge midpoints (n_e = 3 or 6 edges) and 0 at the vertices — so a cell counts
    with the fraction of its edge midpoints that are active.  For P2 the forces of a contact
    zone sit on the edge midpoints: an interior vertex's load ∫ λ φ_i is O(h²) of either
    sign for a smooth density λ (∫ φ_i ≤ 0), so the discrete solution leaves most vertices
    of the contact zone free, lifted above ψ by O(h³); counting the active nodes with the
    P1-iso-P2 weights w_i would miss their share (a quarter of the area in 2D) at any h.
    In 2D m_i = ∫ φ_i (the P2 vertex functions integrate to 0 over a triangle)."""
    if iso_p2_rule(V, ufl.dx) is None:
        return lumped_weights(V, ufl.dx(domain=V.mesh))
    dim = V.mesh.topology.dim
    points, weights = iso_p2_weights(dim)
    n_vertices = dim + 1
    weights = np.zeros_like(weights)
    weights[n_vertices:] = (0.5 if dim == 2 else 1.0 / 6) / (len(weights) - n_vertices)
    measure = ufl.dx(
        domain=V.mesh,
        metadata={
            "quadrature_rule": "custom",
            "quadrature_points": points,
            "quadrature_weights": weights,
        },
    )
    return _nodal_integrals(V, measure)


#: initial gaps within TIE_RTOL × (the largest coordinate, at least 1) of the smallest count as
#: one, and coordinates are compared rounded to TIE_RTOL × the largest (meshes of different
#: partitions differ in the last bits of their coordinates)
TIE_RTOL = 1e-9
#: current gaps within TOUCH_RTOL × (the largest coordinate, at least 1) of the smallest count
#: as one: the nodes that touch on a current configuration, whose gaps at the coupling point
#: are those of the coupling's fixed point (a relative 1e-9 of the displacement), not 0
TOUCH_RTOL = 1e-6


def first_contact_point(comm: MPI.Comm, X: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The first point of contact (the same on any number of ranks; collective): of the rows
    of X (this rank's points) with the smallest ``dist`` over all ranks, the first in
    coordinate order (smallest x, then y, then z).  Several nodes touching at once (a flat
    face on a plane, a patch test) are a tie, broken by that order rather than by the rank
    that holds them; gaps and coordinates are compared to :data:`TIE_RTOL` of the largest
    coordinate.  A ``dist`` of two columns, the current gaps on a current configuration and
    the bounds (:meth:`~contact.solvers.problem.DiscreteProblem.contact_gaps`), ranks by the
    first, current gaps within :data:`TOUCH_RTOL` tied (the nodes that touch), then by the
    second.  None when no rank has a point."""
    return _first_contact(comm, X, dist, X)[0]


def first_contact_row(
    comm: MPI.Comm, X: np.ndarray, dist: np.ndarray, rows: np.ndarray
) -> np.ndarray:
    """The row of ``rows`` (e.g. the nodal normals, row for row with X) at
    :func:`first_contact_point` (collective)."""
    return _first_contact(comm, X, dist, rows)[1]


def _first_contact(comm: MPI.Comm, X: np.ndarray, dist: np.ndarray, rows: np.ndarray) -> tuple:
    """(point, row of ``rows``) of :func:`first_contact_point`, as arrays (None, None if no
    rank has a point)."""
    scale = max(
        comm.allreduce(float(np.max(np.abs(X), initial=0.0)), op=MPI.MAX), np.finfo(float).tiny
    )
    keys = np.asarray(dist, dtype=float)
    keys = keys if keys.ndim == 2 else keys[:, None]
    near = np.arange(len(X))
    ties = (TIE_RTOL,) if keys.shape[1] == 1 else (TOUCH_RTOL, TIE_RTOL)
    for key, tie in zip(keys.T, ties, strict=True):  # the rows tied in one, ranked by the next
        lowest = comm.allreduce(float(np.min(key[near], initial=np.inf)), op=MPI.MIN)
        near = near[key[near] <= lowest + tie * max(scale, 1.0)]
    local = None
    if len(near):
        key = np.round(X[near] / scale, -int(np.log10(TIE_RTOL))) + 0.0  # + 0.0: no −0.0
        i = np.lexsort(key.T[::-1])[0]  # lexsort: the last key is the primary one
        local = (key[i].tolist(), X[near[i]].tolist(), np.asarray(rows[near[i]]).tolist())
    found = [c for c in comm.allgather(local) if c is not None]
    if not found:
        return None, None
    _, point, row = min(found, key=lambda c: c[0])  # lists compare in coordinate order
    return np.asarray(point), np.asarray(row)
