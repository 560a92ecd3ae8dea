# # Bring your own forms: a soap film over an obstacle
#
# A soap film spans the wire frame ∂Ω, Ω = (0, 1)², at height 0 and is pushed up by a dome
# ψ = 0.2 − 2|x − x₀|².  Its height u minimizes the area ∫ √(1 + |∇u|²) dx over u ≥ ψ: the
# minimal surface obstacle problem, a PDE `contact` does not ship.  Its residual
#
#     F(u; v) = ∫ ∇u·∇v / √(1 + |∇u|²) dx
#
# is nonlinear in u.  Written in plain UFL, it is all `contact.ComplementarityProblem`
# needs: semismooth Newton re-assembles F and its derivative J = ∂F/∂u at every iterate and
# solves F(u_h; φ_i) = w_i λ_i, u_i ≥ ψ_i, λ_i ≥ 0, (u_i − ψ_i) λ_i = 0 at the nodes
# (w_i = ∫ φ_i dx): λ_h is the force density the dome exerts.  Run it with
# `python demos/demo_own_forms.py [N]` (N × N cells, default 32; also under `mpirun -n 2`).

import sys

import contact  # before dolfinx

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

N = int(sys.argv[1]) if len(sys.argv) > 1 else 32
comm = MPI.COMM_WORLD
msh = mesh.create_unit_square(comm, N, N)
V = fem.functionspace(msh, ("Lagrange", 1))
frame = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
bc = fem.dirichletbc(0.0, fem.locate_dofs_topological(V, 1, frame), V)


def dome(x):
    return 0.2 - 2.0 * ((x[0] - 0.5) ** 2 + (x[1] - 0.5) ** 2)


# ## One problem, five solvers
#
# Each solve starts from the flat film u = 0 (the Function's values are the initial guess
# and receive the solution): semismooth Newton on the NCP functions fb, min and blend, and
# PETSc's VI solvers as the reference.  The constraint u ≥ ψ holds in Ω (`ufl.dx`, the
# default); `Unilateral(g, measure=ds(tag))` would put u ≤ g on tagged facets instead.
solutions = {}
for method in ("vinewtonrsls", "fb", "min", "blend", "vinewtonssls"):
    u, v = fem.Function(V, name="u"), ufl.TestFunction(V)
    F = ufl.inner(ufl.grad(u), ufl.grad(v)) / ufl.sqrt(1 + ufl.grad(u) ** 2) * ufl.dx
    with contact.ComplementarityProblem.from_residual(
        F, u, contact.Unilateral(dome, side="lower"), [bc]
    ) as problem:
        r = problem.solve(method, rtol=1e-12)
        solutions[method] = u.x.array.copy()
    if comm.rank == 0:
        print(
            f"{method:>12s}: {r.iterations:3d} Newton iterations, {r.reason}, {r.n_active} nodes "
            f"on the dome, its force ∫ λ_h = {r.contact_force:.6f}"
        )

# ## The same discrete solution
diff = max(
    comm.allreduce(float(np.max(np.abs(s - solutions["vinewtonrsls"]))), op=MPI.MAX)
    for s in solutions.values()
)
if comm.rank == 0:
    print(f"largest difference from vinewtonrsls: {diff:.2e}")
