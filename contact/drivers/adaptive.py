"""The adaptive loop SOLVE → ESTIMATE → MARK → REFINE (docs/theory.md §6).

The adaptive loop SOLVE → ESTIMATE → MARK → REFINE (docs/theory.md §6), of
:func:`contact.solve`, :mod:`contact.adaptivity.estimate`, :mod:`contact.adaptivity.mark`
and :mod:`contact.adaptivity.refine`.

The pieces are plain functions so a user can write their own loop in a few lines::

    scene = contact.load_scene("configs/signorini_free_boundary.yaml")
    for level in range(6):
        result = contact.solve(scene)
        est = contact.estimate(scene, result)
        cells = contact.mark(est.eta_T, "dorfler", theta=0.5)
        scene, u0 = contact.refine(scene, cells, result.u_h)
"""

from __future__ import annotations

import functools
import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from dolfinx import fem
from mpi4py import MPI

from ..adaptivity.energy_error import solution_error
from ..adaptivity.estimate import Estimate, estimate
from ..adaptivity.mark import mark
from ..adaptivity.refine import next_dofs_bound, refine
from ..base import progress
from ..base.errors import ConfigError
from ..base.lifetime import return_freed_memory
from ..base.timing import Timer
from ..models import build_problem
from ..setup.budget import max_dofs
from ..setup.scene import Scene
from ..setup.scene_config import AdaptConfig
from ..solvers.result import Result, solves_text
from ..solvers.stopping import AdaptiveStopping
from .solve import solve


@dataclass
class Level:
    """One level of the adaptive loop, as :func:`contact.adapt` hands it to ``on_level``.

    Attributes:
        index: The level's number, 0 for the first mesh.
        scene: The level's scene (its mesh).
        result: The solve on this level.
        estimate: The error estimate of that solve.
        error: The energy error against the scene's ``data.exact``, None without one.
        seconds: Seconds spent per phase (``assembly``, ``solve``, ``estimate``, ``error``,
            ``mark``, ``refine``, ``output``).
        imbalance: Under MPI the busiest rank's owned DoFs over the mean (1 in serial).
        passes: Solves of this level (adaptive stopping may solve on).
        elapsed: Wall seconds from the start of the loop to this level's solution, estimate
            and error, the levels' outputs (``on_level``) not counted: the time to reach
            ``error`` (the first level's includes its grid-sequencing solves).
    """

    index: int
    scene: Scene
    result: Result
    estimate: Estimate
    error: float | None
    seconds: dict[str, float]
    imbalance: float = 1.0  # max over ranks of the owned DoFs / their mean (1 in serial)
    passes: int = 1  # solves of this level (adaptive stopping may solve on: solve_level)
    elapsed: float = 0.0  # wall seconds of the loop up to this level, outputs not counted
    released: bool = False  # the solution's fields and η_T dropped (release)

    @functools.cached_property
    def cells(self) -> int:
        """Return the number of cells of the level's mesh, over all ranks."""
        msh = self.scene.mesh
        return msh.topology.index_map(msh.topology.dim).size_global

    def release(self) -> None:
        """Keep the level's figures only (its row, iterations, history, η and error).

        Its solution's fields and PETSc objects
        (:meth:`~contact.solvers.result.Result.release`) and the indicator field η_T are
        dropped, so the loop's memory follows the last level, not the sum of all. The mesh
        stays while a finer level refers to it (the chain of coarser meshes
        :mod:`contact.drivers.sequencing` solves on).
        """
        _ = self.cells  # cached while the mesh is at hand
        self.result.release()
        self.estimate.eta_T = None  # type: ignore[assignment]
        self.released = True

    def row(self) -> dict[str, Any]:
        """Return the level's row of ``convergence.csv`` (DoFs, cells, η, its terms, …)."""
        row: dict[str, Any] = {
            "level": self.index,
            "dofs": self.result.dofs,
            "cells": self.cells,
            "eta": self.estimate.eta,
        }
        # Σ_T of each term
        row.update({f"eta2_{k}": float(v) for k, v in self.estimate.terms.items()})
        row["error"] = self.error if self.error is not None else ""
        row["effectivity"] = self.estimate.eta / self.error if self.error else ""
        row.update(
            {
                "newton_iterations": self.result.iterations,
                "polish_solves": self.result.polish_solves,
                "converged": self.result.converged,
                "active_nodes": self.result.n_active,
                "rank_imbalance": round(self.imbalance, 4),
            }
        )
        row.update(self.errors())
        row.update({f"seconds_{k}": round(v, 4) for k, v in self.seconds.items()})
        row["seconds_elapsed"] = round(self.elapsed, 4)
        return row

    def errors(self) -> dict[str, Any]:
        """Return the error components and the solver's work of adaptive stopping.

        η_disc (the level's η), η_lin and η_alg of the final iterate (adaptive stopping
        only; '' otherwise, or where not defined), the Krylov iterations of all its solves.
        """
        st = self.result.stopping

        def finite(v: float) -> float | str:
            return float(v) if st is not None and math.isfinite(v) else ""

        return {
            "stopping": "adaptive" if st is not None else "fixed",
            "eta_disc": self.estimate.eta,
            "eta_lin": finite(st.eta_lin if st else 0.0),
            "eta_alg": finite(st.eta_alg if st else 0.0),
            "krylov_iterations": self.result.krylov_iterations,
            "solve_passes": self.passes,
        }


@dataclass
class AdaptResult:
    """The levels of an adaptive loop (:func:`contact.adapt`) and why it stopped.

    Attributes:
        levels: The levels solved, first to last (each a
            :class:`~contact.drivers.adaptive.Level`).
        stop: Why the loop stopped, e.g. ``"eta = 3.1e-03 <= tol = 4.0e-03"`` or
            ``"reached max_levels = 6"``.
    """

    levels: list[Level] = field(default_factory=list)
    stop: str = ""

    @property
    def rows(self) -> list[dict]:
        """The levels' rows of ``convergence.csv`` (:meth:`~contact.drivers.adaptive.Level.row`)."""
        return [lv.row() for lv in self.levels]


def rank_imbalance(V: fem.FunctionSpace) -> float:
    """Return max_r N_r / mean_r N_r of the DoFs N_r each rank owns (collective).

    1 in serial; 1.15 means the busiest rank has 15 % more than its share, and 2 ranks gain
    at most 2/1.15 = 1.74×. Near 1 with ``adapt.rebalance`` (the default); without it a
    refined mesh keeps its parents' partition, and refinement concentrated on one rank's
    part of the domain unbalances the work.
    """
    return busiest_share(V.mesh.comm, V.dofmap.index_map.size_local)


def busiest_share(comm: MPI.Comm, owned: int) -> float:
    """max_r n_r / mean_r n_r of a count ``owned`` = n_r on each rank (collective)."""
    return comm.allreduce(owned, op=MPI.MAX) * comm.size / max(comm.allreduce(owned, op=MPI.SUM), 1)


def adapt_options(scene: Scene, **overrides: Any) -> AdaptConfig:
    """Return the scene's ``adapt`` section with keyword overrides, validated.

    The section's defaults if the scene has none; each override is validated as in the
    scene file (the section itself was at load).
    """
    return (scene.config.adapt or AdaptConfig()).updated(**overrides)


def check_on_level(on_level: Callable | None) -> None:
    """Raise ValueError unless ``on_level`` is None or callable (one line naming it)."""
    if on_level is not None and not callable(on_level):
        raise ValueError(
            f"on_level: expected a function of one Level, got {type(on_level).__name__}"
        )


def adapt(
    scene: Scene,
    method: str | None = None,
    on_level: Callable[[Level], None] | None = None,
    verbose: bool | None = None,
    u0: fem.Function | None = None,
    keep: Callable[[Level], bool] | None = None,
    **options: Any,
) -> AdaptResult:
    """Run the h-adaptive loop SOLVE → ESTIMATE → MARK → REFINE on a scene.

    The loop stops when η ≤ ``tol``, before a level would exceed ``max_dofs`` or the DoF
    budget (``solver.max_dofs``), after ``max_levels`` levels, or when a solve does not
    converge (the levels before it are kept). Each level after the first starts from the
    previous level's solution interpolated onto the refined mesh (``nested``). Collective.

    Args:
        scene: The first level's scene.
        method: The solver method (fb, min, blend, vinewtonrsls, vinewtonssls); default
            the scene's ``solver.method``.
        on_level: Called with each :class:`~contact.drivers.adaptive.Level` once it is
            estimated (the CLI writes the level's files there).
        verbose: Print a table row per level (default: the scene's ``output.verbose``).
        u0: The first level's initial guess (a load step's previous solution).
        keep: Which levels keep their solution once the next level is estimated (and
            ``on_level`` has written it): the others are released
            (:meth:`~contact.drivers.adaptive.Level.release`: their rows, iterations, η
            and errors stay) and the loop's memory follows its last level. None (the
            default) keeps every level whole; ``lambda level: False`` releases all but
            the last.
        **options: Overrides of the scene's ``adapt`` section: ``strategy`` (dorfler,
            maximum, uniform, none; hp is :func:`contact.adapt`'s), ``theta``, ``tol``,
            ``max_dofs``, ``max_levels``, ``nested``, ``newton_rtol``, ``rebalance``,
            ``pictures``.

    Returns:
        The levels and the reason the loop stopped.

    Raises:
        ConfigError: For an unknown or invalid option (one line naming it).
        ValueError: If ``scene`` is not a Scene or ``on_level`` or ``keep`` is not callable.

    :func:`contact.adapt` (which also runs the hp loop) shows it at work.
    """
    check_on_level(on_level)
    if keep is not None and not callable(keep):
        raise ValueError(f"keep: expected a function of one Level, got {type(keep).__name__}")
    opts = adapt_options(scene, **options)
    if opts.strategy == "hp":  # contact.adapt and the CLI dispatch it to contact.hp
        raise ConfigError("adapt.strategy: hp runs one solve per level (no load path, no study)")
    verbose = scene.config.output.verbose if verbose is None else verbose
    comm = scene.comm
    out = AdaptResult()
    start, outputs = time.perf_counter(), 0.0  # the loop's clock, and the outputs' share
    for index in range(opts.max_levels):
        seconds = {}
        problem = build_problem(scene)
        seconds["assembly"] = problem.assembly_time
        progress.note(f"level {index}: assembled, {problem.assembly_time:.0f} s")
        # nested: the previous level's solution; cold (nested: false) means cold, not sequenced
        result, est, passes = solve_level(
            scene,
            problem,
            u0,
            seconds,
            f"level {index}",
            method=method,
            rtol=opts.newton_rtol,
            sequence=None if opts.nested else "off",
            previous=out.levels[-1] if out.levels else None,
        )
        with Timer(seconds, "error"):
            error = solution_error(scene, result)
        level = Level(
            index,
            scene,
            result,
            est,
            error,
            seconds,
            imbalance=rank_imbalance(result.u_h.function_space),
            passes=passes,
            elapsed=time.perf_counter() - start - outputs,
        )
        out.levels.append(level)
        # a failed level is dropped by the CLI: the one before it stays whole
        if keep is not None and index > 0 and result.converged and not keep(out.levels[-2]):
            out.levels[-2].release()
            gc.collect()  # the released fields sit in reference cycles (UFL, dolfinx)
            return_freed_memory()
        if on_level is not None:
            with Timer(seconds, "output"):
                progress.note(f"level {index}: writing its files")
                on_level(level)
            outputs += seconds["output"]
        if verbose and comm.rank == 0:
            _print_row(level, header=index == 0)
            progress.heard()
        if not result.converged:
            out.stop = f"solver did not converge on level {index} ({result.reason})"
            break
        if est.eta <= opts.tol:
            out.stop = f"eta = {est.eta:.3e} <= tol = {opts.tol:.3e}"
            break
        if index + 1 >= opts.max_levels:
            out.stop = f"reached max_levels = {opts.max_levels}"
            break
        if opts.strategy == "none":
            out.stop = "strategy none: one solve"
            break
        with Timer(seconds, "mark"):
            cells = mark(est.eta_T, opts.strategy, opts.theta)
        bound = next_dofs_bound(scene, cells, result.u_h.function_space)
        if bound is not None and bound > opts.max_dofs:  # refining would be wasted work
            out.stop = (
                f"the next level would have at least {bound} DoFs > max_dofs = {opts.max_dofs}"
            )
            break
        parts: dict[str, float] = {}
        with Timer(seconds, "refine"):
            progress.note(f"level {index}: refining the marked cells")
            new_scene, new_u0 = refine(
                scene,
                cells,
                result.u_h if opts.nested else None,
                opts.rebalance,
                timings=parts,
            )
        seconds["refine_mesh"] = parts["mesh"]  # of which dolfinx.mesh.refine
        # DoFs of the next level in the same element as u_h (vector-valued for elasticity)
        V_next = (
            new_u0.function_space
            if new_u0 is not None
            else fem.functionspace(new_scene.mesh, result.u_h.function_space.ufl_element())
        )
        new_dofs = V_next.dofmap.index_map.size_global * V_next.dofmap.index_map_bs
        if new_dofs > opts.max_dofs:
            out.stop = f"the next level would have {new_dofs} DoFs > max_dofs = {opts.max_dofs}"
            break
        # memory budget of one solve
        if new_dofs > (budget := max_dofs(scene.config.solver, scene.mesh.geometry.dim)):
            out.stop = f"the next level would have {new_dofs} DoFs > solver.max_dofs = {budget}"
            break
        scene, u0 = new_scene, new_u0
    return out


#: adaptive stopping: at most this many solves of a level (each from the last one's solution)
MAX_PASSES = 3
#: the prediction of a level's η_disc is taken this much smaller: an iterate that fails the
#: criteria against the η_disc computed at it costs another solve and another estimate, and
#: the estimate is most of a level's cost (demos/RESULTS.md §12); a stricter target costs a
#: Krylov iteration or two
PREDICTION_SAFETY = 0.5


def solve_level(
    scene: Scene,
    problem,
    u0: fem.Function | None,
    seconds: dict,
    label: str,
    previous: Level | None = None,
    **options: Any,
) -> tuple[Result, Estimate, int]:
    """SOLVE and ESTIMATE one level.

    SOLVE and ESTIMATE of one level (``seconds['solve']``, ``seconds['estimate']``; options
    of :func:`~contact.drivers.solve.solve`; ``label`` names it in progress lines); returns
    (result, estimate, solves).

    With ``solver.stopping: adaptive`` (:mod:`contact.solvers.stopping`) a level after the
    first is solved against the discretization error it should reach, predicted from the
    previous level at the optimal rate, :data:`PREDICTION_SAFETY` · η_prev (N_prev / N)^{p/d};
    the level's η_disc is then
    computed at the final iterate, and where the iterate fails either criterion against it
    (the prediction was too large), the level is solved on from there with η_disc — at most
    :data:`MAX_PASSES` solves; the Krylov iterations of all of them are counted.  The first
    level, with no η known yet, uses the fixed tolerances.
    """
    solver = scene.config.solver
    adaptive = solver.stopping == "adaptive" and previous is not None
    eta = None
    if adaptive:
        assert previous is not None  # adaptive needs the previous level's η
        V = problem.V
        dofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
        rate = V.element.basix_element.degree / V.mesh.geometry.dim
        eta = PREDICTION_SAFETY * previous.estimate.eta * (previous.result.dofs / dofs) ** rate
    seconds["solve"] = seconds["estimate"] = 0.0
    krylov, passes = 0, 0
    while True:
        stopping = (  # eta is known exactly when the stopping is adaptive
            None if eta is None else AdaptiveStopping(eta, solver.gamma_lin, solver.gamma_alg)
        )
        with Timer(seconds, "solve"):
            result = solve(
                scene, problem=problem, u0=u0, verbose=False, criterion=stopping, **options
            )
        progress.note(f"{label}: solved ({result.dofs} DoFs), {seconds['solve']:.0f} s; estimating")
        with Timer(seconds, "estimate"):
            est = estimate(scene, result)
        krylov += result.krylov_iterations
        passes += 1
        if (
            stopping is None
            or not result.converged
            or stopping.balanced(est.eta)
            or passes == MAX_PASSES
        ):
            break
        eta, u0 = est.eta, result.u_h  # solve on from the iterate, against its η_disc
    result.krylov_iterations = krylov
    return result, est, passes


def format_table(rows: list[dict]) -> str:
    """The convergence table as fixed-width text."""
    lines = [_header()]
    lines += [_format(r) for r in rows]
    return "\n".join(lines)


def _header() -> str:
    return (
        f"{'level':>5s} {'DoFs':>9s} {'eta':>11s} {'error':>11s} {'eff.':>6s} {'Newton':>6s} "
        f"{'active':>7s} {'solve s':>8s}"
    )


def _format(r: dict) -> str:
    err = f"{r['error']:11.4e}" if r["error"] != "" else f"{'-':>11s}"
    eff = f"{r['effectivity']:6.2f}" if r["effectivity"] != "" else f"{'-':>6s}"
    its = solves_text(r["newton_iterations"], r["polish_solves"])
    return (
        f"{r['level']:5d} {r['dofs']:9d} {r['eta']:11.4e} {err} {eff} {its:>6s} "
        f"{r['active_nodes']:7d} {r.get('seconds_solve', 0):8.2f}"
    )


def _print_row(level: Level, header: bool) -> None:
    if header:
        print(_header(), flush=True)
    print(_format(level.row()), flush=True)
