"""Run the adaptive loop on a scene and save per-level DoFs, η, errors and tie margins (run
under mpirun).

    python tests/adapt_levels.py OUT.json SCENE.yaml METHOD STRATEGY LEVELS [REBALANCE]
"""

import json
import sys

import contact
from contact.setup.run import adapt

from mpi4py import MPI
from ties import tie_margin


def main(out, scene_path, method, strategy, levels, rebalance="true"):
    scene = contact.load_scene(scene_path, ["output.verbose=false", f"adapt.rebalance={rebalance}"])
    margins = []  # each level's tie margin (tests/ties.py), taken while its problem is alive
    res = adapt(
        scene,
        method=method,
        strategy=strategy,
        max_levels=int(levels),
        max_dofs=10**7,
        verbose=False,
        on_level=lambda level: margins.append(tie_margin(level.result)),
    )
    rows = [
        {**{k: v for k, v in r.items() if not k.startswith("seconds")}, "tie_margin": m}
        for r, m in zip(res.rows, margins)
    ]
    if MPI.COMM_WORLD.rank == 0:
        with open(out, "w") as fh:
            json.dump(rows, fh)


if __name__ == "__main__":
    main(*sys.argv[1:])
