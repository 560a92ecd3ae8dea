"""The solver's typed options (issue 28b): ``contact.solvers.options.SolverOptions`` is a frozen
pydantic model with exactly the solver's knobs, its defaults and its one-line messages those
of the scene's ``solver`` section, and it is what the solver receives (no dict)."""

from __future__ import annotations

import contact
from contact import ConfigError
from contact.solvers.options import SolverOptions
from contact.solvers.problem import newton_max_it, nodes_across

import numpy as np
import pydantic
import pytest
from clirun import ROOT
from mpi4py import MPI

SCENE = str(ROOT / "configs" / "signorini_square.yaml")
KNOBS = {
    "method",
    "mu",
    "c",
    "kappa",
    "line_search",
    "polish",
    "rtol",
    "atol",
    "max_it",
    "linear",
    "inexact",
    "forcing",
    "petsc_options",
    "predictor",
    # the baselines' parameters (contact.solvers.baselines)
    "epsilon0",
    "r0",
    "gamma0",
    "nitsche_theta",
    "uzawa_rtol",
    "uzawa_max_it",
}


def test_exactly_the_solvers_knobs_with_the_scenes_defaults():
    """A scene with no ``solver`` section has SolverOptions' defaults (and the driver's keys)."""
    scene = contact.load_scene(
        {
            "name": "plain",
            "mesh": {"type": "rectangle", "corners": [[0, 0], [1, 1]], "cells": [2, 2]},
            "boundaries": {"clamp": {"role": "dirichlet", "where": "x < 1e-10"}},
            "model": {"type": "obstacle", "bound": "lower"},
            "data": {"f": "-1", "psi": "-1"},
        }
    )
    assert set(SolverOptions.model_fields) == KNOBS
    section = scene.config.solver
    # the scene's section = the solver's knobs + the driver's (initial guess, sequencing, budget,
    # and the adaptive loop's stopping rule, which the driver hands the solver as an object)
    assert set(section.model_dump()) - KNOBS == {
        "u0",
        "sequence",
        "max_dofs",
        "stopping",
        "gamma_lin",
        "gamma_alg",
    }
    assert SolverOptions().model_dump() == {key: getattr(section, key) for key in KNOBS}
    assert section.knobs() == SolverOptions()


@pytest.mark.parametrize(
    "key, value",
    [
        ("mu", 1.5),
        ("mu", 0),
        ("method", "newton"),
        ("c", -1),
        ("c", "big"),
        ("kappa", 0),
        ("line_search", "cubic"),
        ("polish", "yes"),
        ("rtol", -1e-3),
        ("max_it", 0),
        ("max_it", 2.5),
        ("linear", "cholesky"),
        ("inexact", 1),
        ("petsc_options", {"ksp_type": [1]}),
        ("petsc_options", 3),
    ],
)
def test_the_same_one_line_message_as_the_scene(key, value):
    """A bad value gives the ConfigError line the scene's loader gives for it."""
    with pytest.raises(ConfigError) as scene_error:
        contact.load_scene(
            SCENE,
            [f"solver.{key}={value!r}" if isinstance(value, str) else f"solver.{key}={value}"],
        )
    with pytest.raises(ConfigError) as typed_error:
        SolverOptions.parse({key: value})
    assert str(typed_error.value) == str(scene_error.value)
    assert "\n" not in str(typed_error.value) and str(typed_error.value).startswith(f"solver.{key}")


def test_an_unknown_knob_is_named():
    with pytest.raises(
        ConfigError, match=r"^solver.max_iterations: unknown key \(expected one of method, "
    ):
        SolverOptions.parse({"max_iterations": 3})


def test_frozen():
    options = SolverOptions.parse({"method": "min", "rtol": 1e-8})
    with pytest.raises(pydantic.ValidationError, match="frozen"):
        options.rtol = 1.0
    assert options.model_copy(update={"rtol": 1e-6}).rtol == 1e-6 and options.rtol == 1e-8


def test_the_solver_receives_the_typed_options(monkeypatch):
    """contact.solve hands solve_problem one SolverOptions built from the section and the
    call's overrides; the result records them."""
    from contact.drivers import solve as driver

    seen = []
    real = driver.solve_problem

    def spy(problem, u0, opts, *args, **kwargs):
        seen.append(opts)
        return real(problem, u0, opts, *args, **kwargs)

    monkeypatch.setattr(driver, "solve_problem", spy)
    scene = contact.load_scene(SCENE, ["mesh.cells=[6,6]", "solver.sequence=off"])
    result = contact.solve(scene, method="min", rtol=1e-9, verbose=False)
    (options,) = seen
    assert isinstance(options, SolverOptions)
    kappa = scene.config.solver.kappa
    assert (options.method, options.rtol, options.kappa) == ("min", 1e-9, kappa)
    assert result.converged and result.options == options.model_dump()


def test_max_it_is_auto_or_a_positive_integer():
    """``max_it`` defaults to ``auto`` and takes a positive integer as given; another word is
    one line naming the key."""
    assert SolverOptions().max_it == "auto"
    assert SolverOptions.parse({"max_it": 7}).max_it == 7
    with pytest.raises(ConfigError, match=r"^solver.max_it: expected an integer, got"):
        SolverOptions.parse({"max_it": "many"})


def test_auto_step_limit_grows_with_the_nodes_across_the_constrained_set():
    """``auto`` is max(50, n), n the nodes across the constrained set: N points along a
    line are N across, an m × m grid m, a 1024 × 8 strip about 1024 (its long side); a number
    is kept; a point or an empty set is one node across."""
    comm = MPI.COMM_SELF
    line = np.column_stack([np.linspace(0.0, 1.0, 300), np.zeros(300)])
    g = np.linspace(-1.0, 1.0, 200)
    grid = np.array([[x, y] for x in g for y in g])
    strip = np.array([[x, y] for x in range(1024) for y in range(8)], dtype=float)
    assert nodes_across(line, 1, comm) == pytest.approx(300.0)
    assert nodes_across(grid, 2, comm) == pytest.approx(200.0)
    assert nodes_across(strip, 2, comm) == pytest.approx(1023.0 * (8192 / (1023 * 7)) ** 0.5)
    assert nodes_across(np.zeros((0, 2)), 1, comm) == 1.0
    assert nodes_across(np.zeros((5, 3)), 2, comm) == pytest.approx(5**0.5)
    assert newton_max_it("auto", 20.0) == 50 and newton_max_it("auto", 299.2) == 300
    assert newton_max_it(7, 1e6) == 7


def test_a_cold_start_longer_than_fifty_steps_converges_with_the_defaults():
    """deal.II's step-41 obstacle at 128² cells from u = 0 without grid sequencing:
    PETSc's vinewtonssls moves the active set a few nodes per step and needs more than 50
    steps (53), the fixed limit before; with the defaults (``auto``: 127, the interior
    nodes across Ω) it converges, with ``max_it: 50`` it stops at the limit, exit 1's
    reason.  min converges with the defaults too (21 steps, 64² → 128²: the O(1/h) path)."""
    sets = ["mesh.cells=[128,128]", "solver.sequence=off"]
    scene = contact.load_scene(str(ROOT / "configs" / "peers" / "dealii_step41.yaml"), sets)
    auto = contact.solve(scene, method="vinewtonssls", verbose=False)
    assert auto.converged, auto.reason
    assert auto.max_it == 127 and auto.iterations > 50
    fixed = contact.solve(scene, method="vinewtonssls", max_it=50, verbose=False)
    assert not fixed.converged and fixed.reason == "diverged_max_it" and fixed.iterations == 50
    assert fixed.max_it == 50
    newton = contact.solve(scene, method="min", verbose=False)
    assert newton.converged and newton.iterations < 50, newton.reason
    assert newton.max_it == 50  # the limit by the mesh is only computed past the floor


@pytest.mark.parametrize("method", ["min", "fb"])
def test_newton_raises_its_step_limit_at_the_floor(monkeypatch, method):
    """fb / min / blend start with the floor of ``auto`` and compute the limit by the mesh
    only once a solve reaches it (the node coordinates are not read for the usual short
    solve).  With the floor lowered to 10, the cold step-41 path at 128² (21 min steps)
    converges with ``auto``, its limit raised to the 127 nodes across; an explicit 10
    stops there."""
    from contact.solvers import problem as problem_module

    monkeypatch.setattr(problem_module, "MAX_IT_FLOOR", 10)
    sets = ["mesh.cells=[128,128]", "solver.sequence=off"]
    scene = contact.load_scene(str(ROOT / "configs" / "peers" / "dealii_step41.yaml"), sets)
    auto = contact.solve(scene, method=method, verbose=False)
    assert auto.converged and auto.iterations > 10 and auto.max_it == 127, auto.reason
    fixed = contact.solve(scene, method=method, max_it=10, verbose=False)
    assert not fixed.converged and fixed.reason == "diverged_max_it" and fixed.iterations == 10
