"""Quasi-static load paths (``load:`` section): a sequence of pseudo-times
t_1 < t_2 < … < t_N, one contact solve per step.

Data expressions may use the pseudo-time ``t`` (e.g. ``u_D: ["0.01*t", "-delta"]``); step k
solves the problem at t = t_k, starting from the solution of step k − 1 (a warm start), and
friction's slip increments s_t = u_t − u_t^prev are measured from that solution (the state
``u_prev`` of :attr:`contact.setup.scene.Scene.history`; zero before the first step).  A scene
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
    """One load step: its pseudo-time, the scene it was solved on (the final mesh of its
    adaptive loop, if any), the result, the adaptive loop's levels and the wall time."""

    index: int  # 1 … N
    time: float
    scene: Scene
    result: Result
    levels: list = field(default_factory=list)  # adapt.Level of an adaptive step
    seconds: float = 0.0
    negative_eigenvalues: int | None = None  # of K_T at the solution (hyperelastic bodies)
    min_det_F: float | None = None  # the smallest det F of the solution (hyperelastic bodies)

    def release(self) -> None:
        """Keep the step's figures only: its result and its adaptive levels' results are
        released (:meth:`contact.solvers.result.Result.release`: iterations, residual,
        history, contact force stay; functions, nodal arrays and PETSc objects go), its
        scene and the levels' scenes and η_T functions dropped."""
        for level in self.levels:
            level.result.release()
            level.scene, level.estimate.eta_T = None, None
        self.result.release()
        self.scene = None  # type: ignore[assignment]  # released: unused afterwards


@dataclass
class LoadPath:
    steps: list[Step] = field(default_factory=list)
    stop: str = ""
    cuts: list[str] = field(default_factory=list)  # step cutting: 't = … (reason) cut to t = …'
    indefinite: str = ""  # the first step whose K_T is not positive definite (hyperelastic)
    inverted: str = ""  # the first step whose solution inverts matter (det F <= 0)
    # what the energy search did, one line per step where it did anything (hyperelastic)
    tangent_events: list[str] = field(default_factory=list)
    forgotten: int = 0  # converged steps dropped before ``steps`` (run_load_path's forget)

    @property
    def converged(self) -> bool:
        return bool(self.steps) and all(s.result.converged for s in self.steps)

    @property
    def count(self) -> int:
        """The number of steps, forgotten ones included."""
        return self.forgotten + len(self.steps)


def load_times(cfg: SceneConfig) -> list[float]:
    """The pseudo-times of the scene's load path ([1.0] without a ``load:`` section)."""
    return list(cfg.load.times) if cfg.load is not None else [1.0]


def copy_function(fn: fem.Function, name: str) -> fem.Function:
    out = fem.Function(fn.function_space, name=name)
    out.x.array[:] = fn.x.array
    return out


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


def extrapolate(
    u_prev: fem.Function, u_prev2: fem.Function, t: float, t_prev: float, t_prev2: float
) -> fem.Function | None:
    """The secant predictor
    u_k ≈ u_{k−1} + (t_k − t_{k−1}) / (t_{k−1} − t_{k−2}) (u_{k−1} − u_{k−2})
    (None when the two steps live on different meshes: ``load.adapt: each``)."""
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
    """Solve the scene's load path step by step (see the module doc); ``on_step`` is called
    after every step (the CLI writes its output there: anything that needs a step's
    functions or scene belongs there).  Stops at the first step that does not converge —
    unless step cutting (``load.cuts``, :func:`step_cuts`) may halve it: the step from
    t_{k−1} to t_k is then retried as two, to (t_{k−1} + t_k)/2 first, at most ``cuts``
    times in a row; each cut is reported (``LoadPath.cuts``, verbose output) and the failed
    attempt is not a step (``on_step`` sees converged steps and the final failure only).
    The last step stays whole, and the last converged one before a failed step; the others
    are released when the next one is solved (:meth:`Step.release`), unless ``keep_all``,
    and with ``forget`` dropped from ``LoadPath.steps`` (counted in ``forgotten``).
    ``adaptive``: run the adaptive loop (default: when the scene has an ``adapt``
    section), with ``adapt_options`` overriding that section; ``options`` are solver
    options as for :func:`contact.solve`.

    From the third step on, a step is offered the secant predictor (:func:`extrapolate`,
    ``load.predictor``) beside the previous solution: Newton starts from the one of
    smaller ‖Φ‖ (``Result.predictor``)."""

    verbose = scene.config.output.verbose if verbose is None else verbose
    times = load_times(scene.config)
    max_cuts = step_cuts(scene.config)
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
        levels = []
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
            result = solve(
                step_scene, method=method, u0=u_prev, verbose=verbose, alternative=guess, **options
            )
        if not result.converged and depth < max_cuts:
            mid = t_prev + (t - t_prev) / 2
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
        step = Step(k, t, step_scene, result, levels, time.perf_counter() - t0)
        text = tangent_text(result.tangent_log)  # what the energy search did (hyperelastic)
        if text:
            out.tangent_events.append(f"step {k} (t = {t:g}): {text}")
        if result.converged and scene.config.model.type == "hyperelastic":
            check_tangent(step, out, verbose)
        out.steps.append(step)
        if on_step is not None:
            on_step(step)
        if not result.converged:
            out.stop = f"step {k} (t = {t:g}) did not converge ({result.reason})" + _notes(out)
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
    """Count the negative eigenvalues of a hyperelastic step's tangent K_T at its solution
    (:func:`contact.models.hyperelastic.negative_eigenvalues`) and its smallest det F; the
    first step where K_T is not positive definite is reported (``LoadPath.indefinite``, the
    stop text, verbose), and the first whose solution inverts matter (``inverted``: an
    equilibrium of the discrete equations that no body reaches — plain Newton on St
    Venant–Kirchhoff in strong compression converges to such states)."""
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


def _notes(path: LoadPath) -> str:
    """', 2 step cut(s): t = 1 (diverged_fnorm_nan) cut to t = 0.5; …' and '; K_T not
    positive definite from step k (…)' ('' without either)."""
    cuts = f", {len(path.cuts)} step cut(s): " + "; ".join(path.cuts) if path.cuts else ""
    notes = [note for note in (path.indefinite, path.inverted) if note]
    return cuts + "".join(f"; {note}" for note in notes)
