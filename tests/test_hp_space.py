"""The hp space V_hp ⊂ P_{p_max} (docs/theory.md §11, contact.hp.space): on every cell its
functions are polynomials of degree p_T, on every edge of degree p_E (the minimum rule), the
cellwise basis agrees across facets (C⁰), L Q = I, its dimension is the count of the
minimum rule, and Qᵀ K Q solves Poisson's problem exactly for a solution of degree ≤ p_min
— serially and on 2 ranks (the last test reruns the others under mpirun)."""

from __future__ import annotations

import math

import contact  # noqa: F401  (MPI before dolfinx)
from contact.hp.reference import lagrange
from contact.hp.space import HPSpace

import basix
import dolfinx.fem.petsc  # noqa: F401  (fem.petsc)
import numpy as np
import pytest
import ufl
from clirun import pytest_on_ranks
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

COMM = MPI.COMM_WORLD


def _degrees(msh, p_max: int, low: int = 1) -> np.ndarray:
    """A degree per owned cell from its midpoint (the same field on any partition)."""
    d = msh.topology.dim
    n = msh.topology.index_map(d).size_local
    mid = mesh.compute_midpoints(msh, d, np.arange(n, dtype=np.int32))
    code = np.floor(7.3 * mid[:, 0] + 13.1 * mid[:, 1] + 5.7 * mid[:, 2]).astype(int)
    return low + code % (p_max - low + 1)


def _mesh(d: int):
    if d == 2:
        return mesh.create_unit_square(COMM, 5, 4)
    return mesh.create_unit_cube(COMM, 2, 2, 3)


def _gmax(value: float) -> float:
    return COMM.allreduce(float(value), op=MPI.MAX)


@pytest.mark.parametrize("d, p_max", [(2, 5), (3, 3)])
def test_functions_have_the_cell_and_edge_degrees_and_are_continuous(d, p_max):
    msh = _mesh(d)
    space = HPSpace(msh, p_max, _degrees(msh, p_max))
    Q, L = space.matrices()
    V = space.V
    rng = np.random.default_rng(COMM.rank)
    x, u, y = fem.Function(V), fem.Function(V), fem.Function(V)
    x.x.array[:] = rng.standard_normal(len(x.x.array)) * space.active
    x.x.scatter_forward()  # one value per slot, the owner's
    Q.mult(x.x.petsc_vec, u.x.petsc_vec)
    u.x.scatter_forward()
    cell = lagrange(d, p_max).cell_type
    Xq, wq = (np.asarray(a) for a in basix.make_quadrature(cell, 2 * p_max))
    P = np.asarray(basix.tabulate_polynomials(basix.PolynomialType.legendre, cell, p_max, Xq))
    phi = np.asarray(lagrange(d, p_max).tabulate(0, Xq))[0, :, :, 0]
    top = lagrange(d, p_max)
    msh.topology.create_connectivity(d, 1)
    c2e = msh.topology.connectivity(d, 1).array.reshape(-1, math.comb(d + 1, 2))
    p_edge = space.entity_degrees[0]
    gap = cell_excess = edge_excess = 0.0
    for basis, cells in space.groups:
        cd = V.dofmap.list[cells]
        # C⁰: each cell's own combination Q_T x_T equals the global Q x at its DoFs
        own = x.x.array[cd[:, basis.slots]] @ basis.Q.T
        gap = max(gap, np.abs(own - u.x.array[cd]).max())
        # the orthonormal (Dubiner) coefficients of degree > p_T vanish
        coef = (u.x.array[cd] @ phi.T) @ (wq[:, None] * P.T)
        for c, p in enumerate(space.cell_degrees[cells]):
            cell_excess = max(cell_excess, np.abs(coef[c, math.comb(p + d, d) :]).max(initial=0))
        # on each edge: the Legendre coefficients of degree > p_E vanish
        for e, (v0, v1) in enumerate(basix.topology(cell)[1]):
            ids = [top.entity_dofs[0][v0][0], *top.entity_dofs[1][e], top.entity_dofs[0][v1][0]]
            t = np.asarray(top.points)[ids] - np.asarray(top.points)[ids[0]]
            s = 2 * np.linalg.norm(t, axis=1) / np.linalg.norm(t[-1]) - 1
            leg = np.polynomial.legendre.legvander(s, p_max)
            c1 = np.linalg.solve(leg, u.x.array[cd[:, ids]].T).T
            pe = p_edge[c2e[cells, e]]
            for c in range(len(cells)):
                edge_excess = max(edge_excess, np.abs(c1[c, pe[c] + 1 :]).max(initial=0))
    L.mult(u.x.petsc_vec, y.x.petsc_vec)
    n = V.dofmap.index_map.size_local
    assert _gmax(gap) < 1e-12
    assert _gmax(cell_excess) < 1e-11
    assert _gmax(edge_excess) < 1e-10
    assert _gmax(np.abs(y.x.array[:n] - x.x.array[:n]).max()) < 1e-12  # L Q = I
    # the dimension: one unknown per vertex, p_e − 1 per edge, the faces' and cells' nodes
    expected = msh.topology.index_map(0).size_global
    for dim in range(1, d + 1):
        imap = msh.topology.index_map(dim)
        degs = space.entity_degrees[dim - 1] if dim < d else space.cell_degrees
        own_degs = degs[: imap.size_local]
        nodes = {1: own_degs - 1, 2: (own_degs - 1) * (own_degs - 2) // 2}.get(
            dim, (own_degs - 1) * (own_degs - 2) * (own_degs - 3) // 6
        )
        expected += COMM.allreduce(int(np.sum(np.maximum(nodes, 0))), op=MPI.SUM)
    assert space.dimension == expected
    # the minimum rule: p_E ≤ p_T of every cell around E, and equal to one of them
    assert np.all(p_edge[c2e] <= space.cell_degrees[:, None])
    assert space.dimension < V.dofmap.index_map.size_global


@pytest.mark.parametrize("d, p_max, low", [(2, 5, 3), (3, 3, 2)])
def test_reduced_poisson_solves_a_polynomial_of_degree_p_min_exactly(d, p_max, low):
    """−Δu = f with u = the polynomial of degree ``low`` (the smallest p_T) given on ∂Ω:
    Qᵀ K Q x = Qᵀ b with the Dirichlet unknowns eliminated gives u_h = u to round-off."""
    msh = _mesh(d)
    space = HPSpace(msh, p_max, _degrees(msh, p_max, low))
    V = space.V
    X = ufl.SpatialCoordinate(msh)

    def exact_np(x):
        return sum((1 + k) * x[k] ** low for k in range(d)) + x[0] * x[1] ** (low - 1)

    u_ex = exact_np(X)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    K = fem.petsc.assemble_matrix(fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx))
    K.assemble()
    b = fem.petsc.assemble_vector(fem.form(-ufl.div(ufl.grad(u_ex)) * v * ufl.dx))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    Q, _ = space.matrices()
    A = K.PtAP(Q)
    rhs = A.createVecRight()
    Q.multTranspose(b, rhs)
    msh.topology.create_connectivity(d - 1, d)
    boundary = mesh.exterior_facet_indices(msh.topology)
    fixed_mask = ~space.active
    slots = space.slots_of(d - 1, boundary)
    fixed_mask[slots] = True
    values = fem.Function(V)
    values.x.array[slots] = space.interpolate(exact_np)[slots]
    n = V.dofmap.index_map.size_local
    fixed = np.flatnonzero(fixed_mask[:n]).astype(np.int32)
    diag = A.createVecRight()
    diag.array_w[:] = (~space.active[:n]).astype(float)
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    A.setDiagonal(diag, addv=PETSc.InsertMode.ADD_VALUES)
    rows = V.dofmap.index_map.local_to_global(fixed).astype(PETSc.IntType)
    A.zeroRowsColumns(rows, 1.0, values.x.petsc_vec, rhs)
    ksp = PETSc.KSP().create(COMM)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    x, u_h = fem.Function(V), fem.Function(V)
    ksp.solve(rhs, x.x.petsc_vec)
    x.x.scatter_forward()
    Q.mult(x.x.petsc_vec, u_h.x.petsc_vec)
    u_h.x.scatter_forward()
    e = fem.assemble_scalar(
        fem.form(ufl.inner(ufl.grad(u_h - u_ex), ufl.grad(u_h - u_ex)) * ufl.dx)
    )
    assert np.sqrt(abs(COMM.allreduce(e, op=MPI.SUM))) < 1e-9


def test_the_space_on_two_ranks():
    if COMM.size > 1:
        pytest.skip("this test starts the others on 2 ranks")
    proc = pytest_on_ranks("test_hp_space.py", "not two_ranks", ranks=2)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "4 passed" in proc.stdout
