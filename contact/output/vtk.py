"""Fields as VTK XML files that ParaView, pyvista (VTK) and meshio open directly.

* :func:`write_vtu` — one unstructured grid (``.vtu``, raw binary, uncompressed) with the
  nodal fields as point data and the cellwise (DG0) fields as cell data;
* :class:`Series` — a time series: ``<name>_000.vtu``, ``<name>_001.vtu``, … and the
  collection ``<name>.pvd`` that ParaView opens as one animation, with the refinement level,
  load step or pseudo-time as its time value (each step may have its own mesh).

The grid's points are the nodes of the fields' Lagrange space, so P2 fields keep every DoF
(edge midpoints included; the cells are VTK Lagrange cells of degree 2).  In parallel each
rank sends its owned nodes (in the global DoF order) and owned cells to rank 0, which writes
one file: the same layout for any number of ranks, no duplicated partition-boundary nodes.
``dolfinx.io.VTKFile`` writes ASCII pieces, one per rank, and a .pvtu: several times slower
and larger on big meshes (timings: demos/RESULTS.md §10).  The XDMF files
(:mod:`contact.output.xdmf`) are written in parallel.

Reading back in Python::

    import pyvista
    grid = pyvista.read("results/square/solution.vtu")           # one solve
    reader = pyvista.get_reader("results/demo/solution.pvd")     # a series
    reader.set_active_time_value(reader.time_values[-1]); grid = reader.read()[0]
    import meshio
    mesh = meshio.read("results/square/solution.vtu")
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
from dolfinx import cpp, fem
from mpi4py import MPI

from .folder import Collection, write_on_root
from .grid import Grid


def _degree(V: fem.FunctionSpace) -> int:
    return V.element.basix_element.degree


def nodal_rows(fn: fem.Function, W: fem.FunctionSpace, ghosts: bool = False) -> np.ndarray:
    """Nodal values of the Lagrange function ``fn`` in the node numbering of the scalar
    space W, (n, bs), of the owned nodes (and the ghosts after them if ``ghosts``): fn's own
    array when its space numbers its nodes like W, else fn interpolated on a space that does
    (exact between Lagrange spaces of one degree on one mesh)."""
    V = fn.function_space
    bs = V.dofmap.index_map_bs
    if V.dofmap.index_map.size_local != W.dofmap.index_map.size_local or not np.array_equal(
        V.dofmap.list, W.dofmap.list
    ):
        out = fem.Function(fem.functionspace(W.mesh, ("Lagrange", _degree(W), V.value_shape)))
        out.interpolate(fn)
        fn = out
    imap = W.dofmap.index_map
    n = imap.size_local + (imap.num_ghosts if ghosts else 0)
    return fn.x.array[: n * bs].real.reshape(n, bs)


def cell_rows(fn: fem.Function, n_cells: int | None = None) -> np.ndarray:
    """Values of a cellwise (DG0) function on the first ``n_cells`` local cells (all if
    None), (n_cells, bs)."""
    V = fn.function_space
    bs = V.dofmap.index_map_bs
    return fn.x.array.real.reshape(-1, bs)[V.dofmap.list[:n_cells, 0]]


#: gather_grid returns a pyvista grid (True: the old path, which imports pyvista and VTK
#: for every file and picture) or a :class:`~contact.output.grid.Grid` (False)
PYVISTA_GRID = False


def gather_grid(
    point_fields: Sequence[fem.Function], cell_fields: Sequence[fem.Function] = (), root: int = 0
):
    """The fields on one :class:`~contact.output.grid.Grid` on rank ``root`` (None elsewhere;
    collective).

    All point fields must be Lagrange of one degree on one mesh (scalar or vector valued);
    the grid's points are that space's nodes (in global DoF order), its cells the owned
    cells of every rank.  Vector fields of a 2D mesh get a zero third component, so that
    ParaView's "Warp By Vector" applies."""
    msh = point_fields[0].function_space.mesh
    comm = msh.comm
    W = _scalar_space(point_fields)
    imap = W.dofmap.index_map
    n_owned, n_cells = imap.size_local, msh.topology.index_map(msh.topology.dim).size_local
    global_of = np.concatenate(
        [np.arange(n_owned, dtype=np.int64) + imap.local_range[0], imap.ghosts.astype(np.int64)]
    )
    dofs = W.dofmap.list[:n_cells]
    vtk_order = np.argsort(cpp.io.perm_vtk(msh.topology.cell_type, dofs.shape[1]))
    connectivity = global_of[dofs[:, vtk_order]]
    points = {fn.name: _gather_rows(nodal_rows(fn, W), comm, root) for fn in point_fields}
    cells = {fn.name: _gather_rows(cell_rows(fn, n_cells), comm, root) for fn in cell_fields}
    x = _gather_rows(W.tabulate_dof_coordinates()[:n_owned], comm, root)
    connectivity = _gather_rows(connectivity, comm, root)
    if comm.rank != root:
        return None
    assert x is not None and connectivity is not None  # gathered on root
    grid = Grid(x, connectivity.astype(np.int64), _vtk_cell_type(msh, _degree(W)))
    gdim = msh.geometry.dim
    for fields, where in ((points, grid.point_data), (cells, grid.cell_data)):
        for name, values in fields.items():
            assert values is not None  # gathered on root
            if values.shape[1] == 1:
                values = values[:, 0]
            elif values.shape[1] == gdim == 2:
                values = np.c_[values, np.zeros(len(values))]
            where[name] = values
    return grid.pyvista() if PYVISTA_GRID else grid


def _scalar_space(point_fields: Sequence[fem.Function]) -> fem.FunctionSpace:
    """The scalar Lagrange space whose nodes are the grid's points: that of the first scalar
    point field (λ_h, on the output space), else a new one of the fields' degree."""
    for fn in point_fields:
        if fn.function_space.dofmap.index_map_bs == 1:
            return fn.function_space
    V = point_fields[0].function_space
    return fem.functionspace(V.mesh, ("Lagrange", _degree(V)))


FIRST_ORDER = {
    "interval": 3,
    "triangle": 5,
    "quadrilateral": 9,
    "tetrahedron": 10,
    "hexahedron": 12,
}


def _vtk_cell_type(msh, degree: int) -> int:
    """The VTK cell type of Lagrange cells of ``degree`` (linear cells, or VTK Lagrange cells)."""
    if degree == 1:
        return FIRST_ORDER[msh.topology.cell_name()]
    return cpp.io.get_vtk_cell_type(msh.topology.cell_type, msh.topology.dim)


def _gather_rows(a: np.ndarray, comm: MPI.Comm, root: int) -> np.ndarray | None:
    """The rows of every rank's array ``a`` stacked in rank order on ``root`` (None elsewhere;
    collective).  One ``Gatherv`` of the raw buffers: no pickling, which is slow on big
    meshes even on one rank (timings: demos/RESULTS.md §10)."""
    a = np.ascontiguousarray(a)
    counts = comm.gather(a.size, root=root)
    if comm.rank != root:
        comm.Gatherv(a, None, root=root)
        return None
    assert counts is not None  # gathered on root
    out = np.empty((sum(counts) // int(np.prod(a.shape[1:])), *a.shape[1:]), dtype=a.dtype)
    comm.Gatherv(a, (out, counts), root=root)
    return out


def write_vtu(
    path: str | Path,
    point_fields: Sequence[fem.Function],
    cell_fields: Sequence[fem.Function] = (),
    field_data: dict | None = None,
) -> None:
    """One ``.vtu`` file with the fields (collective; rank 0 writes).  ``field_data`` adds
    global numbers (e.g. the level and the DoFs) as VTK field data."""
    grid = gather_grid(point_fields, cell_fields)

    def save() -> None:
        for key, value in (field_data or {}).items():
            grid.field_data[key] = np.atleast_1d(value)
        save_vtu(path, grid)

    write_on_root(point_fields[0].function_space.mesh.comm, save, Path(path).name)


def save_vtu(path: str | Path, grid) -> None:
    """Write a :class:`~contact.output.grid.Grid` (or a pyvista/VTK unstructured grid) as
    ``.vtu`` (VTK XML: the arrays uncompressed in one raw appended block, each as its byte
    count, UInt64, and its little-endian bytes), which VTK's readers (ParaView, pyvista) and
    meshio read.

    The block holds the arrays in the reverse of their order in the XML: meshio 5.3.5
    re-encodes the arrays one by one in block order and looks each up as the first
    DataArray of the XML whose offset attribute equals its raw offset, so with the
    arrays in XML order it takes an already re-encoded array whose new offset happens to be
    equal (three field-data numbers suffice) and drops the field; in reverse order the
    re-encoded arrays all come after the one looked up.  VTK's own writer puts them in XML
    order; its base64 encoding (which meshio reads safely) is about ten times slower than
    raw data.  No compression: LZ4 is unknown to meshio, and zlib, even at level 1, costs
    more than the raw write it shrinks, on rank 0 while the other ranks wait (timings:
    demos/RESULTS.md §10)."""
    arrays: list[tuple[str, str, np.ndarray, dict]] = []  # (section, name, values, attributes)
    for name in grid.field_data.keys():
        values = np.asarray(grid.field_data[name])
        arrays.append(("FieldData", name, values, {"NumberOfTuples": len(values)}))
    for section, data in (("PointData", grid.point_data), ("CellData", grid.cell_data)):
        arrays += [(section, name, np.asarray(data[name]), {}) for name in data.keys()]
    arrays.append(("Points", "Points", np.asarray(grid.points), {}))
    arrays += [
        ("Cells", name, np.asarray(values), {})
        for name, values in (
            ("connectivity", grid.cell_connectivity),
            ("offsets", grid.cell_offsets[1:]),
            ("types", grid.celltypes),
        )
    ]
    arrays = [
        (sec, name, np.ascontiguousarray(v, dtype=v.dtype.newbyteorder("<")), attrs)
        for sec, name, v, attrs in arrays
    ]
    offsets, position = [0] * len(arrays), 0
    for k in reversed(range(len(arrays))):
        offsets[k], position = position, position + 8 + arrays[k][2].nbytes
    lines, open_section = [], None
    for (section, name, values, attrs), offset in zip(arrays, offsets):
        if section != open_section:
            if open_section is not None:
                lines.append(f"</{open_section}>")
            if section == "PointData":
                lines.append(
                    f'<Piece NumberOfPoints="{grid.n_points}" NumberOfCells="{grid.n_cells}">'
                )
            lines.append(f"<{section}>")
            open_section = section
        attrs = {"type": VTK_TYPES[values.dtype.kind, values.dtype.itemsize], "Name": name, **attrs}
        if values.ndim > 1:
            attrs["NumberOfComponents"] = values.shape[1]
        attrs.update(format="appended", offset=offset)
        pairs = "".join(f" {k}={quoteattr(str(v))}" for k, v in attrs.items())
        lines.append(f"<DataArray{pairs}/>")
    lines += ["</Cells>", "</Piece>", "</UnstructuredGrid>", '<AppendedData encoding="raw">']
    head = (
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
        'byte_order="LittleEndian" header_type="UInt64">\n<UnstructuredGrid>\n'
        + "\n".join(lines)
        + "\n_"
    )
    with open(path, "wb") as fh:
        fh.write(head.encode())
        for _, _, values, _ in reversed(arrays):
            fh.write(np.uint64(values.nbytes).tobytes())
            fh.write(values.data)
        fh.write(b"\n</AppendedData>\n</VTKFile>\n")


VTK_TYPES = {
    ("f", 8): "Float64",
    ("f", 4): "Float32",
    ("i", 8): "Int64",
    ("i", 4): "Int32",
    ("u", 1): "UInt8",
    ("u", 8): "UInt64",
}


class Series:
    """A time series ``<folder>/<name>.pvd`` of ``<name>_KKK.vtu`` files (collective).

    ``write(t, ...)`` adds one step with time value ``t`` and appends it to the collection
    (:class:`contact.output.folder.Collection`: a step's cost does not grow with the steps
    before it), so that the .pvd always lists every file written so far."""

    def __init__(self, folder: str | Path, name: str, comm: MPI.Comm = MPI.COMM_WORLD):
        self.folder, self.name, self.comm = Path(folder), name, comm
        self.count = 0
        head, tail = pvd([]).split(PVD_ROWS)
        self._collection = Collection(self.path, head, tail)

    @property
    def path(self) -> Path:
        return self.folder / f"{self.name}.pvd"

    def write(
        self,
        t: float,
        point_fields: Sequence[fem.Function],
        cell_fields: Sequence[fem.Function] = (),
        field_data: dict | None = None,
    ) -> Path:
        file = f"{self.name}_{self.count:03d}.vtu"
        write_vtu(self.folder / file, point_fields, cell_fields, {"time": t, **(field_data or {})})
        write_on_root(
            self.comm, lambda: self._collection.append(pvd_row(float(t), file)), self.path.name
        )
        self.count += 1
        return self.folder / file


PVD_ROWS = "<!-- rows -->\n"  # where the rows go in the empty collection


def pvd(steps: Sequence[tuple[float, str]]) -> str:
    """The ParaView collection file of (time value, file name) pairs (with none, the
    placeholder :data:`PVD_ROWS` where the rows go)."""
    rows = "".join(pvd_row(t, f) for t, f in steps) or PVD_ROWS
    return (
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" '
        'byte_order="LittleEndian">\n'
        f"  <Collection>\n{rows}  </Collection>\n</VTKFile>\n"
    )


def pvd_row(t: float, file: str) -> str:
    """One line of a .pvd: the file of time value ``t``."""
    return f'    <DataSet timestep="{t!r}" part="0" file={quoteattr(file)}/>\n'
