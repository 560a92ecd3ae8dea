"""The DoF budget of one solve (``solver.max_dofs``): refuse a problem that would not fit in
memory before building it, instead of running for minutes into swap or a MemoryError.

The number of degrees of freedom N is known from the mesh parameters of the built-in meshes
before any mesh exists (:func:`estimate_dofs`), and from the mesh itself otherwise (gmsh
files and the parametric Hertz bodies: :func:`mesh_dofs`, before assembly).  A scene with
N > ``solver.max_dofs`` is bad input: exit code 2 naming the key, with a hint.

``solver.max_dofs: auto`` (the default) is the largest N whose predicted peak memory stays
within MEMORY_FRACTION (1/2) of this machine's physical memory.  The prediction is the
peak resident memory of one serial solve with the default linear solvers, measured by
``demos/bench/bench_memory.py`` (2 cores, 24 GiB; peak RSS / DoFs at the largest size,
``demos/results/memory.csv``; every kind below now solves with CG + GAMG):

=====================================  =========  ======================  ==============
kind                                   N          peak                    bytes per DoF
=====================================  =========  ======================  ==============
scalar 2D                              1 050 625  1324 MiB                1321
elasticity 2D                            526 338   805 MiB                1603
elasticity 3D                          1 029 000  2850 MiB                2904
scalar 3D                                117 649   421 MiB                3751 (slope 2773)
=====================================  =========  ======================  ==============

so memory(N) = BYTES_PER_DOF · N with BYTES_PER_DOF = 3600 B, which keeps a margin of at
least 20 % over the largest per-DoF peak above (it was the measured peak of MUMPS LU, the
2D default before CG + GAMG; ``solver.linear: direct`` still uses it).  A direct (LU /
Cholesky) solve in 3D has a fill-in growing like N^{4/3} (nested dissection):
memory(N) = BYTES_PER_DOF_3D_DIRECT · N · (N / N_REF_3D_DIRECT)^{1/3}, from MUMPS LU on
the 48³ scalar box (1760 MiB at 117 649 DoFs, when it was that kind's default).  On a 24 GiB
machine that allows 3.6 M DoFs (1024² scalar and 1 M-DoF 3D elasticity fit), and 0.5 M
DoFs for a 3D direct solve.  Under MPI, N counts the DoFs of all ranks and the memory is
this machine's: on a cluster of several nodes, set ``solver.max_dofs`` yourself.
"""
from __future__ import annotations

import os
from typing import Any

from .config import ConfigError

BYTES_PER_DOF = 3600              # >= 1.2 x every measured per-DoF peak (bench_memory.py)
BYTES_PER_DOF_3D_DIRECT = 15700   # a 3D direct solve at N_REF_3D_DIRECT DoFs ...
N_REF_3D_DIRECT = 117649          # ... growing like N^{1/3} per DoF
MEMORY_FRACTION = 0.5             # of the physical memory one solve may plan to use


def physical_memory() -> int:
    """Bytes of physical memory of this machine."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # not POSIX: assume 8 GiB
        return 8 * 2**30


def direct_3d(cfg: dict, gdim: int) -> bool:
    """Whether the scene's linear solver is a direct factorization of a 3D problem."""
    from .solvers.options import default_options

    options = {**default_options(cfg["solver"].get("linear", "auto"), gdim), **cfg["solver"]["petsc_options"]}
    return gdim == 3 and str(options.get("pc_type")) in ("lu", "cholesky")


def predicted_memory(dofs: int, direct3d: bool) -> float:
    """Predicted peak bytes of one solve with ``dofs`` DoFs (see the module doc)."""
    if direct3d:
        return BYTES_PER_DOF_3D_DIRECT * dofs * (dofs / N_REF_3D_DIRECT) ** (1.0 / 3.0)
    return BYTES_PER_DOF * dofs


def default_max_dofs(direct3d: bool = False) -> int:
    """``solver.max_dofs: auto`` on this machine: memory(N) ≤ MEMORY_FRACTION × memory."""
    budget = MEMORY_FRACTION * physical_memory()
    if direct3d:  # B N^{4/3} / N_ref^{1/3} ≤ budget
        return int((budget * N_REF_3D_DIRECT ** (1.0 / 3.0) / BYTES_PER_DOF_3D_DIRECT) ** 0.75)
    return int(budget / BYTES_PER_DOF)


def max_dofs(cfg: dict, gdim: int) -> int:
    """The scene's DoF budget: ``solver.max_dofs``, or :func:`default_max_dofs` for auto."""
    value = cfg["solver"].get("max_dofs", "auto")
    return default_max_dofs(direct_3d(cfg, gdim)) if value == "auto" else int(value)


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


def check_dofs(cfg: dict, dofs: int | None, gdim: int | None, key: str, what: str) -> None:
    """ConfigError ``<key>: <what> N DoFs, more than solver.max_dofs = M …`` when N > M."""
    if dofs is None or gdim is None:
        return
    limit = max_dofs(cfg, gdim)
    if dofs <= limit:
        return
    gib = predicted_memory(dofs, direct_3d(cfg, gdim)) / 2**30
    raise ConfigError(f"{key}: {what} {dofs} DoFs, more than solver.max_dofs = {limit} (predicted peak memory "
                      f"{gib:.1f} GiB; this machine has {physical_memory() / 2**30:.0f} GiB); use a coarser mesh, "
                      f"or --set solver.max_dofs={dofs} if it fits")
