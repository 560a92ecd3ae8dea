"""A scene's :class:`~contact.post.posed.Posed` record: what the figures of its solves need
of the problem beyond the result, taken from its configuration (for a level or a load step
once, ``level.posed``)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import ufl
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..base import expressions
from .meshes import Boundary

if TYPE_CHECKING:
    from .scene import Scene


@dataclass(frozen=True)
class PosedProblem:
    """The problem of a scene as its figures need it (the attributes of
    :class:`contact.post.posed.Posed`, which documents them)."""

    mesh: dmesh.Mesh
    boundary: Boundary
    bodies: dmesh.MeshTags | None
    elastic: bool
    pairs: tuple[tuple[str, str], ...]
    materials: Mapping[str, tuple[float, float]]
    obstacle: Any
    exact: Any
    exact_values: tuple[Callable[[np.ndarray], np.ndarray], ...]
    reference: Any
    coefficient: float | None
    approach: Callable[[np.ndarray], float] | None = field(default=None, repr=False)
    translation: Callable[[], list[float]] | None = field(default=None, repr=False)
    conditions: Callable[[], dict[str, Any]] = field(default=dict, repr=False)

    @property
    def comm(self) -> MPI.Comm:
        """The mesh's communicator."""
        return self.mesh.comm


def posed_of(scene: Scene) -> PosedProblem:
    """Return the record of ``scene`` (its mesh, boundary, bodies and pseudo-time; the
    sections of its configuration the figures read).

    Args:
        scene: The scene.

    Returns:
        The record; its ``approach`` and ``conditions`` compute on the scene when called.
    """
    from .exact_data import posed_problem

    cfg = scene.config
    model = cfg.model
    if cfg.bodies:
        materials = {name: (b.E, b.nu) for name, b in cfg.bodies.items()}
    elif cfg.elastic and model.E is not None:
        materials = {"": (model.E, model.nu)}
    else:
        materials = {}
    one_obstacle = cfg.obstacle is not None and not cfg.pairs
    exact, constants, t = cfg.data.exact, cfg.constants, scene.time
    texts = () if exact is None else exact if isinstance(exact, tuple) else (exact,)
    parts = [expressions.to_ufl(e, scene.mesh, constants, t=t) for e in texts]
    return PosedProblem(
        mesh=scene.mesh,
        boundary=scene.boundary,
        bodies=scene.bodies,
        elastic=cfg.elastic,
        pairs=tuple((pair.slave, pair.master) for pair in cfg.pairs or ()),
        materials=materials,
        obstacle=cfg.obstacle,
        exact=None
        if exact is None
        else ufl.as_vector(parts)
        if isinstance(exact, tuple)
        else parts[0],
        exact_values=tuple(expressions.to_numpy(e, constants, t=t) for e in texts),
        reference=cfg.reference,
        coefficient=None if cfg.friction is None else cfg.friction.coefficient,
        approach=functools.partial(obstacle_approach, scene) if one_obstacle else None,
        translation=functools.partial(obstacle_translation, scene) if one_obstacle else None,
        conditions=functools.partial(posed_problem, scene),
    )


def obstacle_approach(scene: Scene, point: np.ndarray) -> float:
    """a(t) = g_0(X) − g_t(X) at ``point`` X, t the scene's pseudo-time: how far the rigid
    obstacle moved towards the body there since t = 0 (:mod:`contact.post.load_curve`)."""
    from .obstacle import scene_surface

    X = np.asarray(point, dtype=float)[None, : scene.mesh.geometry.dim]
    return float(scene_surface(scene, 0.0).project(X)[0][0] - scene_surface(scene).project(X)[0][0])


def obstacle_translation(scene: Scene) -> list[float]:
    """The rigid obstacle's translation since t = 0 (gdim components,
    :mod:`contact.post.load_curve`)."""
    from .obstacle import scene_obstacle

    return (scene_obstacle(scene).position - scene_obstacle(scene, 0.0).position).tolist()
