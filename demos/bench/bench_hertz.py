"""Hertz validation (issue #4 figures): the adaptive loop on configs/hertz_2d.yaml and
configs/hertz_3d.yaml for fb and min — per level DoFs, Newton iterations, contact
half-width/radius and peak pressure against Hertz for the computed force, seconds — then,
on the final mesh of the fb run, every method from a cold start (u = 0, no grid sequencing)
and from the nested guess with the default linear solver (``solver.linear: auto``: CG + GAMG
on the reduced Newton system at these sizes; the PETSc VI solvers keep their own, MUMPS in 2D
and BiCGStab + GAMG with the rigid-body near-nullspace in 3D), and fb from a cold start with
the other kinds of ``solver.linear`` too.  The ``linear_solver`` column is the one the solve
used (``Result.linear``).  Writes CSV.

    python demos/bench/bench_hertz.py --out bench/hertz        (about 8 minutes on 2 cores)
    python demos/bench/bench_hertz.py --full ...               (+ VI solvers cold and MUMPS for fb
                                                          on the 3D mesh)
    python demos/bench/bench_hertz.py --set solver.kappa=100 --out bench/hertz_kappa100
                                                         (scene overrides, as contact run --set)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import contact
from contact.output.folder import write_csv
from contact.post.reference import compare
from contact.post.resultants import contact_resultants
from contact.setup.build import build_problem
from contact.solvers import method_variant
from contact.solvers.linear import choose_linear

LINEAR_SOLVERS = ("direct", "gamg", "bcgs")  # the kinds of solver.linear
METHODS = ("fb", "min", "blend", "vinewtonrsls", "vinewtonssls", "fb-nopolish")


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="bench/hertz")
    ap.add_argument(
        "--set", dest="extra", action="append", default=[], help="scene override KEY=VALUE"
    )
    ap.add_argument(
        "--full",
        action="store_true",
        help="also the PETSc VI solvers from a cold start, vinewtonssls nested, and fb with "
        "MUMPS on the final 3D mesh (vinewtonssls took over 6 minutes cold and "
        "over 4 nested there, vinewtonrsls 136 s cold, MUMPS 219 s; left out of "
        "make bench)",
    )
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    levels, finals = [], []
    for name in ("hertz_2d", "hertz_3d"):
        runs = {}
        for method in ("fb", "min"):
            scene = contact.load_scene(
                f"configs/{name}.yaml", ["output.verbose=false", *args.extra]
            )
            t0 = time.perf_counter()
            runs[method] = res = contact.adapt(scene, method=method, verbose=False)
            wall = time.perf_counter() - t0
            for lv in res.levels:
                h = {
                    **contact_resultants(lv.posed, lv.result),
                    **compare(lv.posed, lv.result).values,
                }
                row = {
                    "scene": name,
                    "method": method,
                    "level": lv.index,
                    "dofs": lv.result.dofs,
                    "newton": lv.result.iterations,
                    "polish": lv.result.polish_solves,
                    "a_error": round(h["a_error"], 5),
                    "p0_error": round(h["p0_error"], 5),
                    "a_over_R": round(h["a_over_R"], 4),
                    "force_balance": h["force_balance_error"],
                    "seconds_solve": round(lv.seconds["solve"], 2),
                }
                levels.append(row)
                print(row, flush=True)
            print(f"{name} {method}: {len(res.levels)} levels in {wall:.1f} s", flush=True)
        last = runs["fb"].levels[-1]
        problem = build_problem(last.scene)
        nested = _previous_guess(runs["fb"])
        full_3d = name != "hertz_3d" or args.full
        default = choose_linear(problem)  # what solver.linear: auto picks on this mesh
        for method in METHODS:
            for start in ("cold", "nested"):
                if not full_3d and (
                    method == "vinewtonssls" or (start == "cold" and method.startswith("vi"))
                ):
                    continue
                solvers = ["auto"]  # the default: resolves to `default` for fb, min, blend
                if method == "fb" and start == "cold" and full_3d:  # the linear-solver comparison
                    solvers += [k for k in LINEAR_SOLVERS if k != default]
                for linear in solvers:
                    m, variant = method_variant(method)
                    t0 = time.perf_counter()
                    r = contact.solve(
                        last.scene,
                        method=m,
                        problem=problem,
                        u0=nested if start == "nested" else None,
                        verbose=False,
                        max_it=100,
                        linear=linear,
                        sequence="off",
                        **variant,
                    )
                    row = {
                        "scene": name,
                        "method": method,
                        "start": start,
                        "linear_solver": r.linear,
                        "dofs": r.dofs,
                        "converged": r.converged,
                        "reason": r.reason,
                        "newton": r.iterations,
                        "polish": r.polish_solves,
                        "seconds": round(time.perf_counter() - t0, 2),
                    }
                    finals.append(row)
                    print(row, flush=True)
    write_csv(out / "levels.csv", levels)
    write_csv(out / "final_mesh_methods.csv", finals)
    print(f"wrote {out}/levels.csv, {out}/final_mesh_methods.csv")


def _previous_guess(res):
    """The second-to-last level's solution interpolated onto the last mesh (nested guess)."""
    prev, last = res.levels[-2], res.levels[-1]
    import numpy as np
    from dolfinx import fem

    V = last.result.u_h.function_space
    u0 = fem.Function(V)
    n = last.scene.mesh.topology.index_map(last.scene.mesh.topology.dim)
    cells = np.arange(n.size_local + n.num_ghosts, dtype=np.int32)
    u0.interpolate_nonmatching(
        prev.result.u_h,
        cells,
        fem.create_interpolation_data(V, prev.result.u_h.function_space, cells),
    )
    return u0


if __name__ == "__main__":
    main()
