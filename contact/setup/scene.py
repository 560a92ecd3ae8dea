"""A scene: the validated configuration plus the mesh and its boundary parts.

``load_scene`` is the entry point of the data flow  config → scene → solver → output.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..base.errors import ConfigError
from .config import load_config
from .meshes import Boundary, build_mesh, mesh_dimension, tag_bodies, tag_boundaries
from .scene_config import SceneConfig


@dataclass
class Scene:
    """What a scene file describes, turned into a mesh with tagged boundary parts.

    ``time`` is the pseudo-time t of a quasi-static load path (the name ``t`` in data
    expressions; 1 at the end of the path and for a scene without one); ``t_constant`` is
    it as a ``fem.Constant`` on the mesh, so that forms with t-dependent data compile once
    for all steps.  ``history`` holds functions on the mesh that a load step needs from the
    previous one (friction: the previous displacement ``u_prev``); refinement carries them
    to the refined mesh."""

    config: SceneConfig
    mesh: dmesh.Mesh
    boundary: Boundary
    time: float = 1.0
    history: dict = field(default_factory=dict)
    _t_constant: Any = field(default=None, repr=False)
    bodies: dmesh.MeshTags | None = None  # cell tags k + 1 of the k-th body (scenes with bodies)
    # the mesh's own facet tags (gmsh groups), carried by refinement
    surfaces: dmesh.MeshTags | None = None
    #: for a scene made by :func:`contact.refine`: (the scene it was refined from, the parent
    #: cell of each new cell) — the coarser meshes grid sequencing solves on first
    parent: tuple[Scene, np.ndarray] | None = None

    @property
    def t_constant(self):
        """The pseudo-time as a ``fem.Constant`` on the mesh (created once, kept in step)."""
        if self._t_constant is None:
            from dolfinx import fem
            from petsc4py import PETSc

            self._t_constant = fem.Constant(self.mesh, PETSc.ScalarType(self.time))  # type: ignore[operator]
        return self._t_constant

    def set_time(self, t: float) -> None:
        """Move the scene to pseudo-time ``t`` (the number and the constant forms see)."""
        self.time = float(t)
        if self._t_constant is not None:
            self._t_constant.value = self.time

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def comm(self) -> MPI.Comm:
        return self.mesh.comm


def require_scene(scene: Any) -> None:
    """ValueError unless ``scene`` is a :class:`Scene` (argument check of the public API)."""
    if not isinstance(scene, Scene):
        raise ValueError(
            f"scene: expected a contact.Scene (from contact.load_scene), got {type(scene).__name__}"
        )


def public[**P, R](function: Callable[P, R]) -> Callable[P, R]:
    """``function`` (whose first argument is a scene) as the package exports it: the user's
    scene argument checked first (:func:`require_scene`).  The drivers call the unchecked
    functions with the Scenes the package built."""

    @functools.wraps(function)
    def checked(*args: P.args, **kwargs: P.kwargs) -> R:
        require_scene(args[0] if args else kwargs.get("scene"))
        return function(*args, **kwargs)

    return checked


def load_scene(
    source: str | Path | Mapping[str, Any],
    overrides: list[str] | tuple[str, ...] = (),
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> Scene:
    """Read and validate a scene (YAML path or dict), build its mesh and tag its boundary.

    ``overrides`` are ``"key.path=value"`` strings as given to ``contact run --set``.
    Raises :class:`contact.ConfigError` with a one-line message on any bad input.
    """
    if isinstance(source, bool) or not isinstance(source, (str, Path, Mapping)):
        raise ConfigError(
            f"source: expected a scene file path or a mapping, got {type(source).__name__}"
        )
    if (
        isinstance(overrides, (str, bytes))
        or not isinstance(overrides, (list, tuple))
        or not all(isinstance(o, str) for o in overrides)
    ):
        raise ConfigError(
            f"overrides: expected a list of 'key.path=value' strings, got {overrides!r:.80}"
        )
    return build_scene(load_config(source, overrides), comm)


def build_scene(cfg: SceneConfig, comm: MPI.Comm = MPI.COMM_WORLD) -> Scene:
    """The scene of a validated config (:func:`contact.setup.config.load_config`): its mesh and
    tagged boundary.  Before the mesh is built: the DoF budget (from the mesh parameters)
    and the PETSc options; after: the declared boundary surfaces."""
    from .budget import check_parameters
    from .surfaces import boundary_surfaces

    gdim = mesh_dimension(cfg)  # None: a gmsh file, known once read
    check_parameters(cfg, gdim)
    if gdim is not None:
        _check_solver(cfg, gdim, comm)
    msh, file_tags, cell_tags = build_mesh(cfg, comm)
    if gdim is None:
        _check_solver(cfg, msh.geometry.dim, comm)
    bodies = tag_bodies(msh, cfg, cell_tags)
    scene = Scene(
        cfg, msh, tag_boundaries(msh, cfg, file_tags, bodies), bodies=bodies, surfaces=file_tags
    )
    # a declared surface that does not fit the mesh is bad input now, not at the first refinement
    boundary_surfaces(cfg, msh.geometry.dim, scene.boundary)
    return scene


def _check_solver(cfg: SceneConfig, gdim: int, comm: MPI.Comm) -> None:
    """The scene's PETSc options work with the model's default linear solver."""
    from ..solvers.options import check_petsc_options, default_options

    solver = cfg.solver
    check_petsc_options(solver.petsc_options, default_options(solver.linear, gdim, comm.size), comm)
