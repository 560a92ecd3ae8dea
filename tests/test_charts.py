"""iterations.png (issue #14, item 7): x is the refinement level — the ``level`` axis of
single solves, or the adaptive loop's level — and cold starts are not called nested."""

import dataclasses
from pathlib import Path

from contact.app.study import load_study, run_study
from contact.output import charts

ROOT = Path(__file__).resolve().parents[1]


def _draw(study, tmp_path):
    rows, level_rows = run_study(study, verbose=False)
    png = tmp_path / "iterations.png"
    curves = charts.iterations(png, study, rows, level_rows)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    return {label: ([p["x"] for p in pts], [p["y"] for p in pts]) for label, pts in curves.items()}


def test_level_axis_study_draws_single_solves_along_the_levels(tmp_path):
    study = load_study(
        {
            "name": "levels",
            "scene": str(ROOT / "configs" / "signorini_square.yaml"),
            "set": ["mesh.cells=[8,8]"],
            "axes": {"method": ["fb", "min"], "level": [0, 1, 2]},
            "charts": ["iterations"],
            "warmup": False,
        }
    )
    curves = _draw(study, tmp_path)
    assert set(curves) == {"fb, single solves (cold)", "min, single solves (cold)"}
    for xs, ys in curves.values():
        assert xs == [0, 1, 2] and all(y >= 1 for y in ys)


def test_shipped_iterations_levels_study_nested_and_cold(tmp_path):
    shipped = load_study(ROOT / "configs" / "studies" / "iterations_levels.yaml")
    assert shipped.charts[0] == "iterations"
    study = dataclasses.replace(
        shipped,
        axes={"method": ["min"], "nested": [True, False]},
        adapt={**shipped.adapt, "max_levels": 3},
        warmup=False,
    )
    curves = _draw(study, tmp_path)
    assert set(curves) == {"min, nested", "min, cold start"}
    nested, cold = curves["min, nested"], curves["min, cold start"]
    assert nested[0] == cold[0] == [0, 1, 2]
    assert nested[1][2] < cold[1][2], "nested iteration needs fewer steps on a refined level"
