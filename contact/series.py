"""Fields as VTK XML files that ParaView and pyvista (VTK) open directly.

* :func:`write_vtu` — one unstructured grid (``.vtu``, raw binary, LZ4-compressed) with the
  nodal fields as point data and the cellwise (DG0) fields as cell data;
* :class:`Series` — a time series: ``<name>_000.vtu``, ``<name>_001.vtu``, … and the
  collection ``<name>.pvd`` that ParaView opens as one animation, with the refinement level,
  load step or pseudo-time as its time value (each step may have its own mesh).

The grid's points are the nodes of the fields' Lagrange space, so P2 fields keep every DoF
(edge midpoints included; the cells are VTK Lagrange cells of degree 2).  In parallel each
rank sends its owned nodes (in the global DoF order) and owned cells to rank 0, which writes
one file: the same layout for any number of ranks, no duplicated partition-boundary nodes.
(Measured against ``dolfinx.io.VTKFile``'s ASCII pieces: 1.9 MB against 9.5 MB for a
30³ box with four P1 fields, and one file per step instead of one per rank plus a .pvtu.)

Reading back in Python::

    import pyvista
    grid = pyvista.read("results/square/solution.vtu")           # one solve
    reader = pyvista.get_reader("results/demo/solution.pvd")     # a series
    reader.set_active_time_value(reader.time_values[-1]); grid = reader.read()[0]
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence
from xml.sax.saxutils import quoteattr

import numpy as np
from mpi4py import MPI

from dolfinx import fem, plot


def _degree(V: fem.FunctionSpace) -> int:
    return V.element.basix_element.degree


def _on_space(fn: fem.Function, W: fem.FunctionSpace) -> np.ndarray:
    """Owned nodal values of ``fn`` in the node numbering of the scalar space W, (n, bs):
    used as is when fn's space numbers its nodes like W, else interpolated (exact between
    Lagrange spaces of one degree on one mesh)."""
    V = fn.function_space
    bs = V.dofmap.index_map_bs
    n = W.dofmap.index_map.size_local
    if V.dofmap.index_map.size_local != n or not np.array_equal(V.dofmap.list, W.dofmap.list):
        shape = (bs,) if bs > 1 else ()
        out = fem.Function(fem.functionspace(W.mesh, ("Lagrange", _degree(W), shape)))
        out.interpolate(fn)
        fn = out
    return fn.x.array[: n * bs].real.reshape(n, bs)


def _cell_values(fn: fem.Function, n_cells: int) -> np.ndarray:
    """Values of a cellwise (DG0) function on the owned cells, (n_cells, bs)."""
    V = fn.function_space
    bs = V.dofmap.index_map_bs
    dofs = V.dofmap.list[:n_cells, 0]
    return fn.x.array.real.reshape(-1, bs)[dofs]


def gather_grid(point_fields: Sequence[fem.Function], cell_fields: Sequence[fem.Function] = (), root: int = 0):
    """The fields on one pyvista grid on rank ``root`` (None elsewhere; collective).

    All point fields must be Lagrange of one degree on one mesh (scalar or vector valued);
    the grid's points are that space's nodes (in global DoF order), its cells the owned
    cells of every rank.  Vector fields of a 2D mesh get a zero third component, so that
    ParaView's "Warp By Vector" applies."""
    import pyvista

    msh = point_fields[0].function_space.mesh
    comm = msh.comm
    W = fem.functionspace(msh, ("Lagrange", _degree(point_fields[0].function_space)))
    topology, cell_types, x = plot.vtk_mesh(W)
    imap = W.dofmap.index_map
    n_owned, n_cells = imap.size_local, len(cell_types)
    top = topology.reshape(n_cells, -1).astype(np.int64)
    top[:, 1:] = imap.local_to_global(top[:, 1:].ravel().astype(np.int32)).reshape(n_cells, -1)
    points = {fn.name: _gather_rows(_on_space(fn, W), comm, root) for fn in point_fields}
    cells = {fn.name: _gather_rows(_cell_values(fn, n_cells), comm, root) for fn in cell_fields}
    x, top, cell_types = (_gather_rows(a, comm, root) for a in (x[:n_owned], top, cell_types))
    if comm.rank != root:
        return None
    grid = pyvista.UnstructuredGrid(top.ravel(), cell_types, x)
    gdim = msh.geometry.dim
    for fields, where in ((points, grid.point_data), (cells, grid.cell_data)):
        for name, values in fields.items():
            if values.shape[1] == 1:
                values = values[:, 0]
            elif values.shape[1] == gdim == 2:
                values = np.c_[values, np.zeros(len(values))]
            where[name] = values
    return grid


def _gather_rows(a: np.ndarray, comm: MPI.Comm, root: int) -> np.ndarray | None:
    """The rows of every rank's array ``a`` stacked in rank order on ``root`` (None elsewhere;
    collective).  One ``Gatherv`` of the raw buffers: no pickling, which cost 0.17 s for
    1.2M cells even on one rank."""
    a = np.ascontiguousarray(a)
    counts = comm.gather(a.size, root=root)
    if comm.rank != root:
        comm.Gatherv(a, None, root=root)
        return None
    out = np.empty((sum(counts) // int(np.prod(a.shape[1:])), *a.shape[1:]), dtype=a.dtype)
    comm.Gatherv(a, (out, counts), root=root)
    return out


def write_vtu(path: str | Path, point_fields: Sequence[fem.Function],
              cell_fields: Sequence[fem.Function] = (), field_data: dict | None = None) -> None:
    """One ``.vtu`` file with the fields (collective; rank 0 writes).  ``field_data`` adds
    global numbers (e.g. the level and the DoFs) as VTK field data."""
    grid = gather_grid(point_fields, cell_fields)
    if grid is not None:
        for key, value in (field_data or {}).items():
            grid.field_data[key] = np.atleast_1d(value)
        save_vtu(path, grid)


def save_vtu(path: str | Path, grid) -> None:
    """Write a pyvista/VTK unstructured grid as ``.vtu``: the arrays LZ4-compressed in one raw
    appended block, which ParaView's and VTK's readers (hence ``pyvista.read``) open.

    Raw appended data is neither base64-encoded nor inline: 1.2M cells with four point fields
    and one cell field, 0.11–0.16 s and 52 MB, against 0.51–0.58 s and 69 MB for the inline
    base64 that ``grid.save(..., binary=True)`` writes.
    LZ4 rather than VTK's default zlib: 4x faster (0.45 s against 1.7 s for 1.3M cells, inline),
    1.5x larger."""
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    writer = vtkXMLUnstructuredGridWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(grid)
    writer.SetDataModeToAppended()
    writer.EncodeAppendedDataOff()
    writer.SetCompressorTypeToLZ4()
    writer.SetHeaderTypeToUInt64()   # blocks of arrays above 4 GB
    if not writer.Write():
        raise OSError(f"could not write {path}")


class Series:
    """A time series ``<folder>/<name>.pvd`` of ``<name>_KKK.vtu`` files (collective).

    ``write(t, ...)`` adds one step with time value ``t`` and rewrites the collection, so
    the .pvd always lists every file written so far."""

    def __init__(self, folder: str | Path, name: str, comm: MPI.Comm = MPI.COMM_WORLD):
        self.folder, self.name, self.comm = Path(folder), name, comm
        self.steps: list[tuple[float, str]] = []

    @property
    def path(self) -> Path:
        return self.folder / f"{self.name}.pvd"

    def write(self, t: float, point_fields: Sequence[fem.Function],
              cell_fields: Sequence[fem.Function] = (), field_data: dict | None = None) -> Path:
        file = f"{self.name}_{len(self.steps):03d}.vtu"
        write_vtu(self.folder / file, point_fields, cell_fields, {"time": t, **(field_data or {})})
        self.steps.append((float(t), file))
        if self.comm.rank == 0:
            self.path.write_text(pvd(self.steps))
        return self.folder / file


def pvd(steps: Sequence[tuple[float, str]]) -> str:
    """The ParaView collection file of (time value, file name) pairs."""
    rows = "\n".join(f'    <DataSet timestep="{t!r}" part="0" file={quoteattr(f)}/>' for t, f in steps)
    return ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
            f"  <Collection>\n{rows}\n  </Collection>\n</VTKFile>\n")
