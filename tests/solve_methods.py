"""Solve scenes with several methods and save gathered nodal results (run under mpirun).

    python tests/solve_methods.py OUT.npz SCENE.yaml [SCENE.yaml ...] [--set k=v ...]

For every scene and method the npz holds X (coordinates), u, lambda, gap (nodal values
sorted by coordinate) and ``info``: converged, iterations, complementarity residual,
active nodes, polishing solves, tie margin (tests/ties.py); tests compare them across
methods and across MPI sizes.
"""

import sys

import contact
from contact.output.folder import gather_nodal
from contact.setup.build import build_problem
from contact.solvers import method_variant, owned_residual

import numpy as np
from mpi4py import MPI
from ties import tie_margin

METHODS = ("fb", "min", "blend", "vinewtonrsls")
VARIANTS = METHODS + ("fb-nopolish", "blend-nopolish")  # pure FB / blend Newton, no polishing


def main(argv):
    out, rest = argv[0], argv[1:]
    scenes = [a for a in rest if a.endswith(".yaml")]
    overrides = [
        a.split("=", 1)[1] if a.startswith("--set=") else a for a in rest if not a.endswith(".yaml")
    ]
    data = {}
    for path in scenes:
        scene = contact.load_scene(path, overrides=[o for o in overrides if o != "--set"])
        problem = build_problem(scene)
        for name in VARIANTS:
            m, opts = method_variant(name)
            r = contact.solve(scene, method=m, problem=problem, verbose=False, max_it=200, **opts)
            key = f"{scene.name}/{name}"
            X, u = gather_nodal(r.u_h)
            _, lam = gather_nodal(r.lmbda_h)
            _, gap = gather_nodal(r.gap)
            con = problem.constraint
            # complementarity residual min(σ(g - u), -σ c λ) on the constraint set, scaled
            x = problem.b.duplicate()
            problem.to_unknowns(r.u_h.x.petsc_vec, x)  # the solver's unknowns (x = Q⁻¹ u)
            a = con.sign * (con.g - x.array_r[con.dofs])
            x.destroy()
            b = -con.sign * problem.c * owned_residual(r)[con.dofs] / con.w
            comp = scene.comm.allreduce(
                float(np.max(np.abs(np.minimum(a, b)), initial=0.0)), op=max
            )
            scale = scene.comm.allreduce(float(np.max(np.abs(con.g), initial=0.0)), op=max) + 1.0
            margin = tie_margin(r)
            if scene.comm.rank == 0:
                data[key + "/X"], data[key + "/u"] = X, u
                data[key + "/lambda"], data[key + "/gap"] = lam, gap
                data[key + "/info"] = np.array(
                    [r.converged, r.iterations, comp / scale, r.n_active, r.polish_solves, margin]
                )
    if MPI.COMM_WORLD.rank == 0:
        np.savez(out, **data)


if __name__ == "__main__":
    main(sys.argv[1:])
