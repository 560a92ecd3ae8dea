"""A scene: the validated configuration plus the mesh and its boundary parts.

``load_scene`` is the entry point of the data flow  config → scene → solver → output.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from mpi4py import MPI

from dolfinx import mesh as dmesh

from .config import load_config
from .meshes import Boundary, build_mesh, tag_boundaries


@dataclass
class Scene:
    """What a scene file describes, turned into a mesh with tagged boundary parts."""

    cfg: dict
    mesh: dmesh.Mesh
    boundary: Boundary

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
