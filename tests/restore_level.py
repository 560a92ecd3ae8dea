"""A releasing adaptive loop on problem A whose level 3 fails, and what it held of level 2.

Level 3's solve is made to fail (its result marked not converged before the loop sees it),
so level 2, held through that solve, is the last that converged and is restored for its
files and bound.  :func:`run` records, for one path (``STOW_PREVIOUS``), what the level the
loop will release holds during each later solve, and whether each field of the restored
level 2 — the result's functions, η_T, the nodal contact force, b, the mesh's
connectivities and facet tags — equals the level's while it was whole, bit for bit.  Run
by tests/test_adaptive.py in-process and under mpirun:

    python tests/restore_level.py OUT.json
"""

import json
import sys
from pathlib import Path

import contact
from contact.adaptivity.bare import present
from contact.drivers import adaptive as loop
from contact.setup.run import adapt
from contact.solvers.result import owned_residual

import numpy as np
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]


def values(level) -> dict[str, np.ndarray]:
    """The level's fields, this rank's part: what restoring it must give back."""
    r = level.result
    fields = {n: getattr(r, n).x.array.copy() for n in ("u_h", "lmbda_h", "gap", "active")}
    fields["eta_T"] = level.estimate.eta_T.x.array.copy()
    fields["force"] = owned_residual(r)
    fields["b"] = level.problem.b.array.copy()
    topology = level.domain.mesh.topology
    for d0, d1 in np.ndindex(3, 3):
        if present(topology, d0, d1):
            fields[f"{d0}->{d1}"] = topology.connectivity(d0, d1).array.copy()
    fields["facet tags"] = level.domain.facets.indices.copy()
    return fields


def run(stow: bool) -> dict:
    """Run the failing loop with ``STOW_PREVIOUS = stow``; return its record (the same on
    every rank: ``equal`` holds on all ranks)."""
    scene = contact.load_scene(
        ROOT / "configs" / "signorini_free_boundary.yaml", ["output.verbose=false"]
    )
    solve_level, old = loop.solve_level, loop.STOW_PREVIOUS
    held, whole = [], {}

    def spied(*args, **kwargs):
        previous = kwargs["previous"]
        if previous is None:
            return solve_level(*args, **kwargs)
        # what the level the loop will release holds during this solve
        msh = previous.domain.mesh if previous.stowed is None else previous.stowed.domain.mesh
        held.append(
            {
                "problem": previous.problem is not None,
                "u_h": previous.result.u_h is not None,
                "scene": previous.scene is not None,
                "mesh": [list(k) for k in np.ndindex(3, 3) if present(msh.topology, *k)],
            }
        )
        if previous.index < 2:
            return solve_level(*args, **kwargs)
        solve = args[5]  # level 3's solve fails: level 2 is the last that converged

        def failing(*a, **k):
            result = solve(*a, **k)
            result.converged, result.reason = False, "diverged_max_it"
            return result

        return solve_level(*args[:5], failing, *args[6:], **kwargs)

    def on_level(level):  # the fields while the level is whole
        if level.result.converged:
            whole[level.index] = values(level)

    loop.solve_level, loop.STOW_PREVIOUS = spied, stow
    try:
        out = adapt(scene, max_levels=6, verbose=False, keep=lambda lv: False, on_level=on_level)
    finally:
        loop.solve_level, loop.STOW_PREVIOUS = solve_level, old
    kept = out.levels[-2]
    restored = values(kept)
    comm = kept.domain.comm
    equal = {
        name: comm.allreduce(
            name in restored and np.array_equal(restored[name], value, equal_nan=True),
            op=MPI.LAND,
        )
        for name, value in whole[kept.index].items()
    }
    return {
        "levels": len(out.levels),
        "stop": out.stop,
        "kept": kept.index,
        "whole": kept.scene is not None and kept.stowed is None,
        "same_scene": kept.scene.mesh is kept.domain.mesh and kept.result.problem is kept.problem,
        "held": held,
        "fields": sorted(restored),
        "equal": equal,
        "rows": [[r["dofs"], r["eta"], r["error"]] for r in out.rows],
        "bound": contact.estimate(kept.problem, kept.result, "equilibrated").eta,
    }


if __name__ == "__main__":
    record = {str(stow): run(stow) for stow in (False, True)}
    if MPI.COMM_WORLD.rank == 0:
        Path(sys.argv[1]).write_text(json.dumps(record))
