"""Run by tests/test_adaptive.py (serial and under mpirun): contact.adapt.prolong (parent-cell
evaluation) against dolfinx's interpolate_nonmatching (point search) after a local
refinement, for scalar P1, P2 and vector P1; prints the largest difference."""
import numpy as np
from mpi4py import MPI

import contact  # noqa: F401  (dolfinx_solver first)
import ufl
from dolfinx import fem, mesh
from contact.adapt import prolong

comm = MPI.COMM_WORLD
msh = mesh.create_unit_square(comm, 12, 9, ghost_mode=mesh.GhostMode.shared_facet)
msh.topology.create_entities(1)
n = msh.topology.index_map(2).size_local
mid = mesh.compute_midpoints(msh, 2, np.arange(n, dtype=np.int32))
cells = np.flatnonzero(mid[:, 0] + 0.5 * mid[:, 1] < 0.6).astype(np.int32)  # refine a corner region
edges = mesh.compute_incident_entities(msh.topology, cells, 2, 1)
new, parent_cell, _ = mesh.refine(msh, edges, option=mesh.RefinementOption.parent_cell)
worst = 0.0
for element in (("Lagrange", 1), ("Lagrange", 2), ("Lagrange", 1, (2,))):
    V = fem.functionspace(msh, element)
    u = fem.Function(V)
    if V.dofmap.index_map_bs == 1:
        u.interpolate(lambda x: np.sin(3 * x[0]) * np.exp(x[1]))
    else:
        u.interpolate(lambda x: np.vstack([np.sin(3 * x[0]), x[0] * x[1] ** 2]))
    fast = prolong(u, new, parent_cell)
    ref = fem.Function(fast.function_space)
    nc = new.topology.index_map(2).size_local + new.topology.index_map(2).num_ghosts
    allc = np.arange(nc, dtype=np.int32)
    ref.interpolate_nonmatching(u, allc, fem.create_interpolation_data(ref.function_space, V, allc))
    worst = max(worst, comm.allreduce(float(np.max(np.abs(fast.x.array - ref.x.array))), op=MPI.MAX))
if comm.rank == 0:
    print(f"max difference {worst:.3e}")
