"""Gmsh geometries for Hertz contact validation (contact.setup.geometry): measures of the body
and of each tagged part, every exterior facet tagged by the right part, the mesh graded
down to h_contact near the contact point, argument errors as one-line ConfigErrors, and
the same mesh on 1 and 2 MPI ranks; refinement snaps the new vertices of the curved
boundary onto the circle / sphere (same coordinates on 1 and 2 ranks, nested iteration
keeps its values, other meshes untouched, an inverting snap is an error)."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import contact  # noqa: F401  (must precede dolfinx)
from contact import refine
from contact.adaptivity.refine import refine_partitioner
from contact.base.errors import ConfigError
from contact.setup.geometry import (
    CONTACT,
    GRADING,
    CurvedBoundary,
    curved_boundary,
    quarter_disk,
    sphere_octant,
)

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from snap_levels import SCENES, load, main, near_contact, refinements

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"

# small meshes; radius ≠ 1 so that a missing factor R shows
DISK = dict(radius=2.0, h=0.2, h_contact=0.02, zone=0.3)
OCTANT = dict(radius=1.5, h=0.2, h_contact=0.03, zone=0.25)


def _R2(R):  # (expected measure of the body, of each tag) for the quarter disk
    return math.pi * R**2 / 4, {1: math.pi * R / 2, 2: R, 3: R}


def _R3(R):
    return math.pi * R**3 / 6, {
        1: math.pi * R**2 / 2,
        2: math.pi * R**2 / 4,
        3: math.pi * R**2 / 4,
        4: math.pi * R**2 / 4,
    }


CASES = {"quarter_disk": (quarter_disk, DISK, _R2), "sphere_octant": (sphere_octant, OCTANT, _R3)}


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    build, params, expected = CASES[request.param]
    msh, tags = build(MPI.COMM_WORLD, **params)
    return msh, tags, params, expected(params["radius"])


def _sum(comm, value):
    return comm.allreduce(value, op=MPI.SUM)


def test_measures(case):
    msh, tags, params, (body, parts) = case
    comm, tdim = msh.comm, msh.topology.dim
    assert msh.geometry.dim == tdim and msh.topology.cell_type == (
        dmesh.CellType.triangle if tdim == 2 else dmesh.CellType.tetrahedron
    )
    assert [c.degree for c in msh.geometry.cmaps] == [1]
    one = fem.Constant(msh, 1.0)
    volume = _sum(comm, fem.assemble_scalar(fem.form(one * ufl.dx)))
    assert volume == pytest.approx(body, rel=1e-2)
    assert volume < body  # inscribed polygon / polyhedron
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    for tag, exact in parts.items():
        measure = _sum(comm, fem.assemble_scalar(fem.form(one * ds(tag))))
        # flat parts are exact up to their curved edge; the curved part is inscribed
        assert measure == pytest.approx(exact, rel=1e-2), tag
    flat_top = _sum(comm, fem.assemble_scalar(fem.form(one * ds(2))))
    if tdim == 2:
        assert flat_top == pytest.approx(params["radius"], rel=1e-12)


def test_every_exterior_facet_tagged_by_its_part(case):
    msh, tags, params, (_, parts) = case
    tdim, R = msh.topology.dim, params["radius"]
    msh.topology.create_connectivity(tdim - 1, tdim)
    exterior = dmesh.exterior_facet_indices(msh.topology)
    assert np.array_equal(np.unique(tags.indices), np.sort(tags.indices)), "a facet tagged twice"
    assert np.array_equal(np.sort(tags.indices), exterior)
    assert set(np.unique(tags.values)) <= set(parts)
    assert set(np.concatenate(msh.comm.allgather(np.unique(tags.values)))) == set(parts)
    # the vertices of each part lie on its surface
    for tag in parts:
        assert np.all(_off_surface(msh, tags, tag, R) < 1e-8 * R), tag
    # and the body lies in the part of the disk / ball it should
    centre = np.zeros(3)
    centre[tdim - 1] = R
    x = msh.geometry.x
    assert np.all(np.linalg.norm(x - centre, axis=1) <= R * (1 + 1e-10))
    assert np.all(x[:, : tdim - 1] >= -1e-12) and np.all(x[:, tdim - 1] <= R * (1 + 1e-12))


def _off_surface(msh, tags, tag, R):
    """Distance of the vertices of the facets tagged ``tag`` from that part's exact surface
    (the circle / sphere |x − (0, R)| = R or |x − (0, 0, R)| = R for tag 1, the planes
    y = R / z = R, x = 0 and y = 0 for tags 2, 3, 4)."""
    tdim = msh.topology.dim
    centre = np.zeros(3)
    centre[tdim - 1] = R
    x = msh.geometry.x[dmesh.entities_to_geometry(msh, tdim - 1, tags.find(tag)).ravel()]
    return {
        1: np.abs(np.linalg.norm(x - centre, axis=1) - R),
        2: np.abs(x[:, tdim - 1] - R),
        3: np.abs(x[:, 0]),
        4: np.abs(x[:, 1]),
    }[tag]


def test_graded_towards_contact_point(case):
    msh, _, params, _ = case
    comm, tdim = msh.comm, msh.topology.dim
    cells = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    h = msh.h(tdim, cells)
    r = np.linalg.norm(dmesh.compute_midpoints(msh, tdim, cells), axis=1)
    near, far = r < params["zone"], r > params["zone"]
    mean = lambda sel: _sum(comm, h[sel].sum()) / _sum(comm, int(sel.sum()))  # noqa: E731
    assert mean(near) < mean(far) / 3
    # the cell diameter (longest edge) is a modest multiple of the requested size
    assert params["h_contact"] < mean(near) < 2 * params["h_contact"]
    coarse = r > params["zone"] + (params["h"] - params["h_contact"]) / GRADING
    assert params["h"] < mean(coarse) < 2 * params["h"]
    assert comm.allreduce(h.max(), op=MPI.MAX) < 2.5 * params["h"]  # tets: a few long edges


@pytest.mark.parametrize("build", [quarter_disk, sphere_octant])
@pytest.mark.parametrize(
    "key, value, message",
    [
        ("radius", 0.0, "mesh.radius: must be > 0, got 0"),
        ("h", -1, "mesh.h: must be > 0, got -1"),
        ("h_contact", -1, "mesh.h_contact: must be > 0, got -1"),
        ("zone", float("nan"), "mesh.zone: must be > 0, got nan"),
        ("h", "fine", "mesh.h: must be a number, got 'fine'"),
        ("h_contact", 0.5, "mesh.h_contact: must be <= mesh.h (0.1), got 0.5"),
        ("zone", 1.0, "mesh.zone: must be < mesh.radius (1), got 1"),
    ],
)
def test_bad_arguments(build, key, value, message):
    params = dict(radius=1, h=0.1, h_contact=0.01, zone=0.2)
    params[key] = value
    with pytest.raises(ConfigError) as err:
        build(MPI.COMM_WORLD, **params)
    assert str(err.value) == message


SCRIPT = f"""
import json, contact, ufl
from mpi4py import MPI
from dolfinx import fem
from contact.setup.geometry import quarter_disk
msh, tags = quarter_disk(MPI.COMM_WORLD, **{DISK!r})
one = fem.Constant(msh, 1.0)
area = msh.comm.allreduce(fem.assemble_scalar(fem.form(one * ufl.dx)), op=MPI.SUM)
arc = msh.comm.allreduce(fem.assemble_scalar(fem.form(
    one * ufl.Measure("ds", domain=msh, subdomain_data=tags)(1))), op=MPI.SUM)
local = msh.topology.index_map(2).size_local
counts = msh.comm.gather(local, root=0)
if msh.comm.rank == 0:
    print(json.dumps({{"cells": msh.topology.index_map(2).size_global, "counts": counts,
                      "area": area, "arc": arc}}))
"""


@pytest.mark.mpi
def test_quarter_disk_same_on_two_ranks():
    serial, tags = quarter_disk(MPI.COMM_WORLD, **DISK)
    one = fem.Constant(serial, 1.0)
    area = fem.assemble_scalar(fem.form(one * ufl.dx))
    proc = subprocess.run(
        [str(MPIRUN), "-n", "2", sys.executable, "-c", SCRIPT],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["cells"] == serial.topology.index_map(2).size_global
    assert len(out["counts"]) == 2 and min(out["counts"]) > 0 and sum(out["counts"]) == out["cells"]
    assert out["area"] == pytest.approx(area, rel=1e-12)
    assert out["arc"] == pytest.approx(math.pi * DISK["radius"] / 2, rel=1e-2)


# --- refinement puts the new vertices of the curved boundary on the circle / sphere -------


def _volume(msh):
    one = fem.Constant(msh, 1.0)
    return _sum(msh.comm, fem.assemble_scalar(fem.form(one * ufl.dx)))


@pytest.mark.parametrize("kind", list(SCENES))
def test_refinement_puts_curved_boundary_on_the_surface(kind):
    """Every vertex of a tag-1 facet lies on the circle / sphere, those of the flat parts on
    their planes, and the body's volume converges to the disk's / ball's (midpoints alone
    keep the coarse polygon's volume exactly)."""
    body, parts = CASES[kind][2](SCENES[kind][1])
    errors = []
    for scene, R in refinements(kind):
        errors.append(abs(_volume(scene.mesh) - body) / body)
        if len(errors) > 1:
            for tag in parts:
                assert np.all(_off_surface(scene.mesh, scene.boundary.tags, tag, R) < 1e-12 * R), (
                    tag
                )
    assert errors[1] < 0.4 * errors[0] and errors[2] < errors[1], errors


def test_nested_iteration_keeps_the_values_at_snapped_vertices():
    """u_h is interpolated before the vertices move: a new arc vertex carries u_h at the
    midpoint m of its parent chord, where dolfinx put it, not u_h extrapolated to (or 0 at)
    its snapped place π(m) outside the old mesh; elsewhere u0 = u_h.  (u_h = f, linear, is
    reproduced by P1, so u0 = f(m) on the arc and f(x) off it.)"""
    scene, R = load("quarter_disk")
    msh = scene.mesh
    arc = msh.geometry.x[
        np.unique(dmesh.entities_to_geometry(msh, 1, scene.boundary.tags.find(CONTACT))), :2
    ]
    arc = arc[np.argsort(np.arctan2(arc[:, 1] - R, arc[:, 0]))]  # from (0, 0) to (R, R)
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    f = lambda x: np.vstack([1 + x[0] + 2 * x[1], 3 - x[1]])  # noqa: E731
    u_h = fem.Function(V)
    u_h.interpolate(f)
    _, u0 = refine(scene, near_contact(msh, np.inf), u_h)
    X = u0.function_space.tabulate_dof_coordinates()[:, :2]
    at = X.copy()  # where u0 should equal f
    new_on_arc = np.flatnonzero(
        (np.abs(np.linalg.norm(X - [0.0, R], axis=1) - R) < 1e-12 * R)
        & (np.linalg.norm(X[:, None] - arc[None], axis=2).min(axis=1) > 1e-12)
    )
    k = np.searchsorted(
        np.arctan2(arc[:, 1] - R, arc[:, 0]), np.arctan2(X[new_on_arc, 1] - R, X[new_on_arc, 0])
    )
    assert len(new_on_arc) == len(arc) - 1 and np.array_equal(np.sort(k), np.arange(1, len(arc)))
    at[new_on_arc] = 0.5 * (arc[k - 1] + arc[k])  # the chord midpoints
    assert np.abs(at - X).max() > 1e-3  # the snap moved them
    assert np.abs(u0.x.array.reshape(-1, 2) - f(at.T).T).max() < 1e-12


def test_other_meshes_are_refined_as_dolfinx_does():
    """A rectangle (its contact part is tag 1 too) has no curved boundary: refine leaves
    the coordinates exactly as dolfinx.mesh.refine makes them."""
    scene = contact.load_scene(
        ROOT / "configs" / "signorini_free_boundary.yaml", ["output.verbose=false"]
    )
    assert curved_boundary(scene.config.mesh) is None and scene.boundary.ids["contact"] == CONTACT
    msh = scene.mesh
    cells = near_contact(msh, 0.5)
    child, _ = refine(scene, cells)
    msh.topology.create_entities(1)
    plain, _, _ = dmesh.refine(
        msh,
        dmesh.compute_incident_entities(msh.topology, cells, 2, 1),
        partitioner=refine_partitioner(msh),
        option=dmesh.RefinementOption.parent_cell_and_facet,
    )
    assert np.array_equal(child.mesh.geometry.x, plain.geometry.x)


def test_rectangle_refinement_does_not_import_gmsh():
    code = (
        "import sys, numpy as np, contact; s = "
        "contact.load_scene('configs/signorini_free_boundary.yaml'); "
        "contact.refine(s, np.arange(4, dtype=np.int32)); print('gmsh' in sys.modules)"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[-1] == "False"


def test_snapping_that_inverts_a_cell_is_an_error():
    """Projecting the bottom of the rectangle onto a small circle inside it pulls the
    bottom vertices above the first row of vertices."""
    scene = contact.load_scene(
        ROOT / "configs" / "signorini_free_boundary.yaml", ["output.verbose=false"]
    )
    surface = CurvedBoundary(centre=(0.0, 0.5), radius=0.1, tag=CONTACT)
    with pytest.raises(RuntimeError, match="inverts or flattens"):
        surface.snap(scene.mesh, scene.boundary.tags)


@pytest.mark.parametrize("nproc", [1, 3])
def test_collapse_check_of_the_touched_cells_equals_the_full_check(nproc):
    """Snapping checks only the cells with a moved node (tests/collapse_check.py): the same
    collapsed cells as checking every cell on each rank, ghosts excluded, when the bottom
    row of an 8 × 8 square moves up to 0.05 (none collapse), 0.2 (the bottom row inverts)
    or 0.125 (it flattens onto the first row of vertices)."""
    cmd = [sys.executable, str(ROOT / "tests" / "collapse_check.py"), "0.05", "0.2", "0.125"]
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc)] + cmd
    proc = subprocess.run(
        cmd,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.splitlines()[-1]) == {"0.05": 0, "0.2": 16, "0.125": 16}


@pytest.mark.mpi
@pytest.mark.parametrize("kind", list(SCENES))
def test_snapped_coordinates_same_on_two_ranks(tmp_path, kind):
    """After two refinements the 2-rank mesh has the serial nodes (gathered, sorted), and
    every ghost node has its owner's coordinates to the bit (a rank may hold a node on the
    curved surface without holding a tagged facet through it)."""
    main(str(tmp_path / "serial.json"), kind)
    proc = subprocess.run(
        [
            str(MPIRUN),
            "-n",
            "2",
            sys.executable,
            str(ROOT / "tests" / "snap_levels.py"),
            str(tmp_path / "parallel.json"),
            kind,
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stderr
    serial, parallel = (
        json.loads((tmp_path / f"{n}.json").read_text()) for n in ("serial", "parallel")
    )
    assert parallel["ghosts_disagree"] == 0
    X, Y = np.array(serial["x"]), np.array(parallel["x"])
    assert X.shape == Y.shape
    assert np.abs(X - Y).max() <= 1e-14 * SCENES[kind][1]
