"""Exit codes (issue 10, defect 2): 0 solved, 1 not converged, 2 bad input, 3 internal
error — one line each, the traceback only with ``--debug`` / ``CONTACT_DEBUG=1``, and under
``mpirun`` a failure on one rank ends the job with the same code instead of a hang.

Internal errors are provoked by a wrapper that replaces ``contact.solve`` with a function
that raises (on every rank, or on rank 1 only) and then calls the real ``contact.app.cli.main``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest
from clirun import MPIRUN, ROOT, contact, error_lines, small_scene

WRAPPER = """
import sys
from mpi4py import MPI
import contact, contact.app.cli
from petsc4py import PETSc

mode, argv = sys.argv[1], sys.argv[2:]
real = contact.solve

def broken_solve(*args, **kwargs):
    if mode == "rank1" and MPI.COMM_WORLD.rank != 1:
        return real(*args, **kwargs)
    if mode == "memory":
        raise MemoryError()
    if mode == "petsc":
        err = PETSc.Error(76)
        raise err
    raise RuntimeError("boom\\nsecond line " + "x" * 1000)

contact.solve = broken_solve
sys.exit(contact.app.cli.main(argv))
"""


def _wrapped(tmp: Path, mode: str, *args: str, ranks: int = 0, env: dict | None = None):
    import os
    import subprocess

    (tmp / "wrapper.py").write_text(WRAPPER)
    small_scene(tmp / "scene.yaml")
    cmd = [sys.executable, str(tmp / "wrapper.py"), mode, "run", "scene.yaml", "-o", "out", *args]
    if ranks:
        cmd = [str(MPIRUN), "-n", str(ranks), *cmd]
    return subprocess.run(
        cmd,
        cwd=tmp,
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "OMP_NUM_THREADS": "1", **(env or {})},
    )


def _internal(proc) -> str:
    lines = error_lines(proc)
    assert proc.returncode == 3, proc.stderr
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert len(lines[0]) <= 300
    return lines[0]


def test_internal_error_is_exit_3_in_one_line(tmp_path: Path) -> None:
    line = _internal(_wrapped(tmp_path, "all"))
    assert line.startswith("contact: internal error: RuntimeError: boom second line xxx")
    assert line.endswith("(rerun with --debug for the traceback)")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("how", ["--debug", "CONTACT_DEBUG=1"])
def test_debug_prints_the_traceback(tmp_path: Path, how: str) -> None:
    proc = _wrapped(
        tmp_path,
        "all",
        *(["--debug"] if how == "--debug" else []),
        env={"CONTACT_DEBUG": "1"} if how != "--debug" else None,
    )
    assert proc.returncode == 3
    assert "Traceback (most recent call last)" in proc.stderr and "broken_solve" in proc.stderr
    assert error_lines(proc)[-1].startswith("contact: internal error: RuntimeError: boom")


def test_memory_error_is_exit_3(tmp_path: Path) -> None:
    assert _internal(_wrapped(tmp_path, "memory")).startswith(
        "contact: internal error: out of memory"
    )


def test_petsc_error_is_exit_3_with_petsc_code(tmp_path: Path) -> None:
    assert _internal(_wrapped(tmp_path, "petsc")).startswith(
        "contact: internal error: PETSc error 76"
    )


def test_internal_error_on_every_rank_under_mpirun(tmp_path: Path) -> None:
    line = _internal(_wrapped(tmp_path, "all", ranks=2))
    assert line.startswith("contact: internal error: RuntimeError: boom")


def test_internal_error_on_one_rank_ends_the_job_with_code_3(tmp_path: Path) -> None:
    t0 = time.perf_counter()
    proc = _wrapped(tmp_path, "rank1", ranks=2)
    assert proc.returncode == 3, proc.stderr
    assert time.perf_counter() - t0 < 60
    ours = [ln for ln in error_lines(proc) if ln.startswith("contact")]
    assert ours == [ours[0]] and ours[0].startswith(
        "contact (rank 1): internal error: RuntimeError: boom"
    )
    assert "Traceback" not in proc.stderr


def test_bad_input_under_mpirun_is_exit_2_once(tmp_path: Path) -> None:
    small_scene(tmp_path / "scene.yaml", solver__mu=5)
    proc = contact(tmp_path, "run", "scene.yaml", ranks=2)
    assert proc.returncode == 2
    assert error_lines(proc) == ["contact: error: solver.mu: must lie in (0, 1), got 5.0"]


def test_not_converged_is_exit_1(tmp_path: Path) -> None:
    small_scene(tmp_path / "scene.yaml", solver__max_it=1)
    proc = contact(tmp_path, "run", "scene.yaml", "-o", "out")
    assert proc.returncode == 1
    assert error_lines(proc)[-1].startswith(
        "contact: error: solver fb did not converge (diverged_max_it)"
    )
    assert not (tmp_path / "out").exists()


def test_error_lines_are_capped(tmp_path: Path) -> None:
    small_scene(tmp_path / "scene.yaml", data__g="q" * 5000)
    proc = contact(tmp_path, "run", "scene.yaml")
    lines = error_lines(proc)
    assert proc.returncode == 2 and len(lines) == 1
    assert (
        lines[0].startswith("contact: error: data.g: unknown name 'qqqq") and len(lines[0]) <= 300
    )


@pytest.mark.parametrize("ranks", [0, 2])
def test_unknown_petsc_solver_type_is_exit_2_before_meshing(tmp_path: Path, ranks: int) -> None:
    """Checked on a tiny system when the scene is loaded: 0.5 s, not after the assembly
    (the 1500² mesh would take half a minute to build)."""
    small_scene(
        tmp_path / "scene.yaml", solver__petsc_options={"pc_factor_mat_solver_type": "nonsense"}
    )
    t0 = time.perf_counter()
    proc = contact(tmp_path, "run", "scene.yaml", "--set", "mesh.cells=[1500,1500]", ranks=ranks)
    assert time.perf_counter() - t0 < 30
    assert proc.returncode == 2
    assert error_lines(proc) == [
        "contact: error: solver.petsc_options.pc_factor_mat_solver_type: PETSc cannot use "
        "'nonsense' (Could not "
        f"locate solver type nonsense for factorization type LU and matrix type "
        f"{'mpiaij' if ranks else 'seqaij'}. "
        "Perhaps you must ./configure with --download-nonsense)"
    ]


@pytest.mark.parametrize(
    "options, expect",
    [
        (
            {"ksp_type": "cgg"},
            r"^solver\.petsc_options\.ksp_type: PETSc cannot use 'cgg' \(Unable to find "
            r"requested KSP",
        ),
        ({"pc_type": "hypre"}, r"^solver\.petsc_options\.pc_type: PETSc cannot use 'hypre'"),
        (
            {"ksp_type": "cg", "snes_linesearch_type": "zz"},
            r"^solver\.petsc_options\.snes_linesearch_type: ",
        ),
    ],
)
def test_petsc_options_checked_in_the_api(options: dict, expect: str) -> None:
    import contact as ct

    scene = ct.load_scene(str(ROOT / "configs" / "signorini_square.yaml"), ["mesh.cells=[4,4]"])
    with pytest.raises(ct.ConfigError, match=expect):
        ct.solve(scene, petsc_options=options, verbose=False)
    with pytest.raises(ct.ConfigError, match=expect):
        ct.load_scene(
            str(ROOT / "configs" / "signorini_square.yaml"),
            ["mesh.cells=[4,4]", f"solver.petsc_options={options}"],
        )


@pytest.mark.parametrize("ranks", [0, 2])
def test_adaptive_run_failing_at_level_2_keeps_levels_0_and_1(tmp_path: Path, ranks: int) -> None:
    """Cold starts (nested: false) need 2, 4, 5 Newton steps on the uniform levels 0, 1, 2
    of the 4×4 square; with max_it = 4 level 2 fails.  Defect 6: the two finished levels
    are written as a complete folder, marked as failed, exit code 1."""
    import csv
    import json

    small_scene(
        tmp_path / "scene.yaml",
        cells=4,
        solver__max_it=4,
        adapt={"strategy": "uniform", "max_levels": 4, "nested": False},
    )
    proc = contact(tmp_path, "run", "scene.yaml", "-o", "out", "-q", ranks=ranks)
    assert proc.returncode == 1, proc.stderr
    assert error_lines(proc)[-1].startswith(
        "contact: error: solver did not converge on level 2 (diverged_max_it)"
    )
    assert "kept levels 0-1 in out/" in error_lines(proc)[-1]
    out = tmp_path / "out"
    names = {p.name for p in out.iterdir()}
    assert {
        "solution_000.vtu",
        "solution_001.vtu",
        "solution.pvd",
        "convergence.csv",
        "summary.json",
        ".contact-result",
    } <= names
    assert (
        "solution_002.vtu" not in names
        and "solution_002.vtu" not in (out / "solution.pvd").read_text()
    )
    rows = list(csv.DictReader(open(out / "convergence.csv")))
    assert [int(r["dofs"]) for r in rows] == [25, 81]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] is False and summary["failed_level"] == 2 and summary["levels"] == 2
    assert summary["failed_reason"] == "diverged_max_it"
    # no temporaries left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "scene.yaml"]


def test_readme_documents_the_exit_codes() -> None:
    from contact.app import failures

    text = (ROOT / "docs" / "guide" / "safe-runs.md").read_text()
    rows = {
        line.split("|")[1].strip(): line
        for line in text.splitlines()
        if line.startswith("| ")
        and line.split("|")[1].strip() in ("0", "1", "2", "3", "130", "143")
    }
    assert set(rows) == {"0", "1", "2", "3", "130", "143"}
    assert (
        "solved" in rows[str(failures.SOLVED)]
        and "did not converge" in rows[str(failures.NOT_CONVERGED)]
    )
    assert (
        "bad input" in rows[str(failures.BAD_INPUT)]
        and "internal error" in rows[str(failures.INTERNAL)]
    )
    assert "interrupted (Ctrl-C" in rows[str(failures.INTERRUPTED)]
    assert "terminated (SIGTERM" in rows[str(failures.TERMINATED)]
    assert "--debug" in text and "CONTACT_DEBUG=1" in text


@pytest.mark.parametrize("ranks", [0, 2])
def test_the_level_kept_for_a_failing_last_level_is_written_as_if_it_were_last(
    tmp_path: Path, ranks: int
) -> None:
    """With ``output.levels: last`` a run failing on level 2 writes level 1's files after
    the loop, from the level kept through level 2's solve (stowed: its mesh and nodal values
    only, its problem built again once level 2 has failed, contact.drivers.adaptive.restore):
    the files are those of a run that stops at level 1, but for the failure's marks and the
    clocks."""
    import csv
    import json

    import h5py
    import numpy as np

    for name, levels in (("failing", 4), ("stopping", 2)):
        small_scene(
            tmp_path / f"{name}.yaml",
            cells=4,
            solver__max_it=4,
            output__levels="last",
            adapt={"strategy": "uniform", "max_levels": levels, "nested": False},
        )
        proc = contact(tmp_path, "run", f"{name}.yaml", "-o", name, "-q", ranks=ranks)
        assert proc.returncode == (1 if name == "failing" else 0), proc.stderr
    failing, stopping = tmp_path / "failing", tmp_path / "stopping"
    assert sorted(p.name for p in failing.iterdir()) == sorted(p.name for p in stopping.iterdir())
    assert (failing / "contact.csv").read_bytes() == (stopping / "contact.csv").read_bytes()
    rows = [list(csv.DictReader(open(f / "convergence.csv"))) for f in (failing, stopping)]
    assert [r["dofs"] for r in rows[0]] == [r["dofs"] for r in rows[1]] == ["25", "81"]

    def figures(folder: Path) -> dict:
        info = json.loads((folder / "summary.json").read_text())
        clocks = ("time", "seconds", "wall", "stop", "converged", "failed")
        return {k: v for k, v in info.items() if not k.startswith(clocks)}

    assert figures(failing) == figures(stopping)
    summary = json.loads((failing / "summary.json").read_text())
    assert summary["failed_level"] == 2 and summary["converged"] is False
    for h5 in sorted(stopping.glob("*.h5")):
        with h5py.File(h5) as a, h5py.File(failing / h5.name) as b:
            keys: list[str] = []
            a.visititems(
                lambda k, o, keys=keys: keys.append(k) if isinstance(o, h5py.Dataset) else None
            )
            assert keys
            for key in keys:
                assert np.array_equal(a[key][()], b[key][()], equal_nan=True), (h5.name, key)
