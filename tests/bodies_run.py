"""Solve a multi-body scene with several methods and save gathered interface results
(run under mpirun to compare rank counts).

    python tests/bodies_run.py OUT.npz SCENE.yaml [--set k=v ...] [--methods fb,min]

For every method the npz holds the slave nodes' coordinates and pressures λ_i (sorted by
coordinate), the master nodes' pressures λ^m_j, u_h at every node (sorted), and info =
[converged, Newton iterations, active nodes, contact force, interface balance error, tie
margin (tests/ties.py)].
"""

import sys

import contact
from contact.models.mortar import master_pressure
from contact.output.folder import gather_nodal
from contact.post.interface import resultants
from contact.setup.build import build_problem
from contact.setup.posed import posed_of

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from ties import tie_margin


def _restricted(fn, nodes):
    """(coordinates, values) of ``fn`` at the output-space DoFs ``nodes`` on rank 0, sorted."""
    mask = fn.copy()
    mask.x.array[:] = 0.0
    mask.x.array[nodes] = 1.0
    X, values = gather_nodal(fn)
    _, on = gather_nodal(mask)
    if X is None:
        return None, None
    return X[on > 0.5], values[on > 0.5]


def main(argv):
    out, rest = argv[0], argv[1:]
    methods = ["fb", "min", "blend", "vinewtonrsls"]
    overrides = []
    for arg in rest[1:]:
        if arg.startswith("--methods="):
            methods = arg.split("=", 1)[1].split(",")
        else:
            overrides.append(arg.split("=", 1)[1] if arg.startswith("--set=") else arg)
    scene = contact.load_scene(rest[0], overrides)
    problem = build_problem(scene)
    degree = problem.V.element.basix_element.degree
    nodal_body = fem.Function(fem.functionspace(scene.mesh, ("Lagrange", degree)))
    nodal_body.interpolate(problem.data.body)
    data = {}
    for method in methods:
        r = contact.solve(scene, method=method, problem=problem, verbose=False, max_it=100)
        res = resultants(posed_of(scene), r)
        margin = tie_margin(r)
        lam_m = master_pressure(r)
        S = lam_m.function_space
        master = np.flatnonzero(np.abs(lam_m.x.array) > 0)
        Xs, ls = _restricted(r.lmbda_h, problem.output.nodes)
        Xm, lm = _restricted(lam_m, master[master < S.dofmap.index_map.size_local])
        Xu, u = gather_nodal(r.u_h)
        _, body = gather_nodal(nodal_body)  # coincident nodes of two bodies: order by body
        if Xu is not None:
            order = np.lexsort((body, *np.round(Xu, 12).T[::-1]))
            Xu, u = Xu[order], u[order]
        if scene.comm.rank == 0:
            data.update(
                {
                    f"{method}/Xs": Xs,
                    f"{method}/lambda": ls,
                    f"{method}/Xm": Xm,
                    f"{method}/lambda_master": lm,
                    f"{method}/X": Xu,
                    f"{method}/u": u,
                    f"{method}/info": np.array(
                        [
                            r.converged,
                            r.iterations,
                            r.n_active,
                            res["contact_force"],
                            res["interface_balance_error"],
                            margin,
                        ]
                    ),
                }
            )
    if MPI.COMM_WORLD.rank == 0:
        np.savez(out, **data)


if __name__ == "__main__":
    main(sys.argv[1:])
