"""The suite's test-only perturbation switch (tests/perturb/sitecustomize.py) does what it
says, in a subprocess as the suite's own ``contact run`` and ``mpirun`` children see it:
CONTACT_TEST_PERTURB=ε moves the assembled load b by a relative ε off the Dirichlet rows
and leaves the prescribed values alone; without it b is untouched."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = """
import json
import numpy as np
import contact
from contact.setup.build import build_problem
scene = contact.load_scene("configs/signorini_square.yaml", ["mesh.cells=[8,8]", "data.f=1 + x"])
p = build_problem(scene)
fixed = np.zeros(p.b.getLocalSize(), bool)
fixed[p.bcs[0].dof_indices()[0]] = True
print(json.dumps({"b": p.b.array.tolist(), "fixed": fixed.tolist()}))
"""


def _b(eps: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "CONTACT_TEST_PERTURB"}
    env["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT / "tests" / "perturb"), env.get("PYTHONPATH", "")]
    )
    if eps is not None:
        env["CONTACT_TEST_PERTURB"] = eps
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    return {k: np.array(v) for k, v in out.items()}


def test_perturbation_moves_the_load_by_a_relative_eps_off_the_dirichlet_rows() -> None:
    plain, again, moved = _b(None), _b(None), _b("1e-12")
    assert np.array_equal(plain["b"], again["b"])
    fixed, free = plain["fixed"], ~plain["fixed"]
    assert fixed.any() and np.array_equal(moved["b"][fixed], plain["b"][fixed])
    rel = np.abs(moved["b"][free] / plain["b"][free] - 1.0)
    assert 1e-14 < np.median(rel) and rel.max() < 1e-11
