# # Self-contact at finite strain: a rubber ring squeezed until its inner faces touch
#
# A neo-Hookean ring (plane strain, radii 1 and 0.8, E = 1, ν = 0.3) is squeezed by two arcs of
# its outer surface (|x| < 0.24) clamped to plates that close in by 2 × 0.83, more than the
# hole's diameter.  The contact is a dual-mortar pair of two parts of *one* boundary (slave: the
# middle of the upper inner face; master: the lower one) coupled on the current configuration
# X + u, redone at each solution until it is that of the solution itself (`solve_recoupled`,
# Aitken-relaxed).  `python demos/demo_self_contact.py [STEPS]` (default 8; also mpirun -n 2).

import sys

import contact  # before dolfinx
from contact.drivers.recouple import solve_recoupled
from contact.models.mortar import couple
from contact.setup.meshes import ring
from contact.solvers import owned_residual

import matplotlib.pyplot as plt
import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from matplotlib.collections import PolyCollection
from mpi4py import MPI

STEPS = int(sys.argv[1]) if len(sys.argv) > 1 else 8
comm, E, nu, d = MPI.COMM_WORLD, 1.0, 0.3, 0.83
mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
say = print if comm.rank == 0 else lambda *a: None

# ## The ring (96 × 3 cells), its contact parts (facet tags 1 slave, 2 master), the plates
msh = ring(comm, 0.8, 1.0, (96, 3))[0]
hole = lambda x: np.hypot(x[0], x[1]) < 0.81  # noqa: E731
slave = dmesh.locate_entities_boundary(msh, 1, lambda x: hole(x) & (x[1] > 0) & (abs(x[0]) < 0.45))
master = dmesh.locate_entities_boundary(msh, 1, lambda x: hole(x) & (x[1] < 1e-9))
values = np.r_[np.ones(len(slave)), 2 * np.ones(len(master))].astype(np.int32)
tags = dmesh.meshtags(msh, 1, np.r_[slave, master], values)
V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
u, v, u_D = fem.Function(V), ufl.TestFunction(V), fem.Function(V)
bcs = [fem.dirichletbc(u_D, fem.locate_dofs_geometrical(V, lambda x: abs(x[1]) > 0.97))]

# ## The energy Π, the residual R = ∂Π/∂u, the pair; a problem coupled on X + ũ, one solve
F = ufl.Identity(2) + ufl.grad(u)
J, Ic = ufl.det(F), ufl.tr(F.T * F)
Pi = (mu / 2 * (Ic - 2 - 2 * ufl.ln(J)) + lmbda / 2 * ufl.ln(J) ** 2) * ufl.dx
R = ufl.derivative(Pi, u, v)
ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
pair = contact.MortarPair(slave=ds(1), master=ds(2), names=("upper", "lower"))
CP = contact.ComplementarityProblem  # its .problem: what solve_recoupled re-couples


def build(at):  # the problem with the pair coupled on the configuration X + at
    return CP.from_residual(R, u, pair, bcs, energy=Pi, coupled_at=at).problem


def once(problem, guess):  # semismooth Newton (Fischer–Burmeister) from the guess
    u.x.array[:] = u.x.array if guess is None else guess.x.array
    return CP(problem).solve("fb")


# ## The load path: the plates close in, each step from the last one's solution (in u)
for t in np.arange(1, STEPS + 1) / STEPS:
    u_D.interpolate(lambda x, t=t: np.vstack([0 * x[0], -d * t * np.sign(x[1])]))
    result = solve_recoupled(build, once, u.copy())
    assert result.converged, result.reason
    n, k = result.n_active, len(result.couplings)
    say(f"t = {t:.3f}: {n} slave nodes pressed, force {result.contact_force:.2e}, {k} couplings")

# ## Action = reaction: the residual summed over a part is the force the other part exerts on
# it (opposite: Qᵀ hands the slave force to the master nodes); the weighted gaps, coupled anew.
r = fem.assemble_vector(fem.form(R))
r.scatter_reverse(la.InsertMode.add)
force = []
for nodes in (fem.locate_dofs_topological(V, 1, facets) for facets in (slave, master)):
    nodes = nodes[nodes < V.dofmap.index_map.size_local]
    force.append(comm.allreduce(r.array.reshape(-1, 2)[nodes].sum(axis=0)))
gaps = couple(V, pair, bcs[0].dof_indices()[0], displacement=u.x.array).gap
gap = comm.allreduce(gaps.min(initial=1), MPI.MIN)

# ## What you see: a dogbone, the upper inner face pressed onto the lower one (red), the forces
# on both faces opposite to round-off, every weighted gap ≥ −1e-9.  The lobes tilt: the pressed
# walls slide along each other (frictionless), the way the mesh's diagonals lean.
p, on = result.problem, slice(0, result.problem.data.pair_nodes)
pressure = p.pressure(owned_residual(result))[on]  # pressed: > 1e-8 of the largest pressure
top = comm.allreduce(pressure.max(initial=0), MPI.MAX)
pressed = p.constraint.dofs[on][pressure > 1e-8 * top] // 2
x = V.tabulate_dof_coordinates()[:, :2] + u.x.array.reshape(-1, 2)
pieces = comm.gather((x[V.dofmap.list[: msh.topology.index_map(2).size_local]], x[pressed]))
if comm.rank == 0:
    balance = np.linalg.norm(force[0] + force[1]) / np.linalg.norm(force[0])
    print(f"force on the slave part {force[0]}, on the master part {force[1]}")
    print(f"action = reaction to {balance:.1e}; smallest weighted gap {gap:.1e}")
    fig, ax = plt.subplots(figsize=(8, 4))
    for triangles, contact_nodes in pieces:
        ax.add_collection(PolyCollection(triangles, fc="0.85", ec="0.4", lw=0.3))
        ax.plot(*contact_nodes.T, "o", color="tab:red", ms=3)
    ax.set(aspect="equal", xlim=(-1.3, 1.3), ylim=(-0.6, 0.6), title="red: slave nodes in contact")
    fig.tight_layout(), fig.savefig("demo_self_contact.png", dpi=100)
    print("wrote demo_self_contact.png")
