"""Kernels of the adaptive loop, each against the path it replaced or might be replaced by (issue
11).

What it shows:

* ``assembly`` — the stiffness matrix of 3D elasticity (P1 tetrahedra on a box of
  ``--cells`` × ``--cells`` × 2 ``--cells``) assembled by PETSc's MatSetValues (the old
  path, ``contact.models.problem.BLOCK_CSR = False``) and through dolfinx's block CSR
  matrix (:func:`contact.models.problem.assemble_matrix`), alternating, ``--repeat``
  times, with the largest entry of their difference;
* ``picture`` — a nodal field on a 2D mesh of ``--cells-2d`` × ``--cells-2d``/2 squares
  (2 triangles each) drawn with Gouraud triangles and as the image of
  :func:`contact.output.plots.raster`, each saved to a PNG;
* ``refine`` (run it under mpirun) — a unit square of ``--cells-refine``² squares whose
  cells with x < 0.3 are refined, as an adaptive loop refines one region: by
  ``dolfinx.mesh.refine`` with the identity partitioner (what
  :func:`contact.adaptivity.refine.refine` does in parallel: children stay on their parent's rank,
  the ghost layer is rebuilt) and with dolfinx's graph partitioner (the refined mesh redistributed),
  and with none (children stay, no ghost layer: what a serial run does), alternating; the check
  column is the busiest rank's owned cells over the mean after refinement;
* ``floor`` (serially and under mpirun) — the least the 2D finest level can cost besides its
  solve: a unit square of ``--cells-floor``² squares refined uniformly (to about the 1.23M
  DoFs of problem A's finest level) by ``dolfinx.mesh.refine`` as the adaptive loop calls it;
  the same child cells handed to ``dolfinx.mesh.create_mesh`` (what a refinement written
  outside dolfinx would pay to obtain a dolfinx mesh); the P1 stiffness matrix and load
  assembled on it; one CG + GAMG solve of that system (rtol 1e-8 from zero, the loop's
  default options), alternating ``--repeat`` times. The check column is each time over the
  solve's (the solve's row: its CG iterations).

Prints one row per measurement and writes CSV (kernel, dofs or cells, path, seconds,
check).  Run serially, and the assembly under ``mpirun -n 2`` too:

    python demos/bench/bench_kernels.py --out demos/results/kernels.csv
    mpirun -n 2 python demos/bench/bench_kernels.py --only assembly --cells 55 --out
    demos/results/kernels_np2.csv mpirun -n 2 python demos/bench/bench_kernels.py --only refine
    --repeat 3 --out demos/results/kernels_refine_np2.csv python demos/bench/bench_kernels.py --only
    floor --repeat 3 --out demos/results/kernels_floor.csv mpirun -n 2 python
    demos/bench/bench_kernels.py --only floor --repeat 3 --out demos/results/kernels_floor_np2.csv
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import dolfinx_solver  # noqa: F401  (before dolfinx / petsc4py with the solver wheel)
from contact.adaptivity.refine import refine_partitioner
from contact.drivers.adaptive import busiest_share
from contact.models import problem as P
from contact.models.elasticity import epsilon, stress
from contact.solvers.options import default_options

import numpy as np
import ufl
from common import save_csv
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc


def _timed(times: list[float], f: Callable[[], Any]) -> Any:
    """f() between two barriers of COMM_WORLD; its wall seconds appended to ``times``."""
    MPI.COMM_WORLD.Barrier()
    t0 = time.perf_counter()
    out = f()
    MPI.COMM_WORLD.Barrier()
    times.append(time.perf_counter() - t0)
    return out


def assembly(cells: int, repeat: int) -> list[dict]:
    comm = MPI.COMM_WORLD
    msh = dmesh.create_box(
        comm, [[0, 0, 0], [1, 1, 2]], [cells, cells, 2 * cells], dmesh.CellType.tetrahedron
    )
    V = fem.functionspace(msh, ("Lagrange", 1, (3,)))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = fem.form(ufl.inner(stress(u, 1.0, 1.0), epsilon(v)) * ufl.dx)
    floor = dmesh.locate_entities_boundary(msh, 2, lambda x: np.isclose(x[2], 0.0))
    bcs = [fem.dirichletbc(np.zeros(3), fem.locate_dofs_topological(V, 2, floor), V)]
    times: dict[bool, list[float]] = {False: [], True: []}
    K = {}
    for _ in range(repeat):
        for block in (False, True):
            P.BLOCK_CSR = block
            K[block] = _timed(times[block], lambda: P.assemble_matrix(a, bcs))
    P.BLOCK_CSR = True
    D = K[False].copy()
    D.axpy(-1.0, K[True], structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    diff = D.norm(PETSc.NormType.INFINITY) / K[False].norm(PETSc.NormType.INFINITY)
    dofs = K[True].getSize()[0]
    return [
        {
            "kernel": "assembly",
            "ranks": comm.size,
            "size": dofs,
            "path": "petsc" if not block else "block_csr",
            "seconds": round(float(np.median(times[block])), 3),
            "check": f"{diff:.1e}",
        }
        for block in (False, True)
    ]


def picture(cells: int) -> list[dict]:
    import matplotlib

    matplotlib.use("Agg")
    from contact.output import drawing, plots

    import matplotlib.pyplot as plt
    import matplotlib.tri as mtri

    msh = dmesh.create_rectangle(MPI.COMM_SELF, [[-1.0, 0.0], [1.0, 1.0]], [cells, cells // 2])
    x = msh.geometry.x
    tri = mtri.Triangulation(x[:, 0], x[:, 1], msh.geometry.dofmaps[0])
    values = np.sin(3 * x[:, 0]) * x[:, 1]
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for path, limit in (("gouraud", 10**12), ("raster", 0)):
            drawing.RASTER_CELLS = limit
            fig, ax = plt.subplots(figsize=(8.5, 5))
            t0 = time.perf_counter()
            plots.smooth_shading(ax, tri, values, "viridis")
            fig.savefig(Path(tmp) / f"{path}.png", dpi=120)
            out.append(
                {
                    "kernel": "picture",
                    "ranks": 1,
                    "size": len(tri.triangles),
                    "path": path,
                    "seconds": round(time.perf_counter() - t0, 3),
                    "check": "",
                }
            )
            plt.close(fig)
    return out


def refine(cells: int, repeat: int) -> list[dict]:
    comm = MPI.COMM_WORLD
    msh = dmesh.create_unit_square(comm, cells, cells, ghost_mode=dmesh.GhostMode.shared_facet)
    msh.topology.create_entities(1)
    owned = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    marked = owned[dmesh.compute_midpoints(msh, 2, owned)[:, 0] < 0.3]
    edges = dmesh.compute_incident_entities(msh.topology, marked, 2, 1)
    paths = {
        "identity": dmesh.IdentityPartitionerPlaceholder,
        "graph": lambda: dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet, 2),
        "no_ghosts": lambda: None,
    }
    times: dict[str, list[float]] = {name: [] for name in paths}
    balance, size = {}, 0
    for _ in range(repeat):
        for name, partitioner in paths.items():
            new, _, _ = _timed(
                times[name],
                lambda partitioner=partitioner: dmesh.refine(
                    msh,
                    edges,
                    partitioner=partitioner(),
                    option=dmesh.RefinementOption.parent_cell_and_facet,
                ),
            )
            balance[name] = busiest_share(comm, new.topology.index_map(2).size_local)
            size = new.topology.index_map(2).size_global
            del new
    return [
        {
            "kernel": "refine",
            "ranks": comm.size,
            "size": size,
            "path": name,
            "seconds": round(float(np.median(times[name])), 3),
            "check": f"{balance[name]:.3f}",
        }
        for name in paths
    ]


def floor(cells: int, repeat: int) -> list[dict]:
    comm = MPI.COMM_WORLD
    ghosts = dmesh.GhostMode.shared_facet if comm.size > 1 else dmesh.GhostMode.none
    parent = dmesh.create_unit_square(comm, cells, cells, ghost_mode=ghosts)
    parent.topology.create_entities(1)
    options = PETSc.Options()
    for key, value in {**default_options("gamg", 2, comm.size), "ksp_rtol": 1e-8}.items():
        options[f"floor_{key}"] = value
    times: dict[str, list[float]] = {
        name: [] for name in ("refine", "create_mesh", "assembly", "solve")
    }
    its, size = 0, 0
    for _ in range(repeat):
        child, _, _ = _timed(
            times["refine"],
            lambda: dmesh.refine(
                parent,
                None,
                refine_partitioner(parent),
                dmesh.RefinementOption.parent_cell_and_facet,
            ),
        )
        # the input a refinement outside dolfinx would hand over: owned cells by global node
        # index, the owned nodes' coordinates
        nodes = child.geometry.index_map()
        owned = child.topology.index_map(2).size_local
        cells_g = nodes.local_to_global(child.geometry.dofmaps[0][:owned].reshape(-1)).reshape(
            owned, 3
        )
        x, domain = child.geometry.x[: nodes.size_local, :2].copy(), child.ufl_domain()
        del child
        cells_g = cells_g.astype(np.int64, copy=False)
        msh = _timed(
            times["create_mesh"],
            lambda cells_g=cells_g, domain=domain, x=x: dmesh.create_mesh(
                comm, cells_g, domain, x, refine_partitioner(parent)
            ),
        )
        V = fem.functionspace(msh, ("Lagrange", 1))
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        a, L = fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx), fem.form(v * ufl.dx)
        msh.topology.create_connectivity(1, 2)
        bc = fem.dirichletbc(
            0.0, fem.locate_dofs_topological(V, 1, dmesh.exterior_facet_indices(msh.topology)), V
        )
        K, b = _timed(
            times["assembly"], lambda a=a, L=L, bc=bc: P.assemble_system(a, L, [bc])
        )  # -Δu = 1, u = 0 on ∂Ω
        ksp = PETSc.KSP().create(comm)
        ksp.setOptionsPrefix("floor_")
        ksp.setOperators(K)
        ksp.setFromOptions()
        u_h = b.duplicate()
        u_h.set(0.0)
        _timed(times["solve"], lambda ksp=ksp, b=b, u_h=u_h: ksp.solve(b, u_h))
        its, size = ksp.getIterationNumber(), V.dofmap.index_map.size_global
        for obj in (ksp, K, b, u_h):
            obj.destroy()
    median = {name: float(np.median(t)) for name, t in times.items()}
    return [
        {
            "kernel": "floor",
            "ranks": comm.size,
            "size": size,
            "path": name,
            "seconds": round(median[name], 3),
            "check": str(its) if name == "solve" else f"{median[name] / median['solve']:.3f}",
        }
        for name in median
    ]


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--only", choices=("assembly", "picture", "refine", "floor"))
    ap.add_argument(
        "--cells", type=int, default=50, help="assembly: the box's cells per unit length"
    )
    ap.add_argument("--cells-2d", type=int, default=1100, help="picture: cells along x")
    ap.add_argument(
        "--cells-refine", type=int, default=800, help="refine: the square's cells per side"
    )
    ap.add_argument(
        "--cells-floor", type=int, default=555, help="floor: the square's cells per side"
    )
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out", default="demos/results/kernels.csv")
    args = ap.parse_args()
    rows = []
    if args.only in (None, "assembly"):
        rows += assembly(args.cells, args.repeat)
    if args.only in (None, "picture") and MPI.COMM_WORLD.rank == 0:
        rows += picture(args.cells_2d)
    if args.only == "refine":  # a parallel kernel: asked for explicitly, under mpirun
        rows += refine(args.cells_refine, args.repeat)
    if args.only == "floor":  # asked for explicitly, serially and under mpirun
        rows += floor(args.cells_floor, args.repeat)
    if MPI.COMM_WORLD.rank == 0:
        for r in rows:
            check = {
                "assembly": "relative difference",
                "refine": "busiest rank's cells / mean",
                "floor": "over the solve (solve: CG its)",
            }.get(r["kernel"])
            print(
                f"{r['kernel']:9s} {r['ranks']} rank(s) {r['size']:9d} {r['path']:10s} "
                f"{r['seconds']:7.3f} s" + (f"  {check} {r['check']}" if r["check"] else ""),
                flush=True,
            )
    save_csv(args.out, rows)


if __name__ == "__main__":
    main()
