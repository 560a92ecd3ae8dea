"""The output folder of one run.

A single solve writes the fields (u_h, λ_h, gap, active; von Mises for elasticity) in the
formats of ``output.formats`` (:mod:`contact.output.fields`: ``solution.xdmf`` + ``.h5``,
``solution.vtu``), ``summary.json``, ``history.csv``, ``solution.png`` and, for a contact
scene, ``contact.csv`` and ``pressure.png``.  An adaptive run writes the levels as the
series ``solution.xdmf`` over ``solution_KKK.xdmf`` + ``.h5`` and ``solution.pvd`` over
``solution_KKK.vtu`` (time value = level; η_T added as cell data), ``convergence.csv`` /
``.png``, ``mesh_level_K.png`` and the final level's ``solution.png``, ``contact.csv`` and
``pressure.png``; its ``history.csv`` lists the Newton iterations of every level (column
``level``).

The data files come first, the pictures after them (:func:`contact.output.plots.draw_in_turn`:
a picture that fails is one warning line, and ``summary.json``'s ``pictures`` says which
were written), ``summary.json`` last.
"""

from __future__ import annotations

import functools
import platform
import re
import warnings
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from mpi4py import MPI

from ..adaptivity.energy_error import solution_error
from ..drivers.adaptive import AdaptResult
from ..models.problem import active_weights
from ..post.comparison import Comparison
from ..post.contact_table import Table, contact_table, view_normal
from ..post.interface import resultants
from ..post.posed import Posed
from ..post.reference import compare
from ..post.resultants import current_pressure
from ..solvers import Result
from . import drawing, folder, plots
from .degree import output_fields
from .fields import FieldFiles
from .report import Report

if TYPE_CHECKING:
    from ..setup.run import SceneLevel as Level


def active_measure(result: Result) -> float:
    """The measure of the discrete contact (active) set,

        |A_h| = Σ_{i ∈ A} w_i,    w_i = ∫ φ_i  (the lumped weights of the constraint set),

    summed over the owned constrained nodes of every MPI rank, with A the active nodes by
    the solver's rule (``result.active_mask``).  w_i is integrated over Ω for obstacle
    scenes, so |A_h| is an area in 2D (m², a volume in 3D), and over Γ_C for Signorini and
    elasticity scenes, so it is a length in 2D (m, an area in 3D) — of the modelled part
    only when symmetry planes cut the body.  With every constrained node active it is
    |Ω| (obstacle) or |Γ_C| (Signorini) less the weight of the nodes on the closure of
    Γ_D, which carry no constraint.  For a contact disc of radius a, sqrt(|A_h|/π) ≈ a.
    A P2 obstacle problem counts each cell of Ω with the fraction of its edge midpoints that
    are active instead (:func:`~contact.models.problem.active_weights`: the vertices of a
    P2 contact zone are mostly free, lifted by O(h³))."""
    con = result.problem.constraint
    V = result.u_h.function_space
    w = con.w
    if con.in_domain and V.ufl_element().embedded_superdegree == 2:
        w = active_weights(V)[con.dofs]
    local = float(np.sum(w[result.active_mask]))
    return result.u_h.function_space.mesh.comm.allreduce(local, op=MPI.SUM)


NODES_ACROSS = 5  # fewer active nodes across the contact zone than this: a warning


def nodes_across(result: Result) -> float:
    """About how many nodes span the contact zone, from the n active nodes (× the symmetric
    copies the modelled part stands for): n when the zone is a curve (2D, on Γ_C), the
    diameter 2 √(n/π) of a disc of n nodes when it is a surface (3D on Γ_C, a 2D obstacle),
    (6n/π)^(1/3) for a volume (a 3D obstacle)."""
    p = result.problem
    n = result.n_active * p.symmetry.copies
    dim = p.V.mesh.topology.dim - (0 if p.constraint.in_domain else 1)
    return float({1: n, 2: 2 * np.sqrt(n / np.pi), 3: np.cbrt(6 * n / np.pi)}.get(dim, n))


def warn_coarse_zone(result: Result) -> None:
    """A one-line ContactWarning (rank 0) when the contact zone holds some but fewer than
    NODES_ACROSS nodes across: the pressure, and the forces and ratios from it, are then
    a mesh artefact (one node in contact can carry a sideways force of 10 % of the normal
    force)."""
    across = nodes_across(result)
    if 0 < across < NODES_ACROSS and _comm(result).rank == 0:
        from ..base.errors import ContactWarning

        warnings.warn(
            f"the contact zone holds {result.n_active} active node(s), about "
            f"{across:.1f} across: too few to resolve the contact pressure and the "
            "forces from it; refine the contact zone (mesh cells or h_contact, an adapt "
            f"section) to {NODES_ACROSS} or more nodes across",
            ContactWarning,
            stacklevel=2,
        )


def summary(
    report: Report,
    result: Result,
    wall: float | None = None,
    res: dict | None = None,
    comparison: Comparison | None = None,
    error: float | None = None,
    posed: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The run's figures: sizes, solver outcome, the contact set (``active_nodes``, and
    ``active_measure`` from :func:`active_measure`: m² for obstacle scenes, m for 2D
    Signorini / elasticity), the contact force, timings (seconds), errors if known, the
    untagged boundary and the exact solution's mismatches ``posed`` (``Posed.conditions``),
    the contact resultants ``res`` of an elasticity run and the values of a declared
    reference."""
    con = result.problem.constraint
    comm = _comm(result)
    msh = result.problem.V.mesh
    out = {
        "scene": report.name,
        "model": report.model,
        "method": result.method,
        "dofs": result.dofs,
        "cells": msh.topology.index_map(msh.topology.dim).size_global,
        "degree": result.problem.V.element.basix_element.degree,
        "mpi_ranks": comm.size,
        "converged": result.converged,
        "reason": result.reason,
        "newton_iterations": result.iterations,  # on the final mesh
        "polish_solves": result.polish_solves,
        "newton_iterations_coarse": result.coarse_iterations,  # grid sequencing's coarse levels
        "polish_solves_coarse": sum(lv.polish_solves for lv in result.sequence),
        "coarse_levels": len(result.sequence),
        "linear_solves": result.linear_solves,
        "final_residual": result.residual,
        "linear_solver": result.linear,
        "krylov_iterations": result.krylov_iterations,
        "sequence": [asdict(lv) for lv in result.sequence],
        "weighted_linear_solves": result.weighted_linear_solves,
        "constrained_nodes": con.global_size(comm),
        "active_nodes": result.n_active,
        "active_measure": active_measure(result),
        "contact_force": result.contact_force,
        "c": result.options.get("c"),
        "line_search": result.options.get("line_search"),
        "backtracked_steps": result.backtracked,
        "time_assembly": result.timings["assembly"],
        "time_linear_solve": result.timings["solve"],
        "time_other": result.timings["other"],
        "time_sequence": result.timings.get("coarse", 0.0),
        "time_total": wall if wall is not None else result.timings["total"],
        "host": platform.node(),
    }
    if result.sequence_note:
        out["sequence_note"] = result.sequence_note
    if unfaced(result):
        out["unfaced_note"] = UNFACED_NOTE
    out.update(result.figures)  # a baseline method's own
    out.update(posed or {})
    if res is not None:
        out.update(res)
    if comparison is not None and report.reference is not None:
        out["reference"] = report.reference
        out.update(comparison.values)
    # the adaptive loop's, if known
    error = solution_error(result.problem, result) if error is None else error
    if error is not None:
        out["error_energy"] = error
    return out


#: summary.json's note on a solve whose contact pairs have no slave node facing a master
UNFACED_NOTE = (
    "no slave node of the contact pairs faces a master surface within its search distance: "
    "no node is constrained, the gap field is undefined (NaN) at every node and the contact "
    "table has no rows"
)


def unfaced(result: Result) -> bool:
    """Whether ``result``'s contact pairs constrain no node on any rank (collective): on a
    current configuration a slave node facing no master facet is out of contact
    (:func:`contact.models.mortar.couple`), e.g. a self-contact pair whose faces have not
    turned towards each other.  Its gap (NaN off the constrained nodes) is then undefined
    everywhere and contact.csv has its header only, which summary.json notes."""
    p = result.problem
    return bool(p.data.couplings) and p.constraint.global_size(_comm(result)) == 0


def point_fields(result: Result) -> list:
    """The nodal output fields: u_h, λ_h, the gap (on Γ_C only) and the active set; with
    contact pairs also the pressure the master surfaces see (``lambda_master``); for a
    finite-strain body the contact pressure per deformed area (``pressure_current``,
    :func:`contact.post.resultants.current_pressure`; λ_h is per reference area)."""
    fields = [result.u_h, result.lmbda_h, result.gap, result.active]
    current = current_pressure(result)
    if current is not None:  # a finite-strain body: the pressure per deformed area
        fields.append(result.problem.nodal_output("pressure_current", current))
    if result.problem.data.couplings:
        from ..models.mortar import master_pressure

        fields.append(master_pressure(result))
    return fields


def cell_fields(result: Result, elastic: bool) -> list:
    """Cellwise output fields: the von Mises stress for elasticity (of the Cauchy stress
    for a hyperelastic body), and the ``body`` number of each cell in a scene with bodies."""
    if not elastic:
        return []
    from ..models.elasticity import von_mises

    data = result.problem.data
    return [von_mises(result.u_h, data.mu, data.lmbda_L, data.stresses)] + (
        [data.body] if data.body is not None else []
    )


def solution_picture(
    path: Path, result: Result, title: str, normal: np.ndarray | None
) -> plots.Picture:
    """solution.png: u_h with the active set (3D: and the contact zone with λ_h, seen along
    ``normal``, :func:`contact.post.contact_table.view_normal`)."""
    return plots.solution_picture(
        path, result.u_h, result.active, title=title, lmbda=result.lmbda_h, normal=normal
    )


def write_contact(out: Path, table: Table | None, comm: MPI.Comm) -> None:
    """``contact.csv``, the rows ``table`` of :func:`contact.post.contact_table.contact_table`
    (gathered on rank 0, None on the others; collective)."""
    folder.table_file(out / "contact.csv", table, comm)


def pressure_picture(
    out: Path, report: Report, result: Result, comparison: Comparison | None, table: Table | None
) -> list[plots.Picture]:
    """``pressure.png`` along a contact boundary Γ_C (not for an obstacle in Ω), drawn by
    rank 0 from ``table``: a list of one picture, or none."""
    if not report.png or result.problem.constraint.in_domain:
        return []
    path = out / "pressure.png"
    title = f"{report.name}: along Γ_C ({result.dofs} DoFs, {result.n_active} active nodes)"
    value = "lambda_n" if report.elastic else "lambda"  # the table's column

    # rank 0 holds the table: it draws the picture
    draw = functools.partial(
        drawing.pressure_chart,
        path=path,
        table=table,
        value=value,
        comparison=comparison,
        title=title,
    )
    return [plots.Picture([], draw, path, root=True)]


def write_run(
    outdir: str | Path,
    report: Report,
    posed: Posed,
    result: Result,
    wall: float | None = None,
    label: str | None = None,
) -> dict:
    """Write the complete output folder of ``report`` atomically (``label``: the option that
    chose it, for messages; ``posed``: what was solved, for its figures); return the summary
    (with ``files`` and, with pictures, ``pictures``).  The data files are written first,
    the pictures after them, summary.json last."""
    comm = _comm(result)
    res = resultants(posed, result)
    comparison = compare(posed, result)
    info = summary(report, result, wall, res, comparison, posed=posed.conditions())
    warn_coarse_zone(result)
    with folder.atomic_folder(outdir, comm, label) as tmp:
        files = FieldFiles(tmp, "solution", report.formats, comm, report.elastic)
        files.write_one(point_fields(result), cell_fields(result, report.elastic), posed.boundary)
        info.update(files.timings())
        folder.csv_file(tmp / "history.csv", result.history, comm)
        table = contact_table(posed, result)
        write_contact(tmp, table, comm)
        if report.png:
            title = f"{report.name}: u_h ({result.method}, {result.dofs} DoFs)"
            pictures = [
                solution_picture(tmp / "solution.png", result, title, view_normal(posed, result)),
                *pressure_picture(tmp, report, result, comparison, table),
            ]
            info["pictures"] = plots.draw_in_turn(pictures, comm)
        write_summary(tmp, info, comm)
    return info


def _comm(result: Result) -> MPI.Comm:
    """The communicator of a result's mesh (its solve's ranks)."""
    return result.problem.V.mesh.comm


def write_summary(tmp: Path, info: dict, comm: MPI.Comm) -> None:
    """Write summary.json, listing every file of the folder (itself included)."""
    names = [p.name for p in tmp.iterdir()] if comm.rank == 0 else None
    natural = lambda name: [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]  # noqa: E731
    info["files"] = sorted(set(comm.bcast(names, root=0)) | {"summary.json"}, key=natural)
    folder.json_file(tmp / "summary.json", info, comm)


def files_text(names: list[str]) -> str:
    """File names for one line: a numbered run ``x_000.vtu … x_011.vtu`` is shown as
    ``x_000…011.vtu``."""
    runs: dict[tuple[str, str], list[str]] = {}
    out: list[str] = []
    for name in names:
        m = re.fullmatch(r"(.*_)(\d{3,})(\.\w+)", name)
        if m:
            key = (m.group(1), m.group(3))
            if key not in runs:
                out.append(f"\0{len(runs)}")
                runs[key] = []
            runs[key].append(m.group(2))
        else:
            out.append(name)
    keys = list(runs)
    text = []
    for item in out:
        if item.startswith("\0"):
            (stem, ext) = keys[int(item[1:])]
            nums = runs[(stem, ext)]
            text.append(
                f"{stem}{nums[0]}{ext}" if len(nums) == 1 else f"{stem}{nums[0]}…{nums[-1]}{ext}"
            )
        else:
            text.append(item)
    return ", ".join(text)


class LevelWriter:
    """Callback for :func:`contact.drivers.adaptive.adapt`: level K as step K of the series
    ``solution.xdmf`` / ``solution.pvd`` (u_h, λ_h, gap, active, η_T, the elastic cell
    fields, and an hp level's ``degree``); ``files`` keeps the seconds per format."""

    def __init__(self, tmp: Path, report: Report, comm: MPI.Comm):
        self.elastic = report.elastic
        self.files = FieldFiles(tmp, "solution", report.formats, comm, report.elastic)

    def __call__(self, level: Level) -> None:
        r = level.result
        est = level.estimate
        cells = cell_fields(r, self.elastic)
        if est.eta_T is not None:  # estimated: not the last level of estimate_last false
            cells.insert(0, est.eta_T)
        points = point_fields(r)
        space = getattr(level, "space", None)  # an hp level's degrees
        if space is not None:
            cells.append(space.degree_function())  # p_T: the hp mesh in ParaView
            points = output_fields(points)  # P_{p_max} → the degree the formats carry
        self.files.write_step(
            level.index,
            points,
            cells,
            field_data={
                "level": level.index,
                "dofs": r.dofs,
                **({"eta": est.eta} if est.computed else {}),
            },
            boundary=level.posed.boundary,
        )


def level_writer(tmp: Path, report: Report, comm: MPI.Comm) -> LevelWriter:
    return LevelWriter(tmp, report, comm)


def write_adaptive(
    tmp: Path,
    report: Report,
    adaptive: AdaptResult,
    wall: float | None = None,
    failure: dict | None = None,
    files: FieldFiles | None = None,
) -> dict:
    """After the loop: convergence.csv/.png, history.csv of every level, mesh pictures, and
    the final level's summary, solution.png, contact.csv and pressure.png.  ``failure`` (a
    run that failed on the level after the last of ``adaptive``) is added to summary.json:
    ``converged: false``, ``failed_level``, ``failed_reason``; ``files`` (the levels' field
    files) adds the seconds each format took."""
    last = adaptive.levels[-1]
    comm = _comm(last.result)
    rows = adaptive.rows
    folder.csv_file(tmp / "convergence.csv", rows, comm)
    png = report.png
    shown = picture_levels(adaptive, report.pictures)
    # the final level's figures and the pictures' view directions (contact.post, collective)
    # first, then the files
    posed = last.posed
    res = resultants(posed, last.result)
    comparison = compare(posed, last.result)
    table = contact_table(posed, last.result)
    normals: dict[int, np.ndarray | None] = {}
    if png:
        for lv in (last, *shown):
            normals[lv.index] = view_normal(lv.posed, lv.result)
    info = summary(report, last.result, wall, res, comparison, last.error, posed.conditions())
    if failure is None:  # a failed run's last line is its error
        warn_coarse_zone(last.result)
    info.update(
        {
            "levels": len(rows),
            "stop": adaptive.stop,
            "eta": last.eta,  # None where not estimated (adapt.estimate_last false)
            "strategy": report.strategy,
            "dofs_per_level": [lv.result.dofs for lv in adaptive.levels],
            # time to accuracy: the loop's wall seconds up to level k (outputs not counted)
            # and the energy error (None without data.exact) and η reached there
            "seconds_to_error": [round(lv.elapsed, 4) for lv in adaptive.levels],
            # … and up to its solution and error only (a loop that stops there on a level
            # budget needs no estimate of its last level)
            "seconds_to_solution": [round(lv.solved_elapsed, 4) for lv in adaptive.levels],
            "error_per_level": [lv.error for lv in adaptive.levels],
            "eta_per_level": [lv.eta for lv in adaptive.levels],
            "newton_iterations_per_level": [lv.result.iterations for lv in adaptive.levels],
            "polish_solves_per_level": [lv.result.polish_solves for lv in adaptive.levels],
            "newton_iterations_total": sum(lv.result.iterations for lv in adaptive.levels),
            "polish_solves_total": sum(lv.result.polish_solves for lv in adaptive.levels),
            **_components(adaptive),
            **(files.timings() if files else {}),
            **(failure or {}),
        }
    )
    folder.csv_file(
        tmp / "history.csv",
        [{"level": lv.index, **h} for lv in adaptive.levels for h in lv.result.history],
        comm,
    )
    write_contact(tmp, table, comm)
    if png:
        # the largest first, drawn comm.size at a time (on 2 ranks the final solution and mesh
        # together), the convergence chart last: on 2 ranks beside the first level's mesh;
        # pressure.png (its table is on rank 0) by rank 0
        pictures = [
            solution_picture(
                tmp / "solution.png",
                last.result,
                f"{report.name}: u_h on level {last.index} ({last.result.dofs} DoFs)",
                normals[last.index],
            )
        ]
        for lv in reversed(shown):
            pictures.append(
                plots.mesh_picture(
                    tmp / f"mesh_level_{lv.index}.png",
                    lv.result.u_h,
                    title=f"{report.name}: level {lv.index}, {lv.result.dofs} DoFs",
                    normal=normals[lv.index],
                    active=lv.result.active,
                )
            )
        title = f"{report.name}: adaptive convergence"
        chart = tmp / "convergence.png"
        pictures.append(
            plots.Picture(
                [],
                functools.partial(drawing.convergence_chart, path=chart, rows=rows, title=title),
                chart,
            )
        )
        pictures += pressure_picture(tmp, report, last.result, comparison, table)
        info["pictures"] = plots.draw_in_turn(pictures, comm)
    write_summary(tmp, info, comm)
    return info


def _components(adaptive: AdaptResult) -> dict:
    """The error components and the Krylov iterations per level (Level.errors): lists, with
    None where a component is not defined (fixed stopping: η_lin, η_alg)."""
    rows = [lv.errors() for lv in adaptive.levels]
    out = {
        "stopping": rows[-1]["stopping"],
        "krylov_iterations_total": sum(r["krylov_iterations"] for r in rows),
    }
    for key in ("eta_disc", "eta_lin", "eta_alg", "krylov_iterations"):
        out[f"{key}_per_level"] = [None if r[key] == "" else r[key] for r in rows]
    return out


def picture_levels(adaptive: AdaptResult, count: int) -> list[Level]:
    """``count`` levels spread from the first to the last."""
    n = len(adaptive.levels)
    if count <= 0 or n == 0:
        return []
    idx = sorted(set(int(round(i)) for i in np.linspace(0, n - 1, min(count, n))))
    return [adaptive.levels[i] for i in idx]
