"""Hertz validation (issue #4 figures): the adaptive loop on configs/hertz_2d.yaml and
configs/hertz_3d.yaml for fb and min — per level DoFs, Newton iterations, contact
half-width/radius and peak pressure against Hertz for the computed force, seconds — then,
on the final mesh of each, every method from a cold start and from the nested guess, and
the direct solver against Krylov + GAMG (rigid-body near-nullspace) for fb.  Writes CSV.

    python demos/bench_hertz.py --out bench/hertz        (about 8 minutes on 2 cores)
    python demos/bench_hertz.py --full ...               (+ VI solvers cold on the 3D mesh)
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import contact
from contact.hertz import contact_resultants
from contact.io import write_csv
from contact.solver import build_problem

GAMG = {"ksp_type": "bcgs", "pc_type": "gamg", "ksp_rtol": 1e-10}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="bench/hertz")
    ap.add_argument("--full", action="store_true",
                    help="also the PETSc VI solvers from a cold start, and vinewtonssls nested, on the final "
                         "3D mesh (vinewtonssls took over 6 minutes cold and over 4 nested there, "
                         "vinewtonrsls 136 s cold; left out of make bench)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    levels, finals = [], []
    for name in ("hertz_2d", "hertz_3d"):
        for method in ("fb", "min"):
            scene = contact.load_scene(f"configs/{name}.yaml", ["output.verbose=false"])
            t0 = time.perf_counter()
            res = contact.adapt(scene, method=method, verbose=False)
            wall = time.perf_counter() - t0
            for lv in res.levels:
                h = contact_resultants(lv.scene, lv.result)
                row = {"scene": name, "method": method, "level": lv.index, "dofs": lv.result.dofs,
                       "newton": lv.result.iterations, "polish": lv.result.polish_solves, "a_error": round(h["a_error"], 5),
                       "p0_error": round(h["p0_error"], 5), "a_over_R": round(h["a_over_R"], 4),
                       "force_balance": h["force_balance_error"], "seconds_solve": round(lv.seconds["solve"], 2)}
                levels.append(row)
                print(row, flush=True)
            print(f"{name} {method}: {len(res.levels)} levels in {wall:.1f} s", flush=True)
        last = res.levels[-1]
        problem = build_problem(last.scene)
        for method in ("fb", "min", "blend", "vinewtonrsls", "vinewtonssls", "fb-nopolish"):
            for start in ("cold", "nested"):
                if name == "hertz_3d" and not args.full and (
                        method == "vinewtonssls" or (start == "cold" and method.startswith("vi"))):
                    continue
                u0 = None if start == "cold" else _previous_guess(res)
                for solver, opts in (("direct", {}), ("gamg", GAMG)):
                    if solver == "gamg" and (start == "nested" or method != "fb"):
                        continue  # the linear-solver comparison needs one method (keeps make bench < 30 min)
                    t0 = time.perf_counter()
                    r = contact.solve(last.scene, method=method.removesuffix("-nopolish"), problem=problem,
                                      u0=u0, verbose=False, max_it=100, petsc_options=opts,
                                      polish=not method.endswith("-nopolish"))
                    row = {"scene": name, "method": method, "start": start, "linear_solver": solver,
                           "dofs": r.dofs, "converged": r.converged, "reason": r.reason,
                           "newton": r.iterations, "polish": r.polish_solves, "seconds": round(time.perf_counter() - t0, 2)}
                    finals.append(row)
                    print(row, flush=True)
    write_csv(out / "levels.csv", levels)
    write_csv(out / "final_mesh_methods.csv", finals)
    print(f"wrote {out}/levels.csv, {out}/final_mesh_methods.csv")


def _previous_guess(res):
    """The second-to-last level's solution interpolated onto the last mesh (nested guess)."""
    prev, last = res.levels[-2], res.levels[-1]
    from dolfinx import fem
    import numpy as np

    V = last.result.u_h.function_space
    u0 = fem.Function(V)
    n = last.scene.mesh.topology.index_map(last.scene.mesh.topology.dim)
    cells = np.arange(n.size_local + n.num_ghosts, dtype=np.int32)
    u0.interpolate_nonmatching(prev.result.u_h, cells,
                               fem.create_interpolation_data(V, prev.result.u_h.function_space, cells))
    return u0


if __name__ == "__main__":
    main()
