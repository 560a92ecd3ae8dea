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
η; a finite-strain body's peak pressures, nominal and per deformed area),
``summary.json`` (the run, with the same figures per step under ``steps``),
``contact.csv`` and ``pressure.png`` of the last step
(:func:`contact.output.run_report.write_contact`), for a hyperelastic body ``force.png``
(the force–displacement curve, :func:`plot_load_curve`; steps.csv holds its columns
``obstacle_approach`` and ``prescribed_displacement``), ``traction.png`` (λ_n and λ_t along Γ_C
at every step, with the declared reference's or the exact solution's curves),
``solution.png``, ``history.csv`` (every step's Newton iterations, with a ``load_step``
column) and, when steps ran the
adaptive loop, ``convergence.csv`` (one row per level, with its step).
"""

from __future__ import annotations

import platform
from pathlib import Path
from typing import Any

import numpy as np

from ..adaptivity.estimate import estimate
from ..drivers.load_path import LoadPath, Step
from ..post.contact_table import Table, contact_table, tangent_2d
from ..post.friction_resultants import surface_figures
from ..post.reference import compare
from ..post.resultants import pressure_peaks
from ..setup.scene import Scene
from . import folder, plots
from .fields import FieldFiles
from .run_report import (
    _finish,
    cell_fields,
    plot_solution,
    point_fields,
    posed_problem,
    warn_coarse_zone,
    write_contact,
)


class StepWriter:
    """``on_step`` callback of :func:`contact.drivers.load_path.run_load_path`: writes a
    step's files into ``tmp`` and keeps its figures for :meth:`finish`."""

    def __init__(self, tmp: Path, scene: Scene):
        self.tmp, self.scene = tmp, scene
        formats, elastic = scene.config.output.formats, scene.config.elastic
        self.files = FieldFiles(tmp, "solution", formats, scene.comm, elastic)
        self.rows: list[dict[str, Any]] = []
        self.tables: list[tuple[float, Table | None]] = []  # the tables on rank 0
        self.levels: list[dict[str, Any]] = []
        self.history: list[dict[str, Any]] = []

    def __call__(self, step: Step) -> None:
        r, scene, k = step.result, step.scene, step.index
        # `load_step` beside the Newton rows' own `step` (the step length, as in one solve's
        # history.csv): {"step": k, **h} let the step length overwrite the load step's index
        self.history += [{"load_step": k, **h} for h in r.history]
        if not r.converged:
            return
        est = step.levels[-1].estimate if step.levels else estimate(scene, r)
        row = {
            "step": k,
            "time": step.time,
            "dofs": r.dofs,
            "newton_iterations": r.iterations,
            "converged": r.converged,
            "reason": r.reason,
            "eta": est.eta,
            "seconds": round(step.seconds, 4),
        }
        table = contact_table(scene, r)
        if r.friction is not None:
            if "fixed_point_iterations" in r.friction:
                row["fixed_point_iterations"] = r.friction["fixed_point_iterations"]
            row.update(surface_figures(scene, r, table))
        else:
            row["contact_force"] = r.contact_force
        row.update(pressure_peaks(r))  # a finite-strain body: nominal and per deformed area
        if step.negative_eigenvalues is not None:  # hyperelastic: K_T's stability
            from ..post.load_curve import load_displacements
            from ..solvers.energy_search import tangent_figures

            row.update(load_displacements(scene, r))  # the force–displacement curve
            row["tangent_negative_eigenvalues"] = step.negative_eigenvalues
            row["min_det_F"] = step.min_det_F
            row.update(tangent_figures(r.tangent_log))
        self.rows.append(row)
        self.levels += [{"step": k, "time": step.time, **lv.row()} for lv in step.levels]
        self.tables.append((step.time, table))
        if table is not None:  # rank 0
            folder.write_table(self.tmp / f"contact_step_{k - 1:03d}.csv", table)
        if self.files.formats:
            nodal = point_fields(r)
            if r.friction is not None:
                from ..solvers.friction import surface_functions

                nodal += surface_functions(r)
            cells = [*cell_fields(scene, r), *([est.eta_T] if step.levels else [])]
            self.files.write_step(
                step.time, nodal, cells, {"step": k, "dofs": r.dofs}, scene.boundary
            )

    def finish(
        self, path: LoadPath, wall: float | None = None, failure: dict | None = None
    ) -> dict[str, Any]:
        """The run's files after the last (converged) step; ``failure`` (``converged:
        false``, the failed step) goes into summary.json.  Returns the summary."""
        tmp, comm = self.tmp, self.scene.comm
        last = path.steps[-1]
        r = last.result
        folder.write_csv(tmp / "steps.csv", [_flat(row) for row in self.rows], comm)
        folder.write_csv(tmp / "history.csv", self.history, comm)
        if self.levels:
            folder.write_csv(tmp / "convergence.csv", self.levels, comm)
        comparison = compare(last.scene, r)
        if failure is None:  # a failed run's last line is its error
            warn_coarse_zone(last.scene, r)
        write_contact(tmp, last.scene, r, comparison, contact_table(last.scene, r))
        config = self.scene.config
        friction = config.friction.law if config.friction is not None else "none"
        its = [s["newton_iterations"] for s in self.rows]
        info = {
            "scene": self.scene.name,
            "model": self.scene.config.model.type,
            "method": r.method,
            "friction": friction,
            "steps_total": len(path.steps),
            "stop": path.stop,
            "dofs": r.dofs,
            "mpi_ranks": comm.size,
            "converged": path.converged,
            "newton_iterations": sum(its),
            "newton_iterations_max_per_step": max(its),
            "time_total": wall if wall is not None else sum(s.seconds for s in path.steps),
            "host": platform.node(),
            **self.files.timings(),
            **posed_problem(last.scene),
            "steps": self.rows,
        }
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
        if config.friction is not None and friction != "none":
            info["tangential_form"] = config.friction.form
        if self.scene.config.elastic:  # the forces are of the whole body
            info["symmetric_copies"] = r.problem.symmetric_copies
        info.update(failure or {})
        if comparison is not None and config.reference is not None:
            info["reference"] = config.reference.type
            info.update(comparison.values)
        if self.scene.config.output.png:
            origin, t0 = first_contact(last.scene, r)
            if comm.rank == 0:
                tables = [(t, table) for t, table in self.tables if table is not None]
                plots.plot_traction(
                    tmp / "traction.png",
                    tables,
                    title=f"{self.scene.name}: contact tractions ({r.dofs} DoFs)",
                    references=reference_curves(
                        last.scene, self.tables[-1][1], comparison, origin, t0
                    ),
                )
            if comm.rank == 0 and self.rows and "obstacle_approach" in self.rows[0]:
                plot_load_curve(tmp / "force.png", self.rows, self.scene.name, r.dofs)
            plot_solution(
                tmp / "solution.png",
                last.scene,
                r,
                title=f"{self.scene.name}: u_h at t = {last.time:g} ({r.dofs} DoFs)",
            )
        _finish(tmp, info, comm)
        return info


def plot_load_curve(path: Path, rows: list[dict[str, Any]], name: str, dofs: int) -> None:
    """force.png: the contact force of each step against the obstacle's approach if the
    obstacle moves, else the prescribed displacement if there is one, else the pseudo-time
    (:mod:`contact.post.load_curve`); steps where the energy search met an indefinite
    tangent, and unstable solutions, marked."""
    axes = (
        ("obstacle_approach", "obstacle's approach (displacement towards the body)"),
        ("prescribed_displacement", "largest prescribed displacement |u_D|"),
        ("time", "pseudo-time t"),
    )
    key, label = next(
        (k, lb) for k, lb in axes if k == "time" or np.ptp([0.0, *(row[k] for row in rows)]) > 0
    )
    x = [row[key] for row in rows]
    plots.plot_force_displacement(
        path,
        x,
        [row["contact_force"] for row in rows],
        label,
        title=f"{name}: force–displacement ({dofs} DoFs)",
        indefinite=[row.get("indefinite_newton_steps", 0) > 0 for row in rows],
        unstable=[row.get("tangent_negative_eigenvalues", 0) > 0 for row in rows],
    )


def first_contact(scene: Scene, result) -> tuple[np.ndarray, np.ndarray | None]:
    """The first point of contact (smallest initial gap, over all ranks; collective) and, in
    2D, the tangent t_0 of the position's sign convention."""
    from ..models.obstacles import first_contact_point

    p = result.problem
    con = p.constraint
    gdim = scene.mesh.geometry.dim
    X = p.V.tabulate_dof_coordinates()[con.dofs // p.V.dofmap.index_map_bs, :gdim]
    return first_contact_point(scene.comm, X, con.sign * con.g), (
        tangent_2d(result) if gdim == 2 else None
    )


def _flat(row: dict[str, Any]) -> dict[str, Any]:
    """A CSV row: vectors as one column per component (``contact_force_x`` …)."""
    out = {}
    for key, value in row.items():
        if isinstance(value, list):
            names = "xyz" if key.endswith("force") else [str(i) for i in range(len(value))]
            out.update({f"{key}_{names[i]}": v for i, v in enumerate(value)})
        else:
            out[key] = value
    return out


def reference_curves(
    scene: Scene,
    table: Table | None,
    comparison=None,
    origin: np.ndarray | None = None,
    t0: np.ndarray | None = None,
) -> list:
    """Reference curves of the traction plot (rank 0): the exact tractions of a declared
    exact solution (``data.exact``, 2D), or the pressure of a declared reference
    (``reference:``, e.g. Hertz for the computed force) on both sides of the first point of
    contact ``origin`` (2D; in 3D against r)."""
    if table is None or scene.comm.rank != 0:
        return []
    if scene.config.data.exact is not None:
        return exact_tractions(scene, table, t0)
    if comparison is None or not (comparison.curves or comparison.traction_curves):
        return []
    curves = [(0, *c) for c in comparison.curves] + [(1, *c) for c in comparison.traction_curves]
    if "s" not in table:
        return curves
    X = np.c_[table["x"], table["y"]]
    assert origin is not None  # a table with arc lengths s has a first point of contact
    s0 = float(table["s"][int(np.argmin(np.linalg.norm(X - origin[:2], axis=1)))])
    return [
        (panel, np.r_[s0 - x[::-1], s0 + x], np.r_[y[::-1], y], label)
        for panel, x, y, label in curves
    ]


def exact_tractions(scene: Scene, table: Table, t0: np.ndarray | None, h: float = 1e-6) -> list:
    """2D: −λ_n = −n·σ(u)n and λ_t = t_0·(σ(u)n − λ_n n) of the exact solution at the contact
    nodes of ``table`` (σ by central differences of ``data.exact`` with step h, n the
    obstacle's normal at the node, t_0 of :func:`contact.post.contact_table.tangent_2d`)."""
    from ..models.elasticity import lame
    from ..setup import expressions

    cfg = scene.config
    exact = cfg.data.exact
    if (
        scene.mesh.geometry.dim != 2
        or not isinstance(exact, tuple)
        or "s" not in table
        or t0 is None
    ):
        return []
    X = np.vstack([table["x"], table["y"], np.zeros(len(table["x"]))])
    u = [expressions.to_numpy(e, cfg.constants, t=scene.time) for e in exact]
    grad = np.empty((X.shape[1], 2, 2))
    for j in range(2):
        e = np.zeros((3, 1))
        e[j] = h
        for i in range(2):
            grad[:, i, j] = (u[i](X + e) - u[i](X - e)) / (2 * h)
    assert cfg.model.E is not None and cfg.obstacle is not None  # one body, an obstacle
    mu, lmbda = lame(cfg.model.E, cfg.model.nu)
    eps = 0.5 * (grad + grad.transpose(0, 2, 1))
    sigma = 2 * mu * eps + lmbda * np.trace(eps, axis1=1, axis2=2)[:, None, None] * np.eye(2)
    obstacle = cfg.obstacle
    if obstacle.type == "plane":
        nu_o = np.asarray(obstacle.normal, float)
        n = np.tile(
            -nu_o / np.linalg.norm(nu_o),
            (X.shape[1], 1),
        )
    else:
        d = np.asarray(obstacle.center, float)[:, None] - X[:2]
        n = (d / np.linalg.norm(d, axis=0)).T
    T = np.einsum("nij,nj->ni", sigma, n)
    lam_n = np.einsum("ni,ni->n", T, n)
    lam_t = (T - lam_n[:, None] * n) @ t0
    return [(0, table["s"], -lam_n, "exact solution"), (1, table["s"], lam_t, "exact solution")]
