# # Adaptive refinement for a Signorini problem, step by step
#
# Problem A of docs/theory.md §7: on Ω = (−1, 1) × (0, 1), find u with
#
#     −Δu = 0 in Ω,    u = u_D on the sides and the top,
#     u ≤ 0,  λ := ∂u/∂n ≤ 0,  λ u = 0    on Γ_C = {y = 0}.
#
# With u_D = −r^{3/2} cos(3θ/2) (polar coordinates about the origin) the exact solution is
# u_D itself: the body touches the obstacle (u = 0, λ = −(3/2)|x|^{1/2}) for x < 0 and
# separates (u < 0, λ = 0) for x > 0.  The free boundary at x = 0 makes u singular there,
# u ~ r^{3/2}, and that is where the mesh should be fine.
#
# This demo writes the adaptive loop SOLVE → ESTIMATE → MARK → REFINE by hand with the
# four public functions `contact.solve`, `contact.estimate`, `contact.mark` and
# `contact.refine` (what `contact.adapt` and `contact run` do for you), and compares the
# estimator η with the true error ‖u − u_h‖_E = |u − u_h|_{H¹}.
#
# Run it with `python demos/demo_signorini_adaptive.py [LEVELS]` (default 12 levels, about
# 60 000 DoFs, a few seconds; also under `mpirun -n 2`).  It prints one line per level and writes
# `demo_signorini_adaptive.png`, the convergence plot.

import sys

import contact
from contact.adaptivity.energy_error import energy_error

import numpy as np
from mpi4py import MPI

LEVELS = int(sys.argv[1]) if len(sys.argv) > 1 else 12
comm = MPI.COMM_WORLD


def say(*args):
    if comm.rank == 0:
        print(*args, flush=True)


# ## The scene
#
# The same keys as `configs/signorini_free_boundary.yaml`: a coarse 16 × 8 mesh, the contact
# part y = 0 with gap g = 0, Dirichlet data on the other three sides, and the exact
# solution (used here only to measure the error).

exact = "-r**1.5*cos(1.5*theta)"
scene = contact.load_scene(
    {
        "name": "problem_A",
        "mesh": {"type": "rectangle", "corners": [[-1, 0], [1, 1]], "cells": [16, 8]},
        "boundaries": {
            "contact": {"role": "contact", "where": "y < 1e-10"},
            "outer": {
                "role": "dirichlet",
                "where": "x < -1 + 1e-10 or x > 1 - 1e-10 or y > 1 - 1e-10",
            },
        },
        "model": "signorini",
        "data": {"f": "0", "g": "0", "u_D": exact, "exact": exact},
        "solver": {"method": "min"},
        # the residual estimator of docs/theory.md §5 (the scalar models' default is the
        # guaranteed bound of §9: demos/demo_guaranteed_bound.py shows it)
        "estimator": "residual",
        "output": {"verbose": False},
    }
)

# ## The loop
#
# * SOLVE: semismooth Newton on the min function (the primal–dual active set method), started
#   from the previous level's solution interpolated onto the new mesh (nested iteration:
#   after the first level it needs one or two steps);
# * ESTIMATE: the residual estimator of docs/theory.md §5, one DG0 form per term, so one
#   assembly gives every cell's indicator
#
#       η_T² = h_T² ‖Δu_h‖²_T + ½ Σ_E h_E ‖[∂u_h/∂n]‖²_E + Σ_{E ⊂ Γ_N ∪ Γ_C} (...)
#
#   with, on Γ_C, the consistency of λ_h with ∂u_h/∂n, the sign violation ‖λ_h⁺‖² and the
#   complementarity term ∫ min(λ_h, 0)(u_h − g);
# * MARK: Dörfler's bulk criterion — the smallest set M of cells with
#   Σ_M η_T² ≥ θ Σ_T η_T², θ = 0.5;
# * REFINE: the marked cells' edges are bisected (`dolfinx.mesh.refine`, conforming), the
#   boundary parts follow, and u_h is carried to the new mesh.

rows, u0 = [], None
say(f"{'level':>5s} {'DoFs':>7s} {'eta':>10s} {'error':>10s} {'eta/error':>9s} {'Newton':>6s}")
for level in range(LEVELS):
    result = contact.solve(scene, u0=u0)  # SOLVE
    est = contact.estimate(scene, result)  # ESTIMATE
    error = energy_error(result.u_h, exact)
    rows.append((result.dofs, est.eta, error, result.iterations))
    say(
        f"{level:5d} {result.dofs:7d} {est.eta:10.3e} {error:10.3e} {est.eta / error:9.2f} "
        f"{result.iterations:6d}"
    )
    if level + 1 < LEVELS:
        cells = contact.mark(est.eta_T, "dorfler", theta=0.5)  # MARK
        # REFINE (+ nested guess)
        scene, u0 = contact.refine(scene, cells, result.u_h)

# ## Rates
#
# For P1 elements the best possible rate in the energy norm is N^{−1/2} (N = DoFs in 2D).
# The slope of log(error) against log(N) over the second half of the levels:

N, eta, err, its = (np.array(c, dtype=float) for c in zip(*rows))
half = len(N) // 2
rate = np.polyfit(np.log(N[half:]), np.log(err[half:]), 1)[0]
eff = eta / err
say(
    f"error ~ N^{rate:.2f} over the last {len(N) - half} levels; effectivity eta/error "
    f"between {eff.min():.2f} and {eff.max():.2f}"
)

# ## What you see
#
# The table: η follows the error at a nearly constant ratio (the effectivity), so η can
# decide where to refine and when to stop; both fall like N^{−1/2}; Newton needs one step
# per level after the first.  `demo_signorini_adaptive.png`: η and the error against N
# on log–log axes, with the N^{−1/2} slope.

if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    ax.loglog(N, eta, "o-", label="estimator η")
    ax.loglog(N, err, "s-", label="error ‖u − u_h‖_E")
    ax.loglog(N, err[0] * (N / N[0]) ** -0.5, "k--", lw=1, label="N^(−1/2)")
    ax.set_xlabel("degrees of freedom N (a count)")
    ax.set_ylabel("energy norm of the error (dimensionless: k = 1, u of order 1)")
    ax.set_title("problem A, Dörfler θ = 0.5")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig("demo_signorini_adaptive.png", dpi=100)
    say("wrote demo_signorini_adaptive.png")
