"""Refinement that does not depend on the partition (contact.adaptivity.longest_edge): of two
edges of a face with exactly the same length, ``dolfinx.mesh.refine`` takes the one opposite
the vertex of larger global index in 3D.  The mesh is refined displaced by a hash of the
coordinates that leaves no face tied, then put back: the vertices where DOLFINx puts them,
bit for bit.  The same meshes on 1, 2 and 3 ranks are tested in
tests/test_parallel_invariance.py."""

import contact
from contact.adaptivity import longest_edge

import numpy as np
import pytest
from clirun import ROOT
from dolfinx import mesh as dmesh
from mpi4py import MPI

SPHERE = ROOT / "configs" / "two_body_hertz_3d.yaml"


@pytest.fixture(scope="module")
def sphere_mesh() -> dmesh.Mesh:
    """The gmsh mesh of an elastic sphere on a block (its octant of a sphere is meshed
    symmetrically about x = y: faces with two longest edges of equal length)."""
    return contact.load_scene(SPHERE).mesh


def _face_sides(msh: dmesh.Mesh, x: np.ndarray) -> np.ndarray:
    """Each face's edge lengths, ascending (face, 3)."""
    top = msh.topology
    for dim in (1, 2):
        top.create_entities(dim)
    top.create_connectivity(2, 1)
    top.create_connectivity(1, 0)
    top.create_connectivity(3, 0)
    node = np.empty(top.index_map(0).size_local + top.index_map(0).num_ghosts, dtype=np.int64)
    node[top.connectivity(3, 0).array] = msh.geometry.dofmaps[0].ravel()
    e2v = node[top.connectivity(1, 0).array.reshape(-1, 2)]
    lengths = np.linalg.norm(x[e2v[:, 0]] - x[e2v[:, 1]], axis=1)
    return np.sort(lengths[top.connectivity(2, 1).array.reshape(-1, 3)], axis=1)


def _sorted(X: np.ndarray) -> np.ndarray:
    return X[np.lexsort(X.T[::-1])]


def test_displacement_leaves_no_face_tied(sphere_mesh):
    """The sphere's mesh has faces whose two longest edges are equal to the last bit; the
    displacement, at most 10⁻⁴ of the shortest edge, leaves every face's two longest edges
    further apart than 10⁻¹³ relative."""
    x = sphere_mesh.geometry.x
    sides = _face_sides(sphere_mesh, x)
    assert np.count_nonzero(sides[:, 2] == sides[:, 1]) >= 4  # exact ties, as DOLFINx sees them
    shift = longest_edge.displacement(sphere_mesh)
    assert shift is not None and shift.shape == x.shape
    h_min = sides[:, 0].min()
    assert 0 < np.abs(shift).max() <= longest_edge.DISPLACEMENT * h_min
    moved = _face_sides(sphere_mesh, x + shift)
    assert np.all(moved[:, 2] - moved[:, 1] > longest_edge.TIE * moved[:, 2])


def test_displacement_is_a_function_of_the_coordinates(sphere_mesh):
    """The displacement of a vertex depends on its coordinates alone (not on its index, so
    not on the partition), and -0.0 and 0.0 are one coordinate."""
    x = sphere_mesh.geometry.x
    assert np.any(x == 0.0)  # the symmetry planes
    r = longest_edge.coordinate_hash(x, 0)
    order = np.random.default_rng(1).permutation(len(x))
    np.testing.assert_array_equal(longest_edge.coordinate_hash(x[order], 0), r[order])
    np.testing.assert_array_equal(longest_edge.coordinate_hash(np.where(x == 0.0, -0.0, x), 0), r)
    assert np.all((r >= -1) & (r < 1)) and abs(r.mean()) < 0.05  # spread over [-1, 1)
    assert not np.array_equal(longest_edge.coordinate_hash(x, 1), r)  # another draw, other values


def test_refined_vertices_are_dolfinx_s_bit_for_bit(sphere_mesh):
    """Every edge split (the vertices then do not depend on which edges are longest): the
    refined mesh's vertices are dolfinx.mesh.refine's, bit for bit — old vertices where
    they were, new ones at the midpoints DOLFINx computes — and the mesh refined is put back
    unchanged."""
    msh = sphere_mesh
    before = msh.geometry.x.copy()
    msh.topology.create_entities(1)
    edges = np.arange(msh.topology.index_map(1).size_local, dtype=np.int32)
    assert longest_edge.displacement(msh) is not None  # the displaced path is taken
    ours, parent_cell, parent_facet = longest_edge.refine(msh, edges, None)
    theirs, their_parent, _ = dmesh.refine(
        msh, edges, partitioner=None, option=dmesh.RefinementOption.parent_cell_and_facet
    )
    np.testing.assert_array_equal(msh.geometry.x, before)
    np.testing.assert_array_equal(_sorted(ours.geometry.x), _sorted(theirs.geometry.x))
    cells = ours.topology.index_map(3).size_local
    assert cells == theirs.topology.index_map(3).size_local == 8 * len(msh.geometry.dofmaps[0])
    assert len(parent_cell) == cells and len(parent_facet) == 4 * cells
    np.testing.assert_array_equal(
        np.bincount(parent_cell), np.full(len(msh.geometry.dofmaps[0]), 8)
    )
    # every child lies in its parent: its vertices are the parent's vertices and midpoints
    volume = _volumes(ours).sum()
    assert volume == pytest.approx(_volumes(msh).sum(), rel=1e-12)


def _volumes(msh: dmesh.Mesh) -> np.ndarray:
    X = msh.geometry.x[msh.geometry.dofmaps[0]]
    return np.abs(np.linalg.det(X[:, 1:] - X[:, :1])) / 6


def test_a_mesh_without_ties_is_refined_as_dolfinx_does():
    """Kuhn's tetrahedra of a box have right-angled faces (a strictly longest edge): no
    displacement, and the refined mesh is dolfinx.mesh.refine's, cells included."""
    msh = dmesh.create_box(MPI.COMM_SELF, [[0, 0, 0], [1, 1, 1]], [3, 3, 3])
    assert longest_edge.displacement(msh) is None
    msh.topology.create_entities(1)
    edges = np.arange(0, msh.topology.index_map(1).size_local, 3, dtype=np.int32)
    ours, _, _ = longest_edge.refine(msh, edges, None)
    theirs, _, _ = dmesh.refine(
        msh, edges, partitioner=None, option=dmesh.RefinementOption.parent_cell_and_facet
    )
    np.testing.assert_array_equal(ours.geometry.x, theirs.geometry.x)
    np.testing.assert_array_equal(ours.geometry.dofmaps[0], theirs.geometry.dofmaps[0])


def test_ties_left_after_every_draw_are_one_warning(sphere_mesh, monkeypatch):
    """Were every face still tied after the last draw (here: a tie tolerance no
    displacement can beat), DOLFINx's own rule would decide them: one warning says so."""
    monkeypatch.setattr(longest_edge, "TIE", 1.0)
    with pytest.warns(UserWarning, match=r"face\(s\) keep two longest edges .* after 16 draws"):
        shift = longest_edge.displacement(sphere_mesh)
    assert shift is not None
