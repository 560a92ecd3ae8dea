"""The field files of a run, in the formats of ``output.formats``.

* ``xdmf`` (:mod:`contact.output.xdmf`): ``solution.xdmf`` + ``solution.h5``, written in parallel;
  a series is ``solution.xdmf`` (a temporal collection) over ``solution_KKK.xdmf`` + ``.h5``;
* ``vtk`` (:mod:`contact.output.vtk`): ``solution.vtu``; a series is ``solution.pvd`` over
  ``solution_KKK.vtu``.

With ``xdmf`` and a contact surface (the scene's boundary given), the facet mesh of Γ_C with
the contact fields is written beside, as ``contact_surface.xdmf`` or its series
(:mod:`contact.output.surface`).

:class:`FieldFiles` writes one step or a series in every chosen format and keeps the
seconds each format took (``seconds``), which go to summary.json as ``time_output_xdmf``
and ``time_output_vtk``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from dolfinx import fem
from mpi4py import MPI

from .surface import SurfaceFiles, has_surface
from .vtk import Series, write_vtu
from .xdmf import XdmfSeries, write_xdmf

if TYPE_CHECKING:
    from ..post.posed import Parts as Boundary

FORMATS = ("xdmf", "vtk")


class FieldFiles:
    """The fields of ``<folder>/<name>.*`` in ``formats`` (collective): :meth:`write_one`
    for one solve, :meth:`write_step` for step after step of a series (time value t: the
    level, the load step's pseudo-time)."""

    def __init__(
        self,
        folder: str | Path,
        name: str,
        formats: Sequence[str],
        comm: MPI.Comm = MPI.COMM_WORLD,
        elastic: bool = False,
    ):
        self.folder, self.name, self.comm = Path(folder), name, comm
        self.formats = [f for f in FORMATS if f in formats]
        self.seconds = {f: 0.0 for f in self.formats}
        self._xdmf, self._vtk = XdmfSeries(folder, name, comm), Series(folder, name, comm)
        self._surface = SurfaceFiles(folder, elastic, comm)

    def write_one(
        self,
        point_fields: Sequence[fem.Function],
        cell_fields: Sequence[fem.Function] = (),
        boundary: Boundary | None = None,
    ) -> None:
        """``<name>.xdmf`` (+ .h5) and ``<name>.vtu``; with the scene's ``boundary``, also
        ``contact_surface.xdmf`` (+ .h5) when there is a contact surface."""
        path = (self.folder / self.name).with_suffix

        def xdmf() -> None:
            write_xdmf(path(".xdmf"), point_fields, cell_fields)
            if boundary is not None and has_surface(boundary, self.comm):
                self._surface.write_one(boundary, point_fields)

        self._each(
            {"xdmf": xdmf, "vtk": lambda: write_vtu(path(".vtu"), point_fields, cell_fields)}
        )

    def write_step(
        self,
        t: float,
        point_fields: Sequence[fem.Function],
        cell_fields: Sequence[fem.Function] = (),
        field_data: dict | None = None,
        boundary: Boundary | None = None,
    ) -> None:
        """Step ``<name>_KKK`` of the series ``<name>.xdmf`` / ``<name>.pvd`` with time value
        ``t`` (``field_data``: numbers the .vtu carries as VTK field data); with the scene's
        ``boundary``, also step ``contact_surface_KKK`` of ``contact_surface.xdmf``."""

        def xdmf() -> None:
            self._xdmf.write(t, point_fields, cell_fields)
            if boundary is not None and has_surface(boundary, self.comm):
                self._surface.write_step(t, boundary, point_fields)

        self._each(
            {
                "xdmf": xdmf,
                "vtk": lambda: self._vtk.write(t, point_fields, cell_fields, field_data),
            }
        )

    def _each(self, writers: dict) -> None:
        for fmt in self.formats:
            start = time.perf_counter()
            writers[fmt]()
            self.seconds[fmt] += time.perf_counter() - start

    def timings(self) -> dict[str, float]:
        """``{"time_output_xdmf": s, "time_output_vtk": s}`` of the formats written."""
        return {f"time_output_{f}": round(s, 4) for f, s in self.seconds.items()}
