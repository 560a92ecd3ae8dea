"""Reading the field files of a result folder back as users do, each with two independent
readers that must agree: XDMF with meshio and with h5py + the XML (ElementTree), .vtu with
meshio and pyvista.  Used by the output tests on folders that `contact run` wrote in another
process."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

# the XDMF 3 content model of a Grid (Xdmf.dtd):
# Information*, Time*, Grid*, Topology*, Geometry*, Attribute*
GRID_CHILDREN = ("Information", "Time", "Grid", "Topology", "Geometry", "Attribute")
NUMBER_TYPES = {"f": "Float", "i": "Int", "u": "UInt"}


def xdmf_steps(path: Path) -> list[dict]:
    """Every grid (step) of an XDMF file, read with the XML and h5py: ``time`` (None for a
    lone grid), ``topology`` (its TopologyType), ``points``, ``cells``, ``point`` and ``cell``
    ({name: values}), ``files`` (the .h5 files it reads).  Checks the XDMF 3 structure on the
    way: one Domain with one grid, a Temporal collection of Uniform grids or one Uniform grid,
    the children of each grid in the model's order, every DataItem's Dimensions, NumberType
    and Precision equal to its HDF5 dataset's, and every attribute's rows equal to the
    number of points (Center Node) or cells (Center Cell) of its grid."""
    import h5py

    root = ET.parse(path).getroot()
    assert root.tag == "Xdmf" and root.get("Version") == "3.0", path
    (domain,) = list(root)
    (top,) = list(domain)
    assert domain.tag == "Domain" and top.tag == "Grid"
    if top.get("GridType") == "Collection":
        assert top.get("CollectionType") == "Temporal"
        grids = list(top)
    else:
        grids = [top]
    files: dict[str, h5py.File] = {}

    def read(item: ET.Element) -> np.ndarray:
        assert item.tag == "DataItem" and item.get("Format") == "HDF"
        name, h5path = item.text.strip().split(":")
        if name not in files:
            files[name] = h5py.File(path.parent / name, "r")
        data = files[name][h5path][()]
        assert [int(d) for d in item.get("Dimensions").split()] == list(data.shape), (path, h5path)
        assert item.get("NumberType") == NUMBER_TYPES[data.dtype.kind], (path, h5path)
        assert item.get("Precision") == str(data.dtype.itemsize), (path, h5path)
        return data

    steps = []
    try:
        for grid in grids:
            assert grid.tag == "Grid" and grid.get("GridType") == "Uniform"
            tags = [c.tag for c in grid]
            assert set(tags) <= set(GRID_CHILDREN), tags
            assert tags == sorted(tags, key=GRID_CHILDREN.index), tags
            time = grid.find("Time")
            (topology,), (geometry,) = grid.findall("Topology"), grid.findall("Geometry")
            step = {
                "time": None if time is None else float(time.get("Value")),
                "topology": topology.get("TopologyType"),
                "cells": read(topology.find("DataItem")),
                "points": read(geometry.find("DataItem")),
                "point": {},
                "cell": {},
            }
            assert int(topology.get("NumberOfElements")) == len(step["cells"])
            for attribute in grid.findall("Attribute"):
                values = read(attribute.find("DataItem"))
                center = {"Node": "point", "Cell": "cell"}[attribute.get("Center")]
                step[center][attribute.get("Name")] = values
                rows = len(step["points" if center == "point" else "cells"])
                assert len(values) == rows, attribute.get("Name")
            steps.append(step)
    finally:
        for f in files.values():
            f.close()
    for step in steps:
        step["files"] = sorted(files)
    return steps


def meshio_steps(path: Path) -> list[dict]:
    """The same file read with meshio: ``meshio.read`` for one grid, its
    ``xdmf.TimeSeriesReader`` for a collection (which reads one mesh, the first step's, and
    each step's time and fields)."""
    import meshio

    root = ET.parse(path).getroot()
    if root.find("Domain/Grid").get("GridType") != "Collection":
        mesh = meshio.read(path)
        cells = {k: v[0] for k, v in mesh.cell_data.items()}
        return [
            {
                "time": None,
                "points": mesh.points,
                "cells": mesh.cells[0].data,
                "point": dict(mesh.point_data),
                "cell": cells,
            }
        ]
    out = []
    with meshio.xdmf.TimeSeriesReader(path) as reader:
        points, cells = reader.read_points_cells()
        for k in range(reader.num_steps):
            t, point_data, cell_data = reader.read_data(k)
            cells_k = {name: v[0] for name, v in cell_data.items()}
            out.append({"time": t, "point": point_data, "cell": cells_k})
        out[0].update(points=points, cells=cells[0].data)
    return out


def read_xdmf(path: Path) -> list[dict]:
    """:func:`xdmf_steps`, checked against :func:`meshio_steps` (the same times, fields and
    values; the mesh of the first step)."""
    steps, other = xdmf_steps(path), meshio_steps(path)
    assert len(steps) == len(other)
    for step, m in zip(steps, other):
        assert step["time"] == m["time"]
        for kind in ("point", "cell"):
            assert set(step[kind]) == set(m[kind])
            for name, values in step[kind].items():
                theirs = np.asarray(m[kind][name]).reshape(values.shape)
                assert np.array_equal(theirs, values, equal_nan=True), name
    for key in ("points", "cells"):
        assert np.array_equal(other[0][key], steps[0][key]), key
    return steps


def read_vtu(path: Path):
    """A .vtu read with pyvista, checked against meshio: the same points, cells and arrays."""
    import meshio
    import pyvista

    grid = pyvista.read(path)
    mesh = meshio.read(path)
    assert np.array_equal(mesh.points, grid.points)
    assert sum(len(block.data) for block in mesh.cells) == grid.n_cells
    connectivity = np.concatenate([block.data.ravel() for block in mesh.cells])
    assert np.array_equal(connectivity, grid.cell_connectivity)
    assert set(mesh.point_data) == set(grid.point_data.keys())
    assert set(mesh.cell_data) == set(grid.cell_data.keys())
    for name, values in mesh.point_data.items():
        assert np.array_equal(values, grid.point_data[name], equal_nan=True), name
    for name, blocks in mesh.cell_data.items():
        assert np.array_equal(np.concatenate(blocks), grid.cell_data[name], equal_nan=True), name
    return grid


def by_position(points: np.ndarray, *fields: np.ndarray) -> list[np.ndarray]:
    """The points and per-point fields sorted by coordinates (rank counts number them apart)."""
    order = np.lexsort(np.round(points, 10).T[::-1])
    return [points[order]] + [f[order] for f in fields]
