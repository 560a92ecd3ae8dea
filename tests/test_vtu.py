"""The .vtu files (contact.output.vtk): one raw appended block, uncompressed, that VTK's reader
(pyvista.read) and meshio both give back exactly — points, cells, point, cell and field
data — and the gather behind them stacks every rank's rows in rank order, a rank with no
rows included."""

import os
import subprocess
import sys
from pathlib import Path

from contact.output import vtk

import meshio
import numpy as np
import pyvista


def test_vtu_reads_back_exactly_with_pyvista_and_meshio(tmp_path):
    """Five scalar fields of one size and three field-data numbers: the layout on which
    meshio 5.3.5 drops a field of a raw block written in XML order (an earlier array's
    re-encoded offset equals a later raw one), and LZ4 it cannot read at all."""
    rng = np.random.default_rng(3)
    points = rng.random((41, 3))
    cells = rng.integers(0, 41, size=(25, 4))
    grid = pyvista.UnstructuredGrid({pyvista.CellType.TETRA: cells}, points)
    grid.point_data["u_h"] = rng.random((41, 3))
    for name in ("lambda_h", "gap", "active", "status", "bound"):
        grid.point_data[name] = rng.random(41)
    grid.point_data["gap"][::3] = np.nan
    grid.cell_data["eta_T"] = rng.random(25)
    for name, value in (("time", 2.5), ("step", 3), ("dofs", 123)):
        grid.field_data[name] = np.array([value])
    path = tmp_path / "g.vtu"
    vtk.save_vtu(path, grid)
    data = path.read_bytes()
    assert b'<AppendedData encoding="raw">' in data and b"compressor" not in data
    back = pyvista.read(path)
    mesh = meshio.read(path)
    assert np.array_equal(back.points, grid.points) and np.array_equal(back.cells, grid.cells)
    assert np.array_equal(back.celltypes, grid.celltypes)
    assert np.array_equal(mesh.points, grid.points)
    assert np.array_equal(mesh.cells_dict["tetra"], cells)
    for name in grid.point_data.keys():
        assert np.array_equal(back.point_data[name], grid.point_data[name], equal_nan=True), name
        assert np.array_equal(mesh.point_data[name], grid.point_data[name], equal_nan=True), name
    assert np.array_equal(back.cell_data["eta_T"], grid.cell_data["eta_T"])
    assert np.array_equal(mesh.cell_data["eta_T"][0], grid.cell_data["eta_T"])
    for name, value in (("time", 2.5), ("step", 3), ("dofs", 123)):
        assert back.field_data[name][0] == value and mesh.field_data[name][0] == value


GATHER_ROWS = """
import json
import numpy as np
from mpi4py import MPI
from contact.output import vtk
comm = MPI.COMM_WORLD
rows = [3, 0, 5][comm.rank]   # rank 1 holds nothing
a = np.full((rows, 2), comm.rank, dtype=np.int64) + np.arange(rows)[:, None]
b = np.full(rows, 0.5 + comm.rank)
out = [vtk._gather_rows(x, comm, root=2) for x in (a, b)]
if comm.rank == 2:
    print(json.dumps([o.tolist() for o in out] + [str(out[0].dtype), str(out[1].dtype)]))
else:
    assert out == [None, None]
"""


def test_gather_rows_stacks_every_rank_in_order(tmp_path):
    script = tmp_path / "gather.py"
    script.write_text(GATHER_ROWS)
    mpirun = Path(sys.executable).parent / "mpirun"
    proc = subprocess.run(
        [str(mpirun), "-n", "3", sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stderr
    import json

    a, b, da, db = json.loads(proc.stdout.strip().splitlines()[-1])
    assert a == [[0, 0], [1, 1], [2, 2], [2, 2], [3, 3], [4, 4], [5, 5], [6, 6]]
    assert b == [0.5] * 3 + [2.5] * 5 and (da, db) == ("int64", "float64")
