# # Elastic contact: a cylinder on a rigid plane against Hertz theory
#
# An elastic cylinder (radius R, plane strain, E, ν) pressed onto a rigid frictionless plane
# (docs/theory.md §1.3) against Hertz (§7): for the force P per unit thickness, E* = E / (1 − ν²),
# a = 2 √(R P / (π E*)), p(x) = p0 √(1 − x²/a²), p0 = 2P / (π a).  The quarter x ≥ 0 of the lower
# half in gmsh, UFL and DOLFINx, no scene: `python demos/demo_hertz.py [LEVELS]` (default 5).

import sys

import contact  # before dolfinx

import gmsh
import matplotlib.pyplot as plt
import numpy as np
import ufl
from dolfinx import fem, mesh
from dolfinx.io import gmsh as gmshio
from mpi4py import MPI

LEVELS = int(sys.argv[1]) if len(sys.argv) > 1 else 5
comm = MPI.COMM_WORLD
R, E, nu, delta = 1.0, 1.0, 0.3, 0.014
ARC, TOP, AXIS = 1, 2, 3  # facet tags
mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


def sigma(z):  # σ(z) = 2μ ε(z) + λ_L tr ε(z) I
    return 2 * mu * ufl.sym(ufl.grad(z)) + lmbda * ufl.div(z) * ufl.Identity(2)


# ## The mesh: a quarter disk, h = 0.004 at the point of first contact, 0.1 at the others
if comm.rank == 0:
    gmsh.initialize(), gmsh.option.setNumber("General.Terminal", 0)
    occ = gmsh.model.occ
    o, c, k = (occ.addPoint(x, y, 0, h) for x, y, h in ((0, 0, 0.004), (0, R, 0.1), (R, R, 0.1)))
    loop = [occ.addCircleArc(o, c, k), occ.addLine(k, c), occ.addLine(c, o)]
    occ.addPlaneSurface([occ.addCurveLoop(loop)]), occ.synchronize()
    for tag, curve in zip((ARC, TOP, AXIS), loop):
        gmsh.model.addPhysicalGroup(1, [curve], tag)
    gmsh.model.addPhysicalGroup(2, [1], 1), gmsh.model.mesh.generate(2)
ghosts = mesh.create_cell_partitioner(mesh.GhostMode.shared_facet, 2)  # the estimator's jumps
data = gmshio.model_to_mesh(gmsh.model if comm.rank == 0 else None, comm, 0, 2, ghosts)
gmsh.finalize() if comm.rank == 0 else None


def snap(parent: contact.Domain, child: contact.Domain) -> None:  # new arc vertices: on the circle
    nodes = np.unique(mesh.entities_to_geometry(child.mesh, 1, child.facets.find(ARC)))
    X = child.mesh.geometry.x[nodes, :2] - [0.0, R]
    child.mesh.geometry.x[nodes, :2] = [0.0, R] + R * X / np.linalg.norm(X, axis=1)[:, None]


def build(domain: contact.Domain) -> contact.ComplementarityProblem:
    """−div σ(u) = 0 in Ω; on the arc u·n ≤ g, λ_n ≤ 0, λ_n (u·n − g) = 0 (n = −e_y)."""
    msh, tags = domain.mesh, domain.facets
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    u, v, w = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    ds, f = ufl.Measure("ds", domain=msh, subdomain_data=tags), fem.Constant(msh, np.zeros(2))
    top = fem.locate_dofs_topological(V, 1, tags.find(TOP))  # pushed down by δ
    axis = fem.locate_dofs_topological(V.sub(0), 1, tags.find(AXIS))  # x = 0: symmetry, u_x = 0
    bcs = [fem.dirichletbc(np.array([0.0, -delta]), top, V), fem.dirichletbc(0.0, axis, V.sub(0))]
    plane = contact.RigidObstacle(contact.Plane([0.0, 0.0], [0.0, 1.0]), ds(ARC))
    parts = contact.BoundaryData(tags, dirichlet=(TOP,), symmetry=((AXIS, 0),))
    physics = contact.Elasticity(mu, lmbda, f, parts)  # the equations the estimator checks
    a, L = ufl.inner(sigma(w), ufl.sym(ufl.grad(v))) * ufl.dx, ufl.inner(f, v) * ufl.dx
    return contact.ComplementarityProblem.from_forms(a, L, u, plane, bcs, physics=physics)


# ## Solve, estimate, mark, refine: Newton on Fischer–Burmeister, residual estimator, Dörfler
domain = contact.Domain(data.mesh, data.facet_tags, snap=snap)
run = contact.adapt(build, domain, "fb", max_levels=LEVELS)
domain, result = run.levels[-1].domain, run.levels[-1].result
u_h, lmbda_h, P = result.u_h, result.lmbda_h, result.contact_force  # P = Σ_i w_i p_i (×2)

# ## Force balance: P against the top's reaction a(u_h, z), z = e_y at its nodes (×2: halves)
V, z = u_h.function_space, fem.Function(u_h.function_space)
z.x.array[2 * fem.locate_dofs_topological(V, 1, domain.facets.find(TOP)) + 1] = 1.0
work = fem.assemble_scalar(fem.form(ufl.inner(sigma(u_h), ufl.sym(ufl.grad(z))) * ufl.dx))
reaction = -2 * comm.allreduce(work)

# ## Pressure against Hertz: the nodal pressures −λ_n and gaps (NaN off the arc), on rank 0.
# You see η falling, P equal to the reaction, and −λ_n on Hertz's ellipse (demo_hertz.png).
X, n = lmbda_h.function_space.tabulate_dof_coordinates(), lmbda_h.x.index_map.size_local
rows = comm.gather(np.c_[X[:n, 0], -lmbda_h.x.array[:n], result.gap.x.array[:n]])
if comm.rank == 0:
    for lv in run.levels:
        print(f"level {lv.index}: {lv.result.dofs} DoFs, η = {lv.estimate.eta:.2e}")
    print(f"P = {P:.6f}, reaction {reaction:.6f}: relative difference {abs(P - reaction) / P:.1e}")
    x, p, gap = np.concatenate(rows).T
    a_H = 2 * np.sqrt(R * P / (np.pi * E / (1 - nu**2)))
    p0_H, p0_h, edge = 2 * P / (np.pi * a_H), p.max(), x[gap <= 1e-8 * delta].max()
    a_h = 0.5 * (edge + x[(gap > 1e-8 * delta) & (x > edge)].min())  # last active and next
    print(f"half-width a = {a_h:.5f} (Hertz {a_H:.5f}, {100 * (a_h / a_H - 1):+.2f}%), ", end="")
    print(f"peak pressure p0 = {p0_h:.5f} (Hertz {p0_H:.5f}, {100 * (p0_h / p0_H - 1):+.2f}%)")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(x[gap >= -delta], p[gap >= -delta], "o", ms=3, label=f"−λ_n ({result.dofs} DoFs)")
    ax.plot(xs := np.linspace(0, a_H), p0_H * np.sqrt(1 - (xs / a_H) ** 2), "k-", label="Hertz")
    ax.set(xlim=(0, 2 * a_H), xlabel="x (length)", ylabel="contact pressure −λ_n (units of E)")
    ax.legend(), fig.tight_layout(), fig.savefig("demo_hertz.png", dpi=100)
    print("wrote demo_hertz.png")
