"""Run by tests/test_adaptive.py (serial and under mpirun): what refinement carries to the
child mesh, with both partitioners of contact.adaptivity.refine.refine_partitioner (children kept on
their parent's rank, or redistributed by dolfinx's graph partitioner):

* contact.adaptivity.transfer.prolong (parent-cell evaluation on the creating rank) against
dolfinx's
  interpolate_nonmatching (point search), scalar P1, P2 and vector P1;
* facet tags (the four sides, 1…4) and cell tags (left half 1, right half 2) measured on
  the child: each side has length 1, each half area 1/2.

Prints the largest difference of each."""

import contact  # noqa: F401  (dolfinx_solver first)
from contact.adaptivity.refine import refine_partitioner
from contact.adaptivity.transfer import prolong, transfer_cell_tags, transfer_facet_tags

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

comm = MPI.COMM_WORLD
msh = mesh.create_unit_square(comm, 12, 9, ghost_mode=mesh.GhostMode.shared_facet)
msh.topology.create_entities(1)
msh.topology.create_connectivity(2, 1)
n = msh.topology.index_map(2).size_local
mid = mesh.compute_midpoints(msh, 2, np.arange(n, dtype=np.int32))
cells = np.flatnonzero(mid[:, 0] + 0.5 * mid[:, 1] < 0.6).astype(np.int32)  # refine a corner region
edges = mesh.compute_incident_entities(msh.topology, cells, 2, 1)
sides = [
    lambda x: np.isclose(x[0], 0),
    lambda x: np.isclose(x[0], 1),
    lambda x: np.isclose(x[1], 0),
    lambda x: np.isclose(x[1], 1),
]
facets = [mesh.locate_entities_boundary(msh, 1, side) for side in sides]
indices = np.concatenate(facets)
values = np.concatenate([np.full(len(f), k + 1, dtype=np.int32) for k, f in enumerate(facets)])
order = np.argsort(indices)
facet_tags = mesh.meshtags(msh, 1, indices[order], values[order])
all_cells = np.arange(n + msh.topology.index_map(2).num_ghosts, dtype=np.int32)
cell_tags = mesh.meshtags(
    msh,
    2,
    all_cells,
    np.where(mesh.compute_midpoints(msh, 2, all_cells)[:, 0] < 0.5, 1, 2).astype(np.int32),
)


def measure(form):
    return comm.allreduce(fem.assemble_scalar(fem.form(form)), op=MPI.SUM)


for name, rebalance in (("identity", False), ("graph", True)):
    new, parent_cell, parent_facet = mesh.refine(
        msh,
        edges,
        partitioner=refine_partitioner(msh, rebalance),
        option=mesh.RefinementOption.parent_cell_and_facet,
    )
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
        ref.interpolate_nonmatching(
            u, allc, fem.create_interpolation_data(ref.function_space, V, allc)
        )
        worst = max(
            worst, comm.allreduce(float(np.max(np.abs(fast.x.array - ref.x.array))), op=MPI.MAX)
        )
    new.topology.create_connectivity(1, 2)
    ft = transfer_facet_tags(facet_tags, new, parent_cell, parent_facet)
    ds = ufl.Measure("ds", domain=new, subdomain_data=ft)
    side_error = max(abs(measure(1.0 * ds(k)) - 1.0) for k in (1, 2, 3, 4))
    ct = transfer_cell_tags(cell_tags, new, parent_cell)
    dx = ufl.Measure("dx", domain=new, subdomain_data=ct)
    half_error = max(abs(measure(1.0 * dx(k)) - 0.5) for k in (1, 2))
    cells_here = comm.allgather(new.topology.index_map(2).size_local)
    if comm.rank == 0:
        print(
            f"{name}: max difference {worst:.3e} sides {side_error:.3e} halves {half_error:.3e} "
            f"cells per rank {cells_here}"
        )
