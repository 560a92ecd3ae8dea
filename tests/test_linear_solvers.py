"""Krylov + GAMG gives the same discrete solution as the direct solver (issue #2)."""
import numpy as np
import pytest

import contact
from contact.models.scalar import scalar_problem

GAMG = {"ksp_type": "bcgs", "pc_type": "gamg", "ksp_rtol": 1e-10}


@pytest.mark.parametrize("scene_name", ["signorini_square", "signorini_free_boundary", "obstacle_membrane"])
@pytest.mark.parametrize("method", ["fb", "min"])
def test_gamg_matches_direct(scene_name, method):
    scene = contact.load_scene(f"configs/{scene_name}.yaml", ["mesh.cells=[32,32]"])
    problem = scalar_problem(scene)
    direct = contact.solve(scene, method=method, problem=problem, verbose=False)
    u_direct = direct.u_h.x.array.copy()
    krylov = contact.solve(scene, method=method, problem=problem, verbose=False, petsc_options=GAMG)
    assert direct.converged and krylov.converged, (direct.reason, krylov.reason)
    assert np.max(np.abs(krylov.u_h.x.array - u_direct)) <= 1e-8
    assert krylov.n_active == direct.n_active


def test_bad_petsc_option_is_a_config_error():
    scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[8,8]"])
    with pytest.raises(contact.ConfigError, match="solver.petsc_options"):
        contact.solve(scene, verbose=False, petsc_options={"pc_type": "nonexistent"})


def test_options_read_at_setup_reach_the_solver():
    """GAMG reads its level smoothers' options (mg_levels_*) when it is set up, in the first
    linear solve: they must still be in PETSc's database then (they were ignored when the
    options were removed right after KSPSetFromOptions).  More Chebyshev sweeps per level
    must take fewer CG iterations."""
    scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[96,96]"])
    problem = scalar_problem(scene)
    its = {}
    for sweeps in (1, 6):
        r = contact.solve(scene, method="min", problem=problem, verbose=False, linear="gamg",
                          petsc_options={"mg_levels_ksp_max_it": sweeps})
        assert r.converged, r.reason
        its[sweeps] = r.krylov_iterations
    assert its[6] < its[1], its
