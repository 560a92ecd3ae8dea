"""The contact-surface dataset (contact/output/surface.py): read back with meshio and h5py,
Σ over the facets of Γ_C of area × mean nodal pressure equals summary.json's contact force —
for a 2D frictional load path (normal and tangential), a 3D Hertz adaptive run (serially
and on 2 ranks) and a two-body patch test (each side of the interface) — and the series
is one grid per step in the temporal collection scheme of solution.xdmf."""

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"


def _run(out: Path, scene: str, *sets: str, nproc: int = 1) -> dict:
    cmd = [sys.executable, "-m", "contact.app.cli", "run", str(ROOT / "configs" / scene)]
    cmd += ["-o", str(out), "-q", *(f"--set={s}" for s in sets)]
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc), *cmd]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr
    return json.loads((out / "summary.json").read_text())


def _integral(mesh: meshio.Mesh, name: str, cells: np.ndarray | None = None) -> np.ndarray:
    """Σ over facets of measure × mean of the nodal values (exact for P1 fields)."""
    X = mesh.points
    kind = "line" if "line" in mesh.cells_dict else "triangle"
    F = mesh.cells_dict[kind]
    if kind == "line":
        measure = np.linalg.norm(X[F[:, 1]] - X[F[:, 0]], axis=1)
    else:
        measure = 0.5 * np.linalg.norm(
            np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]), axis=1
        )
    values = mesh.point_data[name]
    values = values.reshape(len(X), -1)
    keep = np.ones(len(F), bool) if cells is None else cells
    return (measure[keep, None] * values[F[keep]].mean(axis=1)).sum(axis=0)


def _steps(path: Path) -> list[tuple[float, str]]:
    """(time, first HDF5 file) of each grid of a temporal collection."""
    grids = ET.parse(path).getroot().find("Domain/Grid")
    assert grids.get("CollectionType") == "Temporal"
    return [
        (float(g.find("Time").get("Value")), g.find(".//DataItem").text.split(":")[0])
        for g in grids.findall("Grid")
    ]


def test_friction_load_path_surface_carries_the_contact_forces(tmp_path):
    out = tmp_path / "friction"
    summary = _run(out, "friction_block_2d.yaml", "mesh.cells=[20,5]", "load.steps=3")
    steps = _steps(out / "contact_surface.xdmf")
    assert [t for t, _ in steps] == [t for t, _ in _steps(out / "solution.xdmf")]
    assert [h5 for _, h5 in steps] == [f"contact_surface_00{k}.h5" for k in range(3)]
    for k, step in enumerate(summary["steps"]):
        mesh = meshio.read(out / f"contact_surface_00{k}.xdmf")
        assert {"pressure", "gap", "status", "traction_t", "slip", "bound", "u_h"} <= set(
            mesh.point_data
        )
        copies = summary["symmetric_copies"]
        normal = _integral(mesh, "pressure")[0] * copies
        tangential = _integral(mesh, "traction_t")[:2] * copies
        assert normal == pytest.approx(abs(step["normal_force"]), rel=1e-10)
        # the traction on the body is the contact force's tangential part
        assert tangential == pytest.approx(step["contact_force"][:1] + [0.0], abs=1e-12)
        status = mesh.point_data["status"].ravel()
        assert set(np.unique(status)) <= {0.0, 1.0, 2.0}
        assert step["slip_nodes"] == int(np.sum(status == 2))
    with h5py.File(out / "contact_surface_002.h5") as f:
        assert "pressure" in f["Function"] and f["Mesh/mesh/geometry"].shape[1] == 2


@pytest.mark.parametrize("nproc", [1, 2])
def test_hertz_3d_surface_force_is_the_contact_force(tmp_path, nproc):
    out = tmp_path / "hertz"
    summary = _run(out, "hertz_3d.yaml", "adapt.max_levels=2", "mesh.h_contact=0.02", nproc=nproc)
    assert [t for t, _ in _steps(out / "contact_surface.xdmf")] == [0.0, 1.0]
    mesh = meshio.read(out / "contact_surface_001.xdmf")
    assert "triangle" in mesh.cells_dict and np.all(mesh.point_data["pressure"] >= -1e-12)
    force = _integral(mesh, "pressure")[0] * summary["symmetric_copies"]
    assert force == pytest.approx(summary["contact_force"], rel=1e-10)
    # the surface's points are Γ_C's nodes: as many as contact.csv has rows, or more
    # (nodes on Dirichlet / symmetry closures carry no constraint)
    assert len(mesh.points) >= summary["constrained_nodes"]


def test_two_body_surface_has_both_sides_with_equal_forces(tmp_path):
    out = tmp_path / "patch"
    summary = _run(out, "two_body_patch_2d.yaml")
    mesh = meshio.read(out / "contact_surface.xdmf")  # one solve: one grid
    part = mesh.cell_data["part"][0].ravel()
    assert len(np.unique(part)) == 2, "the slave and the master surface"
    sides = [_integral(mesh, "pressure", part == t)[0] for t in np.unique(part)]
    copies = summary["symmetric_copies"]
    assert sides[0] * copies == pytest.approx(summary["contact_force"], rel=1e-10)
    assert sides[1] == pytest.approx(sides[0], rel=1e-10), "action = reaction"
    assert "contact_surface.xdmf" in summary["files"] and "contact_surface.h5" in summary["files"]


def test_obstacle_in_the_domain_writes_no_surface(tmp_path):
    out = tmp_path / "membrane"
    summary = _run(out, "obstacle_membrane.yaml", "mesh.cells=[8,8]")
    assert not any(name.startswith("contact_surface") for name in summary["files"])


def test_surface_nodes_match_body_nodes_across_rounding_boundaries():
    """Points that differ in their last bits match even where they straddle a boundary of
    the grid the matching rounds to; points farther apart than the tolerance do not."""
    from contact.output.surface import match_points

    rng = np.random.default_rng(3)
    X = rng.uniform(-1.0, 1.0, (500, 3))
    Y = X[::-1] * (1 + 1e-15)
    assert np.array_equal(match_points(X, Y, 1e-12), np.arange(500)[::-1])
    size = 100 * 1e-12  # the grid: points at its half-spacings round apart
    B = (np.arange(20)[:, None] + 0.5) * size * np.ones((1, 2))
    assert np.array_equal(match_points(B + 1e-16, B - 1e-16, 1e-12), np.arange(20))
    assert np.all(match_points(B, B + 0.37 * size, 1e-12) == -1)
