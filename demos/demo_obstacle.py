# # The obstacle problem, three NCP functions, and the primal–dual active set method
#
# A membrane clamped on the boundary of Ω = (−1, 1)² is pulled down by a uniform load
# f = −2 and drapes over a dome ψ(x) = 0.4 − r².  Its deflection u solves the obstacle
# problem (docs/theory.md §1.2)
#
#     −Δu − f ≥ 0,    u − ψ ≥ 0,    (−Δu − f)(u − ψ) = 0    in Ω,     u = 0 on ∂Ω:
#
# where the membrane lifts off (u > ψ) it is in equilibrium, −Δu = f; where it touches
# (u = ψ) the dome pushes up with the contact force density λ = −Δu − f ≥ 0.
#
# With P1 elements and lumped weights w_i = ∫ φ_i dx the discrete problem asks, at every
# free node i,
#
#     a_i = u_i − ψ_i ≥ 0,    b_i = c_i λ_i ≥ 0,    a_i b_i = 0,     λ_i = (K u − F)_i / w_i,
#
# a complementarity problem.  A *complementarity (NCP) function* φ has φ(a, b) = 0 exactly
# when a ≥ 0, b ≥ 0 and ab = 0, so the problem becomes the nonsmooth equation
# Φ(u) = (φ(a_i, b_i))_i = 0, which a semismooth Newton method solves.  This demo compares
# the three NCP functions of `contact`, and shows that Newton's method on the min function
# *is* the primal–dual active set method.
#
# Run it with `python demos/demo_obstacle.py [N]` (N × N cells, default 64; also under
# `mpirun -n 2`).  It prints the φ table, one line per method and min's active-set history,
# and writes `demo_obstacle.png` (the residual histories and the contact set).

import sys
import time

import contact
from contact.post.contact_table import contact_table
from contact.setup.posed import posed_of
from contact.solvers import ncp, newton_text

import numpy as np
from mpi4py import MPI

N = int(sys.argv[1]) if len(sys.argv) > 1 else 64
comm = MPI.COMM_WORLD


def say(*args):
    if comm.rank == 0:
        print(*args, flush=True)


# ## Three NCP functions
#
#     φ_FB(a, b)  = a + b − √(a² + b²)                 (Fischer–Burmeister: smooth away from 0)
#     φ_min(a, b) = min(a, b)                          (the natural residual: piecewise linear)
#     φ_μ(a, b)   = (1 − μ) φ_FB(a, b) + μ φ_min(a, b)  (a blend, μ = 0.5)
#
# All three vanish on the complementarity set (a ≥ 0, b ≥ 0, ab = 0) and nowhere else:

pairs = [(0.0, 2.0), (1.5, 0.0), (0.0, 0.0), (1.0, 1.0), (-1.0, 0.5), (0.2, -0.3)]
say("\n     a      b   phi_fb  phi_min  phi_blend")
for a, b in pairs:
    values = [float(ncp.phi(np.array([a]), np.array([b]), m, 0.5)[0]) for m in ncp.METHODS]
    say(f"{a:6.2f} {b:6.2f}" + "".join(f" {v:8.4f}" for v in values))

# ## The scene
#
# A scene is a mapping with the same keys as a YAML file in `configs/` (here
# `configs/obstacle_membrane.yaml` at N × N cells): the mesh, the clamped boundary, the
# model `obstacle` with the lower bound u ≥ ψ, and the data.

scene = contact.load_scene(
    {
        "name": "membrane",
        "mesh": {
            "type": "rectangle",
            "corners": [[-1, -1], [1, 1]],
            "cells": [N, N],
            "diagonal": "crossed",
        },
        "boundaries": {
            "clamp": {"role": "dirichlet", "where": "abs(x) > 1 - 1e-10 or abs(y) > 1 - 1e-10"}
        },
        "model": {"type": "obstacle", "bound": "lower"},
        "data": {"f": "-2", "psi": "0.4 - r**2"},
        "output": {"verbose": False},
    }
)

# ## Semismooth Newton with each φ
#
# Newton's method needs an element H of the generalized derivative of Φ: on row i,
# H_i = ∂_aφ · ∂a_i/∂u + ∂_bφ · ∂b_i/∂u, a combination of the identity row and the
# stiffness row K_i.  `contact.solve` assembles K once and builds H as
# diag(s) K + diag(d) from the pairs (a_i, b_i) at every step (docs/theory.md §4).  Every method
# solves the same discrete problem, so the solutions must agree to solver tolerance.

results = {}
for method in ncp.METHODS:
    t0 = time.perf_counter()
    results[method] = r = contact.solve(scene, method=method, polish=False)
    seconds = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    say(
        f"{method:>6s}: {newton_text(r)}, {seconds:5.2f} s, |Phi| = {r.residual:.1e}, "
        f"{r.n_active} nodes in contact, contact force {r.contact_force:.4f}"
    )

u_min = results["min"].u_h.x.array
difference = max(
    comm.allreduce(float(np.max(np.abs(r.u_h.x.array - u_min))), op=MPI.MAX)
    for r in results.values()
)
say(f"largest difference between the three solutions: {difference:.1e}")

# (`polish=False` shows the plain Newton methods; by default fb and blend finish with an
# active-set polishing step, which removes most of FB's slow end game.)
#
# ## Newton on min is the primal–dual active set method
#
# ∂φ_min is (1, 0) where a_i < b_i and (0, 1) where a_i ≥ b_i.  So a Newton step on min
# first splits the nodes by the current iterate into the *active set*
# A = {i : b_i > a_i} and the rest, then solves the linear problem
#
#     u_i = ψ_i  on A,        (K u − F)_i = 0  off A,
#
# which is exactly one step of the primal–dual active set method of Hintermüller, Ito and
# Kunisch (2002).  The method stops when the active set repeats: the next step then
# reproduces the same linear problem, and Φ = 0.  The history shows it — from the initial
# guess u = 0 the set sheds whole layers of nodes, and the last step changes no node.
# (On K that is not an M-matrix PDAS may instead return to an active set it left, a cycle;
# the default `solver.line_search: auto` then backtracks on ½‖Φ‖², and until then its steps
# are PDAS's — here always.  `line_search="basic"` is PDAS without that guard.)

say("\nmin = primal-dual active set: iteration, |Phi|, active nodes, nodes that changed status")
for row in results["min"].history:
    say(
        f"  {row['iteration']:3d}  {row['residual']:10.3e}  {row['active']:6d}  {row['changed']:6d}"
    )
say(f"steps the cycle guard shortened: {results['min'].backtracked} (0: every step was PDAS's)")

# ## What you see
#
# `demo_obstacle.png`: the residual ‖Φ‖ of each method against the iteration (left: min
# drops to round-off in one step once its active set is right; FB converges superlinearly
# but needs more steps; the blend lies in between) and the contact set on the mesh (right).
# The table printed above says the same in numbers.

table = contact_table(posed_of(scene), results["min"])  # the contact set, gathered on rank 0
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax_set) = plt.subplots(1, 2, figsize=(12, 5))
    for method, r in results.items():
        ax.semilogy(
            [h["iteration"] for h in r.history],
            [max(h["residual"], 1e-17) for h in r.history],
            "o-",
            label=f"{method} ({r.iterations} iterations)",
        )
    ax.set_xlabel("Newton iteration")
    ax.set_ylabel("residual ‖Φ‖ (a nodal force: the units of f times an area)")
    ax.legend()
    ax.grid(alpha=0.3)
    ax_set.plot(table["x"], table["y"], ".", ms=3, color="C3")
    ax_set.add_patch(plt.Rectangle((-1, -1), 2, 2, fill=False))
    ax_set.set_aspect("equal")
    ax_set.set_xlabel("x (length, scene units)")
    ax_set.set_ylabel("y (length, scene units)")
    ax_set.set_title(f"contact set: {len(table['x'])} nodes with u = ψ")
    fig.tight_layout()
    fig.savefig("demo_obstacle.png", dpi=100)
    say("wrote demo_obstacle.png")
