"""contact.csv's polar columns of a 3D contact zone: θ ∈ (−π, π] the same on any number of
ranks, no signed zeros (a point on the axis −t₁ is θ = +π, whatever sign the round-off of its
other coordinate has on a partition)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

from contact.post.contact_table import polar

import numpy as np
import pytest
from clirun import ROOT, contact


def test_polar_angle_on_the_negative_axis_is_plus_pi() -> None:
    t1, t2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    rel = np.array(
        [
            [-0.5, -0.0, 0.0],  # a signed zero
            [-0.5, -4.27e-18, 0.0],  # round-off below the axis
            [-0.5, 4.27e-18, 0.0],  # and above it
            [-0.0, -0.0, 0.0],  # the origin
            [0.3, -0.4, 0.0],  # an ordinary point
        ]
    )
    out = polar(rel, t1, t2, 1e-12)
    assert out["theta"][:3].tolist() == [math.pi] * 3
    assert out["theta"][3] == 0.0 and not np.signbit(out["theta"][3])
    assert out["theta"][4] == math.atan2(-0.4, 0.3) and out["r"][4] == pytest.approx(0.5)
    assert not np.any(np.signbit(out["r"]))


def _rows(folder: Path) -> dict[tuple[float, float], dict[str, str]]:
    with open(folder / "contact.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {(round(float(r["x"]), 9), round(float(r["y"]), 9)): r for r in rows}


@pytest.mark.mpi
def test_theta_of_the_3d_patch_test_is_the_same_on_1_and_2_ranks(tmp_path: Path) -> None:
    """The 3D patch test's slave nodes: the first point of contact is the corner on both
    symmetry planes, so a row of nodes lies on the axis θ = ±π, their y round-off zeros
    that differ with the partition; every θ agrees to round-off (no 2π jump) and no
    column of contact.csv holds a −0."""
    scene = ROOT / "configs" / "two_body_patch_3d.yaml"
    runs = {}
    for ranks in (0, 2):
        out = tmp_path / f"np{ranks}"
        proc = contact(
            tmp_path,
            "run",
            str(scene),
            "-o",
            str(out),
            "-q",
            "--set",
            "output.png=false",
            ranks=ranks,
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        text = (out / "contact.csv").read_text()
        assert not any(
            v.startswith("-0.0") and float(v) == 0.0 for v in text.replace("\n", ",").split(",")
        )
        runs[ranks] = _rows(out)
    serial, parallel = runs[0], runs[2]
    assert set(serial) == set(parallel) and len(serial) == 14 * 14
    on_axis = [k for k, r in serial.items() if abs(float(r["theta"])) == math.pi]
    assert on_axis and all(float(serial[k]["theta"]) == math.pi for k in on_axis)
    worst = max(abs(float(serial[k]["theta"]) - float(parallel[k]["theta"])) for k in serial)
    assert worst <= 1e-12
