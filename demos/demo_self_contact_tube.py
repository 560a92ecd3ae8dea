# # Self-contact in 3D: a rubber tube pinched until its inner walls touch
#
# A neo-Hookean tube (radii 1 and 0.8, E = 1, ν = 0.3) is pinched by two plates of half-length
# 0.5 that close in by 2 × 0.83, more than the hole's diameter: under the plates the upper inner
# wall is pressed onto the lower one, beyond them the tube stays open.  The shipped scene
# `configs/hyperelastic_self_contact_tube.yaml` models a quarter (the symmetry planes x = 0 and
# z = 0); its pair — the middle of the upper inner face (slave) against the lower one (master),
# two parts of one boundary — is coupled on the current configuration X + u and re-coupled to
# its fixed point at every load step.  In the reference configuration no slave normal meets
# the master (they point at the axis, across the symmetry plane): those nodes are out of
# contact until the walls flatten.  `python demos/demo_self_contact_tube.py [STEPS]` (default
# 8; also mpirun -n 2).

import sys
from pathlib import Path

import contact  # before dolfinx
from contact.models.mortar import part_facets, surface_facets
from contact.solvers import owned_residual

import matplotlib.pyplot as plt
import numpy as np
from dolfinx import fem, la
from matplotlib.collections import PolyCollection
from mpi4py import MPI

STEPS = int(sys.argv[1]) if len(sys.argv) > 1 else 8
SCENE = Path(__file__).resolve().parents[1] / "configs" / "hyperelastic_self_contact_tube.yaml"
comm = MPI.COMM_WORLD
say = print if comm.rank == 0 else lambda *a: None

# ## The load path of the scene, step by step
scene = contact.load_scene(SCENE, ["output.verbose=false", f"load.steps={STEPS}"])
run = contact.run_load_path(scene, verbose=False)
assert run.converged
for step in run.steps:
    r = step.result
    say(f"t = {step.time:.3f}: {r.n_active} slave nodes pressed, force {r.contact_force:.2e}")

# ## Action = reaction along y: the residual summed over a part is the force the other part
# exerts on it (along x and z the symmetry planes' reactions at the parts' nodes add to it)
result = run.steps[-1].result
p, V = result.problem, result.problem.V
res = fem.assemble_vector(p.data.reaction_form)
res.scatter_reverse(la.InsertMode.add)
force = []
for part in ("inner_top", "inner_bottom"):
    nodes = np.unique(surface_facets(V, part_facets(scene.boundary, part)).nodes)
    nodes = nodes[nodes < V.dofmap.index_map.size_local]
    force.append(comm.allreduce(res.array.reshape(-1, 3)[nodes].sum(axis=0)))

# ## What you see: the mid-section z = 0 flattened into a dogbone (mirrored to the whole
# section) and, from above, the pressure on the slave face: the contact zone ends where the
# plates end (z = 0.5), widest at the mid-plane.
u = result.u_h.x.array
section = surface_facets(V, part_facets(scene.boundary, "sym_z"), u).X[:, :, :2]
on = slice(0, p.data.pair_nodes)
X = V.tabulate_dof_coordinates()[p.constraint.dofs[on] // 3]
pressure = p.pressure(owned_residual(result))[on]
pieces = comm.gather((section, X, pressure))
if comm.rank == 0:
    fy = force[0][1]
    print(f"y-force on the slave part {fy:.6e}, on the master part {force[1][1]:.6e}")
    print(f"action = reaction along y to {abs(fy + force[1][1]) / abs(fy):.1e}")
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    for triangles, nodes, lam in pieces:
        for sign in (1, -1):  # the mirror image in the plane x = 0
            mirrored = triangles * np.array([sign, 1])
            left.add_collection(PolyCollection(mirrored, fc="0.85", ec="0.4", lw=0.3))
            shown = right.scatter(sign * nodes[:, 0], nodes[:, 2], c=lam, cmap="Reds", vmin=0)
    left.set(aspect="equal", xlim=(-1.4, 1.4), ylim=(-0.7, 0.7), title="mid-section z = 0")
    right.set(aspect="equal", xlabel="x (reference)", ylabel="z (reference)")
    right.set_title("pressure on the upper inner wall")
    fig.colorbar(shown, ax=right)
    fig.tight_layout(), fig.savefig("demo_self_contact_tube.png", dpi=100)
    print("wrote demo_self_contact_tube.png")
