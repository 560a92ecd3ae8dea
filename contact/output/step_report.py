"""The output folder of a load path (``load:``) or a frictional run, step by step.

Per step k (numbered 000, 001, …):

* ``solution_00k.xdmf`` + ``.h5`` and ``solution_00k.vtu`` in the series ``solution.xdmf``
  and ``solution.pvd`` (the formats of ``output.formats``; time value t_k; each step may
  have its own mesh) — u_h, λ_n (``lambda_h``), the gap, the active set and, with friction,
  λ_t and the slip increment (vectors), the status (0 separated, 1 stick, 2 slip, −1 off
  Γ_C) and the friction bound ρ; cellwise the von Mises stress (and η_T after an adaptive step);
* ``contact_step_00k.csv`` — one row per contact node along Γ_C (:mod:`contact.post.contact_table`
  with its friction columns: s or r, λ_n, λ_t, gap, slip, bound, status).

After the last step: ``steps.csv`` (one row per step: t, DoFs, Newton iterations, the
resultants and zone measures of :func:`contact.post.friction_resultants.surface_figures`,
η; a finite-strain body's peak pressures, nominal and per deformed area; the columns
``obstacle_approach`` and ``prescribed_displacement`` of the force–displacement curve),
``history.csv`` (every step's Newton iterations, with a ``load_step`` column), when steps
ran the adaptive loop ``convergence.csv`` (one row per level, with its step), and
``contact.csv`` of the last step (:func:`contact.output.run_report.write_contact`); then
the pictures — ``traction.png`` (λ_n and λ_t along Γ_C at up to :data:`TRACTION_CURVES`
steps, with the declared reference's or the exact solution's curves), ``solution.png``,
``force.png`` (the force–displacement curve, :func:`plot_load_curve`) and ``pressure.png``
of the last step —, a picture that fails costing a warning; ``summary.json`` (the run,
with the same figures per step under ``steps`` and the pictures' outcome) last.

The figures of the steps go to hidden JSON-lines files of the folder as the steps finish
(:class:`contact.output.folder.RowLog`), read back at the end: nothing kept in memory
grows with the number of steps.
"""

from __future__ import annotations

import platform
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from mpi4py import MPI

from ..adaptivity.estimate import estimate
from ..drivers.load_path import LoadPath
from ..post.contact_table import Table, contact_table, view_normal
from ..post.friction_resultants import surface_figures
from ..post.reference import compare
from ..post.resultants import pressure_peaks
from ..post.traction_curves import first_contact, reference_curves
from . import folder, plots
from .fields import FieldFiles
from .report import Report
from .run_report import (
    UNFACED_NOTE,
    cell_fields,
    point_fields,
    pressure_picture,
    solution_picture,
    unfaced,
    warn_coarse_zone,
    write_contact,
    write_summary,
)

if TYPE_CHECKING:
    from ..setup.run import SceneStep as Step

#: the most load steps traction.png draws a curve of (evenly spread, first and last included)
TRACTION_CURVES = 25


class StepWriter:
    """``on_step`` callback of :func:`contact.drivers.load_path.run_load_path`: writes a
    step's files into ``tmp`` and appends its figures to the run's tables (hidden JSON-lines
    files of the folder, :class:`contact.output.folder.RowLog`), so that nothing it keeps in
    memory grows with the steps; :meth:`finish` writes the run's files from them."""

    def __init__(self, tmp: Path, report: Report, comm: MPI.Comm):
        self.tmp, self.report, self.comm = tmp, report, comm
        self.files = FieldFiles(tmp, "solution", report.formats, comm, report.elastic)
        self.rows = folder.RowLog(tmp / ".steps.jsonl", comm)
        self.levels = folder.RowLog(tmp / ".levels.jsonl", comm)
        self.history = folder.RowLog(tmp / ".history.jsonl", comm)
        self.iterations = [0, 0]  # the Newton iterations of the converged steps: sum, largest
        self.unfaced: list[int] = []  # the steps whose pairs constrain no node (run_report)

    def __call__(self, step: Step) -> None:
        r, posed, k = step.result, step.posed, step.index
        # `load_step` beside the Newton rows' own `step` (the step length, as in one solve's
        # history.csv): {"step": k, **h} let the step length overwrite the load step's index
        self.history.add([{"load_step": k, **h} for h in r.history])
        if not r.converged:
            return
        from ..post.load_curve import load_displacements

        est = (
            step.levels[-1].estimate
            if step.levels
            else estimate(r.problem, r, self.report.estimator)
        )
        row = {
            "step": k,
            "time": step.time,
            "dofs": r.dofs,
            "newton_iterations": r.iterations,
            "converged": r.converged,
            "reason": r.reason,
            "eta": est.eta if est.computed else "",  # adapt.estimate_last false: none
            "seconds": round(step.seconds, 4),
        }
        table = contact_table(posed, r)
        if r.friction is not None:
            if "fixed_point_iterations" in r.friction:
                row["fixed_point_iterations"] = r.friction["fixed_point_iterations"]
            row.update(surface_figures(posed, r, table))
        else:
            row["contact_force"] = r.contact_force
        row.update(pressure_peaks(r))  # a finite-strain body: nominal and per deformed area
        row.update(load_displacements(posed, r))  # the force–displacement curve
        if step.negative_eigenvalues is not None:  # hyperelastic: K_T's stability
            from ..solvers.energy_search import tangent_figures

            row["tangent_negative_eigenvalues"] = step.negative_eigenvalues
            row["min_det_F"] = step.min_det_F
            row.update(tangent_figures(r.tangent_log))
        self.rows.add([row])
        if unfaced(r):
            self.unfaced.append(k)
        self.iterations = [self.iterations[0] + r.iterations, max(self.iterations[1], r.iterations)]
        self.levels.add([{"step": k, "time": step.time, **lv.row()} for lv in step.levels])
        folder.table_file(self.tmp / table_name(k), table, self.comm)
        if self.files.formats:
            nodal = point_fields(r)
            if r.friction is not None:
                from ..solvers.friction import surface_functions

                nodal += surface_functions(r)
            cells = cell_fields(r, self.report.elastic)
            if step.levels and est.eta_T is not None:  # the last level estimated
                cells.append(est.eta_T)
            self.files.write_step(
                step.time, nodal, cells, {"step": k, "dofs": r.dofs}, posed.boundary
            )

    def finish(
        self, path: LoadPath, wall: float | None = None, failure: dict | None = None
    ) -> dict[str, Any]:
        """The run's files after the last (converged) step; ``failure`` (``converged:
        false``, the failed step) goes into summary.json.  The data files come first, the
        pictures after them (a picture that fails is a warning, ``pictures`` in
        summary.json), summary.json last.  Returns the summary."""
        tmp, comm, report = self.tmp, self.comm, self.report
        last = path.steps[-1]
        r = last.result
        self.rows.write_csv(tmp / "steps.csv", _flat)
        self.history.write_csv(tmp / "history.csv")
        if self.levels.count:
            self.levels.write_csv(tmp / "convergence.csv")
        posed = last.posed
        comparison = compare(posed, r)
        if failure is None:  # a failed run's last line is its error
            warn_coarse_zone(r)
        table = contact_table(posed, r)
        write_contact(tmp, table, comm)
        friction = report.friction
        rows = list(self.rows.rows()) if comm.rank == 0 else []  # rank 0 writes summary.json
        info: dict[str, Any] = {
            "scene": report.name,
            "model": report.model,
            "method": r.method,
            "friction": friction,
            "steps_total": path.count,
            "stop": path.stop,
            "dofs": r.dofs,
            "mpi_ranks": comm.size,
            "converged": path.converged,
            "newton_iterations": self.iterations[0],
            "newton_iterations_max_per_step": self.iterations[1],
            "time_total": wall if wall is not None else sum(s.seconds for s in path.steps),
            "host": platform.node(),
            **self.files.timings(),
            **posed.conditions(),
            "steps": rows,
        }
        if self.unfaced:  # steps with an undefined gap and contact tables without rows
            info["unfaced_steps"] = self.unfaced
            info["unfaced_note"] = UNFACED_NOTE
        if path.cuts:  # step cutting (load.cuts): the steps that were halved
            info["step_cuts"] = path.cuts
        if path.indefinite:
            info["tangent_indefinite"] = path.indefinite
        if path.inverted:
            info["inverted"] = path.inverted
        if path.tangent_events:  # what the energy search did, per step (one line each)
            info["tangent_events"] = path.tangent_events
        if path.bifurcation:  # no stable state found: the equilibrium branch followed
            info["bifurcation"] = path.bifurcation
            info["equilibrium_branch"] = [
                {"step": k, "time": t, "negative_eigenvalues": n} for k, t, n in path.branch_steps
            ]
        if report.tangential_form is not None and friction != "none":
            info["tangential_form"] = report.tangential_form
        if report.elastic:  # the forces are of the whole body
            info["symmetric_copies"] = r.problem.symmetry.copies
        info.update(failure or {})
        if comparison is not None and report.reference is not None:
            info["reference"] = report.reference
            info.update(comparison.values)
        if report.png:
            origin, t0 = first_contact(posed, r)
            normal = view_normal(posed, r)
            name, dofs = report.name, r.dofs

            def traction(_) -> None:  # rank 0: the tables of the steps drawn, read back
                plots.plot_traction(
                    tmp / "traction.png",
                    self.traction_tables(rows),
                    title=f"{name}: contact tractions ({dofs} DoFs)",
                    references=reference_curves(posed, table, comparison, origin, t0),
                )

            pictures = [
                *(
                    []
                    if r.problem.constraint.in_domain  # an obstacle in Ω: no contact boundary
                    else [plots.Picture([], traction, tmp / "traction.png", root=True)]
                ),
                solution_picture(
                    tmp / "solution.png",
                    r,
                    f"{name}: u_h at t = {last.time:g} ({dofs} DoFs)",
                    normal,
                ),
                plots.Picture(
                    [],
                    lambda _: plot_load_curve(tmp / "force.png", rows, name, dofs),
                    tmp / "force.png",
                    root=True,
                ),
                *pressure_picture(tmp, report, r, comparison, table),
            ]
            info["pictures"] = plots.draw_in_turn(pictures, comm)
        for log in (self.rows, self.levels, self.history):
            log.remove()
        write_summary(tmp, info, comm)
        return info

    def traction_tables(self, rows: list[dict[str, Any]]) -> list[tuple[float, Table]]:
        """(t, contact table) of at most :data:`TRACTION_CURVES` steps, evenly spread from the
        first to the last (rank 0: read back from the steps' contact_step_KKK.csv)."""
        picked = sorted({int(round(i)) for i in np.linspace(0, len(rows) - 1, TRACTION_CURVES)})
        out = []
        for i in picked if rows else []:
            file = self.tmp / table_name(rows[i]["step"])
            if file.exists():
                out.append((rows[i]["time"], folder.read_table(file)))
        return out


def table_name(step: int) -> str:
    """The contact table of load step ``step`` (1, 2, …): contact_step_000.csv, …"""
    return f"contact_step_{step - 1:03d}.csv"


def plot_load_curve(path: Path, rows: list[dict[str, Any]], name: str, dofs: int) -> None:
    """force.png: the contact force of each step against the obstacle's approach if the
    obstacle moves along one direction, else the prescribed displacement if there is one,
    else the pseudo-time (:mod:`contact.post.load_curve`; an obstacle whose translation
    turns — pressed in, then dragged along the body — is drawn against the pseudo-time);
    steps where the energy search met an indefinite tangent, and unstable solutions,
    marked.  With friction the normal force −Σ w λ_n and the magnitude of the tangential
    (friction) force, each a curve."""
    axes: tuple[tuple[str, str], ...] = (
        ("obstacle_approach", "obstacle's approach (displacement towards the body)"),
        ("prescribed_displacement", "largest prescribed displacement |u_D|"),
        ("time", "pseudo-time t"),
    )
    if translation_turns(rows):
        axes = axes[2:]
    key, label = next(
        (k, lb)
        for k, lb in axes
        if k == "time" or np.ptp([0.0, *(row.get(k, 0.0) for row in rows)]) > 0
    )
    plots.plot_force_displacement(
        path,
        [row[key] for row in rows],
        load_forces(rows),
        label,
        title=f"{name}: force–displacement ({dofs} DoFs)",
        indefinite=[row.get("indefinite_newton_steps", 0) > 0 for row in rows],
        unstable=[row.get("tangent_negative_eigenvalues", 0) > 0 for row in rows],
    )


def translation_turns(rows: list[dict[str, Any]]) -> bool:
    """Whether the obstacle's translations (``obstacle_translation`` of the rows) point in
    more than one direction (to 1e-9)."""
    moves = np.array([row.get("obstacle_translation") or [0.0] for row in rows], dtype=float)
    lengths = np.linalg.norm(moves, axis=1)
    moves = moves[lengths > 1e-12 * max(float(np.max(lengths, initial=0.0)), 1e-300)]
    if len(moves) < 2:
        return False
    directions = moves / np.linalg.norm(moves, axis=1)[:, None]
    return bool(np.any(directions @ directions[0] < 1.0 - 1e-9))


def load_forces(rows: list[dict[str, Any]]) -> dict[str, list[float]]:
    """The forces of the force–displacement curve, by label, one value per step: with
    friction the normal force (−Σ w λ_n: the pressure's resultant, ≥ 0 in contact) and
    |tangential force|; otherwise ``contact_force`` (its magnitude if it is a vector)."""
    if rows and "normal_force" in rows[0]:
        return {
            "normal force (pressure resultant)": [-float(row["normal_force"]) for row in rows],
            "|tangential force| (friction)": [
                float(np.linalg.norm(row["tangential_force"])) for row in rows
            ],
        }
    return {
        "contact force": [
            float(np.linalg.norm(f)) if np.ndim(f) else float(f)
            for f in (row["contact_force"] for row in rows)
        ]
    }


def _flat(row: dict[str, Any]) -> dict[str, Any]:
    """A CSV row: vectors as one column per component (``contact_force_x`` …)."""
    out = {}
    for key, value in row.items():
        if isinstance(value, list):
            named = key.endswith(("force", "translation"))
            names = "xyz" if named else [str(i) for i in range(len(value))]
            out.update({f"{key}_{names[i]}": v for i, v in enumerate(value)})
        else:
            out[key] = value
    return out
