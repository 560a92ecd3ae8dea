"""The public API (``contact.__all__``) checks its arguments (issue 10, defect 9): misuse is
a ``ValueError`` (``ConfigError`` for scene input) with one line naming the argument — not
a segmentation fault, a silently wrong answer or a raw PETSc error code."""

from __future__ import annotations

import contact
from contact import ConfigError

import numpy as np
import pytest
from clirun import ROOT

SCENE = str(ROOT / "configs" / "signorini_square.yaml")


@pytest.fixture(scope="module")
def solved():
    scene = contact.load_scene(SCENE, ["mesh.cells=[4,4]"])
    result = contact.solve(scene, verbose=False)
    return scene, result, contact.estimate(scene, result)


def _one_line(err: pytest.ExceptionInfo) -> str:
    text = str(err.value)
    assert "\n" not in text and len(text) < 300
    return text


@pytest.mark.parametrize(
    "cells, message",
    [
        (
            np.array([10**6]),
            r"^cells: 1 index\(es\) outside the owned cells 0 … 31, e\.g\. 1000000",
        ),
        (np.array([3, -1]), r"^cells: 1 index\(es\) outside the owned cells 0 … 31, e\.g\. -1"),
        (np.array([0.5, 1.0]), r"^cells: expected a 1D array of integer cell indices, got float64"),
        (
            np.array([[0, 1]]),
            r"^cells: expected a 1D array of integer cell indices, got int64 with shape \(1, 2\)",
        ),
    ],
)
def test_refine_checks_cell_indices(solved, cells, message) -> None:
    scene, _, _ = solved
    with pytest.raises(ValueError, match=message) as err:
        contact.refine(scene, cells)
    _one_line(err)


def test_refine_accepts_lists_and_empty(solved) -> None:
    scene, result, _ = solved
    child, u0 = contact.refine(scene, [0, 1], result.u_h)
    assert child.mesh.topology.index_map(2).size_global > 32 and u0 is not None
    same, _ = contact.refine(scene, np.zeros(0, dtype=np.int64))
    assert same.mesh.topology.index_map(2).size_global == 32


@pytest.mark.parametrize(
    "strategy, theta, message",
    [
        ("dorfler", -1, r"^theta: must be a number in \(0, 1\], got -1"),
        ("dorfler", 7, r"^theta: must be a number in \(0, 1\], got 7"),
        ("maximum", 0, r"^theta: must be a number in \(0, 1\], got 0"),
        ("dorfler", "half", r"^theta: must be a number in \(0, 1\], got 'half'"),
        ("bulk", 0.5, r"^strategy: unknown marking strategy 'bulk'"),
    ],
)
def test_mark_checks_strategy_and_theta(solved, strategy, theta, message) -> None:
    _, _, est = solved
    with pytest.raises(ValueError, match=message) as err:
        contact.mark(est.eta_T, strategy, theta=theta)
    _one_line(err)


def test_mark_checks_the_indicator(solved) -> None:
    _, _, est = solved
    with pytest.raises(ValueError, match=r"^eta_T: expected the DG0 indicator function"):
        contact.mark(est.eta_T.x.array, "dorfler", 0.5)


@pytest.mark.parametrize(
    "overrides", ["mesh.cells=[4,4]", b"mesh.cells=[4,4]", [1, 2], {"mesh.cells": 4}]
)
def test_load_scene_overrides_must_be_a_list_of_strings(overrides) -> None:
    with pytest.raises(
        ConfigError, match=r"^overrides: expected a list of 'key.path=value' strings"
    ) as err:
        contact.load_scene(SCENE, overrides)
    _one_line(err)


def test_load_scene_source_type() -> None:
    with pytest.raises(
        ConfigError, match=r"^source: expected a scene file path or a mapping, got int"
    ):
        contact.load_scene(3)


def test_guess_from_another_mesh(solved) -> None:
    """Was a raw PETSc "error code 75" (vector sizes differ)."""
    scene, _, _ = solved
    other = contact.load_scene(SCENE, ["mesh.cells=[6,6]"])
    foreign = contact.solve(other, verbose=False).u_h
    with pytest.raises(
        ValueError, match=r"^u0: lives on another mesh than the scene's problem"
    ) as err:
        contact.solve(scene, u0=foreign, verbose=False)
    _one_line(err)
    with pytest.raises(ValueError, match=r"^u0: expected a dolfinx\.fem\.Function"):
        contact.solve(scene, u0=np.zeros(25), verbose=False)
    with pytest.raises(
        ValueError, match=r"^u_h: expected a dolfinx\.fem\.Function on the scene's mesh"
    ):
        contact.refine(scene, [0], foreign)


def test_scene_and_result_arguments(solved) -> None:
    scene, result, _ = solved
    other = contact.load_scene(SCENE, ["mesh.cells=[6,6]"])
    for call in (
        lambda: contact.solve("configs/x.yaml"),
        lambda: contact.adapt(scene.config),
        lambda: contact.estimate(None, result),
        lambda: contact.refine("scene", [0]),
    ):
        with pytest.raises(ValueError, match=r"^scene: expected a contact\.Scene"):
            call()
    with pytest.raises(
        ValueError, match=r"^result: expected the contact\.Result of contact\.solve on this scene"
    ):
        contact.estimate(other, result)
    with pytest.raises(ValueError, match=r"^on_level: expected a function"):
        contact.adapt(scene, on_level="print")
    with pytest.raises(ConfigError, match=r"^solver\.method: 'newton' is not one of"):
        contact.solve(scene, method="newton")
    with pytest.raises(ConfigError, match=r"^adapt\.theta: must lie in \(0, 1\]"):
        contact.adapt(scene, theta=2.0)


# ------------------------------------------------------------------------- issue 26
def test_a_bad_config_never_reaches_the_solver() -> None:
    """A friction law typo in a Scene's config changed after loading was a bare PETSc "error
    code 101".  The config is validated once and frozen (issue 28): changing it in place is
    refused at the assignment (so nothing unchecked reaches a solve), and the same values
    given the way a config is changed — overrides when loading — are the one-line
    ConfigErrors of the YAML."""
    import pydantic

    path = ROOT / "configs" / "friction_block_2d.yaml"
    scene = contact.load_scene(path, ["mesh.cells=[8,4]"])
    for key, value, message in [
        ("law", "coulom", r"^friction\.law: 'coulom' is not one of none, tresca, coulomb$"),
        ("law", "tresca", r"^friction\.threshold: required for friction law tresca$"),
        ("coefficient", -1, r"^friction\.coefficient: must be >= 0, got -1"),
    ]:
        with pytest.raises(pydantic.ValidationError, match="frozen"):
            setattr(scene.config.friction, key, value)
        with pytest.raises(ConfigError, match=message) as err:
            contact.load_scene(path, ["mesh.cells=[8,4]", f"friction.{key}={value}"])
        _one_line(err)
    with pytest.raises(pydantic.ValidationError, match="frozen"):
        scene.config.model.nu = 0.5
    with pytest.raises(ConfigError, match=r"^model\.nu: must lie in \(-1, 0\.5\), got 0\.5"):
        contact.load_scene(path, ["mesh.cells=[8,4]", "model.nu=0.5"])
    for mapping in (scene.config.boundaries, scene.config.constants):  # mappings too
        with pytest.raises(TypeError, match="immutable"):
            mapping["x"] = 1
    assert scene.config.friction.law == "coulomb" and contact.solve(scene, verbose=False).converged


@pytest.mark.parametrize("bad", [np.nan, np.inf, -1.0])
def test_mark_refuses_indicators_that_are_not_finite(solved, bad) -> None:
    """NaN indicators marked no cell at all (a NaN is never above a threshold)."""
    _, _, est = solved
    eta = est.eta_T.copy()
    eta.x.array[5] = bad
    for strategy in ("dorfler", "maximum"):
        with pytest.raises(
            ValueError,
            match=r"^eta_T: 1 of 32 indicators are not finite "
            r"numbers >= 0 \(NaN, inf or negative\)",
        ) as err:
            contact.mark(eta, strategy)
        _one_line(err)
