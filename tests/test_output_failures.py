"""Results are never lost to a picture, and a folder that cannot be written is one line.

* A picture that fails (planted: its drawing raises) costs one warning line naming it on
  stderr; the run keeps its exit code, every data file is written, and summary.json lists
  the picture as not written — serially and under ``mpirun -n 2`` (where rank 1 draws).
* A full disk — a 2 MB tmpfs mounted in a user and mount namespace of its own (``unshare
  -Urm``) holding a previous result — gives exit code 2 and one stderr line naming ``-o``,
  the file and "No space left on device", serially and under ``mpirun -n 2``, wherever the
  disk fills up: at the HDF5 file (its space is claimed inside it before HDF5 writes:
  HDF5 meeting a full disk aborts the process or leaves a file that cannot be closed,
  contact/output/hdf5.py), when another process fills the disk once that space is claimed
  (HDF5's writes go into the claim; DOLFINx's XML beside it is cut short), at the .vtu rank
  0 writes, at a picture.  The previous result is unchanged and no temporary is left.
  Before: exit 3 and
  54 lines of HDF5 error stack serially; under MPI exit 6, 171 lines and "Failed to close
  HDF5 file" from std::terminate.  Where no namespace can be made, the full disk is
  planted (ENOSPC raised where the HDF5 file's space is claimed, where the .vtu is saved;
  a file size limit is no stand-in: MPI's shared memory needs large files).
* A folder name too long for its temporary sibling is refused before the solve, in one
  line naming ``-o`` (before: the solve ran, then exit 2 with two lines naming neither).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from clirun import MPIRUN, contact, error_lines, small_scene
from test_rank_failures import friction_scene

PLANT = """
import os, sys
from mpi4py import MPI
import contact.app.cli
from contact.output import drawing, picture_process, step_report

what = sys.argv[1]
if what.startswith("level-1:"):  # level 1 fails (one Newton step, no polishing)
    from contact.setup import run  # the scene's solve, which its adaptive loop calls per level

    what, calls, real_solve = what.split(":", 1)[1], [], run.solve

    def failing(scene, **kwargs):
        calls.append(1)
        if len(calls) > 1:
            kwargs.update(max_it=1, polish=False)
        return real_solve(scene, **kwargs)

    run.solve = failing
if what == "race":  # another process fills the disk once the HDF5 file's space is claimed
    from contact.output import hdf5

    real_claim = hdf5.claim

    def claim_then_fill(path, nbytes):
        real_claim(path, nbytes)
        disk = os.path.dirname(os.path.dirname(path))
        fd = os.open(os.path.join(disk, "racefill"), os.O_WRONLY | os.O_CREAT)
        try:
            while True:
                os.write(fd, bytes(4096))
        except OSError:
            os.close(fd)

    hdf5.claim = claim_then_fill
elif what.startswith("enospc:"):  # a full disk planted where no tmpfs can be mounted
    import errno, importlib

    module_name, _, name = what.split(":", 1)[1].rpartition(".")

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    setattr(importlib.import_module(module_name), name, full)
elif what != "none":
    module = step_report if what == "plot_load_curve" else drawing
    real = getattr(module, what)
    # the plant is in this process: it draws its pictures (one failing in the picture
    # process: tests/test_picture_process.py)
    picture_process.ENABLED = False

    def planted(*args, **kwargs):
        raise RuntimeError(f"planted in {what}")

    setattr(module, what, planted)
sys.exit(contact.app.cli.main(sys.argv[2:]))
"""


def _plant(tmp: Path, what: str, *args: str, ranks: int = 0) -> subprocess.CompletedProcess:
    """``contact ARGS`` (serially, or under mpirun) with ``what`` planted (see PLANT)."""
    (tmp / "plant.py").write_text(PLANT)
    cmd = [sys.executable, str(tmp / "plant.py"), what, *args]
    if ranks:
        cmd = [str(MPIRUN), "-n", str(ranks), *cmd]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONWARNINGS": "default"}
    return subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True, timeout=300)


# (planted function, the picture it draws, the scene): pressure.png of one solve (rank 0),
# the solution of a load path (rank 1 on 2 ranks), its force curve (rank 0)
PICTURES = {
    "pressure": ("plot_pressure", "pressure.png", "square"),
    "solution": ("solution_2d", "solution.png", "friction"),
    "force": ("plot_load_curve", "force.png", "friction"),
}


@pytest.mark.mpi
@pytest.mark.parametrize("ranks", [0, 2])
@pytest.mark.parametrize("case", list(PICTURES))
def test_a_failing_picture_is_one_warning(tmp_path: Path, case: str, ranks: int) -> None:
    what, picture, kind = PICTURES[case]
    scene = (
        friction_scene(tmp_path)
        if kind == "friction"
        else small_scene(tmp_path / "scene.yaml", output={"png": True})
    )
    proc = _plant(tmp_path, what, "run", str(scene), "-o", "out", "-q", ranks=ranks)
    assert proc.returncode == 0, proc.stderr
    lines = error_lines(proc)  # the scene's own warnings (a coarse contact zone) besides
    assert all(ln.startswith("contact: warning: ") for ln in lines), proc.stderr
    assert [ln for ln in lines if "not written" in ln] == [
        f"contact: warning: {picture} not written: RuntimeError: planted in {what}"
    ]
    out = tmp_path / "out"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pictures"][picture] == f"not written: RuntimeError: planted in {what}"
    assert {v for k, v in summary["pictures"].items() if k != picture} == {"written"}
    assert not (out / picture).exists() and picture not in summary["files"]
    data = {"contact.csv", "history.csv", "solution.xdmf", "summary.json"}
    data |= {"steps.csv", "solution.pvd"} if kind == "friction" else {"solution.vtu"}
    assert data <= set(summary["files"]) == {p.name for p in out.iterdir()} - {".contact-result"}


def test_a_failing_picture_keeps_the_exit_code_of_the_solve(tmp_path: Path) -> None:
    """Level 1 of an adaptive run does not converge (one Newton step allowed there): exit 1
    with level 0 kept, and the failing picture is a warning besides."""
    scene = small_scene(
        tmp_path / "scene.yaml",
        output={"png": True},
        adapt={"strategy": "uniform", "max_levels": 2},
    )
    what = "level-1:plot_convergence"
    proc = _plant(tmp_path, what, "run", str(scene), "-o", "out", "-q")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert proc.returncode == 1 and summary["converged"] is False, proc.stderr
    warning = "contact: warning: convergence.png not written: RuntimeError: planted in "
    assert warning + "plot_convergence" in error_lines(proc)
    assert summary["pictures"]["convergence.png"].startswith("not written: RuntimeError")


# ------------------------------------------------------------------------------ full disk
DRIVER = """
import hashlib, json, os, subprocess, sys
disk, plant, mode = sys.argv[1], sys.argv[2], sys.argv[3]
if mode == "tmpfs":
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", disk], check=True)
out = os.path.join(disk, "res")

def run(ranks, what, cells, formats, png):
    cmd = [sys.executable, plant, what, "run", "scene.yaml", "-o", out, "-q",
           "--set", f"mesh.cells=[{cells},{cells}]", "--set", f"output.formats={formats}",
           "--set", f"output.png={png}"]
    if ranks:
        cmd = [sys.argv[4], "-n", str(ranks), *cmd]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)

def tree():
    return {name: hashlib.sha256(open(os.path.join(out, name), "rb").read()).hexdigest()
            for name in sorted(os.listdir(out))}

def leave(free):  # the filler takes all but `free` bytes of the disk
    filler = os.path.join(disk, "filler")
    open(filler, "wb").close()
    stat = os.statvfs(disk)
    with open(filler, "wb") as fh:
        fh.write(bytes(max(stat.f_bavail * stat.f_frsize - free, 0)))

first = run(0, "none", 4, "[xdmf,vtk]", "false")
assert first.returncode == 0, first.stderr
before = tree()
results = []
for *case, free in json.loads(sys.argv[5]):
    if mode == "tmpfs":
        leave(free)
    proc = run(*case)
    if os.path.exists(os.path.join(disk, "racefill")):
        os.remove(os.path.join(disk, "racefill"))
    results.append({"code": proc.returncode, "stderr": proc.stderr, "kept": tree() == before,
                    "entries": sorted(os.listdir(disk))})
print(json.dumps(results))
"""

# (ranks, planted, cells, formats, png, free bytes): where the disk fills up, the file named
FULL = [
    ((0, "none", 32, "[xdmf,vtk]", "false", 16384), "solution.h5"),
    ((0, "race", 16, "[xdmf]", "false", 400000), "solution.xdmf"),
    ((0, "none", 16, "[vtk]", "false", 16384), "solution.vtu"),
    ((0, "none", 16, "[]", "true", 16384), "solution.png"),
    ((2, "none", 32, "[xdmf,vtk]", "false", 16384), "solution.h5"),
    ((2, "race", 16, "[xdmf]", "false", 400000), "solution.xdmf"),
    ((2, "none", 16, "[vtk]", "false", 16384), "solution.vtu"),
]
#: where no tmpfs can be mounted (no user namespaces): the full disk planted
PLANTED = [
    ((ranks, f"enospc:contact.output.{where}", 16, formats, "false", 0), name)
    for ranks in (0, 2)
    for where, formats, name in (
        ("hdf5._fallocate", "[xdmf]", "solution.h5"),
        ("vtk.save_vtu", "[vtk]", "solution.vtu"),
    )
]


@pytest.mark.mpi
@pytest.mark.slow
def test_a_full_disk_is_one_line_and_the_previous_result_is_kept(tmp_path: Path) -> None:
    small_scene(tmp_path / "scene.yaml")
    (tmp_path / "plant.py").write_text(PLANT)
    (tmp_path / "driver.py").write_text(DRIVER)
    (tmp_path / "disk").mkdir()
    probe = subprocess.run(
        ["unshare", "-Urm", "mount", "-t", "tmpfs", "tmpfs", str(tmp_path / "disk")],
        capture_output=True,
    )
    mode = "tmpfs" if probe.returncode == 0 else "planted"
    cases, names = zip(*(FULL if mode == "tmpfs" else PLANTED))
    cmd = [sys.executable, "driver.py", str(tmp_path / "disk"), "plant.py", mode, str(MPIRUN)]
    cmd.append(json.dumps(cases))
    if mode == "tmpfs":
        cmd = ["unshare", "-Urm", *cmd]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    results = json.loads(proc.stdout.strip().splitlines()[-1])
    reason = "No space left on device"
    for result, case, name in zip(results, cases, names):
        where = f"{case}: {result['stderr'][-2000:]}"
        lines = [ln for ln in result["stderr"].splitlines() if ln.strip()]
        assert result["code"] == 2 and len(lines) == 1, where
        head = "contact: error: -o "
        tail = f": cannot write {name}: {reason}; nothing was written"
        tail += " (a previous result there is kept)"
        assert lines[0].startswith(head) and lines[0].endswith(tail), where
        assert len(lines[0]) <= 300, where
        # the folder as given, or (a long temporary path) its two ends around one "…"
        shown, full = lines[0][len(head) : -len(tail)], str(tmp_path / "disk" / "res")
        start, _, end = shown.partition("…")
        assert shown == full or (full.startswith(start) and full.endswith(end)), where
        assert result["kept"], where
        assert result["entries"] == (["filler", "res"] if mode == "tmpfs" else ["res"]), where
    assert len(results) == len(cases)


# ------------------------------------------------------------------------ long -o names
@pytest.mark.parametrize("length", [240, 255, 300])
def test_a_long_output_name_is_refused_before_solving(tmp_path: Path, length: int) -> None:
    small_scene(tmp_path / "scene.yaml")
    name = "r" * length
    proc = contact(tmp_path, "run", "scene.yaml", "-o", name)
    lines = error_lines(proc)
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert lines[0].startswith("contact: error: -o rrrr") and "…" in lines[0]
    assert f"the folder name is {length} bytes long; at most" in lines[0]
    assert len(lines[0]) <= 300 and "DoFs" not in proc.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.yaml"]
