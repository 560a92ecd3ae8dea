"""The DoF budget of one solve (``solver.max_dofs``): refuse a problem that would not fit in
memory before building it, instead of running for minutes into swap or a MemoryError.

The number of degrees of freedom N is known from the mesh parameters of the built-in meshes
before any mesh exists (:func:`estimate_dofs`), and from the mesh itself otherwise (gmsh
files and the parametric Hertz bodies: :func:`mesh_dofs`, before assembly).  A scene with
N > ``solver.max_dofs`` is bad input: exit code 2 naming the key, with a hint.

``solver.max_dofs: auto`` (the default) is

    max_dofs = MEMORY_FRACTION × (physical memory of this machine) / BYTES_PER_DOF,

with BYTES_PER_DOF the peak resident memory per DoF of one solve with the default linear
solvers, measured by ``demos/bench/bench_memory.py`` (the largest of its kinds; see the
README).  Under MPI, N counts the DoFs of all ranks and the memory is this machine's: on a
cluster of several nodes, set ``solver.max_dofs`` yourself.
"""
from __future__ import annotations

import os
from typing import Any

from .config import ConfigError

BYTES_PER_DOF = 3000        # measured peak bytes per DoF (demos/bench/bench_memory.py)
MEMORY_FRACTION = 0.5       # of the physical memory one solve may plan to use


def physical_memory() -> int:
    """Bytes of physical memory of this machine."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # not POSIX: assume 8 GiB
        return 8 * 2**30


def default_max_dofs() -> int:
    """``solver.max_dofs: auto`` on this machine (see the module doc)."""
    return int(MEMORY_FRACTION * physical_memory() / BYTES_PER_DOF)


def max_dofs(cfg: dict) -> int:
    """The scene's DoF budget: ``solver.max_dofs``, or :func:`default_max_dofs` for auto."""
    value = cfg["solver"].get("max_dofs", "auto")
    return default_max_dofs() if value == "auto" else int(value)


def estimate_dofs(cfg: dict) -> int | None:
    """DoFs of the scene's problem from its mesh parameters (built-in meshes; None for
    gmsh files and the parametric gmsh bodies).  Vertices V and cells F of the structured
    triangulations / tetrahedralizations, P2 adds one node per edge (E = V + F − 1 for a
    triangulated polygon, Euler), times the components (elasticity: the dimension)."""
    mesh = cfg["mesh"]
    kind, cells = mesh["type"], mesh.get("cells")
    if kind in ("rectangle", "unit_square"):
        nx, ny = cells
        crossed = mesh.get("diagonal") == "crossed"
        vertices = (nx + 1) * (ny + 1) + (nx * ny if crossed else 0)
        faces = (4 if crossed else 2) * nx * ny
        gdim = 2
    elif kind == "lshape":
        (n,) = cells
        vertices, faces, gdim = (2 * n + 1) ** 2 - n * n, 6 * n * n, 2
    elif kind == "box":
        nx, ny, nz = cells
        vertices, faces, gdim = (nx + 1) * (ny + 1) * (nz + 1), None, 3
    else:
        return None
    nodes = vertices
    if mesh.get("degree", 1) == 2 and faces is not None:
        nodes += vertices + faces - 1
    return nodes * (gdim if cfg["model"]["type"] == "elasticity" else 1)


def mesh_dofs(msh: Any, degree: int, components: int) -> int:
    """DoFs of the Lagrange space of ``degree`` (1 or 2) with ``components`` on a mesh."""
    top = msh.topology
    nodes = top.index_map(0).size_global
    if degree == 2:
        top.create_entities(1)
        nodes += top.index_map(1).size_global
    return nodes * components


def check_dofs(cfg: dict, dofs: int | None, key: str, what: str) -> None:
    """ConfigError ``<key>: <what> N DoFs, more than solver.max_dofs = M …`` when N > M."""
    limit = max_dofs(cfg)
    if dofs is None or dofs <= limit:
        return
    gib = dofs * BYTES_PER_DOF / 2**30
    raise ConfigError(f"{key}: {what} {dofs} DoFs, more than solver.max_dofs = {limit} (about {gib:.1f} GiB at "
                      f"{BYTES_PER_DOF} bytes per DoF; this machine has {physical_memory() / 2**30:.0f} GiB); "
                      f"use a coarser mesh, or --set solver.max_dofs={dofs} if it fits")
