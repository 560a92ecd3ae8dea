"""Adaptive stopping against fixed tolerances (issue 30, item 3): the adaptive loop of
problem A (configs/signorini_free_boundary.yaml, ``estimator: equilibrated``, CG + GAMG
Newton systems: ``solver.linear: gamg``) run to the same final η (``adapt.tol``) with
``solver.stopping: fixed`` (today's rtol / atol and Eisenstat–Walker forcing terms) and
``adaptive`` (contact/solvers/stopping.py: Newton stops at η_lin ≤ γ_lin η_disc, CG at
η_alg ≤ γ_alg (η_disc + η_lin)).  Per run: levels, final DoFs, η and energy error, total
Krylov iterations, Newton iterations and polishing solves, and the wall and CPU seconds
of the loop (CPU seconds of the busiest rank: on a shared machine the steadier measure;
``cpu_*``: the loop's phases);
the runs alternate (``--repeat``) so that the machine's load hits both, and the verdict
compares the best run of each.
Prints each mode's CPU seconds (min / median / max over the runs) and a verdict against the
acceptance (≥ 2× fewer Krylov iterations, less wall time, final errors within 5 %);
``--modes fixed adaptive adaptive_sa`` also runs adaptive stopping with smoothed-aggregation
GAMG, its preconditioner before it took plain aggregation.  Writes ``stopping.csv`` (one
row per run) and
``stopping_levels.csv`` (one row per level: η_disc, η_lin, η_alg, Krylov iterations).

    python demos/bench/bench_stopping.py --tol 2e-3 --out demos/results/stopping
    mpirun -n 2 python demos/bench/bench_stopping.py --tol 2e-3 --out demos/results/stopping

``--scene hertz_2d`` runs the elastic Hertz scene instead (configs/hertz_2d.yaml: CG + GAMG
with the rigid-body near-nullspace; η_disc the weakly symmetric equilibrated stress's bound
of contact/adaptivity/equilibration/elastic.py), writing ``stopping_hertz_2d*.csv``:

    python demos/bench/bench_stopping.py --scene hertz_2d --tol 1.2e-4 --out demos/results/stopping

There the estimate (the C kernels of contact/adaptivity/equilibration/stress_c.py) is still
80 % of the loop's CPU, so adaptive stopping saves 6 % of the loop (0.35–0.4 s of solve): on an
idle machine less CPU and wall time in every pair of ``--repeat 5``; on a loaded one the
estimate's run-to-run spread can be larger than that.

Figures: README ("Adaptive stopping") and demos/RESULTS.md §12.
"""

from __future__ import annotations

import argparse
import collections
import time
from pathlib import Path

import contact

from common import PHASES, count_phase_cpu, elastic_reference, energy_distance, save_csv
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[2]
MODES = ("fixed", "adaptive")
#: further modes (``--modes``): adaptive stopping with smoothed-aggregation GAMG, the
#: preconditioner it used before it took plain aggregation (contact/solvers/snes.py)
VARIANTS = {
    "adaptive_sa": ["solver.stopping=adaptive", "solver.petsc_options.pc_gamg_agg_nsmooths=1"]
}
#: the CPU seconds of the loop's phases (common.count_phase_cpu)
CPU: dict[str, float] = collections.defaultdict(float)
#: the final (scene, u_h) of each run, for the errors against a reference (hertz_2d)
FINAL: list = []


def run(mode: str, tol: float, extra: list[str], scene_name: str) -> tuple[dict, list[dict]]:
    """One adaptive loop of the scene (problem A by default) to η ≤ ``tol``; (the run's row,
    its levels' rows)."""
    sets = [
        "estimator=equilibrated",
        "output.verbose=false",
        "solver.linear=gamg",
        *([f"solver.stopping={mode}"] if mode in MODES else VARIANTS[mode]),
        f"adapt.tol={tol}",
        "adapt.max_levels=60",
        "adapt.max_dofs=5000000",
        *extra,
    ]
    scene = contact.load_scene(ROOT / "configs" / f"{scene_name}.yaml", sets)
    MPI.COMM_WORLD.Barrier()
    CPU.clear()
    t0, c0 = time.perf_counter(), time.process_time()
    out = contact.adapt(scene)
    wall = MPI.COMM_WORLD.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    cpu = MPI.COMM_WORLD.allreduce(time.process_time() - c0, op=MPI.MAX)
    levels = [{"mode": mode, **lv.row()} for lv in out.levels]
    last = out.levels[-1]
    FINAL.append((last.scene, last.result.u_h))
    row = {
        "mode": mode,
        "ranks": MPI.COMM_WORLD.size,
        "tol": tol,
        "levels": len(levels),
        "dofs": last.result.dofs,
        "eta": last.estimate.eta,
        "error": last.error,
        "krylov_iterations": sum(r["krylov_iterations"] for r in levels),
        "newton_iterations": sum(r["newton_iterations"] for r in levels),
        "polish_solves": sum(r["polish_solves"] for r in levels),
        "solve_passes": sum(r["solve_passes"] for r in levels),
        "seconds_solve": round(sum(r["seconds_solve"] for r in levels), 3),
        "seconds_estimate": round(sum(r["seconds_estimate"] for r in levels), 3),
        "wall": round(wall, 3),
        "cpu": round(cpu, 3),
        **{
            f"cpu_{k}": round(MPI.COMM_WORLD.allreduce(CPU[k], op=MPI.MAX), 3)
            for k in PHASES.values()
        },
        "stop": out.stop,
    }
    return row, levels


def spread(rows: list[dict]) -> str:
    """CPU seconds of each mode's runs: min / median / max."""
    out = []
    for m in dict.fromkeys(r["mode"] for r in rows):
        cpu = sorted(r["cpu"] for r in rows if r["mode"] == m)
        out.append(f"{m} {cpu[0]:.2f} / {cpu[len(cpu) // 2]:.2f} / {cpu[-1]:.2f} s")
    return "CPU min / median / max: " + ", ".join(out)


def verdict(rows: list[dict]) -> str:
    best = {m: min((r for r in rows if r["mode"] == m), key=lambda r: r["cpu"]) for m in MODES}
    f, a = best["fixed"], best["adaptive"]
    ratio = f["krylov_iterations"] / max(a["krylov_iterations"], 1)
    err = abs(a["error"] - f["error"]) / f["error"]
    return (
        f"Krylov iterations {f['krylov_iterations']} -> {a['krylov_iterations']} "
        f"({ratio:.2f}x fewer, "
        f">= 2: {ratio >= 2}); CPU (best of runs) {f['cpu']:.2f} -> {a['cpu']:.2f} s "
        f"(less: {a['cpu'] < f['cpu']}; wall {f['wall']:.2f} -> {a['wall']:.2f} s); "
        f"final error {f['error']:.4e} -> {a['error']:.4e} "
        f"({100 * err:.2f} %, <= 5 %: {err <= 0.05}); "
        f"final eta {f['eta']:.4e} / {a['eta']:.4e}, "
        f"DoFs {f['dofs']} / {a['dofs']}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--tol", type=float, default=2e-3, help="adapt.tol: the final η of both runs")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each mode, alternating")
    ap.add_argument("--set", action="append", default=[], help="further scene overrides")
    ap.add_argument(
        "--scene",
        default="signorini_free_boundary",
        choices=("signorini_free_boundary", "hertz_2d"),
        help="the scene (configs/NAME.yaml): problem A or the elastic Hertz cylinder",
    )
    ap.add_argument(
        "--modes",
        nargs="+",
        default=list(MODES),
        choices=[*MODES, *VARIANTS],
        help="the modes to run, alternating (fixed and adaptive give the verdict)",
    )
    ap.add_argument("--out", default="demos/results/stopping")
    args = ap.parse_args()
    count_phase_cpu(CPU)
    rows, levels = [], []
    for k in range(args.repeat):
        for mode in args.modes:
            row, lv = run(mode, args.tol, args.set, args.scene)
            rows.append({"run": k, **row})
            levels += [{"run": k, **r} for r in lv]
            if MPI.COMM_WORLD.rank == 0:
                print(
                    f"{mode:8s} run {k}: {row['levels']} levels, {row['dofs']} DoFs, "
                    f"eta {row['eta']:.4e}, "
                    f"error {row['error'] or float('nan'):.4e}, "
                    f"Krylov {row['krylov_iterations']}, Newton "
                    f"{row['newton_iterations']} (+{row['polish_solves']}), "
                    f"wall {row['wall']:.2f} s, CPU {row['cpu']:.2f} s (of which solve "
                    f"{row['cpu_solve']:.2f}, estimate {row['cpu_estimate']:.2f}, refine "
                    f"{row['cpu_refine']:.2f})",
                    flush=True,
                )
    if rows[0]["error"] is None:  # no exact solution: a reference 4× finer than run 0's last
        ref = elastic_reference(*FINAL[0])  # mesh (fixed mode), the same for every run
        for row, (_, u_h) in zip(rows, FINAL):
            row.update(error=energy_distance(ref, u_h), reference_dofs=ref.dofs)
        if MPI.COMM_WORLD.rank == 0:
            print(f"errors against a reference solution with {ref.dofs} DoFs", flush=True)
    if MPI.COMM_WORLD.rank == 0:
        print(spread(rows), flush=True)
        if set(MODES) <= set(args.modes):
            print(verdict(rows), flush=True)
    suffix = "" if MPI.COMM_WORLD.size == 1 else f"_np{MPI.COMM_WORLD.size}"
    if args.scene != "signorini_free_boundary":
        suffix = f"_{args.scene}{suffix}"
    save_csv(Path(args.out) / f"stopping{suffix}.csv", rows)
    save_csv(Path(args.out) / f"stopping_levels{suffix}.csv", levels)


if __name__ == "__main__":
    main()
