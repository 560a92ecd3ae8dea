"""A scene's solve, estimate, refinement, adaptive loop and load path.

A scene's solve, estimate, refinement, adaptive loop and load path: the scene's problem
built (:func:`contact.setup.build.build_problem`), its options and data read, and handed to the
drivers of problems (``contact.drivers.solve.solve``,
``contact.adaptivity.estimate.estimate``, ``contact.adaptivity.refine.refine`` on the
scene's mesh as a :class:`~contact.adaptivity.refine.Domain`,
``contact.drivers.adaptive.adapt``, ``contact.drivers.load_path.run_steps``); the
scene's grid sequencing is :mod:`.levels`.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from dolfinx import fem

from ..adaptivity.estimate import Estimate
from ..adaptivity.estimate import estimate as estimate_problem
from ..adaptivity.refine import Domain
from ..adaptivity.refine import refine as refine_domain
from ..base.errors import ConfigError, ContactWarning
from ..drivers.adaptive import AdaptResult, Level, check_on_level
from ..drivers.adaptive import adapt as adapt_domain
from ..drivers.load_path import LoadPath, Previous, Step, run_steps
from ..drivers.recouple import COUPLING_RTOL, solve_recoupled
from ..drivers.sequencing import COARSE_RTOL, initial_guess
from ..drivers.solve import Enforce
from ..drivers.solve import solve as solve_problem
from ..models.discrete import Problem
from ..solvers import Result
from ..solvers.floating import free_in_contact
from ..solvers.options import BASELINE_METHODS
from ..solvers.problem import DiscreteProblem
from ..solvers.result import not_unique_text
from ..solvers.stopping import AdaptiveStopping
from .build import build_problem
from .data import interpolate_expression
from .levels import scene_hierarchy
from .meshes import Boundary
from .posed import PosedProblem, posed_of
from .scene import Scene, require_scene
from .scene_config import AdaptConfig, SceneConfig
from .untagged import report_as, warn_untagged


def estimate(subject: Any, result: Result, kind: str | None = None) -> Estimate:
    """Estimate the error of a solve (the ESTIMATE step of the adaptive loop).

    ``residual`` assembles each term of η_T² once as a DG0 vector (docs/theory.md §5;
    reliable up to an unknown constant); ``equilibrated`` and ``equilibrated_rt0``
    reconstruct an equilibrated flux and return a guaranteed bound ‖u − u_h‖_E ≤ η
    (docs/theory.md §9). For a scene the default kind is its ``estimator`` (``auto``:
    ``equilibrated`` for the scalar models, ``residual`` for elasticity); for a problem
    (``contact.adaptivity.estimate.estimate``) it is ``residual``, and the problem must
    declare its physics. Collective.

    Args:
        subject: The :class:`~contact.setup.scene.Scene` that was solved, or a problem with
            its physics declared (a :class:`~contact.models.forms.ComplementarityProblem`).
        result: A solve of it on its mesh (:func:`contact.solve`).
        kind: ``residual``, ``equilibrated`` or ``equilibrated_rt0``; None: the default.

    Returns:
        The indicators η_T, the global η and each term's total.

    Raises:
        ValueError: If ``result`` is not a solve of ``subject`` on its mesh.

    Example:
        >>> import contact
        >>> scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["adapt=none"])
        >>> est = contact.estimate(scene, contact.solve(scene, verbose=False))
        >>> est.eta > 0, sorted(est.terms)[:2]
        (True, ['complementarity', 'dirichlet'])
    """
    if not isinstance(subject, Scene):
        if subject is None or isinstance(subject, (str, bytes)) or not hasattr(subject, "V"):
            if getattr(subject, "problem", None) is None:
                raise ValueError(
                    "scene: expected a contact.Scene (from contact.load_scene) or a problem, "
                    f"got {type(subject).__name__}"
                )
        return estimate_problem(subject, result, kind or "residual")
    if not isinstance(result, Result) or result.u_h.function_space.mesh is not subject.mesh:
        raise ValueError(
            "result: expected the contact.Result of contact.solve on this scene (same mesh)"
        )
    return estimate_problem(result.problem, result, kind or subject.config.estimator)


def scene_domain(scene: Scene) -> Domain:
    """Return the scene's mesh as a :class:`~contact.adaptivity.refine.Domain`.

    The scene's mesh as a :class:`~contact.adaptivity.refine.Domain`: its boundary tags,
    body tags, the mesh builder's surface tags (``surfaces``), the history functions, and
    the snapping of curved boundary parts (the declared ``surface`` of a part, the curved
    surfaces of the built-in Hertz meshes).
    """
    return Domain(
        scene.mesh,
        scene.boundary.tags,
        scene.bodies,
        {} if scene.surfaces is None else {"surfaces": scene.surfaces},
        dict(scene.history),
        scene.snap,
    )


def on_domain(scene: Scene, domain: Domain, parent: Scene | None = None) -> Scene:
    """Return the scene on another domain of its mesh's (a refinement of it).

    The scene on another domain of its mesh's (a refinement of it): the same configuration,
    boundary parts and pseudo-time, the domain's tags and functions; ``parent`` the scene of
    the domain's parent (the coarser levels of grid sequencing).
    """
    bnd = scene.boundary
    assert domain.facets is not None  # a scene's domain has its boundary tags
    return Scene(
        scene.config,
        domain.mesh,
        Boundary(domain.facets, dict(bnd.ids), dict(bnd.roles)),
        time=scene.time,
        history=dict(domain.functions),
        previous_time=scene.previous_time,
        bodies=domain.cells,
        surfaces=domain.tags.get("surfaces"),
        parent=None if parent is None or domain.parent is None else (parent, domain.parent[1]),
        snap=scene.snap,
        budget=scene.budget,
    )


def refine(
    scene: Scene,
    cells: np.ndarray,
    u_h: fem.Function | None = None,
    rebalance: bool | None = None,
    *,
    timings: dict[str, float] | None = None,
    edges: np.ndarray | None = None,
) -> tuple[Scene, fem.Function | None]:
    """Refine the marked cells and carry the scene over (the REFINE step).

    ``contact.adaptivity.refine.refine`` on the scene's mesh as a
    :class:`~contact.adaptivity.refine.Domain`: the boundary and body tags carried over,
    ``u_h`` interpolated onto the new mesh (nested iteration), the functions of
    ``scene.history`` (a load step's state from the previous step) prolonged, the vertices
    of a curved boundary part moved onto its exact surface (the built-in Hertz meshes and
    parts that declare a ``surface``; a gmsh contact part that looks curved gets a one-line
    warning). The refined scene keeps the pseudo-time. The refined mesh does not depend on
    the number of ranks. Collective. (``contact.refine`` of a
    :class:`~contact.adaptivity.refine.Domain` refines the domain itself.)

    Args:
        scene: The scene to refine.
        cells: Owned local cell indices, as :func:`contact.mark` returns them.
        u_h: A function on the scene's mesh to carry over (e.g. ``result.u_h``), or None.
        rebalance: In parallel, redistribute the refined mesh evenly over the ranks
            (default: the scene's ``adapt.rebalance``, true); the mesh itself does not
            depend on it.
        timings: If given, receives the seconds of the parts: ``mesh``, ``transfer`` and
            ``snap``.
        edges: The marked cells' edges (``contact.adaptivity.refine.incident_edges``),
            where the caller has found them already.

    Returns:
        The refined scene (its ``parent`` the scene and the parent cells) and ``u_h``
        interpolated onto it (None if ``u_h`` was None).

    Raises:
        ValueError: On every rank, if ``cells`` are not owned local cell indices or
            ``u_h`` is not a function on the scene's mesh.

    Example:
        >>> import contact
        >>> scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["adapt=none"])
        >>> result = contact.solve(scene, verbose=False)
        >>> cells = contact.mark(contact.estimate(scene, result).eta_T, "uniform")
        >>> fine, u0 = contact.refine(scene, cells, result.u_h)
        >>> cells_of = lambda s: s.mesh.topology.index_map(2).size_global
        >>> cells_of(fine), cells_of(scene)
        (1024, 256)
    """
    if u_h is not None and (
        not isinstance(u_h, fem.Function) or u_h.function_space.mesh is not scene.mesh
    ):
        raise ValueError(
            "u_h: expected a dolfinx.fem.Function on the scene's mesh (e.g. result.u_h of "
            "contact.solve on this scene)"
        )
    if rebalance is None:
        adapt = scene.config.adapt
        rebalance = adapt.rebalance if adapt is not None else True
    child, u0 = refine_domain(
        scene_domain(scene), cells, u_h, rebalance, timings=timings, edges=edges
    )
    return on_domain(scene, child, parent=scene), u0


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
    coulomb; fb, min or blend only) adds the tangential rows of the friction law (no
    polishing, the assembled block Jacobian) and returns the nodal friction fields in
    ``Result.friction``; ``friction.coulomb: fixed_point`` solves a sequence of Tresca
    problems instead. Collective; never raises on divergence (``Result.converged``).
    ``contact.solve`` of a problem (your own forms) is ``contact.drivers.solve.solve``.

    Args:
        scene: The scene to solve (:func:`contact.load_scene`).
        method: fb, min, blend, vinewtonrsls or vinewtonssls; default the scene's
            ``solver.method``.
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
    if problem is None and recoupled(scene):
        # finite strain: the pairs' coupling follows the current configuration
        return solve_coupled(scene, method, None, u0, verbose, criterion, **options)
    opts = config.solver.updated(config.constants, method=method, **options)
    verbose = config.output.verbose if verbose is None else verbose
    built_here = problem is None
    problem = problem or build_problem(scene)
    coarse = None
    # A frictional load step after the first is sequenced too, its history carried to the
    # coarse levels (.levels): its guess replaces the previous step's solution and the
    # predictor; without coarse levels the step starts from those. A hyperelastic body's
    # later steps start from the tangent predictor alone: sequenced is its first step only
    frictional_step = (
        bool(scene.history) and problem.friction is not None and config.model.type != "hyperelastic"
    )
    if u0 is None or frictional_step:
        coarse = scene_hierarchy(scene, problem.V, opts, solve)
        coarse.replaces_guess = frictional_step

    def start(V: fem.FunctionSpace) -> fem.Function:
        return interpolate_expression(V, opts.u0, scene, key="solver.u0")

    result = solve_problem(
        problem,
        options=opts.knobs(),
        u0=u0,
        start=start,
        coarse=coarse,
        verbose=verbose,
        criterion=criterion,
        alternative=alternative,
        assembly=problem.assembly_time if built_here else 0.0,
        check_options=bool(options.get("petsc_options")),
        enforce=baseline(scene) if opts.method in BASELINE_METHODS else None,
    )
    if result.converged and problem.floating:
        # a body only frictionless contact holds may slide: u_h is then one of many
        bodies = config.bodies
        free = free_in_contact(
            problem, scene.bodies if bodies else None, list(bodies or ()), result.active_mask
        )
        if free and scene.comm.rank == 0:
            warnings.warn(not_unique_text(free), ContactWarning, stacklevel=1)
    return result


def recoupled(scene: Scene) -> bool:
    """Return whether the scene's solves re-couple its pairs on the current configuration.

    Hyperelastic bodies in contact through mortar pairs (:mod:`contact.drivers.recouple`).
    """
    return scene.config.model.type == "hyperelastic" and bool(scene.config.pairs)


def solve_coupled(
    scene: Scene,
    method: str | None,
    problem: DiscreteProblem | None,
    u0: fem.Function | None,
    verbose: bool | None,
    criterion: AdaptiveStopping | None = None,
    coupling_rtol: float = COUPLING_RTOL,
    **options: Any,
) -> Result:
    """Solve a scene of hyperelastic bodies in contact through pairs: the coupling's fixed point.

    :func:`contact.drivers.recouple.solve_recoupled`, each coupling one :func:`solve` of the
    problem coupled on the current configuration of the last solution.  Without a guess the
    coarse levels of ``solver.sequence`` (:func:`.levels.scene_hierarchy`) are solved first,
    each its own fixed point of couplings on its own mesh, and the fixed point starts from
    their solution, its first coupling on that solution's configuration (the levels and
    their note on ``Result.sequence``); otherwise the first coupling is that of ``u0``'s
    configuration (the reference one without a guess).  ``problem``: the scene's problem
    coupled on the reference configuration, if built already (the first coupling of a cold
    start; destroyed otherwise).  Collective.
    """
    opts = scene.config.solver.updated(scene.config.constants, method=method, **options)
    levels: list = []
    note = ""
    if u0 is None:
        problem = problem or build_problem(scene)

        def coarse_solve(coarse: Scene, problem, u0, verbose) -> Result:
            return solve_coupled(coarse, None, problem, u0, verbose, coupling_rtol=COARSE_RTOL)

        hierarchy = scene_hierarchy(scene, problem.V, opts, coarse_solve)
        note = hierarchy.note
        if hierarchy.levels:
            loud = scene.config.output.verbose if verbose is None else verbose
            u0, levels, note = initial_guess(hierarchy, problem.V, loud, opts.method)
    first: list[Any] = [problem] if problem is not None and u0 is None else []
    if problem is not None and u0 is not None:
        problem.destroy()  # the first coupling is that of the guess

    def build(at: np.ndarray | None) -> Problem:
        return first.pop() if first else build_problem(scene, at)

    def once(built: Problem, guess: fem.Function | None) -> Result:
        return solve(
            scene, method, built, guess, verbose, criterion, **{**options, "sequence": "off"}
        )

    result = solve_recoupled(build, once, u0, rtol=coupling_rtol)
    result.sequence, result.sequence_note = levels, note
    return result


def baseline(scene: Scene) -> Enforce:
    """Return the solve of the scene's problem by a baseline enforcement.

    Penalty, augmented Lagrangian or Nitsche (:mod:`.baselines`): the scene's constraint as
    UFL, solved from the guess the core chose.
    """
    from .baselines import solve_baseline

    def enforce(problem, u0, options, verbose, timers, clock) -> Result:
        return solve_baseline(scene, problem, u0, options, verbose, timers, clock)

    return enforce


@dataclass
class SceneLevel(Level):
    """A level of a scene's adaptive loop.

    The core's :class:`~contact.drivers.adaptive.Level` and the scene on its mesh.

    Attributes:
        scene: The scene on the level's mesh (what its output is written from); None once
            the level is released.
    """

    scene: Scene = None  # type: ignore[assignment]  # always given; None once released

    @functools.cached_property
    def posed(self) -> PosedProblem:
        """The record of its scene for the figures, built once.

        The first argument of ``contact.post``'s figures (``contact.setup.posed.posed_of``).
        """
        return posed_of(self.scene)

    def release(self) -> None:
        """Keep the figures only; the scene is dropped too."""
        super().release()
        self.scene = None  # type: ignore[assignment]  # released: unused afterwards
        self.__dict__.pop("posed", None)

    def stow(self, mesh: bool = True) -> bool:
        """Stow the level; the scene is dropped too.

        :meth:`~contact.drivers.adaptive.Level.stow`; the loop's ``make_level`` makes the
        scene again on the restored domain.
        """
        if not super().stow(mesh):
            return False
        self.scene = None  # type: ignore[assignment]  # stowed: made again on restore
        self.__dict__.pop("posed", None)
        return True


def adapt_options(scene: Scene, **overrides: Any) -> AdaptConfig:
    """Return the scene's ``adapt`` section with keyword overrides, validated.

    The scene's ``adapt`` section (defaults if absent) with keyword overrides (each
    validated as in the scene file; the section itself was at load).
    """
    return (scene.config.adapt or AdaptConfig()).updated(**overrides)


def adapt(
    scene: Scene,
    method: str | None = None,
    on_level: Callable[[SceneLevel], None] | None = None,
    verbose: bool | None = None,
    u0: fem.Function | None = None,
    keep: Callable[[SceneLevel], bool] | None = None,
    **options: Any,
) -> AdaptResult:
    """Run the h-adaptive loop SOLVE → ESTIMATE → MARK → REFINE on a scene.

    The loop of ``contact.drivers.adaptive.adapt`` over the scene: each level is the
    scene on a refinement of its mesh, its problem built and solved as :func:`solve` does,
    with the scene's estimator, DoF budget (``solver.max_dofs``) and stopping
    (``solver.stopping``). The loop stops when η ≤ ``tol``, before a level would exceed
    ``max_dofs`` or the DoF budget, after ``max_levels`` levels, or when a solve does not
    converge (the levels before it are kept). Each level after the first starts from the
    previous level's solution interpolated onto the refined mesh (``nested``). Collective.
    ``contact.adapt(build, mesh)`` adapts your own problem (a builder of it on a mesh).

    Args:
        scene: The first level's scene.
        method: The solver method (fb, min, blend, vinewtonrsls, vinewtonssls); default
            the scene's ``solver.method``.
        on_level: Called with each level (a ``SceneLevel``) once it is estimated, marked
            and refined (the CLI writes the level's files there).
        verbose: Print a table row per level (default: the scene's ``output.verbose``).
        u0: The first level's initial guess (a load step's previous solution).
        keep: Which levels keep their solution once the next level is solved (and
            ``on_level`` has written it): the others are released
            (:meth:`~contact.drivers.adaptive.Level.release`: their rows, iterations, η
            and errors stay) before the next level is estimated, and the loop's memory
            follows its last level (its refined scenes are then not linked to their
            parents). None (the default) keeps every level whole; ``lambda level:
            False`` releases all but the last.
        **options: Overrides of the scene's ``adapt`` section: ``strategy`` (dorfler,
            maximum, uniform, none; hp is :func:`contact.adapt`'s), ``theta``, ``growth``, ``tol``,
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
    opts = adapt_options(scene, **options)
    if opts.strategy == "hp":  # contact.adapt and the CLI dispatch it to contact.hp
        raise ConfigError("adapt.strategy: hp runs one solve per level (no load path, no study)")
    config = scene.config
    verbose = config.output.verbose if verbose is None else verbose
    solver = config.solver
    root = scene_domain(scene)
    # the scene of the last domain asked for, no more: a released level's scene, and its
    # mesh, are not kept here (a refined domain's parent, if linked, is the last one)
    scenes: list[tuple[Domain, Scene]] = [(root, scene)]

    def scene_of(domain: Domain) -> Scene:
        for known, its in scenes:
            if known is domain:
                return its
        if domain.parent is None:  # a released loop's level: its scene is not linked
            made = on_domain(scene, domain)
            report_as(made, scene)
        else:
            made = on_domain(scene, domain, parent=scene_of(domain.parent[0]))
        scenes[:] = [(domain, made)]
        return made

    def level_solve(problem, domain: Domain, guess, criterion) -> Result:
        # nested: the previous level's solution; cold (nested: false) means cold, not sequenced
        # (pairs at finite strain: the level's fixed point of couplings, its result's problem
        # that of the last coupling)
        return (solve_coupled if recoupled(scene) else solve)(
            scene_of(domain),
            method=method,
            problem=problem,
            u0=guess,
            verbose=False,
            criterion=criterion,
            rtol=opts.newton_rtol,
            sequence=None if opts.nested else "off",
        )

    def scene_level(level: Level) -> SceneLevel:
        fields = {f: getattr(level, f) for f in Level.__dataclass_fields__}
        return SceneLevel(**fields, scene=scene_of(level.domain))

    run = adapt_domain(
        lambda domain: build_problem(scene_of(domain)),
        root,
        options=opts,
        kind=config.estimator,
        u0=u0,
        on_level=on_level,  # type: ignore[arg-type]  # called with the SceneLevels
        keep=keep,  # type: ignore[arg-type]
        make_level=scene_level,
        solve=level_solve,
        budget=scene.budget,
        stopping=(solver.gamma_lin, solver.gamma_alg) if solver.stopping == "adaptive" else None,
        verbose=verbose,
    )
    return run


@dataclass
class SceneStep(Step):
    """A step of a scene's load path.

    The core's :class:`~contact.drivers.load_path.Step` and the scene it was solved on.

    Attributes:
        scene: The scene at the step's pseudo-time on the mesh it was solved on (the final
            mesh of its adaptive loop, if any); None once the step is released.
    """

    scene: Scene = None  # type: ignore[assignment]  # always given; None once released

    @functools.cached_property
    def posed(self) -> PosedProblem:
        """The record of its scene for the figures, built once.

        The first argument of ``contact.post``'s figures (``contact.setup.posed.posed_of``).
        """
        return posed_of(self.scene)

    def release(self) -> None:
        """Keep the figures only; the scene is dropped too."""
        super().release()
        self.scene = None  # type: ignore[assignment]  # released: unused afterwards
        self.__dict__.pop("posed", None)


def load_times(cfg: SceneConfig) -> list[float]:
    """The pseudo-times of the scene's load path ([1.0] without a ``load:`` section)."""
    return list(cfg.load.times) if cfg.load is not None else [1.0]


#: ``load.cuts`` of a hyperelastic scene (none given): a step may be halved 4 times in a row
#: (to 1/16 of its length)
HYPERELASTIC_CUTS = 4


def step_cuts(cfg: SceneConfig) -> int:
    """Return how many times in a row a step that does not converge is halved.

    How many times in a row a step that does not converge is halved (``load.cuts``;
    default :data:`HYPERELASTIC_CUTS` for a hyperelastic body, whose Newton iteration
    converges only near enough to the solution, 0 for the linear models, whose solution
    does not depend on the path but for friction).
    """
    cuts = cfg.load.cuts if cfg.load is not None else None
    if cuts is not None:
        return int(cuts)
    return HYPERELASTIC_CUTS if cfg.model.type == "hyperelastic" else 0


def secant_predictor(cfg: SceneConfig) -> bool:
    """Return whether steps k ≥ 3 are offered the secant predictor.

    Whether steps k ≥ 3 are offered the secant predictor (``load.predictor``; linear models:
    a hyperelastic step keeps its warm start, ``step_cuts`` handles its failures).
    """
    predictor = cfg.load.predictor if cfg.load is not None else "secant"
    return predictor == "secant" and cfg.model.type != "hyperelastic"


def run_load_path(
    scene: Scene,
    method: str | None = None,
    on_step: Callable[[SceneStep], None] | None = None,
    verbose: bool | None = None,
    adaptive: bool | None = None,
    adapt_options: dict | None = None,
    keep_all: bool = False,
    forget: bool = False,
    **options: Any,
) -> LoadPath:
    """Solve the scene's quasi-static load path step by step.

    Step k solves the scene at t = t_k (data expressions may use ``t``, e.g.
    ``u_D: ["0.01*t", "-delta"]``), starting from step k − 1's solution, its history
    (``u_prev`` of ``contact.setup.scene.Scene.history``: friction's slips are measured
    from it); the loop is ``contact.drivers.load_path.run_steps``. From the third step
    on, a step is offered the secant predictor (``load.predictor``) beside the previous
    solution; a step that does not converge may be halved (``load.cuts``,
    ``step_cuts``); a hyperelastic body's equilibrium branch is followed where the
    energy search finds no stable state. With an ``adapt:`` section (or ``adaptive``) the
    adaptive loop runs at every step (``load.adapt: each``: step k refines on from the final
    mesh of step k − 1) or at the last step only (``end``). The last step stays whole, and
    the last converged one before a failed step; the others are released when the next one
    is solved, unless ``keep_all``. Collective. ``contact.run_load_path(build, times)``
    runs your own problem's path (``contact.drivers.load_path.load_path``).

    Args:
        scene: The scene; its ``load:`` section gives the pseudo-times (one step at t = 1
            without one).
        method: The solver method; default the scene's ``solver.method``.
        on_step: Called with each step (a ``SceneStep``) once it is solved (converged
            steps and the final failure only): anything that needs a step's functions or
            scene belongs there (the CLI writes its output there).
        verbose: Print a line per step (default: the scene's ``output.verbose``).
        adaptive: Run the adaptive loop (default: when the scene has an ``adapt`` section),
            at every step or at the last (``load.adapt``).
        adapt_options: Overrides of the scene's ``adapt`` section.
        keep_all: Keep every step whole (for short paths: each whole step holds MPI
            communicators, of which MPI has a few thousand).
        forget: Drop released steps from ``LoadPath.steps`` altogether (counted in
            ``LoadPath.forgotten``), for a caller that keeps each step's figures itself as
            it goes (the CLI's step writer): the path's memory then stays flat.
        **options: Solver options as for :func:`contact.solve`.

    Returns:
        The steps and, if it stopped early, why.

    Example:
        >>> import contact
        >>> scene = contact.load_scene(
        ...     "configs/friction_block_2d.yaml", ["mesh.cells=[16,4]", "load.steps=4"]
        ... )
        >>> path = contact.run_load_path(scene, verbose=False)
        >>> path.converged, [step.time for step in path.steps]
        (True, [0.25, 0.5, 0.75, 1.0])
    """
    config = scene.config
    verbose = config.output.verbose if verbose is None else verbose
    mode = config.load.adapt if config.load is not None else "end"
    if adaptive is None:
        adaptive = config.adapt is not None

    def at(t: float, previous: Previous) -> Scene:
        base = previous.where or scene  # an adaptive path continues on the last final mesh
        return Scene(
            base.config,
            base.mesh,
            base.boundary,
            time=t,
            history={} if previous.u is None else {"u_prev": previous.u},
            previous_time=None if previous.u is None else previous.time,
            bodies=base.bodies,
            surfaces=base.surfaces,
            snap=base.snap,
            budget=base.budget,
        )

    def solve_step(t: float, previous: Previous, **extra: Any) -> tuple[Scene, Result]:
        step_scene = at(t, previous)
        return step_scene, solve(
            step_scene,
            method=method,
            u0=previous.u,
            verbose=verbose,
            alternative=previous.guess,
            **{**options, **extra},
        )

    def adapt_step(t: float, previous: Previous) -> tuple[Scene, Result, list]:
        run = adapt(
            at(t, previous), method=method, verbose=verbose, u0=previous.u, **(adapt_options or {})
        )
        last = run.levels[-1]
        assert (
            isinstance(last, SceneLevel) and last.scene is not None
        )  # a level's scene, kept until the step is released
        return last.scene, last.result, run.levels

    def make_step(k: int, t: float, where: Scene, result: Result, levels: list, seconds: float):
        return SceneStep(k, t, result, levels, seconds, scene=where)

    return run_steps(
        solve_step,
        load_times(config),
        scene.comm,
        adapt_step=adapt_step if adaptive else None,
        adapt_each=mode == "each",
        cuts=step_cuts(config),
        predictor=secant_predictor(config),
        branches=config.model.type == "hyperelastic",
        on_step=on_step,
        make_step=make_step,
        verbose=verbose,
        keep_all=keep_all,
        forget=forget,
    )


def is_problem(subject: Any) -> bool:
    """Return whether ``subject`` is a problem the drivers of problems take.

    Whether ``subject`` is a problem the drivers of problems take (a model's problem or a
    :class:`~contact.models.forms.ComplementarityProblem`).
    """
    return isinstance(getattr(subject, "problem", subject), DiscreteProblem)


def is_builder(subject: Any) -> bool:
    """Return whether ``subject`` is a user's builder of problems (a callable)."""
    return callable(subject)


def is_domain(subject: Any) -> bool:
    """Return whether ``subject`` is a :class:`~contact.adaptivity.refine.Domain`."""
    return isinstance(subject, Domain)


def either[**P, R](
    for_scene: Callable[P, R], for_problem: Callable[..., Any], takes: Callable[[Any], bool]
) -> Callable[P, R]:
    """Return a public function of a scene or a problem.

    A public function of a scene or a problem: ``for_scene`` when the first argument is a
    :class:`Scene`, ``for_problem`` when ``takes`` it; anything else is the one-line
    ValueError of :func:`contact.setup.scene.require_scene`.  The first call with a scene
    warns when facets of its boundary are in no part (:func:`.untagged.warn_untagged`).
    """

    @functools.wraps(for_scene)
    def call(*args: P.args, **kwargs: P.kwargs) -> R:
        first = args[0] if args else kwargs.get("scene")
        if not isinstance(first, Scene) and takes(first):
            return for_problem(*args, **kwargs)
        require_scene(first)
        assert isinstance(first, Scene)  # require_scene raised for anything else
        warn_untagged(first)
        return for_scene(*args, **kwargs)

    return call
