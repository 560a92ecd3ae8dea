"""The shipped scenes (configs/*.yaml) through ``contact run`` as users run them: their small
overrides, the readback of every file of a result folder, and the comparison of a run on
several ranks with the serial run (tests/test_shipped_scenes*.py, tests/test_cli_mpi.py)."""

from __future__ import annotations

import csv
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from clirun import run_scene, serial_runs
from readback import read_vtu, read_xdmf, xdmf_steps

# seconds per run on a loaded 2-core machine (3 ranks oversubscribe it)
TIMEOUT = {0: 240, 2: 300, 3: 300}
#: scene -> --set overrides that make it small (a few seconds a run); its outputs as shipped
SCENES: dict[str, list[str]] = {
    "biactive.yaml": ["mesh.cells=[8,8]"],
    "block_on_plane.yaml": ["mesh.cells=[16,4]", "adapt.max_levels=2"],
    "friction_block_2d.yaml": ["mesh.cells=[20,5]", "load.steps=2"],
    "friction_box_3d.yaml": ["mesh.cells=[6,6,3]", "load.steps=2"],
    "friction_cylinder_2d.yaml": ["mesh.cells=[40,10]", "load.steps=2"],
    "friction_tresca_manufactured.yaml": ["adapt.max_levels=2"],
    "hertz_2d.yaml": ["mesh.h=0.3", "mesh.h_contact=0.05", "adapt.max_levels=2"],
    "hertz_3d.yaml": ["mesh.h=0.5", "mesh.h_contact=0.1", "adapt=none"],
    # a body load: the estimator of the exactly represented homogeneous state is round-off
    "hyperelastic_block.yaml": ["data.f=[0,-0.5]"],
    "hyperelastic_cylinder.yaml": ["mesh.h=0.3", "mesh.h_contact=0.05", "load.steps=2"],
    "hyperelastic_drag.yaml": ["mesh.cells=[20,5]", "load.steps=4"],
    "hyperelastic_indentation.yaml": ["mesh.cells=[20,10]", "load.steps=2"],
    "hyperelastic_ironing_2d.yaml": ["mesh.cells=[18,8]", "load={times: [0.1, 0.2, 0.3]}"],
    "hyperelastic_sphere.yaml": ["mesh.cells=[6,6,4]", "load.steps=2"],
    # buckles in the second step (its tangent turns indefinite at t ≈ 1.15 on 40 × 2 cells)
    "hyperelastic_strip.yaml": ["mesh.cells=[40,2]", "load.times=[1.1,1.25]"],
    "hyperelastic_two_body_drag_2d.yaml": ["load={times: [0.2, 0.3]}"],
    "hyperelastic_two_body_drag_3d.yaml": ["load={times: [0.2, 0.4]}"],
    "hyperelastic_two_body_patch_2d.yaml": [],
    "hyperelastic_self_contact_ring.yaml": ["mesh.cells=[64,2]", "load.steps=2"],
    "hyperelastic_self_contact_tube.yaml": ["mesh.cells=[2,24,4]", "load.steps=2"],
    "hyperelastic_self_contact_kink.yaml": [
        "mesh.cells=[2,12,4]",
        "load.steps=2",
        "constants.p=0.6",
    ],
    "indentation_2d.yaml": ["mesh.cells=[20,10]"],
    "lshape_corner.yaml": ["adapt.max_levels=2"],
    "obstacle_membrane.yaml": ["mesh.cells=[8,8]"],
    "obtuse_square.yaml": ["mesh.cells=[8,8]"],
    "semicoercive.yaml": ["mesh.cells=[8,8]"],
    "signorini_free_boundary.yaml": ["adapt.max_levels=2"],
    "signorini_smooth.yaml": ["adapt.max_levels=2"],
    "signorini_square.yaml": ["mesh.cells=[8,8]"],
    "two_body_cattaneo_2d.yaml": ["mesh.h_contact=0.05", "load.times=[0.5,0.875]"],
    # a body load: the estimator of the exactly represented sliding state is round-off
    "two_body_friction_patch_3d.yaml": ["data.f=[0,0,-0.01]"],
    "two_body_hertz_2d.yaml": ["mesh.h_contact=0.2", "adapt.max_levels=2"],
    "two_body_hertz_3d.yaml": ["mesh.h=0.5", "mesh.h_contact=0.1", "adapt=none"],
    "two_body_patch_2d.yaml": [],
    "two_body_patch_3d.yaml": [],
    "two_body_stack_2d.yaml": [],
}
#: scenes whose constraint lives in Ω: no contact boundary, no contact_surface.xdmf
IN_DOMAIN = {"obstacle_membrane.yaml"}
#: load paths on scenes that ship none (scene -> its overrides, load.steps added)
PATHS: dict[str, list[str]] = {
    "signorini_square.yaml": ["mesh.cells=[4,4]", "load.steps=3"],
    "obstacle_membrane.yaml": ["mesh.cells=[8,8]", "load.steps=2"],
}
NAMES = ("solution", "contact_surface")  # the field datasets of one result
PNG = b"\x89PNG\r\n\x1a\n"
#: scenes whose 3-rank run draws its pictures: their data pass through collectives of their
#: own (the 2D frictional load paths: traction.png with the first point of contact and a
#: reference curve, pressure.png, solution.png); the other 3-rank runs write everything else
#: (VTK files, CSV, JSON), gathered the same way — pictures are most of a small run's time
PICTURES_ON_THREE_RANKS = {"friction_block_2d.yaml", "two_body_cattaneo_2d.yaml"}

#: summary.json keys that are not the answer: timings, the machine, the path a solver took
#: (iteration counts, residuals and reasons may differ with the rank count), file lists
VOLATILE = {
    "time_total",
    "time_assembly",
    "time_linear_solve",
    "time_other",
    "time_sequence",
    "seconds",
    "seconds_to_error",
    "seconds_to_solution",
    "host",
    "mpi_ranks",
    "newton_iterations",
    "newton_iterations_total",
    "newton_iterations_max_per_step",
    "newton_iterations_per_level",
    "polish_solves",
    "polish_solves_total",
    "polish_solves_per_level",
    "linear_solves",
    "weighted_linear_solves",
    "krylov_iterations",
    "final_residual",
    "reason",
    "sequence",
    "sequence_note",
    "fixed_point_iterations",
    "linear_solver",
    "newton_iterations_coarse",
    "polish_solves_coarse",
    "backtracked_steps",
    # the energy search's path (contact/solvers/energy_search.py): what it did per step
    "indefinite_newton_steps",
    "largest_shift",
    "curvature_steps",
    "shortened_steps",
    "tangent_events",
    "krylov_iterations_total",
    "krylov_iterations_per_level",
    "eta_lin_per_level",
    "eta_alg_per_level",
}
#: keys whose values are sizes: equal exactly
EXACT = {
    "dofs",
    "cells",
    "levels",
    "dofs_per_level",
    "constrained_nodes",
    "steps_total",
    "step",
    "degree",
    "converged",
    "symmetric_copies",
}
# relative, of a figure or of a column's largest magnitude (the solver stops at |Phi| ~ 1e-12)
RTOL = 1e-6
# absolute, for figures that vanish up to round-off (the scenes' forces are 1e-3 or more)
ATOL = 1e-12


def _answer_keys(summary: dict) -> set[str]:
    """The keys of a summary that hold the answer: not VOLATILE, not a timing (time_*)."""
    return {k for k in summary if k not in VOLATILE and not k.startswith("time_")}


def same(a, b, where: str) -> None:
    """JSON values a (serial) and b (parallel) agree: sizes exactly, figures to RTOL."""
    key = where.rsplit(".", 1)[-1].split("[")[0]
    if isinstance(a, dict):
        assert isinstance(b, dict), where
        keys, other = _answer_keys(a), _answer_keys(b)
        assert keys == other, f"{where}: {sorted(keys ^ other)}"
        for k in sorted(keys):
            same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), where
        if a and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in a + b):
            scale = max(abs(v) for v in a + b)  # a vector: to RTOL of its largest component
            for i, (x, y) in enumerate(zip(a, b)):
                assert (x == y) if key in EXACT else abs(x - y) <= RTOL * scale + ATOL, (
                    f"{where}[{i}]: {x} != {y}"
                )
        else:
            for i, (x, y) in enumerate(zip(a, b)):
                same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) or isinstance(b, float):
        # relative errors may be a balance of round-off (force_balance_error ~ 1e-15)
        atol = 1e-8 if key.endswith("_error") else ATOL
        assert (a == b) if key in EXACT else math.isclose(a, b, rel_tol=RTOL, abs_tol=atol), (
            f"{where}: {a} != {b}"
        )
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def _table(path: Path) -> tuple[list[str], list[list[str]]]:
    """contact.csv's header and rows sorted by coordinates (rows of equal r or s may come in
    rank order)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    axes = [header.index(c) for c in "xyz" if c in header]
    return header, sorted(body, key=lambda r: [round(float(r[i]), 10) for i in axes])


def same_table(a: Path, b: Path) -> None:
    """Every column of two contact tables agrees to RTOL of its unit's scale: lengths (the
    coordinates, s, r, gap, slip) of the largest coordinate, tractions (λ, λ_n, λ_t, the
    bound) of the largest |λ_n| or |λ| — columns of round-off zeros (y on a plane y = 0, λ_t
    without friction) are no scale of their own —, θ weighted by r (θ ∈ (−π, π] is the same
    number on any number of ranks: a point on the axis θ = π is never −π); ATOL absolute
    (biactive.yaml's λ is 0 up to round-off)."""
    ha, ra = _table(a)
    hb, rb = _table(b)
    assert ha == hb and len(ra) == len(rb), f"{a.name}: {len(ra)} rows against {len(rb)}"
    if not ra:  # a step with no constrained node (a self-contact pair not yet facing itself)
        return
    cols = {name: ([r[j] for r in ra], [r[j] for r in rb]) for j, name in enumerate(ha)}
    num = {
        name: ([float(v) for v in x], [float(v) for v in y])
        for name, (x, y) in cols.items()
        if name != "status"
    }
    biggest = lambda names: max(abs(v) for n in names if n in num for v in num[n][0] + num[n][1])  # noqa: E731
    length = biggest("xyz")
    traction = biggest(("lambda_n", "lambda"))
    for name, (va, vb) in num.items():
        if name == "theta":
            continue
        scale = (
            length
            if name in ("x", "y", "z", "s", "r", "gap") or name.startswith("slip")
            else traction
            if name.startswith("lambda") or name == "bound"
            else biggest([name])
        )
        worst = max((abs(x - y) for x, y in zip(va, vb)), default=0.0)
        assert worst <= RTOL * scale + ATOL, (
            f"{a.name}: column {name} differs by {worst:.2e} (scale {scale:.2e})"
        )
    if "theta" in num:
        r, (va, vb) = num["r"][0], num["theta"]
        assert all(ri * abs(x - y) <= RTOL * length for ri, x, y in zip(r, va, vb)), (
            f"{a.name}: column theta"
        )
    if "status" in cols:
        assert cols["status"][0] == cols["status"][1], f"{a.name}: column status"


def run(
    tmp: Path, scene: str, ranks: int, sets: list[str] | None = None, pictures: bool = True
) -> Path:
    """``contact run`` of the shipped scene (``sets``: default its SCENES overrides) serially
    (``ranks`` 0) or under ``mpirun -n ranks``: with its outputs as shipped, every file read
    back (:func:`read_folder`), or without pictures (``output.png=false``); its folder."""
    items = SCENES[scene] if sets is None else sets
    if not pictures:
        items = [*items, "output.png=false"]
    out, proc = run_scene(tmp, scene, ranks, items, TIMEOUT[ranks])
    if pictures:
        assert "not written" not in proc.stderr, proc.stderr
        read_folder(out)
        assert (out / "contact_surface.xdmf").exists() == (scene not in IN_DOMAIN), scene
    return out


def same_run(ref: Path, out: Path, ranks: int) -> None:
    """The run ``out`` on ``ranks`` ranks gives the serial run ``ref``'s answer: the same
    files (those of ``ref`` but its pictures when ``out`` drew none), summary.json's answer
    (:func:`same`) and every contact table (:func:`same_table`)."""
    drawn = any(p.suffix == ".png" for p in out.iterdir())
    names = sorted(p.name for p in ref.iterdir() if drawn or p.suffix != ".png")
    assert sorted(p.name for p in out.iterdir()) == names
    a, b = (json.loads((d / "summary.json").read_text()) for d in (ref, out))
    assert b["mpi_ranks"] == ranks
    if not drawn:  # which pictures the serial run drew is no part of the answer
        a = {k: v for k, v in a.items() if k != "pictures"}
        a["files"] = [n for n in a["files"] if not n.endswith(".png")]
    same(a, b, "summary")
    for name in names:
        if name == "contact.csv" or name.startswith("contact_step_"):
            same_table(ref / name, out / name)


def read_folder(out: Path) -> dict:
    """Open every file of a result folder with its reader: XDMF with meshio and h5py
    (:mod:`readback`, which checks each against the other), the .h5 files with h5py, .vtu
    with meshio and pyvista, the .pvd's XML and the files it lists, PNG with matplotlib's
    image reader, CSV and JSON with their modules; summary.json (which must list exactly the
    folder's files and say every picture was written)."""
    summary = json.loads((out / "summary.json").read_text())
    names = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert sorted(summary["files"]) == names
    assert json.loads((out / ".contact-result").read_text())["tool"] == "contact"
    for name in names:
        path = out / name
        suffix = path.suffix
        if suffix == ".xdmf":
            steps = read_xdmf(path)
            assert steps and all(len(s["points"]) and len(s["cells"]) for s in steps), name
        elif suffix == ".h5":  # a pair facing no master: the gap is undefined (summary note)
            _read_h5(path, "unfaced_note" in summary)
        elif suffix == ".vtu":
            grid = read_vtu(path)
            assert grid.n_points > 0 and grid.n_cells > 0, name
        elif suffix == ".pvd":
            _read_pvd(path)
        elif suffix == ".png":
            read_png(path)
        elif suffix == ".csv":
            _read_csv(path)
        elif suffix == ".json":
            json.loads(path.read_text())
        else:
            raise AssertionError(f"{name}: a file no reader is known for")
    pictures = summary.get("pictures", {})
    assert pictures and set(pictures.values()) == {"written"}, pictures
    assert set(pictures) == {n for n in names if n.endswith(".png")}
    if "contact_surface.xdmf" in names:  # the same grids as solution.xdmf: one, or a series
        times = [[s["time"] for s in xdmf_steps(out / f"{n}.xdmf")] for n in NAMES]
        assert times[1] == times[0], times
    if "steps" in summary:  # a load path: its force–displacement curve
        assert "force.png" in names
        if "solution.xdmf" in names:
            assert len(xdmf_steps(out / "solution.xdmf")) == len(summary["steps"])
        with open(out / "steps.csv", newline="") as fh:
            header = next(csv.reader(fh))
        assert {"obstacle_approach", "prescribed_displacement"} <= set(header)
    return summary


def _read_h5(path: Path, unfaced: bool = False) -> None:
    """Every dataset of an HDF5 file; NaN marks "not defined here" (the gap off Γ_C): every
    float dataset has a number, but for the gap of a run whose pairs faced no master
    (``unfaced``: summary.json's ``unfaced_note``), undefined at every node."""
    import h5py

    arrays = {}
    with h5py.File(path, "r") as f:
        f.visititems(
            lambda name, obj: (
                arrays.update({name: obj[()]}) if isinstance(obj, h5py.Dataset) else None
            )
        )
    undefined = {n for n in arrays if unfaced and n.startswith("Function/gap/")}
    assert arrays and all(
        np.isfinite(a).any()
        for n, a in arrays.items()
        if a.dtype.kind == "f" and n not in undefined
    ), path


def _read_pvd(path: Path) -> None:
    root = ET.parse(path).getroot()
    assert root.get("type") == "Collection"
    rows = root.findall("Collection/DataSet")
    times = [float(r.get("timestep")) for r in rows]
    assert rows and times == sorted(times), path
    assert all((path.parent / r.get("file")).is_file() for r in rows)


def read_png(path: Path) -> None:
    import matplotlib.image

    assert path.read_bytes()[:8] == PNG, path
    image = matplotlib.image.imread(path)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100, path
    assert np.ptp(image[..., :3]) > 0, f"{path.name}: one colour"


def _read_csv(path: Path) -> None:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows and rows[0], path
    assert all(len(row) == len(rows[0]) for row in rows[1:]), path


def scene_tests(scenes: list[str]) -> tuple:
    """The tests of the shipped scenes ``scenes`` for a test module to bind to its names
    (tests/test_shipped_scenes*.py: two files, one for each of pytest-xdist's workers):
    the module fixture ``serial`` (the serial run of a scene with every output, made when a
    test first needs it, the reference of the parallel runs), the serial run's test, the run
    on 2 ranks with every output and on 3 ranks without pictures (but
    :data:`PICTURES_ON_THREE_RANKS`'), each giving the serial answer (:func:`same_run`)."""

    @pytest.fixture(scope="module")
    def serial(tmp_path_factory):
        return serial_runs(tmp_path_factory, run)

    @pytest.mark.slow
    @pytest.mark.parametrize("scene", scenes)
    def with_its_outputs(serial, scene: str) -> None:
        serial(scene)

    @pytest.mark.slow
    @pytest.mark.parametrize("scene", scenes)
    def on_two_ranks(tmp_path: Path, serial, scene: str) -> None:
        same_run(serial(scene), run(tmp_path, scene, 2), 2)

    @pytest.mark.parametrize("scene", scenes)
    def on_three_ranks(tmp_path: Path, serial, scene: str) -> None:
        out = run(tmp_path, scene, 3, pictures=scene in PICTURES_ON_THREE_RANKS)
        same_run(serial(scene), out, 3)

    return serial, with_its_outputs, on_two_ranks, on_three_ranks
