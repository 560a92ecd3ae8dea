"""The figures a solve puts on its result: the first point of contact and the forces on a
mortar pair's surfaces (``Result.first_contact``, ``Result.interface_forces``,
``Coupling.surface_forces``), against independent computations of the same numbers."""

from pathlib import Path

import contact
from contact.models.mortar import part_facets, surface_facets
from contact.models.problem import TIE_RTOL, first_contact_point
from contact.post.interface import resultants
from contact.post.resultants import whole_body
from contact.setup.build import build_problem
from contact.setup.posed import posed_of

import dolfinx.fem.petsc
import numpy as np
import pytest
import ufl
from clirun import pytest_on_ranks
from dolfinx import fem, la, mesh
from mpi4py import MPI
from petsc4py import PETSc

ROOT = Path(__file__).resolve().parents[1]
PATCH_2D = ROOT / "configs" / "two_body_patch_2d.yaml"


@pytest.fixture(scope="module")
def patch():
    scene = contact.load_scene(PATCH_2D, ["output.verbose=false", "solver.rtol=1e-12"])
    problem = build_problem(scene)
    return scene, problem, contact.solve(scene, problem=problem, verbose=False)


def _surface_nodes(V, bnd, part: str) -> np.ndarray:
    """The owned nodes of a boundary part, from its facets' vertices on any rank."""
    nodes = surface_facets(V, part_facets(bnd, part)).nodes
    mark = la.vector(V.dofmap.index_map, 1)
    mark.array[np.unique(nodes)] = 1.0
    mark.scatter_reverse(la.InsertMode.add)
    return np.flatnonzero(mark.array[: V.dofmap.index_map.size_local] > 0)


def test_interface_forces_are_the_residual_on_each_surface(patch):
    """Result.interface_forces = Σ over each surface's owned nodes of a(u_h, v) − L(v), the
    Dirichlet DoFs left out (assembled here again), to 1e-12; the report's interface forces
    are those of the whole body; they balance (a uniform pressure: exactly)."""
    scene, problem, r = patch
    assert r.converged and r.interface_forces is not None
    p, comm = r.problem, scene.mesh.comm
    V, bs = p.V, p.V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local
    vec = dolfinx.fem.petsc.assemble_vector(p.data.reaction_form)
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    residual = vec.array_r.reshape(-1, bs).copy()
    vec.destroy()
    fixed = np.zeros(n_owned * bs, dtype=bool)
    for bc in p.data.u_bcs:
        dofs = bc.dof_indices()[0]
        fixed[dofs[dofs < n_owned * bs]] = True
    residual[fixed.reshape(-1, bs)] = 0.0
    posed = posed_of(scene)
    expected = [
        sum(
            comm.allreduce(residual[_surface_nodes(V, scene.boundary, pair[side])].sum(axis=0))
            for pair in posed.pairs
        )
        for side in (0, 1)
    ]
    scale = np.linalg.norm(expected[0])
    assert scale > 0
    for mine, theirs in zip(r.interface_forces, expected):
        assert np.linalg.norm(mine - theirs) <= 1e-12 * scale
    report = resultants(posed, r)
    assert report["interface_force_slave"] == whole_body(p, r.interface_forces[0])
    assert report["interface_force_master"] == whole_body(p, r.interface_forces[1])
    balance = np.linalg.norm(r.interface_forces[0] + r.interface_forces[1])
    assert balance <= 1e-10 * scale


def test_surface_forces_count_each_surface_node_once(patch):
    """Coupling.surface_forces of the force 1 at every node: the number of nodes of the
    slave and of the master surface (their facets' nodes, counted over all ranks)."""
    scene, problem, _ = patch
    V, comm = problem.V, scene.mesh.comm
    tdim = scene.mesh.topology.dim
    n_owned = V.dofmap.index_map.size_local
    ones = np.ones((n_owned, V.dofmap.index_map_bs))
    bnd = scene.boundary
    pair = posed_of(scene).pairs[0]
    coupling = problem.data.couplings[0]
    slave, master = coupling.surface_forces(ones, comm)
    for force, part in zip((slave, master), pair):
        nodes = fem.locate_dofs_topological(V, tdim - 1, part_facets(bnd, part))
        owned = comm.allreduce(int(np.sum(nodes < n_owned)))
        assert owned > 0 and np.array_equal(force, np.full(len(force), float(owned)))


def test_first_contact_of_own_forms():
    """An obstacle problem of own forms solved by contact.solve: the first point of contact
    is the node where the obstacle ψ comes closest, ψ = 0.05 + |x − (0.25, 0.5)|²."""
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 8, 8)
    V = fem.functionspace(msh, ("Lagrange", 1))
    u, v = fem.Function(V), ufl.TestFunction(V)
    F = ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx - 10 * v * ufl.dx
    facets = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
    bc = fem.dirichletbc(0.0, fem.locate_dofs_topological(V, 1, facets), V)
    x = ufl.SpatialCoordinate(msh)
    psi = 0.05 + (x[0] - 0.25) ** 2 + (x[1] - 0.5) ** 2
    problem = contact.ComplementarityProblem.from_residual(F, u, contact.Unilateral(psi), [bc])
    result = contact.solve(problem)
    assert result.converged
    assert np.allclose(result.first_contact, [0.25, 0.5], rtol=0, atol=1e-14)
    problem.close()


def test_first_contact_is_the_smallest_gap(patch):
    """Result.first_contact: a constrained node whose initial gap σg is the smallest over all
    ranks (a tie within TIE_RTOL of the coordinates: the flat patch touches everywhere) —
    the first of those in coordinate order (first_contact_point)."""
    scene, problem, r = patch
    comm = scene.mesh.comm
    con = problem.constraint
    X, dist = problem.node_coordinates(), con.sign * con.g
    assert np.array_equal(r.first_contact, first_contact_point(comm, X, dist))
    lowest = comm.allreduce(float(dist.min(initial=np.inf)), op=MPI.MIN)
    at = np.all(np.isclose(X, r.first_contact, rtol=0, atol=1e-14), axis=1)
    found = comm.allreduce(float(dist[at].min(initial=np.inf)), op=MPI.MIN)
    scale = max(1.0, comm.allreduce(float(np.abs(X).max(initial=0.0)), op=MPI.MAX))
    assert lowest <= found <= lowest + TIE_RTOL * scale


@pytest.mark.mpi
def test_on_two_ranks():
    """The tests above pass on each of 2 MPI ranks: every assertion compares global values
    (sums and minima over the ranks), so a partitioned mesh gives the same figures."""
    proc = pytest_on_ranks(__file__, "not ranks")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert proc.stdout.count("4 passed") == 2 and " failed" not in proc.stdout
