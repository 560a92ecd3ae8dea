"""The suite runs what users run: every shipped scene (configs/*.yaml) through ``contact run``
with its default outputs — every field format and every picture — serially and under
``mpirun -n 2``, on small meshes (``--set``), and every file it writes opened by a reader:
XDMF with meshio and h5py (:mod:`readback`, which checks each against the other), the .h5
files with h5py, .vtu with meshio and pyvista, the .pvd's XML and the files it lists, PNG
with matplotlib's image reader, CSV and JSON with their modules.  summary.json lists
exactly the folder's files and says every picture was written; every load path writes
force.png and the ``obstacle_approach`` column of steps.csv; every scene with a contact
boundary writes the contact-surface dataset, as one grid or as a series with the steps of
solution.xdmf.  A load path on a scalar scene (which ships none) and on an obstacle in Ω:
the same, with ``load.steps`` set.  The runs on 2 and on 3 ranks (these without pictures,
but where their data pass through collectives of their own: tests/scene_runs.py) give the
serial run's answer: the same DoFs, cells and node counts on every level and step,
summary.json's figures and every column of contact.csv (the r/θ columns of 3D scenes
included) to the solver's tolerance.  One serial run of a scene is the reference of both.

This file runs the scenes of small strain; tests/test_shipped_scenes_finite_strain.py the
hyperelastic ones (two files: pytest-xdist's workers take a file each).

Before, the suite ran these scenes with ``output.png=false``: the frictional hyperelastic
load path (hyperelastic_drag) solved every step and then failed drawing force.png
(its contact force is a vector there), exit 3 and nothing written.  Before issue 26 the
frictional scenes hung under MPI after their first step (a collective entered on ranks 1…
only).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from clirun import ROOT
from scene_runs import IN_DOMAIN, PATHS, SCENES, run, scene_tests

pytestmark = pytest.mark.mpi

#: the scenes of this file: every shipped scene of small strain
HERE = [s for s in SCENES if not s.startswith("hyperelastic_")]


def test_every_shipped_scene_is_listed() -> None:
    assert {p.name for p in (ROOT / "configs").glob("*.yaml")} == set(SCENES)


(
    serial,
    test_shipped_scene_with_its_outputs,
    test_shipped_scene_with_its_outputs_on_two_ranks,
    test_shipped_scene_on_three_ranks,
) = scene_tests(HERE)


@pytest.mark.slow
@pytest.mark.parametrize("ranks", [0, 2])
@pytest.mark.parametrize("scene", list(PATHS))
def test_load_path_on_a_scene_without_one(tmp_path: Path, scene: str, ranks: int) -> None:
    """A scalar scene's load path (traction.png: its flux per step) and an obstacle in Ω's
    (no contact boundary: no traction.png, no contact surface) with the default outputs."""
    out = run(tmp_path, scene, ranks, PATHS[scene])
    assert (out / "traction.png").exists() == (scene not in IN_DOMAIN)
