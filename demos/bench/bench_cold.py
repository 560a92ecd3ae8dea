"""Benchmark: the cold start of deal.II's step-41 obstacle problem, inexact Newton's forcing rules.

What it shows: one solve of ``configs/peers/dealii_step41.yaml`` (the membrane on a
stair-step obstacle, deal.II tutorial step-41) from u = 0 without grid sequencing
(``solver.sequence: off``, the path a user takes whenever sequencing cannot apply), method
``min`` (= the primal-dual active set method of step-41), CG + GAMG on the reduced Newton
system, on N × N cells, for each forcing rule of inexact Newton (``--variants``):

* ``new`` — ``solver.forcing: active_set`` (the default): the Krylov tolerance of a Newton
  step after one that changed statuses is loose (Eisenstat–Walker's η, at least 1e-2, at
  most 0.1), the Krylov solve warm-started from the last direction;
* ``zero`` — the same, the Krylov solves from zero (PETSc option ``reduced_warm_start
  false``): what the warm start adds;
* ``old`` — ``solver.forcing: eisenstat_walker``, the rule before: Eisenstat–Walker's
  forcing, tightened tenfold after every step that did not halve ‖Φ‖;
* ``each`` — ``new`` with the residual K x − b computed at each look at an iterate (PETSc
  option ``reuse_residual false``, the path before it was computed once per iterate).

Per row: Newton steps, Krylov iterations, GAMG set-ups, the solve's CPU and wall seconds
(assembly of K included: everything after the mesh exists), the final ‖Φ‖, the largest
nodal difference to the first variant's solution, and the ratio to ONE CG + GAMG solve of
K (rtol 1e-8 from zero, set-up included) measured in the same process just before — and
the CPU ratio of each variant to the first.  CPU seconds are the fair figure on a shared
machine.  ``--dealii-cpu`` (seconds) adds the ratio to deal.II step-41's CPU time at the
largest N (measured apart: the tutorial built from Debian's libdeal.ii-doc, see
demos/RESULTS.md).  Every solve runs to the default tolerances and the default step limit
``solver.max_it: auto`` (the nodes across Ω: 255, 511, 1023; the cold path takes 39, 75
and 144 steps, above the fixed 50 of before from 512² on); ``--max-it N`` sets a number.

    python demos/bench/bench_cold.py --cells 256 512 --out demos/results/cold/step41.csv
    python demos/bench/bench_cold.py --cells 1024 --variants new,old \
        --out demos/results/cold/step41_1024.csv

``--dealii BINARY`` runs deal.II's step-41 instead, once per ``--cells`` N (built from
Debian's libdeal.ii-doc 9.4.1: ``cp -r /usr/share/doc/libdeal.ii-doc/examples/step-41 .``;
in step-41.cc ``refine_global(7)`` made ``refine_global(step41_refinements)``, a global
``unsigned int step41_refinements`` set from ``argv[1]`` in ``main`` — N = 2^r Q1 cells a
side, the same (N + 1)² nodes as our N × N scene — and the call ``output_results(iteration)``
commented out, so that no VTU file is written per iteration; ``cmake
-DCMAKE_BUILD_TYPE=Release . && make``) as a child process and writes its CPU seconds
(user + system of the child, ``RUSAGE_CHILDREN``), wall seconds, Newton iterations and CG
iterations (parsed from its output) to ``--out``, which demos/make_results.py holds against
the rows above:

    python demos/bench/bench_cold.py --dealii step-41/step-41 --cells 256 512 \
        --out demos/results/cold/dealii_step41.csv

``--pair BINARY`` alternates the two, deal.II's run then ours (rule ``new``, the defaults),
``--repeat`` pairs per N, and writes each pair's CPU seconds and their ratio: on a shared
machine the ratio within a pair is the fair figure:

    nice python demos/bench/bench_cold.py --pair step-41/step-41 --cells 512 --repeat 2 \
        --out demos/results/cold/pair_step41_512.csv
"""

from __future__ import annotations

import argparse
import time

import contact
from contact.output.folder import gather_nodal

import numpy as np
from bench_cost import one_linear_solve
from common import save_csv
from mpi4py import MPI

SCENE = "configs/peers/dealii_step41.yaml"
#: variant -> (solver.forcing, warm start)
VARIANTS = {
    "new": ("active_set", True),
    "zero": ("active_set", False),
    "old": ("eisenstat_walker", False),
    "each": ("active_set", True),
}
#: variant -> PETSc options of its own (``each``: the residual at each of SNES's, the
#: monitor's, the Jacobian's and the cycle guard's look at an iterate, the path before)
OPTIONS = {"zero": {"reduced_warm_start": "false"}, "each": {"reuse_residual": "false"}}


def cold_solve(n: int, variant: str, max_it: int | str, method: str):
    """(wall s, CPU s, Result) of one cold solve on n × n cells with ``variant``'s rule."""
    forcing = VARIANTS[variant][0]
    overrides = [
        f"mesh.cells=[{n},{n}]",
        "solver.sequence=off",
        f"solver.max_it={max_it}",
        f"solver.method={method}",
        f"solver.forcing={forcing}",
        "output.verbose=false",
    ]
    if variant in OPTIONS:
        given = ", ".join(f"{k}: {v}" for k, v in OPTIONS[variant].items())
        overrides.append(f"solver.petsc_options={{{given}}}")
    scene = contact.load_scene(SCENE, overrides)
    MPI.COMM_WORLD.barrier()
    t0, c0 = time.perf_counter(), time.process_time()
    r = contact.solve(scene, verbose=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    comm = MPI.COMM_WORLD
    return comm.allreduce(wall, op=MPI.MAX), comm.allreduce(cpu, op=MPI.MAX), r


def dealii_run(binary: str, n: int) -> dict:
    """One run of deal.II's step-41 ``binary`` (in its folder) on n × n cells: its CPU
    (user + system of the child) and wall seconds, Newton and CG iterations (module doc)."""
    import re
    import resource
    import subprocess
    from pathlib import Path

    exe = Path(binary).resolve()
    refinements = int(round(np.log2(n)))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(
        [str(exe), str(refinements)], cwd=exe.parent, capture_output=True, text=True
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    text = proc.stdout
    dofs = re.search(r"Number of degrees of freedom: (\d+)", text)
    newton = re.findall(r"Newton iteration (\d+)", text)
    cg = [int(k) for k in re.findall(r"in (\d+) CG iterations", text)]
    row = {
        "code": "deal.II step-41",
        "cells": 2**refinements,
        "dofs": int(dofs.group(1)) if dofs else None,
        "returncode": proc.returncode,
        "newton_iterations": len(newton),
        "cg_iterations": sum(cg),
        "cpu_s": round(cpu, 2),
        "wall_s": round(wall, 2),
    }
    print(
        f"deal.II step-41 {row['cells']}²: {row['dofs']} DoFs, {len(newton)} Newton "
        f"iterations, {sum(cg)} CG iterations, cpu {cpu:.1f} s, wall {wall:.1f} s, "
        f"exit {proc.returncode}",
        flush=True,
    )
    return row


def run_dealii(binary: str, cells: list[int], out: str) -> None:
    """Run deal.II's step-41 ``binary`` once per N of ``cells``; its rows to ``out``."""
    save_csv(out, [dealii_run(binary, n) for n in cells])


def run_pairs(
    binary: str, cells: list[int], repeat: int, max_it: int | str, method: str, out: str
) -> None:
    """deal.II's step-41 and our cold solve (rule ``new``) alternated, ``repeat`` pairs per
    N: each pair in the same window of a shared machine, so that the CPU ratio of the pair
    is the figure (``--pair``; serial)."""
    cold_solve(16, "new", max_it, method)  # warm-up: forms, first touch
    rows = []
    for n in cells:
        for k in range(repeat):
            peer = dealii_run(binary, n)
            _, cpu, r = cold_solve(n, "new", max_it, method)
            row = {
                "cells": n,
                "dofs": r.dofs,
                "pair": k + 1,
                "method": method,
                "converged": r.converged,
                "max_it": r.max_it,
                "newton": r.iterations,
                "krylov": r.krylov_iterations,
                "cpu_s": round(cpu, 2),
                "dealii_dofs": peer["dofs"],
                "dealii_returncode": peer["returncode"],
                "dealii_newton": peer["newton_iterations"],
                "dealii_cg": peer["cg_iterations"],
                "dealii_cpu_s": peer["cpu_s"],
                "ratio_cpu_vs_dealii": round(cpu / peer["cpu_s"], 3),
            }
            rows.append(row)
            print(
                f"pair {k + 1} {n}²: ours {r.iterations} Newton, {r.krylov_iterations} Krylov, "
                f"converged {r.converged} (max_it {r.max_it}), cpu {cpu:.1f} s; deal.II "
                f"{peer['newton_iterations']} Newton, cpu {peer['cpu_s']:.1f} s; "
                f"ratio {row['ratio_cpu_vs_dealii']:.3f}",
                flush=True,
            )
            save_csv(out, rows)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cells", type=int, nargs="+", default=[256, 512, 1024])
    ap.add_argument("--variants", default="new,zero,old", help=f"of {', '.join(VARIANTS)}")
    ap.add_argument("--method", default="min")
    ap.add_argument("--max-it", default="auto", help="Newton steps: auto or a number")
    ap.add_argument(
        "--dealii-cpu",
        type=float,
        default=None,
        help="deal.II step-41's CPU seconds at the largest N (measured apart)",
    )
    ap.add_argument("--dealii", default=None, help="run this step-41 binary instead (module doc)")
    ap.add_argument(
        "--pair", default=None, help="alternate this step-41 binary with our solve (module doc)"
    )
    ap.add_argument("--repeat", type=int, default=1, help="--pair: pairs per N")
    ap.add_argument("--out", default="demos/results/cold/step41.csv")
    args = ap.parse_args()
    if args.dealii:
        run_dealii(args.dealii, args.cells, args.out)
        return
    if args.pair:
        run_pairs(args.pair, args.cells, args.repeat, args.max_it, args.method, args.out)
        return
    variants = args.variants.split(",")
    say = MPI.COMM_WORLD.rank == 0
    cold_solve(16, variants[0], args.max_it, args.method)  # warm-up: forms, first touch
    rows = []
    for n in args.cells:
        scene = contact.load_scene(SCENE, [f"mesh.cells=[{n},{n}]", "output.verbose=false"])
        ref_wall, ref_cpu, ref_its = one_linear_solve(scene)
        first_u, first_cpu = None, None
        for variant in variants:
            wall, cpu, r = cold_solve(n, variant, args.max_it, args.method)
            _, u = gather_nodal(r.u_h)
            if first_u is None:
                first_u, first_cpu = u, cpu
            diff = float(np.max(np.abs(u - first_u))) if say else float("nan")
            setups = sum(entry.get("setups", 0) for entry in r.krylov_log)
            row = {
                "cells": n,
                "dofs": r.dofs,
                "ranks": MPI.COMM_WORLD.size,
                "method": args.method,
                "variant": variant,
                "forcing": VARIANTS[variant][0],
                "warm_start": VARIANTS[variant][1],
                "converged": r.converged,
                "newton": r.iterations,
                "krylov": r.krylov_iterations,
                "krylov_per_step": round(r.krylov_iterations / max(r.iterations, 1), 2),
                "gamg_setups": setups,
                "residual": f"{r.residual:.3e}",
                "cpu_s": round(cpu, 3),
                "wall_s": round(wall, 3),
                "cpu_vs_first": round(cpu / first_cpu, 3),
                "ref_its": ref_its,
                "ref_cpu_s": round(ref_cpu, 3),
                "ratio_cpu_vs_one_solve": round(cpu / ref_cpu, 2),
                "max_diff_vs_first": diff,
                "dealii_cpu_s": args.dealii_cpu if n == max(args.cells) else None,
                "ratio_cpu_vs_dealii": (
                    round(cpu / args.dealii_cpu, 3)
                    if args.dealii_cpu and n == max(args.cells)
                    else None
                ),
            }
            rows.append(row)
            if say:
                dealii = (
                    f"  / deal.II {row['ratio_cpu_vs_dealii']:.2f}"
                    if row["ratio_cpu_vs_dealii"]
                    else ""
                )
                print(
                    f"{n:5d}² {r.dofs:8d} DoFs {variant:>5s} ({row['forcing']}, warm "
                    f"{row['warm_start']}): newton {r.iterations:3d} krylov "
                    f"{r.krylov_iterations:5d} ({row['krylov_per_step']:5.1f}/step, "
                    f"{setups} set-ups) |Phi| {r.residual:.2e} converged {r.converged}  "
                    f"cpu {cpu:7.2f} s (x{row['cpu_vs_first']:.2f} of {variants[0]}; "
                    f"{row['ratio_cpu_vs_one_solve']:.1f} CG+GAMG solves of {ref_cpu:.2f} s)"
                    f"{dealii}  diff {diff:.1e}",
                    flush=True,
                )
    save_csv(args.out, rows)


if __name__ == "__main__":
    main()
