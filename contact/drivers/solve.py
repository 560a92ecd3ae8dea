"""One contact solve of a scene: its discrete problem (built here unless given), the
``solver`` options with call-time overrides, an initial guess (grid sequencing,
:mod:`.sequencing`, or ``solver.u0``), then the solve itself
(:func:`contact.solvers.snes.solve_problem`), or the Coulomb fixed point
(:mod:`.fixed_point`)."""

from __future__ import annotations

from typing import Any

from dolfinx import fem

from ..base.errors import ConfigError
from ..base.timing import Stopwatch, Timer
from ..models import build_problem
from ..models.problem import interpolate_expression
from ..setup.scene import Scene
from ..solvers import ncp
from ..solvers.problem import DiscreteProblem
from ..solvers.result import Result
from ..solvers.snes import check_guess, solve_problem
from ..solvers.stopping import AdaptiveStopping
from . import sequencing


def solve(
    scene: Scene,
    method: str | None = None,
    problem: DiscreteProblem | None = None,
    u0: fem.Function | None = None,
    verbose: bool | None = None,
    criterion: AdaptiveStopping | None = None,
    **options: Any,
) -> Result:
    """Solve the scene's contact problem; return a :class:`Result` (never raises on divergence).

    ``method`` ∈ {fb, min, blend, vinewtonrsls, vinewtonssls}; further keyword options
    override the scene's ``solver`` section (``mu``, ``c``, ``kappa``, ``line_search``,
    ``polish``, ``rtol``, ``atol``, ``max_it``, ``linear``, ``inexact``, ``sequence``,
    ``petsc_options``).  ``problem`` reuses an assembled problem, ``u0`` is an initial guess;
    without one, grid sequencing (``sequence``, :mod:`.sequencing`) solves coarser meshes
    first when it pays, and the coarsest level (or a cold start) begins from the scene's
    ``solver.u0`` (zero by default).
    A frictional scene (``friction.law`` tresca / coulomb; fb, min or blend only) adds the
    tangential rows of :mod:`contact.solvers.friction` (no polishing, the assembled block
    Jacobian) and returns the nodal friction fields in ``Result.friction``;
    ``friction.coulomb: fixed_point`` solves a sequence of Tresca problems instead
    (:func:`~contact.drivers.fixed_point.coulomb_fixed_point`).  ``criterion``: adaptive
    stopping against a discretization error (:mod:`contact.solvers.stopping`; the adaptive
    loop makes one per level for ``solver.stopping: adaptive``, which a single solve
    ignores: it has no discretization error to balance against).
    """
    if problem is not None and problem.V.mesh is not scene.mesh:
        raise ValueError("problem: was built for another scene's mesh")
    config = scene.config  # validated at load, immutable: only the call's overrides are checked
    opts = config.solver.updated(config.constants, method=method, **options)
    method = opts.method
    verbose = config.output.verbose if verbose is None else verbose
    built_here = problem is None
    problem = problem or build_problem(scene)
    friction = problem.friction
    if friction is not None:
        if method not in ncp.METHODS:
            raise ConfigError(
                f"solver.method: {method} cannot solve frictional contact "
                f"(friction.law: {friction.law}); use fb, min or blend"
            )
        if friction.law == "coulomb" and friction.options.coulomb == "fixed_point":
            from .fixed_point import coulomb_fixed_point

            return coulomb_fixed_point(
                scene, problem, u0, verbose, built_here, solve, method=method, **options
            )
    # the problem's assembly counts once: in the solve that built it
    built = problem.assembly_time if built_here else 0.0
    clock = Stopwatch(before=built)
    timers = {"assembly": built, "solve": 0.0}

    # Initial guess with the Dirichlet values in place: grid sequencing, or solver.u0.
    levels: list[sequencing.CoarseLevel] = []
    note = ""
    if u0 is None:
        with Timer(timers, "coarse"):
            u0, levels, note = sequencing.initial_guess(scene, problem.V, opts, solve, verbose)
    guess = u0 is not None  # given, or the coarse levels' solution
    if u0 is None:
        u0 = interpolate_expression(problem.V, opts.u0, scene, key="solver.u0")
    else:
        check_guess(u0, problem)
    result = solve_problem(
        problem,
        u0,
        opts.knobs(),
        scene.comm,
        verbose,
        guess,
        timers,
        clock,
        check_options=bool(options.get("petsc_options")),
        stopping=criterion,
    )
    result.sequence, result.sequence_note = levels, note
    if result.converged and problem.floating:
        warn_if_not_unique(scene, problem, result)
    return result


def warn_if_not_unique(scene: Scene, problem: DiscreteProblem, result: Result) -> None:
    """A body that only frictionless contact holds may slide: the displacement of a
    converged ``result`` is then one of infinitely many (any sliding of the body along its
    free rigid motions solves the problem as well, :func:`contact.models.floating.free_in_contact`);
    its strains, stresses and contact forces are unique.  Say so in one ContactWarning line
    (rank 0) naming the body — which copy the solver returned depends on the linear
    solver's null pivots, i.e. on rounding."""
    from ..models.floating import free_in_contact

    bodies = scene.config.bodies
    free = free_in_contact(
        problem,
        scene.bodies if bodies else None,
        list(bodies) if bodies else [],
        result.active_mask,
    )
    if free and scene.comm.rank == 0:
        import warnings

        from ..setup.surfaces import ContactWarning

        name, n = free[0]
        warnings.warn(
            f"the displacement is not unique: {'body ' + name if name else 'the body'} keeps "
            f"{n} free rigid motion(s) with its contact nodes active (no dirichlet or symmetry "
            "part holds it, and frictionless contact never holds a sliding motion); the "
            "stresses and contact forces are unique, u_h is one of the solutions",
            ContactWarning,
            stacklevel=2,
        )
