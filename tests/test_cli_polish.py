"""CLI polish (issue #14, item 8): ``contact --version``, ``contact study --set``, and
``adapt: none`` / ``adapt.strategy: none`` for ``contact run`` as for studies."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import contact

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _contact(*args, cwd=ROOT):
    return subprocess.run(
        [sys.executable, "-m", "contact.app.cli", *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )


def test_version():
    proc = _contact("--version")
    assert proc.returncode == 0 and proc.stdout.strip() == f"contact {contact.__version__}"
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert f'version = "{contact.__version__}"' in pyproject


def test_study_set_overrides_the_scene(tmp_path):
    out = tmp_path / "study"
    proc = _contact(
        "study",
        ROOT / "configs" / "studies" / "tiny.yaml",
        "-o",
        out,
        "-q",
        "--set",
        "mesh.cells=[6,6]",
        "--set",
        "solver.max_it=40",
    )
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(open(out / "study.csv")))
    assert {r["dofs"] for r in rows} == {"49"}, "7 x 7 vertices of the 6 x 6 mesh"
    assert json.loads((out / "study.json").read_text())["set"][-2:] == [
        "mesh.cells=[6,6]",
        "solver.max_it=40",
    ]


def test_study_set_bad_key_is_one_line(tmp_path):
    proc = _contact(
        "study",
        ROOT / "configs" / "studies" / "tiny.yaml",
        "-o",
        tmp_path / "s",
        "--set",
        "mesh.cells=[0]",
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert proc.stderr.startswith("contact: error: scene.mesh.cells: must be a positive integer")
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("override", ["adapt=none", "adapt.strategy=none"])
def test_run_with_adapt_none_is_one_solve(tmp_path, override):
    out = tmp_path / "one"
    proc = _contact(
        "run", ROOT / "configs" / "signorini_free_boundary.yaml", "-o", out, "-q", "--set", override
    )
    assert proc.returncode == 0, proc.stderr
    assert "adaptive loop" not in proc.stdout
    names = {p.name for p in out.iterdir()}
    assert (
        "solution.vtu" in names and "solution.pvd" not in names and "convergence.csv" not in names
    )
    assert json.loads((out / "summary.json").read_text())["dofs"] == 17 * 9


def test_adapt_none_in_python_is_one_level():
    scene = contact.load_scene(
        ROOT / "configs" / "signorini_free_boundary.yaml", ["output.verbose=false"]
    )
    res = contact.adapt(scene, strategy="none")
    assert len(res.levels) == 1 and res.stop == "strategy none: one solve"
    assert (
        contact.load_scene(
            ROOT / "configs" / "signorini_free_boundary.yaml", ["adapt=none"]
        ).config.adapt
        is None
    )


def test_output_xdmf_and_vtk_switch_one_format():
    """The old refusal of output.xdmf is gone: it and output.vtk add or drop one format."""

    def formats(*sets: str) -> list[str]:
        scene = contact.load_scene(ROOT / "configs" / "signorini_square.yaml", list(sets))
        return list(scene.config.output.formats)

    assert formats() == formats("output.xdmf=true") == ["xdmf", "vtk"]
    assert formats("output.xdmf=false") == ["vtk"] and formats("output.vtk=false") == ["xdmf"]
    assert formats("output.formats=[]", "output.vtk=true") == ["vtk"]


@pytest.mark.parametrize(
    "overrides, steps, friction",
    [
        (["load=none"], 1, True),  # one frictional step at t = 1
        (["friction=none"], 10, False),  # the scene's 10 steps, frictionless
        (["load=none", "friction=none"], 0, False),  # one frictionless solve
    ],
)
def test_set_none_switches_a_section_off(tmp_path, overrides, steps, friction):
    """``--set load=none`` / ``friction=none`` (any optional section) as ``adapt=none``
    (issue 26): the run is the scene without that section."""
    out = tmp_path / "out"
    items = ["mesh.cells=[8,4]", "output.png=false", *overrides]
    sets = [arg for item in items for arg in ("--set", item)]
    proc = _contact("run", ROOT / "configs" / "friction_block_2d.yaml", "-o", out, "-q", *sets)
    assert proc.returncode == 0, proc.stderr
    if not steps:
        assert (out / "solution.vtu").exists() and not (out / "steps.csv").exists()
        return
    with open(out / "steps.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == steps and float(rows[-1]["time"]) == 1.0
    assert ("stick_nodes" in rows[0]) == friction


@pytest.mark.parametrize(
    "source, section",
    [
        ("friction_block_2d.yaml", "load"),
        ("friction_block_2d.yaml", "friction"),
        ("hertz_2d.yaml", "reference"),
        ("hertz_2d.yaml", "adapt"),
    ],
)
def test_none_in_the_api_and_the_scene_file(source, section):
    cfg = contact.setup.config.load_config(ROOT / "configs" / source)
    assert getattr(cfg, section) is not None
    off = contact.setup.config.load_config(ROOT / "configs" / source, [f"{section}=none"])
    assert getattr(off, section) is None
    raw = contact.setup.config.read_yaml(ROOT / "configs" / source)
    assert getattr(contact.setup.config.validate_scene({**raw, section: "none"}), section) is None
