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
  opens it as one animation; meshio's ``xdmf.TimeSeriesReader`` reads the steps.

DOLFINx's own XML gives each function its own temporal collection beside the mesh, which
ParaView shows as one block per field and meshio reads one field of; its DataItems (HDF5
paths) are kept as they are, with the number type and precision of the HDF5 dataset stated.

Lagrange fields of degree p on a mesh whose geometry has degree 1 < p (P2 scenes) are
written on the same cells with degree-p geometry (``Triangle_6``): one point per P2 node,
every DoF kept; ParaView draws them as quadratic cells.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from pathlib import Path

import basix.ufl
import numpy as np
from dolfinx import fem, graph, io
from dolfinx import mesh as dmesh
from mpi4py import MPI

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
    with io.XDMFFile(msh.comm, str(path), "w") as xdmf:
        xdmf.write_mesh(msh)
        for fn in (*points, *cells):
            xdmf.write_function(fn)

    def rewrite() -> ET.Element:
        grid = one_grid(path, path.stem)
        _write_document(path, grid)
        return grid

    return _on_root(msh.comm, rewrite)


class XdmfSeries:
    """A time series ``<folder>/<name>.xdmf`` of the steps ``<name>_KKK.xdmf`` (collective).

    ``write(t, ...)`` adds one step with time value ``t`` and rewrites the collection, so it
    always lists every step written so far."""

    def __init__(self, folder: str | Path, name: str, comm: MPI.Comm = MPI.COMM_WORLD):
        self.folder, self.name, self.comm = Path(folder), name, comm
        self.count = 0
        self.steps: list[ET.Element] = []  # rank 0: the grids of the collection

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

        def collect() -> None:
            assert grid is not None  # collect runs on rank 0, where write_xdmf returns the grid
            step = copy.deepcopy(grid)
            step.set("Name", self.name)  # one name for every step: one grid in ParaView's list
            step.insert(0, ET.Element("Time", Value=repr(float(t))))
            self.steps.append(step)
            series = ET.Element(
                "Grid", Name=self.name, GridType="Collection", CollectionType="Temporal"
            )
            series.extend(self.steps)
            _write_document(self.path, series)

        _on_root(self.comm, collect)
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


def _on_root(comm: MPI.Comm, action: Callable):
    """``action()`` on rank 0 (collective): its value there, None elsewhere; if it fails,
    an OSError with its message on every rank."""
    value, problem = None, None
    if comm.rank == 0:
        try:
            value = action()
        except Exception as err:  # noqa: BLE001 - reported on every rank below
            problem = f"{type(err).__name__}: {err}"
    problem = comm.bcast(problem, root=0)
    if problem is not None:
        raise OSError(f"writing XDMF failed on rank 0: {problem}")
    return value


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
