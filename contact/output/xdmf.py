"""Fields as XDMF 3 (XML + HDF5) for ParaView, meshio and h5py.

The heavy data are written in parallel by ``dolfinx.io.XDMFFile`` (HDF5 through MPI-IO:
each rank writes its own rows, nothing is gathered); the XML is then arranged by rank 0 so
that every field of a step sits on one grid:

* :func:`write_xdmf` — ``<name>.xdmf`` + ``<name>.h5``: one grid (``GridType="Uniform"``)
  holding the mesh (``Topology``, ``Geometry``), the nodal fields (``Center="Node"``; vectors
  of a 2D mesh with a zero third component) and the cellwise DG0 fields (``Center="Cell"``);
* :class:`XdmfSeries` — a time series (adaptive levels, load steps): step k as
  ``<name>_KKK.xdmf`` + ``<name>_KKK.h5`` (one grid as above, on that step's own mesh), and
  ``<name>.xdmf``, the temporal collection ``<Grid GridType="Collection"
  CollectionType="Temporal">`` of those grids, each with its ``<Time Value="t"/>`` (the level,
  or the load step's pseudo-time) and DataItems pointing into the step's ``.h5``.  ParaView
  opens it as one animation; meshio's ``xdmf.TimeSeriesReader`` reads the steps.  Each step
  is appended to the collection (:class:`contact.output.folder.Collection`): the cost of a
  step does not grow with the steps before it, and no step's XML is kept in memory.

A failed HDF5 write (a full disk) fails on every rank alike — each operation of
``XDMFFile`` is agreed on by all ranks — and raises :class:`contact.output.folder.OutputError`
naming the ``.h5`` file and the cause, after the file is released and closed
(:mod:`contact.output.hdf5`).

DOLFINx's own XML gives each function its own temporal collection beside the mesh, which
ParaView shows as one block per field and meshio reads one field of; its DataItems (HDF5
paths) are kept as they are, with the number type and precision of the HDF5 dataset stated.

Lagrange fields of degree p on a mesh whose geometry has degree 1 < p (P2 scenes) are
written on the same cells with degree-p geometry (``Triangle_6``): one point per P2 node,
every DoF kept; ParaView draws them as quadratic cells.
"""

from __future__ import annotations

import errno
import os
import shutil
import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from pathlib import Path
from xml.sax.saxutils import quoteattr

import basix.ufl
import numpy as np
from dolfinx import fem, graph, io
from dolfinx import mesh as dmesh
from mpi4py import MPI

from . import hdf5
from .folder import Collection, OutputError, write_on_root
from .vtk import cell_rows, nodal_rows

HEADER = '<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
NUMBER_TYPES = {"f": "Float", "i": "Int", "u": "UInt"}  # numpy dtype kind -> XDMF NumberType


def write_xdmf(
    path: str | Path, point_fields: Sequence[fem.Function], cell_fields: Sequence[fem.Function] = ()
) -> ET.Element | None:
    """Write ``path`` (.xdmf) and its .h5: the fields' mesh and the fields on one grid
    (collective).  Returns the grid's XML element on rank 0, None on the other ranks."""
    path = Path(path)
    points, cells = on_output_mesh(point_fields, cell_fields)
    msh = (points or cells)[0].function_space.mesh
    write_h5(path, msh, (*points, *cells))

    def rewrite() -> ET.Element:
        try:
            grid = one_grid(path, path.stem)
        except ET.ParseError:  # DOLFINx's XML is cut short where the disk filled up
            if _no_space(path):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)) from None
            raise
        finally:  # after the XML: the claim's unused space kept until then
            hdf5.trim(path.with_suffix(".h5"))
        _write_document(path, grid)
        return grid

    return write_on_root(msh.comm, rewrite, path.name)


def write_h5(path: Path, msh: dmesh.Mesh, fields: Sequence[fem.Function]) -> None:
    """The mesh and ``fields`` into ``path`` (.xdmf) and its .h5 by ``dolfinx.io.XDMFFile``
    (collective; HDF5 through MPI-IO), into the space :func:`contact.output.hdf5.claim`
    allocated (:func:`h5_bytes`; a full disk is an OutputError before HDF5 writes).  Every
    rank agrees on the outcome of each operation: if one fails on any rank, every rank
    releases the file (:func:`contact.output.hdf5.release`: its open datasets closed, its
    data cut), closes it and raises an OutputError naming the .h5 file and the cause."""
    comm = msh.comm
    h5 = path.with_suffix(".h5")
    nbytes = h5_bytes(msh, fields)

    def prepare() -> None:  # HDF5 must never meet a full disk (contact.output.hdf5)
        path.unlink(missing_ok=True)
        hdf5.claim(h5, nbytes)

    write_on_root(comm, prepare, h5.name)
    xdmf: io.XDMFFile | None = None
    reason: str | None = None

    def agreed(operation: Callable[[], object]) -> bool:
        nonlocal reason
        try:
            operation()
        except RuntimeError as err:  # DOLFINx's message; HDF5's reason is in its error stack
            reason = hdf5.cause() or _no_space(path) or str(err)
        return not comm.allreduce(reason is not None, op=MPI.LOR)

    def create() -> None:  # "a": into the file claim() made
        nonlocal xdmf
        xdmf = io.XDMFFile(comm, str(path), "a")

    def write(fn: fem.Function) -> Callable[[], object]:
        assert xdmf is not None  # created by the first agreed operation
        return lambda: xdmf.write_function(fn)

    if agreed(create):
        assert xdmf is not None
        if agreed(lambda: xdmf.write_mesh(msh)) and all(agreed(write(fn)) for fn in fields):
            if agreed(xdmf.close):
                return  # the caller trims the claim (hdf5.trim) once it has read the XML
    if xdmf is not None:  # a failure, agreed on by every rank: release and close the file
        hdf5.release(h5, truncate=comm.rank == 0)
        comm.Barrier()  # the data are cut before any rank closes
        try:
            xdmf.close()
        except RuntimeError:
            pass
    reasons = [r for r in comm.allgather(reason) if r is not None]
    raise OutputError(f"cannot write {h5.name}: {reasons[0]}")


def h5_bytes(msh: dmesh.Mesh, fields: Sequence[fem.Function]) -> int:
    """An upper bound of the bytes of the .h5 file of ``msh`` and ``fields``: all ranks'
    datasets of 8-byte numbers (2D vectors padded to 3 components) and 5 % more, 64 KiB and
    4 KiB a dataset for HDF5's own structures (measured: 12 KiB for 6 datasets)."""
    cells = msh.topology.index_map(msh.topology.dim).size_global
    nodes = msh.geometry.index_map().size_global
    numbers = nodes * msh.geometry.dim + cells * msh.geometry.dofmaps[0].shape[1]
    for fn in fields:
        V = fn.function_space
        bs = V.dofmap.index_map_bs
        numbers += V.dofmap.index_map.size_global * (3 if bs == 2 else bs)
    return int(8.4 * numbers) + 65536 + 4096 * (2 + len(fields))


def _no_space(path: Path) -> str | None:
    """'No space left on device' when the file system of ``path`` has less than
    :data:`FULL` bytes free (what a failed write there most likely met), else None."""
    try:
        full = shutil.disk_usage(path.parent).free < FULL
    except OSError:
        return None
    return os.strerror(errno.ENOSPC) if full else None


FULL = 1 << 20  # free bytes below which a file system counts as full


class XdmfSeries:
    """A time series ``<folder>/<name>.xdmf`` of the steps ``<name>_KKK.xdmf`` (collective).

    ``write(t, ...)`` adds one step with time value ``t`` and appends its grid to the
    collection, which therefore lists every step written so far."""

    def __init__(self, folder: str | Path, name: str, comm: MPI.Comm = MPI.COMM_WORLD):
        self.folder, self.name, self.comm = Path(folder), name, comm
        self.count = 0
        head = (
            f'{HEADER}<Xdmf Version="3.0">\n  <Domain>\n    <Grid Name={quoteattr(name)} '
            'GridType="Collection" CollectionType="Temporal">\n'
        )
        self._collection = Collection(self.path, head, "    </Grid>\n  </Domain>\n</Xdmf>\n")

    @property
    def path(self) -> Path:
        return self.folder / f"{self.name}.xdmf"

    def write(
        self,
        t: float,
        point_fields: Sequence[fem.Function],
        cell_fields: Sequence[fem.Function] = (),
    ) -> Path:
        file = self.folder / f"{self.name}_{self.count:03d}.xdmf"
        grid = write_xdmf(file, point_fields, cell_fields)

        def append() -> None:
            assert grid is not None  # append runs on rank 0, where write_xdmf returns the grid
            grid.set("Name", self.name)  # one name for every step: one grid in ParaView's list
            grid.insert(0, ET.Element("Time", Value=repr(float(t))))
            ET.indent(grid, level=3)  # its place in the collection: Xdmf/Domain/Grid/Grid
            grid.tail = None  # the step file's layout after it
            self._collection.append(f"      {ET.tostring(grid, encoding='unicode')}\n")

        write_on_root(self.comm, append, self.path.name)
        self.count += 1
        return file


def one_grid(path: Path, name: str) -> ET.Element:
    """The grid ``name`` holding the mesh and every field of the file DOLFINx's XDMFFile
    wrote at ``path`` (its mesh grid and one temporal collection of one step per function),
    each DataItem with the number type and precision of its HDF5 dataset."""
    domain = _child(ET.parse(path).getroot(), "Domain")
    mesh_grid = _child(domain, "Grid[@GridType='Uniform']")
    grid = ET.Element("Grid", Name=name, GridType="Uniform")
    topology = _child(mesh_grid, "Topology")
    if topology.get("TopologyType") == "PolyLine":  # intervals (the facets of a 2D Γ_C):
        topology.set("TopologyType", "Polyline")  # XDMF's spelling, which meshio reads too
    grid.extend([topology, _child(mesh_grid, "Geometry")])
    grid.extend(domain.iterfind("Grid[@GridType='Collection']/Grid/Attribute"))
    _state_types(grid, path.parent)
    return grid


def _child(element: ET.Element, path: str) -> ET.Element:
    """The first match of ``path`` under ``element`` (a file DOLFINx wrote has it)."""
    found = element.find(path)
    if found is None:
        raise ValueError(f"XDMF: no {path} under <{element.tag}>")
    return found


def _state_types(grid: ET.Element, folder: Path) -> None:
    """Set NumberType and Precision of every HDF5 DataItem from its dataset (float64 is
    Float 8; XDMF's default, when unstated, is Float 4)."""
    import h5py

    files: dict[str, h5py.File] = {}
    try:
        for item in grid.iter("DataItem"):
            if item.get("Format") != "HDF":
                continue
            name, h5path = (item.text or "").strip().split(":", 1)
            if name not in files:
                files[name] = h5py.File(folder / name, "r")
            dtype = files[name][h5path].dtype
            item.set("NumberType", NUMBER_TYPES[dtype.kind])
            item.set("Precision", str(dtype.itemsize))
    finally:
        for f in files.values():
            f.close()


def _write_document(path: Path, grid: ET.Element) -> None:
    root = ET.Element("Xdmf", Version="3.0")
    ET.SubElement(root, "Domain").append(grid)
    ET.indent(root)
    path.write_text(HEADER + ET.tostring(root, encoding="unicode") + "\n")


# ------------------------------------------------------------------ P2 on a quadratic mesh
def on_output_mesh(
    point_fields: Sequence[fem.Function], cell_fields: Sequence[fem.Function]
) -> tuple[list[fem.Function], list[fem.Function]]:
    """The fields on a mesh XDMFFile can write them on: as they are when the point fields
    are Lagrange of the mesh's geometry degree; else (P2 fields of a P1 mesh) copied onto
    the same cells with geometry of the fields' degree (:func:`lagrange_mesh`), nodal values
    node by node and DG0 values cell by cell (no interpolation: the same numbers)."""
    if not point_fields:
        return [], list(cell_fields)
    V = point_fields[0].function_space
    msh, degree = V.mesh, V.element.basix_element.degree
    if degree == msh.geometry.cmaps[0].degree:
        return list(point_fields), list(cell_fields)
    W = fem.functionspace(msh, ("Lagrange", degree))
    out, node_of, cell_of = lagrange_mesh(W)
    n_cells = out.topology.index_map(out.topology.dim).size_local
    spaces: dict[tuple, fem.FunctionSpace] = {}

    def copy_to(fn: fem.Function, element: tuple[str, int], rows: np.ndarray) -> fem.Function:
        key = (*element, fn.function_space.value_shape)
        if key not in spaces:
            spaces[key] = fem.functionspace(out, key)
        new = fem.Function(spaces[key], name=fn.name)
        bs = new.function_space.dofmap.index_map_bs
        if element[0] == "Lagrange":
            new.x.array.reshape(-1, bs)[:] = rows[node_of]
        else:
            new.x.array.reshape(-1, bs)[new.function_space.dofmap.list[:n_cells, 0]] = rows[cell_of]
        return new

    points = [
        copy_to(fn, ("Lagrange", degree), nodal_rows(fn, W, ghosts=True)) for fn in point_fields
    ]
    return points, [copy_to(fn, ("DG", 0), cell_rows(fn)) for fn in cell_fields]


def lagrange_mesh(W: fem.FunctionSpace) -> tuple[dmesh.Mesh, np.ndarray, np.ndarray]:
    """The cells of W's mesh with geometry of W's degree: every node of the scalar Lagrange
    space W a geometry node (collective; each rank keeps its own cells, no repartitioning).

    Returns the mesh, ``node_of`` (for each local DoF of the same Lagrange space on the new
    mesh, W's local DoF at that node) and ``cell_of`` (for each owned new cell, the local
    cell of W's mesh it copies)."""
    msh = W.mesh
    comm, tdim, gdim = msh.comm, msh.topology.dim, msh.geometry.dim
    imap = W.dofmap.index_map
    n_cells = msh.topology.index_map(tdim).size_local
    global_of = np.concatenate(
        [
            np.arange(imap.size_local, dtype=np.int64) + imap.local_range[0],
            imap.ghosts.astype(np.int64),
        ]
    )
    degree = W.element.basix_element.degree
    element = basix.ufl.element("Lagrange", msh.topology.cell_name(), degree, shape=(gdim,))

    def keep_cells(*_):  # every cell stays on its rank
        return graph.adjacencylist(np.full(n_cells, comm.rank, dtype=np.int32))._cpp_object

    x = W.tabulate_dof_coordinates()[: imap.size_local, :gdim]
    # basix.ufl.element is annotated as returning the abstract base, create_mesh lists its
    # subclasses
    out = dmesh.create_mesh(
        comm,
        global_of[W.dofmap.list[:n_cells]],
        element,  # type: ignore[arg-type]
        x,
        partitioner=keep_cells,
    )
    order = np.argsort(global_of)
    local_of_global = lambda g: order[np.searchsorted(global_of, g, sorter=order)]  # noqa: E731
    Q = fem.functionspace(out, ("Lagrange", degree))
    qmap = Q.dofmap.index_map
    node_of = np.empty(qmap.size_local + qmap.num_ghosts, dtype=np.int64)
    geometry_nodes = out.geometry.dofmaps[0]
    node_of[Q.dofmap.list] = local_of_global(out.geometry.input_global_indices[geometry_nodes])
    first_cell = comm.exscan(n_cells) or 0
    n_out = out.topology.index_map(tdim).size_local
    cell_of = np.asarray(out.topology.original_cell_index[:n_out], dtype=np.int64) - first_cell
    return out, node_of, cell_of
