"""The tool never touches what it did not write (issue 10, defects 1 and 7).

Every output folder carries the marker ``.contact-result``; ``contact run``/``study``
replace only such a folder holding nothing but what the tool wrote, and refuse anything
else — an existing user folder (``-o .``, ``-o results``, a scene ``output.dir`` or
``name``), a file, a path below a file, a read-only place — with exit code 2, one line
naming the option, before any solve, leaving every byte as it was.  Temporaries of killed
runs are tidied by the next run, and a replace killed between its renames is recovered.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml
from clirun import contact, error_lines, small_scene, tree

PREFIX = "contact: error: "


def _refused(proc, starts: str) -> str:
    lines = error_lines(proc)
    assert proc.returncode == 2, proc.stderr + proc.stdout
    assert len(lines) == 1 and lines[0].startswith(PREFIX + starts), proc.stderr
    assert "DoFs" not in proc.stdout, "refused only after solving"
    return lines[0]


@pytest.fixture
def workdir(tmp_path: Path) -> Path:
    small_scene(tmp_path / "scene.yaml")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("three years of work\n")
    (tmp_path / "notes.txt").write_text("do not lose\n")
    return tmp_path


@pytest.mark.parametrize("how", ["-o folder", "-o .", "output.dir", "name"])
def test_existing_user_folder_is_refused_and_untouched(workdir: Path, how: str) -> None:
    args = ["run", "scene.yaml"]
    if how == "-o folder":
        args += ["-o", "mine"]
    elif how == "-o .":
        args += ["-o", "."]
    elif how == "output.dir":
        args += ["--set", f"output.dir={workdir / 'mine'}"]
    else:  # the default folder results/<name> is the user's
        (workdir / "results" / "mine").mkdir(parents=True)
        (workdir / "results" / "mine" / "data.csv").write_text("1,2\n")
        args += ["--set", "name=mine"]
    before = tree(workdir)
    proc = contact(workdir, *args)
    line = _refused(
        proc,
        {
            "-o folder": "-o mine: ",
            "-o .": "-o .: ",
            "output.dir": "output.dir ",
            "name": "output folder results/mine (from name 'mine'): ",
        }[how],
    )
    assert "contact did not write" in line
    assert tree(workdir) == before


def test_output_at_a_file_is_refused(workdir: Path) -> None:
    before = tree(workdir)
    _refused(
        contact(workdir, "run", "scene.yaml", "-o", "notes.txt"),
        "-o notes.txt: is an existing file",
    )
    assert tree(workdir) == before  # in particular no hidden .notes.txt.old-* rename


def test_output_below_a_file_is_refused_before_solving(workdir: Path) -> None:
    before = tree(workdir)
    _refused(
        contact(workdir, "run", "scene.yaml", "-o", "notes.txt/out"),
        f"-o notes.txt/out: cannot be created: {workdir.resolve() / 'notes.txt'} is a file",
    )
    assert tree(workdir) == before


def test_read_only_folder_is_refused_before_solving(workdir: Path) -> None:
    locked = workdir / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    # root writes anywhere; a user namespace without a uid map drops that override
    prefix = ("unshare", "-U") if os.geteuid() == 0 else ()
    try:
        proc = contact(workdir, "run", "scene.yaml", "-o", "locked/out", prefix=prefix)
    finally:
        locked.chmod(0o755)
    _refused(proc, "-o locked/out: cannot be written: no permission to create entries in")
    assert list(locked.iterdir()) == []


@pytest.mark.parametrize("name", ["../escaped", "a/b", "/tmp/abs", ".."])
def test_scene_name_must_be_a_plain_folder_name(workdir: Path, name: str) -> None:
    before = tree(workdir.parent)
    _refused(
        contact(workdir, "run", "scene.yaml", "--set", f"name={name}"),
        "name: must be a plain folder name",
    )
    assert tree(workdir.parent) == before


def test_study_refuses_a_user_folder_before_any_run(workdir: Path) -> None:
    study = {"name": "s", "scene": "scene.yaml", "axes": {"method": ["fb"]}, "warmup": False}
    (workdir / "study.yaml").write_text(yaml.safe_dump(study))
    before = tree(workdir)
    proc = contact(workdir, "study", "study.yaml", "-o", "mine")
    _refused(proc, "-o mine: is an existing folder that contact did not write")
    assert "[1/1]" not in proc.stdout
    assert tree(workdir) == before


def test_rerun_replaces_its_own_result_only(workdir: Path) -> None:
    assert contact(workdir, "run", "scene.yaml", "-o", "out", "-q").returncode == 0
    marker = json.loads((workdir / "out" / ".contact-result").read_text())
    assert marker["tool"] == "contact" and marker["pid"] > 0 and "run" in marker["command"]
    assert set(marker["entries"]) == {
        "solution.h5",
        "solution.vtu",
        "solution.xdmf",
        "summary.json",
        "history.csv",
        "contact.csv",
        "contact_surface.h5",
        "contact_surface.xdmf",
    }
    (workdir / "out" / "summary.json").write_text("{}")  # the tool's own file: replaced
    assert contact(workdir, "run", "scene.yaml", "-o", "out", "-q").returncode == 0
    assert json.loads((workdir / "out" / "summary.json").read_text())["converged"] is True
    (workdir / "out" / "added.txt").write_text("mine now\n")  # a user file inside: refused
    before = tree(workdir)
    _refused(
        contact(workdir, "run", "scene.yaml", "-o", "out"),
        "-o out: is a contact result, but holds 1 file(s)",
    )
    assert tree(workdir) == before
    assert sorted(p.name for p in workdir.iterdir()) == ["mine", "notes.txt", "out", "scene.yaml"]


# ----------------------------------------------------------------------- temporaries
def _dead_pid() -> int:
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


def _fake_result(folder: Path, text: str, time: str) -> Path:
    folder.mkdir()
    (folder / "summary.json").write_text(text)
    (folder / ".contact-result").write_text(
        json.dumps({"tool": "contact", "time": time, "entries": ["summary.json"]})
    )
    return folder


def test_replace_killed_between_renames_is_recovered(tmp_path: Path) -> None:
    """The window of a two-rename replace: the previous result in .out.old-*, the new one
    complete in .out.partial-*, no out.  The next run's tidy step puts the newest complete
    result back and removes the leftovers of dead writers only."""
    from contact.output import folder

    host, dead = folder.host_tag(), _dead_pid()
    _fake_result(tmp_path / f".out.old-{host}-{dead}", "old", "2026-01-01T00:00:00+00:00")
    _fake_result(tmp_path / f".out.partial-{host}-{dead}-x1", "new", "2026-01-02T00:00:00+00:00")
    (tmp_path / f".out.partial-{host}-{dead}-x2").mkdir()  # an incomplete one
    live = tmp_path / f".out.partial-{host}-{os.getpid()}-x3"  # a live writer's
    other = tmp_path / f".out.old-otherhost-{dead}"  # another host's
    live.mkdir()
    other.mkdir()
    folder.tidy_temporaries(tmp_path / "out")
    assert (tmp_path / "out" / "summary.json").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["out", live.name, other.name])
    # with only the old one left (killed before the new one was complete): it comes back
    shutil.rmtree(tmp_path / "out")
    _fake_result(tmp_path / f".out.old-{host}-{dead}", "old", "2026-01-01T00:00:00+00:00")
    folder.tidy_temporaries(tmp_path / "out")
    assert (tmp_path / "out" / "summary.json").read_text() == "old"


def test_next_run_cleans_stale_temporaries(workdir: Path) -> None:
    from contact.output import folder

    assert contact(workdir, "run", "scene.yaml", "-o", "out", "-q").returncode == 0
    host, dead = folder.host_tag(), _dead_pid()
    stale = [workdir / f".out.partial-{host}-{dead}-abcd", workdir / f".out.old-{host}-{dead}"]
    shutil.copytree(workdir / "out", stale[0])
    shutil.copytree(workdir / "out", stale[1])
    proc = contact(workdir, "run", "scene.yaml", "-o", "out", "-q")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in workdir.iterdir()) == ["mine", "notes.txt", "out", "scene.yaml"]
