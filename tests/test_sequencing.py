"""Grid sequencing of a single solve and the reduced SPD Newton system (issue 11).

Sequencing changes only the initial guess and the linear solver only how each Newton step
is solved: the answer must be the cold direct solve's to solver tolerance, and the
counts the result reports must be those of the levels actually solved."""

import contact
from contact.drivers.sequencing import COARSEST_DOFS, transfer
from contact.models import build_problem

import numpy as np
import pytest
from conftest import make_square_msh
from ties import tie_margin


def _solve(scene, **opts):
    problem = build_problem(scene)
    return contact.solve(scene, problem=problem, verbose=False, **opts)


@pytest.mark.parametrize("method", ["fb", "min"])
def test_sequenced_gamg_equals_cold_direct(method):
    """128² square (16,641 DoFs): auto sequences (coarse levels of 32², 64²) and solves the
    reduced system with CG + GAMG; the answer is the cold MUMPS solve's to 1e-8, and the
    finest mesh needs at most 3 linear solves (fb: polishing the guess, one Newton step and
    its polishing; 2 while solver.atol was an absolute 1e-12, which the polished guess met
    at 5e-13, 5e-11 of this scene's force scale: issue 26 made it relative to that scale)."""
    scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[128,128]"])
    cold = _solve(scene, method=method, sequence="off", linear="direct")
    seq = _solve(scene, method=method)
    assert cold.converged and seq.converged
    assert seq.linear == "gamg" and cold.linear == "direct"
    assert [lv.dofs for lv in seq.sequence][-2:] == [33**2, 65**2]
    assert all(lv.converged for lv in seq.sequence) and seq.sequence[0].dofs >= COARSEST_DOFS
    # bounds with room: the sequenced guess has the final active set up to a few nodes (1–2
    # solves, one more to meet the relative atol), the cold start from u = 0 moves ~100
    # nodes (≥ 5 solves)
    assert seq.linear_solves <= 3 < cold.linear_solves
    assert np.max(np.abs(seq.u_h.x.array - cold.u_h.x.array)) <= 1e-8
    # work in units of one fine solve: the coarse levels add less than one
    assert seq.weighted_linear_solves < seq.linear_solves + 1.0


def test_sequence_off_and_explicit_levels():
    scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[64,64]"])
    off = _solve(scene, method="min", sequence="off")
    two = _solve(scene, method="min", sequence=2)
    assert off.sequence == [] and [lv.dofs for lv in two.sequence] == [17**2, 33**2]
    assert np.max(np.abs(off.u_h.x.array - two.u_h.x.array)) <= 1e-8
    # more than exist (or than fit the parts): a note
    many = _solve(scene, method="min", sequence=20)
    assert many.sequence_note.startswith("grid sequencing") and 4 <= len(many.sequence) <= 6
    assert many.converged and np.max(np.abs(off.u_h.x.array - many.u_h.x.array)) <= 1e-8


def test_mesh_file_scene_starts_cold_and_says_so(tmp_path):
    """A user's .msh has no coarser mesh: a cold start, and the result's note says why."""
    msh = make_square_msh(tmp_path / "square.msh", size=0.04)
    scene = contact.load_scene(
        {
            "name": "gmsh_square",
            "mesh": {"type": "gmsh", "file": str(msh)},
            "boundaries": {
                "top": {"role": "dirichlet", "tag": 2},
                "sides": {"role": "neumann", "tag": 3},
                "bottom": {"role": "contact", "tag": 1},
            },
            "model": "signorini",
            "data": {"f": "1", "g": "0.1 + 2*(x - 0.5)**2"},
            "output": {"verbose": False},
        }
    )
    r = _solve(scene, method="min", sequence=2)
    assert r.converged and r.sequence == [] and "mesh file" in r.sequence_note


def test_refined_scene_sequences_through_its_ancestors():
    """A scene made by contact.refine solves its coarser ancestors first (exact nested
    prolongation) and gives the cold answer."""
    scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["mesh.cells=[16,16]"])
    for _ in range(5):
        r = contact.solve(scene, method="min", verbose=False, sequence="off")
        cells = contact.mark(contact.estimate(scene, r).eta_T, "uniform")
        scene, _ = contact.refine(scene, cells)
    seq = _solve(scene, method="min", sequence=2)
    cold = _solve(scene, method="min", sequence="off", linear="direct")
    assert len(seq.sequence) == 2 and seq.sequence[-1].dofs * 4 <= seq.dofs
    assert np.max(np.abs(seq.u_h.x.array - cold.u_h.x.array)) <= 1e-8


def test_grid_transfer_is_exact_for_bilinear_data():
    """The structured transfer reproduces a bilinear function (P1 on both meshes, nodes of
    the fine grid on coarse grid lines or inside coarse cells)."""
    from dolfinx import fem

    coarse = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[8,8]"])
    fine = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[32,32]"])
    Vc = fem.functionspace(coarse.mesh, ("Lagrange", 1))
    Vf = fem.functionspace(fine.mesh, ("Lagrange", 1))
    u = fem.Function(Vc)
    u.interpolate(lambda x: 1 + 2 * x[0] - x[1] + 3 * x[0] * x[1])
    out = transfer(u, coarse, fine, Vf)
    X = Vf.tabulate_dof_coordinates()
    exact = 1 + 2 * X[:, 0] - X[:, 1] + 3 * X[:, 0] * X[:, 1]
    assert np.max(np.abs(out.x.array - exact)) <= 1e-12


@pytest.mark.parametrize(
    "scene_name,linear",
    [("hertz_2d", "gamg"), ("hertz_2d", "bcgs"), ("signorini_free_boundary", "gamg")],
)
def test_iterative_newton_systems_equal_direct(scene_name, linear):
    """The reduced CG + GAMG system (rigid-body modes for elasticity) and BiCGStab + GAMG on
    the assembled H give the direct solution to 1e-8 from the same cold start."""
    scene = contact.load_scene(f"configs/{scene_name}.yaml")
    direct = _solve(scene, method="min", sequence="off", linear="direct")
    it = _solve(scene, method="min", sequence="off", linear=linear)
    assert direct.converged and it.converged and it.linear == linear
    assert it.krylov_iterations > 0
    scale = np.max(np.abs(direct.u_h.x.array))
    assert np.max(np.abs(it.u_h.x.array - direct.u_h.x.array)) <= 1e-8 * max(scale, 1.0)
    assert tie_margin(direct) >= 1e-6  # no node near a tie: the counts cannot move with rounding
    assert it.n_active == direct.n_active


def test_frictional_scene_does_not_sequence():
    scene = contact.load_scene("configs/friction_block_2d.yaml")
    r = contact.solve(scene, verbose=False, sequence=2)
    assert r.sequence == [] and "frictional" in r.sequence_note
    assert r.linear in ("direct", "bcgs")


def test_bad_sequence_value_is_a_config_error():
    with pytest.raises(contact.ConfigError, match="solver.sequence"):
        contact.load_scene("configs/signorini_square.yaml", ["solver.sequence=-1"])
    with pytest.raises(contact.ConfigError, match="solver.linear"):
        contact.load_scene("configs/signorini_square.yaml", ["solver.linear=cholesky"])


def test_unquoted_off_turns_sequencing_off():
    """YAML reads an unquoted `off` as false (`--set solver.sequence=off`, `sequence: off`):
    accepted, and it means off; `on` (true) is not a value."""
    scene = contact.load_scene(
        "configs/signorini_square.yaml", ["mesh.cells=[64,64]", "solver.sequence=off"]
    )
    r = _solve(scene, method="min")
    assert r.converged and r.sequence == [] and r.sequence_note == ""
    with pytest.raises(contact.ConfigError, match="solver.sequence: must be auto, off"):
        contact.load_scene("configs/signorini_square.yaml", ["solver.sequence=on"])
