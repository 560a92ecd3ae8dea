"""The DoF budget of one solve (``solver.max_dofs``): refuse a problem that would not fit in
memory before building it, instead of running for minutes into swap or a MemoryError.

The number of degrees of freedom N is known from the mesh parameters of the structured
meshes (rectangle, unit_square, lshape, box, blocks) before any mesh exists
(:func:`estimate_dofs`), is estimated from the sizes h, h_contact, zone of the parametric
gmsh meshes before gmsh meshes them (:func:`parametric_dofs`, within 0.95–1.25 N), and is
counted on the mesh itself before assembly for every mesh (:func:`mesh_dofs`; the only
check of a gmsh file).  A scene with N > ``solver.max_dofs`` is bad input: exit code 2
naming the key, with a hint.

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

import math
import os
from typing import Any

from ..base.errors import ConfigError
from .scene_config import MeshConfig, SceneConfig, SolverConfig

BYTES_PER_DOF = 3600  # >= 1.2 x every measured per-DoF peak (bench_memory.py)
BYTES_PER_DOF_3D_DIRECT = 15700  # a 3D direct solve at N_REF_3D_DIRECT DoFs ...
N_REF_3D_DIRECT = 117649  # ... growing like N^{1/3} per DoF
MEMORY_FRACTION = 0.5  # of the physical memory one solve may plan to use


def physical_memory() -> int:
    """Bytes of physical memory of this machine."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # not POSIX: assume 8 GiB
        return 8 * 2**30


def direct_3d(solver: SolverConfig, gdim: int) -> bool:
    """Whether the scene's linear solver is a direct factorization of a 3D problem."""
    from ..solvers.options import default_options

    options = {**default_options(solver.linear, gdim), **solver.petsc_options}
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


def max_dofs(solver: SolverConfig, gdim: int) -> int:
    """The scene's DoF budget: ``solver.max_dofs``, or :func:`default_max_dofs` for auto."""
    value = solver.max_dofs
    return default_max_dofs(direct_3d(solver, gdim)) if value == "auto" else int(value)


def estimate_dofs(mesh: MeshConfig, elastic: bool) -> int | None:
    """DoFs of the scene's problem from its mesh parameters, exact for the structured meshes
    (rectangle, unit_square, lshape, box, blocks, ring; None for the others).  Vertices V and
    cells F of the structured triangulations / tetrahedralizations, P2 adds one node per
    edge (E = V + F − 1 for a triangulated polygon, Euler; :func:`_kuhn_edges` for the
    tetrahedra of a 3D block), times the components (``elastic``: the dimension)."""
    kind, cells, p2 = mesh.type, mesh.cells, mesh.degree == 2
    if kind in ("rectangle", "unit_square"):
        nx, ny = cells  # type: ignore[misc]
        crossed = mesh.diagonal == "crossed"
        vertices = (nx + 1) * (ny + 1) + (nx * ny if crossed else 0)
        nodes, gdim = vertices + p2 * (vertices + (4 if crossed else 2) * nx * ny - 1), 2
    elif kind == "lshape":
        (n,) = cells  # type: ignore[misc]
        vertices = (2 * n + 1) ** 2 - n * n
        nodes, gdim = vertices + p2 * (vertices + 6 * n * n - 1), 2
    elif kind == "ring":
        n_t, n_r = cells  # type: ignore[misc]
        vertices = n_t * (n_r + 1)  # E = V + F on an annulus (Euler characteristic 0)
        nodes, gdim = vertices + p2 * (vertices + 2 * n_t * n_r), 2
    elif kind == "box":
        nx, ny, nz = cells  # type: ignore[misc]
        nodes, gdim = (nx + 1) * (ny + 1) * (nz + 1), 3  # P2 boxes are refused (config)
    elif kind == "blocks" and mesh.blocks:
        gdim = len(mesh.blocks[0].corners[0])
        nodes = sum(_block_nodes(block.cells, p2) for block in mesh.blocks)
    else:
        return None
    return nodes * (gdim if elastic else 1)


def _block_nodes(n: tuple[int, ...], p2: bool) -> int:
    """Nodes of one structured block of :func:`contact.setup.meshes.blocks` (``n`` cells per
    direction): its vertices, and with ``p2`` its edges too."""
    vertices = math.prod(k + 1 for k in n)
    if not p2:
        return vertices
    if len(n) == 2:
        return 2 * vertices + 2 * n[0] * n[1] - 1
    return vertices + _kuhn_edges(*n)


def _kuhn_edges(nx: int, ny: int, nz: int) -> int:
    """Edges of the grid of nx × ny × nz boxes, each cut into six tetrahedra along its main
    diagonal: the grid lines, one diagonal in every square face, one in every box."""
    lines = nx * (ny + 1) * (nz + 1) + (nx + 1) * ny * (nz + 1) + (nx + 1) * (ny + 1) * nz
    faces = nx * ny * (nz + 1) + nx * (ny + 1) * nz + (nx + 1) * ny * nz
    return lines + faces + nx * ny * nz


#: a parametric gmsh mesh has between 0.95 N and 1.25 N DoFs for the estimate N of
#: :func:`parametric_dofs` (calibration, tests/test_budget.py: 0.99 N to 1.22 N)
ESTIMATE_RANGE = (0.95, 1.25)
#: P2 nodes per vertex of a gmsh mesh: V + E with E ≈ 3 V (triangles), ≈ 6 V (tetrahedra)
P2_NODES_PER_VERTEX = {2: 4, 3: 7}


def parametric_dofs(mesh: MeshConfig, elastic: bool) -> float | None:
    """The DoFs of a parametric gmsh mesh (quarter_disk, sphere_octant, half_disks,
    sphere_on_block; None for the others), estimated from its sizes h, h_contact, zone
    before gmsh meshes it (:func:`contact.setup.geometry.estimated_vertices`); the true number
    lies in :data:`ESTIMATE_RANGE` times it."""
    from .geometry import estimated_vertices

    if mesh.type not in ("quarter_disk", "sphere_octant", "half_disks", "sphere_on_block"):
        return None
    gdim = 2 if mesh.type in ("quarter_disk", "half_disks") else 3
    per_vertex = P2_NODES_PER_VERTEX[gdim] if mesh.degree == 2 else 1
    nodes = estimated_vertices(mesh) * per_vertex
    return nodes * (gdim if elastic else 1)


def check_parameters(cfg: SceneConfig, gdim: int | None) -> None:
    """The DoF budget from the mesh parameters, before any mesh is built (every rank finds
    the same): exact for the structured meshes; for the parametric gmsh meshes refused
    at once when the least number of DoFs the estimate N of :func:`parametric_dofs` allows
    exceeds the budget, else meshed (and the mesh checked exactly before assembly)."""
    mesh, solver = cfg.mesh, cfg.solver
    dofs = estimate_dofs(mesh, cfg.elastic)
    if mesh.type == "blocks":
        cells = [list(block.cells) for block in mesh.blocks or ()]
        check_dofs(solver, dofs, gdim, "mesh.blocks", f"cells {cells} give")
    elif (estimate := parametric_dofs(mesh, cfg.elastic)) is not None:
        sizes = ", ".join(f"{k} = {getattr(mesh, k):g}" for k in ("h", "h_contact", "zone"))
        low, high = (f * estimate for f in ESTIMATE_RANGE)
        at_least = f"{sizes} give at least"
        check_dofs(solver, math.floor(low), gdim, "mesh.h", at_least, enough=math.ceil(high))
    else:
        cells_ = list(mesh.cells) if isinstance(mesh.cells, tuple) else mesh.cells
        check_dofs(solver, dofs, gdim, "mesh.cells", f"{cells_} cells give")


def mesh_dofs(msh: Any, degree: int, components: int) -> int:
    """DoFs of the Lagrange space of ``degree`` (1 or 2) with ``components`` on a mesh."""
    top = msh.topology
    nodes = top.index_map(0).size_global
    if degree == 2:
        top.create_entities(1)
        nodes += top.index_map(1).size_global
    return nodes * components


def check_dofs(
    solver: SolverConfig,
    dofs: int | None,
    gdim: int | None,
    key: str,
    what: str,
    enough: int | None = None,
) -> None:
    """ConfigError ``<key>: <what> N DoFs, more than solver.max_dofs = M …`` when N > M,
    with the hint of a budget that would admit it (N, or ``enough`` for a lower bound N)."""
    if dofs is None or gdim is None:
        return
    limit = max_dofs(solver, gdim)
    if dofs <= limit:
        return
    gib = predicted_memory(dofs, direct_3d(solver, gdim)) / 2**30
    raise ConfigError(
        f"{key}: {what} {dofs} DoFs, more than solver.max_dofs = {limit} (predicted peak memory "
        f"{gib:.1f} GiB; this machine has {physical_memory() / 2**30:.0f} GiB); use "
        f"a coarser mesh, or --set solver.max_dofs={enough or dofs} if it fits"
    )
