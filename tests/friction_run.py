"""Run a frictional load path and save gathered results (run under mpirun).

    python tests/friction_run.py OUT.npz SCENE.yaml [--set=k=v ...]

The npz holds, for the last step, the nodal coordinates and u_h (sorted by coordinate), the
contact surface columns (sorted along Γ_C: position, λ_n, λ_t, slip, status codes) and the
Newton iterations of every step; tests compare serial and parallel runs.
"""

import sys

import contact
from contact.output.folder import gather_nodal
from contact.post.contact_table import STATUS, contact_table
from contact.setup.run import run_load_path

import numpy as np
from mpi4py import MPI


def main(argv):
    out, path = argv[0], argv[1]
    overrides = [a.split("=", 1)[1] for a in argv[2:] if a.startswith("--set=")]
    scene = contact.load_scene(path, overrides + ["output.verbose=false"])
    run = run_load_path(scene)
    last = run.steps[-1]
    X, u = gather_nodal(last.result.u_h)
    table = contact_table(last.posed, last.result)
    if MPI.COMM_WORLD.rank == 0:
        # rank-independent
        order = np.lexsort([np.round(table[c], 12) for c in "zyx" if c in table])
        table = {k: np.asarray(v)[order] for k, v in table.items()}
        cols = [k for k in table if k != "status"]
        np.savez(
            out,
            X=X,
            u=u,
            its=np.array([s.result.iterations for s in run.steps]),
            converged=np.array([s.result.converged for s in run.steps]),
            surface=np.column_stack([np.asarray(table[k], dtype=float) for k in cols]),
            columns=np.array(cols),
            status=np.array([STATUS.index(v) for v in table["status"]]),
        )


if __name__ == "__main__":
    main(sys.argv[1:])
