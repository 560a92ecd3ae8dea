"""The command line under MPI (issue 26, item 2): the peers' scenes (configs/peers/*.yaml,
small meshes through ``--set``) finish with exit code 0 within their timeout serially, under
``mpirun -n 2`` and ``-n 3``, and write the serial run's answer: the same DoFs, cells and
node counts on every level, summary.json's figures and every column of contact.csv to the
solver's tolerance (tests/scene_runs.py compares them).  The frictional load paths on their
fast path (grid sequencing, GMRES) and a frictional ``contact study`` under ``mpirun -n 2``
give the serial answer.

The scenes of configs/*.yaml run serially, on 2 ranks (with their pictures, every file read
back) and on 3 ranks in tests/test_shipped_scenes*.py, against one serial run.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from clirun import ROOT, contact, run_scene, serial_runs
from scene_runs import ATOL, RTOL, TIMEOUT, same, same_run, same_table
from scene_runs import SCENES as SHIPPED

pytestmark = pytest.mark.mpi

SMALL = ["output.png=false"]
#: peer scene (relative to configs/) -> --set overrides that make it small
SCENES: dict[str, list[str]] = {
    "peers/dealii_step41.yaml": ["mesh.cells=[16,16]", *SMALL],
    "peers/petsc_ex9.yaml": SMALL,
}


def test_every_shipped_scene_is_listed() -> None:
    """Every scene of configs/ (but the studies') runs under MPI: here or in
    tests/test_shipped_scenes*.py."""
    shipped = {
        str(p.relative_to(ROOT / "configs"))
        for p in (ROOT / "configs").rglob("*.yaml")
        if "studies" not in p.parts
    }
    assert shipped == set(SCENES) | set(SHIPPED)


def _run(tmp: Path, scene: str, ranks: int, items: list[str] | None = None) -> Path:
    """``contact run`` of the scene (``items``: default its SCENES overrides); its folder."""
    sets = SCENES[scene] if items is None else items
    return run_scene(tmp, scene, ranks, sets, TIMEOUT[ranks])[0]


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The serial run of each scene, made when a test first needs it."""
    return serial_runs(tmp_path_factory, _run)


@pytest.mark.parametrize("ranks", [2, 3])
@pytest.mark.parametrize("scene", list(SCENES))
def test_scene_under_mpirun_matches_serial(tmp_path: Path, serial, scene: str, ranks: int) -> None:
    same_run(serial(scene), _run(tmp_path, scene, ranks), ranks)


#: frictional load paths on issue 29's paths: every step grid-sequenced (the later ones with
#: the previous step carried to the coarse meshes), the secant predictor from the third step,
#: the reduced block system by GMRES + GAMG
FAST_FRICTION = {
    "friction_block_2d.yaml": ["mesh.cells=[64,16]", "load=none", "load={times: [0.2, 0.4, 0.6]}"],
    "two_body_cattaneo_2d.yaml": [
        "mesh.h_contact=0.05",
        "load=none",
        "load={times: [0.5, 0.625, 0.75]}",
    ],
}


@pytest.mark.parametrize("scene", list(FAST_FRICTION))
def test_sequenced_gmres_friction_under_mpirun_matches_serial(tmp_path: Path, scene: str) -> None:
    items = [*FAST_FRICTION[scene], "solver.sequence=1", "solver.linear=gmres", *SMALL]
    ref, out = _run(tmp_path, scene, 0, items), _run(tmp_path, scene, 2, items)
    a, b = (json.loads((d / "summary.json").read_text()) for d in (ref, out))
    # the tangential force before the drag is a discretization residue (4e-7 of the normal
    # force on the Cattaneo scene): compared to RTOL of the normal force
    for sa, sb in zip(a["steps"], b["steps"]):
        scale = abs(sa["normal_force"])
        ta, tb = sa.pop("tangential_force"), sb.pop("tangential_force")
        assert all(abs(x - y) <= RTOL * scale for x, y in zip(ta, tb)), (ta, tb)
    same(a, b, "summary")
    for name in sorted(p.name for p in ref.iterdir()):
        if name == "contact.csv" or name.startswith("contact_step_"):
            same_table(ref / name, out / name)
    steps = list(csv.DictReader((ref / "steps.csv").read_text().splitlines()))
    assert len(steps) == 3


def test_frictional_study_under_mpirun_matches_serial(tmp_path: Path) -> None:
    """A study of load paths (the small friction block, two steps, two methods): its rows
    take their friction figures through the collectives of contact.post.friction_resultants."""
    study = tmp_path / "study.yaml"
    study.write_text(
        f"name: friction\nscene: {ROOT / 'configs' / 'friction_block_2d.yaml'}\n"
        "set: ['mesh.cells=[20,5]', load.steps=2, output.png=false]\n"
        "axes: {method: [min, fb]}\nwarmup: false\n"
    )
    rows = {}
    for ranks in (0, 2):
        proc = contact(
            tmp_path,
            "study",
            str(study),
            "-o",
            f"np{ranks}",
            "-q",
            ranks=ranks,
            timeout=TIMEOUT[ranks],
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        rows[ranks] = list(csv.DictReader(open(tmp_path / f"np{ranks}" / "study.csv")))
    assert [r["ranks"] for r in rows[2]] == ["2", "2"]
    for s, p in zip(rows[0], rows[2]):
        assert s["method"] == p["method"] and s["converged"] == p["converged"] == "True"
        assert s["dofs"] == p["dofs"] and s["levels"] == p["levels"] == "2"
        for key in ("friction_ratio", "stick_measure", "slip_measure", "eta", "active_measure"):
            assert math.isclose(float(s[key]), float(p[key]), rel_tol=RTOL, abs_tol=ATOL), key
