"""Benchmark: the cost of a contact solve measured in linear solves (issue 11).

What it shows: for each mesh, the wall (and CPU) time of one contact solve — everything
after the scene's mesh exists: assembly, the coarse levels of grid sequencing, the Newton
steps on the mesh asked for — divided by the time of ONE CG + GAMG solve of the stiffness
matrix K (PETSc defaults, rtol 1e-8, from zero, GAMG setup included; with the rigid-body
near-nullspace for elasticity), measured in the same process, alternating, ``--repeat``
times (medians).  With and without grid sequencing, per method.  Also the Newton steps and
polishing solves on the finest mesh, the linear solves of all levels weighted by their
DoFs (the work in units of one fine solve), and the largest nodal difference to the answer
of the solver as it was before issue 11 (a cold start with MUMPS, and κ = 100 for the
square; BiCGStab + GAMG in 3D).

    python demos/bench/bench_cost.py square --cells 128 256 512 1024 \
        --out demos/results/cost/square.csv
    python demos/bench/bench_cost.py hertz3d --out demos/results/cost/hertz3d.csv
    mpirun -n 2 python demos/bench/bench_cost.py hertz3d --set adapt.theta=0.3 \
        --max-dofs 1600000 --no-before --sequence auto --repeat 1 \
        --out demos/results/cost/hertz3d_np2.csv          (a 3D mesh of > 1M DoFs)
    mpirun -n 2 python demos/bench/bench_cost.py scene --scene configs/friction_box_3d.yaml \
        --set friction.law=none --set "mesh.cells=[96,96,48]" --no-before --sequence auto \
        --repeat 1 --out demos/results/cost/box3d_np2.csv
    cd demos/bench && mpirun -n 2 python bench_cost.py scene \
        --scene ../../configs/two_body_hertz_3d.yaml --set mesh.h_contact=0.0025 \
        --set adapt=null --no-before --methods fb --sequence auto --repeat 1 \
        --out ../results/cost/two_body_hertz_3d_np2.csv     (two bodies, 480k DoFs; 2D likewise:
        two_body_hertz_2d.yaml, mesh.h_contact=0.00265, about 1M DoFs)
    python demos/bench/bench_cost.py chart demos/results/cost      (cost.png from every CSV there)

Frictional load paths (issue 29), ``path``: every load step of ``--scene`` timed on its own
(CPU and wall from the end of the step before: the step's problem, its coarse levels, its
Newton steps) against one CG + GAMG solve of K of the scene measured in the same process
before and after the path (medians), per ``--variants``: ``new`` (the defaults: the first
step and every later step grid-sequenced, the secant predictor, ``solver.linear: auto``),
``old`` (the path before issue 29: no sequencing, no predictor, MUMPS on H; ``old-bcgs``
with BiCGStab + GAMG, the old 3D default), ``gmres`` / ``direct`` (the defaults with that
linear solver), ``noseq`` (no sequencing), ``nopred`` (no predictor), ``lag`` (GAMG lagged
across Newton steps, the block system's default before it took a set-up per step); the
last step's largest nodal difference to the first variant's:

    mpirun -n 2 python demos/bench/bench_cost.py path --scene configs/friction_box_3d.yaml \
        --set "mesh.cells=[72,72,36]" --times 0.5,0.75,1 --variants new,lag \
        --out demos/results/cost/friction_box_3d_np2.csv
    mpirun -n 2 python demos/bench/bench_cost.py path --scene configs/two_body_cattaneo_2d.yaml \
        --set mesh.h_contact=0.0022 --times 0.5,0.625,0.75 --variants new,lag \
        --out demos/results/cost/two_body_cattaneo_2d_np2.csv

``square`` uses configs/signorini_square.yaml with its defaults (cells changed);
``hertz3d`` runs configs/hertz_3d.yaml's adaptive loop (up to ``--max-dofs``) and
measures on its final mesh, whose coarser levels are the loop's earlier meshes; ``scene``
measures one solve of ``--scene`` on the mesh its ``--set`` options give (e.g. the 3D box of
configs/friction_box_3d.yaml without friction at 96×96×48 cells, 1.38M DoFs, whose coarser
levels are boxes of cells/2^k; the two-body Hertz scenes, whose coarser levels are gmsh
meshes of sizes h·2^k, h_contact·2^k, and whose K is Qᵀ K Q of the mortar change of basis).
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import contact
from contact.output.folder import gather_nodal
from contact.setup.build import build_problem

import numpy as np
from common import save_csv
from mpi4py import MPI
from petsc4py import PETSc


def one_linear_solve(scene) -> tuple[float, float, int]:
    """(wall s, CPU s, iterations) of one CG + GAMG solve of K, rtol 1e-8, from zero."""
    p = build_problem(scene)
    if p.near_nullspace is not None:
        p.K.setNearNullSpace(p.near_nullspace)
    ksp = PETSc.KSP().create(scene.comm)
    ksp.setOperators(p.K)
    ksp.setType("cg")
    ksp.getPC().setType("gamg")
    ksp.setTolerances(rtol=1e-8)
    x = p.b.duplicate()
    x.set(0.0)
    scene.comm.barrier()
    t0, c0 = time.perf_counter(), time.process_time()
    ksp.solve(p.b, x)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    its = ksp.getIterationNumber()
    for obj in (ksp, x, p.K, p.b):
        obj.destroy()
    return max_over_ranks(wall), max_over_ranks(cpu), its


def max_over_ranks(value: float) -> float:
    return MPI.COMM_WORLD.allreduce(value, op=MPI.MAX)


def contact_solve(scene, method: str, sequence: str, **options):
    MPI.COMM_WORLD.barrier()
    t0, c0 = time.perf_counter(), time.process_time()
    seq = int(sequence) if sequence.isdigit() else sequence  # a number of coarser levels
    r = contact.solve(scene, method=method, sequence=seq, verbose=False, **options)
    return max_over_ranks(time.perf_counter() - t0), max_over_ranks(time.process_time() - c0), r


def measure(
    case: str, scene, methods: list[str], sequences: list[str], repeat: int, reference: dict | None
) -> list[dict]:
    """Rows for one scene: every method × sequencing setting, ``repeat`` alternations of
    one linear solve and one contact solve; the largest nodal difference to the solve of
    options ``reference`` (None: not compared)."""
    rows = []
    say = MPI.COMM_WORLD.rank == 0
    contact_solve(scene, methods[0], "auto")  # warm-up: JIT compilation, first-touch
    u_ref = (
        None
        if reference is None
        else gather_nodal(contact.solve(scene, verbose=False, **reference).u_h)[1]
    )
    for method in methods:
        for sequence in sequences:
            refs, runs = [], []
            for _ in range(repeat):
                refs.append(one_linear_solve(scene))
                runs.append(contact_solve(scene, method, sequence))
            r = runs[-1][2]
            _, u = gather_nodal(r.u_h)
            diff = float(np.max(np.abs(u - u_ref))) if say and u_ref is not None else float("nan")
            ref_wall = statistics.median(w for w, _, _ in refs)
            ref_cpu = statistics.median(c for _, c, _ in refs)
            wall = statistics.median(w for w, _, _ in runs)
            cpu = statistics.median(c for _, c, _ in runs)
            row = {
                "case": case,
                "dofs": r.dofs,
                "ranks": MPI.COMM_WORLD.size,
                "method": method,
                "sequence": sequence,
                "levels": len(r.sequence) + 1,
                "coarse_dofs": " ".join(str(lv.dofs) for lv in r.sequence),
                "coarse_solves": r.coarse_linear_solves,
                "newton": r.iterations,
                "polish": r.polish_solves,
                "weighted_solves": round(r.weighted_linear_solves, 3),
                "krylov": r.krylov_iterations,
                "linear": r.linear,
                "converged": r.converged,
                "ref_its": refs[-1][2],
                "ref_wall_s": round(ref_wall, 3),
                "solve_wall_s": round(wall, 3),
                "ratio_wall": round(wall / ref_wall, 3),
                "ref_cpu_s": round(ref_cpu, 3),
                "solve_cpu_s": round(cpu, 3),
                "ratio_cpu": round(cpu / ref_cpu, 3),
                "ratio_wall_runs": " ".join(
                    f"{w / rw:.2f}" for (w, _, _), (rw, _, _) in zip(runs, refs)
                ),
                "max_diff_vs_before": diff,
                "repeat": repeat,
            }
            rows.append(row)
            if say:
                print(
                    f"{case:>10s} {r.dofs:9d} {method:>5s} seq {sequence:>4s}  fine "
                    f"{r.iterations}+{r.polish_solves} "
                    f"coarse {row['coarse_solves']:3d} weighted {row['weighted_solves']:5.2f}  "
                    f"ref {ref_wall:6.2f} s  solve {wall:7.2f} s  ratio {row['ratio_wall']:5.2f} "
                    f"(cpu {row['ratio_cpu']:5.2f})  diff {diff:.1e}",
                    flush=True,
                )
    return rows


#: load-path variants: --set options over the scene's (``path``)
VARIANTS = {
    "new": [],
    "gmres": ["solver.linear=gmres"],
    "direct": ["solver.linear=direct"],
    "noseq": ["solver.sequence=off"],
    "nopred": ["load.predictor=none"],
    "lag": ["solver.petsc_options.reduced_lag_pc=true"],
    "old": ["solver.sequence=off", "load.predictor=none", "solver.linear=direct"],
    "old-bcgs": ["solver.sequence=off", "load.predictor=none", "solver.linear=bcgs"],
}


def measure_path(
    path: str, overrides: list[str], times: list[float], variants: list[str], repeat: int
) -> list[dict]:
    """Rows for a load path of scene file ``path``: one per variant and step (module doc)."""
    say = MPI.COMM_WORLD.rank == 0
    load = ["load=none", "load={times: [" + ", ".join(f"{t:g}" for t in times) + "]}"]
    base = ["output.verbose=false", *overrides, *load]
    scene = contact.load_scene(path, base)
    # warm-up: first touch, and K's forms compiled (a first run on an empty JIT cache still
    # pays the friction and estimator forms in the first variant's first step)
    one_linear_solve(scene)
    rows, u_first = [], None
    for variant in variants:
        refs = [one_linear_solve(scene) for _ in range(repeat)]
        clock = [time.perf_counter(), time.process_time()]
        steps: list[dict] = []

        def on_step(step, clock=clock, steps=steps) -> None:
            wall, cpu = time.perf_counter() - clock[0], time.process_time() - clock[1]
            r = step.result
            steps.append(
                {
                    "step": step.index,
                    "t": step.time,
                    "dofs": r.dofs,
                    "newton": r.iterations,
                    "krylov": r.krylov_iterations,
                    "linear": r.linear,
                    "levels": len(r.sequence) + 1,
                    "coarse_dofs": " ".join(str(lv.dofs) for lv in r.sequence),
                    "coarse_solves": r.coarse_linear_solves,
                    "predictor": r.predictor,
                    "converged": r.converged,
                    "wall": max_over_ranks(wall),
                    "cpu": max_over_ranks(cpu),
                }
            )
            clock[:] = [time.perf_counter(), time.process_time()]

        variant_scene = contact.load_scene(path, [*base, *VARIANTS[variant]])
        MPI.COMM_WORLD.barrier()
        clock[:] = [time.perf_counter(), time.process_time()]  # the mesh exists: not timed
        run = contact.run_load_path(variant_scene, on_step=on_step)
        refs += [one_linear_solve(scene) for _ in range(repeat)]
        _, u = gather_nodal(run.steps[-1].result.u_h)
        if u_first is None:
            u_first = u
        diff = float(np.max(np.abs(u - u_first))) if say else float("nan")
        ref_wall = statistics.median(w for w, _, _ in refs)
        ref_cpu = statistics.median(c for _, c, _ in refs)
        for st in steps:
            row = {
                "case": scene.name,
                "ranks": MPI.COMM_WORLD.size,
                "method": scene.config.solver.method,
                "variant": variant,
                "sequence": "off" if "solver.sequence=off" in VARIANTS[variant] else "auto",
                **{k: v for k, v in st.items() if k not in ("wall", "cpu")},
                "ref_its": refs[-1][2],
                "ref_wall_s": round(ref_wall, 3),
                "step_wall_s": round(st["wall"], 3),
                "ratio_wall": round(st["wall"] / ref_wall, 3),
                "ref_cpu_s": round(ref_cpu, 3),
                "step_cpu_s": round(st["cpu"], 3),
                "ratio_cpu": round(st["cpu"] / ref_cpu, 3),
                "max_diff_vs_first": diff,
                "repeat": repeat,
            }
            rows.append(row)
            if say:
                print(
                    f"{scene.name:>22s} {row['dofs']:9d} {variant:>8s} step {row['step']} "
                    f"t={row['t']:g}: newton {row['newton']:2d} krylov {row['krylov']:4d} "
                    f"({row['linear']}, {row['levels']} levels, predictor {row['predictor']})  "
                    f"ref {ref_cpu:6.2f} s cpu  step {st['cpu']:7.2f} s cpu  ratio "
                    f"{row['ratio_cpu']:5.2f} (wall {row['ratio_wall']:5.2f})  diff {diff:.1e}",
                    flush=True,
                )
    return rows


def chart(folder: Path) -> Path:
    """cost.png from every CSV in ``folder``.  Left: the wall-time ratio of one solve (contact
    solve / one CG + GAMG solve of K) against the DoFs, one line per scene × method ×
    sequencing setting.  Right (``path`` rows): the CPU-time ratio of each load step of a
    frictional path — its first step and the worst later one — per variant (CPU: the fair
    figure on a shared machine, where the wall time of a long path drifts with the load)."""
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves: dict[tuple, list[tuple[int, float]]] = {}
    paths: dict[tuple, dict[int, dict[int, float]]] = {}  # (case, variant) → dofs → step → ratio
    for path in sorted(folder.glob("*.csv")):
        with open(path, newline="") as fh:
            for r in csv.DictReader(fh):
                ranks = f"{r['ranks']} rank{'s' if r['ranks'] != '1' else ''}"
                if r.get("step"):
                    key = (f"{r['case']} ({ranks})", r["variant"])
                    steps = paths.setdefault(key, {}).setdefault(int(r["dofs"]), {})
                    steps[int(r["step"])] = float(r["ratio_cpu"])
                    continue
                label = (f"{r['case']} ({ranks})", r["method"], r["sequence"])
                curves.setdefault(label, []).append((int(r["dofs"]), float(r["ratio_wall"])))
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, 5.2))
    colours = {"fb": "tab:blue", "min": "tab:orange", "blend": "tab:green"}
    markers = ["o", "s", "^", "D", "v", "P"]
    cases = sorted({k[0] for k in curves})
    for (case, method, sequence), pts in sorted(curves.items()):
        pts.sort()
        ax.plot(
            [p[0] for p in pts],
            [p[1] for p in pts],
            marker=markers[cases.index(case) % len(markers)],
            color=colours.get(method, "k"),
            linestyle="-" if sequence != "off" else "--",
            label=f"{case} {method}, sequence {sequence}",
        )
    ax.axhline(3.0, color="grey", lw=0.8, ls=":")
    ax.axhline(4.0, color="grey", lw=0.8, ls="-.")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("DoFs of the mesh asked for")
    ax.set_ylabel("contact solve / one CG + GAMG solve of K (wall)")
    ax.set_title("One solve (targets 3×: 2D, 4×: 3D)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    path_cases = sorted({k[0] for k in paths})
    for i, ((case, variant), by_dofs) in enumerate(sorted(paths.items())):
        dofs = sorted(by_dofs)
        mark = markers[path_cases.index(case) % len(markers)]
        colour = f"C{i % 10}"
        first = [by_dofs[n].get(1, float("nan")) for n in dofs]
        later = [max((v for k, v in by_dofs[n].items() if k > 1), default=np.nan) for n in dofs]
        bx.plot(dofs, first, marker=mark, color=colour, ls="none", mfc="none", ms=9)
        bx.plot(dofs, later, marker=mark, color=colour, ls="none", label=f"{case} {variant}")
    bx.axhline(3.0, color="grey", lw=0.8, ls=":")
    bx.axhline(6.0, color="grey", lw=0.8, ls="-.")
    bx.set_xscale("log")
    bx.set_yscale("log")
    bx.set_xlabel("DoFs")
    bx.set_ylabel("load step / one CG + GAMG solve of K (CPU)")
    bx.set_title(
        "Frictional load paths: first step (open) ≤ 6×, worst later step (filled) ≤ 3×",
        fontsize=10,
    )
    bx.grid(True, which="both", alpha=0.3)
    if paths:
        bx.legend(fontsize=7)
    fig.suptitle("Cost in linear solves")
    fig.tight_layout()
    out = folder / "cost.png"
    fig.savefig(out, dpi=120)
    plt.close(fig)
    print(f"wrote {out}", flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("case", choices=("square", "hertz3d", "scene", "path", "chart"))
    ap.add_argument(
        "--scene", default="configs/friction_box_3d.yaml", help="scene: its file (with --set)"
    )
    ap.add_argument(
        "folder", nargs="?", default="demos/results/cost", help="chart: the folder of the CSVs"
    )
    ap.add_argument("--cells", type=int, nargs="+", default=[128, 256, 512, 1024])
    ap.add_argument("--methods", default="fb,min")
    ap.add_argument(
        "--sequence",
        default="auto,off",
        help="sequencing settings to compare: auto, off or a number of coarser levels",
    )
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument(
        "--max-dofs", type=int, default=300000, help="hertz3d: DoF budget of the adaptive loop"
    )
    ap.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        help="hertz3d: scene overrides (e.g. adapt.theta=0.3 for a finer last step)",
    )
    ap.add_argument(
        "--no-before",
        action="store_true",
        help="skip the comparison with the solver as it was before (a cold solve: long in 3D)",
    )
    ap.add_argument("--times", default="0.5,0.75,1", help="path: the load steps' pseudo-times")
    ap.add_argument(
        "--variants", default="new,old", help=f"path: of {', '.join(VARIANTS)} (module doc)"
    )
    ap.add_argument("--out", default="bench/cost.csv")
    args = ap.parse_args()
    if args.case == "chart":
        if MPI.COMM_WORLD.rank == 0:
            chart(Path(args.folder))
        return
    methods, sequences = args.methods.split(","), args.sequence.split(",")
    rows = []
    if args.case == "square":
        before = {
            "method": "fb",
            "linear": "direct",
            "sequence": "off",
            "kappa": 100.0,
            "max_it": 200,
        }
        for n in args.cells:
            scene = contact.load_scene(
                "configs/signorini_square.yaml", [f"mesh.cells=[{n},{n}]", "output.verbose=false"]
            )
            rows += measure("square", scene, methods, sequences, args.repeat, before)
    elif args.case == "path":  # a load path, every step against one linear solve
        times = [float(t) for t in args.times.split(",")]
        rows += measure_path(
            args.scene, args.overrides, times, args.variants.split(","), args.repeat
        )
    elif args.case == "scene":  # one solve of a scene file on the mesh its --set options give
        scene = contact.load_scene(args.scene, ["output.verbose=false", *args.overrides])
        before = {"method": "fb", "linear": "bcgs", "sequence": "off", "max_it": 200}
        rows += measure(
            scene.name, scene, methods, sequences, args.repeat, None if args.no_before else before
        )
    else:
        scene = contact.load_scene(
            "configs/hertz_3d.yaml",
            [
                "output.verbose=false",
                f"adapt.max_dofs={args.max_dofs}",
                "adapt.max_levels=20",
                *args.overrides,
            ],
        )
        t0 = time.perf_counter()
        res = contact.adapt(scene, verbose=False)
        if MPI.COMM_WORLD.rank == 0:
            print(
                f"hertz_3d adaptive loop: {[lv.result.dofs for lv in res.levels]} DoFs, "
                f"{time.perf_counter() - t0:.1f} s",
                flush=True,
            )
        before = {"method": "fb", "linear": "bcgs", "sequence": "off", "max_it": 200}
        rows += measure(
            "hertz3d",
            res.levels[-1].scene,
            methods,
            sequences,
            args.repeat,
            None if args.no_before else before,
        )
    save_csv(args.out, rows)


if __name__ == "__main__":
    main()
