"""demos/demo_torsion.py runs as written, serially and on 2 ranks, and prints its key
figures: a user's own forms (the elastic–plastic torsion of a square bar as an obstacle
problem) get grid sequencing, the guaranteed estimator and the adaptive loop from the core.
Grid sequencing needs fewer Newton iterations on the finest mesh than a cold start; the
adaptive loop's η decreases and the torque converges, below the fully plastic torque; the
same figures on 2 ranks as serially."""

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"


def _run(tmp_path: Path, ranks: int) -> str:
    cmd = [sys.executable, str(ROOT / "demos" / "demo_torsion.py"), "32"]
    proc = subprocess.run(
        [str(MPIRUN), "-n", str(ranks), *cmd] if ranks > 1 else cmd,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)},
    )
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "demo_torsion.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    return proc.stdout


def _figures(out: str) -> tuple[np.ndarray, np.ndarray]:
    uniform = re.findall(r"^\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d\.\d+)$", out, re.M)
    levels = re.findall(r"^\s+\d+\s+(\d+)\s+(\d\.\d+e[-+]\d+)\s+(\d\.\d+)", out, re.M)
    return np.array(uniform, dtype=float), np.array(levels, dtype=float)


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("serial"), 1)


def test_sequencing_and_adaptivity_of_own_forms(serial):
    uniform, levels = _figures(serial)
    assert [int(n) for n in uniform[:, 0]] == [16, 32]
    cold, sequenced = uniform[-1, 1], uniform[-1, 2]
    assert sequenced < cold and sequenced <= 4  # from the coarser solution: a few steps
    dofs, eta, torque = levels.T
    assert len(levels) == 9 and np.all(np.diff(dofs) > 0) and np.all(np.diff(eta) < 0)
    changes = np.abs(np.diff(torque))
    assert changes[-1] < 0.02 * changes[0] and torque[-1] < 8 / 3
    # the adaptive loop's torque agrees with the finest uniform mesh's within 1 %
    assert abs(torque[-1] - uniform[-1, 3]) < 0.01 * torque[-1]
    assert "reached max_levels = 9" in serial


def test_two_ranks_as_serially(serial, tmp_path):
    uniform, levels = _figures(serial)
    uniform2, levels2 = _figures(_run(tmp_path, 2))
    assert np.array_equal(uniform2[:, :3], uniform[:, :3])  # the same Newton iterations
    assert np.allclose(uniform2[:, 3], uniform[:, 3], rtol=1e-7)
    assert np.array_equal(levels2[:, 0], levels[:, 0])  # the same meshes
    assert np.allclose(levels2[:, 1:], levels[:, 1:], rtol=1e-5)
