"""The hyperelastic shipped scenes (configs/hyperelastic_*.yaml) as tests/test_shipped_scenes.py
runs the others: through ``contact run`` serially with every output, every file read back,
and under ``mpirun -n 2`` (with pictures) and ``-n 3`` (without) with the serial run's
answer; the frictional finite-strain load path draws its vector force."""

from __future__ import annotations

import csv

import pytest
from scene_runs import SCENES, read_png, scene_tests

pytestmark = pytest.mark.mpi

#: the scenes of this file: every hyperelastic shipped scene
HERE = [s for s in SCENES if s.startswith("hyperelastic_")]


(
    serial,
    test_shipped_scene_with_its_outputs,
    test_shipped_scene_with_its_outputs_on_two_ranks,
    test_shipped_scene_on_three_ranks,
) = scene_tests(HERE)


def test_hyperelastic_drag_draws_its_vector_force(serial) -> None:
    """The frictional finite-strain path: force.png has the normal force −Σ w λ_n and the
    friction force |F_t| per step, whose values are steps.csv's columns."""
    out = serial("hyperelastic_drag.yaml")
    with open(out / "steps.csv", newline="") as fh:
        steps = list(csv.DictReader(fh))
    assert len(steps) == 4
    normal = [-float(s["normal_force"]) for s in steps]
    tangential = [float(s["tangential_force_x"]) for s in steps]
    assert all(f > 0 for f in normal) and any(abs(t) > 0 for t in tangential)
    read_png(out / "force.png")
