"""`make bench`: every benchmark and every shipped study, then the report demos/RESULTS.md.

The steps, each in its own process and timed (demos/results/timings.csv); every CSV and
chart goes to demos/results/ (committed with the report, so its numbers can be checked):

1. ``demos/bench/bench_newton.py --cells 512`` — the Newton methods on the 512² square (issue 2);
2. ``demos/bench/bench_adaptive.py`` — rates and effectivity of the adaptive loop (issue 3);
3. ``demos/bench/bench_hertz.py`` — Hertz 2D/3D, every method, direct and GAMG (issue 4);
   ``demos/bench/bench_memory.py`` — peak memory per DoF, the figures of ``solver.max_dofs:
   auto`` (issue 10; about 12 minutes);
   ``demos/bench/bench_friction.py`` — friction (issue 12, about 5 minutes);
   ``demos/bench/bench_friction_cycle.py`` — its tangential-form cases × line search basic /
   auto / bt: the projection form's 2-cycle and the guard, and with ``--rounding`` the
   cycling cases under perturbed loads and 1 / 2 BLAS threads (about 3 + 3 minutes);
   ``demos/bench/bench_two_bodies.py`` — two bodies (issue 13): patch tests, two cylinders,
   Cattaneo–Mindlin, and the sphere on a block on 2 MPI ranks (about 8 minutes; its
   508k-DoF row: ``mpirun -n 2 … sphere --h-contact 0.0025``, 9 more minutes), and with
   P1 and P2 serially (``sphere_degrees``, about 12 minutes on a loaded machine), P2 on
   straight and on curved cells (``p2``, ``p2sphere``: about 1.5 + 2.5 minutes), P2 cold
   against the start from P1 (``p1_start``, about 3 minutes; ``p1_start_floating``, the P2
   patch tests, under a minute);
   ``demos/bench/bench_newton_min_cycle.py`` — plain Newton-min cycling on a P-matrix LCP
   (the stability map's case (p), under a second);
   ``demos/bench/bench_cold.py`` — deal.II's step-41 from a cold start at 256² and 512², by
   inexact Newton's forcing rule (about 2 minutes; the 1024² rows and deal.II's own runs
   are separate commands, in its docstring);
   ``demos/bench/bench_cost.py`` — a cold contact solve against one CG + GAMG solve of K:
   the square 128² … 1024² with and without grid sequencing, hertz_3d's final mesh, a 3D mesh
   of about 1M DoFs on 2 MPI ranks, and the chart ``cost/cost.png`` (issue 11; about 12 minutes);
   ``demos/bench/bench_scale.py`` — adaptive runs end to end through the CLI: problem A to
   1.2M DoFs on 1 and 2 ranks, hertz_3d to 865k DoFs on 2 ranks (wall, peak memory, phases),
   and the 2-rank speed-up as the median of 3 paired runs;
   ``demos/bench/bench_error_quadrature.py`` — the energy error's quadrature degree (accuracy,
   cost); ``demos/bench/bench_kernels.py`` — block-CSR assembly and raster pictures against the old
   paths, (on 2 ranks) refinement with and without redistribution or a ghost layer, and (serially
   and on 2 ranks) the 2D floor of the finest level: refinement, ``create_mesh`` and
   assembly against one CG + GAMG solve;
   ``demos/bench/bench_bandwidth.py`` on 1 and 2 ranks — the machine's memory-bound speed-up;
   ``demos/bench/bench_hyperelastic.py`` — finite deformation (issue 31): plain Newton against
   the energy line search on nonconvex and buckling cases, the buckling strip against Euler,
   the neo-Hookean cylinder to 0.5 R under uniform refinement against vinewtonrsls, Coulomb
   friction between two neo-Hookean blocks in 2D and 3D, adaptivity and grid sequencing of two
   neo-Hookean cylinders, a tube kinked into self-contact (about 20 minutes);
   ``demos/bench/bench_ironing.py`` — the ironing benchmark in plane strain on three meshes,
   the die's forces against the sliding distance (about 2 minutes);
   ``demos/bench/bench_equilibrated.py`` (1 and 2 ranks, and its 2D / 3D cost),
   ``bench_estimators.py`` and ``bench_stopping.py`` (1 and 2 ranks) — guaranteed bounds,
   the two estimators, adaptive stopping (issue 30, RESULTS §12; about 40 minutes);
   ``demos/bench/bench_baselines.py`` — penalty, augmented Lagrangian and Nitsche against fb
   over their parameters and meshes (issue 44, RESULTS §13; about 25 minutes);
   ``demos/bench/bench_time_to_accuracy.py`` — the adaptive loop against uniform meshes at
   equal error (ex9, problem A and the L-shape; the loop's variants, adaptive P2 and hp
   against the same uniform P1 and P2 runs), ``bench_adaptive_profile.py ex9`` with growth
   2, with every level kept and with the earlier ones released (the loop's memory),
   ``bench_run_wall.py`` — ``contact run`` of ex9 on a level budget against the uniform run,
   whole processes in turn, ``bench_startup.py`` — ``import contact`` and a tiny run
   (issue 41, RESULTS §14; about 35 minutes);
   ``demos/bench/bench_hp.py`` — hp against h-adaptive P1 and P2 (RESULTS §15, minutes);
4. ``contact study configs/studies/<name>.yaml -o demos/results/<name>`` for every study
   file (speed against accuracy, stability map and its 1024² part ``stability_scale``, about 30
   minutes, iterations per level, peer problems);
5. ``demos/make_results.py`` — demos/RESULTS.md from the CSVs written above.

    python demos/run_bench.py                 # everything (about 2 hours on 2 cores;
    stability_scale alone 45 min) python demos/run_bench.py --only studies  # steps 4 and 5
    python demos/run_bench.py --only report   # step 5 on the existing CSVs

Studies run serially, one process each, so their timings do not disturb one another.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
CONTACT = str(Path(PY).parent / "contact")
MPIRUN = str(Path(PY).parent / "mpirun")
STEPS = {
    "newton": [
        [
            PY,
            "demos/bench/bench_newton.py",
            "--cells",
            "512",
            "--out",
            "demos/results/newton_512.csv",
        ]
    ],
    "adaptive": [[PY, "demos/bench/bench_adaptive.py", "--out", "demos/results/adaptive"]],
    "hertz": [[PY, "demos/bench/bench_hertz.py", "--out", "demos/results/hertz"]],
    "memory": [[PY, "demos/bench/bench_memory.py", "--out", "demos/results/memory.csv"]],
    "friction": [
        [PY, "demos/bench/bench_friction.py", "--out", "demos/results/friction"],
        [
            PY,
            "demos/bench/bench_friction_cycle.py",
            "--out",
            "demos/results/friction/line_search.csv",
        ],
        [
            PY,
            "demos/bench/bench_friction_cycle.py",
            "--rounding",
            "--out",
            "demos/results/friction/line_search_rounding.csv",
        ],
    ],
    "two_bodies": [
        [PY, "demos/bench/bench_two_bodies.py", part]
        for part in ("patch", "cylinders", "cattaneo", "p2", "p2sphere")
    ]
    + [
        [
            MPIRUN,
            "-n",
            "2",
            PY,
            "demos/bench/bench_two_bodies.py",
            "sphere",
            "--h-contact",
            "0.01",
            "0.005",
            "0.0035",
            "--swap",
            "0.005",
        ],
        [PY, "demos/bench/bench_two_bodies.py", "sphere_degrees", "--max-dofs", "60000"],
        [PY, "demos/bench/bench_two_bodies.py", "p1_start", "--h-contact", "0.1", "0.05", "0.025"],
        [PY, "demos/bench/bench_two_bodies.py", "p1_start_floating"],
    ],
    "cycle": [
        [PY, "demos/bench/bench_newton_min_cycle.py", "--out", "demos/results/newton_min_cycle.csv"]
    ],
    "cold": [
        [
            PY,
            "demos/bench/bench_cold.py",
            "--cells",
            "256",
            "512",
            "--out",
            "demos/results/cold/step41.csv",
        ]
    ],
    "cost": [
        [
            PY,
            "demos/bench/bench_cost.py",
            "square",
            "--sequence",
            "auto",
            "--out",
            "demos/results/cost/square.csv",
        ],
        [
            PY,
            "demos/bench/bench_cost.py",
            "square",
            "--sequence",
            "off",
            "--repeat",
            "1",
            "--out",
            "demos/results/cost/square_off.csv",
        ],
        [
            PY,
            "demos/bench/bench_cost.py",
            "hertz3d",
            "--repeat",
            "2",
            "--out",
            "demos/results/cost/hertz3d.csv",
        ],
        [
            MPIRUN,
            "-n",
            "2",
            PY,
            "demos/bench/bench_cost.py",
            "hertz3d",
            "--set",
            "adapt.theta=0.3",
            "--max-dofs",
            "1600000",
            "--no-before",
            "--sequence",
            "auto",
            "--repeat",
            "1",
            "--out",
            "demos/results/cost/hertz3d_np2.csv",
        ],
        [PY, "demos/bench/bench_cost.py", "chart", "demos/results/cost"],
    ],
    "scale": [
        [PY, "demos/bench/bench_scale.py", "--out", "demos/results/scale.csv"],
        [
            PY,
            "demos/bench/bench_error_quadrature.py",
            "--out",
            "demos/results/error_quadrature.csv",
        ],
        [PY, "demos/bench/bench_kernels.py", "--repeat", "4", "--out", "demos/results/kernels.csv"],
        [
            MPIRUN,
            "-n",
            "2",
            PY,
            "demos/bench/bench_kernels.py",
            "--only",
            "assembly",
            "--cells",
            "55",
            "--repeat",
            "4",
            "--out",
            "demos/results/kernels_np2.csv",
        ],
        [
            MPIRUN,
            "-n",
            "2",
            PY,
            "demos/bench/bench_kernels.py",
            "--only",
            "refine",
            "--repeat",
            "3",
            "--out",
            "demos/results/kernels_refine_np2.csv",
        ],
        [
            PY,
            "demos/bench/bench_kernels.py",
            "--only",
            "floor",
            "--repeat",
            "3",
            "--out",
            "demos/results/kernels_floor.csv",
        ],
        [
            MPIRUN,
            "-n",
            "2",
            PY,
            "demos/bench/bench_kernels.py",
            "--only",
            "floor",
            "--repeat",
            "3",
            "--out",
            "demos/results/kernels_floor_np2.csv",
        ],
    ]
    + [
        (
            ["rm", "-f", "demos/results/bandwidth.csv"]
            if n == 0
            else [
                MPIRUN,
                "-n",
                str(n),
                PY,
                "demos/bench/bench_bandwidth.py",
                "--out",
                "demos/results/bandwidth.csv",
            ]
        )
        for n in (0, 1, 2)
    ],
    "hyperelastic": [
        [PY, "demos/bench/bench_hyperelastic.py", *part, "--out", "demos/results/hyperelastic"]
        for part in (
            ["line_search"],
            ["predictor"],
            ["strip"],
            ["refinement", "--levels", "5"],
            ["refinement", "--top", "symmetry"],
            ["adaptive"],
            ["adaptive", "--case", "indenter"],
            ["adaptive", "--case", "indentation"],
            ["sequence"],
            ["drag"],
            ["pairs"],
            ["kink"],
        )
    ]
    + [[PY, "demos/bench/bench_ironing.py", "--out", "demos/results/hyperelastic"]],
    # RESULTS §12: both estimators per level, the reconstruction's cost, the tolerance each
    # estimator certifies at what cost, adaptive stopping
    "bounds": [
        [PY, "demos/bench/bench_equilibrated.py", "--out", "demos/results/equilibrated"],
        [
            MPIRUN,
            "-n",
            "2",
            PY,
            "demos/bench/bench_equilibrated.py",
            "--out",
            "demos/results/equilibrated",
        ],
        *(
            [
                PY,
                "demos/bench/bench_equilibrated.py",
                *size,
                "--backends",
                "compiled",
                "--out",
                "demos/results/equilibrated",
            ]
            for size in (["--cost", "720"], ["--cost3d", "63"])
        ),
        [PY, "demos/bench/bench_estimators.py", "--out", "demos/results/equilibrated"],
        [
            PY,
            "demos/bench/bench_stopping.py",
            "--tol",
            "2e-3",
            "--repeat",
            "3",
            "--out",
            "demos/results/stopping",
        ],
        [
            MPIRUN,
            "-n",
            "2",
            PY,
            "demos/bench/bench_stopping.py",
            "--tol",
            "2e-3",
            "--out",
            "demos/results/stopping",
        ],
    ],
    # RESULTS §13: penalty, augmented Lagrangian and Nitsche against fb (the stability map's
    # rows for them are the study stability_baselines.yaml, in "studies")
    "baselines": [
        [PY, "demos/bench/bench_baselines.py", "--out", "demos/results/baselines"],
    ],
    "time_to_accuracy": [
        [
            PY,
            "demos/bench/bench_time_to_accuracy.py",
            "--max-dofs",
            "1400000",
            "--out",
            "demos/results/time_to_accuracy.csv",
        ],
        # ex9 at equal certification: the uniform meshes bounded too (RESULTS §14)
        [
            PY,
            "demos/bench/bench_time_to_accuracy.py",
            "ex9",
            "--target",
            "4e-3",
            "--max-dofs",
            "1400000",
            "--variant",
            "res3:adapt.growth=3,adapt.indicators=residual,adapt.tol=4e-3",
            "--variant",
            "p2tol:mesh.degree=2,adapt.growth=2,adapt.tol=4e-3",
            # … and on a level budget, its last level (the first reaching 4e-3) not estimated
            "--variant",
            "budget3:adapt.growth=3,adapt.indicators=residual,adapt.max_levels=8,"
            "adapt.estimate_last=false",
            "--uniform-bound",
            "--repeat",
            "3",
            "--out",
            "demos/results/adaptive_cost/time_to_accuracy_ex9_certified.csv",
        ],
        # ex9 on a level budget against the uniform run: `contact run` as whole processes
        [
            PY,
            "demos/bench/bench_run_wall.py",
            "--pairs",
            "5",
            "--out",
            "demos/results/adaptive_cost/run_wall_ex9.csv",
        ],
        [
            PY,
            "demos/bench/bench_adaptive_profile.py",
            "ex9",
            "--max-dofs",
            "700000",
            "--set",
            "adapt.growth=2",
            "--out",
            "demos/results/adaptive_cost/profile_ex9_growth2.csv",
        ],
        *(
            [
                PY,
                "demos/bench/bench_adaptive_profile.py",
                "ex9",
                "--max-dofs",
                "300000",
                "--keep",
                *flags,
                "--out",
                f"demos/results/adaptive_cost/profile_ex9_keep_{stem}.csv",
            ]
            for flags, stem in (
                (["all"], "all"),
                (["last", "--no-trim"], "last_notrim"),
                (["last"], "last"),
            )
        ),
        [
            PY,
            "demos/bench/bench_startup.py",
            "--repeat",
            "5",
            "--old-plots",
            "--old-gc",
            "--old-grid",
            "--out",
            "demos/results/startup.csv",
        ],
    ],
    "hp": [[PY, "demos/bench/bench_hp.py", "--out", "demos/results/hp"]],
    "studies": [
        [CONTACT, "study", str(p.relative_to(ROOT)), "-o", f"demos/results/{p.stem}"]
        for p in sorted((ROOT / "configs" / "studies").glob("*.yaml"))
    ],
    "report": [[PY, "demos/make_results.py"]],
}


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--only", nargs="+", choices=list(STEPS), help="run only these steps (in this order)"
    )
    ap.add_argument(
        "--keep-going",
        action="store_true",
        help="after a failed command, run the others and exit with the first failure's code",
    )
    args = ap.parse_args()
    steps = args.only or list(STEPS)
    if "studies" in steps and "report" not in steps:
        steps.append("report")
    (ROOT / "demos" / "results").mkdir(exist_ok=True)
    timings = ROOT / "demos" / "results" / "timings.csv"
    rows = _read(timings)
    t_all = time.perf_counter()
    failed: list[tuple[str, int]] = []
    for step in steps:
        for cmd in STEPS[step]:
            label = _label(cmd)
            print(f"\n=== {label}", flush=True)
            t0 = time.perf_counter()
            proc = subprocess.run(cmd, cwd=ROOT)
            seconds = time.perf_counter() - t0
            rows[label] = f"{seconds:.1f}"
            _write(timings, rows)
            if proc.returncode != 0:
                print(
                    f"run_bench: {label!r} failed with exit code {proc.returncode}", file=sys.stderr
                )
                failed.append((label, proc.returncode))
                if not args.keep_going:
                    return proc.returncode
                continue
            print(f"=== {label}: {seconds:.1f} s", flush=True)
    if failed:
        print(
            f"\nrun_bench: {len(failed)} command(s) failed: "
            + "; ".join(f"{lab!r} ({rc})" for lab, rc in failed),
            file=sys.stderr,
        )
        return failed[0][1]
    print(
        f"\nrun_bench: {', '.join(steps)} done in {(time.perf_counter() - t_all) / 60:.1f} min; "
        f"timings in {timings.relative_to(ROOT)}",
        flush=True,
    )
    return 0


def _label(cmd: list[str]) -> str:
    """The command as timings.csv names it: the venv's programs by their name, so that rows
    do not depend on where the checkout lives (``mpirun -n 2 python demos/...``)."""
    return " ".join(Path(c).name if c in (PY, CONTACT, MPIRUN) else c for c in cmd)


def _read(path: Path) -> dict[str, str]:
    if not path.is_file():
        return {}
    lines = path.read_text().splitlines()[1:]
    return dict(line.rsplit(",", 1) for line in lines if "," in line)


def _write(path: Path, rows: dict[str, str]) -> None:
    path.write_text("step,seconds\n" + "".join(f"{k},{v}\n" for k, v in rows.items()))


if __name__ == "__main__":
    sys.exit(main())
