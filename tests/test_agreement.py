"""Every semismooth method agrees with PETSc's vinewtonrsls on the same mesh, in serial
and on 2 MPI ranks, and serial and parallel answers agree (issue #2).  obtuse_square (a
sheared ``mesh.map`` mesh whose stiffness is not an M-matrix) checks that agreement does not
rest on the discrete maximum principle, and that every rank maps its nodes alike."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENES = ["signorini_square", "signorini_free_boundary", "obstacle_membrane", "obtuse_square"]
SCRIPT = ROOT / "tests" / "solve_methods.py"
MPIRUN = Path(sys.executable).parent / "mpirun"


def run_methods(
    tmp_path_factory, nproc: int, scenes: list[Path] | None = None, overrides: tuple[str, ...] = ()
) -> dict:
    """Solve ``scenes`` (default: SCENES) with every method of solve_methods.py on ``nproc``
    ranks, with ``--set``-style ``overrides``; return the gathered results by key."""
    out = tmp_path_factory.mktemp(f"np{nproc}") / "res.npz"
    scenes = scenes or [ROOT / "configs" / f"{s}.yaml" for s in SCENES]
    cmd = [sys.executable, str(SCRIPT), str(out)] + [str(s) for s in scenes] + list(overrides)
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc)] + cmd
    subprocess.run(
        cmd, check=True, cwd=ROOT, timeout=300, env={**os.environ, "OMP_NUM_THREADS": "1"}
    )
    return dict(np.load(out))


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    return run_methods(tmp_path_factory, 1)


@pytest.fixture(scope="module")
def parallel(tmp_path_factory):
    return run_methods(tmp_path_factory, 2)


@pytest.fixture(scope="module")
def serial_gamg(tmp_path_factory):
    """The Newton steps on the reduced SPD system by CG + GAMG (issue 11's default for large
    problems), the VI baseline by BiCGStab + GAMG on K."""
    return run_methods(tmp_path_factory, 1, overrides=("--set", "solver.linear=gamg"))


@pytest.fixture(scope="module")
def parallel_gamg(tmp_path_factory):
    return run_methods(tmp_path_factory, 2, overrides=("--set", "solver.linear=gamg"))


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("method", ["fb", "min", "blend", "fb-nopolish", "blend-nopolish"])
@pytest.mark.parametrize("which", ["serial", "parallel", "serial_gamg", "parallel_gamg"])
def test_method_agrees_with_vinewtonrsls(request, which, scene, method):
    assert_agrees_with_vinewtonrsls(request.getfixturevalue(which), scene, method)


def assert_agrees_with_vinewtonrsls(res: dict, scene: str, method: str) -> None:
    """Same nodes, nodal values within 1e-8 and the same active set as vinewtonrsls."""
    info, ref = res[f"{scene}/{method}/info"], res[f"{scene}/vinewtonrsls/info"]
    assert info[0] == 1 and ref[0] == 1, f"not converged: {method} {info}, rsls {ref}"
    assert np.array_equal(res[f"{scene}/{method}/X"], res[f"{scene}/vinewtonrsls/X"])
    diff = np.max(np.abs(res[f"{scene}/{method}/u"] - res[f"{scene}/vinewtonrsls/u"]))
    assert diff <= 1e-8, f"max nodal difference {diff:.3e}"
    # the counts cannot move with rounding: every constrained node is ≥ 1e-6 (relative) from
    # the tie b_i = a_i, far beyond what 1e-8 of the solution changes
    assert info[5] >= 1e-6 and ref[5] >= 1e-6, (info[5], ref[5])
    assert info[3] == ref[3], "active sets differ"


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("method", ["fb", "min", "blend", "vinewtonrsls", "fb-nopolish"])
@pytest.mark.parametrize("which", ["serial", "parallel"])
def test_complementarity_holds_nodewise(request, which, scene, method):
    comp = request.getfixturevalue(which)[f"{scene}/{method}/info"][2]
    assert comp <= 1e-8, f"|min(g - u, -c lambda)| = {comp:.3e}"


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("method", ["fb", "min", "blend", "vinewtonrsls"])
def test_serial_and_parallel_agree(serial, parallel, scene, method):
    key = f"{scene}/{method}"
    assert np.allclose(serial[key + "/X"], parallel[key + "/X"], atol=1e-12)
    for field in ("u", "lambda"):
        scale = max(np.max(np.abs(serial[f"{key}/{field}"])), 1.0)
        diff = np.max(np.abs(serial[f"{key}/{field}"] - parallel[f"{key}/{field}"]))
        assert diff <= 1e-8 * scale, f"{field}: serial vs 2 ranks differ by {diff:.3e}"
    # no node near a tie: see above
    assert min(serial[key + "/info"][5], parallel[key + "/info"][5]) >= 1e-6
    assert serial[key + "/info"][3] == parallel[key + "/info"][3]
