"""A scene's solve, estimate, refinement, adaptive loop and load path: the scene's problem
built (:func:`contact.models.build_problem`), its options and data read, and handed to the
drivers of problems (:func:`contact.drivers.solve.solve`,
:func:`contact.adaptivity.estimate.estimate`, :func:`contact.adaptivity.refine.refine` on the
scene's mesh as a :class:`~contact.adaptivity.refine.Domain`,
:func:`contact.drivers.adaptive.adapt`, :func:`contact.drivers.load_path.run_steps`); the
scene's grid sequencing is :mod:`.levels`."""

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
from ..base.errors import ContactWarning
from ..drivers.adaptive import AdaptResult, Level
from ..drivers.adaptive import adapt as adapt_domain
from ..drivers.load_path import LoadPath, Previous, Step, run_steps
from ..drivers.solve import solve as solve_problem
from ..solvers import Result
from ..solvers.floating import free_in_contact
from ..solvers.problem import DiscreteProblem
from ..solvers.result import not_unique_text
from ..solvers.stopping import AdaptiveStopping
from .budget import max_dofs
from .build import build_problem
from .data import interpolate_expression
from .geometry import builder_surfaces
from .levels import scene_hierarchy
from .meshes import Boundary
from .scene import Scene, require_scene
from .scene_config import AdaptConfig, SceneConfig
from .surfaces import boundary_surfaces, warn_undeclared_curves


def estimate(subject: Any, result: Result, kind: str | None = None) -> Estimate:
    """η_T and η of a solve (collective).

    Args:
        subject: the :class:`~contact.setup.scene.Scene` that was solved (its ``estimator``
            is the default kind), or a problem with its physics declared
            (:func:`contact.adaptivity.estimate.estimate`; the default kind ``residual``).
        result: the solve's :class:`~contact.solvers.result.Result`.
        kind: ``residual``, ``equilibrated`` or ``equilibrated_rt0``.

    Returns:
        The :class:`~contact.adaptivity.estimate.Estimate`.  A result of another scene or
        problem is a ValueError."""
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
    """The scene's mesh as a :class:`~contact.adaptivity.refine.Domain`: its boundary tags,
    body tags, the mesh builder's surface tags (``surfaces``), the history functions, and
    the snapping of curved boundary parts (the declared ``surface`` of a part, the curved
    surfaces of the built-in Hertz meshes)."""
    cfg, bnd = scene.config, scene.boundary
    ids, roles = dict(bnd.ids), dict(bnd.roles)

    def snap(parent: Domain, child: Domain) -> None:
        assert parent.facets is not None and child.facets is not None  # a scene's boundary
        boundary = Boundary(parent.facets, ids, roles)
        warn_undeclared_curves(cfg, parent.mesh, boundary)
        for surface in boundary_surfaces(cfg, parent.mesh.geometry.dim, boundary):
            surface.snap(child.mesh, child.facets)
        # by the mesh's own tags of its curved surfaces
        for surface in builder_surfaces(cfg.mesh):
            surface.snap(child.mesh, child.tags["surfaces"])

    return Domain(
        scene.mesh,
        bnd.tags,
        scene.bodies,
        {} if scene.surfaces is None else {"surfaces": scene.surfaces},
        dict(scene.history),
        snap,
    )


def on_domain(scene: Scene, domain: Domain, parent: Scene | None = None) -> Scene:
    """The scene on another domain of its mesh's (a refinement of it): the same configuration,
    boundary parts and pseudo-time, the domain's tags and functions; ``parent`` the scene of
    the domain's parent (the coarser levels of grid sequencing)."""
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
    )


def refine(
    scene: Scene,
    cells: np.ndarray,
    u_h: fem.Function | None = None,
    rebalance: bool | None = None,
    *,
    timings: dict[str, float] | None = None,
) -> tuple[Scene, fem.Function | None]:
    """Refine the marked cells of the scene's mesh (:func:`contact.adaptivity.refine.refine`
    on :func:`scene_domain`): the boundary and body tags carried over, ``u_h`` interpolated
    onto the new mesh (nested iteration), the history functions prolonged, curved boundary
    parts snapped to their surfaces (a gmsh contact part that looks curved and declares no
    surface gets a one-line warning).  ``rebalance``: default the scene's
    ``adapt.rebalance`` (true).  Returns (the refined scene, u_h on it or None); a ``u_h``
    on another mesh, or cells that are not owned indices, is a ValueError."""
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
    child, u0 = refine_domain(scene_domain(scene), cells, u_h, rebalance, timings=timings)
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
    """Solve the scene's contact problem; return a :class:`Result` (never raises on divergence).

    ``method`` ∈ {fb, min, blend, vinewtonrsls, vinewtonssls}; further keyword options
    override the scene's ``solver`` section (``mu``, ``c``, ``kappa``, ``line_search``,
    ``polish``, ``rtol``, ``atol``, ``max_it``, ``linear``, ``inexact``, ``sequence``,
    ``petsc_options``).  ``problem`` reuses an assembled problem, ``u0`` is an initial guess;
    without one, grid sequencing (``sequence``, :mod:`.levels`) solves coarser meshes
    first when it pays, and the coarsest level (or a cold start) begins from the scene's
    ``solver.u0`` (zero by default).  The solve itself is
    :func:`contact.drivers.solve.solve`'s (friction, the Coulomb fixed point).
    ``criterion``: adaptive stopping against a discretization error
    (:mod:`contact.solvers.stopping`; the adaptive loop makes one per level for
    ``solver.stopping: adaptive``, which a single solve ignores: it has no discretization
    error to balance against).  ``alternative``: another guess beside ``u0`` (a load
    path's extrapolation); Newton starts from the one whose ‖Φ‖ is smaller
    (``Result.predictor`` says which)."""
    if problem is not None and problem.V.mesh is not scene.mesh:
        raise ValueError("problem: was built for another scene's mesh")
    config = scene.config  # validated at load, immutable: only the call's overrides are checked
    opts = config.solver.updated(config.constants, method=method, **options)
    verbose = config.output.verbose if verbose is None else verbose
    built_here = problem is None
    problem = problem or build_problem(scene)
    coarse = None
    # A frictional load step after the first is sequenced too, its history carried to the
    # coarse levels (.levels): its guess replaces the previous step's solution and the
    # predictor; without coarse levels the step starts from those
    frictional_step = bool(scene.history) and problem.friction is not None
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


@dataclass
class SceneLevel(Level):
    """A level of a scene's adaptive loop: the core :class:`~.adaptive.Level` and the scene
    on its mesh (what its output is written from)."""

    scene: Scene = None  # type: ignore[assignment]  # always given; None once released

    def release(self) -> None:
        super().release()
        self.scene = None  # type: ignore[assignment]  # released: unused afterwards


def adapt_options(scene: Scene, **overrides: Any) -> AdaptConfig:
    """The scene's ``adapt`` section (defaults if absent) with keyword overrides (each
    validated as in the scene file; the section itself was at load)."""
    return (scene.config.adapt or AdaptConfig()).updated(**overrides)


def adapt(
    scene: Scene,
    method: str | None = None,
    on_level: Callable[[SceneLevel], None] | None = None,
    verbose: bool | None = None,
    u0: fem.Function | None = None,
    **options: Any,
) -> AdaptResult:
    """The adaptive loop of :func:`contact.drivers.adaptive.adapt` over the scene: each level
    the scene on a refinement of its mesh (:func:`refine`), its problem built
    (:func:`contact.models.build_problem`) and solved as :func:`solve` does, with the scene's
    estimator, the scene's ``adapt`` section (keyword ``options`` override it; validated),
    its solver's DoF budget (``solver.max_dofs``) and stopping (``solver.stopping``).
    ``on_level`` is called with each :class:`SceneLevel` once it is estimated (used by the
    CLI to write output as it goes); ``u0`` is the first level's initial guess (a load
    step's previous solution).  Returns the levels as :class:`SceneLevel` objects."""
    if on_level is not None and not callable(on_level):
        raise ValueError(
            f"on_level: expected a function of one Level, got {type(on_level).__name__}"
        )
    opts = adapt_options(scene, **options)
    config = scene.config
    verbose = config.output.verbose if verbose is None else verbose
    solver = config.solver
    root = scene_domain(scene)
    scenes: dict[int, Scene] = {id(root): scene}

    def scene_of(domain: Domain) -> Scene:
        if id(domain) not in scenes:
            assert domain.parent is not None  # a refinement of the root's
            scenes[id(domain)] = on_domain(scene, domain, parent=scene_of(domain.parent[0]))
        return scenes[id(domain)]

    def level_solve(problem, domain: Domain, guess, criterion) -> Result:
        # nested: the previous level's solution; cold (nested: false) means cold, not sequenced
        return solve(
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

    levels: list[SceneLevel] = []

    def seen(level: Level) -> None:
        levels.append(scene_level(level))
        if on_level is not None:
            on_level(levels[-1])

    run = adapt_domain(
        lambda domain: build_problem(scene_of(domain)),
        root,
        options=opts,
        kind=config.estimator,
        u0=u0,
        on_level=seen,
        solve=level_solve,
        budget=max_dofs(solver, scene.mesh.geometry.dim),
        stopping=(solver.gamma_lin, solver.gamma_alg) if solver.stopping == "adaptive" else None,
        verbose=verbose,
    )
    return AdaptResult(list(levels), run.stop)


@dataclass
class SceneStep(Step):
    """A step of a scene's load path: the core :class:`~.load_path.Step` and the scene it was
    solved on (the final mesh of its adaptive loop, if any)."""

    scene: Scene = None  # type: ignore[assignment]  # always given; None once released

    def release(self) -> None:
        super().release()
        self.scene = None  # type: ignore[assignment]  # released: unused afterwards


def load_times(cfg: SceneConfig) -> list[float]:
    """The pseudo-times of the scene's load path ([1.0] without a ``load:`` section)."""
    return list(cfg.load.times) if cfg.load is not None else [1.0]


#: ``load.cuts`` of a hyperelastic scene (none given): a step may be halved 4 times in a row
#: (to 1/16 of its length)
HYPERELASTIC_CUTS = 4


def step_cuts(cfg: SceneConfig) -> int:
    """How many times in a row a step that does not converge is halved (``load.cuts``;
    default :data:`HYPERELASTIC_CUTS` for a hyperelastic body, whose Newton iteration
    converges only near enough to the solution, 0 for the linear models, whose solution
    does not depend on the path but for friction)."""
    cuts = cfg.load.cuts if cfg.load is not None else None
    if cuts is not None:
        return int(cuts)
    return HYPERELASTIC_CUTS if cfg.model.type == "hyperelastic" else 0


def secant_predictor(cfg: SceneConfig) -> bool:
    """Whether steps k ≥ 3 are offered the secant predictor (``load.predictor``; linear models:
    a hyperelastic step keeps its warm start, :func:`step_cuts` handles its failures)."""
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
    **options: Any,
) -> LoadPath:
    """Solve the scene's load path (``load:`` section; one step at t = 1 without one) step by
    step (:func:`contact.drivers.load_path.run_steps`).

    Data expressions may use the pseudo-time ``t`` (e.g. ``u_D: ["0.01*t", "-delta"]``);
    each step is the scene at t_k with the previous step's solution as its history
    (``u_prev`` of :attr:`contact.setup.scene.Scene.history`: friction's slips are measured
    from it), solved as :func:`solve` does, with the secant predictor (``load.predictor``),
    step cutting (``load.cuts``, :func:`step_cuts`) and — for a hyperelastic body — the
    equilibrium branch followed where the energy search finds no stable state.  With an
    ``adapt:`` section (or ``adaptive``) the adaptive loop runs at every step
    (``load.adapt: each``: step k refines on from the final mesh of step k − 1, so meshes
    only get finer and u_prev is carried exactly by nested prolongation) or at the last
    step only (``end``), ``adapt_options`` overriding that section.  ``on_step`` is called
    with each :class:`SceneStep` (the CLI writes its output there); ``options`` are solver
    options as for :func:`solve`."""
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
    )


def is_problem(subject: Any) -> bool:
    """Whether ``subject`` is a problem the drivers of problems take (a model's problem or a
    :class:`~contact.models.forms.ComplementarityProblem`)."""
    return isinstance(getattr(subject, "problem", subject), DiscreteProblem)


def either[**P, R](
    for_scene: Callable[P, R], for_problem: Callable[..., Any], takes: Callable[[Any], bool]
) -> Callable[P, R]:
    """A public function of a scene or a problem: ``for_scene`` when the first argument is a
    :class:`Scene`, ``for_problem`` when ``takes`` it; anything else is the one-line
    ValueError of :func:`contact.setup.scene.require_scene`."""

    @functools.wraps(for_scene)
    def call(*args: P.args, **kwargs: P.kwargs) -> R:
        first = args[0] if args else kwargs.get("scene")
        if not isinstance(first, Scene) and takes(first):
            return for_problem(*args, **kwargs)
        require_scene(first)
        return for_scene(*args, **kwargs)

    return call
