"""Krylov + GAMG gives the same discrete solution as the direct solver (issue #2)."""

import contact
from contact.setup.scalar import scalar_problem

import numpy as np
import pytest
from ties import tie_margin

GAMG = {"ksp_type": "bcgs", "pc_type": "gamg", "ksp_rtol": 1e-10}


@pytest.mark.parametrize(
    "scene_name", ["signorini_square", "signorini_free_boundary", "obstacle_membrane"]
)
@pytest.mark.parametrize("method", ["fb", "min"])
def test_gamg_matches_direct(scene_name, method):
    scene = contact.load_scene(f"configs/{scene_name}.yaml", ["mesh.cells=[32,32]"])
    problem = scalar_problem(scene)
    direct = contact.solve(scene, method=method, problem=problem, verbose=False)
    u_direct = direct.u_h.x.array.copy()
    krylov = contact.solve(scene, method=method, problem=problem, verbose=False, petsc_options=GAMG)
    assert direct.converged and krylov.converged, (direct.reason, krylov.reason)
    assert np.max(np.abs(krylov.u_h.x.array - u_direct)) <= 1e-8
    assert tie_margin(direct) >= 1e-6  # no node near a tie: 1e-8 cannot move the count
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
        r = contact.solve(
            scene,
            method="min",
            problem=problem,
            verbose=False,
            linear="gamg",
            petsc_options={"mg_levels_ksp_max_it": sweeps},
        )
        assert r.converged, r.reason
        its[sweeps] = r.krylov_iterations
    assert its[6] < its[1], its


def test_gamg_coarsens_by_mis2_only_in_parallel_2d():
    """2D on several ranks: the first aggressive coarsening by MIS-2, not the squared graph
    (whose product scales badly across ranks); serial and 3D keep the squared graph."""
    from contact.solvers.options import default_options

    key = "pc_gamg_aggressive_square_graph"
    assert default_options("gamg", 2, ranks=2)[key] is False
    assert key not in default_options("gamg", 2, ranks=1) and key not in default_options(
        "gamg", 3, ranks=2
    )


MIS2_RUN = """
import json
import numpy as np
from mpi4py import MPI
import contact
from contact.setup.scalar import scalar_problem
from contact.solvers.linear import default_linear_solver
from dolfinx import fem
import ufl
import sys
sys.path.insert(0, "tests")   # run from the repository root
from ties import tie_margin
scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[96,96]"])
problem = scalar_problem(scene)
r = contact.solve(scene, method="min", problem=problem, verbose=False, linear="gamg")
norm2 = scene.mesh.comm.allreduce(fem.assemble_scalar(fem.form(r.u_h**2 * ufl.dx)))
margin = tie_margin(r)
if scene.mesh.comm.rank == 0:
    square = default_linear_solver(problem, "gamg").get("pc_gamg_aggressive_square_graph")
    print(json.dumps([r.converged, square, norm2, r.n_active, margin]))
"""


def test_gamg_in_parallel_gives_the_serial_answer(tmp_path):
    """The 2-rank default (MIS-2 coarsening) solves signorini_square 96² to the serial answer:
    ∫ u_h² and the active set agree (CG to 1e-10 relative, Newton to its tolerance)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    import ufl
    from dolfinx import fem

    script = tmp_path / "mis2.py"
    script.write_text(MIS2_RUN)
    proc = subprocess.run(
        [str(Path(sys.executable).parent / "mpirun"), "-n", "2", sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=Path(__file__).resolve().parents[1],
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stderr
    converged, square_graph, norm2, n_active, margin = json.loads(
        proc.stdout.strip().splitlines()[-1]
    )
    assert converged and square_graph is False and margin >= 1e-6  # no node near a tie
    scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[96,96]"])
    r = contact.solve(scene, method="min", verbose=False, linear="gamg")
    serial = fem.assemble_scalar(fem.form(r.u_h**2 * ufl.dx))
    assert r.converged and n_active == r.n_active
    assert abs(norm2 - serial) <= 1e-8 * serial


@pytest.mark.parametrize("method", ["min", "fb"])
def test_active_set_forcing_takes_fewer_krylov_iterations_from_a_cold_start(method):
    """The cold start (no grid sequencing) of the step-41 obstacle problem on CG + GAMG:
    the forcing rule ``active_set`` (loose Krylov solves while the active set moves,
    warm-started) reaches the same solution to the same Newton tolerance as
    Eisenstat–Walker's rule alone with fewer Krylov iterations (at 64²: min 80 against 211,
    fb 152 against 259; fb 202 against 257 under the perturbed load) and at most one more
    Newton step."""
    runs = {}
    for forcing in ("eisenstat_walker", "active_set"):
        scene = contact.load_scene(
            "configs/peers/dealii_step41.yaml",
            ["mesh.cells=[64,64]", "solver.sequence=off", "solver.linear=gamg"],
        )
        runs[forcing] = contact.solve(scene, method=method, forcing=forcing, verbose=False)
    old, new = runs["eisenstat_walker"], runs["active_set"]
    assert old.converged and new.converged, (old.reason, new.reason)
    # the same start, the same final tolerance: ‖Φ‖ ≤ rtol ‖Φ_0‖ (rtol 1e-12) for both
    for r in (old, new):
        assert r.residual <= 1e-12 * r.history[0]["residual"], (r.residual, r.history[0])
    # min moves its active set in every step of the cold start; fb's steps raise ‖Φ‖ at times
    # (its rule falls back to Eisenstat–Walker's), and its gain is smaller
    bound = 0.5 if method == "min" else 0.9
    assert new.krylov_iterations <= bound * old.krylov_iterations, (
        new.krylov_iterations,
        old.krylov_iterations,
    )
    assert new.iterations <= old.iterations + 1
    u_old, u_new = old.u_h.x.array, new.u_h.x.array
    assert np.max(np.abs(u_new - u_old)) <= 1e-10 * np.max(np.abs(u_old))
    assert new.n_active == old.n_active


def test_gamg_is_set_up_afresh_when_the_active_set_moves():
    """The lagging rule ``active_set`` (the default) keeps an earlier GAMG hierarchy only
    while the Newton system's fixed rows (the active set) are those it was built with: on
    the cold step-41 path, whose every step moves the active set, each Newton solve after
    a change of the fixed rows sets GAMG up.  The old rule (``reduced_lag_rule: rate``,
    the convergence rate alone) lags across such changes; both reach the same solution."""
    runs = {}
    for rule in ("active_set", "rate"):
        scene = contact.load_scene(
            "configs/peers/dealii_step41.yaml",
            ["mesh.cells=[64,64]", "solver.sequence=off", "solver.linear=gamg"],
        )
        runs[rule] = contact.solve(
            scene, method="min", petsc_options={"reduced_lag_rule": rule}, verbose=False
        )
    for rule, r in runs.items():
        assert r.converged, (rule, r.reason)
    log = runs["active_set"].krylov_log
    moved = [b for a, b in zip(log, log[1:], strict=False) if a["fixed_rows"] != b["fixed_rows"]]
    assert moved and all(entry["setups"] >= 1 for entry in moved)
    old = runs["rate"].krylov_log
    assert any(
        b["setups"] == 0 and a["fixed_rows"] != b["fixed_rows"]
        for a, b in zip(old, old[1:], strict=False)
    )
    u_new, u_old = runs["active_set"].u_h.x.array, runs["rate"].u_h.x.array
    assert np.max(np.abs(u_new - u_old)) <= 1e-10 * np.max(np.abs(u_old))
    scene = contact.load_scene("configs/peers/dealii_step41.yaml", ["mesh.cells=[64,64]"])
    with pytest.raises(contact.ConfigError, match="^solver.petsc_options.reduced_lag_rule: must"):
        contact.solve(scene, method="min", linear="gamg", petsc_options={"reduced_lag_rule": "x"})


@pytest.mark.parametrize("method", ["fb", "min"])
def test_the_reduced_operator_shares_the_preconditioner_matrix(method):
    """On the CG + GAMG path the reduced operator A and the matrix P that GAMG is built from
    are one matrix, except while a lagged GAMG (built from an earlier A) needs P's values
    and the new A at once: one copy of K's pattern fewer during the solve (PETSc's count of
    live matrices), and the same iterates bit for bit as with two copies
    (``reduced_share_matrix: false``, the path before) — lagged steps included."""
    from contact.base.lifetime import petsc_objects
    from contact.setup.run import build_problem
    from contact.solvers.options import SolverOptions
    from contact.solvers.snes import SemismoothNewton

    from dolfinx import fem
    from petsc4py import PETSc

    PETSc.Log.begin()
    scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[64,64]"])
    p = build_problem(scene)
    runs, matrices, shared = {}, {}, {}
    try:
        for share in (False, True):
            options = SolverOptions.parse(
                {
                    "method": method,
                    "linear": "gamg",
                    "petsc_options": {"reduced_share_matrix": share},
                }
            )
            with SemismoothNewton(p, options) as solver:
                runs[share] = solver.solve(fem.Function(p.V))
                matrices[share] = petsc_objects().get("Matrix", 0)
                shared[share] = solver.system.A is solver.system.P
    finally:
        p.destroy()
    old, new = runs[False], runs[True]
    assert old.converged and new.converged, (old.reason, new.reason)
    assert any(e["setups"] == 0 for e in new.krylov_log)  # a lagged solve was taken
    assert [e["iterations"] for e in new.krylov_log] == [e["iterations"] for e in old.krylov_log]
    assert [h["residual"] for h in new.history] == [h["residual"] for h in old.history]
    assert np.array_equal(new.u_h.x.array, old.u_h.x.array)
    assert shared == {False: False, True: True}
    assert matrices[True] == matrices[False] - 1
