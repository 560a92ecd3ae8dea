"""The scene's rigid obstacle at one pseudo-time, as a typed value: the ``obstacle`` section
(:class:`~contact.setup.scene_config.ObstacleConfig`) with its point or centre evaluated at t
(the models take it)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..base import expressions
from ..base.errors import ConfigError
from ..models.constraints import Ball, Plane
from .scene_config import ObstacleConfig

if TYPE_CHECKING:
    from .scene import Scene


@dataclass(frozen=True)
class RigidObstacle:
    """A rigid plane (through ``point``, unit ``normal`` ν pointing towards the body) or a
    circle / sphere (``center``, ``radius``; the body outside it) at pseudo-time ``time``.
    ``moving``: its position depends on t (``obstacle.point`` / ``obstacle.center`` are
    expressions of t)."""

    kind: str  # plane | circle | sphere
    point: np.ndarray | None = None
    normal: np.ndarray | None = None
    center: np.ndarray | None = None
    radius: float | None = None
    moving: bool = False
    time: float = 1.0

    @property
    def position(self) -> np.ndarray:
        """The obstacle's reference point: the plane's point, the circle's / sphere's centre."""
        position = self.point if self.kind == "plane" else self.center
        assert position is not None  # a validated obstacle has it
        return position


def rigid_obstacle(
    obstacle: ObstacleConfig, constants: Mapping[str, float], time: float
) -> RigidObstacle:
    """The scene's obstacle section at pseudo-time ``time`` (``constants`` for its
    expressions).  A point or centre that is not a finite number at that time (an expression
    of t such as ``1/(t - 0.6)``) is a ConfigError naming the key, the component and t."""
    coords = obstacle.point if obstacle.type == "plane" else obstacle.center
    assert coords is not None  # required for its type at load
    position = vector_at(coords, constants, time)
    key = "obstacle.point" if obstacle.type == "plane" else "obstacle.center"
    for i, value in enumerate(position):
        if not np.isfinite(value):
            raise ConfigError(
                f"{key}[{i}] (at t = {time:g}): not a finite number ({value}) for the "
                f"{obstacle.type}'s position {coords[i]!r}"
            )
    moving = any(expressions.uses_time(c, constants) for c in coords)
    if obstacle.type == "plane":
        nu = np.asarray(obstacle.normal, dtype=float)
        return RigidObstacle(
            "plane", point=position, normal=nu / np.linalg.norm(nu), moving=moving, time=time
        )
    assert obstacle.radius is not None  # required for a circle / sphere at load
    return RigidObstacle(
        obstacle.type, center=position, radius=float(obstacle.radius), moving=moving, time=time
    )


def vector_at(
    coords: Sequence[float | str], constants: Mapping[str, float], time: float
) -> np.ndarray:
    """Coordinates given as numbers or expressions of the pseudo-time t, evaluated at t."""
    origin = np.zeros((3, 1))
    with np.errstate(all="ignore"):  # a non-finite value is the caller's to report
        return np.array(
            [float(expressions.to_numpy(c, constants, t=time)(origin)[0]) for c in coords]
        )


def scene_obstacle(scene: Scene, time: float | None = None) -> RigidObstacle:
    """The scene's rigid obstacle at its pseudo-time (or at ``time``): a plane's point or a
    circle's centre may be expressions of t, an obstacle moved along a load path."""
    config = scene.config
    assert config.obstacle is not None  # an elastic scene with an obstacle (checked at load)
    return rigid_obstacle(config.obstacle, config.constants, scene.time if time is None else time)


def scene_surface(scene: Scene, time: float | None = None) -> Plane | Ball:
    """The scene's rigid obstacle at its pseudo-time (or at ``time``) as a surface: a
    :class:`~contact.models.constraints.Plane` through p with the normal ν of the scene, or
    a :class:`~contact.models.constraints.Ball` (circle in 2D, sphere in 3D).  Coordinates of
    the wrong length, or a circle in 3D (a sphere in 2D), are a ConfigError naming the key."""
    config, gdim = scene.config.obstacle, scene.mesh.geometry.dim
    assert config is not None  # the scene's rigid obstacle
    obstacle = scene_obstacle(scene, time)
    if config.type == "plane":
        assert config.normal is not None  # required for a plane at load
        plane = Plane(obstacle.position, np.asarray(config.normal, dtype=float))
        if len(plane.normal) != gdim or len(plane.point) != gdim:
            raise ConfigError(
                f"obstacle: point and normal need {gdim} components in a {gdim}D scene"
            )
        return plane
    want = "circle" if gdim == 2 else "sphere"
    if config.type != want:
        raise ConfigError(f"obstacle.type: a {gdim}D scene needs a {want}, got {config.type}")
    assert config.radius is not None  # checked at load
    if len(obstacle.position) != gdim:
        raise ConfigError(f"obstacle.center: needs {gdim} components in a {gdim}D scene")
    return Ball(obstacle.position, float(config.radius))
