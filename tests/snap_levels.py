"""Refine a coarse Hertz scene twice (every cell, then the cells near the contact point) and
save the owned geometry nodes sorted by coordinate, and whether each rank's ghost nodes
agree bit for bit with their owners (run under mpirun; used by tests/test_geometry.py).

    python tests/snap_levels.py OUT.json KIND        # KIND: quarter_disk or sphere_octant
"""

import json
import sys
from pathlib import Path

import contact
from contact import refine

import numpy as np
from dolfinx import la
from dolfinx import mesh as dmesh
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]

# coarse Hertz scenes (scene file, radius R, overrides); R ≠ 1 so that a missing factor R shows
SCENES = {
    "quarter_disk": (
        "hertz_2d.yaml",
        2.0,
        ["mesh.radius=2", "mesh.h=0.4", "mesh.h_contact=0.1", "mesh.zone=0.5"],
    ),
    "sphere_octant": (
        "hertz_3d.yaml",
        1.5,
        ["mesh.radius=1.5", "mesh.h=0.4", "mesh.h_contact=0.15", "mesh.zone=0.3"],
    ),
}
# the second refinement marks the cells whose midpoint is this close to the contact point (× R)
NEAR = 0.4


def load(kind: str) -> tuple[contact.Scene, float]:
    """The coarse scene ``kind`` and its radius R."""
    name, R, overrides = SCENES[kind]
    return contact.load_scene(ROOT / "configs" / name, ["output.verbose=false", *overrides]), R


def near_contact(msh: dmesh.Mesh, distance: float) -> np.ndarray:
    """Owned cells whose midpoint lies within ``distance`` of the contact point (the origin);
    all owned cells for distance = inf.  Partition independent."""
    tdim = msh.topology.dim
    cells = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    return cells[np.linalg.norm(dmesh.compute_midpoints(msh, tdim, cells), axis=1) < distance]


def refinements(kind: str):
    """Yield (scene, R) for the coarse scene, after a uniform refinement, and after a
    refinement near the contact point."""
    scene, R = load(kind)
    yield scene, R
    for distance in (np.inf, NEAR * R):
        scene, _ = refine(scene, near_contact(scene.mesh, distance))
        yield scene, R


def ghosts_disagree(msh: dmesh.Mesh) -> int:
    """Number of ghost geometry nodes (over all ranks) whose coordinates differ from the
    owner's in any bit."""
    imap, gdim = msh.geometry.index_map(), msh.geometry.dim
    mine = msh.geometry.x[:, :gdim]
    owners = la.vector(imap, gdim)
    owners.array.reshape(-1, gdim)[:] = mine
    owners.scatter_forward()
    differ = np.any(owners.array.reshape(-1, gdim) != mine, axis=1)
    return msh.comm.allreduce(int(differ.sum()), op=MPI.SUM)


def main(out: str, kind: str) -> None:
    *_, (scene, _) = refinements(kind)
    msh = scene.mesh
    n_owned = msh.geometry.index_map().size_local
    parts = msh.comm.gather(msh.geometry.x[:n_owned, : msh.geometry.dim], root=0)
    disagree = ghosts_disagree(msh)
    if msh.comm.rank == 0:
        X = np.vstack(parts)
        X = X[np.lexsort(np.round(X, 12).T[::-1])]
        Path(out).write_text(json.dumps({"x": X.tolist(), "ghosts_disagree": disagree}))


if __name__ == "__main__":
    main(*sys.argv[1:])
