"""Quasi-static load paths (the ``load:`` section of a scene).

A sequence of pseudo-times t_1 < t_2 < … < t_N, one contact solve per step.

Data expressions may use the pseudo-time ``t`` (e.g. ``u_D: ["0.01*t", "-delta"]``); step k
solves the problem at t = t_k, starting from the solution of step k − 1 (a warm start), and
friction's slip increments s_t = u_t − u_t^prev are measured from that solution (the state
``u_prev`` of ``Scene.history``; zero before the first step).  A scene
without a ``load:`` section is one step at t = 1.

With an ``adapt:`` section the adaptive loop runs at every step (``load.adapt: each``: step
k refines on from the final mesh of step k − 1, so meshes only get finer and u_prev is
carried exactly by nested prolongation) or at the last step only (``end``: steps 1 … N−1
on the scene's mesh, the adaptive loop at t_N with u_prev prolonged to every level).

A path may have any number of steps: once step k is solved (and ``on_step`` has written its
output), step k − 1 is released (:meth:`Step.release`) — its PETSc objects destroyed, its
functions, scene and meshes dropped — and keeps only its figures.  Every live function holds
MPI communicators (two per vector on more than one rank) and MPI has a few thousand, so
keeping every step whole (``keep_all``) suits short paths only.  With ``forget`` a released
step is dropped altogether (``LoadPath.forgotten`` counts them): the path's memory does not
grow with its steps, for a caller whose ``on_step`` keeps what it needs (the CLI writes each
step's figures to disk).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from dolfinx import fem

from ..setup.scene import Scene
from ..setup.scene_config import SceneConfig
from ..solvers import Result
from ..solvers.energy_search import tangent_text
from .adaptive import adapt
from .solve import solve


@dataclass
class Step:
    """One load step, as :func:`contact.run_load_path` hands it to ``on_step``.

    Attributes:
        index: The step's number, 1 … N.
        time: Its pseudo-time t.
        scene: The scene it was solved on (the final mesh of its adaptive loop, if any);
            None once the step is released.
        result: The solve (of the final level, for an adaptive step).
        levels: The adaptive loop's levels (:class:`~contact.drivers.adaptive.Level`), empty
            for a step without one.
        seconds: The step's wall time.
        negative_eigenvalues: Hyperelastic bodies: the negative eigenvalues of the tangent
            K_T at the solution (None otherwise).
        min_det_F: Hyperelastic bodies: the smallest det F of the solution.
        branch: Hyperelastic bodies: how the step was solved on the equilibrium branch by
            plain Newton where the energy search found no stable state, in one phrase
            ("" otherwise).
    """

    index: int  # 1 … N
    time: float
    scene: Scene
    result: Result
    levels: list = field(default_factory=list)  # adapt.Level of an adaptive step
    seconds: float = 0.0
    negative_eigenvalues: int | None = None  # of K_T at the solution (hyperelastic bodies)
    min_det_F: float | None = None  # the smallest det F of the solution (hyperelastic bodies)
    # solved on the equilibrium branch by plain Newton where the energy search found no
    # stable state (:func:`follow_branch`): what happened, in one phrase; else ''
    branch: str = ""

    def release(self) -> None:
        """Keep the step's figures only.

        Its result and its adaptive levels' results are released (``Result.release``:
        iterations, residual, history, contact force stay; functions, nodal arrays and PETSc
        objects go), its scene and the levels' scenes and η_T functions dropped.
        """
        for level in self.levels:
            level.result.release()
            level.scene, level.estimate.eta_T = None, None
        self.result.release()
        self.scene = None  # type: ignore[assignment]  # released: unused afterwards


@dataclass
class LoadPath:
    """The steps of a quasi-static load path (:func:`contact.run_load_path`).

    Attributes:
        steps: The steps solved, in order (each a :class:`~contact.drivers.load_path.Step`;
            all but the last converged ones are released unless ``keep_all``).
        stop: Why the path stopped early, with the path's notes ("" when every step
            converged).
        failure: Why the path stopped short, in one short phrase (the step, t, the
            reason, the limit of step cutting reached); "" when it reached its end.
        cuts: Step cutting: one line per cut, ``'t = … (reason) cut to t = …'``.
        indefinite: Hyperelastic bodies: the first step whose tangent K_T is not positive
            definite ("" if none).
        inverted: Hyperelastic bodies: the first step whose solution inverts matter
            (det F ≤ 0; "" if none).
        tangent_events: What the energy search did, one line per step where it did
            anything (hyperelastic bodies).
        bifurcation: The first step solved on the equilibrium branch where the energy
            search found no stable state ("" if none).
        branch_steps: Every step on that branch: (step, t, negative eigenvalues of K_T).
    """

    steps: list[Step] = field(default_factory=list)
    stop: str = ""
    # why the path stopped short, in one short phrase (the step, t, the reason, the limit
    # of step cutting reached); `stop` adds the path's notes; '' when it reached its end
    failure: str = ""
    cuts: list[str] = field(default_factory=list)  # step cutting: 't = … (reason) cut to t = …'
    indefinite: str = ""  # the first step whose K_T is not positive definite (hyperelastic)
    inverted: str = ""  # the first step whose solution inverts matter (det F <= 0)
    # what the energy search did, one line per step where it did anything (hyperelastic)
    tangent_events: list[str] = field(default_factory=list)
    # the first step solved on the equilibrium branch where the energy search found no
    # stable state (a bifurcation), and every step on that branch: (step, t, negative
    # eigenvalues of K_T there)
    bifurcation: str = ""
    branch_steps: list[tuple[int, float, int]] = field(default_factory=list)
    forgotten: int = 0  # converged steps dropped before ``steps`` (run_load_path's forget)

    @property
    def converged(self) -> bool:
        """Whether the path has steps and every one converged."""
        return bool(self.steps) and all(s.result.converged for s in self.steps)

    @property
    def count(self) -> int:
        """The number of steps, forgotten ones included."""
        return self.forgotten + len(self.steps)


def load_times(cfg: SceneConfig) -> list[float]:
    """The pseudo-times of the scene's load path ([1.0] without a ``load:`` section)."""
    return list(cfg.load.times) if cfg.load is not None else [1.0]


def copy_function(fn: fem.Function, name: str) -> fem.Function:
    """Return a copy of ``fn`` named ``name`` on the same space."""
    out = fem.Function(fn.function_space, name=name)
    out.x.array[:] = fn.x.array
    return out


#: ``load.cuts`` of a hyperelastic scene (none given): a step may be halved 4 times in a row
#: (to 1/16 of its length)
HYPERELASTIC_CUTS = 4
#: no cut makes a step shorter than this fraction of the path's last pseudo-time (the
#: schema bounds ``load.cuts`` too: ``contact.setup.config.MAX_STEP_CUTS``)
MIN_STEP = 1e-9


def step_cuts(cfg: SceneConfig) -> int:
    """Return how many times in a row a step that does not converge is halved.

    ``load.cuts``; default :data:`HYPERELASTIC_CUTS` for a hyperelastic body, whose Newton
    iteration converges only near enough to the solution, 0 for the linear models, whose
    solution does not depend on the path but for friction.
    """
    cuts = cfg.load.cuts if cfg.load is not None else None
    if cuts is not None:
        return int(cuts)
    return HYPERELASTIC_CUTS if cfg.model.type == "hyperelastic" else 0


def secant_predictor(cfg: SceneConfig) -> bool:
    """Return whether steps k ≥ 3 are offered the secant predictor.

    ``load.predictor``, for the linear models: a hyperelastic step keeps its warm start,
    and :func:`step_cuts` handles its failures.
    """
    predictor = cfg.load.predictor if cfg.load is not None else "secant"
    return predictor == "secant" and cfg.model.type != "hyperelastic"


def extrapolate(
    u_prev: fem.Function, u_prev2: fem.Function, t: float, t_prev: float, t_prev2: float
) -> fem.Function | None:
    """Return the secant predictor of step k from the two previous solutions.

    The secant predictor u_k ≈ u_{k−1} + (t_k − t_{k−1}) / (t_{k−1} − t_{k−2}) (u_{k−1} −
    u_{k−2}) (None when the two steps live on different meshes: ``load.adapt: each``).
    """
    V, W = u_prev.function_space, u_prev2.function_space
    if V.mesh is not W.mesh or len(u_prev.x.array) != len(u_prev2.x.array) or t_prev <= t_prev2:
        return None
    ratio = (t - t_prev) / (t_prev - t_prev2)
    out = fem.Function(u_prev.function_space, name="u_predicted")
    out.x.array[:] = u_prev.x.array + ratio * (u_prev.x.array - u_prev2.x.array)
    return out


def run_load_path(
    scene: Scene,
    method: str | None = None,
    on_step: Callable[[Step], None] | None = None,
    verbose: bool | None = None,
    adaptive: bool | None = None,
    adapt_options: dict | None = None,
    keep_all: bool = False,
    forget: bool = False,
    **options: Any,
) -> LoadPath:
    """Solve the scene's quasi-static load path step by step.

    Step k solves the problem at t = t_k (data expressions may use ``t``), starting from
    step k − 1's solution; friction's slip increments are measured from it. From the third
    step on, a step is offered the secant predictor beside the previous solution: Newton
    starts from the one of smaller ‖Φ‖ (``Result.predictor``). The path stops at the first
    step that does not converge — unless step cutting (``load.cuts``) may halve it: the
    step from t_{k−1} to t_k is then retried as two, to (t_{k−1} + t_k)/2 first, at most
    ``cuts`` times in a row, and no cut makes a step shorter than ``MIN_STEP`` × the last
    t; each cut is reported (``LoadPath.cuts``, verbose output) and the failed attempt is
    not a step. A hyperelastic step whose energy search met an indefinite tangent and found
    no stable state is solved by plain Newton before it is cut: an admissible equilibrium
    there is kept and reported with K_T's negative eigenvalues (``Step.branch``,
    ``LoadPath.bifurcation``, ``LoadPath.branch_steps``), and plain Newton follows that
    branch while K_T stays indefinite. The last step stays whole, and the last converged
    one before a failed step; the others are released when the next one is solved, unless
    ``keep_all``: memory and MPI communicators do not grow with the number of steps.
    Collective.

    Args:
        scene: The scene; its ``load:`` section gives the pseudo-times (one step at t = 1
            without one).
        method: The solver method; default the scene's ``solver.method``.
        on_step: Called with each :class:`~contact.drivers.load_path.Step` once it is
            solved (converged steps and the final failure only): anything that needs a
            step's functions or scene belongs there (the CLI writes its output there).
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
    verbose = scene.config.output.verbose if verbose is None else verbose
    times = load_times(scene.config)
    max_cuts = step_cuts(scene.config)
    smallest = MIN_STEP * abs(times[-1])
    hyperelastic = scene.config.model.type == "hyperelastic"
    following = False  # on an unstable equilibrium branch: plain Newton (follow_branch)
    predict = secant_predictor(scene.config)
    mode = scene.config.load.adapt if scene.config.load is not None else "end"
    if adaptive is None:
        adaptive = scene.config.adapt is not None
    comm = scene.comm
    out, u_prev, t_prev = LoadPath(), None, 0.0
    u_prev2, t_prev2 = None, 0.0  # the step before the previous one (the predictor)
    pending = [(t, 0) for t in times]  # (pseudo-time, cuts that led to it)
    while pending:
        t, depth = pending.pop(0)
        k = out.count + 1
        t0 = time.perf_counter()
        step_scene = Scene(
            scene.config,
            scene.mesh,
            scene.boundary,
            time=t,
            history={} if u_prev is None else {"u_prev": u_prev},
            previous_time=None if u_prev is None else t_prev,
            bodies=scene.bodies,
            surfaces=scene.surfaces,
        )
        if verbose and comm.rank == 0 and len(times) > 1:
            print(f"contact: load step {k}/{k + len(pending)}, t = {t:g}", flush=True)
        levels, branch = [], ""
        if adaptive and (mode == "each" or not pending):
            run = adapt(
                step_scene, method=method, verbose=verbose, u0=u_prev, **(adapt_options or {})
            )
            levels = run.levels
            step_scene, result = levels[-1].scene, levels[-1].result
        else:
            guess = None
            if predict and u_prev is not None and u_prev2 is not None:
                guess = extrapolate(u_prev, u_prev2, t, t_prev, t_prev2)
            attempt = _attempt(step_scene, method, u_prev, verbose, guess, options)
            kept = keep_to_branch(attempt) if following else None
            if kept is not None:
                result, branch = kept, "on the equilibrium branch (plain Newton)"
            else:
                result = attempt()
                if hyperelastic and not result.converged and searched_indefinite(result):
                    result, branch = follow_branch(result, attempt)
        why = ""
        if not result.converged:
            mid = t_prev + (t - t_prev) / 2
            if depth < max_cuts and mid - t_prev >= smallest:
                out.cuts.append(f"t = {t:g} ({result.reason}) cut to t = {mid:g}")
                if verbose and comm.rank == 0:
                    print(
                        f"contact: step {k} to t = {t:g} did not converge ({result.reason}): "
                        f"cut to t = {mid:g} (cut {depth + 1} of at most {max_cuts} in a row)",
                        flush=True,
                    )
                result.release()
                pending[:0] = [(mid, depth + 1), (t, depth + 1)]
                continue
            why = (
                f"a cut would make the step {mid - t_prev:.3g}, below the smallest "
                f"({MIN_STEP:g} of t = {times[-1]:g})"
                if depth < max_cuts
                else f"cut {depth} time(s) in a row (load.cuts: {max_cuts})"
                if max_cuts
                else ""
            )
        step = Step(k, t, step_scene, result, levels, time.perf_counter() - t0)
        text = tangent_text(result.tangent_log)  # what the energy search did (hyperelastic)
        if text:
            out.tangent_events.append(f"step {k} (t = {t:g}): {text}")
        if result.converged and hyperelastic:
            check_tangent(step, out, verbose)
            if branch:
                following = on_branch(step, branch, out)
        out.steps.append(step)
        if on_step is not None:
            on_step(step)
        if not result.converged:
            out.failure = f"step {k} (t = {t:g}) did not converge ({result.reason})" + (
                f": {why}" if why else ""
            )
            out.stop = out.failure + _notes(out)
            break
        u_prev2, t_prev2 = u_prev, t_prev
        scene, t_prev = step_scene, t  # 'each': the next step continues on this step's final mesh
        u_prev = copy_function(result.u_h, "u_prev")
        if len(out.steps) > 1 and not keep_all:
            out.steps[-2].release()
            if forget and len(out.steps) > 2:
                del out.steps[0]
                out.forgotten += 1
    else:
        out.stop = f"reached t = {times[-1]:g} in {out.count} step(s)" + _notes(out)
    return out


def check_tangent(step: Step, path: LoadPath, verbose: bool) -> None:
    """Count the negative eigenvalues of a hyperelastic step's tangent at its solution.

    Count the negative eigenvalues of a hyperelastic step's tangent K_T at its solution
    (:func:`contact.models.hyperelastic.negative_eigenvalues`) and its smallest det F; the
    first step where K_T is not positive definite is reported (``LoadPath.indefinite``, the
    stop text, verbose), and the first whose solution inverts matter (``inverted``: an
    equilibrium of the discrete equations that no body reaches — plain Newton on St
    Venant–Kirchhoff in strong compression converges to such states).
    """
    from ..models.hyperelastic import min_det_F, negative_eigenvalues

    J = step.min_det_F = min_det_F(step.result)
    if J <= 0 and not path.inverted:
        path.inverted = (
            f"step {step.index} (t = {step.time:g}) inverts matter (min det F = {J:.3g}): "
            "not a physical deformation"
        )
        if verbose and step.scene.comm.rank == 0:
            print(f"contact: {path.inverted}", flush=True)
    n = step.negative_eigenvalues = negative_eigenvalues(step.result)
    if n and not path.indefinite:
        path.indefinite = (
            f"K_T not positive definite from step {step.index} (t = {step.time:g}: "
            f"{n} negative eigenvalue(s) on the free unknowns)"
        )
        if verbose and step.scene.comm.rank == 0:
            print(
                f"contact: step {step.index}: {path.indefinite}: the solution may be unstable "
                "(past a limit point, or a nonconvex law)",
                flush=True,
            )


def _attempt(
    scene: Scene,
    method: str | None,
    u0: fem.Function | None,
    verbose: bool,
    guess: fem.Function | None,
    options: dict,
) -> Callable[..., Result]:
    """Return the solve of one load step from ``u0`` as a call with keyword overrides.

    The solve of one load step from ``u0`` (``guess`` beside it), as a call whose keywords
    override ``options`` (:func:`follow_branch` asks for plain Newton).
    """

    def attempt(**extra: Any) -> Result:
        return solve(
            scene, method=method, u0=u0, verbose=verbose, alternative=guess, **{**options, **extra}
        )

    return attempt


def searched_indefinite(result: Result) -> bool:
    """Return whether a failed solve was the energy search's and met an indefinite tangent.

    Whether a solve that failed was the energy search's and met a tangent that is not
    positive definite (:mod:`contact.solvers.energy_search`'s log).
    """
    return any(event["negative"] for event in result.tangent_log)


def follow_branch(failed: Result, attempt: Callable[..., Result]) -> tuple[Result, str]:
    """Solve a step on the equilibrium branch where the energy search found no stable state.

    Where the energy search found no stable state that keeps det F > 0 (it met an indefinite
    tangent and stopped or ran out of iterations), the equilibrium branch the path was on:
    the same step by plain Newton (``attempt(line_search="basic")``, from the same start).
    Its solution is taken if it keeps matter whole (det F > 0 everywhere); the load path
    then counts K_T's negative eigenvalues there (:func:`on_branch`): past a bifurcation (St
    Venant–Kirchhoff's homogeneous compression past the loss of stability of its free
    surface) that state is an unstable equilibrium, reported as such. Returns (the result to
    keep, a phrase for the report; '' and ``failed`` if plain Newton gives no admissible
    equilibrium either).
    """
    plain = keep_to_branch(attempt)
    if plain is None:
        return failed, ""
    how = (
        f"the energy search found no stable equilibrium with det F > 0 ({failed.reason} "
        f"after {failed.iterations} Newton iterations); followed the equilibrium branch "
        "(plain Newton)"
    )
    failed.release()
    return plain, how


def keep_to_branch(attempt: Callable[..., Result]) -> Result | None:
    """Return the step solved by plain Newton if it converges and keeps det F > 0, else None.

    The step by plain Newton (the equilibrium branch; :func:`follow_branch`, and the next
    steps on an unstable branch, :func:`on_branch`): its solution if it converges and keeps
    det F > 0, else None (the energy search's answer stands, or takes the step).
    """
    from ..models.hyperelastic import min_det_F

    plain = attempt(line_search="basic")
    if plain.converged and min_det_F(plain) > 0:
        return plain
    plain.release()
    return None


def on_branch(step: Step, how: str, path: LoadPath) -> bool:
    """Record a step solved on the equilibrium branch; return whether the next keeps to it.

    Record a step solved on the equilibrium branch (:func:`follow_branch`) with the negative
    eigenvalues of K_T there (``LoadPath.branch_steps``; the first one's phrase is
    ``LoadPath.bifurcation``, ``Step.branch`` each one's).  Returns whether the next step
    keeps to the branch: while K_T is not positive definite there (the energy search would
    leave it again and find no stable state), plain Newton follows it.
    """
    n = int(step.negative_eigenvalues or 0)
    state = (
        f"unstable, K_T has {n} negative eigenvalue(s) there"
        if n
        else "stable, K_T positive definite there"
    )
    step.branch = f"step {step.index} (t = {step.time:g}): {how}: {state}"
    path.branch_steps.append((step.index, step.time, n))
    if not path.bifurcation:
        path.bifurcation = step.branch
    return n > 0


def _notes(path: LoadPath) -> str:
    """Return the terminal's note on a load path's step cuts and tangent events.

    ', 2 step cut(s) (the last: t = 1 (diverged_fnorm_nan) cut to t = 0.5)' and '; K_T not
    positive definite from step k (…)' ('' without either; every cut is in
    ``LoadPath.cuts``).
    """
    cuts = f", {len(path.cuts)} step cut(s) (the last: {path.cuts[-1]})" if path.cuts else ""
    notes = [note for note in (path.indefinite, path.inverted) if note]
    if path.branch_steps:
        first, last = path.branch_steps[0], path.branch_steps[-1]
        notes.append(
            f"on the equilibrium branch plain Newton followed from step {first[0]} "
            f"(t = {first[1]:g}: {first[2]} negative eigenvalue(s) of K_T; {last[2]} at "
            f"step {last[0]})"
        )
    return cuts + "".join(f"; {note}" for note in notes)
