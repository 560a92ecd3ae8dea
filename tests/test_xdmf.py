"""XDMF output (issue 27), read back in this process from folders `contact run` wrote in
another: every .xdmf with meshio and with h5py + the XML (tests/readback.py), every .vtu
with meshio and pyvista; the same content from 1 and 2 MPI ranks up to the order of nodes
and cells; load steps as a temporal collection with time t; `output.formats` choosing
the files."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from readback import by_position, read_vtu, read_xdmf

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
SQUARE = ROOT / "configs" / "signorini_square.yaml"
BLOCK = ROOT / "configs" / "friction_block_2d.yaml"


def _run(args, nproc=1, cwd=ROOT):
    cmd = [sys.executable, "-m", "contact.app.cli", "run"] + [str(a) for a in args]
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc)] + cmd
    return subprocess.run(
        cmd,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )


def _content(step: dict) -> tuple:
    """A step's points and fields sorted by position, and its cells' sorted cell values."""
    names = sorted(step["point"])
    nodal = by_position(step["points"], *(step["point"][n] for n in names))
    return nodal, names, {n: np.sort(v.ravel()) for n, v in step["cell"].items()}


@pytest.mark.mpi
@pytest.mark.parametrize(
    "scene,sets",
    [
        ("signorini_square.yaml", ["mesh.cells=[16,12]"]),
        ("block_on_plane.yaml", ["mesh.cells=[12,6]", "adapt=none"]),
    ],
)
def test_one_and_two_ranks_write_the_same_fields(tmp_path, scene, sets):
    """The XDMF grid and the .vtu of a 2-rank run hold the serial run's points, cells and
    values (to the solver's tolerance), in another order."""
    steps, grids = {}, {}
    for nproc in (1, 2):
        out = tmp_path / f"np{nproc}"
        proc = _run(
            [
                ROOT / "configs" / scene,
                "-o",
                out,
                "-q",
                "--set",
                "output.png=false",
                *(f"--set={s}" for s in sets),
            ],
            nproc,
        )
        assert proc.returncode == 0, proc.stderr
        (steps[nproc],) = read_xdmf(out / "solution.xdmf")
        grids[nproc] = read_vtu(out / "solution.vtu")
        assert json.loads((out / "summary.json").read_text())["mpi_ranks"] == nproc
    (n1, names, c1), (n2, names2, c2) = _content(steps[1]), _content(steps[2])
    assert names == names2 and len(steps[1]["cells"]) == len(steps[2]["cells"])
    assert np.array_equal(n1[0], n2[0]), "the same points"
    scale = max(np.nanmax(np.abs(v)) for v in n1[1:]) or 1.0
    for name, a, b in zip(names, n1[1:], n2[1:]):
        assert np.array_equal(np.isnan(a), np.isnan(b)), name
        assert np.allclose(a, b, rtol=0, atol=1e-8 * scale, equal_nan=True), name
    assert c1.keys() == c2.keys()
    for name in c1:
        assert np.allclose(c1[name], c2[name], rtol=1e-7), name
    # the .vtu: the same points and values as the serial one too
    v1, v2 = (
        by_position(np.asarray(g.points), *(np.asarray(g.point_data[n]) for n in names))
        for g in (grids[1], grids[2])
    )
    assert np.allclose(v1[0], v2[0], rtol=0, atol=1e-12)
    for name, a, b in zip(names, v1[1:], v2[1:]):
        assert np.allclose(a, b, rtol=0, atol=1e-8 * scale, equal_nan=True), name


@pytest.mark.mpi
def test_load_steps_are_one_temporal_collection(tmp_path):
    """Three load steps on 2 ranks: solution.xdmf is a temporal collection with times
    t = 1/3, 2/3, 1, one grid per step with the mesh's node count of every field; each
    step's own file holds that step's grid."""
    out = tmp_path / "steps"
    proc = _run(
        [
            BLOCK,
            "-o",
            out,
            "-q",
            "--set",
            "output.png=false",
            "--set",
            "friction.law=none",
            "--set",
            "load.steps=3",
            "--set",
            "mesh.cells=[20,5]",
        ],
        2,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    steps = read_xdmf(out / "solution.xdmf")
    assert [s["time"] for s in steps] == pytest.approx([1 / 3, 2 / 3, 1.0])
    assert steps[0]["files"] == ["solution_000.h5", "solution_001.h5", "solution_002.h5"]
    for k, step in enumerate(steps):
        n = len(step["points"])
        assert 2 * n == summary["dofs"] and len(step["cells"]) == 2 * 20 * 5
        assert {"u_h", "lambda_h", "gap", "active"} <= set(step["point"])
        assert "von_mises" in step["cell"]
        assert step["point"]["u_h"].shape == (n, 3) and np.all(step["point"]["u_h"][:, 2] == 0)
        (alone,) = read_xdmf(out / f"solution_{k:03d}.xdmf")
        assert alone["time"] is None and np.array_equal(alone["point"]["u_h"], step["point"]["u_h"])
        grid = read_vtu(out / f"solution_{k:03d}.vtu")
        assert grid.n_points == n and grid.field_data["time"][0] == pytest.approx(step["time"])
    # the Dirichlet values on top, u_D = (drag max(t - 0.2, 0)/0.8, -delta min(t/0.2, 1)), at each t
    for step in steps:
        t, top = step["time"], step["points"][:, 1] > 0.5 - 1e-10
        expected = [0.04 * max(t - 0.2, 0) / 0.8, -0.01 * min(t / 0.2, 1)]
        assert top.sum() == 21
        assert np.allclose(step["point"]["u_h"][top, :2], expected, rtol=0, atol=1e-14)


def test_friction_steps_carry_the_friction_fields(tmp_path):
    out = tmp_path / "drag"
    proc = _run(
        [
            BLOCK,
            "-o",
            out,
            "-q",
            "--set",
            "output.png=false",
            "--set",
            "load.steps=2",
            "--set",
            "mesh.cells=[20,5]",
        ]
    )
    assert proc.returncode == 0, proc.stderr
    steps = read_xdmf(out / "solution.xdmf")
    assert [s["time"] for s in steps] == [0.5, 1.0]
    for step in steps:
        n = len(step["points"])
        assert {"lambda_t", "slip", "status", "bound"} <= set(step["point"])
        assert step["point"]["lambda_t"].shape == (n, 3) and step["point"]["status"].shape == (n, 1)
        assert set(np.unique(step["point"]["status"])) <= {-1.0, 0.0, 1.0, 2.0}


@pytest.mark.parametrize(
    "sets,present,absent",
    [
        (["output.formats=[vtk]"], {"solution.vtu"}, {"solution.xdmf", "solution.h5"}),
        (["output.xdmf=false"], {"solution.vtu"}, {"solution.xdmf", "solution.h5"}),
        (["output.formats=[xdmf]"], {"solution.xdmf", "solution.h5"}, {"solution.vtu"}),
        (
            ["output.formats=[]", "output.xdmf=true"],
            {"solution.xdmf", "solution.h5"},
            {"solution.vtu"},
        ),
        (["output.formats=[]"], set(), {"solution.xdmf", "solution.h5", "solution.vtu"}),
    ],
)
def test_formats_choose_the_field_files(tmp_path, sets, present, absent):
    out = tmp_path / "run"
    proc = _run(
        [
            SQUARE,
            "-o",
            out,
            "-q",
            "--set",
            "mesh.cells=[6,6]",
            "--set",
            "output.png=false",
            *(f"--set={s}" for s in sets),
        ]
    )
    assert proc.returncode == 0, proc.stderr
    names = {p.name for p in out.iterdir()}
    assert present <= names and not absent & names
    summary = json.loads((out / "summary.json").read_text())
    written = {
        f
        for f, ext in (("xdmf", ".xdmf"), ("vtk", ".vtu"))
        if any(n.endswith(ext) for n in present)
    }
    timed = {k for k in summary if k.startswith("time_output_")}
    assert timed == {f"time_output_{f}" for f in written}


@pytest.mark.parametrize("value,got", [("[pdf]", "['pdf']"), ("[vtk,vtk]", "['vtk', 'vtk']")])
def test_bad_formats_are_one_line_errors(tmp_path, value, got):
    proc = _run([SQUARE, "-o", tmp_path / "x", "--set", f"output.formats={value}"])
    message = f"output.formats: expected a list of distinct formats from xdmf, vtk, got {got}"
    assert proc.returncode == 2 and proc.stderr == f"contact: error: {message}\n"
    assert not (tmp_path / "x").exists()


def test_readme_scene_keys_match(tmp_path):
    """The sample `output:` line of docs/guide/scenes.md is a valid scene section."""
    readme = (ROOT / "docs" / "guide" / "scenes.md").read_text()
    line = next(ln for ln in readme.splitlines() if ln.startswith("output: {"))
    section = yaml.safe_load(line.split("#")[0])["output"]
    import contact

    sets = [f"output.{k}={json.dumps(v)}" for k, v in section.items() if k != "dir"]
    config = contact.load_scene(SQUARE, sets).config
    assert list(config.output.formats) == section["formats"]
