"""The field files of a run, in the formats of ``output.formats``.

* ``xdmf`` (:mod:`contact.output.xdmf`): ``solution.xdmf`` + ``solution.h5``, written in parallel;
  a series is ``solution.xdmf`` (a temporal collection) over ``solution_KKK.xdmf`` + ``.h5``;
* ``vtk`` (:mod:`contact.output.vtk`): ``solution.vtu``; a series is ``solution.pvd`` over
  ``solution_KKK.vtu``.

:class:`FieldFiles` writes one step or a series in every chosen format and keeps the
seconds each format took (``seconds``), which go to summary.json as ``time_output_xdmf``
and ``time_output_vtk``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from dolfinx import fem
from mpi4py import MPI

from .vtk import Series, write_vtu
from .xdmf import XdmfSeries, write_xdmf

FORMATS = ("xdmf", "vtk")


class FieldFiles:
    """The fields of ``<folder>/<name>.*`` in ``formats`` (collective): :meth:`write_one`
    for one solve, :meth:`write_step` for step after step of a series (time value t: the
    level, the load step's pseudo-time)."""

    def __init__(
        self, folder: str | Path, name: str, formats: Sequence[str], comm: MPI.Comm = MPI.COMM_WORLD
    ):
        self.folder, self.name, self.comm = Path(folder), name, comm
        self.formats = [f for f in FORMATS if f in formats]
        self.seconds = {f: 0.0 for f in self.formats}
        self._xdmf, self._vtk = XdmfSeries(folder, name, comm), Series(folder, name, comm)

    def write_one(
        self, point_fields: Sequence[fem.Function], cell_fields: Sequence[fem.Function] = ()
    ) -> None:
        """``<name>.xdmf`` (+ .h5) and ``<name>.vtu``."""
        path = (self.folder / self.name).with_suffix
        self._each(
            {
                "xdmf": lambda: write_xdmf(path(".xdmf"), point_fields, cell_fields),
                "vtk": lambda: write_vtu(path(".vtu"), point_fields, cell_fields),
            }
        )

    def write_step(
        self,
        t: float,
        point_fields: Sequence[fem.Function],
        cell_fields: Sequence[fem.Function] = (),
        field_data: dict | None = None,
    ) -> None:
        """Step ``<name>_KKK`` of the series ``<name>.xdmf`` / ``<name>.pvd`` with time value
        ``t`` (``field_data``: numbers the .vtu carries as VTK field data)."""
        self._each(
            {
                "xdmf": lambda: self._xdmf.write(t, point_fields, cell_fields),
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
