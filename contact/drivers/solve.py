"""One contact solve of a scene.

Its discrete problem (built here unless given), the ``solver``
options with call-time overrides, an initial guess (grid sequencing, :mod:`.sequencing`, or
``solver.u0``), then the solve itself (:func:`contact.solvers.snes.solve_problem`), or the
Coulomb fixed point (:mod:`.fixed_point`).
"""

from __future__ import annotations

from typing import Any

from dolfinx import fem

from ..base.errors import ConfigError
from ..base.timing import Stopwatch, Timer
from ..models import build_problem
from ..models.problem import interpolate_expression
from ..setup.scene import Scene
from ..solvers import ncp
from ..solvers.options import BASELINE_METHODS
from ..solvers.problem import DiscreteProblem
from ..solvers.result import Result, not_unique_text
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
    alternative: fem.Function | None = None,
    **options: Any,
) -> Result:
    """Solve the scene's contact problem once, on its mesh.

    Without an initial guess, grid sequencing (``solver.sequence``) solves coarser meshes
    first when it pays, and the coarsest level (or a cold start) begins from the scene's
    ``solver.u0`` (zero by default). A frictional scene (``friction.law`` tresca or
    coulomb; fb, min, blend or a baseline) adds the tangential rows of the friction law (no
    polishing, the assembled block Jacobian) and returns the nodal friction fields in
    ``Result.friction``; ``friction.coulomb: fixed_point`` solves a sequence of Tresca
    problems instead. Collective; never raises on divergence (``Result.converged``).

    Args:
        scene: The scene to solve (:func:`contact.load_scene`).
        method: fb, min, blend, vinewtonrsls, vinewtonssls or a baseline enforcement
            (penalty, augmented_lagrangian, nitsche: :mod:`contact.solvers.baselines`);
            default the scene's ``solver.method``.
        problem: An assembled problem of this scene to reuse (built here if None).
        u0: An initial guess on the scene's mesh (Dirichlet values are put in).
        verbose: Print a line per Newton iteration (default: the scene's
            ``output.verbose``).
        criterion: Adaptive stopping against a discretization error (the adaptive loop
            makes one per level for ``solver.stopping: adaptive``; a single solve has no
            discretization error to balance against).
        alternative: Another guess beside ``u0`` (a load path's extrapolation); Newton
            starts from the one whose ‖Φ‖ is smaller (``Result.predictor`` says which).
        **options: Overrides of the scene's ``solver`` section, validated as in the scene
            file: ``mu``, ``c``, ``kappa``, ``line_search``, ``polish``, ``rtol``, ``atol``,
            ``max_it``, ``linear``, ``inexact``, ``sequence``, ``petsc_options``, …

    Returns:
        The solution, multiplier, gap, active set, iteration history and resultants.

    Raises:
        ConfigError: For an unknown or invalid option (one line naming it).
        ValueError: If ``scene`` is not a Scene, or ``problem`` or ``u0`` belong to
            another mesh.

    Example:
        >>> import contact
        >>> scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["adapt=none"])
        >>> fb = contact.solve(scene, method="fb", verbose=False)
        >>> pdas = contact.solve(scene, method="min", line_search="basic", verbose=False)
        >>> fb.converged, pdas.converged, fb.n_active == pdas.n_active, fb.dofs
        (True, True, True, 153)
        >>> contact.solve(scene, method="newton")
        Traceback (most recent call last):
        contact.base.errors.ConfigError: solver.method: 'newton' is not one of fb, min, ...
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
    if problem.current is not None and method not in ncp.METHODS:
        raise ConfigError(
            f"solver.method: {method} needs a gap affine in u (PETSc's VI bounds); contact on "
            "the current configuration (a hyperelastic body against a circle or sphere, or "
            "with friction) takes fb, min or blend"
        )
    if friction is not None:
        if method not in ncp.METHODS + BASELINE_METHODS:
            raise ConfigError(
                f"solver.method: {method} cannot solve frictional contact "
                f"(friction.law: {friction.law}); use fb, min or blend"
            )
        if (
            friction.law == "coulomb"
            and friction.options.coulomb == "fixed_point"
            and method in ncp.METHODS
        ):
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
    # A frictional load step after the first is sequenced too, its history carried to the
    # coarse meshes (.sequencing): its guess replaces the previous step's solution and the
    # predictor; without coarse levels the step starts from those
    if u0 is None or (scene.history and friction is not None):
        with Timer(timers, "coarse"):
            coarse, levels, note = sequencing.initial_guess(scene, problem.V, opts, solve, verbose)
        if coarse is not None:
            u0, alternative = coarse, None
    guess = u0 is not None  # given, or the coarse levels' solution
    if u0 is None:
        u0 = interpolate_expression(problem.V, opts.u0, scene, key="solver.u0")
    else:
        check_guess(u0, problem)
    if method in BASELINE_METHODS:
        from .baselines import solve_baseline

        result = solve_baseline(scene, problem, u0, opts.knobs(), verbose, timers, clock)
    else:
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
            alternatives=() if alternative is None else (alternative,),
        )
    result.sequence, result.sequence_note = levels, note
    if result.converged and problem.floating:
        # a body only frictionless contact holds may slide: u_h is then one of many
        import warnings

        from ..setup.surfaces import ContactWarning
        from ..solvers.floating import free_in_contact

        bodies = config.bodies
        free = free_in_contact(
            problem, scene.bodies if bodies else None, list(bodies or ()), result.active_mask
        )
        if free and scene.comm.rank == 0:
            warnings.warn(not_unique_text(free), ContactWarning, stacklevel=1)
    return result
