# # A guaranteed error bound for a Signorini problem
#
# The residual estimator of docs/theory.md §5 tells *where* to refine, but its size is the
# error only up to an unknown constant: on the problem below η_res is about 3.5 times the error.
# The equilibrated estimator of docs/theory.md §9 (`estimator: equilibrated`) reconstructs a
# flux σ_h ∈ RT_p on vertex patches with −div σ_h = Π_p f and σ_h·n = λ̃_h on Γ_C, and
# bounds the energy error with no unknown constant:
#
#     |||u − u_h||| ≤ η = R(A + W, A W + B),   A = ‖σ_h − ∇u_h‖ + osc,
#
# W and B the terms of the contact (a feasible lifting w of the constraint violation and
# ∫ −σλ̃_h (w − σ(u_h − g))).  This demo runs the adaptive loop on problem A (docs/theory.md
# §7, exact solution u = −r^{3/2} cos(3θ/2)) and prints, per level, the true error, both
# estimators and their effectivities η / error.
#
# Run it with `python demos/demo_guaranteed_bound.py [LEVELS]` (default 10 levels, about
# 20 000 DoFs, a few seconds; also under `mpirun -n 2`).

import sys
from pathlib import Path

import contact
from contact.adaptivity.energy_error import energy_error
from contact.adaptivity.estimate import residual_estimate

from mpi4py import MPI

LEVELS = int(sys.argv[1]) if len(sys.argv) > 1 else 10
comm = MPI.COMM_WORLD
exact = "-r**1.5*cos(1.5*theta)"
scene = contact.load_scene(
    Path(__file__).resolve().parents[1] / "configs" / "signorini_free_boundary.yaml",
    ["estimator=equilibrated", "output.verbose=false"],
)

# ## The loop
#
# `contact.estimate` gives the scene's estimator, here the guaranteed bound (its η_T are DG0
# functions like the residual estimator's, so MARK and REFINE do not change); the residual
# estimator of the same solution is computed beside it for comparison.
rows, u0 = [], None
for level in range(LEVELS):
    result = contact.solve(scene, u0=u0)
    bound = contact.estimate(scene, result)
    residual = residual_estimate(result.problem, result)
    error = energy_error(result.u_h, exact)
    rows.append((result.dofs, error, bound.eta, residual.eta))
    if level + 1 < LEVELS:
        cells = contact.mark(bound.eta_T, "dorfler", theta=0.5)
        scene, u0 = contact.refine(scene, cells, result.u_h)

# ## What you see
#
# One line per level: the error, the guaranteed η and η / error (≥ 1 on every level: the
# bound holds; about 1.1–1.3 once the free boundary is resolved), and the residual
# estimator with its effectivity, several times larger and of no guaranteed sign.
if comm.rank == 0:
    print(
        f"{'DoFs':>7s} {'error':>10s} {'eta_eq':>10s} {'eq/err':>7s} {'eta_res':>10s} "
        f"{'res/err':>7s}"
    )
    for dofs, error, eq, res in rows:
        print(
            f"{dofs:7d} {error:10.3e} {eq:10.3e} {eq / error:7.3f} {res:10.3e} {res / error:7.3f}"
        )
    held = all(eq >= error for _, error, eq, _ in rows)
    print(f"guaranteed on every level: {held}")

# `demo_guaranteed_bound.png`: the error and both estimators against the DoFs; the
# guaranteed η runs just above the error, the residual estimator parallel to it, higher.
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    N, err, eq, res = zip(*rows)
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.loglog(N, err, "s-", label="error |||u − u_h|||")
    ax.loglog(N, eq, "o-", label="equilibrated η (guaranteed)")
    ax.loglog(N, res, "^-", label="residual η")
    ax.set_xlabel("degrees of freedom N (a count)")
    ax.set_ylabel("energy norm of the error (dimensionless: k = 1, u of order 1)")
    ax.set_title("problem A, Dörfler θ = 0.5 on the equilibrated η_T")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig("demo_guaranteed_bound.png", dpi=100)
    print("wrote demo_guaranteed_bound.png")
