"""Benchmark: contact on the current configuration (issue 31) — what the curvature term of the
generalized Jacobian buys, and the independent solver of the same discrete problem.

What it shows, on configs/hyperelastic_indentation.yaml (a neo-Hookean block indented to
0.4 R by a rigid cylinder, on the current configuration):

1. ``curvature``: semismooth Newton (fb) with the exact element H = B K_T + D and with the
   obstacle's curvature term S M(R) Dñ dropped from D (``CurrentComplementarity.curvature``),
   in the same process: Newton iterations per load step, the last contraction factor
   r_k / r_{k−1} above round-off (→ 0: superlinear; constant: linear) and the CPU seconds.
2. ``vi_sequence``: the same load path solved by the sequence of PETSc vinewtonrsls solves
   with the gap linearized at the last iterate (``linearized_problem``), in units where
   max |u| ≈ 10 (``--scale``, default 100: PETSc's VI solvers hold a variable within 1e-8,
   absolute, of its bound as active): outer solves per step, the largest difference of u_h
   and of the contact force to fb relative to max |u_h|, and the CPU seconds of both.  Each
   step's sequence starts from the last one's answer; in 5 steps (the scene's own) the
   first VI solve of step 2 inverts cells (diverged_function_nanorinf), hence 10.

Prints tables and writes CSV:

    python demos/bench/bench_current.py --cells 40 20 --steps 10 --out bench/current.csv
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import contact
from contact.models.hyperelastic import linearized_problem
from contact.setup.build import build_problem
from contact.solvers.current import CurrentComplementarity

import numpy as np
from common import save_csv
from dolfinx import fem
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "configs" / "hyperelastic_indentation.yaml"


def contraction(history: list[dict]) -> float:
    """The last contraction factor r_k / r_{k−1} of the residuals above 1e-11 r_0."""
    r = [h["residual"] for h in history]
    r = [x for x in r if x > 1e-11 * r[0]]
    return r[-1] / r[-2] if len(r) >= 2 else float("nan")


def curvature_rows(overrides: list[str]) -> list[dict]:
    rows = []
    for curvature in (True, False):
        CurrentComplementarity.curvature = curvature
        scene = contact.load_scene(SCENE, overrides)
        t0 = time.process_time()
        path = contact.run_load_path(scene, method="fb", max_it=100)
        seconds = time.process_time() - t0
        for step in path.steps:
            r = step.result
            rows.append(
                {
                    "part": "curvature",
                    "curvature_term": curvature,
                    "step": step.index,
                    "time": step.time,
                    "converged": r.converged,
                    "newton_iterations": r.iterations,
                    "last_contraction": contraction(r.history),
                    "contact_force": r.contact_force,
                    "cpu_seconds_path": round(seconds, 3),
                }
            )
    CurrentComplementarity.curvature = True
    return rows


def vi_sequence(scene, u: fem.Function, tol: float = 1e-13, max_outer: int = 60) -> tuple:
    """(the VI sequence's u on this step, outer solves, contact force) from ``u``."""
    p = build_problem(scene)
    comm = scene.comm
    for k in range(max_outer):
        p.u_h.x.array[:] = u.x.array
        lin = linearized_problem(p)
        r = contact.solve(scene, method="vinewtonrsls", problem=lin, u0=u)
        if not r.converged:
            raise RuntimeError(f"vinewtonrsls: {r.reason}")
        change = comm.allreduce(float(np.max(np.abs(r.u_h.x.array - u.x.array))), op=MPI.MAX)
        size = comm.allreduce(float(np.max(np.abs(r.u_h.x.array))), op=MPI.MAX)
        u.x.array[:] = r.u_h.x.array
        force = r.contact_force
        lin.destroy()
        if change <= tol * size:
            p.destroy()
            return u, k + 1, force
    raise RuntimeError("the linearized sequence did not settle")


def vi_rows(overrides: list[str], scale: float) -> list[dict]:
    L = scale
    scaled = [
        *overrides,
        f"mesh.corners=[[{-L},{-L}],[{L},0]]",
        f"constants.R={0.5 * L}",
        f"obstacle.radius={0.5 * L}",
        f"constants.delta={0.2 * L}",
        f"boundaries.top.where=y > {-1e-10 * L}",
        f"boundaries.bottom.where=y < {-L + 1e-10 * L}",
    ]
    scene = contact.load_scene(SCENE, scaled)
    t0 = time.process_time()
    path = contact.run_load_path(scene, method="fb", keep_all=True)
    fb_seconds = time.process_time() - t0
    comm = scene.comm
    rows = []
    u = None
    for step in path.steps:
        step_scene = step.scene
        if u is None:
            u = fem.Function(step.result.u_h.function_space)
        t0 = time.process_time()
        u, outer, force = vi_sequence(step_scene, u)
        seconds = time.process_time() - t0
        ref = step.result.u_h.x.array
        size = comm.allreduce(float(np.max(np.abs(ref))), op=MPI.MAX)
        diff = comm.allreduce(float(np.max(np.abs(u.x.array - ref))), op=MPI.MAX)
        rows.append(
            {
                "part": "vi_sequence",
                "step": step.index,
                "time": step.time,
                "fb_newton_iterations": step.result.iterations,
                "vi_outer_solves": outer,
                "u_difference": diff / size,
                "force_difference": abs(force / step.result.contact_force - 1),
                "cpu_seconds_vi_step": round(seconds, 3),
                "cpu_seconds_fb_path": round(fb_seconds, 3),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cells", type=int, nargs=2, default=[40, 20])
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--scale", type=float, default=100.0)
    parser.add_argument("--out", default="bench/current.csv")
    args = parser.parse_args()
    overrides = [
        f"mesh.cells=[{args.cells[0]},{args.cells[1]}]",
        f"load.steps={args.steps}",
        "output.verbose=false",
    ]
    rows = curvature_rows(overrides)
    rank0 = MPI.COMM_WORLD.rank == 0
    if rank0:
        print("curvature term   step  Newton  last r_k/r_(k-1)  force")
        for r in rows:
            print(
                f"{r['curvature_term']!s:>14s}  {r['step']:4d}  {r['newton_iterations']:6d}"
                f"  {r['last_contraction']:16.2e}  {r['contact_force']:.6f}"
            )
        cpu = {r["curvature_term"]: r["cpu_seconds_path"] for r in rows}
        print(f"CPU seconds of the path: with {cpu[True]}, without {cpu[False]}")
    vi = vi_rows(overrides, args.scale)
    if rank0:
        print("step  fb Newton  VI outer solves  |u - u_vi|/max|u|  |F/F_vi - 1|  VI CPU s")
        for r in vi:
            print(
                f"{r['step']:4d}  {r['fb_newton_iterations']:9d}  {r['vi_outer_solves']:15d}"
                f"  {r['u_difference']:17.2e}  {r['force_difference']:12.2e}"
                f"  {r['cpu_seconds_vi_step']:8.3f}"
            )
        print(f"fb CPU seconds of the whole path: {vi[0]['cpu_seconds_fb_path']}")
    save_csv(args.out, rows + vi)


if __name__ == "__main__":
    main()
