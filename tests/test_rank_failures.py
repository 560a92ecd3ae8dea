"""No hang, ever (issue 26, items 1 and 3): an exception on one MPI rank only — in the
solve, in the output (a collective gather, the step writer of a load path) or in one run of
a study — ends the whole job within a time bound, with exit code 3 and one line naming the
rank; Ctrl-C is one line and exit code 130, serially and under mpirun.  A file rank 0
cannot write (a full disk) is agreed on by every rank (exit code 2, one line), and a
picture that fails on one rank is a warning: the run goes on.

The exception is planted without a hook in the code: a small script replaces one function
of the package by one that raises on the chosen rank, then calls the real
``contact.app.cli.main`` (:data:`PLANT`).  Before the rules of :mod:`contact.app.failures` the
failing rank ran a collective on its way out (``io.atomic_folder``'s ``finally``, a
study's row bookkeeping) while the others waited in another one: the job hung.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from clirun import MPIRUN, ROOT, error_lines, small_scene

pytestmark = pytest.mark.mpi

BOUND = 60.0  # seconds a failing job may take, start-up and the agreement wait included

PLANT = """
import importlib, sys
from mpi4py import MPI
import contact.app.cli

target, rank, argv = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
module_name, _, name = target.rpartition(".")
module = importlib.import_module(module_name)
real = getattr(module, name)

def planted(*args, **kwargs):
    if rank < 0 or MPI.COMM_WORLD.rank == rank:
        if name == "save_vtu":
            raise OSError(28, "No space left on device")
        raise RuntimeError(f"planted in {name}")
    return real(*args, **kwargs)

setattr(module, name, planted)
sys.exit(contact.app.cli.main(argv))
"""


def _planted(
    tmp: Path, target: str, rank: int, *args: str, ranks: int = 2
) -> tuple[subprocess.CompletedProcess, float]:
    """Run ``contact ARGS`` under ``mpirun -n ranks`` with ``target`` (module.function)
    raising on ``rank`` (−1: every rank); returns the process and its wall time."""
    (tmp / "plant.py").write_text(PLANT)
    cmd = [
        str(MPIRUN),
        "-n",
        str(ranks),
        sys.executable,
        str(tmp / "plant.py"),
        target,
        str(rank),
        *args,
    ]
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        cmd,
        cwd=tmp,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1", "PYTHONWARNINGS": "ignore"},
    )
    out, err = _wait(proc)
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err), time.perf_counter() - t0


def _wait(proc: subprocess.Popen) -> tuple[str, str]:
    """(stdout, stderr) of ``proc`` once it ends; after 4 × BOUND it is ended (SIGTERM, which
    mpiexec passes on to its ranks; SIGKILL would leave them running) and the test fails."""
    try:
        return proc.communicate(timeout=4 * BOUND)
    except subprocess.TimeoutExpired:
        proc.terminate()
        try:
            _, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
        # what the job printed says where it was (a timeout alone does not)
        raise AssertionError(
            f"still running {4 * BOUND:g} s later; its stderr ends with: {(err or '')[-3000:]}"
        ) from None


def _ended_by(
    proc: subprocess.CompletedProcess, seconds: float, rank: int, code: int, text: str
) -> None:
    """The job ended within BOUND with ``code`` and one line of ours: ``rank``'s, naming
    ``text``."""
    assert seconds <= BOUND, f"{seconds:.0f} s"
    assert proc.returncode == code, proc.stderr[-3000:]
    ours = {ln for ln in error_lines(proc) if ln.startswith("contact")}
    assert len(ours) == 1, proc.stderr[-3000:]
    line = ours.pop()
    assert line.startswith(f"contact (rank {rank}): ") and text in line, line
    assert len(line) <= 300 and "Traceback" not in proc.stderr


def friction_scene(tmp: Path) -> Path:
    """friction_block_2d on a 20 × 5 mesh, two load steps, traction.png kept (its data are
    gathered through the collectives under test)."""
    import yaml

    scene = yaml.safe_load((ROOT / "configs" / "friction_block_2d.yaml").read_text())
    scene["mesh"]["cells"] = [20, 5]
    scene["load"] = {"steps": 2}
    (tmp / "friction.yaml").write_text(yaml.safe_dump(scene, sort_keys=False))
    return tmp / "friction.yaml"


# (target, rank, scene) — scene "square": the 8 × 8 Signorini square, one solve;
# "adaptive": it with two uniform levels and pictures; "friction": friction_scene
CASES = {
    "solve of a load step": ("contact.setup.run.solve", 1, "friction"),
    "step writer (surface figures)": ("contact.output.step_report.surface_figures", 1, "friction"),
    "VTK gather": ("contact.output.vtk._gather_rows", 1, "square"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_exception_on_one_rank_ends_the_job(tmp_path: Path, case: str) -> None:
    target, rank, kind = CASES[case]
    if kind == "friction":
        scene = friction_scene(tmp_path)
    else:
        scene = small_scene(
            tmp_path / "scene.yaml",
            output={"png": kind == "adaptive"},
            **({"adapt": {"strategy": "uniform", "max_levels": 2}} if kind == "adaptive" else {}),
        )
    proc, seconds = _planted(tmp_path, target, rank, "run", scene.name, "-o", "out", "-q")
    what = (
        "OSError: [Errno 28] No space left on device"
        if rank == 0
        else f"RuntimeError: planted in {target.rsplit('.', 1)[1]}"
    )
    _ended_by(proc, seconds, rank, 3, "internal error: " + what)
    assert not (tmp_path / "out").exists()


def test_a_file_rank_0_cannot_write_is_agreed_on(tmp_path: Path) -> None:
    """Writing a file fails on rank 0 (a full disk): every rank learns it (the writes of
    the output folder are agreed, contact.output.folder.write_on_root), so the job ends
    with one line naming -o and the file, exit code 2, and no abort."""
    scene = small_scene(tmp_path / "scene.yaml")
    proc, seconds = _planted(
        tmp_path, "contact.output.vtk.save_vtu", 0, "run", scene.name, "-o", "out", "-q"
    )
    assert seconds <= BOUND and proc.returncode == 2, proc.stderr[-3000:]
    assert error_lines(proc) == [
        "contact: error: -o out: cannot write solution.vtu: No space left on device; "
        "nothing was written (a previous result there is kept)"
    ]
    assert not (tmp_path / "out").exists()


def test_a_picture_failing_on_one_rank_is_a_warning(tmp_path: Path) -> None:
    """A picture rank 1 draws fails: one warning line from rank 1, and the run finishes
    (its pictures are drawn on each rank without a collective; the outcomes are gathered
    after every rank has drawn its own)."""
    scene = small_scene(
        tmp_path / "scene.yaml",
        output={"png": True},
        adapt={"strategy": "uniform", "max_levels": 2},
    )
    proc, seconds = _planted(
        tmp_path, "contact.output.drawing.mesh_2d", 1, "run", scene.name, "-o", "out", "-q"
    )
    assert seconds <= BOUND and proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "out" / "summary.json").exists()


def _tiny_study(tmp: Path) -> Path:
    study = tmp / "study.yaml"
    study.write_text(
        f"name: tiny\nscene: {ROOT / 'configs' / 'signorini_square.yaml'}\n"
        "set: ['mesh.cells=[8,8]', output.png=false]\naxes: {method: [fb, "
        "min]}\nwarmup: false\n"
    )
    return study


def test_exception_on_one_rank_in_a_study_run_ends_the_job(tmp_path: Path) -> None:
    """A study catches a failing run as a row — but only a failure on every rank: one
    rank's alone ends the job."""
    proc, seconds = _planted(
        tmp_path, "contact.setup.run.solve", 1, "study", str(_tiny_study(tmp_path)), "-o", "out"
    )
    _ended_by(
        proc, seconds, 1, 3, "internal error: study run method=fb: RuntimeError: planted in solve"
    )
    assert not (tmp_path / "out").exists()


def test_exception_on_every_rank_in_a_study_run_is_a_row(tmp_path: Path) -> None:
    import csv

    proc, seconds = _planted(
        tmp_path,
        "contact.setup.run.solve",
        -1,
        "study",
        str(_tiny_study(tmp_path)),
        "-o",
        "out",
    )
    assert proc.returncode == 0 and seconds <= BOUND, proc.stderr
    rows = list(csv.DictReader(open(tmp_path / "out" / "study.csv")))
    assert [(r["method"], r["converged"], r["failure"]) for r in rows] == [
        ("fb", "False", "RuntimeError: planted in solve"),
        ("min", "False", "RuntimeError: planted in solve"),
    ]


# ------------------------------------------------------------------------------ Ctrl-C
def _interrupt(
    tmp: Path, ranks: int, signum: int = signal.SIGINT
) -> tuple[subprocess.Popen, str, float]:
    """Start a long load path (2,000 steps of the small friction block), wait for its second
    step, then press Ctrl-C: SIGINT to the process group of the command, as a terminal
    does (mpiexec forwards it to the ranks, which hydra puts in process groups of their
    own) — or, for ``signum`` SIGTERM, ``kill -TERM`` of the command alone (mpiexec
    forwards it too).  Returns the process, its stderr and the seconds from the signal to
    its end."""
    scene = friction_scene(tmp)
    cmd = [
        sys.executable,
        "-m",
        "contact.app.cli",
        "run",
        str(scene),
        "-o",
        "out",
        "-q",
        "--set",
        "load.steps=2000",
        "--set",
        "output.vtk=false",
        "--set",
        "output.png=false",
    ]
    if ranks:
        cmd = [str(MPIRUN), "-n", str(ranks), *cmd]
    proc = subprocess.Popen(
        cmd,
        cwd=tmp,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        # a terminal's foreground job: SIGINT at its default. A suite started in the
        # background of a non-interactive shell (`make test &`) ignores SIGINT, the children
        # inherit that and Python then keeps it ignored: the Ctrl-C never arrived (240 s)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    for line in proc.stdout:
        if line.startswith("contact: step 2 "):
            break
    if signum == signal.SIGINT:
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signum)
    t0 = time.perf_counter()
    _, err = _wait(proc)
    return proc, err, time.perf_counter() - t0


@pytest.mark.parametrize(
    "signum, code, said",
    [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated (SIGTERM)")],
    ids=["SIGINT", "SIGTERM"],
)
@pytest.mark.parametrize("ranks", [0, 2])
def test_ctrl_c_is_one_line_and_exit_130(
    tmp_path: Path, ranks: int, signum: int, code: int, said: str
) -> None:
    """Ctrl-C: one line and 130; SIGTERM likewise with 143 (not PETSc's error stack and
    MPI_Abort of its own signal handler); the output folder not written either way."""
    proc, err, seconds = _interrupt(tmp_path, ranks, signum)
    assert proc.returncode == code, err[-3000:]
    assert seconds <= BOUND
    ours = [ln for ln in err.splitlines() if ln.startswith("contact")]
    # agreed by every rank: rank 0 says it once; a rank caught inside a collective cannot
    # agree: the interrupted rank says it with its number and aborts (still the same code)
    assert len(ours) == 1 and (
        ours[0] == f"contact: {said}"
        or ranks
        and ours[0].removeprefix("contact (rank 0)").removeprefix("contact (rank 1)") == f": {said}"
    ), err[-3000:]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert "PETSC ERROR" not in err and "Caught signal" not in err
    assert not (tmp_path / "out").exists()
    others = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("contact")]
    # besides ours, only mpiexec's note of the abort of a rank that could not agree
    assert all(ln.startswith("Abort(") for ln in others), err[-3000:]
