"""Problem A (docs/theory.md §7): the H¹-seminorm error of P1 falls like O(h) under
uniform refinement."""

import contact
from contact.adaptivity.energy_error import energy_error

import numpy as np

SCENE = "configs/signorini_free_boundary.yaml"
# |u|²_{H¹} = 3.443380724 (docs/theory.md §7 A)
EXACT_SEMINORM_SQ = 1.5 * (np.sqrt(2.0) + np.arcsinh(1.0))


def test_problem_A_energy_error_rate():
    errors, hs = [], []
    for n in (8, 16, 32, 64):
        scene = contact.load_scene(SCENE, [f"mesh.cells=[{2 * n},{n}]"])
        result = contact.solve(scene, method="min", verbose=False)
        assert result.converged, result.reason
        errors.append(energy_error(result.u_h, scene.config.data.exact))
        hs.append(1.0 / n)
    rates = np.diff(np.log(errors)) / np.diff(np.log(hs))
    assert np.all(rates[-3:] >= 0.9), f"errors {errors}, rates {rates}"


def test_exact_seminorm_matches_spec():
    """The quadrature of the exact solution reproduces |u|²_{H¹} = 3.443380724
    (docs/theory.md §7 A), so the error above is measured against the right function."""
    import ufl
    from dolfinx import fem
    from mpi4py import MPI

    scene = contact.load_scene(SCENE, ["mesh.cells=[64,32]"])
    u = contact.base.expressions.to_ufl(scene.config.data.exact, scene.mesh)
    dx = ufl.dx(domain=scene.mesh, metadata={"quadrature_degree": 10})
    val = scene.comm.allreduce(
        fem.assemble_scalar(fem.form(ufl.inner(ufl.grad(u), ufl.grad(u)) * dx)), op=MPI.SUM
    )
    assert abs(val - 3.443380724) < 1e-5
    assert abs(EXACT_SEMINORM_SQ - 3.443380724) < 1e-9
