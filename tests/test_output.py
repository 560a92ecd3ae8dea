"""The CLI's output folder: XDMF that reads back with the expected fields and sizes,
summary.json, history.csv and solution.png; in serial and on 2 MPI ranks; and nothing
at all when the solver fails (issue #2)."""
import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
SCENE = ROOT / "configs" / "signorini_square.yaml"
FIELDS = ("u_h", "lambda_h", "gap", "active")


def _contact(args, nproc=1, cwd=ROOT):
    cmd = [sys.executable, "-m", "contact.cli"] + [str(a) for a in args]
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc)] + cmd
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "OMP_NUM_THREADS": "1"})


@pytest.mark.parametrize("nproc", [1, 2])
def test_run_writes_complete_folder(tmp_path, nproc):
    out = tmp_path / "run"
    proc = _contact(["run", SCENE, "-o", out, "--set", "mesh.cells=[24,20]"], nproc)
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [".contact-result", "solution.xdmf", "solution.h5", "summary.json", "history.csv", "solution.png"])
    n_vertices = 25 * 21
    with h5py.File(out / "solution.h5") as h5:
        assert h5["Mesh/mesh/geometry"].shape == (n_vertices, 2)
        assert h5["Mesh/mesh/topology"].shape == (2 * 24 * 20, 3)
        for name in FIELDS:
            assert h5[f"Function/{name}/0"].shape == (n_vertices, 1), name
        active = h5["Function/active/0"][:, 0]
        lam = h5["Function/lambda_h/0"][:, 0]
        assert set(np.unique(active)) <= {0.0, 1.0}
    xdmf = (out / "solution.xdmf").read_text()
    for name in FIELDS:
        assert f'Name="{name}"' in xdmf
    summary = json.loads((out / "summary.json").read_text())
    for key in ("dofs", "mpi_ranks", "method", "newton_iterations", "polish_solves", "final_residual", "reason",
                "active_nodes", "time_assembly", "time_linear_solve", "time_other"):
        assert key in summary, key
    assert summary["dofs"] == n_vertices and summary["mpi_ranks"] == nproc
    assert summary["converged"] and summary["reason"].startswith("converged")
    assert summary["active_nodes"] == int(active.sum()) > 0
    assert np.all(lam[active == 1] < 0), "active nodes carry a compressive multiplier λ < 0"
    rows = list(csv.DictReader(open(out / "history.csv")))
    assert len(rows) == summary["newton_iterations"] + 1
    assert list(rows[0]) == ["iteration", "residual", "step", "active", "changed", "polished"]
    polished = sum(r["polished"] == "True" for r in rows)
    assert polished <= summary["polish_solves"]
    assert summary["linear_solves"] == summary["newton_iterations"] + summary["polish_solves"]
    assert int(rows[-1]["active"]) == summary["active_nodes"]
    png = (out / "solution.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    if nproc == 1:
        assert "it   1" in proc.stdout, "progress line per Newton iteration"


def test_failed_solve_writes_nothing_and_exits_nonzero(tmp_path):
    out = tmp_path / "run"
    proc = _contact(["run", SCENE, "-o", out, "--set", "mesh.cells=[24,20]", "--set", "solver.max_it=1"])
    assert proc.returncode == 1
    assert "did not converge" in proc.stderr and "diverged_max_it" in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_existing_folder_replaced_only_when_complete(tmp_path):
    out = tmp_path / "run"
    assert _contact(["run", SCENE, "-o", out, "--set", "mesh.cells=[12,10]"]).returncode == 0
    before = json.loads((out / "summary.json").read_text())
    assert _contact(["run", SCENE, "-o", out, "--set", "mesh.cells=[12,10]", "--set", "solver.max_it=1"]).returncode == 1
    assert json.loads((out / "summary.json").read_text()) == before, "failed run must not touch the old folder"
    assert [p.name for p in tmp_path.iterdir()] == ["run"]
