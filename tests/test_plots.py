"""The pictures of big 2D meshes: nodal fields sampled at pixel centres
(contact.output.plots.raster) must be the P1 interpolant there — what Gouraud shading paints — and
blank outside Ω."""

import json
import os
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from contact.output import drawing, plots  # noqa: E402

import matplotlib.tri as mtri  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402


def _square(n: int, lo, seed: int):
    """Delaunay triangles of n scattered points in the unit square at ``lo`` and its corners:
    irregular, partly sub-pixel triangles that cover the square exactly."""
    P = (
        np.vstack([np.random.default_rng(seed).random((n, 2)), [[0, 0], [1, 0], [0, 1], [1, 1]]])
        + lo
    )
    return P, mtri.Triangulation(P[:, 0], P[:, 1]).triangles


def _lshape(n: int):
    """(−1, 1)² without the quadrant x, y > 0, as three independently triangulated squares."""
    parts = [_square(n // 3, lo, seed) for seed, lo in enumerate(([-1, -1], [0, -1], [-1, 0]))]
    P = np.vstack([p for p, _ in parts])
    offsets = np.cumsum([0] + [len(p) for p, _ in parts[:-1]])
    return mtri.Triangulation(
        P[:, 0], P[:, 1], np.vstack([t + o for (_, t), o in zip(parts, offsets)])
    )


def _centres(image, extent):
    ny, nx = image.shape
    x = extent[0] + (np.arange(nx) + 0.5) * (extent[1] - extent[0]) / nx
    y = extent[2] + (np.arange(ny) + 0.5) * (extent[3] - extent[2]) / ny
    return np.meshgrid(x, y)


@pytest.mark.parametrize("n, width", [(300, 50), (40000, 120)])
def test_raster_reproduces_a_linear_field_and_masks_outside(n, width):
    tri = _lshape(n)
    f = lambda x, y: 2.0 * x - 3.0 * y + 0.5  # noqa: E731  (P1-exact)
    image, extent = plots.raster(tri, f(tri.x, tri.y), width=width, chunk=1000)
    X, Y = _centres(image, extent)
    inside = ~((X > 0) & (Y > 0)) & (X < 1) & (Y < 1)
    assert np.isfinite(image[inside]).all()
    assert np.abs(image[inside] - f(X[inside], Y[inside])).max() < 1e-12
    outside = (X > 1e-9) & (Y > 1e-9)  # the removed quadrant stays blank
    assert np.isnan(image[outside]).all()


def test_raster_matches_the_triangulation_interpolant():
    P, triangles = _square(5000, [0, 0], seed=7)
    tri = mtri.Triangulation(P[:, 0], P[:, 1], triangles)
    v = np.sin(3 * tri.x) * np.cos(2 * tri.y)
    image, extent = plots.raster(tri, v, width=90)
    X, Y = _centres(image, extent)
    ref = mtri.LinearTriInterpolator(tri, v)(X, Y)
    both = np.isfinite(image) & ~np.ma.getmaskarray(ref)
    assert both.all()  # a square: every pixel centre is inside
    assert np.abs(image - ref).max() < 1e-10


def test_one_raster_plan_samples_every_field_as_its_own_raster():
    """The mesh picture samples two fields through one Raster: each image equals the raster of
    that field alone (NaN outside at the same pixels), and the plan's extent is the raster's."""
    tri = _lshape(3000)
    plan = plots.Raster(tri, width=80, chunk=500)
    for v in (np.sin(4 * tri.x) * tri.y, np.exp(tri.x - 2 * tri.y)):
        image, extent = plots.raster(tri, v, width=80, chunk=700)
        assert np.array_equal(plan.image(v), image, equal_nan=True) and plan.extent == extent
    assert np.isnan(image).any() and np.isfinite(image).sum() > 2000


def test_big_meshes_are_drawn_as_an_image(monkeypatch):
    """Above RASTER_CELLS the field is an AxesImage, below it Gouraud triangles."""
    import matplotlib.pyplot as plt

    tri = _lshape(2000)
    v = tri.x + tri.y
    for cells, kind in ((10**9, "TriMesh"), (10, "AxesImage")):
        monkeypatch.setattr(drawing, "RASTER_CELLS", cells)
        fig, ax = plt.subplots()
        assert type(plots.smooth_shading(ax, tri, v, "viridis")).__name__ == kind
        plt.close(fig)


def test_3d_pictures_draw_without_warnings(tmp_path):
    """The 3D pictures (pyvista) of a small elastic block on a plane: both files are PNGs,
    and drawing them emits no warning (a user's run prints nothing but its own lines)."""
    import warnings

    import contact

    scene = contact.load_scene(
        {
            "name": "box3d",
            "mesh": {"type": "box", "corners": [[0, 0, 0], [1, 1, 1]], "cells": [3, 3, 3]},
            "boundaries": {
                "floor": {"role": "contact", "where": "z < 1e-10"},
                "top": {"role": "dirichlet", "where": "z > 1 - 1e-10"},
            },
            "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
            "obstacle": {"type": "plane", "point": [0, 0, -0.001], "normal": [0, 0, 1]},
            "data": {"u_D": ["0", "0", "-0.01"]},
        }
    )
    r = contact.solve(scene, verbose=False)
    assert r.converged and r.n_active > 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plots.plot_solution(
            tmp_path / "solution.png", r.u_h, active=r.active, lmbda=r.lmbda_h, normal=[0, 0, -1]
        )
        plots.plot_mesh(tmp_path / "mesh.png", r.u_h, active=r.active, normal=[0, 0, -1])
    for name in ("solution.png", "mesh.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name


DRAW_IN_TURN = """
import json, sys
import numpy as np
from mpi4py import MPI
import contact
from contact.output import plots
from dolfinx import fem, mesh
comm = MPI.COMM_WORLD
u = fem.Function(fem.functionspace(mesh.create_unit_square(comm, 8, 8), ("Lagrange", 1)), name="u")
u.interpolate(lambda x: x[0] + 2 * x[1])
def record(k):   # picture k notes the rank that drew it and the gathered grid's size and values
    def error(grid):
        exact = grid.points[:, 0] + 2 * grid.points[:, 1]
        return float(np.max(np.abs(grid.point_data["u"] - exact)))
    return lambda grid: open(f"{sys.argv[1]}/{k}.json", "w").write(json.dumps(
        [comm.rank, grid.n_points, error(grid)]))
plots.DRAW_RANKS = int(sys.argv[2]) or None
def chart(grid):   # a picture without fields: drawn by its rank, with no grid
    open(f"{sys.argv[1]}/3.json", "w").write(json.dumps([comm.rank, grid, 0.0]))
pictures = [plots.Picture([u], record(k)) for k in range(3)] + [plots.Picture([], chart)]
plots.draw_in_turn(pictures, comm)
# after the barrier: all there
files = [json.load(open(f"{sys.argv[1]}/{k}.json")) for k in range(4)]
if comm.rank == 0:
    print(json.dumps(files))
"""


@pytest.mark.parametrize("draw_ranks, drawn_by", [(0, [0, 1, 0, 1]), (1, [0, 0, 0, 0])])
def test_pictures_are_drawn_in_turn_by_every_rank(tmp_path, draw_ranks, drawn_by):
    """On 2 ranks picture k is gathered whole (81 nodes, u = x + 2y at each) on rank k mod 2
    and drawn there, a chart (no fields) too, without a grid; plots.DRAW_RANKS = 1 (the old
    path) draws every picture on rank 0; every file exists when draw_in_turn returns."""
    script = tmp_path / "draw.py"
    script.write_text(DRAW_IN_TURN)
    mpirun = Path(sys.executable).parent / "mpirun"
    proc = subprocess.run(
        [str(mpirun), "-n", "2", sys.executable, str(script), str(tmp_path), str(draw_ranks)],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stderr
    files = json.loads(proc.stdout.strip().splitlines()[-1])
    assert [f[0] for f in files] == drawn_by
    assert all(f[1] == 81 and f[2] < 1e-12 for f in files[:3]), files
    assert files[3][1] is None


def test_traction_map_of_a_frictionless_3d_load_path(tmp_path):
    """A 3D load path without friction (``--set friction.law=none``) has no λ_t columns: its
    traction.png is the pressure map alone (issue 26: KeyError 'lambda_t_x', exit 3)."""
    import matplotlib.image

    x, y = np.meshgrid(np.linspace(-0.5, 0.5, 5), np.linspace(-0.5, 0.5, 5))
    table = {
        "x": x.ravel(),
        "y": y.ravel(),
        "z": np.zeros(25),
        "r": np.hypot(x, y).ravel(),
        "lambda_n": -(1.0 - x**2 - y**2).ravel(),
    }
    path = tmp_path / "traction.png"
    plots.plot_traction(path, [(0.5, table), (1.0, table)], title="frictionless")
    height, width = matplotlib.image.imread(path).shape[:2]
    assert width < 1.3 * height  # one panel, not the two of a frictional map
