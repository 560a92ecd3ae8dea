# # Two elastic bodies in contact: mortar coupling with dual multipliers
#
# Two bodies Ω¹ (slave) and Ω² (master), meshed independently, touch along surfaces whose
# meshes do not match.  On the slave surface Γ_s, with the P1 trace basis φ_i, its dual
# basis ψ_i (∫ ψ_i φ_k ds = δ_ik D_ii) and the projection π onto the master surface Γ_m
# (docs/theory.md §1.5),
#
#     D_ii = ∫_{Γ_s} φ_i ds,     M_ij = ∫_{Γ_s} ψ_i (φ_j^m ∘ π) ds,
#
# and non-penetration at slave node i is a bound on one unknown, the normal displacement
# relative to the master
#
#     x_i = n_i · (u_s,i − Σ_j (M_ij / D_ii) u_m,j)  ≤  g_i     (g_i the weighted gap),
#
# which is one more change of basis u = Q x, as for the rotated rigid obstacles: every
# solver (semismooth Newton on φ_FB / φ_min, PETSc's VI solvers) applies unchanged, and
# λ_i = R̃_i / D_ii is the interface pressure, acting on both bodies (R̃ = Qᵀ R).
#
# The demo runs three scenes: the *contact patch test* (two blocks of different materials,
# non-matching meshes, a uniform pressure p on top: the mortar coupling transmits it
# exactly, at every slave node), *two identical cylinders* (Hertz: effective radius
# R = R_c/2, E* = E/(2(1 − ν²))), solved adaptively, and the same cylinders with Coulomb
# friction under a growing tangential force (Cattaneo–Mindlin partial slip).  Run it with
# `python demos/demo_two_bodies.py [LEVELS]` (default 6 levels, under a minute; also under
# `mpirun -n 2`).  It prints the patch test's largest pressure error, the level table, the
# forces on both sides of the interface and the reactions, a and p0 against Hertz, and the
# stick zones against Cattaneo–Mindlin; it
# writes `demo_two_bodies.png` (both bodies, and the pressure on both sides against Hertz).

import sys
from pathlib import Path

import contact
from contact.models.mortar import master_pressure
from contact.output.folder import gather_nodal
from contact.post.interface import interface_resultants
from contact.post.reference import compare
from contact.setup.run import run_load_path

import numpy as np
from mpi4py import MPI

LEVELS = int(sys.argv[1]) if len(sys.argv) > 1 else 6
comm = MPI.COMM_WORLD


def say(*args):
    if comm.rank == 0:
        print(*args, flush=True)


# ## The patch test
#
# `mesh.type: blocks` builds structured blocks into one mesh without shared nodes (the
# bodies are its disconnected components, cell tags 1, 2, …).  `bodies` gives each its
# material; a boundary part with `body:` keeps only that body's facets, so the slave and
# master surfaces can be selected by the same predicate.  The upper block has 31 cells
# along the interface, the lower one 10: no node is aligned except at the corners.  The
# upper block only touches the lower one (nothing else holds it vertically), so the initial
# guess presses it in a little and the first Newton step sees the contact.

p = 0.01
patch = contact.load_scene(
    {
        "mesh": {
            "type": "blocks",
            "blocks": [
                {"corners": [[0, 0], [1, 0.5]], "cells": [10, 5]},
                {"corners": [[0, 0.5], [1, 1]], "cells": [31, 15]},
            ],
        },
        "bodies": {
            "lower": {"tag": 1, "E": 1.0, "nu": 0.3},
            "upper": {"tag": 2, "E": 3.0, "nu": 0.2},
        },
        "boundaries": {
            "top": {"role": "neumann", "where": "y > 1 - 1e-10"},
            "bottom": {"role": "symmetry", "where": "y < 1e-10"},
            "left": {"role": "symmetry", "where": "x < 1e-10"},
            "slave": {"role": "interface", "where": "abs(y - 0.5) < 1e-10", "body": "upper"},
            "master": {"role": "interface", "where": "abs(y - 0.5) < 1e-10", "body": "lower"},
        },
        "pairs": [{"slave": "slave", "master": "master"}],
        "model": {"type": "elasticity"},
        "data": {"t": ["0", f"-{p}"]},
        "solver": {"u0": ["0", "-1e-4 * (y > 0.5 - 1e-10)"]},
        "output": {"verbose": False},
    }
)
result = contact.solve(patch, method="fb")
lam = result.lmbda_h.x.array[result.problem.output_nodes]  # λ_i at this rank's slave nodes
lam_m = master_pressure(result).x.array  # λ^m_j = Σ_i M_ij λ_i / ∫ φ_j^m
worst = comm.allreduce(float(np.max(np.abs(lam + p))), op=MPI.MAX) / p
worst_m = comm.allreduce(float(np.max(np.abs(lam_m[lam_m != 0] + p), initial=0.0)), op=MPI.MAX) / p
say(
    f"patch test: {result.n_active} slave nodes active; largest |λ_i + p| / p = {worst:.1e} "
    f"(slave side), {worst_m:.1e} (master side)"
)

# ## Two cylinders, adaptively
#
# `mesh.type: half_disks` builds (gmsh) the upper half of one disk and the lower half of the
# other, touching at the origin: cell tags 1 (upper), 2 (lower); facet tags 1 and 3 the arcs
# (refinement moves new vertices onto the circles), 2 the top, 4 the bottom.  The top is
# pushed down by δ, the bottom is fixed.  The slave surface is the upper arc near the
# contact; the master surface must cover it (a slave node whose facets face no master facet
# is an error naming the pair).  The estimator adds, on both sides of the interface, the
# consistency of the traction σ(u_h)n with the pressure (λ_h on the slave side, λ^m on the
# master side), and Dörfler marking refines both bodies; the coupling is recomputed on
# every level.

Rc, E, nu, delta = 8.0, 200.0, 0.3, 0.1
scene = contact.load_scene(
    {
        "name": "two_cylinders",
        "mesh": {"type": "half_disks", "radius": Rc, "h": 1.0, "h_contact": 0.05, "zone": 1.0},
        "bodies": {"upper": {"tag": 1, "E": E, "nu": nu}, "lower": {"tag": 2, "E": E, "nu": nu}},
        "boundaries": {
            "top": {"role": "dirichlet", "tag": 2},
            "bottom": {"role": "dirichlet", "tag": 4},
            "slave": {"role": "interface", "where": "abs(x) < 2 and y < 1", "body": "upper"},
            "master": {"role": "interface", "where": "abs(x) < 3 and y > -1", "body": "lower"},
        },
        "pairs": [{"slave": "slave", "master": "master"}],
        # Hertz for the effective radius R_c / 2 (from the mesh) and E* of the bodies
        "reference": {"type": "hertz"},
        "model": {"type": "elasticity"},
        "data": {"u_D": ["0", f"-{delta} * (y > 0)"]},
        "output": {"verbose": False},
    }
)
levels = contact.adapt(scene, method="fb", strategy="dorfler", theta=0.5, max_levels=LEVELS).levels
say(f"\n{'level':>5s} {'DoFs':>7s} {'eta':>10s} {'Newton':>6s} {'active':>6s}")
for lv in levels:
    say(
        f"{lv.index:5d} {lv.result.dofs:7d} {lv.estimate.eta:10.3e} {lv.result.iterations:6d} "
        f"{lv.result.n_active:6d}"
    )
scene, result = levels[-1].scene, levels[-1].result

# ## Action and reaction
#
# The force each body's surface needs from the other is the residual a(u_h, v) − L(v)
# summed over its interface nodes; Qᵀ hands the slave force to the master nodes through
# the same M_ij / D_ii, so the two are opposite to round-off, and equal to the reactions
# on the top and the bottom.

res = interface_resultants(scene, result)
F_s, F_m = res["interface_force_slave"][1], res["interface_force_master"][1]
say(
    f"\nforce on the slave surface {F_s:.6f}, on the master surface {F_m:.6f} "
    f"(balance error {res['interface_balance_error']:.1e}); reactions: top "
    f"{res['reactions']['top'][1]:.6f}, bottom {res['reactions']['bottom'][1]:.6f}"
)

# ## The pressure against Hertz
#
# For the force P per unit thickness, two cylinders of radius R_c are Hertz's cylinder of
# the effective radius R = R_c / 2 on a rigid plane with E* = E / (2(1 − ν²)):
# a = 2 √(R P / (π E*)), p0 = 2 P / (π a): the scene declares `reference: {type: hertz}`,
# whose radius defaults to the effective one of the two half-disks, and E* comes from the
# two bodies of the pair.

hz = compare(scene, result).values
say(
    f"half-width a = {hz['contact_half_width']:.5f} (Hertz {hz['hertz_a']:.5f}, "
    f"{100 * hz['a_error']:+.2f}%), peak pressure p0 = {res['peak_pressure']:.5f} (Hertz "
    f"{hz['hertz_p0']:.5f}, {100 * hz['p0_error']:+.2f}%), a/R_c = "
    f"{hz['contact_half_width'] / Rc:.3f}"
)

# ## Partial slip: Cattaneo–Mindlin
#
# The tangential unknowns of a slave node are its displacement relative to the master, so
# the Coulomb law of `friction:` (docs/theory.md §1.4) applies to the pair unchanged.  Two identical
# cylinders, built interpenetrating by 0.1 (`mesh.overlap`: the normal force), their flat
# faces rolling on planes (`role: symmetry`), a body force in x on the upper one whose
# resultant Q grows at constant P (`load:` steps in the pseudo-time t): the stick zone
# shrinks as c/a = √(1 − Q/(F P)) (`configs/two_body_cattaneo_2d.yaml`, declared
# `reference: {type: cattaneo_mindlin}`).  The frames of the slave nodes use the common
# normal of the two surfaces (flat between equal cylinders): pressing alone then makes no
# tangential traction, as for the half-spaces of the theory.

cm = contact.load_scene(
    Path(__file__).resolve().parents[1] / "configs" / "two_body_cattaneo_2d.yaml",
    ["mesh.h_contact=0.03", "output.verbose=false"],
)


def show(step):
    if step.index == 1:  # t = 0.5: P only
        return
    v = compare(step.scene, step.result).values
    say(
        f"Q/(F P) = {v['Q_over_FP']:.3f}: stick zone c/a = {v['c_over_a']:.4f} (Cattaneo–Mindlin "
        f"{v['c_over_a_theory']:.4f}, {100 * v['c_error']:+.1f}%), tangential traction L² error "
        f"{100 * v['q_error']:.1f}%"
    )


run_load_path(cm, verbose=False, on_step=show)

# ## What you see
#
# The patch test's pressure is exact to round-off on both sides: the slave facets are
# integrated against the master facets over their exact overlaps (segment intersection;
# polygon clipping in 3D), so constants cross the interface exactly — which node-to-segment
# coupling does not achieve.  On the cylinders, the pressure follows Hertz's ellipse on the
# slave nodes and, transported by M, on the master nodes; the half-width is within a
# fraction of the finest element of a.  `demo_two_bodies.png`: the deformed bodies (the
# displacement magnified) coloured by body, and the pressure on both sides against Hertz.

X, lam_s = gather_nodal(result.lmbda_h)
_, lam_m = gather_nodal(master_pressure(result))
V = result.u_h.function_space
cells = V.dofmap.list[: scene.mesh.topology.index_map(2).size_local]  # this rank's triangles
body = result.problem.data["body"]
triangles = comm.gather(
    (
        V.tabulate_dof_coordinates()[cells][:, :, :2],
        result.u_h.x.array.reshape(-1, 2)[cells],
        body.x.array[body.function_space.dofmap.list[: len(cells), 0]],
    ),
    root=0,
)
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    T, U, B = (np.concatenate([t[k] for t in triangles]) for k in range(3))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), gridspec_kw={"width_ratios": [1, 1.2, 1.3]})
    scale = 5.0
    for ax, window, edges in (
        (axes[0], (-8.5, 8.5, -8.5, 8.5), "none"),
        (axes[1], (-0.8, 0.8, -0.55, 0.15), "k"),
    ):
        for k, colour in ((1, "#9ecae1"), (2, "#fdae6b")):
            on = np.rint(B) == k
            ax.add_collection(
                PolyCollection(
                    T[on] + scale * U[on],
                    facecolors=colour,
                    edgecolors=edges,
                    linewidths=0.15,
                    antialiased=edges != "none",
                    label=["upper body (slave)", "lower body (master)"][k - 1],
                )
            )
        ax.set_xlim(window[:2])
        ax.set_ylim(window[2:])
        ax.set_aspect("equal")
    axes[0].set_title(f"two cylinders, displacement magnified × {scale:g}")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[1].set_title(
        f"the contact zone, displacement magnified × {scale:g}:\nnon-matching meshes "
        f"({result.dofs} DoFs)"
    )
    for ax in axes[:2]:
        ax.set_xlabel("x (length, scene units)")
        ax.set_ylabel("y (length, scene units)")
    a_H, p0_H = hz["hertz_a"], hz["hertz_p0"]
    near = np.abs(X[:, 0]) <= 2 * a_H
    slave, master = near & (lam_s != 0), near & (lam_m != 0)
    axes[2].plot(X[slave, 0], -lam_s[slave], "o", ms=3, label="slave nodes: −λ_i")
    axes[2].plot(X[master, 0], -lam_m[master], "x", ms=3, label="master nodes: −λ^m_j")
    xs = np.linspace(-a_H, a_H, 300)
    axes[2].plot(
        xs,
        p0_H * np.sqrt(1 - (xs / a_H) ** 2),
        "k-",
        lw=1,
        label=f"Hertz: a = {a_H:.4f}, p0 = {p0_H:.4f}",
    )
    axes[2].set_xlabel("x (length, scene units; undeformed position)")
    axes[2].set_ylabel("contact pressure (stress, units of E)")
    axes[2].set_title("pressure on both sides of the interface")
    axes[2].grid(alpha=0.3)
    axes[2].legend(loc="lower center", fontsize=8)
    fig.tight_layout()
    fig.savefig("demo_two_bodies.png", dpi=90)
    say("wrote demo_two_bodies.png")
