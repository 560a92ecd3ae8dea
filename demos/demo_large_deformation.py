# # Finite deformation: a rubber cylinder pressed far into a rigid plane
#
# A neo-Hookean cylinder (plane strain, radius R, Young's modulus E, Poisson's ratio ν) is
# pressed into a rigid frictionless plane until the indentation is a third of its radius.
# In the reference configuration (coordinates X, F = I + ∇u, J = det F, C = FᵀF) it stores
#
#     ψ(F) = μ/2 (tr C − 3 − 2 ln J) + λ/2 (ln J)²,
#
# and equilibrium with contact is: minimise Π(u) = ∫ ψ(F) dX over the u that keep the
# deformed body on its side of the plane.  For a plane through p with normal ν the deformed
# point X + u must satisfy (X + u − p)·ν ≥ 0: *affine in u*, so on the contact nodes it is a
# bound on the normal displacement — the same complementarity problem as in linear
# elasticity, with the residual R(u) = ∂Π/∂u and the tangent K_T = ∂²Π/∂u² re-assembled at
# every Newton iterate (UFL derivatives of ψ; `contact/models/hyperelastic.py`).
#
# The plane rises along a load path, y = δ t, t = 1/N … 1; each step starts from the last
# one.  The same path is solved with linear elasticity: the two agree while the strains are
# small and part as the contact widens to a sizeable part of R.
#
# Run it with `python demos/demo_large_deformation.py [STEPS]` (default 6; seconds, also
# under `mpirun -n 2`).  It prints the force–indentation table of both models, the Newton
# residuals of the last step and whether the tangent stayed positive definite, and writes
# `demo_large_deformation.png`.

import sys

import contact
from contact.output.run_report import active_measure

import numpy as np
from mpi4py import MPI

STEPS = int(sys.argv[1]) if len(sys.argv) > 1 else 6
comm = MPI.COMM_WORLD
R, E, nu, delta = 1.0, 1.0, 0.3, 1 / 3


def say(*args):
    if comm.rank == 0:
        print(*args, flush=True)


# ## The scene
#
# The quarter of the cylinder's lower half (`mesh.type: quarter_disk`, gmsh tags 1 arc,
# 2 flat top, 3 axis x = 0), its top held, the axis a symmetry line; the plane's point
# moves with the pseudo-time t.  Only `model` differs between the two runs.


def scene(model: dict) -> contact.Scene:
    return contact.load_scene(
        {
            "name": "large_deformation",
            "constants": {"delta": delta},
            "mesh": {"type": "quarter_disk", "radius": R, "h": 0.1, "h_contact": 0.02, "zone": 0.7},
            "boundaries": {
                "arc": {"role": "contact", "tag": 1},
                "top": {"role": "dirichlet", "tag": 2},
                "axis": {"role": "symmetry", "tag": 3},
            },
            "model": model,
            "obstacle": {"type": "plane", "point": [0.0, "delta*t"], "normal": [0.0, 1.0]},
            "load": {"steps": STEPS},
            "output": {"verbose": False},
        }
    )


# ## Two load paths
#
# `contact.run_load_path` solves step after step (semismooth Newton on Fischer–Burmeister);
# for a hyperelastic body it halves a step that does not converge (`load.cuts`) and counts
# the negative eigenvalues of K_T at each solution (`Step.negative_eigenvalues`: 0 means a
# stable equilibrium).  `keep_all` keeps every step's solution for the picture.

paths = {
    name: contact.run_load_path(scene(model), method="fb", keep_all=True)
    for name, model in (
        ("linear", {"type": "elasticity", "E": E, "nu": nu}),
        ("neo-Hookean", {"type": "hyperelastic", "law": "neo_hookean", "E": E, "nu": nu}),
    )
}
assert all(p.converged for p in paths.values()), {k: p.stop for k, p in paths.items()}
lin, nh = paths["linear"].steps, paths["neo-Hookean"].steps

# ## Force against indentation
#
# The contact force P (per unit thickness, of the whole cylinder: twice the modelled
# quarter's) and the contact half-width a = |A_h| (the measure of the active contact nodes,
# in the reference configuration).

say(
    f"{'indentation/R':>13s} {'P linear':>10s} {'P neo-Hookean':>13s} {'ratio':>7s} "
    f"{'a linear':>9s} {'a neo-H.':>9s} {'Newton':>6s}"
)
for s_lin, s_nh in zip(lin, nh):
    d = delta * s_nh.time / R
    P_lin, P_nh = s_lin.result.contact_force, s_nh.result.contact_force
    a_lin, a_nh = active_measure(s_lin.result), active_measure(s_nh.result)
    say(
        f"{d:13.3f} {P_lin:10.5f} {P_nh:13.5f} {P_nh / P_lin:7.4f} {a_lin:9.4f} {a_nh:9.4f} "
        f"{s_nh.result.iterations:6d}"
    )
for which, k in (("first", 0), ("last", -1)):
    ratio = nh[k].result.contact_force / lin[k].result.contact_force
    say(f"{which} step: neo-Hookean / linear force = {ratio:.4f}")

# ## Newton
#
# Inside a step the active set settles within a few iterations; from then on Newton on the
# exact tangent converges quadratically — each residual about the square of the previous
# one (in units of the largest nodal force) until round-off.

residuals = [h["residual"] for h in nh[-1].result.history]
say("Newton residuals of the last step: " + " ".join(f"{r:.1e}" for r in residuals))
say(f"K_T positive definite at every step: {all(s.negative_eigenvalues == 0 for s in nh)}")

# ## What you see
#
# At small indentation both models give the same force (the first step's ratio is close to
# 1).  Deeper, the neo-Hookean cylinder is stiffer: the contact zone spreads over a large
# part of the arc and the compressed material resists volume change (the ln J terms), so
# its force grows faster than linear elasticity predicts.  `demo_large_deformation.png`:
# the force–indentation curves, and the deformed neo-Hookean quarter (X + u_h) on the plane
# at the last step.

u_h = nh[-1].result.u_h
V = u_h.function_space
X = V.tabulate_dof_coordinates()[:, :2]
u = u_h.x.array.reshape(-1, 2)
owned = V.mesh.topology.index_map(2).size_local
dofs = V.dofmap.list[:owned]
cells = comm.gather((X[dofs] + u[dofs]).reshape(-1, 3, 2), root=0)
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    d = [delta * s.time / R for s in nh]
    for name, steps in paths.items():
        ax1.plot([0] + d, [0] + [s.result.contact_force for s in steps.steps], "o-", label=name)
    ax1.set_xlabel("indentation / R (dimensionless)")
    ax1.set_ylabel("contact force P (per unit thickness, E = 1)")
    ax1.legend()
    ax1.grid(alpha=0.3)
    mesh = PolyCollection(np.concatenate(cells), facecolor="none", edgecolor="k", lw=0.2)
    ax2.add_collection(mesh)
    ax2.axhline(delta, color="tab:red", lw=1.5, label="rigid plane")
    ax2.set_xlim(0, 1.4 * R)
    ax2.set_ylim(delta - 0.05, R)
    ax2.set_aspect("equal")
    ax2.set_xlabel("x (length, scene units)")
    ax2.set_ylabel("y (length, scene units)")
    ax2.set_title(f"deformed neo-Hookean quarter at indentation {delta / R:.2f} R (true scale)")
    ax2.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig("demo_large_deformation.png", dpi=100)
    say("wrote demo_large_deformation.png")
