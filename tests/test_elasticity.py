"""Elastic contact against a rigid plane (issue #4): every method agrees with vinewtonrsls,
1 and 2 MPI ranks agree, the contact force equals the reaction, GAMG with the rigid-body
near-nullspace matches the direct solver, and bad elasticity input is a one-line error."""

import json
import os
import subprocess
import sys
from pathlib import Path

import contact
from contact.post.hertz import hertz
from contact.post.reference import compare
from contact.post.resultants import contact_resultants
from contact.setup.build import build_problem
from contact.setup.posed import posed_of

import numpy as np
import pytest
from ties import tie_margin

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
SMALL = ["mesh.h=0.2", "mesh.h_contact=0.02", "mesh.zone=0.2", "output.verbose=false"]


@pytest.fixture(scope="module")
def scene():
    return contact.load_scene(ROOT / "configs" / "hertz_2d.yaml", SMALL)


@pytest.fixture(scope="module")
def reference(scene):
    problem = build_problem(scene)
    r = contact.solve(scene, method="vinewtonrsls", problem=problem)
    assert r.converged
    return problem, r.u_h.x.array.copy(), r.lmbda_h.x.array.copy(), r.n_active


@pytest.mark.parametrize("method", ["fb", "min", "blend"])
def test_methods_agree_with_vinewtonrsls(scene, reference, method):
    problem, u_ref, lam_ref, n_ref = reference
    r = contact.solve(scene, method=method, problem=problem)
    # a bound, not a path: the cold solves take 8–11 steps here (RESULTS §3 (f)); 15 fails
    # only if superlinear convergence is lost
    assert r.converged and r.iterations <= 15
    assert np.max(np.abs(r.u_h.x.array - u_ref)) <= 1e-8
    assert np.max(np.abs(r.lmbda_h.x.array - lam_ref)) <= 1e-8 * np.max(np.abs(lam_ref))
    assert tie_margin(r) >= 1e-6  # no node near a tie: the count cannot move with rounding
    assert r.n_active == n_ref > 0


def test_force_balance_and_hertz_sanity(scene):
    r = contact.solve(scene, method="min")
    res = contact_resultants(posed_of(scene), r)
    assert res["force_balance_error"] < 1e-8
    assert res["contact_force"] == r.contact_force > 0 and res["symmetric_copies"] == 2
    # Hertz relations hold for the values reported, and a coarse mesh is already close
    res.update(compare(posed_of(scene), r).values)
    a_H, p0_H = hertz(1.0, 1.0, 0.3, res["contact_force"], 2)
    assert np.isclose(a_H, res["hertz_a"]) and np.isclose(p0_H, res["hertz_p0"])
    assert abs(res["a_error"]) < 0.15 and abs(res["p0_error"]) < 0.15
    assert np.all(r.lmbda_h.x.array <= 1e-12), "compressive pressure only"


def test_gamg_with_rigid_body_modes_matches_direct(scene, reference):
    problem, u_ref, _, _ = reference
    assert problem.near_nullspace is not None
    r = contact.solve(
        scene,
        method="fb",
        problem=problem,
        petsc_options={"ksp_type": "bcgs", "pc_type": "gamg", "ksp_rtol": 1e-12},
    )
    assert r.converged
    assert np.max(np.abs(r.u_h.x.array - u_ref)) <= 1e-8


def test_serial_and_two_ranks_agree(tmp_path):
    script = ROOT / "tests" / "solve_methods.py"
    scene = str(ROOT / "configs" / "hertz_2d.yaml")
    out1, out2 = tmp_path / "s.npz", tmp_path / "p.npz"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    args = [scene] + [f"--set={o}" for o in SMALL]
    subprocess.run(
        [sys.executable, str(script), str(out1), *args], check=True, timeout=300, env=env
    )
    subprocess.run(
        [str(MPIRUN), "-n", "2", sys.executable, str(script), str(out2), *args],
        check=True,
        timeout=300,
        env=env,
    )
    s, p = dict(np.load(out1)), dict(np.load(out2))
    for method in ("fb", "min", "blend", "vinewtonrsls"):
        key = f"hertz_2d/{method}"
        assert np.allclose(s[key + "/X"], p[key + "/X"], atol=1e-12)
        assert np.max(np.abs(s[key + "/u"] - p[key + "/u"])) <= 1e-8
        assert np.max(np.abs(s[key + "/lambda"] - p[key + "/lambda"])) <= 1e-8 * np.max(
            np.abs(s[key + "/lambda"])
        )
        # no node near a tie (tests/ties.py)
        assert min(s[key + "/info"][5], p[key + "/info"][5]) >= 1e-6
        assert s[key + "/info"][3] == p[key + "/info"][3]


@pytest.mark.parametrize(
    "override,message",
    [
        ("model.E=-1", "model.E: must be > 0"),
        ("model.nu=0.5", "model.nu: must lie in (-1, 0.5)"),
        ("obstacle.normal=[0,0]", "obstacle.normal: must not be the zero vector"),
        ("data.g=0", "data.g: not used by model type elasticity"),
    ],
)
def test_bad_elasticity_input(override, message):
    with pytest.raises(
        contact.ConfigError,
        match=message.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)"),
    ):
        scene = contact.load_scene(ROOT / "configs" / "hertz_2d.yaml", SMALL + [override])
        build_problem(scene)


@pytest.fixture(scope="module")
def indentation():
    scene = contact.load_scene(
        ROOT / "configs" / "indentation_2d.yaml", ["mesh.cells=[80,40]", "output.verbose=false"]
    )
    problem = build_problem(scene)
    ref = contact.solve(scene, method="vinewtonrsls", problem=problem)
    assert ref.converged
    return scene, problem, ref.u_h.x.array.copy(), ref.n_active


@pytest.mark.parametrize("method", ["fb", "min", "blend"])
def test_circular_obstacle_agrees_with_vinewtonrsls(indentation, method):
    """A rigid circle: per-node rotated unknowns, same discrete problem for every solver."""
    scene, problem, u_ref, n_ref = indentation
    assert problem.basis is not None
    r = contact.solve(scene, method=method, problem=problem)
    assert r.converged
    assert np.max(np.abs(r.u_h.x.array - u_ref)) <= 1e-8
    assert tie_margin(r) >= 1e-6  # no node near a tie: the count cannot move with rounding
    assert r.n_active == n_ref > 0


def test_circular_obstacle_is_respected_and_balanced(indentation):
    scene, problem, _, _ = indentation
    r = contact.solve(scene, method="min", problem=problem)
    res = {**contact_resultants(posed_of(scene), r), **compare(posed_of(scene), r).values}
    assert res["min_gap"] >= -1e-10, "no node penetrates the circle"
    assert res["force_balance_error"] < 1e-8
    assert abs(res["a_error"]) < 0.05 and abs(res["p0_error"]) < 0.05
    # physical displacement of a node on the circle: |x + u - c| = R_o at active nodes
    X = r.u_h.function_space.tabulate_dof_coordinates()[:, :2]
    u = r.u_h.x.array.reshape(-1, 2)
    act = r.active.x.array > 0.5
    dist = np.linalg.norm(X[act] + u[act] - np.array([0.0, 5.0]), axis=1)
    assert np.all(np.abs(dist - 5.0) < 1e-4)  # linearised contact: second-order gap error


def test_spherical_obstacle_3d_agrees_with_vinewtonrsls():
    scene = contact.load_scene(
        {
            "name": "sphere_indenter",
            "constants": {"R": 5.0, "delta": 0.01},
            "mesh": {"type": "box", "corners": [[-1, -1, -1], [1, 1, 0]], "cells": [12, 12, 6]},
            "boundaries": {
                "top": {"role": "contact", "where": "z > -1e-10"},
                "bottom": {"role": "dirichlet", "where": "z < -1 + 1e-10"},
            },
            "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
            "obstacle": {"type": "sphere", "center": [0.0, 0.0, 5.0], "radius": 5.0},
            "data": {"u_D": ["0", "0", "delta"]},
            "output": {"verbose": False},
        }
    )
    problem = build_problem(scene)
    ref = contact.solve(scene, method="vinewtonrsls", problem=problem).u_h.x.array.copy()
    for method in ("fb", "min"):
        r = contact.solve(scene, method=method, problem=problem)
        assert r.converged and r.n_active > 0
        assert np.max(np.abs(r.u_h.x.array - ref)) <= 1e-8
        res = contact_resultants(posed_of(scene), r)
        assert res["force_balance_error"] < 1e-8 and res["min_gap"] >= -1e-10


def test_tilted_plane_agrees_with_vinewtonrsls():
    """A plane whose normal is no coordinate direction uses the rotated unknowns too."""
    scene = contact.load_scene(
        {
            "name": "tilted",
            "constants": {"delta": 0.02},
            "mesh": {"type": "rectangle", "corners": [[-1, -1], [1, 0]], "cells": [40, 20]},
            "boundaries": {
                "top": {"role": "contact", "where": "y > -1e-10"},
                "bottom": {"role": "dirichlet", "where": "y < -1 + 1e-10"},
            },
            "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
            "obstacle": {"type": "plane", "point": [-1.0, 0.0], "normal": [0.1, -1.0]},
            "data": {"u_D": ["0", "delta"]},
            "output": {"verbose": False},
        }
    )
    problem = build_problem(scene)
    assert problem.basis is not None
    ref = contact.solve(scene, method="vinewtonrsls", problem=problem).u_h.x.array.copy()
    for method in ("fb", "min"):
        r = contact.solve(scene, method=method, problem=problem)
        assert r.converged and r.n_active > 0
        assert np.max(np.abs(r.u_h.x.array - ref)) <= 1e-8
        # no node crosses the plane: (x + u − p)·ν ≥ 0 with ν the unit normal
        X = r.u_h.function_space.tabulate_dof_coordinates()[:, :2]
        nu = np.array([0.1, -1.0]) / np.linalg.norm([0.1, -1.0])
        top = X[:, 1] > -1e-10
        dist = (X[top] + r.u_h.x.array.reshape(-1, 2)[top] - np.array([-1.0, 0.0])) @ nu
        assert dist.min() >= -1e-10


def test_adaptive_dof_budget_counts_vector_dofs(scene):
    """max_dofs bounds the displacement DoFs (gdim per node), not the mesh nodes."""
    levels = contact.adapt(scene, method="min", max_levels=6, max_dofs=4000, verbose=False).levels
    assert all(lv.result.dofs <= 4000 for lv in levels)
    assert levels[-1].result.dofs > 2000, "the budget, not the level count, stopped the loop"


#: the modules a scene loads only when its model needs them (README: a scalar scene never
#: imports the elasticity code, a rectangle never gmsh, a frictionless scene never friction)
LAZY = (
    "contact.models.elasticity",
    "contact.models.friction",
    "contact.solvers.friction",
    "gmsh",
    "contact.models.hyperelastic",
)


def test_a_run_imports_only_its_own_model(tmp_path):
    """``contact run`` of a coarse scalar scene leaves every module of LAZY unloaded; one of
    a frictionless elastic block then loads elasticity but neither friction module."""
    code = (
        "import sys; from contact.app.cli import main; lazy = " + repr(LAZY) + "\n"
        "for scene, cells, out in [('signorini_square', '[8, 8]', 's'),\n                      "
        "    ('block_on_plane', '[8, 2]', 'b')]:\n    rc = main(['run', "
        "f'configs/{scene}.yaml', '--set', f'mesh.cells={cells}',\n               '--set', "
        "'adapt.max_levels=2', '--set', 'output.verbose=false',\n"
        "               '-o', " + repr(str(tmp_path) + "/") + " + out])\n"
        "    print(scene, rc, *[m for m in lazy if m in sys.modules])\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    lines = [
        line
        for line in proc.stdout.splitlines()
        if line.split()[0] in ("signorini_square", "block_on_plane")
    ]
    assert lines == ["signorini_square 0", "block_on_plane 0 contact.models.elasticity"]


# ------------------------------------------------------------------------- issue 26
def test_tolerances_follow_the_scale_of_the_data(tmp_path):
    """E = 1e-12 "converged" after 0 iterations with no contact and a force balance error of
    2e287, exit 0: an absolute atol of 1e-12 was above every force of the scene.  solver.atol
    is relative to the scene's force scale ‖Φ(x_D)‖ (contact.solvers.snes.force_scale), so
    scaling E scales the forces and nothing else: the same active set, forces × E."""
    from clirun import contact as cli

    summaries = {}
    for E in (1.0, 1e-12, 1e12):
        out = tmp_path / f"E{E:g}"
        sets = [f"model.E={E}", "adapt=none", "output.png=false"]
        proc = cli(
            tmp_path,
            "run",
            str(ROOT / "configs" / "block_on_plane.yaml"),
            "-o",
            str(out),
            "-q",
            *(arg for s in sets for arg in ("--set", s)),
        )
        assert proc.returncode == 0, proc.stderr
        summaries[E] = json.loads((out / "summary.json").read_text())
    unit = summaries[1.0]
    assert unit["newton_iterations"] >= 1 and unit["active_nodes"] > 0
    for E in (1e-12, 1e12):
        s = summaries[E]
        assert s["newton_iterations"] >= 1 and s["active_nodes"] == unit["active_nodes"]
        assert s["contact_force"] == pytest.approx(E * unit["contact_force"], rel=1e-9)
        assert s["force_balance_error"] < 1e-9


def test_first_contact_point_breaks_ties_by_coordinates():
    """Several nodes at the smallest initial gap (a flat face on a plane, a patch test): the
    origin of contact.csv's r, θ is the first of them in coordinate order, whatever the order
    of the rows — which is the partition's, so the same origin on any number of ranks (issue
    26: the first in row order was taken before).  Gaps within round-off are a tie."""
    import itertools

    from contact.models.problem import first_contact_point, first_contact_row

    from mpi4py import MPI

    X = np.array([[0.5, 0.2, 0.0], [0.1, 0.9, 0.0], [0.1, 0.3, 0.0], [0.0, 0.0, 1.0]])
    gap = np.array([0.0, 1e-13, 0.0, 0.5])
    for order in map(list, itertools.permutations(range(4))):
        assert first_contact_point(MPI.COMM_SELF, X[order], gap[order]).tolist() == [0.1, 0.3, 0.0]
        assert first_contact_row(MPI.COMM_SELF, X[order], gap[order], np.arange(4)[order]) == 2
    assert first_contact_point(MPI.COMM_SELF, X, np.array([0.3, 0.2, 0.1, 0.0])).tolist() == [
        0.0,
        0.0,
        1.0,
    ]
