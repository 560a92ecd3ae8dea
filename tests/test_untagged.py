"""No silent change of the problem posed: the exterior facets in no boundary part (which carry
the natural condition) are reported on every run and in summary.json, the same on 1 and 2
ranks; a declared exact solution is checked against the scene's boundary conditions."""

import csv
import json
import re
import warnings
from pathlib import Path

import contact
from contact.setup.exact_data import exact_mismatches
from contact.setup.meshes import NATURAL
from contact.setup.untagged import untagged_boundary

import meshio
import numpy as np
import pytest
import yaml
from clirun import ROOT, script_json
from clirun import contact as run_cli
from conftest import make_square_msh


def readme_scene() -> dict:
    """The scene example of docs/guide/scenes.md ("Every key"), as printed."""
    section = (ROOT / "docs" / "guide" / "scenes.md").read_text().split("## Every key", 1)[1]
    return yaml.safe_load(re.search(r"```yaml\n(.*?)```", section, re.S).group(1))


def corner_gap(scene: dict) -> dict:
    """``scene`` with the Scene files example's former Dirichlet predicate ``y > 1e-10``:
    the side facets touching the bottom corners are in no part (one vertex at y = 0)."""
    scene["boundaries"]["rest"]["where"] = "y > 1e-10"
    return scene


def report(scene):
    u = untagged_boundary(scene.mesh, scene.boundary)
    return u, u.line(scene.config.elastic)


def test_where_selects_facets_all_of_whose_vertices_satisfy_it():
    """The example's former predicate leaves the two side facets at the bottom corners out:
    2 facets of length h = 1/8 (cells [16, 8] on (-1, 1) × (0, 1)), next to both parts."""
    u, line = report(contact.load_scene(corner_gap(readme_scene())))
    assert (u.facets, u.measure) == (2, pytest.approx(0.25, rel=1e-14))
    assert u.lower == (-1.0, 0.0) and u.upper == (1.0, pytest.approx(0.125, rel=1e-14))
    assert u.next_to == ("floor", "rest")
    assert line.startswith("boundary: 2 exterior facet(s) (length 0.25) in no part carry the ")
    assert "x ∈ [-1, 1], y ∈ [0, 0.125], next to floor, rest" in line and len(line) <= 290


def test_fully_tagged_scenes_report_none():
    """The Scene files example as printed, a 3D gmsh builder and a scene whose parts cover every
    side report no untagged facet."""
    for source, sets in (
        (readme_scene(), []),
        (ROOT / "configs" / "signorini_free_boundary.yaml", []),
        (ROOT / "configs" / "hertz_3d.yaml", ["mesh.h=0.3", "mesh.h_contact=0.1"]),
    ):
        u, line = report(contact.load_scene(source, sets))
        assert (u.facets, u.measure, u.lower, u.next_to) == (0, 0.0, None, ())
        assert line == "boundary: every exterior facet is in a boundary part"
        assert u.as_dict() == {"facets": 0, "measure": 0.0, "where": None, "next_to": []}


def test_natural_role_declares_the_facets():
    """A part with role natural is the scene's choice, not an untagged facet; the estimator
    and the forms see it as a zero-flux part (the same tags as the undeclared facets)."""
    scene = corner_gap(readme_scene())
    scene["boundaries"]["corners"] = {"role": "natural", "where": "abs(x) > 1 - 1e-10 and y < 0.2"}
    declared = contact.load_scene(scene)
    undeclared = contact.load_scene(corner_gap(readme_scene()))
    assert report(declared)[0].facets == 0
    assert declared.boundary.roles["corners"] == "natural" and NATURAL not in declared.boundary.ids
    assert np.array_equal(
        declared.boundary.facets("natural"), undeclared.boundary.facets("natural")
    )


def test_gmsh_file_reports_its_untagged_group(tmp_path):
    """A gmsh mesh whose side group 3 no part names: exactly the facets of that group,
    total length 2, on the lines x = 0 and x = 1."""
    path = make_square_msh(tmp_path / "square.msh", size=0.15)
    lines = meshio.read(path).cell_data_dict["gmsh:physical"]["line"]
    scene = contact.load_scene(
        {
            "name": "gmsh_square",
            "mesh": {"type": "gmsh", "file": str(path)},
            "boundaries": {
                "top": {"role": "dirichlet", "tag": 2},
                "bottom": {"role": "contact", "tag": 1},
            },
            "model": "signorini",
            "data": {"f": "1", "g": "0.1"},
        }
    )
    u, _ = report(scene)
    assert u.facets == int(np.sum(lines == 3)) > 4
    assert u.measure == pytest.approx(2.0, rel=1e-12)
    assert u.lower == (0.0, 0.0) and u.upper == (1.0, 1.0) and u.next_to == ("top", "bottom")


UNTAGGED = """
import json, sys
import contact
from contact.setup.untagged import untagged_boundary
scene = contact.load_scene(sys.argv[1], sys.argv[2:])
u = untagged_boundary(scene.mesh, scene.boundary)
if scene.comm.rank == 0:
    print(json.dumps(u.as_dict()))
"""


@pytest.mark.parametrize(
    "config, sets, facets, measure",
    [
        ("two_body_patch_2d.yaml", [], 20, 1.0),  # x = 1 of both blocks (5 + 15 cells)
        ("block_on_plane.yaml", [], 16, 1.0),
        ("two_body_hertz_3d.yaml", ["mesh.h=0.4", "mesh.h_contact=0.1"], None, None),
    ],
)
def test_untagged_report_is_rank_independent(tmp_path, config, sets, facets, measure):
    """Two bodies (2D blocks, 3D gmsh builder) and one elastic body: the same count,
    measure, box and neighbours on 1 and 2 ranks (owned facets counted once)."""
    path = str(ROOT / "configs" / config)
    serial = script_json(UNTAGGED, tmp_path, path, *sets, ranks=1)
    parallel = script_json(UNTAGGED, tmp_path, path, *sets, ranks=2)
    assert serial["facets"] == parallel["facets"] > 0
    assert parallel["measure"] == pytest.approx(serial["measure"], rel=1e-12)
    assert parallel["where"] == serial["where"] and parallel["next_to"] == serial["next_to"]
    if facets is not None:
        assert serial["facets"] == facets and serial["measure"] == pytest.approx(measure)


@pytest.mark.parametrize("ranks", [0, 2])
def test_cli_reports_the_readme_corner_gap(tmp_path, ranks):
    """The Scene files example with its former predicate through the CLI, serially and on 2
    ranks: the one line docs/guide/boundaries.md quotes on stdout, the count and measure in
    summary.json, and one warning that the exact solution's flux is not 0 on those facets."""
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(corner_gap(readme_scene())))
    proc = run_cli(
        tmp_path,
        "run",
        "scene.yaml",
        "-o",
        "out",
        "--set",
        "adapt=none",
        "--set",
        "output.png=false",
        ranks=ranks,
        env={"PYTHONWARNINGS": "default"},
    )
    assert proc.returncode == 0, proc.stderr
    quoted = re.search(
        r"line, e\.g\. `(contact: boundary: .*?) \(…\)`",
        (ROOT / "docs" / "guide" / "boundaries.md").read_text().replace("\n", " "),
    ).group(1)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("contact: boundary:")]
    assert len(lines) == 1 and lines[0].startswith(quoted), lines
    info = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert info["untagged_boundary"] == {
        "facets": 2,
        "measure": pytest.approx(0.25, rel=1e-14),
        "where": {"lower": [-1.0, 0.0], "upper": [1.0, pytest.approx(0.125, rel=1e-14)]},
        "next_to": ["floor", "rest"],
    }
    [mismatch] = info["exact_mismatch"]
    assert mismatch["part"] == NATURAL and mismatch["role"] == "natural"
    assert mismatch["difference"] > 10 * mismatch["tolerance"]
    warnings = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(warnings) == 1 and len(warnings[0]) <= 300, warnings
    assert warnings[0].startswith("contact: warning: data.exact: k ∂u/∂n ≠ 0 on the exterior")


def _elastic(**data) -> dict:
    """A 2D elastic block on a plane, symmetric about x = 0, with a Dirichlet top and a
    Neumann side: u = (a x, −a y) is a uniform strain state, σ(u) n = (2μa, 0) on x = 1."""
    return {
        "name": "uniform_strain",
        "mesh": {"type": "rectangle", "corners": [[0, 0], [1, 1]], "cells": [4, 4]},
        "boundaries": {
            "floor": {"role": "contact", "where": "y < 1e-10"},
            "top": {"role": "dirichlet", "where": "y > 1 - 1e-10"},
            "axis": {"role": "symmetry", "where": "x < 1e-10"},
            "side": {"role": "neumann", "where": "x > 1 - 1e-10"},
        },
        "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
        "obstacle": {"type": "plane", "point": [0, 0], "normal": [0, 1]},
        "constants": {"a": 0.1, "mu": 1 / 2.6},
        "data": {"u_D": ["a*x", "-a*y"], "t": ["2*mu*a", "0"], "exact": ["a*x", "-a*y"], **data},
    }


MISMATCH_CASES = {
    # (scene, overrides): the parts flagged
    "signorini right": (ROOT / "configs" / "biactive.yaml", [], {}),
    "signorini dirichlet": (
        ROOT / "configs" / "biactive.yaml",
        ["data.exact=y**2 + 0.1*x"],
        {"top": "dirichlet", NATURAL: "natural"},
    ),
    "signorini P2 right": (ROOT / "configs" / "signorini_smooth.yaml", ["mesh.degree=2"], {}),
    "obstacle right": (ROOT / "configs" / "peers" / "petsc_ex9.yaml", [], {}),
    "obstacle dirichlet": (
        ROOT / "configs" / "peers" / "petsc_ex9.yaml",
        ["data.u_D=0"],
        {"outer": "dirichlet"},
    ),
    "elastic right": (_elastic(), [], {}),
    "elastic wrong": (
        _elastic(exact=["a*x + 0.01", "-a*y"]),
        [],
        {"top": "dirichlet", "axis": "symmetry"},
    ),
    "elastic traction": (_elastic(t=["0", "0"]), [], {"side": "neumann"}),
    "tresca right": (ROOT / "configs" / "friction_tresca_manufactured.yaml", [], {}),
    "tresca dirichlet": (
        ROOT / "configs" / "friction_tresca_manufactured.yaml",
        ["data.u_D=[0, 0]"],
        {"top": "dirichlet"},
    ),
}


@pytest.mark.parametrize("case", list(MISMATCH_CASES))
def test_exact_solution_checked_against_the_conditions(case):
    """Right exact solutions (manufactured, P1 and P2, scalar and elastic, singular and
    smooth) raise nothing; each wrong one is flagged on exactly the parts it misses, with
    a one-line message naming the part."""
    source, sets, flagged = MISMATCH_CASES[case]
    scene = contact.load_scene(source, sets)
    found = exact_mismatches(scene)
    assert {m.part: m.role for m in found} == flagged
    for m in found:
        line = m.line(scene.config.elastic)
        assert len(line) <= 280 and "\n" not in line
        assert (f"boundaries.{m.part}" if m.part != NATURAL else "in no part") in line


def test_no_exact_solution_no_check():
    assert exact_mismatches(contact.load_scene(ROOT / "configs" / "signorini_square.yaml")) is None


MISMATCH = """
import json, sys
import contact
from contact.setup.exact_data import exact_mismatches
scene = contact.load_scene(sys.argv[1], sys.argv[2:])
found = exact_mismatches(scene)
if scene.comm.rank == 0:
    print(json.dumps([m.as_dict() for m in found]))
"""


def test_exact_mismatch_is_rank_independent(tmp_path):
    path = str(ROOT / "configs" / "friction_tresca_manufactured.yaml")
    sets = ["data.u_D=[0, 0]", "data.t=[0, 0]"]
    serial = script_json(MISMATCH, tmp_path, path, *sets, ranks=1)
    parallel = script_json(MISMATCH, tmp_path, path, *sets, ranks=2)
    assert [m["part"] for m in serial] == [m["part"] for m in parallel] == ["top", "sides"]
    for a, b in zip(serial, parallel):
        assert b["difference"] == pytest.approx(a["difference"], rel=1e-10)
        assert b["tolerance"] == pytest.approx(a["tolerance"], rel=1e-10)


def test_load_path_summary_reports_the_boundary(tmp_path: Path):
    """A frictional scene runs as a load path (its own summary writer): the untagged
    boundary and the exact solution's check are in its summary.json too."""
    proc = run_cli(
        tmp_path,
        "run",
        str(ROOT / "configs" / "friction_tresca_manufactured.yaml"),
        "-o",
        "out",
        "-q",
        "--set",
        "adapt=none",
        "--set",
        "mesh.cells=[4, 4]",
        "--set",
        "output.png=false",
        env={"PYTHONWARNINGS": "default"},
    )
    assert proc.returncode == 0, proc.stderr
    assert "contact: boundary: every exterior facet is in a boundary part" in proc.stdout
    info = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert info["untagged_boundary"]["facets"] == 0 and info["exact_mismatch"] == []
    assert not [ln for ln in proc.stderr.splitlines() if "data.exact" in ln]


@pytest.mark.parametrize("ranks", [0, 2])
def test_study_reports_the_boundary_once_per_mesh(tmp_path: Path, ranks):
    """``contact study`` over the Scene files example with its former predicate (case gap)
    and as printed (case tagged), two methods and two uniform refinements: the line of
    ``contact run`` once per mesh the runs start from (four meshes, eight runs), each just
    before the first run on it, and study.csv's ``untagged_facets`` (refinement keeps the
    parts: the halves of the two corner facets are untagged, the same length; none when
    every facet is tagged)."""
    (tmp_path / "gap.yaml").write_text(yaml.safe_dump(corner_gap(readme_scene())))
    (tmp_path / "tagged.yaml").write_text(yaml.safe_dump(readme_scene()))
    study = {
        "name": "posed",
        "scene": "gap.yaml",
        "set": ["adapt=none"],
        "axes": {"method": ["fb", "min"], "level": [0, 1]},
        "cases": {"gap": {}, "tagged": {"scene": "tagged.yaml", "set": ["adapt=none"]}},
        "charts": [],
        "warmup": False,
    }
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    proc = run_cli(tmp_path, "study", "study.yaml", "-o", "out", ranks=ranks)
    assert proc.returncode == 0, proc.stderr + proc.stdout
    lines = proc.stdout.splitlines()
    said = [(lines[i + 1][:5], ln) for i, ln in enumerate(lines) if ln.startswith("contact: b")]
    gap = "contact: boundary: {} exterior facet(s) (length 0.25) in no part carry the natural "
    tagged = "contact: boundary: every exterior facet is in a boundary part"
    expected = [
        ("[1/8]", gap.format(2)),
        ("[2/8]", gap.format(4)),
        ("[5/8]", tagged),
        ("[6/8]", tagged),
    ]
    assert len(said) == len(expected), said
    for (run, line), (first, start) in zip(said, expected):
        assert run == first and line.startswith(start) and len(line) <= 300, said
    with open(tmp_path / "out" / "study.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["case"], r["level"], r["untagged_facets"]) for r in rows] == [
        (case, level, str(facets * (2 if level == "1" else 1)))
        for case, facets in (("gap", 2), ("tagged", 0))
        for _ in ("fb", "min")
        for level in ("0", "1")
    ]
    assert all(r["converged"] == "True" for r in rows)


def test_api_warns_once_per_scene():
    """The Python API gives the line as one ContactWarning per scene: on the first public
    call (contact.solve), not again for a second solve, a scene refined from it or its
    adaptive loop; a fully tagged scene gives none."""
    from contact.base.errors import ContactWarning

    def boundary_warnings(scene) -> list[str]:
        cells = np.arange(scene.mesh.topology.index_map(2).size_local, dtype=np.int32)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(2):
                assert contact.solve(scene, verbose=False).converged
            fine, _ = contact.refine(scene, cells)
            assert contact.solve(fine, verbose=False).converged
            assert len(contact.adapt(scene, max_levels=2).levels) == 2
        return [
            str(w.message)
            for w in caught
            if w.category is ContactWarning and str(w.message).startswith("boundary:")
        ]

    [line] = boundary_warnings(contact.load_scene(corner_gap(readme_scene()), ["adapt=none"]))
    assert line == report(contact.load_scene(corner_gap(readme_scene())))[1]
    assert boundary_warnings(contact.load_scene(readme_scene(), ["adapt=none"])) == []
