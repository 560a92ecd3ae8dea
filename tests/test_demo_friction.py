"""demos/demo_friction.py runs at a small size and prints its key figures: Coulomb's force
law at full sliding, Newton = fixed point, the traction picture."""
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_demo_friction_runs(tmp_path):
    proc = subprocess.run([sys.executable, str(ROOT / "demos" / "demo_friction.py"), "--cells", "40", "10",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    ratio = float(re.search(r"\|F_t\| / \|F_n\| = ([0-9.]+)", proc.stdout).group(1))
    assert abs(ratio - 0.3) <= 1e-9
    assert float(re.search(r"balances the contact force to ([0-9.e+-]+)", proc.stdout).group(1)) < 1e-12
    assert float(re.search(r"max \|u_newton - u_fixed\| / max \|u\| = ([0-9.e+-]+)", proc.stdout).group(1)) < 1e-8
    steps = re.findall(r"^\s+(\d+)\s+([0-9.]+)\s+(\d+)\s+(\d+)\s+(\d+)\s+([0-9.]+)$", proc.stdout, re.M)
    assert len(steps) == 10 and max(int(s[2]) for s in steps) <= 10
    assert int(steps[0][3]) > 0 and int(steps[-1][3]) == 0          # stick first, sliding at the end
    assert (tmp_path / "traction.png").stat().st_size > 10000
