"""The scene's rigid obstacle at one pseudo-time, as a typed value (read from the validated
``obstacle`` section once; the models take it, not the config)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import expressions


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


def rigid_obstacle(cfg: Mapping[str, Any], time: float) -> RigidObstacle | None:
    """The validated scene config's obstacle at pseudo-time ``time`` (None without one)."""
    obstacle = cfg.get("obstacle")
    if not obstacle:
        return None
    constants = cfg["constants"]
    key = "point" if obstacle["type"] == "plane" else "center"
    coords = obstacle[key]
    position = vector_at(coords, constants, time)
    moving = any(expressions.uses_time(c, constants) for c in coords)
    if obstacle["type"] == "plane":
        nu = np.asarray(obstacle["normal"], dtype=float)
        return RigidObstacle(
            "plane", point=position, normal=nu / np.linalg.norm(nu), moving=moving, time=time
        )
    return RigidObstacle(
        obstacle["type"],
        center=position,
        radius=float(obstacle["radius"]),
        moving=moving,
        time=time,
    )


def vector_at(coords: list, constants: Mapping[str, float], time: float) -> np.ndarray:
    """Coordinates given as numbers or expressions of the pseudo-time t, evaluated at t."""
    origin = np.zeros((3, 1))
    return np.array([float(expressions.to_numpy(c, constants, t=time)(origin)[0]) for c in coords])
