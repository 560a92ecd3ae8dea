"""The CLI's output folder (issues #14, #27): every VTK file reads back with pyvista (VTK's
own readers) and meshio, every XDMF file with meshio and with h5py + the XML
(:mod:`readback`), with the mesh and every field at the right size — a single solve, a P2
scene (all DoFs kept), an adaptive series (read as a series) — contact.csv and pressure.png
for scalar and elastic contact, summary.json / history.csv / the "wrote" line list
everything; in serial and on 2 MPI ranks; nothing at all when the solver fails (issue #2)."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from readback import by_position, read_vtu, read_xdmf

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
SCENE = ROOT / "configs" / "signorini_square.yaml"
FIELDS = ("u_h", "lambda_h", "gap", "active")


def _contact(args, nproc=1, cwd=ROOT):
    cmd = [sys.executable, "-m", "contact.app.cli"] + [str(a) for a in args]
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc)] + cmd
    return subprocess.run(
        cmd,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )


def _rows(path: Path) -> list[dict]:
    with open(path) as fh:
        return list(csv.DictReader(fh))


def read_folder(out: Path) -> dict:
    """Read every file of a result folder with its reader: VTK with pyvista and meshio (a .pvd
    as a series), XDMF with meshio and h5py (:func:`readback.read_xdmf`: the list of its
    steps), CSV, JSON, PNG (signature).  Returns {name: content}; fails on a file it does
    not know, and on an .h5 file no .xdmf file reads."""
    import pyvista

    content, h5_read = {}, set()
    for path in sorted(out.iterdir()):
        if path.suffix == ".vtu":
            content[path.name] = read_vtu(path)
        elif path.suffix == ".xdmf":
            content[path.name] = read_xdmf(path)
            h5_read.update(content[path.name][0]["files"])
        elif path.suffix == ".h5":
            content[path.name] = path
        elif path.suffix == ".pvd":
            reader = pyvista.get_reader(path)
            steps = []
            for t in reader.time_values:
                reader.set_active_time_value(t)
                steps.append((t, reader.read()[0]))
            content[path.name] = steps
        elif path.suffix == ".csv":
            content[path.name] = _rows(path)
        elif path.suffix == ".json" or path.name == ".contact-result":  # the marker is JSON too
            content[path.name] = json.loads(path.read_text())
        elif path.suffix == ".png":
            assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000, (
                path.name
            )
            content[path.name] = path
        else:
            raise AssertionError(f"unexpected output file {path.name}")
    h5_files = {name for name in content if name.endswith(".h5")}
    assert h5_read == h5_files, "every .h5 file is read by an .xdmf file"
    return content


def check_grid(grid, summary: dict, nodal_dofs: int, vector: int = 1, cell_fields=()) -> None:
    """The grid holds one point per node of the solution space and every field."""
    assert grid.n_points * vector == summary["dofs"] and grid.n_points == nodal_dofs
    assert grid.n_cells == summary["cells"]
    u = grid.point_data["u_h"]
    assert u.shape == ((grid.n_points, 3) if vector > 1 else (grid.n_points,))
    for name in FIELDS[1:]:
        assert grid.point_data[name].shape == (grid.n_points,), name
    for name in cell_fields:
        assert grid.cell_data[name].shape == (grid.n_cells,), name
    active = grid.point_data["active"]
    assert set(np.unique(active)) <= {0.0, 1.0} and int(active.sum()) == summary["active_nodes"]
    gap = grid.point_data["gap"]
    on = np.isfinite(gap)  # the gap lives on the constrained nodes of Γ_C only
    assert on.sum() == summary["constrained_nodes"] and np.all(gap[on] >= -1e-10)


def check_step(
    step: dict, grid, summary: dict, nodal_dofs: int, vector: int = 1, cell_fields=()
) -> None:
    """An XDMF step (:func:`readback.xdmf_steps`) holds one point per node of the solution
    space, every field, and the same values at the same points as the .vtu ``grid``."""
    points = step["points"]
    assert len(points) * vector == summary["dofs"] and len(points) == nodal_dofs
    assert len(step["cells"]) == summary["cells"]
    assert step["point"]["u_h"].shape == (len(points), 3 if vector > 1 else 1)
    assert set(step["point"]) == set(grid.point_data.keys())
    assert set(step["cell"]) == set(grid.cell_data.keys())
    assert set(cell_fields) <= set(step["cell"])
    names = sorted(step["point"])
    rows = lambda values: np.asarray(values).reshape(len(points), -1)  # noqa: E731
    ours = by_position(
        np.c_[points, np.zeros((len(points), 3 - points.shape[1]))],
        *(rows(step["point"][n]) for n in names),
    )
    theirs = by_position(np.asarray(grid.points), *(rows(grid.point_data[n]) for n in names))
    assert np.allclose(ours[0], theirs[0], rtol=0, atol=1e-12), "the same points (geometry, DoFs)"
    for a, b in zip(ours[1:], theirs[1:]):
        assert np.array_equal(a, b, equal_nan=True), "the XDMF and VTK files: the same nodal values"
    for name in step["cell"]:  # compare the sorted cell values
        sorted_values = np.sort(np.asarray(grid.cell_data[name]))
        assert np.array_equal(np.sort(step["cell"][name].ravel()), sorted_values), name


def check_contact_csv(rows: list[dict], summary: dict, value: str = "lambda") -> None:
    assert len(rows) == summary["constrained_nodes"]
    pos = "s" if "s" in rows[0] else "r"
    exact = ["lambda_exact"] if "lambda_exact" in rows[0] else []  # a declared data.exact
    assert list(rows[0])[-3 - len(exact) :] == [value, *exact, "gap", "active"]
    s = np.array([float(r[pos]) for r in rows])
    assert np.all(np.isfinite(s)) and np.all(np.diff(s) >= 0), "rows sorted along Γ_C"
    lam = np.array([float(r[value]) for r in rows])
    active = np.array([int(r["active"]) for r in rows])
    assert active.sum() == summary["active_nodes"]
    assert np.all(lam[active == 1] < 0), "active nodes carry a compressive multiplier λ < 0"


@pytest.mark.parametrize("nproc", [1, 2])
def test_run_writes_complete_folder(tmp_path, nproc):
    out = tmp_path / "run"
    proc = _contact(["run", SCENE, "-o", out, "--set", "mesh.cells=[24,20]"], nproc)
    assert proc.returncode == 0, proc.stderr
    names = [
        "solution.h5",
        "solution.vtu",
        "solution.xdmf",
        "contact_surface.h5",
        "contact_surface.xdmf",
        "summary.json",
        "history.csv",
        "solution.png",
        "contact.csv",
        "pressure.png",
    ]
    # + the marker
    assert sorted(p.name for p in out.iterdir()) == sorted(names + [".contact-result"])
    files = read_folder(out)
    summary = files["summary.json"]
    assert summary["files"] == sorted(names)
    assert all(name in proc.stdout.splitlines()[-1] for name in names), (
        "the wrote line names every file"
    )
    n_vertices = 25 * 21
    check_grid(files["solution.vtu"], summary, n_vertices)
    assert files["solution.vtu"].n_cells == 2 * 24 * 20
    (step,) = files["solution.xdmf"]
    check_step(step, files["solution.vtu"], summary, n_vertices)
    assert step["topology"] == "Triangle" and step["time"] is None
    assert summary["time_output_xdmf"] > 0 and summary["time_output_vtk"] > 0
    for key in (
        "dofs",
        "mpi_ranks",
        "method",
        "newton_iterations",
        "polish_solves",
        "final_residual",
        "reason",
        "active_nodes",
        "time_assembly",
        "time_linear_solve",
        "time_other",
        "contact_force",
    ):
        assert key in summary, key
    assert summary["dofs"] == n_vertices and summary["mpi_ranks"] == nproc
    assert summary["converged"] and summary["reason"].startswith("converged")
    check_contact_csv(files["contact.csv"], summary)
    # the contact force is Σ w_i (−λ_i): the flux through Γ_C (here uniform spacing 1/24)
    lam = np.array([float(r["lambda"]) for r in files["contact.csv"]])
    w = np.full(len(lam), 1 / 24)
    w[[0, -1]] /= 2
    assert summary["contact_force"] == pytest.approx(float(np.sum(-w * lam)), rel=1e-10)
    rows = files["history.csv"]
    assert len(rows) == summary["newton_iterations"] + 1
    assert list(rows[0]) == ["iteration", "residual", "step", "active", "changed", "polished"]
    polished = sum(r["polished"] == "True" for r in rows)
    assert polished <= summary["polish_solves"]
    assert summary["linear_solves"] == summary["newton_iterations"] + summary["polish_solves"]
    assert int(rows[-1]["active"]) == summary["active_nodes"]
    if nproc == 1:
        assert "it   1" in proc.stdout, "progress line per Newton iteration"


@pytest.mark.parametrize(
    "scene,sets,vector",
    [
        ("signorini_square.yaml", ["mesh.cells=[8,6]"], 1),
        ("block_on_plane.yaml", ["mesh.cells=[8,4]", "adapt=none"], 2),
    ],
)
def test_p2_output_keeps_every_dof(tmp_path, scene, sets, vector):
    out = tmp_path / "p2"
    proc = _contact(
        [
            "run",
            ROOT / "configs" / scene,
            "-o",
            out,
            "-q",
            "--set",
            "mesh.degree=2",
            *(f"--set={s}" for s in sets),
        ]
    )
    assert proc.returncode == 0, proc.stderr
    files = read_folder(out)
    summary = files["summary.json"]
    nx, ny = [int(v) for v in sets[0].split("=")[1].strip("[]").split(",")]
    nodes = (2 * nx + 1) * (2 * ny + 1)  # vertices and edge midpoints
    check_grid(
        files["solution.vtu"],
        summary,
        nodes,
        vector,
        cell_fields=("von_mises",) if vector > 1 else (),
    )
    assert summary["degree"] == 2
    grid = files["solution.vtu"]
    assert set(np.unique(grid.celltypes)) == {69}, "VTK Lagrange triangles of degree 2"
    (step,) = files["solution.xdmf"]
    assert step["topology"] == "Triangle_6", "XDMF: the same cells with quadratic geometry"
    check_step(step, grid, summary, nodes, vector, cell_fields=("von_mises",) if vector > 1 else ())
    check_contact_csv(files["contact.csv"], summary, "lambda_n" if vector > 1 else "lambda")
    assert len(files["contact.csv"]) == summary["constrained_nodes"]


def test_adaptive_series_reads_as_one_series(tmp_path):
    out = tmp_path / "adaptive"
    proc = _contact(
        [
            "run",
            ROOT / "configs" / "signorini_free_boundary.yaml",
            "-o",
            out,
            "--set",
            "adapt.max_levels=3",
            "--set",
            "adapt.pictures=2",
            "--set",  # η = (Σ η_T²)^½ (the equilibrated bound combines its terms otherwise)
            "estimator=residual",
        ],
        2,
    )
    assert proc.returncode == 0, proc.stderr
    files = read_folder(out)
    summary = files["summary.json"]
    steps = files["solution.pvd"]
    assert [t for t, _ in steps] == [0.0, 1.0, 2.0], "the level is the series' time"
    assert [s["time"] for s in files["solution.xdmf"]] == [0.0, 1.0, 2.0]
    conv = files["convergence.csv"]
    for (t, grid), row, step in zip(steps, conv, files["solution.xdmf"]):
        assert grid.n_points == int(row["dofs"]) and grid.n_cells == int(row["cells"])
        assert grid.cell_data["eta_T"].shape == (grid.n_cells,)
        assert np.sqrt(np.sum(grid.cell_data["eta_T"] ** 2)) == pytest.approx(
            float(row["eta"]), rel=1e-10
        )
        assert int(grid.field_data["level"][0]) == t
        level = {**summary, "dofs": int(row["dofs"]), "cells": int(row["cells"])}
        check_step(step, grid, level, int(row["dofs"]), cell_fields=("eta_T",))
        (alone,) = files[f"solution_{int(t):03d}.xdmf"]  # each level's own file: the same grid
        assert all(np.array_equal(alone[k], step[k]) for k in ("points", "cells"))
    check_grid(steps[-1][1], summary, summary["dofs"], cell_fields=("eta_T",))
    # every level's Newton iterations are in history.csv and in summary.json
    hist = files["history.csv"]
    levels = [int(r["level"]) for r in hist]
    assert sorted(set(levels)) == [0, 1, 2]
    its = summary["newton_iterations_per_level"]
    assert its == [int(r["newton_iterations"]) for r in conv]
    assert [levels.count(k) for k in range(3)] == [n + 1 for n in its]
    assert summary["dofs_per_level"] == [int(r["dofs"]) for r in conv]
    assert set(summary["files"]) == set(files) - {".contact-result"}  # the marker is written last
    wrote = proc.stdout.splitlines()[-1]
    assert all(f"solution_000…002.{ext}" in wrote for ext in ("vtu", "h5", "xdmf"))
    assert all(f"contact_surface_000…002.{ext}" in wrote for ext in ("h5", "xdmf"))
    numbered = ("solution_", "contact_surface_")
    assert all(n in wrote for n in summary["files"] if not n.startswith(numbered))
    headers = [line for line in proc.stdout.splitlines() if line.split()[:2] == ["level", "DoFs"]]
    assert len(headers) == 1, "the level table is printed once"
    check_contact_csv(files["contact.csv"], summary)


def test_obstacle_contact_csv_lists_the_contact_set(tmp_path):
    out = tmp_path / "obstacle"
    proc = _contact(
        [
            "run",
            ROOT / "configs" / "obstacle_membrane.yaml",
            "-o",
            out,
            "-q",
            "--set",
            "mesh.cells=[16,16]",
        ]
    )
    assert proc.returncode == 0, proc.stderr
    files = read_folder(out)
    summary = files["summary.json"]
    rows = files["contact.csv"]
    assert len(rows) == summary["active_nodes"] > 0 and all(r["active"] == "1" for r in rows)
    assert "pressure.png" not in files, "an obstacle in Ω has no Γ_C to plot along"
    gap = files["solution.vtu"].point_data["gap"]
    assert np.all(np.isfinite(gap)), "the obstacle's gap ψ − u is defined in all of Ω"


def test_failed_solve_writes_nothing_and_exits_nonzero(tmp_path):
    out = tmp_path / "run"
    proc = _contact(
        ["run", SCENE, "-o", out, "--set", "mesh.cells=[24,20]", "--set", "solver.max_it=1"]
    )
    assert proc.returncode == 1
    assert "did not converge" in proc.stderr and "diverged_max_it" in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_existing_folder_replaced_only_when_complete(tmp_path):
    out = tmp_path / "run"
    assert _contact(["run", SCENE, "-o", out, "--set", "mesh.cells=[12,10]"]).returncode == 0
    before = json.loads((out / "summary.json").read_text())
    assert (
        _contact(
            ["run", SCENE, "-o", out, "--set", "mesh.cells=[12,10]", "--set", "solver.max_it=1"]
        ).returncode
        == 1
    )
    assert json.loads((out / "summary.json").read_text()) == before, (
        "failed run must not touch the old folder"
    )
    assert [p.name for p in tmp_path.iterdir()] == ["run"]
