"""The picture process of ``contact run`` (contact.output.picture_process): the pictures it
draws have the pixels the command's own process draws, the command imports no matplotlib
for them, a process that fails or is killed costs one warning line per picture it did not
draw (exit code 0, the results written), and no process is left behind — also when the
run has no pictures or fails."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from clirun import ROOT, error_lines, small_scene
from PIL import Image

#: one command in a fresh process (argv: output folder, picture process on "1"/"0", then
#: --set items); before it, ``{before}``.  Prints [exit code, matplotlib imported here,
#: the picture process's pid or None, that pid still a process after the command, the
#: command's children left]
ONE_RUN = """
import json, os, sys
import contact.output.picture_process as pp
pp.ENABLED = sys.argv[2] == "1"
{before}
pids = []
start = pp.start
def started():
    process = start()
    if process is not None:
        pids.append(process.proc.pid)
    return process
pp.start = started
from contact.app.cli import main
sets = [a for item in sys.argv[3:] for a in ("--set", item)]
code = main(["run", "configs/signorini_square.yaml", "--set", "mesh.cells=[8,8]", "--set",
             "output.verbose=false", "-o", sys.argv[1], *sets])
me = os.getpid()
children = open(f"/proc/{{me}}/task/{{me}}/children").read().split()
pid = pids[0] if pids else None
print(json.dumps([code, "matplotlib" in sys.modules, pid,
                  pid is not None and os.path.exists(f"/proc/{{pid}}"), children]))
"""


def one_run(tmp_path: Path, name: str, *sets: str, process: bool = True, before: str = ""):
    """(what :data:`ONE_RUN` prints, its stderr's lines) of a tiny run into ``tmp_path/name``."""
    script = tmp_path / f"{name}.py"
    script.write_text(ONE_RUN.format(before=before))
    proc = subprocess.run(
        [sys.executable, str(script), str(tmp_path / name), "1" if process else "0", *sets],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.splitlines()[-1]), error_lines(proc)


def pixels(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path))


def test_pictures_of_the_process_have_the_pixels_of_the_command(tmp_path):
    """With the picture process the command imports no matplotlib, yet both pictures are
    written, pixel for pixel those it draws itself (the old path); the process has ended
    when the command returns and the command has no child left."""
    (code, mpl, pid, alive, children), _ = one_run(tmp_path, "new")
    assert code == 0 and not mpl and pid is not None and not alive and children == []
    (code, mpl, pid, _, children), _ = one_run(tmp_path, "old", process=False)
    assert code == 0 and mpl and pid is None and children == []
    for name in ("solution.png", "pressure.png"):
        new, old = pixels(tmp_path / "new" / name), pixels(tmp_path / "old" / name)
        assert new.shape == old.shape and np.array_equal(new, old), name
    summary = json.loads((tmp_path / "new" / "summary.json").read_text())
    assert summary["pictures"] == {"solution.png": "written", "pressure.png": "written"}


def test_adaptive_pictures_of_the_process_have_the_pixels_of_the_command(tmp_path):
    """An adaptive run's pictures (the mesh of each level, the convergence chart, the last
    level's solution and pressure) drawn by the picture process and by the command."""
    for name, flag in (("new", "True"), ("old", "False")):
        code = (
            "import sys\n"
            "import contact.output.picture_process as pp\n"
            f"pp.ENABLED = {flag}\n"
            "from contact.app.cli import main\n"
            "sys.exit(main(['run', 'configs/signorini_square.yaml', '-o', sys.argv[1], '-q',"
            " '--set', 'mesh.cells=[4,4]', '--set', 'adapt.strategy=uniform',"
            " '--set', 'adapt.max_levels=2']))"
        )
        proc = subprocess.run(
            [sys.executable, "-c", code, str(tmp_path / name)],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr
    names = sorted(p.name for p in (tmp_path / "new").glob("*.png"))
    assert names == sorted(p.name for p in (tmp_path / "old").glob("*.png"))
    assert {"mesh_level_0.png", "mesh_level_1.png", "convergence.png", "solution.png"} <= set(
        names
    ), names
    for name in names:
        new, old = pixels(tmp_path / "new" / name), pixels(tmp_path / "old" / name)
        assert new.shape == old.shape and np.array_equal(new, old), name


#: the picture process replaced by one that reads a byte of its first picture and then
#: exits with code 7 / is killed by SIGKILL
ENDS = "import sys; sys.stdin.buffer.read(1); sys.exit(7)"
KILLED = "import os, signal, sys; sys.stdin.buffer.read(1); os.kill(os.getpid(), signal.SIGKILL)"
#: the drawing of solution.png raises / kills the child drawing it
FAILS, DIES = (
    "pp._BOOT = pp._BOOT.replace('from contact.output.picture_process import serve',"
    " 'import os, signal\\nimport contact.output.drawing as d\\n"
    f"def boom(*args, **kw): {action}\\n"
    "d.solution_2d = boom\\n"
    "from contact.output.picture_process import serve')"
    for action in ('raise ValueError("planted")', "os.kill(os.getpid(), signal.SIGKILL)")
)


def test_a_picture_process_that_ends_costs_a_warning_per_picture(tmp_path):
    """A picture process that exits or is killed while the command waits for its
    pictures: one warning line per picture naming how it ended, exit code 0, the data
    files and summary.json written (which says the pictures were not), no partial
    picture and no process left.  A picture that fails in the process, or whose drawing
    child is killed: its own warning, the other picture written."""
    for name, boot, how in (("ends", ENDS, "exit code 7"), ("killed", KILLED, "signal 9")):
        (code, mpl, pid, alive, children), lines = one_run(
            tmp_path, name, before=f"pp._BOOT = {boot!r}"
        )
        assert code == 0 and not mpl and not alive and children == [], lines
        reason = f"not written: the picture process ended ({how})"
        warned = [ln for ln in lines if "not written" in ln]
        assert warned == [
            f"contact: warning: solution.png {reason}",
            f"contact: warning: pressure.png {reason}",
        ], lines
        out = tmp_path / name
        summary = json.loads((out / "summary.json").read_text())
        assert summary["pictures"] == {"solution.png": reason, "pressure.png": reason}
        assert {"solution.xdmf", "solution.h5", "solution.vtu", "contact.csv"} <= set(
            summary["files"]
        )
        assert all((out / f).exists() for f in summary["files"])
        assert not list(out.glob("*.png"))
    (code, _, _, alive, children), lines = one_run(tmp_path, "fails", before=FAILS)
    assert code == 0 and not alive and children == []
    assert [ln for ln in lines if "not written" in ln] == [
        "contact: warning: solution.png not written: ValueError: planted"
    ], lines
    assert [p.name for p in (tmp_path / "fails").glob("*.png")] == ["pressure.png"]
    (code, _, _, alive, children), lines = one_run(tmp_path, "dies", before=DIES)
    assert code == 0 and not alive and children == []
    assert [ln for ln in lines if "not written" in ln] == [
        "contact: warning: solution.png not written: the process drawing it ended (signal 9)"
    ], lines
    assert [p.name for p in (tmp_path / "dies").glob("*.png")] == ["pressure.png"]


def test_no_picture_process_is_left_without_pictures_or_after_a_failure(tmp_path):
    """``--set output.png=false``: no process is started; a scene whose pictures are off in a
    way the command reads only when it validates the scene (here ``--set output={png:
    false}``): the process started with the command is ended as soon as the scene is
    loaded; a run that fails (exit 2, a bad key; exit 1, no convergence) ends it too."""
    (code, mpl, pid, _, children), _ = one_run(tmp_path, "bare", "output.png=false")
    assert code == 0 and not mpl and pid is None and children == []
    (code, mpl, pid, alive, children), _ = one_run(tmp_path, "late", "output={png: false}")
    assert code == 0 and not mpl and pid is not None and not alive and children == []
    assert not list((tmp_path / "late").glob("*.png"))
    scene = small_scene(tmp_path / "scene.yaml")
    script = (
        "import json, os, sys\n"
        "from contact.app.cli import main\n"
        "codes = [main(['run', sys.argv[1], '-o', sys.argv[2] + str(k), '-q', *extra]) for k,"
        " extra in enumerate((['--set', 'solver.no_such_key=1'],"
        " ['--set', 'solver.max_it=1', '--set', 'output.png=true']))]\n"
        "me = os.getpid()\n"
        "print(json.dumps([codes, open(f'/proc/{me}/task/{me}/children').read().split()]))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script, str(scene), str(tmp_path / "failed")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.splitlines()[-1]) == [[2, 1], []]
