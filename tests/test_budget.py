"""The DoF budget ``solver.max_dofs`` (issue 10, defect 11): a problem beyond it is bad
input (exit 2 with a hint) found before the mesh is built (built-in meshes) or before the
assembly (gmsh meshes), instead of minutes of work ending in a MemoryError."""
from __future__ import annotations

import time
from pathlib import Path

import pytest
from clirun import ROOT, contact, error_lines, small_scene

import contact as ct
from contact import budget
from contact.config import load_config
from contact.models import build_problem


@pytest.mark.parametrize("ranks", [0, 2])
def test_huge_mesh_is_exit_2_before_meshing(tmp_path: Path, ranks: int) -> None:
    """5000² cells were a MemoryError after a long wait (25 M DoFs)."""
    small_scene(tmp_path / "scene.yaml")
    t0 = time.perf_counter()
    proc = contact(tmp_path, "run", "scene.yaml", "--set", "mesh.cells=[5000,5000]", ranks=ranks)
    assert time.perf_counter() - t0 < 30
    assert proc.returncode == 2
    (line,) = error_lines(proc)
    assert line.startswith("contact: error: mesh.cells: [5000, 5000] cells give 25010001 DoFs, more than "
                           "solver.max_dofs = ")
    assert line.endswith("use a coarser mesh, or --set solver.max_dofs=25010001 if it fits")


def test_explicit_budget(tmp_path: Path) -> None:
    small_scene(tmp_path / "scene.yaml")
    proc = contact(tmp_path, "run", "scene.yaml", "--set", "solver.max_dofs=80", "-o", "out")
    assert proc.returncode == 2 and error_lines(proc)[0].startswith(
        "contact: error: mesh.cells: [8, 8] cells give 81 DoFs, more than solver.max_dofs = 80")
    assert contact(tmp_path, "run", "scene.yaml", "--set", "solver.max_dofs=81", "-o", "out", "-q").returncode == 0


@pytest.mark.parametrize("value", [0, -3, 2.5, "lots", True])
def test_budget_value_is_checked(value) -> None:
    with pytest.raises(ct.ConfigError, match=r"^solver\.max_dofs: must be 'auto' or a positive integer"):
        load_config(ROOT / "configs" / "signorini_square.yaml", [f"solver.max_dofs={value}"])


def test_gmsh_mesh_is_checked_before_assembly() -> None:
    scene = ct.load_scene(ROOT / "configs" / "hertz_2d.yaml", ["solver.max_dofs=1000"])
    with pytest.raises(ct.ConfigError, match=r"^mesh: the mesh gives 8004 DoFs, more than solver\.max_dofs = 1000"):
        build_problem(scene)


def test_adaptive_loop_stops_at_the_budget() -> None:
    scene = ct.load_scene(ROOT / "configs" / "lshape_corner.yaml", ["solver.max_dofs=150"])
    res = ct.adapt(scene, verbose=False)
    assert [r["dofs"] for r in res.rows] == [65, 80, 105]
    assert res.stop == "the next level would have 172 DoFs > solver.max_dofs = 150"


@pytest.mark.parametrize("source, overrides", [
    ("signorini_square.yaml", ["mesh.cells=[7,5]"]),
    ("signorini_square.yaml", ["mesh.cells=[7,5]", "mesh.degree=2"]),
    ("signorini_square.yaml", ["mesh.cells=[7,5]", "mesh.diagonal=crossed", "mesh.degree=2"]),
    ("lshape_corner.yaml", ["mesh.cells=5", "mesh.degree=2"]),
    ("indentation_2d.yaml", []),
])
def test_estimate_is_exact_for_built_in_meshes(source: str, overrides: list) -> None:
    scene = ct.load_scene(ROOT / "configs" / source, overrides)
    problem = build_problem(scene)
    dofs = problem.V.dofmap.index_map.size_global * problem.V.dofmap.index_map_bs
    assert budget.estimate_dofs(scene.cfg) == dofs


def test_box_estimate_is_exact() -> None:
    raw = {"mesh": {"type": "box", "cells": [3, 4, 5]},
           "boundaries": {"b": {"role": "contact", "where": "z < 1e-10"}, "t": {"role": "dirichlet", "where": "z > 0.99"}},
           "model": {"type": "elasticity", "E": 1.0}, "obstacle": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}}
    scene = ct.load_scene(raw)
    assert budget.estimate_dofs(scene.cfg) == 4 * 5 * 6 * 3 == budget.mesh_dofs(scene.mesh, 1, 3)


def test_default_budget_on_a_24_gib_machine(monkeypatch) -> None:
    """1024² scalar (1.05 M DoFs) and 1 M-DoF 3D elasticity (GAMG) fit; a 3D direct solve
    (solver.linear: direct) is limited to about 0.5 M DoFs (fill-in ∝ N^{4/3})."""
    monkeypatch.setattr(budget, "physical_memory", lambda: 24 * 2**30)
    scalar = load_config(ROOT / "configs" / "signorini_square.yaml", ["mesh.cells=[1024,1024]"])
    assert budget.estimate_dofs(scalar) == 1050625 <= budget.max_dofs(scalar, 2)
    elastic = load_config(ROOT / "configs" / "hertz_3d.yaml")
    assert not budget.direct_3d(elastic, 3) and budget.max_dofs(elastic, 3) >= 1_029_000
    assert not budget.direct_3d(scalar, 3)  # solver.linear auto: CG + GAMG in 3D
    direct = load_config(ROOT / "configs" / "signorini_square.yaml", ["solver.linear=direct"])
    assert budget.direct_3d(direct, 3) and 450_000 < budget.max_dofs(direct, 3) < 550_000
    assert budget.max_dofs(scalar, 2) == int(0.5 * 24 * 2**30 / budget.BYTES_PER_DOF)
