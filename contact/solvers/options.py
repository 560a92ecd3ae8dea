"""Solver options: the scene's ``solver`` section with call-time overrides, method names
as benchmarks list them, and PETSc's options database (set, read, errors as one line)."""
from __future__ import annotations

from typing import Any

from petsc4py import PETSc

from ..config import SCENE, ConfigError, _validate
from ..failures import petsc_message
from ..scene import Scene


def solver_options(scene: Scene, **overrides: Any) -> dict:
    """The scene's ``solver`` section with keyword overrides, validated like the YAML."""
    raw = {**scene.cfg["solver"], **{k: v for k, v in overrides.items() if v is not None}}
    return _validate(raw, SCENE["solver"], "solver", scene.cfg["constants"])


def method_variant(name: str) -> tuple[str, dict]:
    """A method name as benchmarks and tests list it: ``fb``, … or ``fb-nopolish`` /
    ``blend-nopolish`` (the pure Newton method) → (method, options for :func:`solve`)."""
    if name.endswith("-nopolish"):
        return name.removesuffix("-nopolish"), {"polish": False}
    return name, {}


def set_from_options(snes: PETSc.SNES) -> None:
    """setFromOptions + setUp; a bad PETSc option becomes a one-line ConfigError."""
    PETSc.Sys.pushErrorHandler("python")  # raise, do not print PETSc's trace
    try:
        snes.setFromOptions()
        snes.getKSP().setFromOptions()
        snes.getKSP().getPC().setFromOptions()
    except PETSc.Error as err:
        raise ConfigError(f"solver.petsc_options: PETSc rejected the options ({petsc_message(err)})") from None
    finally:
        PETSc.Sys.popErrorHandler()


def petsc_value(val: Any) -> str:
    if isinstance(val, bool):
        return "true" if val else "false"
    return "" if val is None else str(val)


