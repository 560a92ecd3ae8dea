"""Run the Cattaneo-Mindlin load path of a two-body scene and save the figures of every
step and the final tangential tractions at the slave nodes (gathered, sorted by x) —
under mpirun to compare rank counts.

    python tests/cattaneo_run.py OUT.npz SCENE.yaml [--set k=v ...]
"""

import sys

import contact
from contact.post.reference import compare
from contact.setup.run import run_load_path

import numpy as np
from mpi4py import MPI


def main(argv):
    out, path = argv[0], argv[1]
    overrides = [a.split("=", 1)[1] if a.startswith("--set=") else a for a in argv[2:]]
    scene = contact.load_scene(path, overrides + ["output.verbose=false"])
    run = run_load_path(scene, verbose=False, keep_all=True)
    comm = MPI.COMM_WORLD
    rows = []
    for step in run.steps:
        v = compare(step.posed, step.result).values
        rows.append(
            [
                step.result.converged,
                v["Q_over_FP"],
                v["c_over_a"],
                v["c_over_a_theory"],
                v["c_error"],
                v["q_error"],
            ]
        )
    r = run.steps[-1].result
    p = r.problem
    on = slice(0, p.data.pair_nodes)
    X = p.V.tabulate_dof_coordinates()[p.constraint.dofs[on] // p.V.dofmap.index_map_bs]
    data = comm.gather(
        np.c_[X[:, :2], r.friction["lambda_t_vec"][on], r.friction["lambda_n"][on]], root=0
    )
    if comm.rank == 0:
        table = np.vstack(data)
        table = table[np.lexsort(np.round(table[:, :2], 12).T[::-1])]
        np.savez(out, steps=np.array(rows, dtype=float), nodes=table)


if __name__ == "__main__":
    main(sys.argv[1:])
