"""The adaptive loop SOLVE → ESTIMATE → MARK → REFINE (docs/theory.md §6).

The adaptive loop SOLVE → ESTIMATE → MARK → REFINE (docs/theory.md §6) over a user's
builder: ``build(mesh)`` (or ``build(domain)``) gives the problem on each level's mesh, and
the loop solves it (``contact.drivers.solve.solve``), estimates the error
(``contact.adaptivity.estimate.estimate``), marks cells
(:func:`contact.adaptivity.mark.mark`) and refines them
(``contact.adaptivity.refine.refine``), carrying the solution to the refined mesh as the
next level's initial guess (nested iteration).

The pieces are plain functions so a user can write their own loop in a few lines::

    domain, u0 = contact.Domain(mesh, facet_tags), None
    for level in range(6):
        problem = build(domain)
        result = contact.solve(problem, u0=u0)
        est = contact.estimate(problem, result)
        cells = contact.mark(est.eta_T, "dorfler", theta=0.5)
        domain, u0 = contact.refine(domain, cells, result.u_h)
"""

from __future__ import annotations

import functools
import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..adaptivity.bare import BareDomain, bare
from ..adaptivity.energy_error import solution_error
from ..adaptivity.estimate import Estimate, check_shared_facets, estimate
from ..adaptivity.mark import Growth, mark
from ..adaptivity.refine import CURVED_CELLS, Domain, incident_edges, next_dofs_bound, refine
from ..base import progress
from ..base.errors import ConfigError
from ..base.lifetime import return_freed_memory
from ..base.timing import Timer
from ..models.discrete import discrete
from ..solvers.options import NO_LAST_ESTIMATE_STOPPING, AdaptOptions, SolverOptions
from ..solvers.problem import DiscreteProblem
from ..solvers.result import Result, solves_text
from ..solvers.stopping import AdaptiveStopping
from . import sequencing
from .solve import options_of
from .solve import solve as solve_problem

#: a level the loop will release destroys its operator K before the next level's solve (its
#: nodal contact force kept, :meth:`~contact.solvers.result.Result.shed_operator`); False:
#: it stays whole until the next level is solved, the old path
SHED_PREVIOUS = True
#: with ``keep`` given, the last level destroys its operator K before its guaranteed bound
#: (its nodal contact force kept, as for :data:`SHED_PREVIOUS`): the bound and the level's
#: files need neither K nor the solver; False: K stays until the level is dropped, the old path
SHED_BOUND = True
#: a level the loop will release is stowed before the next level's solve
#: (:meth:`Level.stow`: its mesh and nodal values kept, its problem, functions and scene
#: dropped, all built again should the next level fail); False: it stays whole but for its
#: operator (:data:`SHED_PREVIOUS`), the old path
STOW_PREVIOUS = True
#: the loop collects the garbage alive at its start and freezes the rest (``gc.freeze``: the
#: cycle collector, called at every level to free the released levels' cycles, then walks
#: only the loop's own objects, not every module, form and scene made before it) and
#: unfreezes the heap when it returns (what was frozen before it, e.g. the CLI's loaded
#: modules, is then collected as any other object again).  False: every collection walks
#: everything, the old path
FREEZE_HEAP = True
#: the marked cells' edges are found once, for the DoF bound of the next level
#: (``next_dofs_bound``) and its refinement; False: each finds them, the old path
EDGES_ONCE = True
#: with ``adapt.indicators: residual``, a level whose guaranteed bound will be computed anyway
#: — the last level (``certainly_last``), or one whose bound is predicted to meet ``tol``
#: (``Bound.predicts``) — is estimated by the bound alone, which marks it should the loop
#: go on; False: every level is estimated by the residual indicators first, the old path
PREDICT_BOUND = True
#: the heap freed by refining, stowing and releasing levels is given back to the system
#: (``malloc_trim``: ``return_freed_memory``) only before a guaranteed bound, whose arrays of
#: other sizes would grow the heap around it (the loop's peak where it is computed); a solve
#: or a residual estimate reuses the freed heap, which, given back, it would fault in again
#: page by page.  False: also at each level's start, once the level before is stowed and once
#: it is released, the old path
TRIM_BEFORE_BOUNDS = True


@dataclass
class Stowed:
    """What a stowed level (:meth:`Level.stow`) is restored from.

    Attributes:
        result: The values of its result's functions (``Result.stow``).
        eta_T: The values of its indicator field η_T.
        element: η_T's element (DG0), to make its space again on the level's mesh.
        name: η_T's name.
        domain: Its domain with the mesh's cells only (:func:`~contact.adaptivity.bare.bare`),
            or None: the level keeps its domain whole.
    """

    result: dict[str, np.ndarray]
    eta_T: np.ndarray
    element: Any
    name: str
    domain: BareDomain | None = None


@dataclass
class Level:
    """One level of the adaptive loop, as :func:`contact.adapt` hands it to ``on_level``.

    Attributes:
        index: The level's number, 0 for the first mesh.
        domain: The level's domain (its mesh and tags).
        problem: The problem built on it.
        result: The solve on this level.
        estimate: The error estimate of that solve (``Estimate.skipped``: the last level of a
            loop with ``adapt.estimate_last`` false; :attr:`eta` is then None).
        error: The energy error against the physics' exact solution, None without one.
        seconds: Seconds spent per phase (``assembly``, ``solve``, ``estimate``, ``error``,
            ``mark``, ``refine``, ``output``).
        imbalance: Under MPI the busiest rank's owned DoFs over the mean (1 in serial).
        passes: Solves of this level (adaptive stopping may solve on).
        elapsed: Wall seconds from the start of the loop to this level's solution, estimate
            and error, the levels' outputs (``on_level``) not counted: the time to reach
            ``error`` (the first level's includes its grid-sequencing solves; with
            ``adapt.indicators: residual`` the last level's includes its bound).
        cpu: The CPU seconds of this process likewise.
        solved_elapsed: Wall seconds from the start of the loop to this level's solution and
            its error, its estimate not counted (nor its bound): the time to reach ``error``
            of a loop that knew this level would be its last, as one stopping on a level
            budget needs no estimate of its last level.
        solved_cpu: The CPU seconds of this process likewise.
    """

    index: int
    domain: Domain
    problem: DiscreteProblem
    result: Result
    estimate: Estimate
    error: float | None
    seconds: dict[str, float]
    imbalance: float = 1.0  # max over ranks of the owned DoFs / their mean (1 in serial)
    passes: int = 1  # solves of this level (adaptive stopping may solve on: solve_level)
    elapsed: float = 0.0  # wall seconds of the loop up to this level, outputs not counted
    cpu: float = 0.0  # this process's CPU seconds likewise
    solved_elapsed: float = 0.0  # wall seconds up to its solution and error, no estimate
    solved_cpu: float = 0.0  # this process's CPU seconds likewise
    released: bool = False  # the solution's fields and η_T dropped (release)
    estimator: str = ""  # the estimator of ``estimate`` where it is not the loop's (Bound)
    rebuildable: bool = False  # ``problem`` is the builder's on ``domain`` (stow may drop it)
    stowed: Stowed | None = None  # its problem and fields dropped, their values kept (stow)

    @functools.cached_property
    def cells(self) -> int:
        """Return the number of cells of the level's mesh, over all ranks."""
        msh = self.domain.mesh
        return msh.topology.index_map(msh.topology.dim).size_global

    @property
    def eta(self) -> float | None:
        """The level's η, None where it was not estimated (``adapt.estimate_last`` false)."""
        return self.estimate.eta if self.estimate.computed else None

    def release(self) -> None:
        """Keep the level's figures only (its row, iterations, history, η and error).

        Its solution's fields and PETSc objects (``Result.release``) and the indicator field
        η_T are dropped, and so are its domain and problem, so the loop's memory follows the
        last level, not the sum of all. (A loop that releases levels does not link a refined
        domain to its parent, so the mesh goes too.)
        """
        _ = self.cells  # cached while the mesh is at hand
        self.result.release()
        self.domain = self.problem = self.estimate.eta_T = None  # type: ignore[assignment]
        self.released, self.stowed = True, None

    def stow(self, mesh: bool = True) -> bool:
        """Keep the level's cells and the values of its fields, dropping what they live on.

        The problem (forms, function spaces, PETSc objects), the result's functions and η_T are
        dropped, their values kept (``Stowed``); with ``mesh`` the domain keeps its cells,
        vertices and geometry only (``contact.adaptivity.bare.bare``: the mesh's other entities
        and connectivities, about two thirds of it, go; not for a domain with functions or a
        parent), else it stays whole.  ``restore`` makes the domain whole again, the same entity
        for entity, builds the problem again on it, whose DoF layout is then the same, and gives
        every field its values back bit for bit.  The adaptive loop stows a level it will release
        before it solves the next level, the loop's peak; the level is needed whole again only if
        that solve fails (its files are then written and its bound computed).  A subclass drops what
        it adds that is built on the domain.  Returns whether the level was stowed: not if its
        problem is not the builder's (``rebuildable``, e.g. a coupling built on the solution) or its
        result's fields are not the problem's outputs (``Result.stow``).  Collective.
        """
        if not self.rebuildable or self.released or self.stowed is not None:
            return False
        _ = self.cells  # cached while the mesh is at hand
        values = self.result.stow()
        if values is None:
            return False
        eta_T = self.estimate.eta_T
        if eta_T is None:  # not estimated: the loop's last level, never stowed
            return False
        self.stowed = Stowed(
            values,
            eta_T.x.array.copy(),
            eta_T.function_space.ufl_element(),
            eta_T.name,
            bare(self.domain) if mesh else None,
        )
        self.problem = self.estimate.eta_T = None  # type: ignore[assignment]
        if self.stowed.domain is not None:
            self.domain = None  # type: ignore[assignment]  # stowed: made whole on restore
        return True

    def row(self) -> dict[str, Any]:
        """Return the level's row of ``convergence.csv`` (DoFs, cells, η, its terms, …)."""
        row: dict[str, Any] = {
            "level": self.index,
            "dofs": self.result.dofs,
            "cells": self.cells,
            "eta": self.eta if self.eta is not None else "",  # '' where not estimated
        }
        # Σ_T of each term
        row.update({f"eta2_{k}": float(v) for k, v in self.estimate.terms.items()})
        if self.estimator:  # adapt.indicators residual: the estimator of this row's η
            row["estimator"] = self.estimator
        row["error"] = self.error if self.error is not None else ""
        row["effectivity"] = self.eta / self.error if self.error and self.eta is not None else ""
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
        row["seconds_solved"] = round(self.solved_elapsed, 4)
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
            "eta_disc": self.eta if self.eta is not None else "",
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
            :class:`~contact.drivers.adaptive.Level`, or a scene's level).
        stop: Why the loop stopped, e.g. ``"eta = 3.1e-03 <= tol = 4.0e-03"`` or
            ``"reached max_levels = 6"``.
    """

    levels: list[Any] = field(default_factory=list)  # the Level records (a scene's: SceneLevel)
    stop: str = ""

    @property
    def rows(self) -> list[dict]:
        """The levels' rows of ``convergence.csv`` (:meth:`~contact.drivers.adaptive.Level.row`)."""
        return [lv.row() for lv in self.levels]


def rank_imbalance(V: fem.FunctionSpace) -> float:
    """Return max_r N_r / mean_r N_r of the DoFs N_r each rank owns (collective).

    max_r N_r / mean_r N_r of the DoFs N_r each rank owns (collective; 1 in serial):
    1.15 means the busiest rank has 15 % more than its share, and 2 ranks gain at most
    2/1.15 = 1.74×.  Near 1 with ``rebalance`` (the default); without it a refined
    mesh keeps its parents' partition, and refinement concentrated on one rank's part of
    the domain unbalances the work.
    """
    return busiest_share(V.mesh.comm, V.dofmap.index_map.size_local)


def busiest_share(comm: MPI.Comm, owned: int) -> float:
    """max_r n_r / mean_r n_r of a count ``owned`` = n_r on each rank (collective)."""
    return comm.allreduce(owned, op=MPI.MAX) * comm.size / max(comm.allreduce(owned, op=MPI.SUM), 1)


#: a level's solve: (problem, its domain, initial guess or None, adaptive stopping or None)
LevelSolve = Callable[
    [DiscreteProblem, Domain, fem.Function | None, AdaptiveStopping | None], Result
]


def check_on_level(on_level: Callable | None) -> None:
    """Raise ValueError unless ``on_level`` is None or callable (one line naming it)."""
    if on_level is not None and not callable(on_level):
        raise ValueError(
            f"on_level: expected a function of one Level, got {type(on_level).__name__}"
        )


def frozen_heap[**P](loop: Callable[P, AdaptResult]) -> Callable[P, AdaptResult]:
    """``loop`` run with the objects alive at its call frozen (``FREEZE_HEAP``)."""

    @functools.wraps(loop)
    def run(*args: P.args, **kwargs: P.kwargs) -> AdaptResult:
        if not FREEZE_HEAP:
            return loop(*args, **kwargs)
        gc.collect()  # garbage frozen would live until the loop returns
        gc.freeze()
        try:
            return loop(*args, **kwargs)
        finally:
            gc.unfreeze()

    return run


@frozen_heap
def adapt(
    build: Callable[[Any], Any],
    domain: dmesh.Mesh | Domain,
    method: str | None = None,
    *,
    options: AdaptOptions | None = None,
    solver: SolverOptions | None = None,
    kind: str = "residual",
    u0: fem.Function | None = None,
    on_level: Callable[[Level], None] | None = None,
    keep: Callable[[Level], bool] | None = None,
    solve: LevelSolve | None = None,
    budget: int | None = None,
    stopping: tuple[float, float] | None = None,
    verbose: bool = False,
    make_level: Callable[[Level], Level] | None = None,
    **overrides: Any,
) -> AdaptResult:
    """Run the h-adaptive loop SOLVE → ESTIMATE → MARK → REFINE over a user's builder.

    Run SOLVE → ESTIMATE → MARK → REFINE until η ≤ tol, the DoF budget or the level
    budget is reached.

    Args:
        build: the problem on a level: ``build(mesh)`` when ``domain`` is a mesh,
            ``build(domain)`` when it is a :class:`~contact.adaptivity.refine.Domain` (its
            facet and cell tags carried through refinement); a
            :class:`~contact.models.forms.ComplementarityProblem` or a model's problem,
            with its physics declared (the estimator reads it).
        domain: the first level's mesh or domain.
        method: the solver's method (fb, min, blend, …).
        options: the loop's :class:`~contact.solvers.options.AdaptOptions` (strategy,
            theta, growth, tol, max_dofs, max_levels, nested, rebalance, newton_rtol); keyword
            ``overrides`` change single ones.
        solver: the solver's options (default: the defaults); each level solves to
            ``newton_rtol``.
        kind: the estimator (``residual``, ``equilibrated``, ``equilibrated_rt0``).
        u0: the first level's initial guess (e.g. a load step's previous solution).
        on_level: called with each :class:`Level` once it is estimated, marked and refined
            (output as it goes).
        keep: which levels keep their solution once the next level is solved (and
            ``on_level`` has written it): the others are released (:meth:`Level.release`:
            their rows, iterations, η and errors stay) before the next level is estimated,
            and the loop's memory follows its last level (its refined domains are then not
            linked to their parents, ``Domain.parent``: the loop never solves on them).
            None (the default) keeps every level whole; ``lambda level: False`` releases
            all but the last.  With ``keep`` given, the last level is not solved on again:
            its operator K is destroyed before its guaranteed bound (its nodal contact
            force kept, :meth:`~contact.solvers.result.Result.shed_operator`).
        solve: a level's solve, ``solve(problem, domain, u0, criterion)`` (default: one solve
            of ``contact.drivers.solve.solve``, a first level without a guess sequenced
            over the domain's ancestors); it may solve another problem on the level's
            domain (its result's ``problem``, e.g. a coupling re-built on the current
            configuration), which the level then keeps and estimates.
        budget: the most DoFs one solve may have (a memory budget), or None.
        stopping: (γ_lin, γ_alg) of adaptive stopping (:mod:`contact.solvers.stopping`;
            needs an equilibrated ``kind``), or None: fixed tolerances.
        verbose: print the convergence table as it goes (rank 0).
        make_level: the record of a level as the loop keeps and hands it on (default the
            :class:`Level` itself; a scene's loop adds its scene).
        **overrides: single options of ``options`` (``theta=0.3``, ``max_levels=6``, …).

    Returns:
        The :class:`AdaptResult`: the levels and why the loop stopped.
    """
    check_on_level(on_level)
    if keep is not None and not callable(keep):
        raise ValueError(f"keep: expected a function of one Level, got {type(keep).__name__}")
    opts = (options or AdaptOptions()).updated(**overrides)
    if not opts.estimate_last and stopping is not None:
        raise ConfigError(NO_LAST_ESTIMATE_STOPPING)
    first_mesh = domain if isinstance(domain, dmesh.Mesh) else domain.mesh
    if opts.max_levels > 1 and first_mesh.geometry.cmaps[0].degree > 1:
        raise ConfigError(CURVED_CELLS)  # before the first level is solved
    knobs = options_of(solver, method, {"rtol": opts.newton_rtol})
    meshes = not isinstance(domain, Domain)  # the builder takes meshes
    level_domain = Domain(domain) if isinstance(domain, dmesh.Mesh) else domain
    # the residual indicators mark, the guaranteed bound only where it is reported
    bound = Bound(kind) if opts.indicators == "residual" and stopping is None else None
    if bound is not None or kind == "residual":  # before the first solve (refined: ghosted)
        check_shared_facets(level_domain.mesh, "domain")
    if solve is None:
        solve = _default_solve(build, knobs, meshes, opts.nested)
    comm = level_domain.comm
    growth = Growth(opts.growth)  # the share of the cells marked, learnt level by level
    out = AdaptResult()
    # the loop's clocks, wall and CPU, and the outputs' shares of them
    start, outputs = time.perf_counter(), 0.0
    start_cpu, outputs_cpu = time.process_time(), 0.0
    for index in range(opts.max_levels):
        seconds: dict[str, float] = {}
        previous = out.levels[-1] if out.levels else None
        if keep is not None and previous is not None and opts.nested:
            # a refined level solves from the previous solution, never on the coarser
            # meshes (grid sequencing's chain, Domain.parent): without the link the
            # previous mesh goes once its level is released
            level_domain.parent = None
        # the level before, to be released once this level is solved: only its files may
        # still be written (this level fails), for which its operator is not needed
        leaving = (
            previous
            if keep is not None
            and previous is not None
            and not previous.released
            and not keep(previous)
            else None
        )
        if leaving is not None and SHED_PREVIOUS:
            leaving.result.shed_operator()
        if keep is not None and previous is not None and not TRIM_BEFORE_BOUNDS:
            return_freed_memory()  # what refining freed (the old path)
        built = problem = discrete(build(level_domain.mesh if meshes else level_domain))
        # … nor, once this level is built (a scene's builder drops the level's scene from its
        # cache), its forms, spaces and mesh entities: its values and cells are enough (its
        # mesh stays whole where the refined mesh is linked to it: not nested)
        if leaving is not None and STOW_PREVIOUS and leaving.stow(mesh=opts.nested):
            gc.collect()  # the dropped forms and spaces sit in reference cycles
            if not TRIM_BEFORE_BOUNDS:
                return_freed_memory()
        seconds["assembly"] = problem.assembly_time
        progress.note(f"level {index}: assembled, {problem.assembly_time:.0f} s")

        solved: dict[str, float] = {}  # the clocks when the level's last solve is done
        # a level estimated by a guaranteed bound (the estimator's own, marking every level)
        bounded_level = bound is None and kind != "residual"

        def release_previous(
            result: Result,
            previous: Level | None = previous,
            solved: dict = solved,
            trim: bool = bounded_level or not TRIM_BEFORE_BOUNDS,
        ) -> None:
            # once this level has a solution (a failed one is dropped by the CLI and the
            # one before it stays whole), before its estimate, the loop's peak
            if keep is not None and previous is not None and not previous.released:
                if result.converged and not keep(previous):
                    previous.release()
                    gc.collect()  # the released fields sit in reference cycles (UFL, dolfinx)
                    if trim:
                        return_freed_memory()
            solved.update(wall=time.perf_counter(), cpu=time.process_time())

        # a level the loop knows to be its last before estimating it (the level budget …)
        last = (
            certainly_last(index, problem.V, opts, growth, budget)
            if (bound is not None and PREDICT_BOUND) or not opts.estimate_last
            else ""
        )
        # … is not estimated at all with adapt.estimate_last false: the loop ends with its
        # solution, as a uniform run does
        unestimated = bool(last) and not opts.estimate_last
        # the bound alone where it will be computed anyway (adapt.indicators residual): on
        # the last level (its operator K then shed first, as before the bound of Bound) or
        # where it is predicted to meet tol
        bound_only = (
            not unestimated
            and bound is not None
            and PREDICT_BOUND
            and (bool(last) or bound.predicts(problem.V, opts.tol))
        )

        def on_solved(
            result: Result,
            bounded: bool = bound_only,
            shed: bool = bool(last) and SHED_BOUND and keep is not None,
        ) -> None:
            release_previous(result)
            if bounded and result.converged:  # the bound follows: its peak, as in Bound
                if shed:
                    result.shed_operator()  # nothing solves on the last level again
                return_freed_memory()

        result, est, passes = solve_level(
            problem,
            level_domain,
            u0,
            seconds,
            f"level {index}",
            solve,
            kind if bound is None else "residual",
            stopping,
            previous=previous,
            solved=on_solved,
            bound_kind=bound.kind if bound_only and bound is not None else None,
            estimated=not unestimated,
        )
        # a level's solve may have solved another problem on its mesh (pairs re-coupled on
        # the current configuration): the level is that of its result
        problem = result.problem or problem
        error_cpu = time.process_time()
        with Timer(seconds, "error"):
            error = solution_error(problem, result)
        error_cpu = time.process_time() - error_cpu
        level = Level(
            index,
            level_domain,
            problem,
            result,
            est,
            error,
            seconds,
            imbalance=rank_imbalance(result.u_h.function_space),
            passes=passes,
            elapsed=time.perf_counter() - start - outputs,
            cpu=time.process_time() - start_cpu - outputs_cpu,
            solved_elapsed=solved["wall"] - start - outputs + seconds["error"],
            solved_cpu=solved["cpu"] - start_cpu - outputs_cpu + error_cpu,
            estimator=""
            if bound is None or unestimated
            else bound.kind
            if bound_only and result.converged
            else "residual",
            rebuildable=problem is built,
        )
        if make_level is not None:
            level = make_level(level)
        out.levels.append(level)
        if not result.converged and index > 0 and out.levels[-2].stowed is not None:
            # the level before is the last that converged, written and bounded as the last
            out.levels[-2] = restore(out.levels[-2], build, meshes, make_level)
        # what marks: the estimator's, the residual ones, or the bound's where it alone was
        # computed (a bound is an estimator with local indicators like the residual one)
        indicators = est.eta_T
        eta = est.eta if bound is None or unestimated else bound.eta(level, opts.tol)
        # a level certainly the last stops before marking (its next level's DoFs bounded
        # below without it: certainly_last)
        out.stop = stop_before_marking(level, eta, opts) or last
        child = None
        if not out.stop:
            tdim = level_domain.mesh.topology.dim
            with Timer(seconds, "mark"):
                fraction = growth.fraction(tdim) if opts.strategy == "dorfler" else 0.0
                assert indicators is not None  # an unestimated level is the last
                cells = mark(indicators, opts.strategy, opts.theta, fraction)
            marked = comm.allreduce(len(cells), op=MPI.SUM) / level.cells
            edges = incident_edges(level_domain.mesh, cells) if EDGES_ONCE else None
            estimated = next_dofs_bound(level_domain.mesh, cells, result.u_h.function_space, edges)
            if estimated is not None and estimated > opts.max_dofs:  # refining: wasted work
                out.stop = (
                    f"the next level would have at least {estimated} DoFs > max_dofs = "
                    f"{opts.max_dofs}"
                )
        if not out.stop:
            parts: dict[str, float] = {}
            with Timer(seconds, "refine"):
                progress.note(f"level {index}: refining the marked cells")
                child, new_u0 = refine(
                    level_domain,
                    cells,
                    result.u_h if opts.nested else None,
                    opts.rebalance,
                    timings=parts,
                    edges=edges,
                )
            seconds["refine_mesh"] = parts["mesh"]  # of which dolfinx.mesh.refine
            # DoFs of the next level in the same element as u_h (vector-valued for elasticity)
            V_next = (
                new_u0.function_space
                if new_u0 is not None
                else fem.functionspace(child.mesh, result.u_h.function_space.ufl_element())
            )
            new_dofs = V_next.dofmap.index_map.size_global * V_next.dofmap.index_map_bs
            growth.observe(marked, result.dofs, new_dofs)
            if new_dofs > opts.max_dofs:
                out.stop = f"the next level would have {new_dofs} DoFs > max_dofs = {opts.max_dofs}"
            elif budget is not None and new_dofs > budget:  # the memory budget of one solve
                out.stop = f"the next level would have {new_dofs} DoFs > solver.max_dofs = {budget}"
        if out.stop:  # the refined mesh, if any, is not needed (nor held during the bound)
            child = new_u0 = None
        if bound is not None and out.stop:  # the last level: its bound (unestimated: none)
            if result.converged and not unestimated:
                if SHED_BOUND and keep is not None and level.estimator != bound.kind:
                    result.shed_operator()  # nothing solves on it again: the bound's peak
                bound.compute(level)
            elif not result.converged and index > 0 and not out.levels[-2].released:
                bound.compute(out.levels[-2])
        if on_level is not None:
            cpu = time.process_time()
            with Timer(seconds, "output"):
                progress.note(f"level {index}: writing its files")
                on_level(level)
            outputs += seconds["output"]
            outputs_cpu += time.process_time() - cpu
        if verbose and comm.rank == 0:
            _print_row(level, header=index == 0)
            progress.heard()
        if out.stop:
            break
        assert child is not None  # refined: the loop goes on
        # the level's record holds what is kept of its estimate (Level.stow drops η_T)
        del est, indicators
        level_domain, u0 = child, new_u0
    return out


def restore(
    level: Level,
    build: Callable[[Any], Any],
    meshes: bool,
    make_level: Callable[[Level], Level] | None = None,
) -> Level:
    """Return a stowed level (:meth:`Level.stow`) whole again.

    Its problem is built again by ``build`` on its domain (its mesh when ``meshes``), its
    result's functions and η_T get their values back, and ``make_level`` makes the
    level's record again (a scene's level: its scene on the domain).  Collective.
    """
    stowed = level.stowed
    assert stowed is not None  # only a stowed level is restored
    if stowed.domain is not None:
        level.domain = stowed.domain.whole()
    problem = discrete(build(level.domain.mesh if meshes else level.domain))
    level.result.restore(problem, stowed.result)
    eta_T = fem.Function(fem.functionspace(level.domain.mesh, stowed.element), name=stowed.name)
    eta_T.x.array[:] = stowed.eta_T
    level.estimate.eta_T, level.problem, level.stowed = eta_T, problem, None
    return level if make_level is None else make_level(level)


def stop_before_marking(level: Level, eta: float, opts: AdaptOptions) -> str:
    """Why the loop stops at ``level`` before marking (its estimate ``eta``), or ''."""
    index, result = level.index, level.result
    if not result.converged:
        return f"solver did not converge on level {index} ({result.reason})"
    if eta <= opts.tol:
        return f"eta = {eta:.3e} <= tol = {opts.tol:.3e}"
    if index + 1 >= opts.max_levels:
        return f"reached max_levels = {opts.max_levels}"
    if opts.strategy == "none":
        return "strategy none: one solve"
    return ""


#: the bound is computed on a level whose predicted bound is below this multiple of ``tol``:
#: the ratio bound/residual it is predicted with moves by 5–20 % from level to level (ex9,
#: problem A), so a level predicted further above ``tol`` is refined without it — a bound
#: computed in vain costs about a level's solve, a level refined past ``tol`` costs the next
#: level and its bound, and above 1.1 tol the first is the likelier loss (2.0: the earlier
#: rule, the bound on about two levels before the last)
BOUND_SAFETY = 1.1


@dataclass
class Bound:
    """The estimator's bound where it is reported, the residual indicators marking.

    With ``adapt.indicators: residual`` every level is estimated by the residual
    estimator (cheap, DG0 forms), which marks; the estimator the user asked for (``kind``,
    e.g. the guaranteed bound of an equilibrated flux) is computed on the last level only,
    and on a level where it may meet ``tol``: where the residual η times the last observed
    ratio bound/residual (1 before any) is below :data:`BOUND_SAFETY` · tol.  The level's
    ``estimate`` is then the bound's (its η_T, η, terms) and ``estimator`` names it.

    With ``PREDICT_BOUND`` the loop decides before estimating a level whether its bound
    will be computed (``predicts``, ``certainly_last``) and then computes the bound
    alone: its η_T mark the level should the loop go on.  An equilibrated bound is an
    estimator with local indicators ‖k^{-1/2}(σ_h − k∇u_h)‖_T (docs/theory.md §9),
    reliable and locally efficient, and for the Poisson problem Dörfler marking by them
    converges at the optimal rate as by the residual ones (Cascón & Nochetto, IMA J. Numer.
    Anal. 32, 2012, for estimators equivalent to the residual one); for contact no such
    proof is known, and the meshes they give are compared with the residual ones in the
    changelog.
    Such a level teaches no ratio (it has no residual η); its residual η is taken as its
    bound over the ratio.

    Attributes:
        kind: the estimator of the bound (as :func:`contact.estimate` takes it).
        ratio: η_bound / η_residual on the last level with both, None before.
        last: (residual η, DoFs) of the last level seen by ``eta`` (its bound over the
            ratio where it has no residual η), None before.
    """

    kind: str
    ratio: float | None = None
    last: tuple[float, int] | None = None

    def predicts(self, V: fem.FunctionSpace, tol: float) -> bool:
        """Whether the bound of the next level (its space ``V``) is predicted to meet ``tol``.

        The last level's residual η times (N_last / N)^{p/d} (the optimal rate, as
        adaptive stopping predicts a level's η_disc: ``solve_level``) times the ratio
        bound/residual, against ``BOUND_SAFETY`` · tol, the test ``eta`` makes with
        the level's own residual η.  False before the ratio and a last level are known and
        without a tolerance.
        """
        if tol <= 0 or self.ratio is None or self.last is None:
            return False
        residual, dofs = self.last
        predicted = self.ratio * residual * (dofs / global_dofs(V)) ** optimal_rate(V)
        return predicted <= BOUND_SAFETY * tol

    def eta(self, level: Level, tol: float) -> float:
        """Return the η that the stopping test holds against ``tol``.

        The bound's, computed here on the first level (to learn the ratio) and where it may
        meet ``tol``; else the residual η scaled by the last ratio (above ``tol``, as the
        bound's would be); without a tolerance the residual η (the test cannot stop).  A
        level estimated by the bound alone (``PREDICT_BOUND``) gives its bound.
        """
        if level.estimator == self.kind:  # the bound alone: the level's residual η predicted
            residual = None if self.ratio is None else level.estimate.eta / self.ratio
            self.last = None if residual is None else (residual, level.result.dofs)
            return level.estimate.eta
        self.last = (level.estimate.eta, level.result.dofs)
        if tol <= 0 or not level.result.converged:
            return level.estimate.eta  # no tolerance to meet (or no solution to bound)
        if self.ratio is None:  # the first level: learn the ratio
            return self.compute(level)
        predicted = level.estimate.eta * self.ratio
        return self.compute(level) if predicted <= BOUND_SAFETY * tol else predicted

    def compute(self, level: Level) -> float:
        """Replace the level's residual estimate by the bound's; return its η."""
        if level.estimator == self.kind:
            return level.estimate.eta
        residual = level.estimate.eta
        wall, cpu = time.perf_counter(), time.process_time()
        # the bound's patch data and fields on top of the level are the loop's peak: the heap
        # that the solve and the residual estimate freed is given back first, or the bound's
        # arrays of other sizes would add to it instead of reusing it
        return_freed_memory()
        with Timer(level.seconds, "estimate"):
            level.estimate = estimate(level.problem, level.result, self.kind)
        level.estimator = self.kind
        level.elapsed += time.perf_counter() - wall  # the time to this level's bound
        level.cpu += time.process_time() - cpu
        if residual > 0:
            self.ratio = level.estimate.eta / residual
        return level.estimate.eta


def certainly_last(
    index: int, V: fem.FunctionSpace, opts: AdaptOptions, growth: Growth, budget: int | None
) -> str:
    """Why the loop stops at level ``index`` (its space ``V``) whatever its estimate, or ''.

    The level budget (``max_levels``) or strategy ``none``; or, for P1 on triangles with
    ``dorfler`` (≥ ⌈f N⌉ of the N cells marked, f the ``growth`` share) or ``uniform``
    marking, a next level certainly above ``max_dofs`` (or the solver's ``budget``): m
    marked triangles have at least 3m/2 edges (an edge lies in at most two), each of which
    refinement splits, so the next level has at least bs (vertices + ⌈3m/2⌉) DoFs, at most
    the loop's own lower bound after marking (``next_dofs_bound``).  Collective (global
    counts).
    """
    if index + 1 >= opts.max_levels:
        return f"reached max_levels = {opts.max_levels}"
    if opts.strategy == "none":
        return "strategy none: one solve"
    msh = V.mesh
    if V.element.basix_element.degree != 1 or msh.topology.cell_type != dmesh.CellType.triangle:
        return ""
    cells = msh.topology.index_map(2).size_global
    if opts.strategy == "uniform":
        marked = cells
    elif opts.strategy == "dorfler":
        marked = math.ceil(growth.fraction(2) * cells)
    else:
        return ""
    vertices = msh.topology.index_map(0).size_global
    least = V.dofmap.index_map_bs * (vertices + math.ceil(1.5 * marked))
    if least > opts.max_dofs:
        return f"the next level would have at least {least} DoFs > max_dofs = {opts.max_dofs}"
    if budget is not None and least > budget:
        return f"the next level would have at least {least} DoFs > solver.max_dofs = {budget}"
    return ""


def global_dofs(V: fem.FunctionSpace) -> int:
    """The DoFs of ``V`` over all ranks (blocks counted)."""
    return V.dofmap.index_map.size_global * V.dofmap.index_map_bs


def optimal_rate(V: fem.FunctionSpace) -> float:
    """p/d: η ∝ N^{-p/d} on optimally graded meshes of the degree p of ``V``."""
    return V.element.basix_element.degree / V.mesh.geometry.dim


def _default_solve(build: Callable, knobs: SolverOptions, meshes: bool, nested: bool) -> LevelSolve:
    """Return the default level solve of a user's builder.

    A level's solve of a user's builder: one ``solve``; a level
    without a guess (the first, or every level when not ``nested``) is sequenced over the
    domain's ancestors with ≥ 4× fewer DoFs each (:func:`~.sequencing.ancestors`).
    """
    coarse_knobs = knobs.model_copy(update={"rtol": sequencing.COARSE_RTOL})

    def solve(problem, domain: Domain, u0, criterion) -> Result:
        coarse = None
        if u0 is None and nested:
            V = problem.V
            levels = sequencing.ancestors(
                domain, sequencing.ANCESTOR_RATIO, sequencing.COARSEST_DOFS, V.dofmap.index_map_bs
            )[::-1]
            if levels:
                coarse = sequencing.hierarchy(
                    lambda d: build(d.mesh if meshes else d),
                    levels,
                    domain,
                    lambda p, guess: solve_problem(p, options=coarse_knobs, u0=guess),
                )
        return solve_problem(problem, options=knobs, u0=u0, coarse=coarse, criterion=criterion)

    return solve


#: adaptive stopping: at most this many solves of a level (each from the last one's solution)
MAX_PASSES = 3
#: the prediction of a level's η_disc is taken this much smaller: an iterate that fails the
#: criteria against the η_disc computed at it costs another solve and another estimate, and
#: the estimate is most of a level's cost (demos/RESULTS.md §12); a stricter target costs a
#: Krylov iteration or two
PREDICTION_SAFETY = 0.5


def solve_level(
    problem: DiscreteProblem,
    domain: Domain,
    u0: fem.Function | None,
    seconds: dict,
    label: str,
    solve: LevelSolve,
    kind: str,
    stopping: tuple[float, float] | None,
    previous: Level | None = None,
    solved: Callable[[Result], None] | None = None,
    bound_kind: str | None = None,
    estimated: bool = True,
) -> tuple[Result, Estimate, int]:
    """SOLVE and ESTIMATE one level.

    SOLVE and ESTIMATE of one level (``seconds['solve']``, ``seconds['estimate']``;
    ``solve`` the level's solve, ``kind`` the estimator; ``label`` names it in progress
    lines); returns (result, estimate, solves).

    With adaptive stopping (``stopping`` = (γ_lin, γ_alg), :mod:`contact.solvers.stopping`)
    a level after the first is solved against the discretization error it should reach,
    predicted from the previous level at the optimal rate,
    :data:`PREDICTION_SAFETY` · η_prev (N_prev / N)^{p/d}; the level's η_disc is then
    computed at the final iterate, and where the iterate fails either criterion against it
    (the prediction was too large), the level is solved on from there with η_disc — at most
    :data:`MAX_PASSES` solves; the Krylov iterations of all of them are counted.  The first
    level, with no η known yet, uses the fixed tolerances.  ``solved`` is called with each
    solve's result before it is estimated; a converged one is estimated by ``bound_kind``
    where given (the loop's bound alone, ``PREDICT_BOUND``), else by ``kind``; not
    ``estimated``, the solve is left unestimated (``Estimate.skipped``: the loop's last level
    with ``adapt.estimate_last`` false).
    """
    adaptive = stopping is not None and previous is not None
    eta = None
    if adaptive:
        assert previous is not None  # adaptive needs the previous level's η
        V = problem.V
        rate = optimal_rate(V)
        eta = (
            PREDICTION_SAFETY
            * previous.estimate.eta
            * (previous.result.dofs / global_dofs(V)) ** rate
        )
    seconds["solve"] = seconds["estimate"] = 0.0
    krylov, passes = 0, 0
    while True:
        criterion = (  # eta is known exactly when the stopping is adaptive
            None if eta is None or stopping is None else AdaptiveStopping(eta, *stopping)
        )
        with Timer(seconds, "solve"):
            result = solve(problem, domain, u0, criterion)
        progress.note(f"{label}: solved ({result.dofs} DoFs), {seconds['solve']:.0f} s; estimating")
        if solved is not None:
            solved(result)
        if not estimated:
            est = Estimate.skipped()
            passes += 1
            break
        with Timer(seconds, "estimate"):
            which = bound_kind if bound_kind is not None and result.converged else kind
            est = estimate(result.problem or problem, result, which)
        krylov += result.krylov_iterations
        passes += 1
        if (
            criterion is None
            or not result.converged
            or criterion.balanced(est.eta)
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
    eta = f"{r['eta']:11.4e}" if r["eta"] != "" else f"{'-':>11s}"
    err = f"{r['error']:11.4e}" if r["error"] != "" else f"{'-':>11s}"
    eff = f"{r['effectivity']:6.2f}" if r["effectivity"] != "" else f"{'-':>6s}"
    its = solves_text(r["newton_iterations"], r["polish_solves"])
    return (
        f"{r['level']:5d} {r['dofs']:9d} {eta} {err} {eff} {its:>6s} "
        f"{r['active_nodes']:7d} {r.get('seconds_solve', 0):8.2f}"
    )


def _print_row(level: Level, header: bool) -> None:
    if header:
        print(_header(), flush=True)
    print(_format(level.row()), flush=True)
