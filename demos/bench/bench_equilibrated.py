"""Guaranteed bounds by flux equilibration (issue 30, phase 1): effectivity per level, and
the cost of the reconstruction against one CG + GAMG solve.

Effectivity (default): SPEC problems A (P1, P2), C (P1, P2; configs/signorini_smooth.yaml),
D (P1) and PETSc ex9's obstacle (P1; configs/peers/petsc_ex9.yaml), all with exact
solutions, through the adaptive loop (Dörfler θ = 0.5, ``--strategy uniform`` for uniform
refinement) with ``estimator: equilibrated`` while the next level stays within
``--max-dofs``.  Per level: DoFs, the
energy error, the guaranteed η and its effectivity η / error, the residual estimator's
effectivity on the same solve (SPEC §5), the parts of the bound (A, B, W, D of
contact/adaptivity/equilibration/bound.py) and the estimate's and the solve's seconds.  It checks
η ≥ error on every level and η / error ≤ 1.5 on every level past the first three, prints
each level and a verdict per problem, and writes ``effectivity.csv`` (``effectivity_np2.csv``
under ``mpirun -n 2``); ``--compare-backends`` also computes η with the NumPy patch solver on
every level (``eta_numpy``, ``eta_rel_diff``: the two must agree to round-off);
``--backend flow`` estimates with the cheaper P1 patch fit of contact/adaptivity/equilibration/
flux.py (the P1 problems only; ``effectivity_flow*.csv``).

    python demos/bench/bench_equilibrated.py --out demos/results/equilibrated
    mpirun -n 2 python demos/bench/bench_equilibrated.py --out demos/results/equilibrated

3D (``--uniform3d N ...``): problem A's extrusion of the cost scene below on [2N, N, N] cells,
one solve per N, the effectivity of η with each ``--backends`` (the energy error by a rule of
degree 6: the default degree 4 puts a point on the line r = 0, where ∇u is 0/0);
``effectivity_3d.csv``.

    python demos/bench/bench_equilibrated.py --uniform3d 8 16 24 --backends compiled flow lowest \
        --out demos/results/equilibrated

Elasticity (issue 30 item 2; contact/adaptivity/equilibration/elastic.py): ``tresca_P1``
and ``tresca_P2``, the manufactured Tresca scene (configs/friction_tresca_manufactured.yaml,
exact solution: the same checks), and ``hertz_P1`` (configs/hertz_2d.yaml), whose error on
every level is taken against a reference solution on the final mesh refined uniformly
twice (4× finer; each level's u_h transferred to it by point location, exact on the nested
part and linear extrapolation in the slivers the snapped arc adds): there η ≥ that error
on every level is checked.  Their rows add the Korn-type constant ``part_korn`` (C_K) and
the bound's terms (``term_*``); run alone they go to ``effectivity_elastic*.csv``.

    python demos/bench/bench_equilibrated.py --problems tresca_P1 tresca_P2 hertz_P1 \
        --max-dofs 50000 --out demos/results/equilibrated

Cost (``--cost N``): problem A on [2N, N] cells (N = 720: 1.04M DoFs; ``--cost3d N``: its
extrusion u(x, y, z) = u_A(x, y) on [−1, 1] × [0, 1]² with [2N, N, N] cells, N = 63: 520k
DoFs), the reconstruction
(:func:`contact.adaptivity.equilibration.reconstruct_flux`) with each patch
solver (``--backends``: ``compiled``, the default C kernel, and ``numpy``, the reference;
each after a warm-up call that compiles) against one CG + GAMG solve of the stiffness matrix K
(rtol 1e-8 from zero, the loop's options) in the same process, all of them ``--repeat``
times in turn (medians; ``ratio_cpu_min``: the fastest runs'): wall and CPU seconds (the
machine is shared: CPU seconds are the steadier measure), the phases (gather: the cell data;
patches: the patch problems; assemble: σ_h, λ̃_h and the DG0 fields) and the largest
difference of σ_h between the backends (``lowest``: the lowest-order flux,
``reconstruct_flux(degree=0)``, σ_h ∈ RT_0), and the whole estimate (``estimate_*``:
:func:`~contact.adaptivity.equilibration.bound.guaranteed_bound`, the feasible lifting and the
terms besides the reconstruction; ``estimate_flux_*``: the wall seconds of the reconstruction
inside it, which fits σ_h to k∇s_h) and the residual estimate (``residual_*``); ``cost.csv``
/ ``cost_3d.csv`` (``_np2`` on 2 ranks).

    python demos/bench/bench_equilibrated.py --cost 720 --out demos/results/equilibrated
    mpirun -n 2 python demos/bench/bench_equilibrated.py --cost 720 --out demos/results/equilibrated
    python demos/bench/bench_equilibrated.py --cost3d 63 --backends compiled flow lowest \
        --repeat 3 --out demos/results/equilibrated

Cost of the elastic estimate (``--cost-elastic N``): hertz_2d (configs/hertz_2d.yaml, CG +
GAMG) refined uniformly N times from its initial mesh (N = 2: 126k DoFs), the whole
:func:`elastic_bound` (the Korn constant, the stress reconstruction, the terms) with each
patch backend of contact/adaptivity/equilibration/stress.py (``compiled``: the C kernels of
stress_c.py; ``numpy``: the reference) against one CG + GAMG solve of K with the
rigid-body near-nullspace, ``--repeat`` times in turn after a warm-up call of each: the
medians of the CPU seconds, their ratio to the solve's (``ratio_cpu_min``: the fastest
runs'), η of each backend (the same to round-off) and the phases' wall seconds
(``seconds_korn``, ``seconds_patches``: the cell operators and the patch problems, …);
``cost_elastic.csv``.

    python demos/bench/bench_equilibrated.py --cost-elastic 2 --out demos/results/equilibrated
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import contact
from contact.adaptivity.energy_error import energy_error, solution_error
from contact.adaptivity.equilibration.bound import flux_data, guaranteed_bound
from contact.adaptivity.equilibration.elastic import elastic_bound
from contact.adaptivity.equilibration.flux import BACKENDS, reconstruct_flux
from contact.adaptivity.equilibration.stress import BACKENDS as STRESS_BACKENDS
from contact.adaptivity.estimate import estimate
from contact.adaptivity.refine import next_dofs_bound
from contact.solvers.options import default_options

import numpy as np
from common import elastic_reference, energy_distance, save_csv
from mpi4py import MPI
from petsc4py import PETSc

#: the reconstructions compared: each patch solver of flux.py, and "lowest", the lowest-order
#: flux of a P1 solution (σ_h ∈ RT_0, the compiled solver: ``reconstruct_flux(degree=0)``)
VARIANTS = {**{b: {"backend": b} for b in BACKENDS}, "lowest": {"backend": "compiled", "degree": 0}}

ROOT = Path(__file__).resolve().parents[2]
PROBLEMS = {  # name: (scene, overrides)
    "A_P1": ("signorini_free_boundary.yaml", []),
    "A_P2": ("signorini_free_boundary.yaml", ["mesh.degree=2", "mesh.cells=[8,4]"]),
    "C_P1": ("signorini_smooth.yaml", []),
    "C_P2": ("signorini_smooth.yaml", ["mesh.degree=2", "mesh.cells=[4,4]"]),
    "D_P1": ("lshape_corner.yaml", []),
    "ex9_P1": ("peers/petsc_ex9.yaml", ["mesh.cells=[8,8]"]),
    "tresca_P1": ("friction_tresca_manufactured.yaml", []),
    "tresca_P2": ("friction_tresca_manufactured.yaml", ["mesh.degree=2", "mesh.cells=[4,4]"]),
    "hertz_P1": ("hertz_2d.yaml", []),
}
#: problems whose error is measured against a reference solution 4× finer (no exact one)
REFERENCE = ("hertz_P1",)
#: the elastic problems (their rows go to effectivity_elastic*.csv when run alone)
ELASTIC = ("tresca_P1", "tresca_P2", "hertz_P1")
#: effectivity bound past the first LEVELS_EXEMPT levels (issue 30's acceptance)
BOUND, LEVELS_EXEMPT = 1.5, 3


def residual_eta(scene: contact.Scene, result) -> float:
    """The residual estimator (docs/theory.md §5) of the same solve."""
    return estimate(
        dataclasses.replace(
            scene, config=scene.config.model_copy(update={"estimator": "residual"})
        ),
        result,
    ).eta


def effectivity(
    name: str,
    strategy: str,
    max_dofs: int,
    max_levels: int = 30,
    compare: bool = False,
    backend: str = "compiled",
) -> list[dict]:
    """The loop SOLVE → ESTIMATE (both estimators) → MARK → REFINE of contact/drivers/adaptive.py's
    docstring, with nested iteration, until the next level would exceed ``max_dofs``;
    ``compare``: also η with the NumPy patch solver (``eta_numpy``, the relative difference);
    ``backend``: the patch solver of the scalar problems' η."""
    path, sets = PROBLEMS[name]
    scene = contact.load_scene(
        ROOT / "configs" / path, sets + ["estimator=equilibrated", "output.verbose=false"]
    )
    rows, u0, solves = [], None, []
    bound_of = (
        elastic_bound
        if scene.config.elastic
        else lambda sc, res: guaranteed_bound(res.problem, res, **VARIANTS[backend])
    )
    for level in range(max_levels):
        t0 = time.perf_counter()
        result = contact.solve(scene, u0=u0, verbose=False)
        t1 = time.perf_counter()
        bound = bound_of(scene, result)
        t2 = time.perf_counter()
        err = np.nan if name in REFERENCE else solution_error(result.problem, result)
        if name in REFERENCE:
            solves.append((scene, result))
        extra = {}
        if compare:
            numpy_args = {**VARIANTS[backend], "backend": "numpy"}
            eta_np = guaranteed_bound(result.problem, result, **numpy_args).eta
            extra = {"eta_numpy": eta_np, "eta_rel_diff": abs(bound.eta - eta_np) / eta_np}
        rows.append(
            {
                "problem": name,
                "ranks": MPI.COMM_WORLD.size,
                "strategy": strategy,
                "backend": backend,
                "level": level,
                "dofs": result.dofs,
                "error": err,
                "eta": bound.eta,
                "effectivity": bound.eta / err,
                "residual_eta": residual_eta(scene, result),
                **{f"term_{k}": v for k, v in bound.terms.items()},
                **{f"part_{k}": v for k, v in bound.parts.items()},
                "seconds_estimate": round(t2 - t1, 3),
                "seconds_solve": round(t1 - t0, 3),
                **extra,
            }
        )
        if name not in REFERENCE:
            _print_row(rows[-1], compare)
        cells = contact.mark(bound.eta_T, strategy, 0.5)
        if (
            next_dofs_bound(scene.mesh, cells, result.u_h.function_space) or 2 * result.dofs
        ) > max_dofs:
            break
        scene, u0 = contact.refine(scene, cells, result.u_h)
    if name in REFERENCE:
        errors, ref_dofs = reference_errors([(sc, r.u_h) for sc, r in solves])
        for row, err in zip(rows, errors):
            row.update(error=err, effectivity=row["eta"] / err, reference_dofs=ref_dofs)
            _print_row(row, compare)
    for row in rows:
        row["residual_effectivity"] = row.pop("residual_eta") / row["error"]
    return rows


def _print_row(r: dict, compare: bool) -> None:
    if MPI.COMM_WORLD.rank == 0:
        print(
            f"{r['problem']:9s} {r['level']:3d} {r['dofs']:8d} error {r['error']:.4e} "
            f"eta {r['eta']:.4e} eff {r['effectivity']:.3f} (residual "
            f"{r['residual_eta'] / r['error']:.2f}) estimate {r['seconds_estimate']:.2f} s "
            f"solve {r['seconds_solve']:.2f} s"
            + (f" C_K {r['part_korn']:.3f}" if "part_korn" in r else "")
            + (f" |eta - eta_numpy|/eta {r['eta_rel_diff']:.1e}" if compare else ""),
            flush=True,
        )


def reference_errors(solves: list) -> tuple[list[float], int]:
    """The energy error of each level's u_h against the solve on the last level's mesh
    refined uniformly twice (4× finer), and that reference's DoFs."""
    ref = elastic_reference(*solves[-1])
    return [energy_distance(ref, u_h) for _, u_h in solves], ref.dofs


def verdict(rows: list[dict]) -> str:
    below = [r["level"] for r in rows if r["eta"] < r["error"]]
    high = [r["level"] for r in rows if r["level"] >= LEVELS_EXEMPT and r["effectivity"] > BOUND]
    late = [r["effectivity"] for r in rows if r["level"] >= LEVELS_EXEMPT]
    rng = f"{min(late):.3f}-{max(late):.3f}" if late else "-"
    return (
        f"{rows[0]['problem']}: {len(rows)} levels, eta >= error on every level: {not below} "
        f"{below or ''}; effectivity past level {LEVELS_EXEMPT - 1}: {rng} (<= {BOUND}: "
        f"{not high})"
    )


def cost_scene(n: int, dim: int) -> contact.Scene:
    """Problem A on [2N, N] cells (2D), or its extrusion u(x, y, z) = u_A(x, y) on the box
    [−1, 1] × [0, 1]² with [2N, N, N] cells (3D; z = 0, 1 carry the natural flux 0, which
    u satisfies)."""
    sets = (
        [f"mesh.cells=[{2 * n},{n}]"]
        if dim == 2
        else ["mesh.type=box", "mesh.corners=[[-1,0,0],[1,1,1]]", f"mesh.cells=[{2 * n},{n},{n}]"]
    )
    return contact.load_scene(
        ROOT / "configs" / "signorini_free_boundary.yaml",
        sets + ["output.verbose=false", "solver.max_dofs=30000000"],
    )


def uniform3d(sizes: list[int], backends: list[str]) -> list[dict]:
    """The effectivity η / error of each backend on the 3D cost scene with [2N, N, N] cells, one
    solve per N (the energy error by a rule of degree 6)."""
    rows = []
    for n in sizes:
        scene = cost_scene(n, 3)
        result = contact.solve(scene, verbose=False)
        k = result.problem.data.k
        error = energy_error(result.u_h, scene.config.data.exact, k, quadrature_degree=6)
        for backend in backends:
            eta = guaranteed_bound(result.problem, result, **VARIANTS[backend]).eta
            rows.append(
                {
                    "ranks": MPI.COMM_WORLD.size,
                    "n": n,
                    "dofs": result.dofs,
                    "backend": backend,
                    "error": error,
                    "eta": eta,
                    "effectivity": eta / error,
                }
            )
        if MPI.COMM_WORLD.rank == 0:
            print(
                f"3D N = {n}: {result.dofs} DoFs, error {error:.4e}, effectivity "
                + ", ".join(
                    f"{r['backend']} {r['effectivity']:.3f}" for r in rows[-len(backends) :]
                ),
                flush=True,
            )
    return rows


def _timed(fn):
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t, time.process_time() - c


def k_solver(result, dim: int):
    """One CG + GAMG solve of the stiffness matrix K of ``result`` (rtol 1e-8 from zero, the
    loop's options; a new KSP each time: GAMG's set-up included; the rigid-body
    near-nullspace for elasticity): a function returning the iteration count."""
    comm = MPI.COMM_WORLD
    options = PETSc.Options()
    for key, value in {**default_options("gamg", dim, comm.size), "ksp_rtol": 1e-8}.items():
        options[f"eqcost_{key}"] = value
    problem = result.problem
    if problem.near_nullspace is not None:
        problem.K.setNearNullSpace(problem.near_nullspace)
    x = problem.b.duplicate()

    def solve_K() -> int:
        ksp = PETSc.KSP().create(comm)
        ksp.setOptionsPrefix("eqcost_")
        ksp.setOperators(problem.K)
        ksp.setFromOptions()
        x.set(0.0)
        ksp.solve(problem.b, x)
        its = ksp.getIterationNumber()
        ksp.destroy()
        return its

    return solve_K


class Timings:
    """Wall and CPU seconds (CPU: the busiest rank's) of each measured call, by key."""

    def __init__(self) -> None:
        self.times: dict = {}

    def __call__(self, key: str, fn):
        out, wall, cpu = _timed(fn)
        self.times.setdefault(key, []).append((wall, MPI.COMM_WORLD.allreduce(cpu, op=MPI.MAX)))
        return out

    def med(self, key: str, j: int) -> float:
        """The median wall (j = 0) or CPU (j = 1) seconds."""
        return float(np.median([t[j] for t in self.times[key]]))

    def fastest(self, key: str) -> float:
        """The fastest run's CPU seconds."""
        return min(t[1] for t in self.times[key])


def cost(n: int, dim: int, backends: list[str], repeat: int = 3) -> list[dict]:
    """The reconstruction with each backend (after a warm-up call that compiles the data
    expressions and the kernel), the whole equilibrated estimate, the residual estimate and
    one CG + GAMG solve of K (:func:`k_solver`), in this process, ``repeat`` times in turn (a
    shared machine's load hits all of them); the medians and their ratios to the solve's
    (``*_min``: the fastest run of each)."""
    comm = MPI.COMM_WORLD
    scene = cost_scene(n, dim)
    result = contact.solve(scene, verbose=False)
    data, multiplier, sign = flux_data(result.problem, result)
    solve_K = k_solver(result, dim)
    for backend in backends:
        reconstruct_flux(data, multiplier, sign, **VARIANTS[backend])  # warm-up (JIT)
    residual_eta(scene, result)
    timed = Timings()
    med, fastest = timed.med, timed.fastest
    etas = {}
    for _ in range(repeat):
        its = timed("solve", solve_K)
        timed("residual", lambda: residual_eta(scene, result))
        for b in backends:
            etas[b] = timed(b, lambda b=b: reconstruct_flux(data, multiplier, sign, **VARIANTS[b]))
            # the whole estimate (flux_data, the feasible lifting, the reconstruction, the terms)
            bound = timed(
                f"estimate_{b}", lambda b=b: guaranteed_bound(result.problem, result, **VARIANTS[b])
            )
            # the reconstruction inside the estimate (with its target k∇s_h): wall seconds
            timed.times.setdefault(f"estimate_flux_{b}", []).append((bound.seconds["flux"], 0))

    sol_wall, sol_cpu = med("solve", 0), med("solve", 1)
    rows = []
    for backend in backends:
        wall, cpu = med(backend, 0), med(backend, 1)
        flux = etas[backend]
        rows.append(
            {
                "dim": dim,
                "ranks": comm.size,
                "dofs": result.dofs,
                "cells": scene.mesh.topology.index_map(dim).size_global,
                "backend": backend,
                "repeat": repeat,
                "reconstruction_wall": round(wall, 3),
                "reconstruction_cpu": round(cpu, 3),
                "solve_wall": round(sol_wall, 3),
                "solve_cpu": round(sol_cpu, 3),
                "cg_iterations": its,
                "ratio_wall": round(wall / sol_wall, 2),
                "ratio_cpu": round(cpu / sol_cpu, 2),
                "ratio_cpu_min": round(fastest(backend) / fastest("solve"), 2),
                "estimate_wall": round(med(f"estimate_{backend}", 0), 3),
                "estimate_cpu": round(med(f"estimate_{backend}", 1), 3),
                "estimate_ratio_cpu": round(med(f"estimate_{backend}", 1) / sol_cpu, 2),
                "estimate_flux_wall": round(med(f"estimate_flux_{backend}", 0), 3),
                "estimate_flux_ratio_wall": round(med(f"estimate_flux_{backend}", 0) / sol_wall, 2),
                "residual_cpu": round(med("residual", 1), 3),
                "residual_ratio_cpu": round(med("residual", 1) / sol_cpu, 2),
                **{
                    f"seconds_{k}": round(comm.allreduce(v, op=MPI.MAX), 3)
                    for k, v in flux.seconds.items()
                },
            }
        )
    arrays = [f.sigma_h.x.array for f in etas.values()]
    if len(arrays) == 2 and arrays[0].shape == arrays[1].shape:  # the same σ_h to round-off
        a, b = arrays
        diff = comm.allreduce(float(np.abs(a - b).max()), op=MPI.MAX) / comm.allreduce(
            float(np.abs(a).max()), op=MPI.MAX
        )
        for r in rows:
            r["sigma_rel_diff"] = f"{diff:.2e}"
    if comm.rank == 0:
        r0 = rows[0]
        print(
            f"cost, {dim}D, {r0['dofs']} DoFs, {r0['cells']} cells, {comm.size} rank(s), "
            f"medians of {repeat} runs in turn; one CG + GAMG solve of K: {sol_wall:.2f} s wall, "
            f"{sol_cpu:.2f} s CPU ({r0['cg_iterations']} iterations); CPU seconds of the phases "
            f"(the fastest runs' ratio: {', '.join(str(r['ratio_cpu_min']) for r in rows)}):"
        )
        head = (
            "backend",
            "wall",
            "CPU",
            "CPU/solve",
            "gather",
            "patches",
            "assemble",
            "estimate",
            "est/solve",
            "residual",
        )
        print(f"{head[0]:9s}" + "".join(f" {h:>9s}" for h in head[1:]))
        for r in rows:
            cols = (
                "reconstruction_wall",
                "reconstruction_cpu",
                "ratio_cpu",
                "seconds_gather_cpu",
                "seconds_patches_cpu",
                "seconds_assemble_cpu",
                "estimate_cpu",
                "estimate_ratio_cpu",
                "residual_cpu",
            )
            print(f"{r['backend']:9s}" + "".join(f" {r[c]:9.2f}" for c in cols), flush=True)
    return rows


def elastic_scene(refinements: int) -> tuple[contact.Scene, object]:
    """hertz_2d (configs/hertz_2d.yaml, CG + GAMG) refined uniformly ``refinements`` times
    from its initial mesh (8004 DoFs; 2: 126k), solved on each mesh from the last: (scene,
    result) of the finest."""
    scene = contact.load_scene(
        ROOT / "configs" / "hertz_2d.yaml",
        ["estimator=equilibrated", "output.verbose=false", "solver.linear=gamg"],
    )
    result = contact.solve(scene, verbose=False)
    for _ in range(refinements):
        every = np.arange(scene.mesh.topology.index_map(2).size_local, dtype=np.int32)
        scene, u0 = contact.refine(scene, every, result.u_h)
        result = contact.solve(scene, u0=u0, verbose=False)
    return scene, result


def cost_elastic(refinements: int, backends: list[str], repeat: int = 3) -> list[dict]:
    """The elastic estimate (:func:`elastic_bound`: the Korn constant, the stress
    reconstruction with each patch backend, the terms) against one CG + GAMG solve of K
    (:func:`k_solver`) on hertz_2d refined uniformly ``refinements`` times, ``repeat``
    times in turn in this process after a warm-up call of each (JIT); medians of the CPU
    seconds and their ratio to the solve's (``*_min``: the fastest runs')."""
    comm = MPI.COMM_WORLD
    scene, result = elastic_scene(refinements)
    solve_K = k_solver(result, 2)
    bounds = {b: elastic_bound(result.problem, result, backend=b) for b in backends}  # warm-up
    residual_eta(scene, result)
    timed = Timings()
    for _ in range(repeat):
        its = timed("solve", solve_K)
        timed("residual", lambda: residual_eta(scene, result))
        for b in backends:
            bounds[b] = timed(b, lambda b=b: elastic_bound(result.problem, result, backend=b))
    sol_wall, sol_cpu = timed.med("solve", 0), timed.med("solve", 1)
    rows = []
    for b in backends:
        cpu = timed.med(b, 1)
        rows.append(
            {
                "scene": "hertz_2d",
                "refinements": refinements,
                "ranks": comm.size,
                "dofs": result.dofs,
                "cells": scene.mesh.topology.index_map(2).size_global,
                "backend": b,
                "repeat": repeat,
                "estimate_wall": round(timed.med(b, 0), 3),
                "estimate_cpu": round(cpu, 3),
                "solve_wall": round(sol_wall, 3),
                "solve_cpu": round(sol_cpu, 3),
                "cg_iterations": its,
                "ratio_cpu": round(cpu / sol_cpu, 2),
                "ratio_cpu_min": round(timed.fastest(b) / timed.fastest("solve"), 2),
                "residual_cpu": round(timed.med("residual", 1), 3),
                "residual_ratio_cpu": round(timed.med("residual", 1) / sol_cpu, 2),
                "eta": bounds[b].eta,
                "korn": bounds[b].parts["korn"],
                **{
                    f"seconds_{k}": round(comm.allreduce(v, op=MPI.MAX), 3)
                    for k, v in bounds[b].seconds.items()
                },
            }
        )
    if comm.rank == 0:
        r0 = rows[0]
        print(
            f"cost of the elastic estimate, hertz_2d refined {refinements}x, {r0['dofs']} DoFs, "
            f"{r0['cells']} cells, {comm.size} rank(s), medians of {repeat} runs in turn; one "
            f"CG + GAMG solve of K: {sol_wall:.2f} s wall, {sol_cpu:.2f} s CPU "
            f"({r0['cg_iterations']} iterations); the residual estimate "
            f"{r0['residual_cpu']:.2f} s CPU ({r0['residual_ratio_cpu']}x)"
        )
        phases = ("korn", "tables", "rotations", "patches", "assemble", "terms")
        head = ("backend", "CPU", "CPU/solve", "fastest", *phases, "eta")
        print(f"{head[0]:9s}" + "".join(f" {h:>9s}" for h in head[1:]) + "  (phases: wall s)")
        for r in rows:
            vals = [r["estimate_cpu"], r["ratio_cpu"], r["ratio_cpu_min"]]
            vals += [r.get(f"seconds_{k}", float("nan")) for k in phases]
            print(
                f"{r['backend']:9s}" + "".join(f" {v:9.2f}" for v in vals) + f" {r['eta']:.6e}",
                flush=True,
            )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--problems", nargs="*", default=list(PROBLEMS), choices=list(PROBLEMS))
    ap.add_argument("--strategy", default="dorfler", choices=("dorfler", "uniform"))
    ap.add_argument("--max-dofs", type=int, default=30000)
    ap.add_argument(
        "--compare-backends",
        action="store_true",
        help="also η with the NumPy patch solver per level (eta_numpy, eta_rel_diff)",
    )
    ap.add_argument(
        "--cost",
        type=int,
        default=0,
        help="measure the cost on problem A with [2N, N] cells instead",
    )
    ap.add_argument(
        "--cost3d", type=int, default=0, help="... or on its 3D extrusion with [2N, N, N] cells"
    )
    ap.add_argument(
        "--cost-elastic",
        type=int,
        default=None,
        metavar="N",
        help="... or the elastic estimate's on hertz_2d refined uniformly N times (2: 126k DoFs)",
    )
    ap.add_argument(
        "--backends",
        nargs="*",
        default=list(BACKENDS),
        choices=list(VARIANTS),
        help="the reconstruction backends to time (cost)",
    )
    ap.add_argument(
        "--backend",
        default="compiled",
        choices=list(VARIANTS),
        help="the patch solver of the scalar problems' η (effectivity)",
    )
    ap.add_argument(
        "--uniform3d", type=int, nargs="*", default=[], help="3D effectivity of --backends, per N"
    )
    ap.add_argument("--repeat", type=int, default=3, help="cost: runs of each measurement, in turn")
    ap.add_argument("--out", default="demos/results/equilibrated")
    args = ap.parse_args()
    suffix = "" if MPI.COMM_WORLD.size == 1 else f"_np{MPI.COMM_WORLD.size}"
    if args.cost_elastic is not None:
        backends = [b for b in args.backends if b in STRESS_BACKENDS]  # the stress's
        rows = cost_elastic(args.cost_elastic, backends, args.repeat)
        save_csv(Path(args.out) / f"cost_elastic{suffix}.csv", rows)
        return
    if args.uniform3d:
        save_csv(
            Path(args.out) / f"effectivity_3d{suffix}.csv", uniform3d(args.uniform3d, args.backends)
        )
        return
    if args.cost or args.cost3d:
        dim, n = (2, args.cost) if args.cost else (3, args.cost3d)
        name = f"cost{'' if dim == 2 else '_3d'}{suffix}.csv"
        save_csv(Path(args.out) / name, cost(n, dim, args.backends, args.repeat))
        return
    if args.backend in ("flow", "lowest"):  # P1 fits of the scalar problems' patches
        skipped = [p for p in args.problems if not p.endswith("_P1") or p in ELASTIC]
        args.problems = [p for p in args.problems if p not in skipped]
        if skipped and MPI.COMM_WORLD.rank == 0:
            print(
                f"--backend {args.backend} serves the scalar P1 problems: "
                f"{', '.join(skipped)} left out"
            )
    rows, verdicts = [], []
    for name in args.problems:
        got = effectivity(
            name, args.strategy, args.max_dofs, compare=args.compare_backends, backend=args.backend
        )
        rows += got
        verdicts.append(verdict(got))
    if MPI.COMM_WORLD.rank == 0:
        print("\n".join(verdicts), flush=True)
    tag = "" if args.strategy == "dorfler" else f"_{args.strategy}"
    if args.backend != "compiled":
        tag = f"_{args.backend}{tag}"
    if all(name in ELASTIC for name in args.problems):  # beside the scalar problems' file
        tag = f"_elastic{tag}"
    save_csv(Path(args.out) / f"effectivity{tag}{suffix}.csv", rows)


if __name__ == "__main__":
    main()
