"""Run the adaptive loop on a scene and save per-level DoFs, η and errors (run under mpirun).

    python tests/adapt_levels.py OUT.json SCENE.yaml METHOD STRATEGY LEVELS [REBALANCE]
"""
import json
import sys

from mpi4py import MPI

import contact
from contact.adapt import adapt


def main(out, scene_path, method, strategy, levels, rebalance="true"):
    scene = contact.load_scene(scene_path, ["output.verbose=false", f"adapt.rebalance={rebalance}"])
    res = adapt(scene, method=method, strategy=strategy, max_levels=int(levels), max_dofs=10**7, verbose=False)
    rows = [{k: v for k, v in r.items() if not k.startswith("seconds")} for r in res.rows]
    if MPI.COMM_WORLD.rank == 0:
        with open(out, "w") as fh:
            json.dump(rows, fh)


if __name__ == "__main__":
    main(*sys.argv[1:])
