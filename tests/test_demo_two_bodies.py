"""demos/demo_two_bodies.py (a mortar pair of own forms, no scene) runs as written at a coarse
contact mesh, serially and on 2 ranks, and prints its checks: the interface forces on both
sides opposite (action = reaction), equal to the core's contact force and to the reaction on
the pushed top, and Hertz's peak pressure and half-width."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
H = 0.04  # the mesh size at the contact (1.9k DoFs)


def _number(pattern: str, text: str) -> float:
    return float(re.search(pattern, text).group(1))


@pytest.mark.parametrize("ranks", [1, 2])
def test_demo_two_bodies(tmp_path, ranks):
    cmd = [sys.executable, str(ROOT / "demos" / "demo_two_bodies.py"), str(H)]
    mpirun = [str(Path(sys.executable).parent / "mpirun"), "-n", str(ranks)]
    proc = subprocess.run(
        mpirun + cmd if ranks > 1 else cmd,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)},
    )
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    P = _number(r"contact force P = (\S+)", out)
    slave = _number(r"force on the slave surface (\S+),", out)
    master = _number(r", master (\S+),", out)
    top = _number(r", top (\S+)", out)
    assert P > 0 and _number(r"action = reaction to (\S+)", out) < 1e-9
    # the multipliers' force Σ D_ii λ_i is the residual's on the slave surface and on the top
    # (equilibrium of the upper body to the solver's tolerance)
    assert abs(slave - P) < 1e-6 * P and abs(master + P) < 1e-6 * P and abs(top + P) < 1e-6 * P
    assert abs(_number(r"peak pressure p0 = \S+ \(Hertz \S+, (\S+)%\)", out)) < 1.5
    assert abs(_number(r"half-width a = \S+ \(Hertz \S+, (\S+)%\)", out)) < 5.0  # h/a ≈ 8 %
    assert (tmp_path / "demo_two_bodies.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "wrote demo_two_bodies.png" in out
