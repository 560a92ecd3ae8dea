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
measured in the same run, ratios to ``direct``), the unknowns.  Serial (the patches are
built from the local mesh).  Writes solvers.csv (or ``--csv``).

    python demos/bench/bench_hp_solvers.py --out demos/results/hp
    python demos/bench/bench_hp_solvers.py --refine 3 --degrees 4,6 --csv solvers_refined.csv \
        --out demos/results/hp
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import contact
from contact.hp.problem import hp_problem
from contact.hp.space import HPSpace
from contact.output.folder import write_csv

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem
from petsc4py import PETSc

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "configs" / "signorini_smooth.yaml"
SOLVERS = ("direct", "gamg", "p1-jacobi", "p1-patch")
RTOL = 1e-10


def coarse_interpolation(space: HPSpace) -> PETSc.Mat:
    """P: the P1 coefficients to the hp unknowns, x = L I_1 x_1 (P1 ⊂ V_hp, so exact)."""
    V1 = fem.functionspace(space.mesh, ("Lagrange", 1))
    interp = dolfinx.fem.petsc.interpolation_matrix(V1, space.V)
    interp.assemble()
    _, L = space.matrices()
    P = L.matMult(interp)
    interp.destroy()
    L.destroy()
    return P


def vertex_patches(space: HPSpace) -> list[PETSc.IS]:
    """The active unknowns of each vertex patch (module docstring), as index sets."""
    msh, V = space.mesh, space.V
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    msh.topology.create_connectivity(tdim, 1)
    c2v = msh.topology.connectivity(tdim, 0).array.reshape(-1, tdim + 1)
    layout = V.dofmap.dof_layout
    edges_of = [
        [e for e, verts in enumerate(_ref_edges(tdim)) if a in verts] for a in range(tdim + 1)
    ]
    local = [
        np.concatenate(
            [layout.entity_dofs(0, a)]
            + [layout.entity_dofs(1, e) for e in edges_of[a]]
            + ([layout.entity_dofs(2, f) for f in range(4) if f != a] if tdim == 3 else [])
            + [layout.entity_dofs(tdim, 0)]
        ).astype(np.int64)
        for a in range(tdim + 1)
    ]
    n_vertices = msh.topology.index_map(0).size_local
    dofs = V.dofmap.list
    n_cells = msh.topology.index_map(tdim).size_local
    members: list[list[np.ndarray]] = [[] for _ in range(n_vertices)]
    for c in range(n_cells):
        for a in range(tdim + 1):
            v = c2v[c, a]
            if v < n_vertices:
                members[v].append(dofs[c][local[a]])
    owned = V.dofmap.index_map.size_local
    out = []
    for parts in members:
        idx = np.unique(np.concatenate(parts))
        idx = idx[(idx < owned) & space.active[idx]]
        out.append(PETSc.IS().createGeneral(idx.astype(PETSc.IntType), comm=PETSc.COMM_SELF))
    return out


def _ref_edges(tdim: int) -> list[tuple[int, int]]:
    return (
        [(1, 2), (0, 2), (0, 1)] if tdim == 2 else [(2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1)]
    )


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
    if kind == "p1-jacobi":
        smoother.getPC().setType("jacobi")
    else:
        spc = smoother.getPC()
        spc.setType("asm")
        spc.setASMType(PETSc.PC.ASMType.BASIC)
        spc.setASMOverlap(0)
        spc.setASMLocalSubdomains(len(patches := vertex_patches(space)), patches)
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="demos/results/hp")
    parser.add_argument(
        "--refine", type=int, default=2, help="uniform refinements of C's 8 × 8 mesh"
    )
    parser.add_argument("--degrees", default="2,3,4,6", help="comma-separated degrees p")
    parser.add_argument("--csv", default="solvers.csv", help="the CSV's name in --out")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
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
