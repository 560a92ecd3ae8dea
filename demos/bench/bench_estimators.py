"""What each estimator costs to certify a tolerance (issue 30, the default estimator): the
adaptive loop of a scalar scene run to ``adapt.tol`` with ``estimator: residual`` and with
``estimator: equilibrated``, in turn (``--repeat``) in one process.

Both loops stop at η ≤ tol, but η means different things: the equilibrated η bounds the
energy error (docs/theory.md §9), the residual η is the error times an unknown constant
(3.5–11 on the scenes of demos/RESULTS.md §12), so the residual loop refines until its
error is that many times below the tolerance.  Per run: levels, final DoFs, η, the energy
error, and the CPU seconds of the loop (the busiest rank's) with its estimate phase.
Writes ``estimators.csv`` (``_np2`` on 2 ranks).

    python demos/bench/bench_estimators.py --tol 4e-3 --out demos/results/equilibrated
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import contact

from common import save_csv
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[2]
ESTIMATORS = ("residual", "equilibrated")


def run(scene_file: str, estimator: str, tol: float, extra: list[str]) -> dict:
    """One adaptive loop to η ≤ ``tol``; the run's row."""
    sets = [
        f"estimator={estimator}",
        "output.verbose=false",
        f"adapt.tol={tol}",
        "adapt.max_levels=60",
        "adapt.max_dofs=5000000",
        *extra,
    ]
    scene = contact.load_scene(ROOT / "configs" / scene_file, sets)
    comm = MPI.COMM_WORLD
    comm.Barrier()
    t0, c0 = time.perf_counter(), time.process_time()
    out = contact.adapt(scene)
    wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    cpu = comm.allreduce(time.process_time() - c0, op=MPI.MAX)
    last = out.levels[-1]
    return {
        "scene": scene_file,
        "estimator": estimator,
        "ranks": comm.size,
        "tol": tol,
        "levels": len(out.levels),
        "dofs": last.result.dofs,
        "eta": last.estimate.eta,
        "error": last.error,
        "effectivity": last.estimate.eta / last.error,
        "seconds_estimate": round(sum(lv.seconds["estimate"] for lv in out.levels), 3),
        "wall": round(wall, 3),
        "cpu": round(cpu, 3),
        "stop": out.stop,
    }


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--scene", default="signorini_free_boundary.yaml", help="under configs/")
    ap.add_argument("--tol", type=float, default=4e-3, help="adapt.tol of both loops")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each estimator, in turn")
    ap.add_argument("--set", action="append", default=[], help="further scene overrides")
    ap.add_argument("--out", default="demos/results/equilibrated")
    args = ap.parse_args()
    rows = []
    for k in range(args.repeat):
        for estimator in ESTIMATORS:
            row = {"run": k, **run(args.scene, estimator, args.tol, args.set)}
            rows.append(row)
            if MPI.COMM_WORLD.rank == 0:
                print(
                    f"{estimator:12s} run {k}: {row['levels']} levels, {row['dofs']} DoFs, "
                    f"eta {row['eta']:.4e}, error {row['error']:.4e} (effectivity "
                    f"{row['effectivity']:.2f}), CPU {row['cpu']:.2f} s (estimate wall "
                    f"{row['seconds_estimate']:.2f} s)",
                    flush=True,
                )
    suffix = "" if MPI.COMM_WORLD.size == 1 else f"_np{MPI.COMM_WORLD.size}"
    save_csv(Path(args.out) / f"estimators{suffix}.csv", rows)


if __name__ == "__main__":
    main()
