"""One contact solve of a problem.

Its options, an initial guess (given, from the coarser levels of a
:class:`~.sequencing.Hierarchy`, or the problem's own start), then the solve itself
(:func:`contact.solvers.snes.solve_problem`), or the Coulomb fixed point
(:mod:`.fixed_point`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from dolfinx import fem

from ..base.errors import ConfigError
from ..base.timing import Stopwatch, Timer
from ..models.discrete import discrete
from ..models.problem import first_contact_point
from ..solvers import ncp
from ..solvers.options import BASELINE_METHODS, SolverOptions
from ..solvers.problem import DiscreteProblem
from ..solvers.result import Result
from ..solvers.snes import check_guess, solve_problem
from ..solvers.stopping import AdaptiveStopping
from . import sequencing

#: a baseline enforcement's solve: (problem, initial guess, options, verbose, timers, clock)
Enforce = Callable[[DiscreteProblem, fem.Function, SolverOptions, bool, dict, Stopwatch], Result]


def options_of(options: SolverOptions | None, method: str | None, overrides: dict) -> SolverOptions:
    """Return solver options with the call's method and overrides, validated.

    ``options`` (default: the defaults) with ``method`` and keyword ``overrides``, each
    validated (one ConfigError line naming the key).
    """
    base = options if options is not None else SolverOptions()
    given = {k: v for k, v in {"method": method, **overrides}.items() if v is not None}
    if not given:
        return base
    checked = SolverOptions.parse(given)
    return base.model_copy(update={k: getattr(checked, k) for k in given})


def solve(
    problem: Any,
    method: str | None = None,
    *,
    options: SolverOptions | None = None,
    u0: fem.Function | None = None,
    start: Callable[[fem.FunctionSpace], fem.Function] | None = None,
    coarse: sequencing.Hierarchy | None = None,
    verbose: bool = False,
    criterion: AdaptiveStopping | None = None,
    alternative: fem.Function | None = None,
    assembly: float = 0.0,
    check_options: bool = False,
    enforce: Enforce | None = None,
    **overrides: Any,
) -> Result:
    """Solve a contact problem once.

    Solve a contact problem; return its :class:`~contact.solvers.result.Result` (never
    raises on divergence).

    Args:
        problem: a :class:`~contact.models.forms.ComplementarityProblem` or a model's problem.
        method: fb, min, blend, vinewtonrsls or vinewtonssls (default: ``options``').
        options: the solver's :class:`~contact.solvers.options.SolverOptions` (default: the
            defaults); ``overrides`` (``rtol``, ``linear``, …) change single knobs.
        u0: the initial guess, a function on the problem's space (a real guess: it is
            polished first, and the gamg path takes an exact first step).
        start: the cold start on a space when there is no guess (default: the problem's
            ``u_h`` as it is).
        coarse: grid sequencing: its coarser levels are solved first and the last one's
            solution is the guess, when there is no ``u0`` or ``coarse.replaces_guess``.
        verbose: print the Newton history (rank 0).
        criterion: adaptive stopping against a discretization error
            (:mod:`contact.solvers.stopping`).
        alternative: another guess beside ``u0``; Newton starts from the one of smaller ‖Φ‖
            (``Result.predictor`` says which).
        assembly: seconds already spent assembling the problem for this solve (counted in
            its timings).
        check_options: check ``options.petsc_options`` on a tiny system first.
        enforce: the solve of a baseline enforcement (penalty, augmented Lagrangian,
            Nitsche: ``enforce(problem, u0, options, verbose, timers, clock)``) in place of
            semismooth Newton, for those methods (a scene's solve gives it).
        **overrides: single knobs of ``options`` (``rtol``, ``linear``, …), validated.

    Returns:
        The result.  A frictional problem (its law Tresca or Coulomb) takes fb, min or blend
        and returns the nodal friction fields in ``Result.friction``; Coulomb with
        ``friction.coulomb: fixed_point`` is solved as a sequence of Tresca problems
        (:func:`~.fixed_point.coulomb_fixed_point`).
    """
    p = discrete(problem)
    opts = options_of(options, method, overrides)
    method = opts.method
    friction = p.friction
    if p.current is not None and method not in ncp.METHODS:
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

            def tresca(guess: fem.Function | None) -> Result:
                return solve(
                    p,
                    options=opts,
                    u0=guess,
                    start=start,
                    coarse=coarse,
                    check_options=check_options,
                )

            return coulomb_fixed_point(p, u0, verbose, assembly, tresca)
    # the problem's assembly counts once: in the solve that built it
    clock = Stopwatch(before=assembly)
    timers = {"assembly": assembly, "solve": 0.0}

    # the initial guess with the Dirichlet values in place: given, sequenced, or the start
    levels: list[sequencing.CoarseLevel] = []
    note = ""
    if coarse is not None and (u0 is None or coarse.replaces_guess):
        with Timer(timers, "coarse"):
            guess, levels, note = sequencing.initial_guess(coarse, p.V, verbose, method)
        if guess is not None:
            u0, alternative = guess, None
    given = u0 is not None  # given, or the coarse levels' solution
    if u0 is None:
        u0 = start(p.V) if start is not None else p.u_h
    else:
        check_guess(u0, p)
    if method in BASELINE_METHODS:
        if enforce is None:
            raise ConfigError(
                f"solver.method: {method} needs the constraint as UFL, which a scene's "
                "problem gives (contact.solve(scene, ...)); use fb, min or blend"
            )
        result = enforce(p, u0, opts, verbose, timers, clock)
    else:
        result = solve_problem(
            p,
            u0,
            opts,
            p.V.mesh.comm,
            verbose,
            given,
            timers,
            clock,
            check_options=check_options,
            stopping=criterion,
            alternatives=() if alternative is None else (alternative,),
        )
    result.sequence, result.sequence_note = levels, note
    contact_figures(p, result)
    return result


def contact_figures(problem: DiscreteProblem, result: Result) -> None:
    """Put the figures of a solved problem's contact conditions on its result.

    The first point of contact (``Result.first_contact``) and, with mortar pairs and the
    problem's reaction form (``ProblemData.reaction_form``, which a scene's elastic bodies
    set), the forces on their surfaces (``Result.interface_forces``).  Collective.

    Args:
        problem: the problem solved, its displacement at the solution.
        result: its result.
    """
    comm = problem.V.mesh.comm
    result.first_contact = first_contact_point(
        comm, problem.node_coordinates(), problem.contact_gaps()
    )
    # mortar pairs with a reaction form, a(u_h, v) − L(v) in u's own components (a scene's
    # elastic bodies); a scalar problem loads no multi-body module
    if problem.data.couplings and problem.data.reaction_form is not None:
        from ..models.mortar import interface_forces

        result.interface_forces = interface_forces(problem)


def sequence(
    build: Callable[[Any], Any],
    levels: Sequence[Any],
    method: str | None = None,
    *,
    options: SolverOptions | None = None,
    verbose: bool = False,
    **overrides: Any,
) -> tuple[Any, Result]:
    """Grid-sequence a user's problem over a list of meshes (docs/theory.md §8).

    Grid sequencing of a user's problem (docs/theory.md §8): ``build(level)`` on each of
    ``levels`` (meshes or :class:`~contact.adaptivity.refine.Domain` objects, coarsest
    first), each solved from the coarser solution carried over (exact prolongation along
    refinements, point location between other meshes), the coarse ones to
    ``COARSE_RTOL``.

    Args:
        build: the problem on a level (a :class:`~contact.models.forms.ComplementarityProblem`
            or a model's problem).
        levels: the meshes (or domains), coarsest first; the last is the one to solve on.
        method: fb, min, blend, vinewtonrsls or vinewtonssls.
        options: the :class:`~contact.solvers.options.SolverOptions` of the finest solve;
            ``overrides`` change single knobs.
        verbose: print each level's Newton history (rank 0).
        **overrides: single knobs of ``options``, validated.

    Returns:
        (the finest level's problem, its result; ``Result.sequence`` lists the coarse
        levels' solves).

    Example:
        >>> import contact, numpy as np, ufl
        >>> from dolfinx import fem, mesh
        >>> from mpi4py import MPI
        >>> def build(msh):  # −Δu = 10 in Ω, u = 0 on ∂Ω, u ≤ 0.05
        ...     V = fem.functionspace(msh, ("Lagrange", 1))
        ...     u, v = fem.Function(V), ufl.TestFunction(V)
        ...     F = ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx - 10 * v * ufl.dx
        ...     edge = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
        ...     bc = fem.dirichletbc(0.0, fem.locate_dofs_topological(V, 1, edge), V)
        ...     cap = contact.Unilateral(0.05)
        ...     return contact.ComplementarityProblem.from_residual(F, u, cap, [bc])
        >>> meshes = [mesh.create_unit_square(MPI.COMM_WORLD, n, n) for n in (8, 16, 32)]
        >>> problem, result = contact.sequence(build, meshes)
        >>> result.converged, [level.dofs for level in result.sequence], result.dofs
        (True, [81, 289], 1089)
        >>> problem.close()
    """
    opts = options_of(options, method, overrides)
    coarse_opts = opts.model_copy(update={"rtol": sequencing.COARSE_RTOL})
    *coarse, fine = list(levels)
    problem = build(fine)
    h = sequencing.hierarchy(
        build,
        coarse,
        fine,
        lambda p, u0: solve(p, options=coarse_opts, u0=u0),
    )
    return problem, solve(problem, options=opts, coarse=h, verbose=verbose)
