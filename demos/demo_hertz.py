# # Elastic contact: a cylinder on a rigid plane against Hertz theory
#
# An elastic cylinder of radius R (plane strain, Young's modulus E, Poisson's ratio ν) is
# pressed onto a rigid frictionless plane.  Linear elasticity with the Signorini condition
# on the contact surface Γ_C (docs/theory.md §1.3):
#
#     −div σ(u) = 0,   σ(u) = 2μ ε(u) + λ_L tr ε(u) I,
#     u·n ≤ g,   λ_n := σ_nn(u) ≤ 0,   λ_n (u·n − g) = 0,   σ_nt(u) = 0    on Γ_C,
#
# with n the normal towards the plane and g the initial gap.  Hertz's theory
# (docs/theory.md §7) gives, for the force P per unit thickness and E* = E / (1 − ν²), a contact
# strip of half-width a = 2 √(R P / (π E*)) and the pressure p(x) = p0 √(1 − x²/a²),
# p0 = 2P / (π a), valid when a ≪ R.  By symmetry we model the quarter x ≥ 0 of the
# cylinder's lower half: the arc is Γ_C, the flat top is pushed down by δ, and the axis
# x = 0 is a symmetry line.  Everything is plain gmsh, UFL and DOLFINx handed to the core —
# no scene: the problem on a mesh (`build`), the adaptive loop over it (`contact.adapt`),
# the new vertices on the arc put on the circle after each refinement (`Domain.snap`).
# Run it with `python demos/demo_hertz.py [LEVELS]` (default 5 levels; `mpirun -n 2`).

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
ARC, TOP, AXIS = 1, 2, 3  # the facet tags
mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


def sigma(z):  # σ(z) = 2μ ε(z) + λ_L tr ε(z) I
    return 2 * mu * ufl.sym(ufl.grad(z)) + lmbda * ufl.div(z) * ufl.Identity(2)


# ## The mesh: a quarter disk graded towards the point of first contact
if comm.rank == 0:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    occ, field = gmsh.model.occ, gmsh.model.mesh.field
    bottom, centre, corner = (occ.addPoint(*X, 0) for X in ((0, 0), (0, R), (R, R)))
    curves = [occ.addCircleArc(bottom, centre, corner), occ.addLine(corner, centre)]
    curves.append(occ.addLine(centre, bottom))
    body = occ.addPlaneSurface([occ.addCurveLoop(curves)])
    occ.synchronize()
    for tag, curve in zip((ARC, TOP, AXIS), curves):
        gmsh.model.addPhysicalGroup(1, [curve], tag)
    gmsh.model.addPhysicalGroup(2, [body], 10)
    distance, size = field.add("Distance"), field.add("Threshold")
    field.setNumbers(distance, "PointsList", [bottom])
    # h = 0.004 within 0.25 of the first contact point, then growing with slope 0.3 to 0.1
    grading = {"SizeMin": 0.004, "SizeMax": 0.1, "DistMin": 0.25, "DistMax": 0.25 + 0.32}
    for key, value in {"InField": distance, **grading}.items():
        field.setNumber(size, key, value)
    field.setAsBackgroundMesh(size)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.model.mesh.generate(2)
# the estimator's jump terms need the facets between ranks' cells: shared_facet ghosts
ghosts = mesh.create_cell_partitioner(mesh.GhostMode.shared_facet, 2)
data = gmshio.model_to_mesh(gmsh.model if comm.rank == 0 else None, comm, 0, 2, ghosts)
if comm.rank == 0:
    gmsh.finalize()


def snap(parent: contact.Domain, child: contact.Domain) -> None:
    """Move the refined arc's vertices from the chords onto the circle."""
    nodes = np.unique(mesh.entities_to_geometry(child.mesh, 1, child.facets.find(ARC)))
    X = child.mesh.geometry.x[nodes, :2] - [0.0, R]
    child.mesh.geometry.x[nodes, :2] = [0.0, R] + R * X / np.linalg.norm(X, axis=1)[:, None]


def build(domain: contact.Domain) -> contact.ComplementarityProblem:
    """Linear elasticity on the domain's mesh against the plane y = 0."""
    msh, tags = domain.mesh, domain.facets
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    u, v, w = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    f = fem.Constant(msh, np.zeros(2))
    a = ufl.inner(sigma(w), ufl.sym(ufl.grad(v))) * ufl.dx
    top = fem.locate_dofs_topological(V, 1, tags.find(TOP))
    axis = fem.locate_dofs_topological(V.sub(0), 1, tags.find(AXIS))
    bcs = [fem.dirichletbc(np.array([0.0, -delta]), top, V), fem.dirichletbc(0.0, axis, V.sub(0))]
    parts = contact.BoundaryData(tags, dirichlet=(TOP,), symmetry=((AXIS, 0),))
    plane = contact.RigidObstacle(contact.Plane([0.0, 0.0], [0.0, 1.0]), ds(ARC))
    physics = contact.Elasticity(mu, lmbda, f, parts)
    L = ufl.inner(f, v) * ufl.dx
    return contact.ComplementarityProblem.from_forms(a, L, u, plane, bcs, physics=physics)


# ## Solve, estimate, mark, refine: semismooth Newton (Fischer–Burmeister), the residual
# estimator with its contact terms, Dörfler marking, refinement with nested iteration.
run = contact.adapt(
    build, contact.Domain(data.mesh, data.facet_tags, snap=snap), "fb", max_levels=LEVELS
)
if comm.rank == 0:
    print(f"{'level':>5s} {'DoFs':>7s} {'eta':>10s} {'Newton':>6s} {'active':>6s}")
    for k, lv in enumerate(run.levels):
        r = lv.result
        print(f"{k:5d} {r.dofs:7d} {lv.estimate.eta:10.3e} {r.iterations:6d} {r.n_active:6d}")
domain, result = run.levels[-1].domain, run.levels[-1].result

# ## Force balance: the contact force P = Σ_i w_i p_i (both halves) against the reaction on
# the pushed top, a(u_h, w) with w = e_y on the top's DoFs and 0 elsewhere.
V, u_h = result.u_h.function_space, result.u_h
w = fem.Function(V)
w.x.array[2 * fem.locate_dofs_topological(V, 1, domain.facets.find(TOP)) + 1] = 1.0
work = fem.form(ufl.inner(sigma(u_h), ufl.sym(ufl.grad(w))) * ufl.dx)
reaction = -2 * comm.allreduce(fem.assemble_scalar(work), op=MPI.SUM)
P = result.contact_force
if comm.rank == 0:
    print(
        f"\ncontact force P = {P:.6f}, reaction on the top = {reaction:.6f}, "
        f"relative difference {abs(P - reaction) / P:.1e}"
    )

# ## Pressure against Hertz: the nodal pressures −λ_n and gaps on the arc, on rank 0.
W = result.lmbda_h.function_space
dofs = fem.locate_dofs_topological(W, 1, domain.facets.find(ARC))
dofs = dofs[dofs < W.dofmap.index_map.size_local]
nodal = [W.tabulate_dof_coordinates()[dofs, 0], -result.lmbda_h.x.array[dofs]]
rows = comm.gather(np.c_[(*nodal, result.gap.x.array[dofs])], root=0)
if comm.rank == 0:
    x, p, gap = np.concatenate(rows).T
    a_H = 2.0 * np.sqrt(R * P / (np.pi * E / (1.0 - nu**2)))
    p0_H = 2.0 * P / (np.pi * a_H)
    active = gap <= 1e-8 * delta
    a_h = 0.5 * (x[active].max() + x[~active & (x > x[active].max())].min())
    print(
        f"half-width a = {a_h:.5f} (Hertz {a_H:.5f}, {100 * (a_h / a_H - 1):+.2f}%), "
        f"peak pressure p0 = {p.max():.5f} (Hertz {p0_H:.5f}, {100 * (p.max() / p0_H - 1):+.2f}%)"
    )
    fig, ax = plt.subplots(figsize=(7, 4.5))
    keep = x <= 2 * a_H
    ax.plot(x[keep], p[keep], "o", ms=3, label=f"computed −λ_n ({result.dofs} DoFs)")
    xs = np.linspace(0, a_H, 200)
    ax.plot(xs, p0_H * np.sqrt(1 - (xs / a_H) ** 2), "k-", label=f"Hertz: a = {a_H:.4f}")
    ax.set_xlabel("x, distance from the centre of contact (length)")
    ax.set_ylabel("contact pressure −λ_n (stress, units of E)")
    ax.legend(), fig.tight_layout(), fig.savefig("demo_hertz.png", dpi=100)
    print("wrote demo_hertz.png")
