"""The typed scene config (issue 28b): a scene is validated once, when it is loaded, into a
frozen ``SceneConfig`` that every layer reads by attribute; a solve checks only its call's
overrides; friction's knobs are a typed ``FrictionOptions`` like the solver's."""

from __future__ import annotations

import contact
from contact import ConfigError
from contact.setup import config as config_module
from contact.setup.build import build_problem
from contact.setup.scene_config import (
    AdaptConfig,
    FrictionConfig,
    MeshConfig,
    SceneConfig,
    SolverConfig,
)
from contact.solvers.options import FrictionOptions

import pydantic
import pytest
from clirun import ROOT

SQUARE = ROOT / "configs" / "signorini_square.yaml"
FRICTION = ROOT / "configs" / "friction_block_2d.yaml"


def test_the_config_is_typed_and_frozen_at_every_level():
    config = contact.load_scene(SQUARE, ["mesh.cells=[4,4]"]).config
    assert isinstance(config, SceneConfig)
    assert isinstance(config.mesh, MeshConfig) and config.mesh.cells == (4, 4)
    assert isinstance(config.solver, SolverConfig) and config.solver.method == "fb"
    assert config.adapt is None and config.friction is None and config.load is None
    assert isinstance(config.output.formats, tuple)
    with pytest.raises(pydantic.ValidationError, match="frozen"):
        config.solver.rtol = 1.0
    with pytest.raises(pydantic.ValidationError, match="frozen"):
        config.mesh = config.mesh
    with pytest.raises(TypeError, match="immutable"):
        config.boundaries["other"] = next(iter(config.boundaries.values()))
    with pytest.raises(TypeError, match="immutable"):
        config.solver.petsc_options["ksp_type"] = "cg"
    # a changed copy is a new object; the scene's stays as loaded
    coarse = config.with_mesh(cells=(2, 2))
    assert coarse.mesh.cells == (2, 2) and config.mesh.cells == (4, 4)


def test_a_solve_does_not_validate_the_scene_again(monkeypatch):
    """The schema runs at load only: with it broken afterwards, a solve still runs (the old
    drivers validated the solver section again at every solve)."""
    scene = contact.load_scene(SQUARE, ["mesh.cells=[6,6]", "solver.sequence=off"])

    def refuse(*args, **kwargs):
        raise AssertionError("the scene's schema ran again")

    monkeypatch.setattr(config_module, "validate_scene", refuse)
    monkeypatch.setattr(config_module, "complete", refuse)  # the rules across sections
    monkeypatch.setattr(SceneConfig, "model_validate", refuse)  # each section's keys
    assert contact.solve(scene, method="min", verbose=False).converged


@pytest.mark.parametrize(
    "key, value",
    [("mu", 1.5), ("method", "newton"), ("max_it", 0), ("sequence", -1), ("stopping", "x")],
)
def test_a_call_override_has_the_scene_files_message(key, value):
    scene = contact.load_scene(SQUARE, ["mesh.cells=[4,4]"])
    with pytest.raises(ConfigError) as from_file:
        contact.load_scene(SQUARE, ["mesh.cells=[4,4]", f"solver.{key}={value}"])
    with pytest.raises(ConfigError) as from_call:
        contact.solve(scene, **{key: value})
    assert str(from_call.value) == str(from_file.value)
    with pytest.raises(ConfigError, match=r"^solver\.colour: unknown key \(expected one of met"):
        contact.solve(scene, colour="red")


def test_adapt_overrides_are_checked_like_the_section():
    assert AdaptConfig().updated(theta=0.3).theta == 0.3
    with pytest.raises(ConfigError, match=r"^adapt\.theta: must lie in \(0, 1\], got 2"):
        AdaptConfig().updated(theta=2)


@pytest.mark.parametrize(
    "key, value",
    [
        ("c_t", -1),
        ("c_t", "big"),
        ("kappa_t", 0),
        ("form", "tangent"),
        ("coulomb", "newton"),
        ("fixed_point_rtol", 0),
        ("fixed_point_max_it", 1.5),
    ],
)
def test_friction_options_have_the_scene_files_messages(key, value):
    """FrictionOptions (the tangential knobs, beside SolverOptions in contact.solvers) gives
    the loader's line for a bad knob, with the loader's key path."""
    with pytest.raises(ConfigError) as from_file:
        contact.load_scene(FRICTION, [f"friction.{key}={value}"])
    with pytest.raises(ConfigError) as typed:
        FrictionOptions.parse({key: value})
    assert str(typed.value) == str(from_file.value)


def test_the_friction_rows_receive_the_typed_options():
    scene = contact.load_scene(FRICTION, ["mesh.cells=[8,4]", "friction.form=projection"])
    assert isinstance(scene.config.friction, FrictionConfig)
    problem = build_problem(scene)
    options = problem.friction.options
    assert type(options) is FrictionOptions  # the knobs alone, not the scene's section
    assert options == scene.config.friction.knobs() and options.form == "projection"
    assert set(FrictionOptions.model_fields) == {
        "c_t",
        "kappa_t",
        "form",
        "coulomb",
        "fixed_point_rtol",
        "fixed_point_max_it",
    }
    with pytest.raises(pydantic.ValidationError, match="frozen"):
        options.form = "hsw"
