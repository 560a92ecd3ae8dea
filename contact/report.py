"""The output folder of one run: XDMF, summary.json, history.csv, solution.png."""
from __future__ import annotations

import platform
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from . import io, plots
from .adapt import AdaptResult, Level
from .errors import energy_error
from .scene import Scene
from .solvers import Result


def resultants(scene: Scene, result: Result) -> dict | None:
    """Contact resultants and Hertz values of an elasticity run (None for scalar models)."""
    if scene.cfg["model"]["type"] != "elasticity":
        return None
    from .hertz import contact_resultants

    return contact_resultants(scene, result)


def active_measure(result: Result) -> float:
    """The measure of the discrete contact (active) set,

        |A_h| = Σ_{i ∈ A} w_i,    w_i = ∫ φ_i  (the lumped weights of the constraint set),

    summed over the owned constrained nodes of every MPI rank, with A the active nodes by
    the solver's rule (``result.active_mask``).  w_i is integrated over Ω for obstacle
    scenes, so |A_h| is an area in 2D (m², a volume in 3D), and over Γ_C for Signorini and
    elasticity scenes, so it is a length in 2D (m, an area in 3D) — of the modelled part
    only when symmetry planes cut the body.  With every constrained node active it is
    |Ω| (obstacle) or |Γ_C| (Signorini) less the weight of the nodes on the closure of
    Γ_D, which carry no constraint.  For a contact disc of radius a, sqrt(|A_h|/π) ≈ a."""
    con = result.problem.constraint
    local = float(np.sum(con.w[result.active_mask]))
    return result.u_h.function_space.mesh.comm.allreduce(local, op=MPI.SUM)


def summary(scene: Scene, result: Result, wall: float | None = None, res: dict | None = None) -> dict[str, Any]:
    """The run's figures: sizes, solver outcome, the contact set (``active_nodes``, and
    ``active_measure`` from :func:`active_measure`: m² for obstacle scenes, m for 2D
    Signorini / elasticity), timings (seconds), errors if known, and the contact
    resultants ``res`` of an elasticity run."""
    con = result.problem.constraint
    comm = scene.comm
    out = {
        "scene": scene.name,
        "model": scene.cfg["model"]["type"],
        "method": result.method,
        "dofs": result.dofs,
        "cells": scene.mesh.topology.index_map(scene.mesh.topology.dim).size_global,
        "degree": result.problem.V.element.basix_element.degree,
        "mpi_ranks": comm.size,
        "converged": result.converged,
        "reason": result.reason,
        "newton_iterations": result.iterations,
        "polish_solves": result.polish_solves,
        "linear_solves": result.linear_solves,
        "final_residual": result.residual,
        "constrained_nodes": con.global_size(comm),
        "active_nodes": result.n_active,
        "active_measure": active_measure(result),
        "c": result.options.get("c"),
        "line_search": result.options.get("line_search"),
        "time_assembly": result.timings["assembly"],
        "time_linear_solve": result.timings["solve"],
        "time_other": result.timings["other"],
        "time_total": wall if wall is not None else result.timings["total"],
        "host": platform.node(),
    }
    if res is not None:
        out.update({k: v for k, v in res.items() if k != "pressure_profile"})
    exact = scene.cfg["data"]["exact"]
    if exact is not None:
        out["error_energy"] = energy_error(result.u_h, exact, result.problem.data["k"], scene.cfg["constants"])
    return out


def write_run(outdir: str | Path, scene: Scene, result: Result, wall: float | None = None) -> dict:
    """Write the complete output folder atomically; return the summary."""
    comm = scene.comm
    res = resultants(scene, result)
    info = summary(scene, result, wall, res)
    out_cfg = scene.cfg["output"]
    with io.atomic_folder(outdir, comm) as tmp:
        if out_cfg["xdmf"]:
            io.write_xdmf(tmp / "solution.xdmf", [result.u_h, result.lmbda_h, result.gap, result.active],
                          cells=cell_fields(scene, result))
        io.write_csv(tmp / "history.csv", result.history, comm)
        if out_cfg["png"]:
            plots.plot_solution(tmp / "solution.png", result.u_h, result.active,
                                title=f"{scene.name}: u_h ({result.method}, {result.dofs} DoFs)")
            write_pressure_plot(tmp / "pressure.png", scene, result, res)
        io.write_json(tmp / "summary.json", info, comm)
    return info


def cell_fields(scene: Scene, result: Result) -> list:
    """Cellwise output fields: the von Mises stress for elasticity."""
    if scene.cfg["model"]["type"] != "elasticity":
        return []
    from .models.elasticity import von_mises

    return [von_mises(result.u_h, result.problem.data["mu"], result.problem.data["lmbda_L"])]


def write_pressure_plot(path: Path, scene: Scene, result: Result, res: dict | None) -> None:
    """Elasticity: pressure.png, the computed contact pressure with the Hertz profile."""
    if res is not None and scene.comm.rank == 0:
        plots.plot_pressure(path, res, title=f"{scene.name}: contact pressure ({result.dofs} DoFs)")


def level_writer(tmp: Path, scene: Scene):
    """Callback for :func:`contact.adapt.adapt`: XDMF of level K (u_h, λ_h, active, η_T)."""
    def write(level: Level) -> None:
        r = level.result
        if scene.cfg["output"]["xdmf"]:
            io.write_xdmf(tmp / f"level_{level.index:03d}.xdmf", [r.u_h, r.lmbda_h, r.gap, r.active],
                          cells=[level.estimate.eta_T, *cell_fields(level.scene, r)])
    return write


def write_adaptive(tmp: Path, scene: Scene, adaptive: AdaptResult, wall: float | None = None,
                   failure: dict | None = None) -> dict:
    """After the loop: convergence.csv/.png, mesh pictures, and the final level's files.
    ``failure`` (a run that failed on the level after the last of ``adaptive``) is added
    to summary.json: ``converged: false``, ``failed_level``, ``failed_reason``."""
    comm = scene.comm
    rows = adaptive.rows
    io.write_csv(tmp / "convergence.csv", rows, comm)
    last = adaptive.levels[-1]
    res = resultants(last.scene, last.result)
    info = summary(last.scene, last.result, wall, res)
    info.update({"levels": len(rows), "stop": adaptive.stop, "eta": last.estimate.eta,
                 "strategy": (scene.cfg.get("adapt") or {}).get("strategy"), **(failure or {})})
    io.write_csv(tmp / "history.csv", last.result.history, comm)
    if scene.cfg["output"]["png"]:
        if comm.rank == 0:
            plots.plot_convergence(tmp / "convergence.png", rows, title=f"{scene.name}: adaptive convergence")
        for lv in picture_levels(adaptive, (scene.cfg.get("adapt") or {}).get("pictures", 3)):
            plots.plot_mesh(tmp / f"mesh_level_{lv.index}.png", lv.result.u_h,
                            title=f"{scene.name}: level {lv.index}, {lv.result.dofs} DoFs")
        plots.plot_solution(tmp / "solution.png", last.result.u_h, last.result.active,
                            title=f"{scene.name}: u_h on level {last.index} ({last.result.dofs} DoFs)")
        write_pressure_plot(tmp / "pressure.png", last.scene, last.result, res)
    io.write_json(tmp / "summary.json", info, comm)
    return info


def picture_levels(adaptive: AdaptResult, count: int) -> list[Level]:
    """``count`` levels spread from the first to the last."""
    n = len(adaptive.levels)
    if count <= 0 or n == 0:
        return []
    idx = sorted(set(int(round(i)) for i in np.linspace(0, n - 1, min(count, n))))
    return [adaptive.levels[i] for i in idx]
