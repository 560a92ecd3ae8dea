"""Run a frictional scene of hyperelastic bodies in contact along its load path and save, per
step, the figures the finite-strain friction tests compare between rank counts (run under
mpirun).

    python tests/hyperelastic_friction_run.py OUT.npz SCENE.yaml [overrides ...]

``steps`` holds one row per load step: t, converged, couplings, Newton iterations, the stick /
slip / separated slave nodes, the friction ratio Σ w|λ_t| / Σ w|λ_n| over the slipping slave
nodes, and the internal forces (x, y) of the slave and of the master part.  ``nodes``: the
last step's slave nodes (reference x, y, λ_n, λ_t; sorted by coordinate).
"""

import sys

import contact

import numpy as np
from mpi4py import MPI
from test_hyperelastic_bodies import interface_force

STICK, SLIP, SEPARATED = 1, 2, 0


def step_row(step, scene) -> list[float]:
    """The figures of one load step (collective)."""
    r = step.result
    comm = scene.comm
    fr, on = r.friction, slice(0, r.problem.data.pair_nodes)
    status, w = fr["status"][on], fr["w"][on]
    slip = status == SLIP
    sums = [
        float(np.sum(w[slip] * np.linalg.norm(fr["lambda_t"][on][slip], axis=1))),
        float(np.sum(w[slip] * np.abs(fr["lambda_n"][on][slip]))),
    ]
    t_sum, n_sum = (comm.allreduce(v, op=MPI.SUM) for v in sums)
    counts = [
        comm.allreduce(int(np.sum(status == s)), op=MPI.SUM) for s in (STICK, SLIP, SEPARATED)
    ]
    slave = interface_force(r, step.scene, "slave")
    master = interface_force(r, step.scene, "master")
    return [
        step.time,
        float(r.converged),
        len(r.couplings),
        r.iterations,
        *counts,
        t_sum / n_sum if n_sum > 0 else np.nan,
        *slave[:2],
        *master[:2],
    ]


def main(argv):
    out, path, overrides = argv[0], argv[1], argv[2:]
    scene = contact.load_scene(path, ["output.verbose=false", *overrides])
    rows = []

    def on_step(step):
        if step.result.converged:
            rows.append(step_row(step, scene))

    run = contact.run_load_path(scene, on_step=on_step, verbose=False)
    r = run.steps[-1].result
    p = r.problem
    on = slice(0, p.data.pair_nodes)
    bs = p.V.dofmap.index_map_bs
    X = p.V.tabulate_dof_coordinates()[p.constraint.dofs[on] // bs, :2]
    table = np.c_[X, r.friction["lambda_n"][on], r.friction["lambda_t"][on]]
    comm = MPI.COMM_WORLD
    table = comm.gather(table)
    if comm.rank == 0:
        table = np.concatenate(table)
        table = table[np.lexsort(np.round(table[:, :2], 12).T[::-1])]
        np.savez(out, steps=np.array(rows), nodes=table, converged=run.converged)


if __name__ == "__main__":
    main(sys.argv[1:])
