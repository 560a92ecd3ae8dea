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

    Made by :func:`load_scene` (or by :func:`contact.refine` from a coarser scene), never by
    hand: the drivers (:func:`contact.solve`, :func:`contact.adapt`,
    :func:`contact.run_load_path`) take it as their first argument.

    Attributes:
        config: The validated scene as typed, frozen objects, one attribute per key of the
            YAML (``scene.config.solver.rtol``); an optional section left out is ``None``.
        mesh: The DOLFINx mesh (all bodies of a multi-body scene in one mesh).
        boundary: The facet tags of the boundary parts, with their ids and roles.
        time: The pseudo-time t of a quasi-static load path (the name ``t`` in data
            expressions; 1 at the end of the path and for a scene without one).
        history: Functions on the mesh that a load step needs from the previous one
            (friction: the previous displacement ``u_prev``); refinement carries them to
            the refined mesh.
        bodies: Cell tags k + 1 of the k-th body (scenes with ``bodies``), else ``None``.
        surfaces: The facet tags of a gmsh mesh (file or built-in body), else ``None``.
        parent: The coarser scene this one was refined from and the parent cell of each
            cell, else ``None``.
        snap: How a refinement of the mesh keeps to the scene's curved surfaces
            (``contact.setup.surfaces.snapping``, the ``snap`` of its
            :class:`~contact.adaptivity.refine.Domain`), built with the scene.
        budget: The DoF budget, ``solver.max_dofs`` (resolved on this machine for
            ``auto``, ``contact.setup.budget.max_dofs``), built with the scene.

    Example:
        >>> import contact
        >>> scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[8,8]"])
        >>> scene.name, scene.config.model.type, scene.time
        ('signorini_square', 'signorini', 1.0)
    """

    config: SceneConfig
    mesh: dmesh.Mesh
    boundary: Boundary
    time: float = 1.0
    history: dict = field(default_factory=dict)
    #: the pseudo-time of the load step whose solution is ``history["u_prev"]`` (None
    #: without one): how far a moving obstacle went since then (friction's relative slip)
    previous_time: float | None = None
    _t_constant: Any = field(default=None, repr=False)
    bodies: dmesh.MeshTags | None = None  # cell tags k + 1 of the k-th body (scenes with bodies)
    # the mesh's own facet tags (gmsh groups), carried by refinement
    surfaces: dmesh.MeshTags | None = None
    #: for a scene made by :func:`contact.refine`: (the scene it was refined from, the parent
    #: cell of each new cell) — the coarser meshes grid sequencing solves on first
    parent: tuple[Scene, np.ndarray] | None = None
    snap: Callable[[Any, Any], None] | None = field(default=None, repr=False)
    budget: int = 0

    @property
    def t_constant(self):
        """The pseudo-time as a ``fem.Constant`` on the mesh (created once, kept in step).

        Forms with t-dependent data use it, so that they compile once for all load steps.
        """
        if self._t_constant is None:
            from dolfinx import fem
            from petsc4py import PETSc

            self._t_constant = fem.Constant(self.mesh, PETSc.ScalarType(self.time))  # type: ignore[operator]
        return self._t_constant

    def set_time(self, t: float) -> None:
        """Move the scene to pseudo-time ``t`` (the number and the constant forms see).

        Args:
            t: The new pseudo-time.
        """
        self.time = float(t)
        if self._t_constant is not None:
            self._t_constant.value = self.time

    @property
    def name(self) -> str:
        """The scene's ``name`` (default: the scene file's stem)."""
        return self.config.name

    @property
    def comm(self) -> MPI.Comm:
        """The MPI communicator of the mesh."""
        return self.mesh.comm


def require_scene(scene: Any) -> None:
    """Raise ValueError unless ``scene`` is a :class:`Scene` (the public API's check)."""
    if not isinstance(scene, Scene):
        raise ValueError(
            f"scene: expected a contact.Scene (from contact.load_scene), got {type(scene).__name__}"
        )


def public[**P, R](function: Callable[P, R]) -> Callable[P, R]:
    """Return ``function`` (whose first argument is a scene) as the package exports it.

    The user's scene argument is checked first (:func:`require_scene`); the drivers call
    the unchecked functions with the Scenes the package built.
    """

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
    """Read and validate a scene, build its mesh and tag its boundary parts.

    Collective: call it on every rank of ``comm``. Everything is checked before anything
    is solved: keys and values, expressions, files, the DoF budget, the PETSc options, and
    that every boundary part selects facets (the user guide's Scene files page).

    Args:
        source: A scene file (YAML; a relative ``mesh.file`` is taken relative to it), or
            a mapping with the same keys (a relative ``mesh.file`` is taken relative to the
            current directory).
        overrides: ``"key.path=value"`` strings as given to ``contact run --set``, applied
            in order after the file, e.g. ``["mesh.cells=[32,32]", "adapt=none"]``.
        comm: The MPI communicator of the mesh.

    Returns:
        The scene: its frozen config, mesh and tagged boundary parts.

    Raises:
        ConfigError: On any bad input, with a one-line message naming the key or file.

    Example:
        >>> import contact
        >>> scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["adapt=none"])
        >>> scene.config.mesh.cells, scene.config.adapt
        ((16, 8), None)
        >>> contact.load_scene("configs/signorini_free_boundary.yaml", ["solver.method=fbb"])
        Traceback (most recent call last):
        contact.base.errors.ConfigError: solver.method: 'fbb' is not one of fb, min, ...
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
    """Return the scene of a validated config: its mesh and tagged boundary.

    The config comes from :func:`contact.setup.config.load_config`. Before the mesh is
    built the DoF budget (from the mesh parameters) and the PETSc options are checked;
    after, the declared boundary surfaces.
    """
    from .budget import check_parameters, max_dofs
    from .surfaces import boundary_surfaces, snapping

    gdim = mesh_dimension(cfg)  # None: a gmsh file, known once read
    check_parameters(cfg, gdim)
    if gdim is not None:
        _check_solver(cfg, gdim, comm)
    msh, file_tags, cell_tags = build_mesh(cfg, comm)
    if gdim is None:
        _check_solver(cfg, msh.geometry.dim, comm)
    bodies = tag_bodies(msh, cfg, cell_tags)
    boundary = tag_boundaries(msh, cfg, file_tags, bodies)
    # a declared surface that does not fit the mesh is bad input now, not at the first refinement
    boundary_surfaces(cfg, msh.geometry.dim, boundary)
    return Scene(
        cfg,
        msh,
        boundary,
        bodies=bodies,
        surfaces=file_tags,
        snap=snapping(cfg, boundary),
        budget=max_dofs(cfg.solver, msh.geometry.dim),
    )


def _check_solver(cfg: SceneConfig, gdim: int, comm: MPI.Comm) -> None:
    """The scene's PETSc options work with the model's default linear solver."""
    from ..solvers.options import check_petsc_options, default_options

    solver = cfg.solver
    check_petsc_options(solver.petsc_options, default_options(solver.linear, gdim, comm.size), comm)
