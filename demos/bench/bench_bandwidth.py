"""What more MPI ranks can give on this machine: memory-bound kernels, serial against N ranks.

What it shows: the solver's work is sparse matrix–vector products and vector updates,
which stream memory; their speed-up from 1 to N ranks is bounded by the memory bandwidth
the cores share, whatever the code does.  The script times 100 products with the P1
stiffness matrix of the unit square at ``--cells``² cells (1.05M DoFs by default) and 20
scalings of a 20M-entry array split over the ranks.  Run it serially and under mpirun; the
ratio of the two runs' times is the ceiling of a parallel speed-up of the solver's kernels.
The machine is shared and its speed drifts by tens of per cent within minutes, so each
run times ``--repeat`` rounds and reports the fastest (the ceiling) and the median.

    python demos/bench/bench_bandwidth.py --out demos/results/bandwidth.csv
    mpirun -n 2 python demos/bench/bench_bandwidth.py --out demos/results/bandwidth.csv

Each run adds its row to ``--out`` (ranks, DoFs, repeats, the fastest and the median
seconds of the products and of the scalings).
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import dolfinx_solver  # noqa: F401  (before dolfinx / petsc4py with the solver wheel)

import dolfinx.fem.petsc
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cells", type=int, default=1024)
    ap.add_argument(
        "--repeat", type=int, default=7, help="rounds timed (fastest and median reported)"
    )
    ap.add_argument("--out", default="demos/results/bandwidth.csv")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    msh = dmesh.create_unit_square(comm, args.cells, args.cells)
    V = fem.functionspace(msh, ("Lagrange", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    K = dolfinx.fem.petsc.assemble_matrix(fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx))
    K.assemble()
    x, y = K.createVecRight(), K.createVecLeft()
    x.set(1.0)
    a = np.random.default_rng(comm.rank).random(20_000_000 // comm.size)
    b = np.empty_like(a)
    K.mult(x, y)  # warm up
    products, scalings = [], []
    for _ in range(args.repeat):
        comm.Barrier()
        t0 = time.perf_counter()
        for _ in range(100):
            K.mult(x, y)
        comm.Barrier()
        t1 = time.perf_counter()
        for _ in range(20):
            np.multiply(a, 1.0001, out=b)
        comm.Barrier()
        products.append(t1 - t0)
        scalings.append(time.perf_counter() - t1)
    row = {
        "ranks": comm.size,
        "dofs": K.getSize()[0],
        "repeat": args.repeat,
        "matvec_100_s": round(min(products), 4),
        "array_scale_20_s": round(min(scalings), 4),
        "matvec_100_median_s": round(float(np.median(products)), 4),
        "array_scale_20_median_s": round(float(np.median(scalings)), 4),
    }
    if comm.rank == 0:
        print(
            f"{comm.size} rank(s), {row['dofs']} DoFs, fastest (median) of {args.repeat}: 100 "
            f"products "
            f"{row['matvec_100_s']:.3f} s ({row['matvec_100_median_s']:.3f} s), 20 scalings of "
            f"20M entries "
            f"{row['array_scale_20_s']:.3f} s ({row['array_scale_20_median_s']:.3f} s)",
            flush=True,
        )
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        new = not out.exists()
        with open(out, "a", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(row))
            if new:
                w.writeheader()
            w.writerow(row)
        print(f"added a row to {out}", flush=True)


if __name__ == "__main__":
    main()
