"""What every builder of a discrete problem shares
(:class:`~contact.solvers.problem.DiscreteProblem`): K and the lifted load b, lumped
weights, the ends of Γ_C, the size of the coordinates, the first point of contact."""

from __future__ import annotations

from typing import Any

import dolfinx.fem.petsc
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc


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
    free = np.setdiff1d(candidates, dirichlet)
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

    P2 on the triangles of a 3D boundary: ∫ φ_i = 0 at the vertices (the P2 vertex functions
    integrate to zero over a triangle), so a vertex would carry no weight.  There the weights
    are those of the P1-iso-P2 lumping instead — the P1 hats of the triangle split into four
    at its edge midpoints, i.e. the positive rule with the P2 nodes as points and weights
    |T|/12 (vertices), |T|/4 (edge midpoints), exact for affine functions
    (:data:`ISO_P2_TRIANGLE`): a uniform pressure p then gives the nodal forces p ∫ φ_i,
    which vanish at the vertices, so λ_i = R_i / w_i alternates between 0 (vertices) and
    4p/3 (edge midpoints) of an interior patch while the force Σ R_i is exact."""
    if _iso_p2_facets(V, measure):
        points, weights = ISO_P2_TRIANGLE
        measure = measure.reconstruct(
            metadata={
                "quadrature_rule": "custom",
                "quadrature_points": points,
                "quadrature_weights": weights,
            }
        )
    v = ufl.TestFunction(V)
    w = dolfinx.fem.petsc.assemble_vector(
        fem.form((v if component is None else v[component]) * measure)
    )
    add, reverse = PETSc.InsertMode.ADD, PETSc.ScatterMode.REVERSE
    w.ghostUpdate(addv=add, mode=reverse)  # type: ignore[arg-type]
    out = w.array.copy()
    w.destroy()
    return out


#: the P1-iso-P2 lumping rule on the reference triangle (area 1/2): the six P2 nodes, weights
#: 1/12 and 1/4 of the area (:func:`lumped_weights`)
ISO_P2_TRIANGLE = (
    np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]]),
    np.array([1.0 / 24] * 3 + [1.0 / 8] * 3),
)


def _iso_p2_facets(V: fem.FunctionSpace, measure: ufl.Measure) -> bool:
    """Whether ``measure`` integrates over the triangles of a tetrahedral mesh's boundary
    and V is P2 (:func:`lumped_weights`)."""
    return (
        measure.integral_type() == "exterior_facet"
        and V.mesh.topology.cell_name() == "tetrahedron"
        and V.ufl_element().embedded_superdegree == 2
    )


#: initial gaps within TIE_RTOL × (the largest coordinate, at least 1) of the smallest count as
#: one, and coordinates are compared rounded to TIE_RTOL × the largest (meshes of different
#: partitions differ in the last bits of their coordinates)
TIE_RTOL = 1e-9


def first_contact_point(comm: MPI.Comm, X: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The first point of contact (the same on any number of ranks; collective): of the rows
    of X (this rank's points) with the smallest ``dist`` over all ranks, the first in
    coordinate order (smallest x, then y, then z).  Several nodes touching at once (a flat
    face on a plane, a patch test) are a tie, broken by that order rather than by the rank
    that holds them; gaps and coordinates are compared to :data:`TIE_RTOL` of the largest
    coordinate.  None when no rank has a point."""
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
    lowest = comm.allreduce(float(np.min(dist, initial=np.inf)), op=MPI.MIN)
    scale = max(
        comm.allreduce(float(np.max(np.abs(X), initial=0.0)), op=MPI.MAX), np.finfo(float).tiny
    )
    near = np.flatnonzero(dist <= lowest + TIE_RTOL * max(scale, 1.0))
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
