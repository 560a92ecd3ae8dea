"""A scene: the validated configuration plus the mesh and its boundary parts.

``load_scene`` is the entry point of the data flow  config → scene → solver → output.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from mpi4py import MPI

from dolfinx import mesh as dmesh

from .config import load_config
from .meshes import Boundary, build_mesh, tag_boundaries


@dataclass
class Scene:
    """What a scene file describes, turned into a mesh with tagged boundary parts.

    ``time`` is the pseudo-time t of a quasi-static load path (the name ``t`` in data
    expressions; 1 at the end of the path and for a scene without one); ``t_constant`` is
    it as a ``fem.Constant`` on the mesh, so that forms with t-dependent data compile once
    for all steps.  ``history`` holds functions on the mesh that a load step needs from the
    previous one (friction: the previous displacement ``u_prev``); refinement carries them
    to the refined mesh."""

    cfg: dict
    mesh: dmesh.Mesh
    boundary: Boundary
    time: float = 1.0
    history: dict = field(default_factory=dict)
    _t_constant: Any = field(default=None, repr=False)

    @property
    def t_constant(self):
        """The pseudo-time as a ``fem.Constant`` on the mesh (created once, kept in step)."""
        if self._t_constant is None:
            from dolfinx import fem
            from petsc4py import PETSc

            self._t_constant = fem.Constant(self.mesh, PETSc.ScalarType(self.time))
        return self._t_constant

    def set_time(self, t: float) -> None:
        """Move the scene to pseudo-time ``t`` (the number and the constant forms see)."""
        self.time = float(t)
        if self._t_constant is not None:
            self._t_constant.value = self.time

    @property
    def name(self) -> str:
        return self.cfg["name"]

    @property
    def comm(self) -> MPI.Comm:
        return self.mesh.comm


def load_scene(source: str | Path | Mapping[str, Any], overrides: list[str] | tuple[str, ...] = (),
               comm: MPI.Comm = MPI.COMM_WORLD) -> Scene:
    """Read and validate a scene (YAML path or dict), build its mesh and tag its boundary.

    ``overrides`` are ``"key.path=value"`` strings as given to ``contact run --set``.
    Raises :class:`contact.ConfigError` with a one-line message on any bad input.
    """
    from .surfaces import boundary_surfaces

    cfg = load_config(source, overrides)
    msh, file_tags = build_mesh(cfg, comm)
    scene = Scene(cfg, msh, tag_boundaries(msh, cfg, file_tags))
    boundary_surfaces(scene)  # a declared surface that does not fit the mesh is bad input now
    return scene
