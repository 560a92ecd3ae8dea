"""A grid of cells of one type with its data in numpy arrays (:class:`Grid`): what the fields
gathered on one rank become for the .vtu writer (:mod:`.vtk`) and the pictures
(:mod:`.drawing`, :mod:`.plots`).  This module imports numpy only, so that a grid pickled
into the picture process (:mod:`.picture_process`) is read there without DOLFINx."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Grid:
    """An unstructured grid of cells of one type with its data, in numpy arrays: what the
    .vtu writer (:func:`save_vtu`) and the 2D pictures read, with the attribute names of a
    pyvista grid; :meth:`pyvista` makes one (for the 3D pictures).  Neither pyvista nor VTK
    is imported to build it: a run that draws in 2D loads neither."""

    points: np.ndarray  # (n_points, 3)
    connectivity: np.ndarray  # (n_cells, nodes per cell), VTK's node order
    cell_type: int  # the VTK cell type of every cell
    point_data: dict[str, np.ndarray] = field(default_factory=dict)
    cell_data: dict[str, np.ndarray] = field(default_factory=dict)
    field_data: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_cells(self) -> int:
        return len(self.connectivity)

    @property
    def cells_dict(self) -> dict[int, np.ndarray]:
        return {self.cell_type: self.connectivity}

    @property
    def cell_connectivity(self) -> np.ndarray:
        return self.connectivity.ravel()

    @property
    def cell_offsets(self) -> np.ndarray:
        per_cell = self.connectivity.shape[1]
        return np.arange(0, self.n_cells * per_cell + 1, per_cell, dtype=np.int64)

    @property
    def celltypes(self) -> np.ndarray:
        return np.full(self.n_cells, self.cell_type, dtype=np.uint8)

    def pyvista(self):
        """The same grid and data as a ``pyvista.UnstructuredGrid``."""
        grid = pyvista_grid(self.points, self.connectivity, self.cell_type)
        for ours, theirs in (
            (self.point_data, grid.point_data),
            (self.cell_data, grid.cell_data),
            (self.field_data, grid.field_data),
        ):
            for name, values in ours.items():
                theirs[name] = values
        return grid


def pyvista_grid(x: np.ndarray, connectivity: np.ndarray, cell_type: int):
    """A pyvista grid of cells of one type from the (n_cells, nodes per cell) connectivity,
    handed to VTK as offsets and connectivity arrays (no per-cell count column to parse)."""
    import pyvista
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonDataModel import vtkCellArray

    n_cells, per_cell = connectivity.shape
    cells = vtkCellArray()
    offsets = np.arange(0, n_cells * per_cell + 1, per_cell, dtype=np.int64)
    cells.SetData(
        numpy_to_vtkIdTypeArray(offsets, deep=True),
        numpy_to_vtkIdTypeArray(connectivity.astype(np.int64).ravel(), deep=True),
    )
    grid = pyvista.UnstructuredGrid()
    grid.points = x
    grid.SetCells(numpy_to_vtk(np.full(n_cells, cell_type, dtype=np.uint8), deep=True), cells)
    return grid
