"""The hp-adaptive loop SOLVE → ESTIMATE → MARK (h or p) → REFINE (docs/theory.md §11).

Each level builds V_hp for the cells' degrees (:class:`.space.HPSpace`, inside the
Lagrange space of the level's largest degree, not of p_max: a level whose cells are all of
low degree assembles, solves and estimates at that degree), solves the
Signorini problem in the hp unknowns (:func:`.problem.hp_problem`; an elastic body against a
rigid plane in V_hp^d, :func:`.elastic.hp_elastic_problem`; the scene's solver), estimates
(:func:`.estimate.hp_estimate`: the equilibrated bound, or the residual estimator with h/p
weights — the only one for elasticity), marks by Dörfler and splits the marks into h and p
(:mod:`.mark`), then refines the h cells' edges (their children keep the degree) and
raises the p cells' degree.  The previous level's u_h, interpolated onto the new mesh, is
the next initial guess (nested iteration, also when only degrees changed: V_hp grows, u_h
stays in it), so Newton needs few steps per level.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from ..adaptivity.energy_error import solution_error
from ..adaptivity.estimate import Estimate
from ..adaptivity.mark import mark
from ..base.errors import ConfigError
from ..base.timing import Timer
from ..drivers.adaptive import AdaptResult, check_on_level, rank_imbalance
from ..models.discrete import Problem
from ..setup import run as h_adaptive
from ..setup.run import SceneLevel, adapt_options, refine, scene_domain, solve
from ..setup.scene import Scene
from .estimate import hp_estimate
from .mark import SIGMA0, child_degrees, decay_rates, front_cells, hp_mark
from .problem import hp_problem
from .space import HPSpace

#: Newton's tolerances in the hp loop (relative, and absolute against the force scale): an hp
#: loop goes on to errors of 1e-7 on cells of size 1e-6, where a nodal multiplier
#: λ_i = R_i / w_i turns an algebraic residual R_i of 1e-12 at an inactive node into a
#: multiplier the bound's complementarity term sees (problem A, p_max 6, 30 levels: with
#: 1e-10 the error stalled at 2.8e-7 and η rose to 5e-7; with these it went on to 1.8e-7,
#: effectivity 1.28).  The solver's round-off floor keeps them attainable.
NEWTON_RTOL, NEWTON_ATOL = 1e-14, 1e-15
#: Dörfler's θ of the hp loop when neither the scene nor the caller gives one: larger than
#: the h loop's 0.5, as a marked cell gains one degree per level; the largest θ measured
#: whose bound kept η / error ≤ 1.5 past the third level on problems A and C
#: (demos/RESULTS.md §15)
HP_THETA = 0.85
#: the choices of the Lagrange space each level assembles in (:func:`adapt_hp`)
SPACE_DEGREES = ("used", "p_max")


@dataclass
class HPLevel(SceneLevel):
    """A level of the hp loop: a scene's level (:class:`~contact.setup.run.SceneLevel`) and
    its space.

    Attributes:
        space: The level's hp space (its degrees: ``space.cell_degrees``).
        h_cells: Cells refined in h after this level (global count).
        p_cells: Cells refined in p after this level (global count).
    """

    space: HPSpace | None = None
    h_cells: int = 0
    p_cells: int = 0

    def row(self) -> dict[str, Any]:
        """The level's row (:meth:`Level.row`) with the hp columns: p_min, p_max, the
        cells refined in h and in p."""
        row = super().row()
        assert self.space is not None
        comm = self.scene.comm
        n = self.scene.mesh.topology.index_map(self.scene.mesh.topology.dim).size_local
        degs = self.space.cell_degrees[:n]
        row["p_min"] = comm.allreduce(int(degs.min(initial=99)), op=MPI.MIN)
        row["p_max"] = comm.allreduce(int(degs.max(initial=0)), op=MPI.MAX)
        row["h_cells"], row["p_cells"] = self.h_cells, self.p_cells
        return row


def adapt_hp(
    scene: Scene,
    p_max: int = 6,
    p_start: int = 1,
    theta: float = 0.5,
    tol: float = 0.0,
    max_dofs: int = 200_000,
    max_levels: int = 30,
    sigma0: float = SIGMA0,
    estimator: str = "equilibrated",
    on_level: Callable[[HPLevel], None] | None = None,
    verbose: bool = False,
    newton_rtol: float | None = None,
    front_degree: int | None = 1,
    refine_front: bool = False,
    space_degree: str = "used",
    estimate_last: bool = True,
) -> AdaptResult:
    """Run the hp-adaptive loop (module docstring) on a scalar Signorini scene or an elastic
    body against a rigid coordinate plane.

    Args:
        scene: The first level's scene (its mesh: the coarse mesh).
        p_max: The largest degree (V_hp ⊂ P_{p_max}).
        p_start: The first level's degree of every cell, and the smallest degree the loop
            lowers a cell to.
        theta: Dörfler's θ.
        tol: Stop when η ≤ tol.
        max_dofs: Stop before a level with more hp unknowns.
        max_levels: Stop after this many levels.
        sigma0: The decay rate above which a marked cell is p-refined (:mod:`.mark`).
        estimator: ``equilibrated`` (the guaranteed bound, scalar only) or ``residual``
            (h/p weights).
        on_level: Called with each level once it is estimated and marked; its seconds are
            not counted in the levels' ``elapsed`` and ``cpu`` (the time to accuracy).
        verbose: Print a row per level.
        newton_rtol: Newton's relative tolerance (default :data:`NEWTON_RTOL`).
        front_degree: The largest degree of the free boundary's cells (:func:`.mark.hp_mark`),
            raised to ``p_start``: lowering a cell below the first level's degree, with one
            split, discards accuracy the first level had (u ∈ H^{5/2−ε} there: the energy
            error of P_2 on h is of order h^{3/2}, of P_1 on h/2 of order h/2), and the
            error would grow from one level to the next.
        refine_front: h-refine the free boundary's cells on every level (:func:`.mark.hp_mark`).
        space_degree: The degree of the Lagrange space V ⊇ V_hp each level assembles in:
            ``used`` (the largest p_T of the level: V_hp ⊂ P_{max p_T}, so a level whose
            cells are all of low degree assembles, solves and estimates at that degree) or
            ``p_max`` (P_{p_max} on every level).
        estimate_last: False: the level ``max_levels`` is solved and not estimated (no η,
            η_T or effectivity): the loop ends with its solution.

    Returns:
        The levels (``HPLevel``) and why the loop stopped.
    """
    if space_degree not in SPACE_DEGREES:
        raise ValueError(f"space_degree: expected one of {SPACE_DEGREES}, got {space_degree!r}")
    comm = scene.comm
    tdim = scene.mesh.topology.dim
    rtol = newton_rtol or NEWTON_RTOL
    build: Callable[[Scene, HPSpace], Problem] = hp_problem
    elastic = scene.config.model.type == "elasticity"
    if elastic:
        from .elastic import hp_elastic_problem  # a scalar scene never imports elasticity

        build, estimator = hp_elastic_problem, "residual"
    n = scene.mesh.topology.index_map(tdim).size_local
    degrees = np.full(n, min(p_start, p_max), dtype=np.int32)
    if front_degree is not None:
        front_degree = max(front_degree, min(p_start, p_max))
    out = AdaptResult()
    u0: fem.Function | None = None
    # the loop's clocks, wall and CPU, and the outputs' shares of them (Level.elapsed, .cpu)
    start, outputs = time.perf_counter(), 0.0
    start_cpu, outputs_cpu = time.process_time(), 0.0
    for index in range(max_levels):
        seconds: dict[str, float] = {}
        t0 = time.perf_counter()
        caps = scene.boundary.facets("contact") if tdim == 3 or elastic else None
        top = p_max
        if space_degree == "used":
            top = comm.allreduce(int(degrees.max(initial=1)), op=MPI.MAX)
        space = HPSpace(scene.mesh, top, degrees, caps=caps)
        problem = build(scene, space)
        seconds["assembly"] = time.perf_counter() - t0
        if u0 is None:
            u0 = fem.Function(problem.V)
        elif u0.function_space.ufl_element() != problem.V.ufl_element():
            u0 = _raised(u0, problem.V)
        with Timer(seconds, "solve"):
            atol = min(NEWTON_ATOL, scene.config.solver.atol)
            result = solve(
                scene, problem=problem, u0=u0, verbose=False, rtol=rtol, atol=atol, sequence="off"
            )
        result.__dict__["dofs"] = problem.unknowns()  # the hp unknowns, not V's DoFs
        solved_wall, solved_cpu = time.perf_counter(), time.process_time()
        if estimate_last or index + 1 < max_levels:
            with Timer(seconds, "estimate"):
                est = hp_estimate(scene, result, space, estimator)
        else:  # the last level, known before its estimate
            est, seconds["estimate"] = Estimate.skipped(), 0.0
        error_cpu = time.process_time()
        with Timer(seconds, "error"):
            error = solution_error(problem, result)
        error_cpu = time.process_time() - error_cpu
        imbalance = rank_imbalance(space.V)
        level = HPLevel(
            index,
            scene_domain(scene),
            problem,
            result,
            est,
            error,
            seconds,
            imbalance,
            scene=scene,
            space=space,
            elapsed=time.perf_counter() - start - outputs,
            cpu=time.process_time() - start_cpu - outputs_cpu,
            solved_elapsed=solved_wall - start - outputs + seconds["error"],
            solved_cpu=solved_cpu - start_cpu - outputs_cpu + error_cpu,
        )
        out.levels.append(level)
        stop = _stop(result, est.eta, tol, index, max_levels)
        if not stop:
            assert est.eta_T is not None  # an unestimated level is the last
            with Timer(seconds, "mark"):
                marked = mark(est.eta_T, "dorfler", theta)
                front = front_cells(problem, result.active_mask, scene.boundary.facets("contact"))
                sigma = decay_rates(result.u_h, degrees)
                marks = hp_mark(
                    marked, degrees, sigma, front, p_max, sigma0, front_degree, refine_front
                )
            level.h_cells = comm.allreduce(len(marks.h))
            level.p_cells = comm.allreduce(len(marks.p))
        if on_level is not None:
            cpu = time.process_time()
            with Timer(seconds, "output"):
                on_level(level)
            outputs += seconds["output"]
            outputs_cpu += time.process_time() - cpu
        if verbose and comm.rank == 0:
            r = level.row()
            print(
                f"{index:3d} {r['dofs']:8d} {r['cells']:7d} p {r['p_min']}-{r['p_max']} "
                f"eta {'-' if r['eta'] == '' else format(r['eta'], '.3e')} "
                f"err {r['error'] if r['error'] != '' else '-'} "
                f"h {level.h_cells} p {level.p_cells} solve {seconds['solve']:.2f} "
                f"est {seconds['estimate']:.2f}",
                flush=True,
            )
        if stop:
            out.stop = stop
            break
        with Timer(seconds, "refine"):
            if level.h_cells:
                new_scene, new_u0 = refine(scene, marks.h, result.u_h)
                assert new_scene.parent is not None and new_u0 is not None
                degrees = child_degrees(
                    marks.degrees, scene.mesh, new_scene.mesh, new_scene.parent[1]
                )
            else:  # only degrees change: the same mesh, u_h stays in the larger V_hp
                new_scene, new_u0, degrees = scene, result.u_h, marks.degrees
        bs = problem.V.dofmap.index_map_bs
        if bs * comm.allreduce(_next_size(new_scene, degrees, p_max), op=MPI.SUM) > max_dofs:
            out.stop = f"the next level would have more than max_dofs = {max_dofs} unknowns"
            break
        scene, u0 = new_scene, new_u0
    return out


def adapt(
    scene: Scene,
    method: str | None = None,
    on_level: Callable[[SceneLevel], None] | None = None,
    verbose: bool | None = None,
    u0: fem.Function | None = None,
    keep: Callable[[SceneLevel], bool] | None = None,
    **options: Any,
) -> AdaptResult:
    """Run the adaptive loop SOLVE → ESTIMATE → MARK → REFINE on a scene.

    h-refinement (``contact.setup.run.adapt``), or with ``strategy="hp"`` h- or
    p-refinement of each marked cell (``adapt_hp``: the scalar signorini model, or one
    linear elastic body against a rigid coordinate plane).

    The loop stops when η ≤ ``tol``, before a level would exceed ``max_dofs`` (or the DoF
    budget ``solver.max_dofs`` of the h loop), after ``max_levels`` levels, or when a solve
    does not converge (the levels before it are kept).  Each level after the first starts
    from the previous level's solution.  Collective.

    Args:
        scene: The first level's scene.
        method: The solver method of the h loop (fb, min, blend, vinewtonrsls,
            vinewtonssls); default the scene's ``solver.method``.
        on_level: Called with each level (:class:`~contact.setup.run.SceneLevel`) once it is
            estimated (the CLI writes the level's files there).
        verbose: Print a table row per level (default: the scene's ``output.verbose``).
        u0: The h loop's first initial guess (a load step's previous solution).
        keep: Which levels of the h loop keep their solution once the next level is
            solved (``contact.drivers.adaptive.adapt``); the hp loop keeps every level.
        **options: Overrides of the scene's ``adapt`` section: ``strategy`` (dorfler,
            maximum, uniform, hp, none), ``theta``, ``tol``, ``max_dofs``, ``max_levels``,
            ``nested``, ``newton_rtol``, ``rebalance``, ``pictures``; for hp ``p_max`` (the
            largest degree) and ``p_start`` (every cell's first degree); hp's ``theta`` is
            ``HP_THETA`` unless the scene or the call gives one.  The hp loop takes
            the scene's ``estimator`` (``residual``: the h/p-weighted residual estimator;
            otherwise the guaranteed equilibrated bound; elasticity: always the residual
            estimator).

    Returns:
        The levels (``HPLevel``, with the degrees, for hp) and why the loop stopped.

    Raises:
        ConfigError: For an unknown or invalid option, or ``strategy="hp"`` on a model
            other than signorini and elasticity (one line naming it).
        ValueError: If ``scene`` is not a Scene or ``on_level`` is not callable.

    Example:
        >>> import contact
        >>> scene = contact.load_scene("configs/signorini_free_boundary.yaml")
        >>> run = contact.adapt(scene, max_levels=3, verbose=False)
        >>> [level.index for level in run.levels], run.stop
        ([0, 1, 2], 'reached max_levels = 3')
        >>> run.levels[-1].error < run.levels[0].error
        True
        >>> smooth = contact.load_scene("configs/signorini_smooth.yaml")
        >>> hp = contact.adapt(smooth, strategy="hp", p_max=4, max_levels=3, verbose=False)
        >>> [(level.row()["p_min"], level.row()["p_max"]) for level in hp.levels]
        [(1, 1), (1, 2), (1, 3)]
    """
    opts = adapt_options(scene, **options)
    if opts.strategy != "hp":
        return h_adaptive.adapt(scene, method, on_level, verbose, u0, keep=keep, **options)
    check_on_level(on_level)
    if scene.config.model.type not in ("signorini", "elasticity"):
        raise ConfigError(
            "adapt.strategy: hp solves the signorini and elasticity models, "
            f"not {scene.config.model.type!r}"
        )
    if opts.p_start > opts.p_max:
        raise ConfigError(f"adapt.p_start: must be <= p_max = {opts.p_max}, got {opts.p_start}")
    return adapt_hp(
        scene,
        p_max=opts.p_max,
        p_start=opts.p_start,
        theta=opts.theta if _theta_given(scene, options) else HP_THETA,
        tol=opts.tol,
        max_dofs=opts.max_dofs,
        max_levels=opts.max_levels,
        estimate_last=opts.estimate_last,
        estimator="residual" if scene.config.estimator == "residual" else "equilibrated",
        on_level=on_level,
        verbose=scene.config.output.verbose if verbose is None else verbose,
    )


def _theta_given(scene: Scene, options: dict[str, Any]) -> bool:
    """Whether Dörfler's θ is the caller's or the scene's own (else the hp default)."""
    section = scene.config.adapt
    return options.get("theta") is not None or (
        section is not None and "theta" in section.model_fields_set
    )


def _raised(u: fem.Function, V: fem.FunctionSpace) -> fem.Function:
    """``u`` (Lagrange, on V's mesh, of a degree ≤ V's) as a function of V: exact, as
    interpolation of a polynomial of lower degree is."""
    out = fem.Function(V)
    out.interpolate(u)
    return out


def _next_size(scene: Scene, degrees: np.ndarray, p_max: int) -> int:
    """A rank's share of a lower bound of the next level's unknowns: Σ over its owned cells
    of their interior nodes (a cheap bound; the vertices and edges come on top)."""
    d = scene.mesh.topology.dim
    p = degrees.astype(np.int64)
    inner = (p - 1) * (p - 2) // 2 if d == 2 else (p - 1) * (p - 2) * (p - 3) // 6
    return int(np.sum(np.maximum(inner, 0)))


def _stop(result, eta: float, tol: float, index: int, max_levels: int) -> str:
    if not result.converged:
        return f"solver did not converge on level {index} ({result.reason})"
    if eta <= tol:
        return f"eta = {eta:.3e} <= tol = {tol:.3e}"
    if index + 1 >= max_levels:
        return f"reached max_levels = {max_levels}"
    return ""
