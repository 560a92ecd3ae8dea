"""MARK and REFINE, and the adaptive loop SOLVE → ESTIMATE → MARK → REFINE (SPEC §6).

The pieces are plain functions so a user can write their own loop in a few lines::

    scene = contact.load_scene("configs/signorini_free_boundary.yaml")
    for level in range(6):
        result = contact.solve(scene)
        est = contact.estimate(scene, result)
        cells = contact.mark(est.eta_T, "dorfler", theta=0.5)
        scene, u0 = contact.refine(scene, cells, result.u_h)
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from mpi4py import MPI

from dolfinx import fem, la
from dolfinx import mesh as dmesh

from ..base import progress
from ..setup.budget import max_dofs
from ..setup.config import SCENE, _validate
from ..post.energy_error import solution_error
from ..adaptivity.estimate import Estimate, estimate
from ..setup.geometry import builder_surfaces
from ..setup.meshes import Boundary
from ..setup.surfaces import boundary_surfaces, warn_undeclared_curves
from ..adaptivity.transfer import prolong, transfer_cell_tags, transfer_facet_tags
from ..setup.scene import Scene, require_scene
from ..models import build_problem
from ..solvers import Result, solve, solves_text

STRATEGIES = ("dorfler", "maximum", "uniform")
#: indicators within this relative distance of the marking threshold count as equal to it
#: (mirror-image cells differ by round-off that depends on the partition)
MARK_RTOL = 1e-10


def dorfler_threshold(eta_sq: np.ndarray, theta: float, comm: MPI.Comm = MPI.COMM_WORLD) -> float:
    """Global threshold τ of Dörfler (bulk) marking: the set {η_T² ≥ τ} is the smallest set
    M with Σ_M η_T² ≥ θ Σ_T η_T² (ties at τ are all included).

    The owned indicators of all ranks are gathered on rank 0, sorted once there and τ is
    broadcast: every rank marks against the same global threshold (no per-rank sorting).
    """
    parts = comm.gather(np.asarray(eta_sq, dtype=float), root=0)
    tau = None
    if comm.rank == 0:
        values = np.sort(np.concatenate(parts))[::-1]
        cumulative = np.cumsum(values)
        if len(values) == 0 or cumulative[-1] <= 0:
            tau = np.inf
        elif theta >= 1.0:
            tau = float(values[-1])  # everything
        else:
            k = int(np.searchsorted(cumulative, theta * cumulative[-1] * (1 - 1e-14)))
            tau = float(values[min(k, len(values) - 1)])
    return comm.bcast(tau, root=0)


def mark(eta_T: fem.Function, strategy: str = "dorfler", theta: float = 0.5) -> np.ndarray:
    """Owned local cell indices to refine.

    * ``dorfler``: smallest set with Σ_M η_T² ≥ θ Σ η_T² (global threshold τ), θ ∈ (0, 1];
    * ``maximum``: η_T ≥ θ max_T η_T (global maximum), θ ∈ (0, 1];
    * ``uniform``: every cell.

    Values within a relative :data:`MARK_RTOL` (1e-10) below the threshold are marked too:
    cells that are equal up to round-off (symmetric ones, whose η_T differ by ~1e-16
    depending on how the partition summed them) are treated alike, so the refined meshes
    are the same on any number of MPI ranks.
    """
    _check_mark_args(eta_T, strategy, theta)
    W = eta_T.function_space
    comm = W.mesh.comm
    n_owned = W.dofmap.index_map.size_local
    eta = eta_T.x.array[:n_owned]
    bad = comm.allreduce(int(np.count_nonzero(~np.isfinite(eta) | (eta < 0))), op=MPI.SUM)
    if bad:   # a NaN is never >= a threshold: nothing would be marked, silently
        total = W.dofmap.index_map.size_global
        raise ValueError(f"eta_T: {bad} of {total} indicators are not finite numbers >= 0 "
                         "(NaN, inf or negative); mark needs the indicators of contact.estimate")
    if strategy == "uniform":
        return np.arange(n_owned, dtype=np.int32)
    if strategy == "maximum":
        top = comm.allreduce(float(eta.max(initial=0.0)), op=MPI.MAX)
        return np.flatnonzero(eta >= theta * top * (1 - MARK_RTOL)).astype(np.int32)
    tau = dorfler_threshold(eta**2, theta, comm)
    return np.flatnonzero(eta**2 >= tau * (1 - MARK_RTOL)).astype(np.int32)


def _check_mark_args(eta_T: Any, strategy: Any, theta: Any) -> None:
    if not isinstance(eta_T, fem.Function):
        raise ValueError(f"eta_T: expected the DG0 indicator function of contact.estimate, got {type(eta_T).__name__}")
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy: unknown marking strategy {strategy!r}; expected one of {', '.join(STRATEGIES)}")
    if isinstance(theta, bool) or not isinstance(theta, (int, float)) or not 0 < theta <= 1:
        raise ValueError(f"theta: must be a number in (0, 1], got {theta!r}")


def refine(scene: Scene, cells: np.ndarray, u_h: fem.Function | None = None, rebalance: bool | None = None,
           *, timings: dict[str, float] | None = None) -> tuple[Scene, fem.Function | None]:
    """Refine the marked cells' edges (conforming, ``dolfinx.mesh.refine``), carry the
    boundary tags to the new mesh, interpolate ``u_h`` onto it (nested iteration), and
    move the vertices of a curved boundary part onto its exact surface
    (:func:`contact.setup.surfaces.boundary_surfaces`: the built-in Hertz meshes and parts that
    declare a ``surface``; other parts keep dolfinx's midpoints — a gmsh contact part that
    looks curved gets a one-line warning).
    The refined scene keeps the pseudo-time, and the functions of ``scene.history`` (a
    load step's state from the previous step) are prolonged with u_h.
    The two-body builders (``half_disks``, ``sphere_on_block``) snap their curved surfaces by
    the mesh's own facet tags (``scene.surfaces``), whatever parts the scene cut them into,
    and the body tags (``scene.bodies``) follow the cells.

    The interpolation comes first: it evaluates u_h at the new nodes where dolfinx put
    them, inside the old mesh; a snapped node then keeps that value (u0(π(x)) = u_h(x),
    the surface shifts by at most the sagitta h²/(8R) of the old edge).

    In parallel the refined mesh is redistributed evenly over the ranks unless
    ``rebalance`` is false (default: the scene's ``adapt.rebalance``, true; see
    :func:`refine_partitioner`); the mesh itself does not depend on it.

    ``cells`` are owned local cell indices (as :func:`mark` returns them); anything else,
    or a ``u_h`` on another mesh, is a ValueError (on every rank).

    ``timings``, if given, receives the seconds of the parts: ``mesh`` (the marked edges and
    ``dolfinx.mesh.refine`` itself, with the redistribution and the ghost layer),
    ``transfer`` (facets, tags and functions carried over) and ``snap`` (curved boundaries)."""
    require_scene(scene)
    cells = _owned_cells(scene, cells)
    if u_h is not None and (not isinstance(u_h, fem.Function) or u_h.function_space.mesh is not scene.mesh):
        raise ValueError("u_h: expected a dolfinx.fem.Function on the scene's mesh (e.g. result.u_h of "
                         "contact.solve on this scene)")
    if rebalance is None:
        rebalance = (scene.cfg.get("adapt") or {}).get("rebalance", True)
    if not isinstance(rebalance, bool):
        raise ValueError(f"rebalance: expected true or false, got {rebalance!r}")
    msh = scene.mesh
    tdim = msh.topology.dim
    clock = [time.perf_counter()]   # the start, then the end of each part
    msh.topology.create_entities(1)
    edges = dmesh.compute_incident_entities(msh.topology, cells, tdim, 1)
    new, parent_cell, parent_facet = dmesh.refine(msh, edges, partitioner=refine_partitioner(msh, rebalance),
                                                  option=dmesh.RefinementOption.parent_cell_and_facet)
    clock.append(time.perf_counter())
    new.topology.create_entities(tdim - 1)
    new.topology.create_connectivity(tdim - 1, tdim)
    tags = transfer_facet_tags(scene.boundary.tags, new, parent_cell, parent_facet)
    history = {name: prolong(fn, new, parent_cell) for name, fn in scene.history.items()}
    bodies = None if scene.bodies is None else transfer_cell_tags(scene.bodies, new, parent_cell)
    surfaces = None if scene.surfaces is None else transfer_facet_tags(scene.surfaces, new, parent_cell, parent_facet)
    child = Scene(scene.cfg, new, Boundary(tags, dict(scene.boundary.ids), dict(scene.boundary.roles)),
                  time=scene.time, history=history, bodies=bodies, surfaces=surfaces,
                  parent=(scene, parent_cell))
    u0 = None if u_h is None else prolong(u_h, new, parent_cell)
    clock.append(time.perf_counter())
    warn_undeclared_curves(scene.cfg, scene.mesh, scene.boundary)
    for surface in boundary_surfaces(scene.cfg, scene.mesh.geometry.dim, scene.boundary):
        surface.snap(new, tags)
    for surface in builder_surfaces(scene.cfg):   # by the mesh's own tags of its curved surfaces
        surface.snap(new, surfaces)
    clock.append(time.perf_counter())
    if timings is not None:
        timings.update(zip(("mesh", "transfer", "snap"), np.diff(clock).tolist()))
    return child, u0


def next_dofs_bound(scene: Scene, cells: np.ndarray, V: fem.FunctionSpace) -> int | None:
    """A lower bound of the DoFs after refining ``cells`` (P1: one new vertex per marked
    edge; refinement may split more edges for conformity), or None for P2.  An edge counts
    once, on its owning rank, whichever rank's cells marked it (the same bound on any
    number of ranks)."""
    if V.element.basix_element.degree != 1:
        return None
    msh = scene.mesh
    tdim = msh.topology.dim
    msh.topology.create_entities(1)
    edges = dmesh.compute_incident_entities(msh.topology, cells.astype(np.int32), tdim, 1)
    imap = msh.topology.index_map(1)
    marked = la.vector(imap, dtype=np.int32)
    marked.array[edges] = 1
    marked.scatter_reverse(la.InsertMode.add)   # ghost edges' marks to their owners
    owned = int(np.count_nonzero(marked.array[: imap.size_local]))
    vertices = msh.topology.index_map(0).size_global
    return V.dofmap.index_map_bs * (vertices + msh.comm.allreduce(owned, op=MPI.SUM))


def refine_partitioner(msh: dmesh.Mesh, rebalance: bool = True) -> Any:
    """``dolfinx.mesh.refine``'s partitioner.

    * serial: ``None`` (no ghost layer to build: 40 % faster, 2.2 s against 3.7 s for 1.5M
      new cells);
    * parallel, ``rebalance``: dolfinx's graph partitioner, which spreads the refined mesh
      evenly over the ranks — refinement concentrated in one rank's part of the domain
      would otherwise leave that rank with most of the work (problem A: 1.15× its share
      of the DoFs at 1.23M; hertz_3d 1.30× at 865k);
    * parallel, not ``rebalance``: the identity partitioner (children stay on their parent's
      rank).

    Both parallel ones rebuild the ghost layer the estimator's interior-facet jumps need."""
    if msh.comm.size == 1:
        return None
    if rebalance:
        return dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet, 2)
    return dmesh.IdentityPartitionerPlaceholder()


def _owned_cells(scene: Scene, cells: Any) -> np.ndarray:
    """``cells`` as int32 owned local cell indices; ValueError (collective) otherwise."""
    arr = np.asarray(cells)
    comm = scene.comm
    n_owned = scene.mesh.topology.index_map(scene.mesh.topology.dim).size_local
    if arr.ndim != 1 or (arr.size and not np.issubdtype(arr.dtype, np.integer)):
        problem = f"expected a 1D array of integer cell indices, got {arr.dtype} with shape {arr.shape}"
    else:
        bad = arr[(arr < 0) | (arr >= n_owned)]
        problem = f"{len(bad)} index(es) outside the owned cells 0 … {n_owned - 1}, e.g. {bad[0]}" if len(bad) else None
    problems = [p for p in comm.allgather(problem) if p]
    if problems:
        raise ValueError(f"cells: {problems[0]} (owned local cell indices, as contact.mark returns them)")
    return arr.astype(np.int32)


@dataclass
class Level:
    """One level of the adaptive loop."""

    index: int
    scene: Scene
    result: Result
    estimate: Estimate
    error: float | None
    seconds: dict[str, float]
    imbalance: float = 1.0   # max over ranks of the owned DoFs / their mean (1 in serial)

    def row(self) -> dict[str, Any]:
        msh = self.scene.mesh
        row = {"level": self.index, "dofs": self.result.dofs,
               "cells": msh.topology.index_map(msh.topology.dim).size_global,
               "eta": self.estimate.eta}
        row.update({f"eta2_{k}": float(v) for k, v in self.estimate.terms.items()})  # Σ_T of each term
        row["error"] = self.error if self.error is not None else ""
        row["effectivity"] = self.estimate.eta / self.error if self.error else ""
        row.update({"newton_iterations": self.result.iterations, "polish_solves": self.result.polish_solves,
                    "converged": self.result.converged,
                    "active_nodes": self.result.n_active, "rank_imbalance": round(self.imbalance, 4)})
        row.update({f"seconds_{k}": round(v, 4) for k, v in self.seconds.items()})
        return row


@dataclass
class AdaptResult:
    levels: list[Level] = field(default_factory=list)
    stop: str = ""

    @property
    def rows(self) -> list[dict]:
        return [lv.row() for lv in self.levels]


def rank_imbalance(V: fem.FunctionSpace) -> float:
    """max_r N_r / mean_r N_r of the DoFs N_r each rank owns (collective; 1 in serial):
    1.15 means the busiest rank has 15 % more than its share, and 2 ranks gain at most
    2/1.15 = 1.74×.  Near 1 with ``adapt.rebalance`` (the default); without it a refined
    mesh keeps its parents' partition, and refinement concentrated on one rank's part of
    the domain unbalances the work."""
    return busiest_share(V.mesh.comm, V.dofmap.index_map.size_local)


def busiest_share(comm: MPI.Comm, owned: int) -> float:
    """max_r n_r / mean_r n_r of a count ``owned`` = n_r on each rank (collective)."""
    return comm.allreduce(owned, op=MPI.MAX) * comm.size / max(comm.allreduce(owned, op=MPI.SUM), 1)


def adapt_options(scene: Scene, **overrides: Any) -> dict:
    """The scene's ``adapt`` section (defaults if absent) with keyword overrides, validated."""
    raw = {**(scene.cfg.get("adapt") or {}), **{k: v for k, v in overrides.items() if v is not None}}
    return _validate(raw, SCENE["adapt"], "adapt", scene.cfg["constants"])


def adapt(scene: Scene, method: str | None = None, on_level: Callable[[Level], None] | None = None,
          verbose: bool | None = None, u0: fem.Function | None = None, **options: Any) -> AdaptResult:
    """Run SOLVE → ESTIMATE → MARK → REFINE until η ≤ tol, the DoF budget or the level
    budget is reached (options as in the scene's ``adapt`` section).  ``on_level`` is
    called after each level is estimated (used by the CLI to write output as it goes);
    ``u0`` is the first level's initial guess (a load step's previous solution)."""
    require_scene(scene)
    if on_level is not None and not callable(on_level):
        raise ValueError(f"on_level: expected a function of one Level, got {type(on_level).__name__}")
    opts = adapt_options(scene, **options)
    verbose = scene.cfg["output"]["verbose"] if verbose is None else verbose
    comm = scene.comm
    out = AdaptResult()
    for index in range(opts["max_levels"]):
        seconds = {}
        t0 = time.perf_counter()
        problem = build_problem(scene)
        seconds["assembly"] = problem.assembly_time
        progress.note(lambda: f"level {index}: assembled, {problem.assembly_time:.0f} s")
        # nested: the previous level's solution; cold (nested: false) means cold, not sequenced
        result = solve(scene, method=method, problem=problem, u0=u0, verbose=False, rtol=opts["newton_rtol"],
                       sequence=None if opts["nested"] else "off")
        seconds["solve"] = time.perf_counter() - t0 - problem.assembly_time
        progress.note(lambda: f"level {index}: solved ({result.dofs} DoFs), "
                              f"{seconds['solve']:.0f} s; estimating")
        t0 = time.perf_counter()
        est = estimate(scene, result)
        seconds["estimate"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        error = solution_error(scene, result)
        seconds["error"] = time.perf_counter() - t0
        level = Level(index, scene, result, est, error, seconds, imbalance=rank_imbalance(result.u_h.function_space))
        out.levels.append(level)
        if on_level is not None:
            t0 = time.perf_counter()
            progress.note(f"level {index}: writing its files")
            on_level(level)
            seconds["output"] = time.perf_counter() - t0
        if verbose and comm.rank == 0:
            _print_row(level, header=index == 0)
            progress.heard()
        if not result.converged:
            out.stop = f"solver did not converge on level {index} ({result.reason})"
            break
        if est.eta <= opts["tol"]:
            out.stop = f"eta = {est.eta:.3e} <= tol = {opts['tol']:.3e}"
            break
        if index + 1 >= opts["max_levels"]:
            out.stop = f"reached max_levels = {opts['max_levels']}"
            break
        if opts["strategy"] == "none":
            out.stop = "strategy none: one solve"
            break
        t0 = time.perf_counter()
        cells = mark(est.eta_T, opts["strategy"], opts["theta"])
        seconds["mark"] = time.perf_counter() - t0
        bound = next_dofs_bound(scene, cells, result.u_h.function_space)
        if bound is not None and bound > opts["max_dofs"]:  # refining would be wasted work
            out.stop = f"the next level would have at least {bound} DoFs > max_dofs = {opts['max_dofs']}"
            break
        t0 = time.perf_counter()
        progress.note(f"level {index}: refining the marked cells")
        parts: dict[str, float] = {}
        new_scene, new_u0 = refine(scene, cells, result.u_h if opts["nested"] else None, opts["rebalance"],
                                   timings=parts)
        seconds["refine"] = time.perf_counter() - t0
        seconds["refine_mesh"] = parts["mesh"]   # of which dolfinx.mesh.refine
        # DoFs of the next level in the same element as u_h (vector-valued for elasticity)
        V_next = new_u0.function_space if new_u0 is not None else \
            fem.functionspace(new_scene.mesh, result.u_h.function_space.ufl_element())
        new_dofs = V_next.dofmap.index_map.size_global * V_next.dofmap.index_map_bs
        if new_dofs > opts["max_dofs"]:
            out.stop = f"the next level would have {new_dofs} DoFs > max_dofs = {opts['max_dofs']}"
            break
        if new_dofs > (budget := max_dofs(scene.cfg, scene.mesh.geometry.dim)):  # memory budget of one solve
            out.stop = f"the next level would have {new_dofs} DoFs > solver.max_dofs = {budget}"
            break
        scene, u0 = new_scene, new_u0
    return out


def format_table(rows: list[dict]) -> str:
    """The convergence table as fixed-width text."""
    lines = [_header()]
    lines += [_format(r) for r in rows]
    return "\n".join(lines)


def _header() -> str:
    return f"{'level':>5s} {'DoFs':>9s} {'eta':>11s} {'error':>11s} {'eff.':>6s} {'Newton':>6s} {'active':>7s} {'solve s':>8s}"


def _format(r: dict) -> str:
    err = f"{r['error']:11.4e}" if r["error"] != "" else f"{'-':>11s}"
    eff = f"{r['effectivity']:6.2f}" if r["effectivity"] != "" else f"{'-':>6s}"
    its = solves_text(r["newton_iterations"], r["polish_solves"])
    return (f"{r['level']:5d} {r['dofs']:9d} {r['eta']:11.4e} {err} {eff} {its:>6s} "
            f"{r['active_nodes']:7d} {r.get('seconds_solve', 0):8.2f}")


def _print_row(level: Level, header: bool) -> None:
    if header:
        print(_header(), flush=True)
    print(_format(level.row()), flush=True)
