"""Linear solvers for the hp systems K_hp = Qᵀ K Q against the degree (docs/guide/hp.md).

Problem C (configs/signorini_smooth.yaml) on its mesh, every cell at degree p (p = 2, 3, 4,
6), its reduced stiffness matrix with the fixed unknowns eliminated (the matrix the Newton
steps solve on the inactive set), solved for its right-hand side to a relative residual of
1e-10 by

* ``direct``   — MUMPS LU (the hp loop's solver at these sizes);
* ``gamg``     — CG + GAMG on K_hp as it is (smoothed aggregation on the hp unknowns);
* ``p1-jacobi`` — CG + two-level: the P1 space as the coarse space (x = L I_1 x_1, I_1 the
  interpolation P1 → P_{p_max}, L the hp left inverse; Galerkin coarse matrix solved by one
  GAMG V-cycle) with two Chebyshev–Jacobi smoothing steps;
* ``p1-patch`` — the same coarse space with two Chebyshev steps preconditioned by additive
  Schwarz on the vertex patches (the unknowns of the vertex, of its edges' interiors and of
  its cells' interiors; one LU per patch) as the smoother, the p-robust choice of
  Schöberl, Melenk, Pechstein & Zaglmayr (2008) and Pavarino (1994).

Per solver and p: the Krylov iterations, the CPU seconds of setup and solve (the process's,
measured in the same run, ratios to ``direct``), the unknowns.  Serial.  Writes solvers.csv
(or ``--csv``).  ``p1-patch`` is the library's ``solver.linear: hp_patch``
(:mod:`contact.hp.precondition`).

``--loop LEVELS``: the hp loop on problem C instead, LEVELS levels at each p_max of
``--degrees``, its Newton systems solved with ``solver.linear`` direct, gamg and hp_patch
(exact Krylov solves, ``solver.inexact: false``): the unknowns and degrees of the last
level, the most and the total CG iterations, the loop's CPU seconds and their ratio to
direct's; writes solvers_loop.csv.

    python demos/bench/bench_hp_solvers.py --out demos/results/hp
    python demos/bench/bench_hp_solvers.py --loop 16 --out demos/results/hp
    python demos/bench/bench_hp_solvers.py --refine 3 --degrees 4,6 --csv solvers_refined.csv \
        --out demos/results/hp
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import contact
from contact.hp.precondition import PatchPreconditioner, coarse_interpolation
from contact.hp.problem import hp_problem
from contact.hp.space import HPSpace
from contact.output.folder import write_csv

import numpy as np
from petsc4py import PETSc

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "configs" / "signorini_smooth.yaml"
SOLVERS = ("direct", "gamg", "p1-jacobi", "p1-patch")
RTOL = 1e-10


def make_ksp(kind: str, K: PETSc.Mat, space: HPSpace) -> PETSc.KSP:
    """The KSP of solver ``kind`` (module docstring) with its operators set."""
    ksp = PETSc.KSP().create(K.getComm())
    ksp.setOperators(K)
    pc = ksp.getPC()
    if kind == "direct":
        ksp.setType("preonly")
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
        return ksp
    ksp.setType("cg")
    ksp.setTolerances(rtol=RTOL, atol=0.0, max_it=5000)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    if kind == "gamg":
        pc.setType("gamg")
        return ksp
    if kind == "p1-patch":  # the library's preconditioner, the coarse matrix Galerkin's
        pc.setType("mg")
        PETSc.Options().setValue("pc_mg_galerkin", "both")
        pc.setFromOptions()
        PETSc.Options().delValue("pc_mg_galerkin")
        PatchPreconditioner(space)(pc)
        return ksp
    pc.setType("mg")
    pc.setMGLevels(2)
    pc.setMGType(PETSc.PC.MGType.MULTIPLICATIVE)
    pc.setMGCycleType(PETSc.PC.MGCycleType.V)
    P = coarse_interpolation(space)
    pc.setMGInterpolation(1, P)
    pc.setMGRestriction(1, P)
    coarse = pc.getMGCoarseSolve()
    coarse.setOperators(K.PtAP(P))  # the Galerkin coarse matrix Pᵀ K P
    coarse.setType("preonly")
    coarse.getPC().setType("gamg")
    smoother = pc.getMGSmoother(1)
    smoother.setOperators(K)
    smoother.setType("chebyshev")  # eigenvalue estimates of the preconditioned K
    smoother.setTolerances(max_it=2)
    smoother.getPC().setType("jacobi")
    return ksp


def measure(kind: str, K: PETSc.Mat, b: PETSc.Vec, space: HPSpace) -> dict:
    """Setup and solve of ``kind``: iterations, CPU seconds, the relative residual."""
    t0 = time.process_time()
    ksp = make_ksp(kind, K, space)
    ksp.setUp()
    if kind == "p1-patch":
        for sub in ksp.getPC().getMGSmoother(1).getPC().getASMSubKSP():
            sub.setType("preonly")
            sub.getPC().setType("lu")
    t1 = time.process_time()
    x = b.duplicate()
    ksp.solve(b, x)
    t2 = time.process_time()
    r = b.duplicate()
    K.mult(x, r)
    r.axpy(-1.0, b)
    out = {
        "iterations": ksp.getIterationNumber() if kind != "direct" else 0,
        "converged": ksp.getConvergedReason() > 0,
        "setup_cpu": t1 - t0,
        "solve_cpu": t2 - t1,
        "cpu": t2 - t0,
        "relative_residual": r.norm() / b.norm(),
    }
    for obj in (ksp, x, r):
        obj.destroy()
    return out


LOOP_SOLVERS = ("direct", "gamg", "hp_patch")


def loop(levels: int, degrees: list[int], out: Path) -> None:
    """The hp loop with each ``solver.linear`` of :data:`LOOP_SOLVERS` (module docstring)."""
    rows = []
    for p_max in degrees:
        for linear in LOOP_SOLVERS:
            scene = contact.load_scene(
                SCENE, ["output.verbose=false", f"solver.linear={linear}", "solver.inexact=false"]
            )
            t0 = time.process_time()
            run = contact.adapt(scene, strategy="hp", p_max=p_max, max_levels=levels)
            cpu = time.process_time() - t0
            its = [e["iterations"] for lv in run.levels for e in lv.result.krylov_log]
            last = run.levels[-1].row()
            rows.append(
                {
                    "p_max": p_max,
                    "solver": linear,
                    "levels": len(run.levels),
                    "unknowns": last["dofs"],
                    "degree_max": last["p_max"],
                    "eta": run.levels[-1].estimate.eta,
                    "most_iterations": max(its, default=0),
                    "krylov_iterations": sum(its),
                    "cpu": cpu,
                }
            )
        direct = next(r for r in rows if r["p_max"] == p_max and r["solver"] == "direct")
        for r in rows:
            if r["p_max"] == p_max:
                r["cpu_ratio_direct"] = r["cpu"] / direct["cpu"]
    write_csv(out / "solvers_loop.csv", rows)
    print(
        f"{'p_max':>5} {'solver':9}{'N':>7}{'p':>3}{'eta':>10}{'most':>6}{'its':>7}{'cpu':>8}"
        f"{'/direct':>8}"
    )
    for r in rows:
        print(
            f"{r['p_max']:5d} {r['solver']:9}{r['unknowns']:7d}{r['degree_max']:3d}"
            f"{r['eta']:10.3e}{r['most_iterations']:6d}{r['krylov_iterations']:7d}"
            f"{r['cpu']:8.2f}{r['cpu_ratio_direct']:8.2f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="demos/results/hp")
    parser.add_argument(
        "--refine", type=int, default=2, help="uniform refinements of C's 8 × 8 mesh"
    )
    parser.add_argument("--degrees", default="2,3,4,6", help="comma-separated degrees p")
    parser.add_argument("--csv", default="solvers.csv", help="the CSV's name in --out")
    parser.add_argument("--loop", type=int, default=0, help="levels of the hp loop (0: none)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.loop:
        loop(args.loop, [int(d) for d in args.degrees.split(",")], out)
        return
    scene = contact.load_scene(SCENE, ["output.verbose=false"])
    for _ in range(args.refine):
        scene, _ = contact.refine(scene, np.arange(scene.mesh.topology.index_map(2).size_local))
    n = scene.mesh.topology.index_map(2).size_local
    rows = []
    for p in (int(d) for d in args.degrees.split(",")):
        space = HPSpace(scene.mesh, p, np.full(n, p, dtype=np.int32))
        problem = hp_problem(scene, space)
        for kind in SOLVERS:
            row = {"p": p, "solver": kind, "unknowns": space.dimension, "cells": n}
            row.update(measure(kind, problem.K, problem.b, space))
            rows.append(row)
        direct = next(r for r in rows if r["p"] == p and r["solver"] == "direct")
        for r in rows:
            if r["p"] == p:
                r["cpu_ratio_direct"] = r["cpu"] / direct["cpu"]
        problem.destroy()
    write_csv(out / args.csv, rows)
    print(f"{'p':>3}{'N':>8} {'solver':10}{'its':>6}{'setup':>8}{'solve':>8}{'cpu/direct':>11}")
    for r in rows:
        print(
            f"{r['p']:3d}{r['unknowns']:8d} {r['solver']:10}{r['iterations']:6d}"
            f"{r['setup_cpu']:8.3f}{r['solve_cpu']:8.3f}{r['cpu_ratio_direct']:11.2f}"
            f"  {'ok' if r['converged'] else 'NOT CONVERGED'} {r['relative_residual']:.1e}"
        )


if __name__ == "__main__":
    main()
