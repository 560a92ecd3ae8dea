"""Benchmark: which linear solver for the Newton steps — MUMPS LU of H (``direct``) or CG +
GAMG on the reduced SPD system (``gamg``) — by problem size and dimension.

What it shows: for a scalar and an elastic 2D scene and a 3D scene at growing sizes, one
contact solve (fb, the scene's defaults, grid sequencing ``auto``) with each linear
solver, repeated and interleaved, median wall and CPU time.  ``solver.linear: auto``
switches from MUMPS to GAMG at the size where the medians cross
(``contact.solvers.linear.DIRECT_MAX_DOFS_2D`` / ``_3D``).  Prints a table, writes CSV.

    python demos/bench/bench_linear.py --out demos/results/linear/linear.csv
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import contact

from common import save_csv

CASES = [  # (scene, overrides per size)
    ("configs/signorini_square.yaml", [[f"mesh.cells=[{n},{n}]"] for n in (32, 64, 128, 256, 512)]),
    ("configs/indentation_2d.yaml", [[f"mesh.cells=[{2 * n},{n}]"] for n in (20, 40, 80, 160)]),
    ("configs/hertz_3d.yaml", [[], ["mesh.h_contact=0.005"]]),
]


def timed(scene, linear: str, method: str) -> tuple[float, float, object]:
    t0, c0 = time.perf_counter(), time.process_time()
    r = contact.solve(scene, method=method, linear=linear, verbose=False)
    return time.perf_counter() - t0, time.process_time() - c0, r


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="bench/linear.csv")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--method", default="fb")
    ap.add_argument("--only", help="only scenes whose path contains this text")
    args = ap.parse_args()
    rows = []
    print(f"{'scene':>18s} {'DoFs':>8s} {'linear':>7s} {'its':>5s} {'wall s':>8s} {'cpu s':>8s}")
    for path, sizes in CASES:
        if args.only and args.only not in path:
            continue
        for sets in sizes:
            scene = contact.load_scene(path, ["output.verbose=false", *sets])
            timed(scene, "direct", args.method)  # warm-up: JIT compilation, first-touch
            samples = {"direct": [], "gamg": []}
            for _ in range(args.repeat):
                for linear in samples:
                    samples[linear].append(timed(scene, linear, args.method))
            for linear, runs in samples.items():
                r = runs[-1][2]
                row = {
                    "scene": Path(path).stem,
                    "dofs": r.dofs,
                    "dim": scene.mesh.topology.dim,
                    "linear": linear,
                    "method": args.method,
                    "newton": r.iterations,
                    "polish": r.polish_solves,
                    "sequence_levels": len(r.sequence),
                    "converged": r.converged,
                    "wall_s": round(statistics.median(w for w, _, _ in runs), 4),
                    "cpu_s": round(statistics.median(c for _, c, _ in runs), 4),
                    "repeat": args.repeat,
                }
                rows.append(row)
                print(
                    f"{row['scene']:>18s} {row['dofs']:8d} {linear:>7s} "
                    f"{r.iterations:3d}+{r.polish_solves:<1d} "
                    f"{row['wall_s']:8.3f} {row['cpu_s']:8.3f}",
                    flush=True,
                )
    save_csv(args.out, rows)


if __name__ == "__main__":
    main()
