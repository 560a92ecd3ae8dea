"""What a recoupled finite-strain solve builds once instead of at every coupling
(contact/base/spaces.py: spaces, collapsed components, zero functions and vectors per mesh)
and the small factorizations gathered onto every rank (contact/solvers/linear.py,
``GatheredFactor``).

Checked: a space, a collapsed component, a zero function and a zero vector are made once
and reused, equal to what they replace (the same map, zeros owned and ghost, ghosts updated
through the shared scatter); a self-contact ring's recoupled load path makes fewer spaces
with the caches and gives the same solution (to 1e-12) as without; the gathered LDLᵀ has
distributed MUMPS's inertia and solution (to 1e-12).  Serially and on 2 and 3 ranks."""

from __future__ import annotations

import gc
from pathlib import Path

import contact
from contact.base import spaces
from contact.solvers import linear

import dolfinx
import numpy as np
import pytest
import ufl
from clirun import pytest_on_ranks
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

COMM = MPI.COMM_WORLD
CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def test_a_space_its_components_and_zero_fields_are_made_once():
    assert spaces.CACHE  # on by default
    msh = mesh.create_unit_square(COMM, 6, 4)
    V = spaces.functionspace(msh, ("Lagrange", 1, (2,)))
    assert spaces.functionspace(msh, ("Lagrange", 1, (2,))) is V
    assert spaces.functionspace(msh, ("Lagrange", 2, (2,))) is not V
    other = mesh.create_unit_square(COMM, 6, 4)
    assert spaces.functionspace(other, ("Lagrange", 1, (2,))) is not V
    # a collapsed component: made once, the map of V.sub(k).collapse()
    S, dofs = spaces.collapsed(V, 1)
    assert spaces.collapsed(V, 1)[0] is S
    _, fresh = V.sub(1).collapse()
    assert np.array_equal(dofs, np.asarray(fresh))
    # zero functions: new objects, zero, named, independent; ghosts updated by the copy's
    # scatter as by a function of its own
    f = spaces.zero_function(V, "first")
    f.x.array[:] = 7.0
    g = spaces.zero_function(V, "second")
    assert g is not f and g.name == "second" and not np.any(g.x.array)
    ref = fem.Function(V)
    for fn in (g, ref):
        fn.interpolate(lambda x: np.vstack([x[0] + 2 * x[1], x[0] * x[1]]))
        fn.x.array[V.dofmap.index_map.size_local * 2 :] = -1.0  # ghosts stale
        fn.x.scatter_forward()
    assert np.array_equal(g.x.array, ref.x.array)
    # zero vectors on V's index map likewise
    a = spaces.zero_vector(V, 2)
    a.array[:] = 1.0
    b = spaces.zero_vector(V, 2)
    assert b.array.shape == a.array.shape and not np.any(b.array)


def test_a_function_freed_by_the_cycle_collector_on_one_rank_keeps_the_communicator():
    """A cached space's last function, in a reference cycle, freed by the cyclic collector
    on rank 0 only (as the collector runs at moments of its own on each rank): the next
    PETSc vector on the space is made on every rank without waiting.  Before the space kept
    PETSc's inner communicator (the module doc), rank 0 duplicated it again — a collective
    call rank 1 did not make — and the ranks waited for each other forever (the 2-rank
    Cattaneo run of tests/test_bodies.py did)."""
    assert spaces.CACHE  # on by default
    msh = mesh.create_unit_square(COMM, 8, 8)
    V = spaces.functionspace(msh, ("Lagrange", 1, (2,)))
    enabled = gc.isenabled()
    gc.disable()
    try:
        f = spaces.zero_function(V)
        f.x.petsc_vec.set(1.0)  # the only PETSc vector on V's communicator
        cycle: list = [f]
        cycle.append(cycle)
        del f, cycle
        if COMM.rank == 0:
            gc.collect()  # f's vector destroyed here, on rank 0 only
        g = spaces.zero_function(V)
        g.x.petsc_vec.set(2.0)
        assert g.x.petsc_vec.norm(PETSc.NormType.NORM_1) == 2.0 * g.x.petsc_vec.getSize()
    finally:
        gc.collect()
        if enabled:
            gc.enable()


@pytest.mark.parametrize("shape", [(), (2,)])
def test_a_space_named_by_a_tuple_is_the_space_of_its_element(monkeypatch, shape):
    """``("Lagrange", 1)`` and the UFL element ``fem.functionspace`` makes of it name one
    space (refinement's prolongation asks by element, a scene's builder by tuple); its DoF
    points are tabulated once, read-only, equal to ``tabulate_dof_coordinates``."""
    msh = mesh.create_unit_square(COMM, 5, 3)
    V = spaces.functionspace(msh, ("Lagrange", 1, shape))
    assert spaces.functionspace(msh, V.ufl_element()) is V
    assert spaces.functionspace(msh, ("Lagrange", 2, shape)).ufl_element() != V.ufl_element()
    X = spaces.dof_coordinates(V)
    assert spaces.dof_coordinates(V) is X and not X.flags.writeable
    assert np.array_equal(X, V.tabulate_dof_coordinates())
    monkeypatch.setattr(spaces, "ELEMENT_KEYS", False)  # the old path: cached by the key given
    other = mesh.create_unit_square(COMM, 5, 3)
    V = spaces.functionspace(other, ("Lagrange", 1, shape))
    W = spaces.functionspace(other, V.ufl_element())
    assert W is not V and W.ufl_element() == V.ufl_element()


def test_without_the_cache_everything_is_made_afresh(monkeypatch):
    monkeypatch.setattr(spaces, "CACHE", False)
    msh = mesh.create_unit_square(COMM, 4, 4)
    V = spaces.functionspace(msh, ("Lagrange", 1, (2,)))
    assert spaces.functionspace(msh, ("Lagrange", 1, (2,))) is not V
    assert spaces.collapsed(V, 0)[0] is not spaces.collapsed(V, 0)[0]
    assert not np.any(spaces.zero_function(V).x.array)
    assert spaces.dof_coordinates(V) is not spaces.dof_coordinates(V)


def _indefinite_matrix(n: int) -> tuple[PETSc.Mat, mesh.Mesh]:
    """−Δ − 0.3 on an n × 2 strip (P1, no boundary condition): symmetric, a few negative
    eigenvalues, ~3n unknowns; and its mesh (kept alive: the matrix lives on its
    communicator)."""
    msh = mesh.create_rectangle(COMM, [[0.0, 0.0], [8.0, 1.0]], [n, 2])
    V = fem.functionspace(msh, ("Lagrange", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx - 0.3 * u * v * ufl.dx)
    A = fem_petsc.assemble_matrix(a)
    A.assemble()
    return A, msh


@pytest.mark.parametrize("factor", ["cholesky", "lu"])
def test_a_gathered_factorization_has_the_distributed_inertia_and_solution(monkeypatch, factor):
    """On more than one rank a small system is factorized whole on every rank: the same
    inertia (LDLᵀ) and solution as MUMPS across the ranks (serially both are MUMPS)."""
    A, _msh = _indefinite_matrix(64)
    assert linear.gathers(A) == (COMM.size > 1)
    b = A.createVecLeft()
    b.array_w[:] = np.cos(np.arange(*b.getOwnershipRange()))
    results = []
    for size in (linear.GATHERED_FACTOR_SIZE, 0):
        monkeypatch.setattr(linear, "GATHERED_FACTOR_SIZE", size)
        ksp = linear.mumps_ksp(A, factor)
        ksp.setUp()
        x = b.duplicate()
        ksp.solve(b, x)
        inertia = linear.factor_inertia(ksp.getPC()) if factor == "cholesky" else None
        results.append((inertia, x))
        ksp.destroy()
    (inertia_g, x_g), (inertia_d, x_d) = results
    if factor == "cholesky":
        assert inertia_g == inertia_d and inertia_g[0] > 0  # indefinite: negative eigenvalues
    diff = x_g.copy()
    diff.axpy(-1.0, x_d)
    assert diff.norm() <= 1e-12 * x_d.norm()
    for obj in (A, b, x_g, x_d, diff):
        obj.destroy()


def test_recoupled_passes_reuse_the_space_with_equal_results(monkeypatch):
    """The self-contact ring (64 × 2 cells, 2 load steps, its pairs recoupled ~10 times a
    step): with the caches, the passes make fewer spaces, and the solution is the one built
    afresh at every pass (to 1e-12 of its size)."""
    made = []
    original = dolfinx.fem.functionspace

    def counted(*args, **kwargs):
        made.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(dolfinx.fem, "functionspace", counted)
    overrides = ["mesh.cells=[64,2]", "load.steps=2", "output.png=false"]
    solutions, counts = [], []
    for cache in (True, False):
        monkeypatch.setattr(spaces, "CACHE", cache)
        made.clear()
        scene = contact.load_scene(CONFIGS / "hyperelastic_self_contact_ring.yaml", overrides)
        path = contact.run_load_path(scene)
        result = path.steps[-1].result
        assert path.converged and len(result.couplings) > 2
        solutions.append(result.u_h.x.array[: len(result.u_h.x.array)].copy())
        counts.append(len(made))
    cached, fresh = solutions
    assert counts[0] < counts[1]
    assert np.max(np.abs(cached - fresh)) <= 1e-12 * np.max(np.abs(fresh))


def test_on_two_and_three_ranks():
    if COMM.size > 1:
        pytest.skip("this test starts the others on 2 and 3 ranks")
    proc = pytest_on_ranks("test_spaces.py", "not ranks", ranks=2)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "8 passed" in proc.stdout
    proc = pytest_on_ranks("test_spaces.py", "not ranks and not recoupled", ranks=3)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "7 passed" in proc.stdout
