"""Benchmark: semismooth Newton (fb, min, blend) against PETSc's VI solvers.

What it shows: on one scene and mesh, from the same cold start u = 0 and with the same
linear solver, how many Newton iterations each method needs and how long it takes end to
end (assembly + all Newton steps).  fb and blend polish the active set (``solver.polish``,
the default; each polishing solve is counted in ``polish``); ``fb-nopolish`` and
``blend-nopolish`` are the pure Newton methods.  Each method runs in its own process so
that the peak memory (max RSS) is its own.  Prints a table and writes CSV.

    python demos/bench/bench_newton.py --cells 512 --out bench/newton_512.csv
    python demos/bench/bench_newton.py --cells 512 --np 2 --out bench/newton_512_np2.csv
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

from contact.output.folder import write_csv

METHODS = ("fb", "min", "blend", "vinewtonrsls", "vinewtonssls", "fb-nopolish", "blend-nopolish")


def one(scene: str, cells: int, method: str, extra: list[str]) -> dict:
    """Solve once (in this process) and return the figures."""
    import contact
    from contact.solvers import method_variant

    from mpi4py import MPI

    t0 = time.perf_counter()
    name, variant = method_variant(method)
    s = contact.load_scene(scene, [f"mesh.cells=[{cells},{cells}]", "solver.max_it=200", *extra])
    r = contact.solve(s, method=name, verbose=False, **variant)
    wall = time.perf_counter() - t0
    rss = (
        MPI.COMM_WORLD.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, op=MPI.SUM)
        / 1024
    )
    return {
        "method": method,
        "cells": cells,
        "dofs": r.dofs,
        "ranks": MPI.COMM_WORLD.size,
        "converged": r.converged,
        "reason": r.reason,
        "iterations": r.iterations,
        "polish": r.polish_solves,
        "linear_solves": r.linear_solves,
        "active": r.n_active,
        "seconds": round(wall, 3),
        "seconds_solve": round(r.timings["total"], 3),
        "seconds_per_iteration": round(r.timings["total"] / max(r.linear_solves, 1), 3),
        "linear_solve_seconds": round(r.timings["solve"], 3),
        "peak_rss_mib": round(rss, 1),
        "c": r.options["c"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--scene", default="configs/signorini_square.yaml")
    ap.add_argument("--cells", type=int, default=512)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--set", dest="extra", action="append", default=[], help="scene override")
    ap.add_argument("--out", default="bench/newton.csv")
    ap.add_argument("--np", type=int, default=1, help="MPI ranks for each solve (mpirun -n NP)")
    ap.add_argument("--one", help=argparse.SUPPRESS)  # internal: run one method, print JSON
    args = ap.parse_args()
    if args.one:
        row = one(args.scene, args.cells, args.one, args.extra)
        from mpi4py import MPI

        if MPI.COMM_WORLD.rank == 0:
            print("ROW " + json.dumps(row), flush=True)
        return
    launcher = (
        [str(Path(sys.executable).parent / "mpirun"), "-n", str(args.np)] if args.np > 1 else []
    )
    if "PMI_SIZE" in os.environ or "OMPI_COMM_WORLD_SIZE" in os.environ:
        sys.exit("run the benchmark driver serially; use --np N to give each solve N ranks")
    rows = []
    print(
        f"{'method':>14s} {'DoFs':>8s} {'its':>4s} {'pol':>3s} {'seconds':>8s} "
        f"{'s/solve':>7s} {'lin.solve':>9s} "
        f"{'peak MiB':>9s}  reason"
    )
    for m in args.methods.split(","):
        cmd = launcher + [
            sys.executable,
            __file__,
            "--one",
            m,
            "--scene",
            args.scene,
            "--cells",
            str(args.cells),
        ]
        for e in args.extra:
            cmd += ["--set", e]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        line = [ln for ln in proc.stdout.splitlines() if ln.startswith("ROW ")]
        if proc.returncode or not line:
            print(f"{m:>14s} failed: {proc.stderr.strip().splitlines()[-1:]}")
            continue
        row = json.loads(line[0][4:])
        rows.append(row)
        print(
            f"{m:>14s} {row['dofs']:8d} {row['iterations']:4d} {row['polish']:3d} "
            f"{row['seconds']:8.2f} "
            f"{row['seconds_per_iteration']:7.2f} {row['linear_solve_seconds']:9.2f} "
            f"{row['peak_rss_mib']:9.1f}  {row['reason']}",
            flush=True,
        )
    ref = {r["method"]: r for r in rows}.get("vinewtonrsls")
    if ref:
        for r in rows:
            r["speedup_vs_vinewtonrsls"] = round(ref["seconds"] / r["seconds"], 2)
        print(
            "speed-up against vinewtonrsls (end to end): "
            + ", ".join(f"{r['method']} {r['speedup_vs_vinewtonrsls']:.2f}x" for r in rows)
        )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_csv(out, rows)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
