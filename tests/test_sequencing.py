"""Grid sequencing of a single solve and the reduced SPD Newton system (issue 11).

Sequencing changes only the initial guess and the linear solver only how each Newton step
is solved: the answer must be the cold direct solve's to solver tolerance, and the
counts the result reports must be those of the levels actually solved."""

import contact
from contact.drivers.sequencing import COARSEST_DOFS
from contact.setup.build import build_problem
from contact.setup.levels import transfer

import numpy as np
import pytest
from conftest import make_square_msh
from test_parallel_invariance import run_script
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


def _square_file_scene(tmp_path, degree=1):
    """Signorini on a user's gmsh .msh of the unit square (contact on the bottom)."""
    msh = make_square_msh(tmp_path / "square.msh", size=0.04)
    return contact.load_scene(
        {
            "name": "gmsh_square",
            "mesh": {"type": "gmsh", "file": str(msh), "degree": degree},
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


def test_mesh_file_scene_starts_cold_and_says_so(tmp_path):
    """A user's .msh has no coarser mesh: a cold start, and the result's note says why."""
    scene = _square_file_scene(tmp_path)
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


def test_frictional_single_solve_sequences_and_equals_the_cold_solve():
    """A frictional solve without history (the first load step) sequences like a frictionless
    one (issue 29; before, frictional scenes always started cold)."""
    scene = contact.load_scene("configs/friction_block_2d.yaml", ["load=none"])
    r = contact.solve(scene, verbose=False, sequence=2)
    cold = contact.solve(scene, verbose=False, sequence="off")
    assert len(r.sequence) == 2 and not cold.sequence and r.converged and cold.converged
    u = cold.u_h.x.array
    assert np.max(np.abs(r.u_h.x.array - u)) <= 1e-8 * np.max(np.abs(u))


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


@pytest.mark.parametrize("method", ["fb", "min"])
def test_cold_fine_mesh_converges_at_the_roundoff_floor(method):
    """signorini_square at 256² cells, started cold: every method ran to max_it (issue 26's
    stability study, level 7).  The default atol · F (F the largest nodal force, ~h²) was
    below the round-off floor ε ‖K‖ ‖x‖ of ‖Φ‖; the stopping test now never asks for less
    than that floor.  The contact force agrees with the sequenced solve's (which starts
    from a close guess) to 1e-10."""
    scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[256,256]"])
    cold = contact.solve(scene, method=method, sequence="off")
    warm = contact.solve(scene, method=method)
    assert cold.converged and warm.converged, (cold.reason, warm.reason)
    assert abs(cold.contact_force - warm.contact_force) <= 1e-10 * abs(warm.contact_force)


@pytest.mark.parametrize(
    "name,h_contact,coarse", [("two_body_hertz_3d", 0.01, 1), ("two_body_hertz_2d", 0.025, 1)]
)
def test_two_bodies_sequence_and_equal_the_cold_solve(name, h_contact, coarse):
    """The gmsh-built two-body scenes solve coarser meshes (sizes h·2^k, h_contact·2^k) first,
    the mortar coupling built anew on each: the cold solve's answer to 1e-8, in fewer
    linear solves on the final mesh (measured: 3D 1+2 against 10+1 at 14k DoFs, 2D 1+2
    against 12+2 at 51k DoFs; the cold start moves the active set across the contact zone)."""
    overrides = ["adapt=null", f"mesh.h_contact={h_contact}"]
    scene = contact.load_scene(f"configs/{name}.yaml", overrides)
    cold = _solve(scene, method="fb", sequence="off")
    seq = _solve(scene, method="fb")
    assert cold.converged and seq.converged and seq.sequence_note == ""
    assert len(seq.sequence) >= coarse and all(lv.converged for lv in seq.sequence)
    assert seq.sequence[-1].dofs < seq.dofs
    assert seq.linear_solves < cold.linear_solves
    assert np.max(np.abs(seq.u_h.x.array - cold.u_h.x.array)) <= 1e-8


@pytest.mark.parametrize(
    "name,sizes", [("two_body_hertz_3d", (0.04, 0.01)), ("two_body_hertz_2d", (0.2, 0.05))]
)
def test_point_transfer_keeps_each_body(name, sizes):
    """A field linear on each body, different on the two, is carried from a coarse gmsh mesh
    to a finer one exactly: each body's points are located in its own coarse cells.  The
    bodies touch at the contact point (a vertex of each): located among all coarse cells, a
    point there may take the other body's value (measured: 11 nodes in 3D, 1 in 2D)."""
    from contact.drivers.sequencing import point_transfer

    from dolfinx import fem

    coarse, fine = (
        contact.load_scene(f"configs/{name}.yaml", ["adapt=null", f"mesh.h_contact={h}"])
        for h in sizes
    )
    d = coarse.mesh.geometry.dim
    slope = {1: np.arange(1.0, d * d + 1).reshape(d, d) / 10, 2: -np.eye(d)}
    shift = {1: np.ones(d), 2: -2 * np.ones(d)}

    def bodywise_linear(scene):
        V = fem.functionspace(scene.mesh, ("Lagrange", 1, (d,)))
        X = V.tabulate_dof_coordinates()[:, :d]
        body = np.zeros(len(X), dtype=int)
        body[V.dofmap.list[scene.bodies.indices]] = scene.bodies.values[:, None]
        u = fem.Function(V)
        u.x.array[:] = np.array([shift[b] + slope[b] @ x for b, x in zip(body, X)]).ravel()
        return u

    u_coarse, exact = bodywise_linear(coarse), bodywise_linear(fine)
    carried = transfer(u_coarse, coarse, fine, exact.function_space)
    assert np.max(np.abs(carried.x.array - exact.x.array)) <= 1e-12
    blind = point_transfer(u_coarse, exact.function_space)  # without the bodies' cell tags
    assert np.max(np.abs(blind.x.array - exact.x.array)) > 1.0


def test_refined_two_body_scene_sequences_through_its_ancestors():
    """Two bodies refined by contact.refine: the coarse levels are the ancestors (exact
    nested prolongation, each level's mortar coupling built anew), and the answer is the
    cold solve's (before issue 29 every scene of several bodies started cold)."""
    scene = contact.load_scene(
        "configs/two_body_hertz_2d.yaml",
        ["adapt=null", "mesh.h_contact=0.1", "output.verbose=false"],
    )
    for _ in range(2):
        r = contact.solve(scene, method="fb", verbose=False, sequence="off")
        scene, _ = contact.refine(scene, contact.mark(contact.estimate(scene, r).eta_T, "uniform"))
    cold = _solve(scene, method="fb", sequence="off")
    seq = _solve(scene, method="fb", sequence=1)
    assert cold.converged and seq.converged and seq.sequence_note == ""
    assert len(seq.sequence) == 1 and seq.sequence[0].dofs * 4 <= seq.dofs
    assert np.max(np.abs(seq.u_h.x.array - cold.u_h.x.array)) <= 1e-8


def _same_answer(r, cold, rtol=1e-10):
    """``r`` is the cold solve's answer to ``rtol`` relative to the largest displacement."""
    u = cold.u_h.x.array
    return np.max(np.abs(r.u_h.x.array - u)) <= rtol * np.max(np.abs(u))


def test_p2_gmsh_scene_starts_from_p1_on_its_mesh():
    """P2 two bodies on a gmsh mesh: the last coarse level is P1 on the same mesh (its
    solution interpolated exactly into P2), after P1's coarser gmsh level; the answer is the
    cold P2 solve's to 1e-10, in fewer Newton steps (measured at this size, min: 3 against 7;
    fb at h_contact 0.05, 19k DoFs: 1 + 2 against 10 + 3 linear solves)."""
    scene = contact.load_scene(
        "configs/two_body_hertz_2d.yaml",
        ["adapt=null", "mesh.h=2.0", "mesh.h_contact=0.1", "mesh.zone=1.0", "mesh.degree=2"],
    )
    cold = _solve(scene, method="min", sequence="off")
    p1 = _solve(scene, method="min", sequence=1)
    two = _solve(scene, method="min", sequence=2)
    assert cold.converged and p1.converged and two.converged
    assert [lv.dofs for lv in p1.sequence] == [two.sequence[-1].dofs]
    assert 3 * p1.sequence[0].dofs < p1.dofs  # P1 has ~1/4 of P2's DoFs in 2D
    assert len(two.sequence) == 2 and two.sequence[0].dofs < two.sequence[1].dofs
    assert p1.sequence_note == two.sequence_note == ""
    assert p1.iterations < cold.iterations and two.iterations < cold.iterations
    assert _same_answer(p1, cold) and _same_answer(two, cold)


def test_p2_floating_patch_auto_starts_from_p1():
    """The P2 contact patch (the upper block held by contact alone): ``auto`` solves P1 on
    the same mesh first; P1's solution is P2's there, so ‖Φ‖ starts at round-off and the P2
    solve stops at once (no Newton step), with the cold answer.  The floating body's
    stopping test had no round-off floor: from this guess it ran to max_it, and ``auto``
    kept the cold start on floating scenes."""
    scene = contact.load_scene(
        "configs/two_body_patch_2d.yaml", ["mesh.degree=2", "output.verbose=false"]
    )
    cold = _solve(scene, method="fb", sequence="off")
    r = _solve(scene, method="fb")
    assert r.converged and cold.converged and r.dofs >= 4_000 and r.sequence_note == ""
    assert [lv.dofs for lv in r.sequence] == [1_156] and r.iterations == 0
    assert _same_answer(r, cold)


def test_p2_on_curved_cells_starts_cold_and_says_so():
    """Curved cells (``mesh.geometry_degree: 2``) carry isoparametric P2 alone: no P1 level,
    a cold start with the note."""
    scene = contact.load_scene(
        "configs/two_body_hertz_2d.yaml",
        ["adapt=null", "mesh.h=2.0", "mesh.h_contact=0.1", "mesh.zone=1.0", "mesh.degree=2"]
        + ["mesh.geometry_degree=2", "output.verbose=false"],
    )
    r = _solve(scene, method="fb", sequence=2)
    assert r.converged and r.sequence == [] and "curved cells" in r.sequence_note


def test_p2_mesh_file_scene_starts_from_p1_on_its_mesh(tmp_path):
    """A user's .msh at P2: no coarser mesh, but P1 on the same mesh (which starts cold,
    as the note says) is the P2 solve's guess; the cold P2 answer to 1e-10."""
    scene = _square_file_scene(tmp_path, degree=2)
    cold = _solve(scene, method="min", sequence="off")
    r = _solve(scene, method="min", sequence=2)
    assert r.converged and cold.converged and len(r.sequence) == 1
    assert "mesh file" in r.sequence_note and "P1 on the same mesh" in r.sequence_note
    assert r.iterations <= cold.iterations and _same_answer(r, cold)


def test_p2_obstacle_auto_starts_from_p1():
    """The scalar P2 obstacle (PETSc ex9, 64² cells, 16,641 DoFs): ``auto`` solves P1 on
    a coarser rectangle and on the same mesh first; the cold answer to 1e-10 in fewer Newton
    steps (measured 2 against 22)."""
    scene = contact.load_scene(
        "configs/peers/petsc_ex9.yaml", ["mesh.degree=2", "mesh.cells=[64,64]"]
    )
    cold = _solve(scene, sequence="off")
    r = _solve(scene)
    assert cold.converged and r.converged and r.sequence_note == ""
    assert [lv.dofs for lv in r.sequence][-1] == 65**2  # P1 on the 64² mesh
    assert 2 * r.iterations < cold.iterations and _same_answer(r, cold)


def test_p2_frictional_load_step_restricts_its_history_through_p1():
    """A frictional P2 load path: a later step's history (the P2 previous displacement)
    reaches the P1 levels (interpolated into P1 on the same mesh) and the sequenced path
    ends where the cold one does."""
    args = ["mesh.degree=2", "mesh.cells=[40,10]", "load.steps=3", "output.verbose=false"]
    ends = {}
    for seq in ("off", 1):
        scene = contact.load_scene(
            "configs/friction_block_2d.yaml", [*args, f"solver.sequence={seq}"]
        )
        steps = contact.run_load_path(scene, verbose=False, keep_all=True).steps
        assert all(s.result.converged for s in steps) and len(steps) >= 2
        if seq == 1:
            assert all(len(s.result.sequence) == 1 for s in steps)
        ends[seq] = steps[-1].result
    assert _same_answer(ends[1], ends["off"], 1e-8)


P2_FROM_P1 = """
import json, sys
from mpi4py import MPI
import contact
sets = ["adapt=null", "mesh.h=2.0", "mesh.h_contact=0.1", "mesh.zone=1.0", "mesh.degree=2",
        "output.verbose=false"]
scene = contact.load_scene(sys.argv[1], sets)
r = contact.solve(scene, verbose=False, method="fb", sequence=2)
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps({"levels": [lv.dofs for lv in r.sequence], "converged": bool(r.converged),
                      "force": r.contact_force, "dofs": r.dofs}))
"""


@pytest.mark.mpi
def test_p2_from_p1_same_answer_on_1_and_2_ranks(tmp_path):
    """P2 two bodies sequenced through P1 (a coarser gmsh mesh, then P1 on the same mesh):
    the same levels and force to 1e-8 on 1 and 2 ranks."""
    runs = run_script(tmp_path, P2_FROM_P1, "two_body_hertz_2d.yaml", (1, 2))
    assert runs[1]["converged"] and runs[2]["converged"] and len(runs[1]["levels"]) == 2
    assert runs[2]["levels"] == runs[1]["levels"] and runs[2]["dofs"] == runs[1]["dofs"]
    assert runs[2]["force"] == pytest.approx(runs[1]["force"], rel=1e-8)
