"""Serially or under mpirun: the snap's collapse check restricted to the touched cells finds the
same cells as the full check on every rank (ghosts excluded), for the bottom row of an 8 × 8
square moved up to each height given; prints {height: global count} as JSON on rank 0."""

import json
import sys

import contact  # noqa: F401  (must precede dolfinx)
from contact.setup.geometry import cells_touching, collapsed_cells, signed_volumes

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

counts = {}
for height in map(float, sys.argv[1:]):
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 8, 8, ghost_mode=dmesh.GhostMode.shared_facet)
    x = msh.geometry.x
    moved = np.isclose(x[:, 1], 0.0)
    touched = cells_touching(msh, moved.astype(float))
    n_local = msh.topology.index_map(2).size_local + msh.topology.index_map(2).num_ghosts
    # a proper, nonempty subset
    if len(touched) >= n_local or MPI.COMM_WORLD.allreduce(len(touched)) == 0:
        raise SystemExit(f"rank {MPI.COMM_WORLD.rank}: {len(touched)} of {n_local} cells touched")
    before_all, before_touched = signed_volumes(msh), signed_volumes(msh, touched)
    x[moved, 1] = height
    bad_all, n_all = collapsed_cells(msh, before_all)
    bad_touched, n_touched = collapsed_cells(msh, before_touched, cells=touched)
    if not np.array_equal(np.sort(bad_all), np.sort(bad_touched)) or n_all != n_touched:
        raise SystemExit(f"rank {MPI.COMM_WORLD.rank}, height {height}: {bad_all} != {bad_touched}")
    counts[height] = n_touched
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(counts))
