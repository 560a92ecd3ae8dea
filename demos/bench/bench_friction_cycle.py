"""Frictional Newton and its cycles: the tangential forms × line search.

What it shows: plain semismooth Newton (``solver.line_search: basic``) on the projection
(Alart–Curnier) form 2-cycles on some of bench_friction.py's form cases — the nodes slide
one way, then the other — and whether a case cycles can hang on rounding (the 3D box with
MUMPS cycled on some CPUs and converged on others).  ``auto``, the default, takes plain steps
until a cycle shows and then backtracks on ½‖Φ‖² (:class:`contact.solvers.friction.
GuardedFriction`, :mod:`contact.solvers.globalize`); ``bt`` is PETSc's backtracking from the
first step.  The cases: each form (hsw, projection) × normal NCP (fb, min, blend) on the
block (stick- and slip-dominated), the cylinder and the 3D box, one step from u = 0 and from
the frictionless solution (bench_friction.py's ``forms``), at most 100 Newton steps.  Printed:
per line search the runs converged, the Newton steps, and how many of the runs plain steps
converge in keep plain's count.  About 3 minutes (``--quick``: coarser meshes).

``--rounding``: the cases that cycle — the 3D box of tests/test_friction_speed.py with
MUMPS and GMRES (projection and hsw), the stick-dominated block from its frictionless
solution (projection), each with fb and min — with ``basic`` and ``auto``, once per rounding: the
load as assembled, and perturbed by a relative 1e-13 and 1e-12 (the test suite's
``CONTACT_TEST_PERTURB``, tests/perturb; loaded through PYTHONPATH) with 1 and 2
OpenBLAS/OpenMP threads, each in a process of its own.  About 3 minutes.

    python demos/bench/bench_friction_cycle.py --out demos/results/friction/line_search.csv
    python demos/bench/bench_friction_cycle.py --rounding \
        --out demos/results/friction/line_search_rounding.csv
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import contact
from contact.setup.build import build_problem

from bench_friction import ROOT, forms, same_mesh, scene
from common import save_csv

LINE_SEARCHES = ("basic", "auto", "bt")
#: (ε, seed, threads) of the --rounding runs; ε = 0: the load as assembled, default threads
ROUNDINGS = ((0.0, 0, 0), (1e-13, 20261125, 1), (1e-13, 20261125, 2), (1e-12, 7, 1), (1e-12, 7, 2))
#: the 3D box of tests/test_friction.py (BOX): one step, pressed and dragged, partial slip
BOX = ["load.steps=1", 'data.u_D=["0.001", "0.0005", "-0.005"]', "mesh.cells=[8,8,4]"]
#: the stick-dominated block of tests/test_friction_cycle.py (STICK)
STICK = ["load.steps=1", 'data.u_D=["0.002*t", "-0.01*t"]', "mesh.cells=[40,10]"]


def rounding_cases() -> list[dict]:
    """The cycling cases × basic / auto in this process (its rounding)."""
    rows = []

    def add(case: str, form: str, linear: str, method: str, ls: str, r) -> None:
        rows.append(
            {
                "case": case,
                "form": form,
                "linear": linear,
                "method": method,
                "line_search": ls,
                "converged": r.converged,
                "newton_iterations": r.iterations,
                "backtracked": r.backtracked,
                "residual": f"{r.history[-1]['residual']:.4e}",
            }
        )

    for form, linears in (("projection", ("direct", "gmres")), ("hsw", ("direct",))):
        for linear in linears:
            for method in ("fb", "min"):
                for ls in ("basic", "auto"):
                    case = scene("friction_box_3d", *BOX, f"friction.form={form}")
                    r = contact.solve(case, method=method, linear=linear, line_search=ls)
                    add("box 3D", form, linear, method, ls, r)
    frictionless = contact.solve(
        scene("friction_block_2d", *STICK, "friction.law=none", "friction.coefficient=null")
    )
    for method in ("fb", "min"):
        for ls in ("basic", "auto"):
            case = scene(
                "friction_block_2d", *STICK, "friction.form=projection", "solver.max_it=40"
            )
            problem = build_problem(case)
            u0 = same_mesh(frictionless.u_h, problem.V)
            r = contact.solve(case, problem=problem, u0=u0, method=method, line_search=ls)
            add("block stick, frictionless start", "projection", "direct", method, ls, r)
    return rows


def rounding() -> list[dict]:
    """:func:`rounding_cases` once per entry of :data:`ROUNDINGS`, each in a process of its
    own (the perturbation hook must be in place before the package is imported)."""
    rows = []
    for eps, seed, threads in ROUNDINGS:
        env = {k: v for k, v in os.environ.items() if not k.startswith("CONTACT_TEST_PERTURB")}
        if eps:
            env.update(
                CONTACT_TEST_PERTURB=repr(eps),
                CONTACT_TEST_PERTURB_SEED=str(seed),
                PYTHONPATH=os.pathsep.join(
                    p for p in (str(ROOT / "tests" / "perturb"), env.get("PYTHONPATH")) if p
                ),
            )
        if threads:
            for key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
                env[key] = str(threads)
        proc = subprocess.run(
            [sys.executable, __file__, "--rounding-child"],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        for row in json.loads(proc.stdout.strip().splitlines()[-1]):
            row = {"perturbation": eps, "seed": seed or "", "threads": threads or "default", **row}
            rows.append(row)
            print(
                f"eps={eps:g} threads={row['threads']} {row['case']:32s} {row['form']:10s} "
                f"{row['linear']:6s} {row['method']:3s} {row['line_search']:5s} "
                f"{'converged' if row['converged'] else 'FAILED'} {row['newton_iterations']} its "
                f"({row['backtracked']} shortened)",
                flush=True,
            )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="demos/results/friction/line_search.csv")
    ap.add_argument("--quick", action="store_true", help="small meshes (a smoke run)")
    ap.add_argument("--rounding", action="store_true", help="the cycling cases per rounding")
    ap.add_argument("--rounding-child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.rounding_child:
        print(json.dumps(rounding_cases()), flush=True)
        return
    if args.rounding:
        save_csv(args.out, rounding())
        return
    rows = [row for ls in LINE_SEARCHES for row in forms(args.quick, line_search=ls)]
    key = ("case", "start", "form", "method")
    plain = {tuple(r[k] for k in key): r for r in rows if r["line_search"] == "basic"}
    for ls in LINE_SEARCHES:
        runs = [r for r in rows if r["line_search"] == ls]
        done = [r for r in runs if r["converged"]]
        kept = sum(
            1
            for r in done
            if plain[tuple(r[k] for k in key)]["converged"]
            and plain[tuple(r[k] for k in key)]["newton_iterations"] == r["newton_iterations"]
        )
        print(
            f"{ls:6s} converged {len(done)} of {len(runs)}, "
            f"{sum(r['newton_iterations'] for r in done)} Newton steps in those, "
            f"plain's count kept in {kept} of {sum(p['converged'] for p in plain.values())}",
            flush=True,
        )
    save_csv(args.out, rows)


if __name__ == "__main__":
    main()
