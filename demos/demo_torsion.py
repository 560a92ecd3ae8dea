# # Elastic–plastic torsion of a square bar: your own forms, sequenced and adapted
#
# A bar of square cross-section Ω = (−1, 1)² is twisted by θ per unit length.  Prandtl's
# stress function φ gives the shear stresses τ = (∂φ/∂y, −∂φ/∂x); elastically −Δφ = 2Gθ in Ω,
# φ = 0 on ∂Ω.  A perfectly plastic material caps the shear stress, |∇φ| ≤ k, and on a convex
# section with a constant load this gradient constraint is the obstacle problem
#
#     −Δφ ≤ c,  φ ≤ d(x),  (c + Δφ)(d − φ) = 0,   d = k·dist(x, ∂Ω) = 1 − max(|x|, |y|),
#
# (Brezis and Sibony, 1971) with c = 2Gθ/k: the plastic zone is where φ touches d.  The torque
# is T = 2 ∫ φ dx, between the elastic solution's and the fully plastic T_p = 2 ∫ d dx = 8/3.
# `contact` ships no torsion model: the forms below are plain UFL, and the core gives them grid
# sequencing, the guaranteed estimator and the adaptive loop, given the equations they
# discretise (`contact.Diffusion`, which the estimators read).  Run it with
# `python demos/demo_torsion.py [N]` (finest uniform mesh N × N, default 64; `mpirun -n 2`).

import sys

import contact  # before dolfinx

import matplotlib.pyplot as plt
import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

N = int(sys.argv[1]) if len(sys.argv) > 1 else 64
comm = MPI.COMM_WORLD
C = 4.0  # 2Gθ/k: well past first yield (c ≈ 1.48), short of the fully plastic bar


def square(n: int) -> mesh.Mesh:  # Ω = (−1, 1)², n × n cells
    return mesh.create_rectangle(comm, [[-1.0, -1.0], [1.0, 1.0]], [n, n])


def build(msh: mesh.Mesh) -> contact.ComplementarityProblem:
    """The torsion problem on any mesh of the square: −Δφ = c, φ = 0 on ∂Ω, φ ≤ d."""
    V = fem.functionspace(msh, ("Lagrange", 1))
    phi, v, w = fem.Function(V, name="phi"), ufl.TestFunction(V), ufl.TrialFunction(V)
    x, c, one = ufl.SpatialCoordinate(msh), fem.Constant(msh, C), fem.Constant(msh, 1.0)
    edge = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
    bc = fem.dirichletbc(0.0, fem.locate_dofs_topological(V, 1, edge), V)
    boundary = contact.BoundaryData(mesh.meshtags(msh, 1, np.sort(edge), 1), dirichlet=(1,))
    d = 1.0 - ufl.max_value(abs(x[0]), abs(x[1]))  # k·dist(x, ∂Ω), as UFL
    a, L = ufl.inner(ufl.grad(w), ufl.grad(v)) * ufl.dx, c * v * ufl.dx
    return contact.ComplementarityProblem.from_forms(
        a, L, phi, contact.Unilateral(d), [bc], physics=contact.Diffusion(one, c, boundary)
    )


def torque(phi: fem.Function) -> float:
    return comm.allreduce(fem.assemble_scalar(fem.form(2 * phi * ufl.dx)), op=MPI.SUM)


# ## Grid sequencing: Newton iterations independent of the mesh
#
# From φ = 0 semismooth Newton moves the free boundary a few cells per iteration, so a cold
# start needs more iterations the finer the mesh.  `contact.sequence(build, meshes)` solves
# the coarser meshes first and starts each finer one from the coarser solution.
if comm.rank == 0:
    print("     N  cold start  sequenced     torque T_h")
n = 16
while n <= N:
    with build(square(n)) as problem:
        cold = problem.solve("fb")
    sizes = [m for m in (16, 32, 64, 128, 256, 512) if m <= n]
    problem, seq = contact.sequence(build, [square(m) for m in sizes], "fb")
    T = torque(seq.u_h)
    problem.close()
    if comm.rank == 0:
        print(f"{n:6d} {cold.iterations:11d} {seq.iterations:10d} {T:14.8f}")
    n *= 2

# ## The adaptive loop with a guaranteed bound
#
# `contact.adapt(build, mesh, kind="equilibrated")` solves, estimates ‖∇(φ − φ_h)‖ ≤ η by an
# equilibrated flux (guaranteed: no unknown constant), marks by Dörfler and refines; each
# level starts from the previous solution.  Refinement follows the elastic–plastic
# interface, where the solution's second derivatives jump.
rows: list[tuple[int, float, float]] = []  # each level's DoFs, η and torque, once solved
run = contact.adapt(
    build,
    square(8),
    kind="equilibrated",
    theta=0.5,
    max_levels=9,
    on_level=lambda lv: rows.append((lv.result.dofs, lv.estimate.eta, torque(lv.result.u_h))),
)
dofs, eta, T = (np.array(col) for col in zip(*rows))
if comm.rank == 0:
    print("\nlevel    DoFs   guaranteed η     torque T_h     T_h − T_prev")
    for k, (n_k, e, t) in enumerate(rows):
        print(f"{k:5d} {n_k:7d} {e:14.4e} {t:14.8f}    " + (f"{t - T[k - 1]:.2e}" if k else ""))
    print(f"adaptive loop: {run.stop}; T_h = {T[-1]:.6f} < T_p = {8 / 3:.6f}")
    fig, ax = plt.subplots(figsize=(5, 3.6))
    ax.loglog(dofs, eta, "o-", label="guaranteed η ≥ ‖∇(φ − φ_h)‖")
    ax.loglog(dofs[1:], np.abs(np.diff(T)), "s-", label="|T_h − T_prev| (the torque)")
    ax.set_xlabel("DoFs"), ax.legend(), fig.tight_layout()
    fig.savefig("demo_torsion.png", dpi=120)
    print("wrote demo_torsion.png")
