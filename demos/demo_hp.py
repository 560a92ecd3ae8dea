# # hp-adaptivity: h at the free boundary, p where the solution is smooth
#
# Problem C of docs/theory.md §7 has the exact solution u = −(x − 1/2)₊³ + y² on the unit
# square: smooth everywhere but across the free boundary x = 1/2 on Γ_C = {y = 0}, where
# contact ends. h-adaptive P2 converges like N^{-1} there. `adapt.strategy: hp` raises the
# degree of the marked cells on which u_h's Legendre coefficients decay fast, and splits the
# others, keeping the cells at the free boundary at degree 1 (docs/theory.md §11). The
# error then falls exponentially in N^{1/3}, and η, the guaranteed bound, stays above it.
#
# Run it with `python demos/demo_hp.py [TOL]` (default 1e-6: about 30 levels, 2 500
# unknowns, a minute on a busy machine; also under `mpirun -n 2`).

import sys
from pathlib import Path

import contact

import numpy as np
from mpi4py import MPI

TOL = float(sys.argv[1]) if len(sys.argv) > 1 else 1e-6
scene = contact.load_scene(
    Path(__file__).resolve().parents[1] / "configs" / "signorini_smooth.yaml",
    ["output.verbose=false"],
)

# ## The loop
#
# `contact.adapt` runs SOLVE → ESTIMATE → MARK (h or p) → REFINE until η ≤ TOL. Each level
# is an `HPLevel`: its result, its estimate, its error against the scene's exact solution,
# and its hp space with the cells' degrees.
run = contact.adapt(scene, strategy="hp", p_max=6, tol=TOL, max_levels=60)
rows = [(lv.row()["dofs"], lv.error, lv.estimate.eta, lv.row()["p_max"]) for lv in run.levels]

# ## What you see
#
# One line per level: the unknowns of V_hp, the error, η and η / error (≥ 1 on every level),
# the largest degree. Then the fit log(error) ≈ c − b N^{1/3} over the levels past the third:
# a straight line in these coordinates is exponential convergence.
comm = MPI.COMM_WORLD
x = np.array([n ** (1 / 3) for n, *_ in rows[3:]])
y = np.log([e for _, e, *_ in rows[3:]])
b, c = np.polyfit(x, y, 1)
r2 = 1 - np.sum((y - (b * x + c)) ** 2) / np.sum((y - y.mean()) ** 2)
if comm.rank == 0:
    print(f"{'N':>6s} {'error':>10s} {'eta':>10s} {'eta/err':>7s} {'p_max':>5s}")
    for n, error, eta, p in rows:
        print(f"{n:6d} {error:10.3e} {eta:10.3e} {eta / error:7.3f} {p:5d}")
    print(f"eta >= error on every level: {all(eta >= e for _, e, eta, _ in rows)}")
    print(f"log(error) ~ {c:.2f} - {-b:.3f} N^(1/3), r^2 = {r2:.3f}")

# `demo_hp.png`: left, the error and η against N^{1/3} (log scale: a line is exponential);
# right, the final mesh coloured by the cells' degree — small cells of degree 1 at the free
# boundary's end (x = 1/2, y = 0), degree 2 where u = y² (x < 1/2), 3 and more where the
# cubic term is (x > 1/2). Each rank's cells (corners and degrees) are gathered on rank 0.
last = run.levels[-1]
msh = last.scene.mesh
n_cells = msh.topology.index_map(2).size_local
corners = msh.geometry.x[msh.geometry.dofmaps[0][:n_cells], :2]  # (cells, 3, 2)
parts = comm.gather((corners, last.space.cell_degrees[:n_cells]), root=0)
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    corners = np.concatenate([p[0] for p in parts])
    degrees = np.concatenate([p[1] for p in parts])
    tri = Triangulation(
        corners[:, :, 0].ravel(),
        corners[:, :, 1].ravel(),
        np.arange(3 * len(corners)).reshape(-1, 3),
    )
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12, 5))
    N, err, eta, _ = zip(*rows)
    ax0.semilogy(np.cbrt(N), err, "s-", label="error |||u − u_h|||")
    ax0.semilogy(np.cbrt(N), eta, "o-", label="η (guaranteed bound)")
    ax0.set_xlabel("N^{1/3} (N: unknowns of V_hp)")
    ax0.set_ylabel("energy norm of the error")
    ax0.set_title("problem C, hp (p_max 6)")
    ax0.grid(True, which="both", alpha=0.3)
    ax0.legend()
    cmap = plt.get_cmap("viridis", 6)  # one colour per degree 1 … p_max
    art = ax1.tripcolor(
        tri, facecolors=degrees, edgecolors="k", linewidth=0.2, cmap=cmap, vmin=0.5, vmax=6.5
    )
    fig.colorbar(art, ax=ax1, label="degree p_T")
    ax1.set_aspect("equal")
    ax1.set_title(
        f"the final hp mesh: {len(degrees)} cells, degrees {degrees.min()}–{degrees.max()}"
    )
    fig.tight_layout()
    fig.savefig("demo_hp.png", dpi=100)
    print("wrote demo_hp.png")
