"""demos/demo_two_bodies.py runs as written at a small size and prints its key figures:
the patch test's pressure exact on both sides, action = reaction, Hertz's a and p0, the
Cattaneo–Mindlin stick zones."""

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _number(pattern: str, text: str) -> float:
    return float(re.search(pattern, text).group(1))


def test_demo_two_bodies(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(ROOT / "demos" / "demo_two_bodies.py"), "3"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)},
    )
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert _number(r"largest \|λ_i \+ p\| / p = (\S+) \(slave side\)", out) < 1e-8
    assert _number(r"(\S+) \(master side\)", out) < 1e-8
    assert _number(r"balance error (\S+)\)", out) < 1e-9  # equilibrium to the CG + GAMG tolerance
    assert abs(_number(r"peak pressure p0 = \S+ \(Hertz \S+, (\S+)%\)", out)) < 2.0
    assert abs(_number(r"half-width a = \S+ \(Hertz \S+, (\S+)%\)", out)) < 4.0
    ratios = [float(m) for m in re.findall(r"Q/\(F P\) = (\S+):", out)]
    errors = [float(m) for m in re.findall(r"Cattaneo–Mindlin \S+, (\S+)%\)", out)]
    # a coarse 7.6k-DoF mesh
    assert ratios == [0.25, 0.5, 0.75] and all(abs(e) < 6.0 for e in errors)
    assert (tmp_path / "demo_two_bodies.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
