"""The suite runs what users run: every shipped scene (configs/*.yaml) through ``contact run``
with its default outputs — every field format and every picture — serially and under
``mpirun -n 2``, on small meshes (``--set``), and every file it writes opened by a reader:
XDMF with meshio and h5py (:mod:`readback`, which checks each against the other), the .h5
files with h5py, .vtu with meshio and pyvista, the .pvd's XML and the files it lists, PNG
with matplotlib's image reader, CSV and JSON with their modules.  summary.json lists
exactly the folder's files and says every picture was written; every load path writes
force.png and the ``obstacle_approach`` column of steps.csv; every scene with a contact
boundary writes the contact-surface dataset, as one grid or as a series with the steps of
solution.xdmf.  A load path on a scalar scene (which ships none) and on an obstacle in Ω:
the same, with ``load.steps`` set.  The 2-rank run gives the
serial answer (summary.json and the contact tables, as tests/test_cli_mpi.py compares them;
that file checks 3 ranks, without pictures).

Before, the suite ran these scenes with ``output.png=false``: the frictional hyperelastic
load path (hyperelastic_drag) solved every step and then failed drawing force.png
(its contact force is a vector there), exit 3 and nothing written.
"""

from __future__ import annotations

import csv
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from clirun import ROOT, run_scene, serial_runs
from readback import read_vtu, read_xdmf, xdmf_steps
from test_cli_mpi import same, same_table

pytestmark = pytest.mark.mpi

TIMEOUT = {0: 240, 2: 300}  # seconds per run on a loaded 2-core machine
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
    "hyperelastic_block.yaml": ["data.f=[0,-0.5]"],
    "hyperelastic_cylinder.yaml": ["mesh.h=0.3", "mesh.h_contact=0.05", "load.steps=2"],
    "hyperelastic_drag.yaml": ["mesh.cells=[20,5]", "load.steps=4"],
    "hyperelastic_indentation.yaml": ["mesh.cells=[20,10]", "load.steps=2"],
    "hyperelastic_ironing_2d.yaml": ["mesh.cells=[18,8]", "load={times: [0.1, 0.2, 0.3]}"],
    "hyperelastic_sphere.yaml": ["mesh.cells=[6,6,4]", "load.steps=2"],
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


def test_every_shipped_scene_is_listed() -> None:
    assert {p.name for p in (ROOT / "configs").glob("*.yaml")} == set(SCENES)


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The serial run of each scene, made when a test first needs it."""
    return serial_runs(tmp_path_factory, _run)


def _run(tmp: Path, scene: str, ranks: int, sets: list[str] | None = None) -> Path:
    """``contact run`` of the shipped scene with its outputs (``sets``: default its
    SCENES overrides); its folder, every file read."""
    items = SCENES[scene] if sets is None else sets
    out, proc = run_scene(tmp, scene, ranks, items, TIMEOUT[ranks])
    assert "not written" not in proc.stderr, proc.stderr
    read_folder(out)
    assert (out / "contact_surface.xdmf").exists() == (scene not in IN_DOMAIN), scene
    return out


def read_folder(out: Path) -> dict:
    """Open every file of a result folder with its reader (module doc); summary.json."""
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
            _read_png(path)
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


def _read_png(path: Path) -> None:
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


@pytest.mark.slow
@pytest.mark.parametrize("scene", list(SCENES))
def test_shipped_scene_with_its_outputs(serial, scene: str) -> None:
    serial(scene)


@pytest.mark.slow
@pytest.mark.parametrize("scene", list(SCENES))
def test_shipped_scene_with_its_outputs_on_two_ranks(tmp_path: Path, serial, scene: str) -> None:
    ref = serial(scene)
    out = _run(tmp_path, scene, 2)
    names = sorted(p.name for p in ref.iterdir())
    assert sorted(p.name for p in out.iterdir()) == names
    a, b = (json.loads((d / "summary.json").read_text()) for d in (ref, out))
    assert b["mpi_ranks"] == 2
    same(a, b, "summary")
    for name in names:
        if name == "contact.csv" or name.startswith("contact_step_"):
            same_table(ref / name, out / name)


@pytest.mark.slow
@pytest.mark.parametrize("ranks", [0, 2])
@pytest.mark.parametrize("scene", list(PATHS))
def test_load_path_on_a_scene_without_one(tmp_path: Path, scene: str, ranks: int) -> None:
    """A scalar scene's load path (traction.png: its flux per step) and an obstacle in Ω's
    (no contact boundary: no traction.png, no contact surface) with the default outputs."""
    out = _run(tmp_path, scene, ranks, PATHS[scene])
    assert (out / "traction.png").exists() == (scene not in IN_DOMAIN)


def test_hyperelastic_drag_draws_its_vector_force(serial) -> None:
    """The frictional finite-strain path: force.png has the normal force −Σ w λ_n and the
    friction force |F_t| per step, whose values are steps.csv's columns."""
    out = serial("hyperelastic_drag.yaml")
    with open(out / "steps.csv", newline="") as fh:
        steps = list(csv.DictReader(fh))
    assert len(steps) == 4
    normal = [-float(s["normal_force"]) for s in steps]
    tangential = [float(s["tangential_force_x"]) for s in steps]
    assert all(f > 0 for f in normal) and any(abs(t) > 0 for t in tangential)
    _read_png(out / "force.png")
