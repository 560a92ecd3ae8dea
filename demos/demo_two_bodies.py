# # Two elastic cylinders in contact: a mortar pair on your own forms
#
# Two identical cylinders (radius R, plane strain, E, ν), meshed independently, are pressed
# together: the top of the upper one moves down by δ, the bottom of the lower one is fixed.
# Dual mortar (docs/theory.md §1.5): with D_ii = ∫ φ_i ds and M_ij = ∫ ψ_i (φ_j^m ∘ π) ds on
# the slave surface (ψ_i the dual basis, π the projection onto the master surface), slave node
# i may not penetrate, x_i = n_i · (u_i − Σ_j M_ij u_j^m / D_ii) ≤ g_i: one bound per node
# after a change of basis u = Q x.  We model x ≥ 0 in plain gmsh, UFL and DOLFINx, no scene:
# `python demos/demo_two_bodies.py [H]` (the mesh size at the contact, default 0.02).

import sys

import contact  # before dolfinx
from contact.models.mortar import master_pressure

import gmsh
import matplotlib.pyplot as plt
import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx.io import gmsh as gmshio
from mpi4py import MPI

H = float(sys.argv[1]) if len(sys.argv) > 1 else 0.02
comm = MPI.COMM_WORLD
R, E, nu, delta = 8.0, 200.0, 0.3, 0.1
SLAVE, TOP, MASTER, BOTTOM, AXIS = 1, 2, 3, 4, 5  # facet tags
mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))

# ## The mesh: two quarter disks touching at the origin (h = H there, 1 far away), each arc
# split where its contact surface ends: the master surface reaches past the slave one.
if comm.rank == 0:
    gmsh.initialize(), gmsh.option.setNumber("General.Terminal", 0)
    occ, axes = gmsh.model.occ, []
    for s, reach, arc, flat in ((1, 2.0, SLAVE, TOP), (-1, 3.0, MASTER, BOTTOM)):
        o, c, k = (occ.addPoint(x, s * y, 0, h) for x, y, h in ((0, 0, H), (0, R, 1), (R, R, 1)))
        split = occ.addPoint(reach, s * (R - np.sqrt(R**2 - reach**2)), 0, 4 * H)
        loop = [occ.addCircleArc(o, c, split), occ.addCircleArc(split, c, k)]
        loop += [occ.addLine(k, c), occ.addLine(c, o)]
        occ.addPlaneSurface([occ.addCurveLoop(loop)]), occ.synchronize(), axes.append(loop[3])
        for tag, curve in ((arc, loop[0]), (flat, loop[2])):
            gmsh.model.addPhysicalGroup(1, [curve], tag)
    gmsh.model.addPhysicalGroup(1, axes, AXIS), gmsh.model.addPhysicalGroup(2, [1, 2], 1)
    gmsh.model.mesh.generate(2)
data = gmshio.model_to_mesh(gmsh.model if comm.rank == 0 else None, comm, 0, 2)
gmsh.finalize() if comm.rank == 0 else None
msh, tags = data.mesh, data.facet_tags

# ## Linear elasticity on both bodies, a(w, v) = ∫ σ(w) : ε(v) dx with σ(w) = 2μ ε(w) +
# λ_L tr ε(w) I, the mortar pair coupling them (slave: the upper arc), solved by semismooth
# Newton on the Fischer–Burmeister function.
V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
u_h, v, w = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
e, ds = ufl.sym(ufl.grad(w)), ufl.Measure("ds", domain=msh, subdomain_data=tags)
a = ufl.inner(2 * mu * e + lmbda * ufl.tr(e) * ufl.Identity(2), ufl.sym(ufl.grad(v))) * ufl.dx
L = ufl.inner(fem.Constant(msh, np.zeros(2)), v) * ufl.dx
top, bottom = (fem.locate_dofs_topological(V, 1, tags.find(t)) for t in (TOP, BOTTOM))
axis = fem.locate_dofs_topological(V.sub(0), 1, tags.find(AXIS))
bcs = [fem.dirichletbc(np.array([0.0, -delta]), top, V), fem.dirichletbc(0.0, axis, V.sub(0))]
bcs.append(fem.dirichletbc(np.zeros(2), bottom, V))
pair = contact.MortarPair(slave=ds(SLAVE), master=ds(MASTER), names=("upper", "lower"))
problem = contact.ComplementarityProblem.from_forms(a, L, u_h, pair, bcs)
result = problem.solve("fb")
lmbda_h, P = result.lmbda_h, 2 * result.contact_force  # P = Σ_i D_ii λ_i, ×2: both halves

# ## Action = reaction: the residual r_i = a(u_h, φ_i) is the force the rest of the world
# exerts at node i; its vertical part summed over each surface (×2).
r, F = fem.assemble_vector(fem.form(ufl.action(a, u_h))), {}
r.scatter_reverse(la.InsertMode.add)  # the ghosts' contributions to their owners
for tag in (SLAVE, MASTER, TOP, BOTTOM):
    nodes = fem.locate_dofs_topological(V, 1, tags.find(tag))
    F[tag] = 2 * comm.allreduce(r.array[2 * nodes[nodes < V.dofmap.index_map.size_local] + 1].sum())

# ## The pressure against Hertz: for the force P per unit thickness and E* = E / (2(1 − ν²)),
# a = 2 √(R P / (2π E*)), p0 = 2P / (π a).  You see −λ_i (slave nodes) and −λ^m_j = −Σ_i M_ij
# λ_i / D_jj (master nodes) on Hertz's ellipse, p0 within a percent, a within a mesh size.
W, rows = lmbda_h.function_space, []
for tag, lam in ((SLAVE, lmbda_h), (MASTER, master_pressure(result))):
    dofs = fem.locate_dofs_topological(W, 1, tags.find(tag))
    dofs = dofs[dofs < W.dofmap.index_map.size_local]
    X = W.tabulate_dof_coordinates()[dofs, 0]
    rows.append(comm.gather(np.c_[X, -lam.x.array[dofs], result.active.x.array[dofs]]))
if comm.rank == 0:
    print(f"{result.dofs} DoFs, {result.iterations} Newton iterations; contact force P = {P:.6f}")
    print(f"force on the slave surface {F[SLAVE]:.6f}, master {F[MASTER]:.6f}, top {F[TOP]:.6f}")
    print(f"action = reaction to {abs(F[SLAVE] + F[MASTER]) / P:.1e}")
    (x, p, on), (xm, pm, _) = (np.concatenate(part).T for part in rows)
    a_H = 2 * np.sqrt(R * P / (np.pi * E / (1 - nu**2)))  # 2 √(R P / (2π E*))
    p0_H, p0_h, edge = 2 * P / (np.pi * a_H), p.max(), x[on > 0].max()
    a_h = 0.5 * (edge + x[(on == 0) & (x > edge)].min())  # the last active node and the next
    print(f"half-width a = {a_h:.5f} (Hertz {a_H:.5f}, {100 * (a_h / a_H - 1):+.2f}%)")
    print(f"peak pressure p0 = {p0_h:.5f} (Hertz {p0_H:.5f}, {100 * (p0_h / p0_H - 1):+.2f}%)")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(x, p, "o", ms=3, label="slave nodes: −λ_i")
    ax.plot(xm, pm, "x", label="master nodes: −λ^m_j")
    ax.plot(xs := np.linspace(0, a_H), p0_H * np.sqrt(1 - (xs / a_H) ** 2), "k-", label="Hertz")
    ax.set(xlim=(0, 2 * a_H), xlabel="x, from the centre of contact (length)", ylabel="pressure")
    ax.legend(), fig.tight_layout(), fig.savefig("demo_two_bodies.png", dpi=100)
    print("wrote demo_two_bodies.png")
