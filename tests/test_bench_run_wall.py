"""demos/bench/bench_run_wall.py: ``contact run`` as whole processes, two commands in turn.
A small L-shape loop on a level budget against a small uniform run: every run's folder is a
complete result, and the medians and ratios in the CSV are those of its rows."""

from __future__ import annotations

import csv
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_two_commands_in_turn_and_their_ratios(tmp_path: Path) -> None:
    out = tmp_path / "wall.csv"
    a = ["adapt.max_levels=3", "adapt.estimate_last=false", "output.levels=last"]
    b = ["adapt=none", "mesh.cells=8"]
    cmd = [sys.executable, str(ROOT / "demos" / "bench" / "bench_run_wall.py")]
    cmd += ["configs/lshape_corner.yaml", "--pairs", "2", "--out", str(out)]
    cmd += ["--a", *a, "--b", *b, "--set", "output.png=false"]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = list(csv.DictReader(open(out)))
    runs, (median,) = rows[:-1], rows[-1:]
    assert [(r["run"], r["pair"]) for r in runs] == [("A", "0"), ("B", "0"), ("A", "1"), ("B", "1")]
    assert {r["levels"] for r in runs if r["run"] == "A"} == {"3"}
    assert {r["levels"] for r in runs if r["run"] == "B"} == {"1"}  # one solve
    assert all(float(r["wall"]) > 0 and float(r["peak_mib"]) > 50 for r in runs)
    assert {r["eta"] for r in runs if r["run"] == "A"} == {""}  # its last level not estimated
    wall = {k: [float(r["wall"]) for r in runs if r["run"] == k] for k in "AB"}
    assert float(median["A_wall"]) == statistics.median(wall["A"])
    ratios = [x / y for x, y in zip(wall["A"], wall["B"])]
    assert float(median["ratio_wall"]) == round(statistics.median(ratios), 4)
    assert float(median["ratio_wall_min"]) == round(min(ratios), 4)
    assert median["a_sets"] == " ".join(["output.png=false", *a])
    assert median["A_dofs"] == runs[-2]["dofs"] and median["B_dofs"] == runs[-1]["dofs"]
    assert float(median["A_error"]) > 0 and float(median["B_error"]) > 0
