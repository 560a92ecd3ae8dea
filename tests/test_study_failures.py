"""A failed run of a study is one row whose ``failure`` cell is one line of at most 300
characters — for a PETSc error, PETSc's own message, not its 3 KB stack (issue 10, defect
10)."""

from __future__ import annotations

from contact.app import failures
from contact.app.study import run_study

from clirun import ROOT

SCENE = str(ROOT / "configs" / "signorini_square.yaml")


def _petsc_error():
    """A real PETSc error with its stack: LU with an unknown factorization package."""
    from petsc4py import PETSc

    A = PETSc.Mat().createAIJ([4, 4], nnz=1, comm=PETSc.COMM_SELF)
    for i in range(4):
        A[i, i] = 2.0
    A.assemble()
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("nonsense")
    PETSc.Sys.pushErrorHandler("python")
    try:
        ksp.setUp()
    except PETSc.Error as err:
        return err
    finally:
        PETSc.Sys.popErrorHandler()
    raise AssertionError("PETSc accepted the nonsense solver type")


def test_describe_keeps_petscs_message_not_its_stack() -> None:
    err = _petsc_error()
    assert len(str(err).splitlines()) > 4  # the stack of function names
    line = failures.describe(err)
    assert line.startswith(
        "PETSc error 92: Could not locate solver type nonsense for factorization type LU"
    )
    assert "\n" not in line and len(line) <= failures.MAX_LINE and "KSPSetUp()" not in line


def test_study_failure_cell_is_one_line(monkeypatch) -> None:
    err = _petsc_error()

    def broken(scene, **kwargs):
        raise err

    monkeypatch.setattr("contact.setup.run.solve", broken)
    study = {
        "name": "failing",
        "scene": SCENE,
        "set": ["mesh.cells=[4,4]"],
        "axes": {"method": ["fb"]},
        "warmup": False,
    }
    rows, _ = run_study(study, verbose=False)
    (row,) = rows
    assert row["converged"] is False and row["outcome"] == "error"
    assert row["failure"].startswith("PETSc error 92: Could not locate solver type nonsense")
    assert "\n" not in row["failure"] and len(row["failure"]) <= 300


def test_long_failure_texts_are_capped(monkeypatch) -> None:
    def broken(scene, **kwargs):
        raise RuntimeError("x" * 5000 + "\n" + "y" * 5000)

    monkeypatch.setattr("contact.setup.run.solve", broken)
    study = {
        "name": "failing",
        "scene": SCENE,
        "set": ["mesh.cells=[4,4]"],
        "axes": {"method": ["fb"]},
        "warmup": False,
    }
    (row,), _ = run_study(study, verbose=False)
    assert row["failure"].startswith("RuntimeError: xxx") and row["failure"].endswith("…")
    assert len(row["failure"]) == 300
