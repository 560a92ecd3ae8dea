"""One rule chooses the driver of a scene — one solve, the adaptive loop or a load path —
for ``contact run`` and for every run of a study (:func:`contact.app.dispatch.choose_driver`)."""

from __future__ import annotations

from pathlib import Path

from contact.app.dispatch import choose_driver
from contact.setup.config import load_config

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"


@pytest.mark.parametrize(
    "scene, sets, adaptive, driver",
    [
        ("signorini_square.yaml", [], None, "solve"),
        ("signorini_smooth.yaml", [], None, "adapt"),
        ("signorini_smooth.yaml", ["adapt=none"], None, "solve"),
        ("signorini_smooth.yaml", ["adapt.strategy=none"], None, "solve"),
        ("signorini_smooth.yaml", [], False, "solve"),  # a study's single-solve run
        ("signorini_square.yaml", [], True, "adapt"),  # a study's adaptive run
        ("friction_block_2d.yaml", [], None, "load_path"),  # the slip of a step: from the last
        ("friction_block_2d.yaml", ["load=none"], False, "load_path"),
        ("hyperelastic_block.yaml", [], None, "load_path"),
        # a hyperelastic body without a load section: one step at t = 1, cut if it fails
        ("hyperelastic_block.yaml", ["load=none"], None, "load_path"),
        ("hyperelastic_block.yaml", ["load=none"], True, "load_path"),
    ],
)
def test_the_driver_of_a_scene(scene, sets, adaptive, driver):
    config = load_config(CONFIGS / scene, sets)
    assert choose_driver(config, adaptive) == driver


def test_a_study_runs_a_hyperelastic_body_as_contact_run_does(tmp_path):
    """A hyperelastic block without a load section: ``contact run`` solves it as a load path
    of one step (cut if it fails, its stability checked); a study's run does the same —
    its row carries the path's figures (the largest step's iterations, the tangent's
    negative eigenvalues and det F at the answer)."""
    from contact.app.study import run_study

    study = {
        "name": "hyper",
        "scene": str(CONFIGS / "hyperelastic_block.yaml"),
        "set": ["load=none", "output.png=false"],
        "axes": {"method": ["fb"]},
        "charts": [],
    }
    rows, levels = run_study(study, tmp_path / "out", verbose=False)
    (row,) = rows
    assert row["converged"] and row["outcome"] == "converged"
    assert row["max_step_iterations"] == row["newton_iterations"] > 0
    assert row["tangent_negative_eigenvalues"] == 0 and 0 < row["min_det_F"] < 1
    assert [lv["step"] for lv in levels] == [1] and levels[0]["time"] == 1.0
