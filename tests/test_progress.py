"""What the terminal and the summary say (issue 27, item 6): a sequenced solve reports the
final mesh's Newton iterations beside the coarse levels' (CLI line, summary.json, Result);
progress lines come at most once per period, from rank 0 only; a contact zone with fewer
than five nodes across gets a one-line warning."""

import json
import os
import subprocess
import sys
from pathlib import Path

import contact
from contact.base import progress
from contact.output.run_report import nodes_across
from contact.solvers import newton_text

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
SQUARE = ROOT / "configs" / "signorini_square.yaml"


def _run(args, nproc=1):
    cmd = [sys.executable, "-m", "contact.app.cli", "run"] + [str(a) for a in args]
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc)] + cmd
    return subprocess.run(
        cmd,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )


def test_sequenced_solve_reports_final_and_coarse_iterations(tmp_path):
    """signorini_square (64 × 64) is solved after one coarser mesh: the line and summary.json
    give the final mesh's iterations and the coarse level's, which did the work."""
    out = tmp_path / "seq"
    proc = _run(
        [
            SQUARE,
            "-o",
            out,
            "-q",
            "--set",
            "output.png=false",
            "--set",
            "output.formats=[]",
            "--set",
            "solver.sequence=1",
        ]
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    (coarse,) = summary["sequence"]
    assert summary["coarse_levels"] == 1
    assert summary["newton_iterations_coarse"] == coarse["newton_iterations"] > 0
    assert summary["polish_solves_coarse"] == coarse["polish_solves"]
    line = next(ln for ln in proc.stdout.splitlines() if " DoFs, " in ln)
    polish = f" (+{summary['polish_solves']} polishing)" if summary["polish_solves"] else ""
    coarse_polish = f" (+{coarse['polish_solves']})" if coarse["polish_solves"] else ""
    assert (
        f"{summary['newton_iterations']} Newton iterations{polish} on the final mesh, "
        f"{coarse['newton_iterations']}{coarse_polish} on 1 coarser mesh"
    ) in line


def test_result_counts_coarse_iterations():
    scene = contact.load_scene(SQUARE, ["output.verbose=false", "mesh.cells=[32,32]"])
    seq = contact.solve(scene, sequence=2)
    assert len(seq.sequence) == 2
    assert seq.coarse_iterations == sum(lv.newton_iterations for lv in seq.sequence) > 0
    assert newton_text(seq).endswith(
        f"on the final mesh, {seq.coarse_iterations}"
        + (
            f" (+{sum(lv.polish_solves for lv in seq.sequence)})"
            if any(lv.polish_solves for lv in seq.sequence)
            else ""
        )
        + " on 2 coarser meshes"
    )
    cold = contact.solve(scene, sequence="off")
    assert cold.coarse_iterations == 0 and "coarser" not in newton_text(cold)
    assert newton_text(cold).startswith(f"{cold.iterations} Newton iterations")


def test_progress_lines_are_rate_limited(monkeypatch, capsys):
    """At most one line per period: notes every second for 12 s print at 5 s and 10 s; a
    line printed elsewhere (heard) restarts the clock; off, nothing is printed."""
    from mpi4py import MPI

    clock = [0.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: clock[0])
    progress.enable(MPI.COMM_SELF, period=5.0)
    try:
        printed = []
        for t in range(1, 13):
            clock[0] = float(t)
            if t == 7:
                progress.heard()
            if progress.note(f"step {t}"):
                printed.append(t)
        assert printed == [5, 12]
        assert capsys.readouterr().out == "  … step 5\n  … step 12\n"
    finally:
        progress.disable()
    clock[0] = 100.0
    assert not progress.note("off") and capsys.readouterr().out == ""


PROGRESS_SCRIPT = """
import contact
from mpi4py import MPI
from contact.base import progress
scene = contact.load_scene({scene!r}, ["output.verbose=false", "mesh.cells=[40,40]",
                                       "solver.linear=gamg", "adapt.max_levels=2"])
progress.enable(MPI.COMM_WORLD, period=0.0)
contact.adapt(scene, verbose=False)
"""


@pytest.mark.mpi
def test_progress_lines_come_from_rank_0_only(tmp_path):
    """Under mpirun -n 2 (period 0: every note prints) each progress line appears once:
    the phases of each level and the Krylov iterations of the linear solves."""
    script = tmp_path / "progress.py"
    scene = ROOT / "configs" / "signorini_free_boundary.yaml"
    script.write_text(PROGRESS_SCRIPT.format(scene=str(scene)))
    proc = subprocess.run(
        [str(MPIRUN), "-n", "2", sys.executable, str(script)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("  … ")]
    phases = ("level 0: assembled", "level 0: solved", "level 0: refining", "level 1: assembled")
    for phase in phases:
        assert sum(ln.startswith(f"  … {phase}") for ln in lines) == 1, (phase, lines)
    assert any("linear solve: " in ln and " Krylov iterations, |r| = " in ln for ln in lines), lines
    assert any(" Newton iteration " in ln for ln in lines)


@pytest.mark.parametrize("nproc", [1, pytest.param(2, marks=pytest.mark.mpi)])
def test_coarse_contact_zone_warns_once(tmp_path, nproc):
    """8 × 8 cells put 3 nodes of signorini_square in contact: one warning line (once on 2
    ranks), exit 0; 32 × 32 put enough: none."""
    quiet = ["-q", "--set", "output.png=false", "--set", "output.formats=[]"]
    proc = _run([SQUARE, "-o", tmp_path / "coarse", "--set", "mesh.cells=[8,8]", *quiet], nproc)
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    warning = (
        "contact: warning: the contact zone holds 3 active node(s), about 3.0 across: too "
        "few to resolve the contact pressure and the forces from it; refine the contact "
        "zone (mesh cells or h_contact, an adapt section) to 5 or more nodes across"
    )
    assert lines == [warning], proc.stderr
    fine = _run([SQUARE, "-o", tmp_path / "fine", "--set", "mesh.cells=[32,32]", *quiet], nproc)
    assert fine.returncode == 0 and not fine.stderr.strip(), fine.stderr


class _Problem:
    def __init__(self, tdim, in_domain, copies):
        self.V = type("V", (), {"mesh": type("M", (), {"topology": type("T", (), {"dim": tdim})})})
        self.constraint = type("C", (), {"in_domain": in_domain})
        self.symmetry = type("S", (), {"copies": copies})


@pytest.mark.parametrize(
    "tdim,in_domain,copies,n,across",
    [
        (2, False, 1, 3, 3.0),  # a curve: the nodes themselves
        (2, False, 2, 3, 6.0),  # half of a symmetric zone
        (
            3,
            False,
            4,
            1,
            2 * np.sqrt(4 / np.pi),
        ),  # a quarter disc with one node (block on a sphere)
        (2, True, 1, 20, 2 * np.sqrt(20 / np.pi)),  # an obstacle's contact set in 2D: an area
        (3, True, 1, 30, np.cbrt(180 / np.pi)),  # in 3D: a volume
    ],
)
def test_nodes_across_the_zone(tdim, in_domain, copies, n, across):
    result = type("R", (), {"problem": _Problem(tdim, in_domain, copies), "n_active": n})
    assert nodes_across(result) == pytest.approx(across)
