"""A scene on a gmsh .msh file with physical tags (issue #2): boundary parts by tag give the
same answer as by predicate on the same mesh, semismooth Newton agrees with vinewtonrsls,
and the adaptive loop refines a gmsh mesh keeping its tags."""

import contact
from contact.setup.scalar import scalar_problem

import numpy as np
import pytest
from conftest import make_square_msh


def _scene(msh, boundaries):
    return {
        "name": "gmsh_square",
        "mesh": {"type": "gmsh", "file": str(msh)},
        "boundaries": boundaries,
        "model": "signorini",
        "data": {"f": "1", "g": "0.1 + 2*(x - 0.5)**2"},
        "output": {"verbose": False},
    }


BY_TAG = {
    "top": {"role": "dirichlet", "tag": 2},
    "sides": {"role": "neumann", "tag": 3},
    "bottom": {"role": "contact", "tag": 1},
}
BY_PREDICATE = {
    "top": {"role": "dirichlet", "where": "y > 1 - 1e-10"},
    "sides": {"role": "neumann", "where": "x < 1e-10 or x > 1 - 1e-10"},
    "bottom": {"role": "contact", "where": "y < 1e-10"},
}


@pytest.fixture(scope="module")
def msh(tmp_path_factory):
    return make_square_msh(tmp_path_factory.mktemp("gmsh") / "square.msh", size=0.04)


def test_tags_and_predicates_agree(msh):
    by_tag = contact.load_scene(_scene(msh, BY_TAG))
    by_pred = contact.load_scene(_scene(msh, BY_PREDICATE))
    for role in ("dirichlet", "neumann", "contact"):
        assert np.array_equal(by_tag.boundary.facets(role), by_pred.boundary.facets(role)), role
    a, b = contact.solve(by_tag), contact.solve(by_pred)
    assert a.converged and b.converged
    assert np.max(np.abs(a.u_h.x.array - b.u_h.x.array)) <= 1e-12
    assert a.n_active > 0


@pytest.mark.parametrize("method", ["fb", "min", "blend"])
def test_gmsh_scene_agrees_with_vinewtonrsls(msh, method):
    scene = contact.load_scene(_scene(msh, BY_TAG))
    problem = scalar_problem(scene)
    ref = contact.solve(scene, method="vinewtonrsls", problem=problem).u_h.x.array.copy()
    res = contact.solve(scene, method=method, problem=problem)
    assert res.converged
    assert np.max(np.abs(res.u_h.x.array - ref)) <= 1e-8


def test_adaptive_loop_on_gmsh_mesh(msh):
    scene = contact.load_scene(_scene(msh, BY_TAG))
    levels = contact.adapt(scene, method="min", max_levels=3, verbose=False).levels
    assert len(levels) == 3 and levels[-1].result.converged
    last = levels[-1].scene
    assert set(last.boundary.ids.values()) == {1, 2, 3}
    # every contact facet of the refined mesh still lies on y = 0
    from dolfinx.mesh import compute_midpoints

    mid = compute_midpoints(last.mesh, 1, last.boundary.facets("contact"))
    assert len(mid) > 0 and np.all(np.abs(mid[:, 1]) < 1e-10)
