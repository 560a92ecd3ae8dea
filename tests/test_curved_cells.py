"""Curved (isoparametric P2) cells for P2 contact pairs: ``mesh.geometry_degree: 2`` of the
half_disks builder.  The arcs' edge midpoints lie on the circles, so the two cylinders'
P2 surfaces carry Hertz's pressure node by node (on straight cells the nodal pressures
alternate between vertices and midpoints, tests/test_bodies_p2.py); serial = 2 ranks, the
command line writes every file (XDMF with quadratic cells), the residual estimator's sizes
on curved cells, and the one-line refusals of what curved cells do not do."""

import contact
from contact.adaptivity.estimate import cell_sizes
from contact.adaptivity.refine import Domain, refine
from contact.output.xdmf import lagrange_mesh
from contact.post.interface import resultants
from contact.post.reference import compare
from contact.setup.build import build_problem
from contact.setup.posed import posed_of

import numpy as np
import pytest
import ufl
from clirun import contact as cli
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from readback import xdmf_steps
from test_bodies import COARSE_2D, HERTZ_2D, ROOT
from test_bodies_p2 import check_cylinders_serial_equals_two_ranks, nodal_deviation

CURVED = [*COARSE_2D, "mesh.degree=2", "mesh.geometry_degree=2"]
R_C = 8.0  # the cylinders' radius in two_body_hertz_2d.yaml


def test_curved_cylinders_meet_hertz_at_every_node():
    """Two cylinders (R_c = 8, h_contact = 0.1 over a ≈ 0.48), P2 on quadratic cells: every
    slave node's pressure within 0.5 % of Hertz's p0 over |x| < 0.8 a (measured 0.18 %; the
    same mesh with straight cells 9.6 %), the peak within 0.5 % of p0 (measured −0.12 %;
    straight 9.3 %), action = reaction.  The arcs' geometry nodes lie on the circles, and
    the slave nodes' gaps near the contact point are the circles' (vertices and midpoints
    alike)."""
    scene = contact.load_scene(HERTZ_2D, CURVED)
    msh = scene.mesh
    assert msh.geometry.cmaps[0].degree == 2
    for name, centre in (("slave", (0.0, R_C)), ("master", (0.0, -R_C))):
        facets = scene.boundary.tags.find(scene.boundary.ids[name])
        nodes = dmesh.entities_to_geometry(msh, 1, facets)
        assert nodes.shape[1] == 3  # the end points and the edge's midpoint
        radii = np.linalg.norm(msh.geometry.x[nodes.ravel(), :2] - centre, axis=1)
        assert np.max(np.abs(radii - R_C)) < 1e-12 * R_C
    problem = build_problem(scene)
    c, bs = problem.constraint, problem.V.dofmap.index_map_bs
    x = problem.V.tabulate_dof_coordinates()[c.dofs[: len(c.g)] // bs, 0]
    circles = 2 * R_C - 2 * np.sqrt(R_C**2 - x**2)  # the circles' gap, touching at x = 0
    near = np.abs(x) < 0.2
    # measured 3.0e-6 (straight cells: 3.1e-4, the midpoints' sagittas)
    assert near.sum() == 9 and np.max(np.abs(c.g - circles)[near]) < 1e-5
    r = contact.solve(scene, method="min", problem=problem, verbose=False)
    assert r.converged
    deviation, peak = nodal_deviation(scene, r)
    assert deviation < 0.005 and abs(peak) < 0.005
    assert resultants(posed_of(scene), r)["interface_balance_error"] < 1e-10


def test_curved_sphere_on_block_meets_hertz_closer_than_straight_cells():
    """A sphere on a block (``configs/two_body_hertz_3d.yaml`` at h_contact = 0.04), P2 on
    quadratic tetrahedra: the sphere's geometry nodes lie on it, and the nodal pressures'
    rms deviation from Hertz's over r < 0.8 a is below 3 % of p0 (measured 2.0 %; straight
    cells 6.4 %, P1 10.5 %), the largest below 8 % (5.2 %; straight 13.1 %), action =
    reaction."""
    scene = contact.load_scene(
        ROOT / "configs" / "two_body_hertz_3d.yaml",
        ["mesh.h_contact=0.04", "mesh.degree=2", "mesh.geometry_degree=2", "output.verbose=false"],
    )
    msh = scene.mesh
    assert msh.geometry.cmaps[0].degree == 2
    facets = scene.boundary.tags.find(scene.boundary.ids["slave"])
    nodes = dmesh.entities_to_geometry(msh, 2, facets)
    assert nodes.shape[1] == 6  # the vertices and the edges' midpoints
    radii = np.linalg.norm(msh.geometry.x[nodes.ravel()] - (0.0, 0.0, 1.0), axis=1)
    assert np.max(np.abs(radii - 1.0)) < 1e-12
    r = contact.solve(scene, method="min", verbose=False)
    assert r.converged
    p = r.problem
    X = p.output.space.tabulate_dof_coordinates()[p.output.nodes]
    pressure = -r.lmbda_h.x.array[p.output.nodes]
    ref = compare(posed_of(scene), r).values
    a, p0 = ref["hertz_a"], ref["hertz_p0"]
    radius = np.hypot(X[:, 0], X[:, 1])
    inner = radius < 0.8 * a
    error = (pressure[inner] - p0 * np.sqrt(1 - (radius[inner] / a) ** 2)) / p0
    assert inner.sum() > 20
    assert np.sqrt(np.mean(error**2)) < 0.03 and np.max(np.abs(error)) < 0.08
    assert resultants(posed_of(scene), r)["interface_balance_error"] < 1e-10


@pytest.mark.mpi
def test_curved_cylinders_serial_equals_two_ranks(tmp_path):
    check_cylinders_serial_equals_two_ranks(tmp_path, CURVED)


def test_curved_cylinders_through_the_command_line(tmp_path):
    """``contact run`` on curved cells (one level) writes every file; the solution's XDMF
    has quadratic triangles (Triangle_6, as ParaView reads them), the contact surface
    quadratic edges (Edge_3), and the nodes on the arcs lie on the circles."""
    out = tmp_path / "out"
    args = [f"--set={o}" for o in [*CURVED, "adapt.max_levels=1"]]
    done = cli(tmp_path, "run", str(HERTZ_2D), *args, "--out", str(out))
    assert done.returncode == 0, done.stderr
    (solution,) = xdmf_steps(out / "solution.xdmf")
    (surface,) = xdmf_steps(out / "contact_surface.xdmf")
    assert solution["topology"] == "Triangle_6" and surface["topology"] == "Edge_3"
    X = surface["points"][:, :2]
    upper = X[:, 1] > 1e-9
    off = np.abs(np.linalg.norm(X - np.c_[0 * X[:, 0], np.where(upper, R_C, -R_C)], axis=1) - R_C)
    assert np.max(off) < 1e-12 * R_C
    for name in ("summary.json", "contact.csv", "pressure.png", "solution_000.vtu"):
        assert (out / name).stat().st_size > 0


def test_residual_estimator_sizes_on_curved_cells_are_the_affine_ones():
    """On quadratic cells with straight edges (the P1 mesh's cells, every P2 node a geometry
    node) the estimator's h_T and h_E equal UFL's CellDiameter and FacetArea on the P1
    mesh, cell by cell and facet by facet (∫ h w over cells and exterior facets)."""
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 5, 3, cell_type=dmesh.CellType.triangle)
    quadratic, _, cell_of = lagrange_mesh(fem.functionspace(msh, ("Lagrange", 2)))
    assert quadratic.geometry.cmaps[0].degree == 2
    sums = []
    for m in (msh, quadratic):
        W = fem.functionspace(m, ("DG", 0))
        w = ufl.TestFunction(W)
        h_T, h_E = cell_sizes(m, W)
        owned = m.topology.index_map(2).size_local
        cells = fem.assemble_vector(fem.form(h_T * w * ufl.dx)).array[W.dofmap.list[:owned, 0]]
        facets = fem.assemble_vector(fem.form(h_E * w * ufl.ds)).array[W.dofmap.list[:owned, 0]]
        sums.append((cells, facets))
    (c1, f1), (c2, f2) = sums
    assert np.max(np.abs(c2 - c1[cell_of])) < 1e-14 and np.max(c1) > 0.0
    assert np.max(np.abs(f2 - f1[cell_of])) < 1e-14 and np.max(f1) > 0.0


def test_curved_cells_refuse_refinement_in_one_line():
    """The adaptive loop refuses curved cells before solving (refinement splits the vertex
    simplices and knows nothing of the edge nodes), and so does refine itself."""
    scene = contact.load_scene(HERTZ_2D, CURVED)
    with pytest.raises(contact.ConfigError, match=r"^adapt\.max_levels: curved cells") as e:
        contact.adapt(scene, max_levels=2, verbose=False)
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="curved cells"):
        refine(Domain(scene.mesh), np.zeros(1, np.int32))


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["mesh.geometry_degree=2"], r"^mesh\.geometry_degree: curved cells of degree 2 carry"),
        (
            ["mesh.degree=2", "mesh.geometry_degree=3"],
            r"^mesh\.geometry_degree: ",
        ),
    ],
)
def test_curved_cells_need_p2_displacements(overrides, message):
    with pytest.raises(contact.ConfigError, match=message) as e:
        contact.load_scene(HERTZ_2D, [*COARSE_2D, *overrides])
    assert "\n" not in str(e.value)


def test_curved_cells_are_for_the_curved_builders():
    scene = ROOT / "configs" / "two_body_patch_2d.yaml"
    with pytest.raises(contact.ConfigError, match=r"^mesh\.geometry_degree: not used") as e:
        contact.load_scene(scene, ["mesh.degree=2", "mesh.geometry_degree=2"])
    assert "\n" not in str(e.value)
