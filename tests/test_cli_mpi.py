"""The command line under MPI (issue 26, item 2): ``contact run`` of every shipped scene in
configs/ (small meshes through ``--set``, one or two load steps, two adaptive levels) finishes
with exit code 0 within its timeout serially, under ``mpirun -n 2`` and ``-n 3``, and writes
the serial run's answer: the same DoFs, cells and node counts on every level and step,
summary.json's figures and every column of contact.csv (the r/θ columns of 3D scenes
included) to the solver's tolerance.  A frictional ``contact study`` under ``mpirun -n 2``
gives the serial study.csv.

Pictures are drawn where their data pass through collectives of their own (the 2D
frictional load paths friction_block_2d and two_body_cattaneo_2d: traction.png with the
first point of contact and a reference curve, pressure.png, solution.png); the other scenes
write everything else (VTK files, CSV, JSON), which is gathered the same way — pictures
are most of a small run's time.  Before issue 26 the frictional scenes
hung under MPI after their first step (a collective entered on ranks 1… only).

The scenes of configs/ run here on 3 ranks: their serial and 2-rank runs with every
output, pictures included, every file read back, are tests/test_shipped_scenes.py's.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from clirun import ROOT, contact, run_scene, serial_runs

pytestmark = pytest.mark.mpi

# seconds per run (a loaded 2-core machine; 3 ranks oversubscribe it)
TIMEOUT = {0: 180, 2: 240, 3: 300}
SMALL = ["output.png=false"]
#: scene (relative to configs/) -> --set overrides that make it small
SCENES: dict[str, list[str]] = {
    "biactive.yaml": ["mesh.cells=[8,8]", *SMALL],
    "block_on_plane.yaml": ["mesh.cells=[16,4]", "adapt.max_levels=2", *SMALL],
    "friction_block_2d.yaml": ["mesh.cells=[20,5]", "load.steps=2"],
    "friction_box_3d.yaml": ["mesh.cells=[6,6,3]", "load.steps=2", *SMALL],
    "friction_cylinder_2d.yaml": ["mesh.cells=[40,10]", "load.steps=2", *SMALL],
    "friction_tresca_manufactured.yaml": ["adapt.max_levels=2", *SMALL],
    "hertz_2d.yaml": ["mesh.h=0.3", "mesh.h_contact=0.05", "adapt.max_levels=2", *SMALL],
    "hertz_3d.yaml": ["mesh.h=0.5", "mesh.h_contact=0.1", "adapt=none", *SMALL],
    # a body load: the estimator of the exactly represented homogeneous state is round-off
    "hyperelastic_block.yaml": ["data.f=[0,-0.5]", *SMALL],
    "hyperelastic_cylinder.yaml": ["mesh.h=0.3", "mesh.h_contact=0.05", "load.steps=2", *SMALL],
    "hyperelastic_drag.yaml": ["mesh.cells=[20,5]", "load.steps=4", *SMALL],
    "hyperelastic_indentation.yaml": ["mesh.cells=[20,10]", "load.steps=2", *SMALL],
    "hyperelastic_ironing_2d.yaml": ["mesh.cells=[18,8]", "load={times: [0.1, 0.2, 0.3]}", *SMALL],
    "hyperelastic_sphere.yaml": ["mesh.cells=[6,6,4]", "load.steps=2", *SMALL],
    # buckles in the second step (its tangent turns indefinite at t ≈ 1.15 on 40 × 2 cells)
    "hyperelastic_strip.yaml": ["mesh.cells=[40,2]", "load.times=[1.1,1.25]", *SMALL],
    "hyperelastic_self_contact_ring.yaml": ["mesh.cells=[64,2]", "load.steps=2", *SMALL],
    "hyperelastic_two_body_drag_2d.yaml": ["load={times: [0.2, 0.3]}", *SMALL],
    "hyperelastic_two_body_drag_3d.yaml": ["load={times: [0.2, 0.4]}", *SMALL],
    "hyperelastic_self_contact_tube.yaml": ["mesh.cells=[2,24,4]", "load.steps=2", *SMALL],
    "hyperelastic_self_contact_kink.yaml": [
        "mesh.cells=[2,12,4]",
        "load.steps=2",
        "constants.p=0.6",
        *SMALL,
    ],
    "hyperelastic_two_body_patch_2d.yaml": SMALL,
    "indentation_2d.yaml": ["mesh.cells=[20,10]", *SMALL],
    "lshape_corner.yaml": ["adapt.max_levels=2", *SMALL],
    "obstacle_membrane.yaml": ["mesh.cells=[8,8]", *SMALL],
    "obtuse_square.yaml": ["mesh.cells=[8,8]", *SMALL],
    "semicoercive.yaml": ["mesh.cells=[8,8]", *SMALL],
    "signorini_free_boundary.yaml": ["adapt.max_levels=2", *SMALL],
    "signorini_smooth.yaml": ["adapt.max_levels=2", *SMALL],
    "signorini_square.yaml": ["mesh.cells=[8,8]", *SMALL],
    "two_body_cattaneo_2d.yaml": ["mesh.h_contact=0.05", "load.times=[0.5,0.875]"],
    # a body load: the estimator of the exactly represented sliding state is round-off
    "two_body_friction_patch_3d.yaml": ["data.f=[0,0,-0.01]", *SMALL],
    "two_body_hertz_2d.yaml": ["mesh.h_contact=0.2", "adapt.max_levels=2", *SMALL],
    "two_body_hertz_3d.yaml": ["mesh.h=0.5", "mesh.h_contact=0.1", "adapt=none", *SMALL],
    "two_body_patch_2d.yaml": SMALL,
    "two_body_patch_3d.yaml": SMALL,
    "two_body_stack_2d.yaml": SMALL,
    "peers/dealii_step41.yaml": ["mesh.cells=[16,16]", *SMALL],
    "peers/petsc_ex9.yaml": SMALL,
}

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


def test_every_shipped_scene_is_listed() -> None:
    shipped = {
        str(p.relative_to(ROOT / "configs"))
        for p in (ROOT / "configs").rglob("*.yaml")
        if "studies" not in p.parts
    }
    assert shipped == set(SCENES)


def _run(tmp: Path, scene: str, ranks: int, items: list[str] | None = None) -> Path:
    """``contact run`` of the scene (``items``: default its SCENES overrides); its folder."""
    sets = SCENES[scene] if items is None else items
    return run_scene(tmp, scene, ranks, sets, TIMEOUT[ranks])[0]


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The serial run of each scene, made when a test first needs it."""
    return serial_runs(tmp_path_factory, _run)


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


#: (scene, ranks): the peers' scenes on 2 and 3 ranks, configs/*.yaml on 3 (their 2-rank
#: runs, with pictures: tests/test_shipped_scenes.py)
RUNS = [(s, r) for s in SCENES for r in ((2, 3) if s.startswith("peers/") else (3,))]


@pytest.mark.parametrize("scene, ranks", RUNS)
def test_scene_under_mpirun_matches_serial(tmp_path: Path, serial, scene: str, ranks: int) -> None:
    ref = serial(scene)
    out = _run(tmp_path, scene, ranks)
    names = sorted(p.name for p in ref.iterdir())
    assert sorted(p.name for p in out.iterdir()) == names
    a, b = (json.loads((d / "summary.json").read_text()) for d in (ref, out))
    assert b["mpi_ranks"] == ranks
    same(a, b, "summary")
    for name in names:
        if name == "contact.csv" or name.startswith("contact_step_"):
            same_table(ref / name, out / name)


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
