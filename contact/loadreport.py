"""The output folder of a load path (``load:``) or a frictional run, step by step.

Per step k (files numbered 001, 002, …):

* ``step_00k.xdmf`` — u_h, λ_n (``lambda_h``), the gap, the active set and, with friction,
  λ_t and the slip increment (vectors), the status (0 separated, 1 stick, 2 slip, −1 off
  Γ_C) and the friction bound ρ; cellwise the von Mises stress (and η_T when the step ran
  the adaptive loop).  ParaView opens the numbered files as one series over the steps;
* ``contact_step_00k.csv`` — one row per contact node along Γ_C
  (:func:`contact.surface.surface_rows`: position, λ_n, λ_t, gap, slip, bound, status).

After the last step: ``steps.csv`` (one row per step: t, DoFs, Newton iterations, the
resultants and zone measures of :func:`contact.surface.surface_figures`, η), ``summary.json``
(the run, with the same figures per step under ``steps``), ``contact.csv`` (the last
step's surface), ``traction.png`` (λ_n and λ_t along Γ_C, every step), ``solution.png``,
``history.csv`` (the last step's Newton iterations) and, when steps ran the adaptive loop,
``convergence.csv`` (one row per level, with its step).
"""
from __future__ import annotations

import platform
from pathlib import Path
from typing import Any

import numpy as np

from . import io, plots
from .estimate import estimate
from .report import cell_fields
from .scene import Scene
from .solvers.loadpath import LoadPath, Step
from .surface import surface_figures, surface_functions, surface_rows


class StepWriter:
    """``on_step`` callback of :func:`contact.solvers.loadpath.run_load_path`: writes a
    step's files into ``tmp`` and keeps its figures for :meth:`finish`."""

    def __init__(self, tmp: Path, scene: Scene):
        self.tmp, self.scene = tmp, scene
        self.rows: list[dict[str, Any]] = []
        self.surfaces: list[tuple[float, list[dict]]] = []
        self.levels: list[dict[str, Any]] = []

    def __call__(self, step: Step) -> None:
        r, scene, k = step.result, step.scene, step.index
        if not r.converged:
            return
        est = step.levels[-1].estimate if step.levels else estimate(scene, r)
        row = {"step": k, "time": step.time, "dofs": r.dofs, "newton_iterations": r.iterations,
               "converged": r.converged, "reason": r.reason, "eta": est.eta, "seconds": round(step.seconds, 4)}
        if r.friction is not None and "fixed_point_iterations" in r.friction:
            row["fixed_point_iterations"] = r.friction["fixed_point_iterations"]
        row.update(surface_figures(scene, r))
        self.rows.append(row)
        for lv in step.levels:
            self.levels.append({"step": k, "time": step.time, **lv.row()})
        rows = surface_rows(scene, r)
        self.surfaces.append((step.time, rows))
        io.write_csv(self.tmp / f"contact_step_{k:03d}.csv", rows or [], scene.comm)
        if scene.cfg["output"]["xdmf"]:
            nodal = [r.u_h, r.lmbda_h, r.gap, r.active] + (surface_functions(r) if r.friction is not None else [])
            io.write_xdmf(self.tmp / f"step_{k:03d}.xdmf", nodal, t=step.time,
                          cells=[*cell_fields(scene, r), *([est.eta_T] if step.levels else [])])

    def finish(self, path: LoadPath, wall: float | None = None) -> dict[str, Any]:
        """The run's files after the last step; returns the summary."""
        tmp, comm = self.tmp, self.scene.comm
        last = path.steps[-1]
        r = last.result
        io.write_csv(tmp / "steps.csv", [_flat(row) for row in self.rows], comm)
        io.write_csv(tmp / "contact.csv", self.surfaces[-1][1] or [], comm)
        io.write_csv(tmp / "history.csv", r.history, comm)
        if self.levels:
            io.write_csv(tmp / "convergence.csv", self.levels, comm)
        friction = (self.scene.cfg.get("friction") or {}).get("law", "none")
        info = {"scene": self.scene.name, "model": self.scene.cfg["model"]["type"], "method": r.method,
                "friction": friction, "steps_total": len(path.steps), "stop": path.stop,
                "dofs": r.dofs, "mpi_ranks": comm.size, "converged": path.converged,
                "newton_iterations": sum(s["newton_iterations"] for s in self.rows),
                "newton_iterations_max_per_step": max(s["newton_iterations"] for s in self.rows),
                "time_total": wall if wall is not None else sum(s.seconds for s in path.steps),
                "host": platform.node(), "steps": self.rows}
        if friction != "none":
            info["tangential_form"] = self.scene.cfg["friction"]["form"]
        io.write_json(tmp / "summary.json", info, comm)
        if self.scene.cfg["output"]["png"]:
            if comm.rank == 0:
                plots.plot_traction(tmp / "traction.png", self.surfaces,
                                    title=f"{self.scene.name}: contact tractions ({r.dofs} DoFs)",
                                    references=reference_curves(last.scene, self.surfaces[-1][1]))
            plots.plot_solution(tmp / "solution.png", r.u_h, r.active,
                                title=f"{self.scene.name}: u_h at t = {last.time:g} ({r.dofs} DoFs)")
        return info


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


def reference_curves(scene: Scene, rows: list[dict] | None) -> list:
    """Reference curves of the traction plot: the exact tractions of a declared exact
    solution (``data.exact``, 2D), and the Hertz pressure for the computed force when the
    scene is a Hertz scene (elastic body with a radius against a plane)."""
    if not rows or scene.comm.rank != 0:
        return []
    if scene.cfg["data"]["exact"] is not None:
        return exact_tractions(scene, rows)
    from .hertz import hertz, hertz_radius

    cfg = scene.cfg
    R = hertz_radius(cfg)
    if R is None or (cfg.get("obstacle") or {}).get("type") != "plane":
        return []
    dim = scene.mesh.geometry.dim
    lam = np.array([r["lambda_n"] for r in rows])
    w = np.array([r["weight"] for r in rows])
    copies = 2 ** sum(role == "symmetry" for role in scene.boundary.roles.values())
    force = copies * float(np.sum(-w * lam))
    if dim == 2 and copies == 1:       # a full cylinder: the profile on both sides
        grid = np.linspace(-1, 1, 201)
    else:
        grid = np.linspace(0, 1, 101)
    a, p0 = hertz(R, cfg["model"]["E"], cfg["model"]["nu"], force, dim)
    return [(0, a * grid, p0 * np.sqrt(np.maximum(1 - grid**2, 0)), f"Hertz (a = {a:.3g}, p0 = {p0:.3g})")]


def exact_tractions(scene: Scene, rows: list[dict], h: float = 1e-6) -> list:
    """2D: −λ_n = −n·σ(u)n and λ_t = t_0·(σ(u)n − λ_n n) of the exact solution at the contact
    nodes (σ by central differences of ``data.exact`` with step h, n the obstacle's normal at
    the node, t_0 as in :mod:`contact.surface`)."""
    from . import expressions
    from .models.elasticity import lame

    cfg = scene.cfg
    exact = cfg["data"]["exact"]
    if scene.mesh.geometry.dim != 2 or not isinstance(exact, list):
        return []
    rows = sorted(rows, key=lambda r: r["position"])
    X = np.array([[r["x"], r["y"], 0.0] for r in rows]).T
    u = [expressions.to_numpy(e, cfg["constants"], t=scene.time) for e in exact]
    grad = np.empty((X.shape[1], 2, 2))
    for j in range(2):
        e = np.zeros((3, 1))
        e[j] = h
        for i in range(2):
            grad[:, i, j] = (u[i](X + e) - u[i](X - e)) / (2 * h)
    mu, lmbda = lame(cfg["model"]["E"], cfg["model"]["nu"])
    eps = 0.5 * (grad + grad.transpose(0, 2, 1))
    sigma = 2 * mu * eps + lmbda * np.trace(eps, axis1=1, axis2=2)[:, None, None] * np.eye(2)
    obstacle = cfg["obstacle"]
    if obstacle["type"] == "plane":
        n = np.tile(-np.asarray(obstacle["normal"], float) / np.linalg.norm(obstacle["normal"]), (X.shape[1], 1))
    else:
        d = np.asarray(obstacle["center"], float)[:, None] - X[:2]
        n = (d / np.linalg.norm(d, axis=0)).T
    T = np.einsum("nij,nj->ni", sigma, n)
    lam_n = np.einsum("ni,ni->n", T, n)
    n0 = n[int(np.argmin([abs(r["position"]) for r in rows]))]
    lam_t = (T - lam_n[:, None] * n) @ np.array([-n0[1], n0[0]])
    x = np.array([r["position"] for r in rows])
    return [(0, x, -lam_n, "exact solution"), (1, x, lam_t, "exact solution")]
