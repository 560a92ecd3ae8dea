"""Run a scene of hyperelastic bodies in contact along its load path and save what the
finite-strain two-body tests compare between rank counts (run under mpirun).

    python tests/hyperelastic_bodies_run.py OUT.npz SCENE.yaml [overrides ...]

The npz holds the last step's slave nodes' coordinates and interface pressures (sorted by
coordinate), the contact force, the first point of contact and the normal there, the
couplings of each step's fixed point (Newton iterations, the displacement change and the
error estimate) and converged.
"""

import sys

import contact
from contact.solvers import owned_residual

import numpy as np
from mpi4py import MPI


def main(argv):
    out, path, overrides = argv[0], argv[1], argv[2:]
    scene = contact.load_scene(path, ["output.verbose=false", *overrides])
    run = contact.run_load_path(scene, verbose=False)
    r = run.steps[-1].result
    p = r.problem
    on = slice(0, p.data.pair_nodes)
    bs = p.V.dofmap.index_map_bs
    X = p.V.tabulate_dof_coordinates()[p.constraint.dofs[on] // bs, : scene.mesh.geometry.dim]
    pressure = p.pressure(owned_residual(r))[on]
    comm = MPI.COMM_WORLD
    X = comm.gather(X)
    pressure = comm.gather(pressure)
    if comm.rank == 0:
        X, pressure = np.concatenate(X), np.concatenate(pressure)
        order = np.lexsort(X.T[::-1])
        couplings = [
            [c["newton"], c["change"], c["error"]] for s in run.steps for c in s.result.couplings
        ]
        np.savez(
            out,
            X=X[order],
            pressure=pressure[order],
            force=r.contact_force,
            first_contact=r.first_contact,
            n=p.data.n,
            couplings=np.array(couplings),
            converged=run.converged,
        )


if __name__ == "__main__":
    main(sys.argv[1:])
