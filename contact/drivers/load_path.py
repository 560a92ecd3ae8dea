"""Quasi-static load paths over a problem whose data depend on the pseudo-time t.

Quasi-static load paths: a sequence of pseudo-times t_1 < t_2 < … < t_N, one contact solve
per step, over a problem whose data depend on t.

Step k solves the problem at t = t_k, starting from the solution of step k − 1 (a warm
start); friction's slip increments s_t = u_t − u_t^prev are measured from that solution
(the builder receives it).  From the third step on a step is offered the secant predictor
(:func:`extrapolate`) beside the previous solution: Newton starts from the one of smaller
‖Φ‖ (``Result.predictor``).

A step that does not converge may be cut (``cuts``): the step from t_{k−1} to t_k is
retried as two, to (t_{k−1} + t_k)/2 first, at most ``cuts`` times in a row; each cut is
reported (``LoadPath.cuts``) and the failed attempt is not a step.  No cut makes a step
shorter than :data:`MIN_STEP` × the last t.  Where a body's energy search met an
indefinite tangent and found no stable state (``branches``: a hyperelastic body), the step
is solved by plain Newton before it is cut (:func:`follow_branch`): an admissible
equilibrium there is kept and reported with K_T's negative eigenvalues (``Step.branch``,
``LoadPath.bifurcation``, ``LoadPath.branch_steps``), and plain Newton follows that branch
while K_T stays indefinite (:func:`on_branch`).

A path may have any number of steps: once step k is solved (and ``on_step`` has seen it),
step k − 1 is released (:meth:`Step.release`) — its PETSc objects destroyed, its functions
dropped — and keeps only its figures.  Every live function holds MPI communicators (two
per vector on more than one rank) and MPI has a few thousand, so keeping every step whole
(``keep_all``) suits short paths only.  With ``forget`` a released step is dropped
altogether (``LoadPath.forgotten`` counts them): the path's memory does not grow with its
steps, for a caller whose ``on_step`` keeps what it needs (the CLI writes each step's
figures to disk).

:func:`load_path` runs a user's builder ``build(t, u_prev)``; :func:`run_steps` is the loop
itself, over a step's solve and, optionally, an adaptive loop at a step (the scene's:
:mod:`contact.setup.run`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from dolfinx import fem
from mpi4py import MPI

from ..models.discrete import discrete
from ..solvers.energy_search import tangent_text
from ..solvers.options import SolverOptions
from ..solvers.result import Result
from .solve import options_of, solve

#: no cut makes a step shorter than this fraction of the path's last pseudo-time (a scene's
#: schema bounds ``load.cuts`` too: ``contact.setup.config.MAX_STEP_CUTS``)
MIN_STEP = 1e-9


@dataclass
class Step:
    """One load step, as a load path hands it to ``on_step``.

    Attributes:
        index: The step's number, 1 … N.
        time: Its pseudo-time t.
        result: The solve (of the final level, for an adaptive step).
        levels: The adaptive loop's levels (:class:`~contact.drivers.adaptive.Level`), empty
            for a step without one.
        seconds: The step's wall time.
        negative_eigenvalues: A body with an energy: the negative eigenvalues of the tangent
            K_T at the solution (None otherwise).
        min_det_F: Hyperelastic bodies: the smallest det F of the solution.
        branch: Hyperelastic bodies: how the step was solved on the equilibrium branch by
            plain Newton where the energy search found no stable state, in one phrase
            ("" otherwise).
    """

    index: int  # 1 … N
    time: float
    result: Result
    levels: list = field(default_factory=list)  # adaptive.Level of an adaptive step
    seconds: float = 0.0
    negative_eigenvalues: int | None = None  # of K_T at the solution (hyperelastic bodies)
    min_det_F: float | None = None  # the smallest det F of the solution (hyperelastic bodies)
    # solved on the equilibrium branch by plain Newton where the energy search found no
    # stable state (:func:`follow_branch`): what happened, in one phrase; else ''
    branch: str = ""

    def release(self) -> None:
        """Keep the step's figures only.

        Its result and its adaptive levels' results are released
        (``contact.solvers.result.Result.release``: iterations, residual, history,
        contact force stay; functions, nodal arrays and PETSc objects go).
        """
        for level in self.levels:
            level.release()
        self.result.release()


@dataclass
class LoadPath:
    """The steps of a quasi-static load path (:func:`contact.run_load_path`).

    Attributes:
        steps: The steps solved, in order (each a :class:`~contact.drivers.load_path.Step`,
            or a scene's step; all but the last converged ones are released unless
            ``keep_all``).
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

    steps: list = field(default_factory=list)
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


@dataclass
class Previous:
    """What a load step starts from.

    What a step starts from: the previous step's solution ``u`` (None before the first),
    its pseudo-time ``time``, the secant predictor's ``guess`` (or None), and what the
    previous step was solved on (``where``: its mesh, scene…; None before the first).
    """

    u: fem.Function | None
    time: float
    guess: fem.Function | None
    where: Any


#: a step's solve: (t, what it starts from, solver overrides) → (what it was solved on, result)
StepSolve = Callable[..., tuple[Any, Result]]
#: the adaptive loop at a step: (t, what it starts from) → (its final mesh's…, result, levels)
StepAdapt = Callable[[float, Previous], tuple[Any, Result, list]]


def copy_function(fn: fem.Function, name: str) -> fem.Function:
    """Return a copy of ``fn`` named ``name`` on the same space."""
    out = fem.Function(fn.function_space, name=name)
    out.x.array[:] = fn.x.array
    return out


def extrapolate(
    u_prev: fem.Function, u_prev2: fem.Function, t: float, t_prev: float, t_prev2: float
) -> fem.Function | None:
    """Return the secant predictor of step k from the two previous solutions.

    u_k ≈ u_{k−1} + (t_k − t_{k−1}) / (t_{k−1} − t_{k−2}) (u_{k−1} − u_{k−2}) (None when the
    two steps live on different meshes: an adaptive path).
    """
    V, W = u_prev.function_space, u_prev2.function_space
    if V.mesh is not W.mesh or len(u_prev.x.array) != len(u_prev2.x.array) or t_prev <= t_prev2:
        return None
    ratio = (t - t_prev) / (t_prev - t_prev2)
    out = fem.Function(u_prev.function_space, name="u_predicted")
    out.x.array[:] = u_prev.x.array + ratio * (u_prev.x.array - u_prev2.x.array)
    return out


def run_steps(
    solve_step: StepSolve,
    times: Sequence[float],
    comm: MPI.Comm,
    *,
    adapt_step: StepAdapt | None = None,
    adapt_each: bool = False,
    cuts: int = 0,
    predictor: bool = True,
    branches: bool = False,
    on_step: Callable[[Any], None] | None = None,
    make_step: Callable[..., Step] | None = None,
    verbose: bool = False,
    keep_all: bool = False,
    forget: bool = False,
) -> LoadPath:
    """The load path of the module doc.

    Args:
        solve_step: ``solve_step(t, previous, **overrides)`` → (what it was solved on, its
            result): one solve of the step to t (``overrides``: solver options, plain Newton
            for :func:`follow_branch`).
        times: the pseudo-times.
        comm: the problem's communicator (who prints).
        adapt_step: ``adapt_step(t, previous)`` → (what the last level was solved on, its
            result, the levels): the adaptive loop at a step, at the last step only or at
            every step (``adapt_each``); None: every step is one solve.
        adapt_each: run ``adapt_step`` at every step (each refining on from the previous
            step's final mesh), not only at the last.
        cuts: how many times in a row a failed step is halved.
        predictor: offer the secant predictor from the third step on.
        branches: follow the equilibrium branch where the energy search found no stable
            state, and check the stability of every solution (a body with an energy).
        on_step: called with each step record as it is done.
        make_step: ``make_step(index, t, where, result, levels, seconds)`` → the step record
            (default :class:`Step`, ``where`` left out).
        verbose: a line per step and per cut (rank 0).
        keep_all: keep every step whole (else each is released once the next is done).
        forget: drop released steps from ``LoadPath.steps`` altogether (counted in
            ``LoadPath.forgotten``), for a caller that keeps each step's figures itself as
            it goes (the CLI's step writer): the path's memory then stays flat.

    Returns:
        The :class:`LoadPath`; it stops at the first step that does not converge and may
        not be cut.
    """
    make = make_step or _step
    smallest = MIN_STEP * abs(times[-1])
    following = False  # on an unstable equilibrium branch: plain Newton (follow_branch)
    out, u_prev, t_prev, where = LoadPath(), None, 0.0, None
    u_prev2, t_prev2 = None, 0.0  # the step before the previous one (the predictor)
    pending = [(t, 0) for t in times]  # (pseudo-time, cuts that led to it)
    while pending:
        t, depth = pending.pop(0)
        k = out.count + 1
        t0 = time.perf_counter()
        if verbose and comm.rank == 0 and len(times) > 1:
            print(f"contact: load step {k}/{k + len(pending)}, t = {t:g}", flush=True)
        levels: list = []
        branch = ""
        if adapt_step is not None and (adapt_each or not pending):
            solved_on, result, levels = adapt_step(t, Previous(u_prev, t_prev, None, where))
        else:
            guess = None
            if predictor and u_prev is not None and u_prev2 is not None:
                guess = extrapolate(u_prev, u_prev2, t, t_prev, t_prev2)
            previous = Previous(u_prev, t_prev, guess, where)

            def attempt(previous: Previous = previous, t: float = t, **extra: Any) -> Result:
                nonlocal solved_on
                solved_on, r = solve_step(t, previous, **extra)
                return r

            solved_on = None
            kept = keep_to_branch(attempt) if following else None
            if kept is not None:
                result, branch = kept, "on the equilibrium branch (plain Newton)"
            else:
                result = attempt()
                if branches and not result.converged and searched_indefinite(result):
                    result, branch = follow_branch(result, attempt)
        why = ""
        if not result.converged:
            mid = t_prev + (t - t_prev) / 2
            if depth < cuts and mid - t_prev >= smallest:
                out.cuts.append(f"t = {t:g} ({result.reason}) cut to t = {mid:g}")
                if verbose and comm.rank == 0:
                    print(
                        f"contact: step {k} to t = {t:g} did not converge ({result.reason}): "
                        f"cut to t = {mid:g} (cut {depth + 1} of at most {cuts} in a row)",
                        flush=True,
                    )
                result.release()
                pending[:0] = [(mid, depth + 1), (t, depth + 1)]
                continue
            why = (
                f"a cut would make the step {mid - t_prev:.3g}, below the smallest "
                f"({MIN_STEP:g} of t = {times[-1]:g})"
                if depth < cuts
                else f"cut {depth} time(s) in a row (load.cuts: {cuts})"
                if cuts
                else ""
            )
        step = make(k, t, solved_on, result, levels, time.perf_counter() - t0)
        text = tangent_text(result.tangent_log)  # what the energy search did (hyperelastic)
        if text:
            out.tangent_events.append(f"step {k} (t = {t:g}): {text}")
        if result.converged and branches:
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
        where, t_prev = solved_on, t  # an adaptive path continues on this step's final mesh
        u_prev = copy_function(result.u_h, "u_prev")
        if len(out.steps) > 1 and not keep_all:
            out.steps[-2].release()
            if forget and len(out.steps) > 2:
                del out.steps[0]
                out.forgotten += 1
    else:
        out.stop = f"reached t = {times[-1]:g} in {out.count} step(s)" + _notes(out)
    return out


def _step(k: int, t: float, where: Any, result: Result, levels: list, seconds: float) -> Step:
    """A :class:`Step` record (``where`` left out)."""
    return Step(k, t, result, levels, seconds)


def load_path(
    build: Callable[[float, fem.Function | None], Any],
    times: Sequence[float],
    method: str | None = None,
    *,
    options: SolverOptions | None = None,
    cuts: int = 0,
    predictor: bool = True,
    on_step: Callable[[Step], None] | None = None,
    verbose: bool = False,
    keep_all: bool = False,
    **overrides: Any,
) -> LoadPath:
    """The load path of a user's problem whose data depend on the pseudo-time t.

    Args:
        build: ``build(t, u_prev)``: the problem at t (a
            :class:`~contact.models.forms.ComplementarityProblem` or a model's problem),
            given the previous step's solution (None on the first step; friction measures
            its slips from it).
        times: the pseudo-times t_1 < … < t_N.
        method: the solver's method (fb, min, blend, …).
        options: the :class:`~contact.solvers.options.SolverOptions` of every step;
            ``overrides`` change single knobs.
        cuts: how many times in a row a step that does not converge is halved.
        predictor: offer the secant predictor from the third step on.
        on_step: called with each :class:`Step` as it is done.
        verbose: a line per step (rank 0 of ``MPI.COMM_WORLD``).
        **overrides: single knobs of ``options``, validated.
        keep_all: keep every step's functions (else each step is released once the next
            one is done).

    Returns:
        The :class:`LoadPath`.
    """
    opts = options_of(options, method, overrides)

    def solve_step(t: float, previous: Previous, **extra: Any) -> tuple[Any, Result]:
        problem = discrete(build(t, previous.u))
        knobs = options_of(opts, None, extra)
        return problem.V.mesh, solve(
            problem,
            options=knobs,
            u0=previous.u,
            alternative=previous.guess,
            assembly=problem.assembly_time,
            verbose=verbose,
        )

    return run_steps(
        solve_step,
        times,
        MPI.COMM_WORLD,
        cuts=cuts,
        predictor=predictor,
        branches=False,
        on_step=on_step,
        verbose=verbose,
        keep_all=keep_all,
    )


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

    comm = step.result.u_h.function_space.mesh.comm
    J = step.min_det_F = min_det_F(step.result)
    if J <= 0 and not path.inverted:
        path.inverted = (
            f"step {step.index} (t = {step.time:g}) inverts matter (min det F = {J:.3g}): "
            "not a physical deformation"
        )
        if verbose and comm.rank == 0:
            print(f"contact: {path.inverted}", flush=True)
    n = step.negative_eigenvalues = negative_eigenvalues(step.result)
    if n and not path.indefinite:
        path.indefinite = (
            f"K_T not positive definite from step {step.index} (t = {step.time:g}: "
            f"{n} negative eigenvalue(s) on the free unknowns)"
        )
        if verbose and comm.rank == 0:
            print(
                f"contact: step {step.index}: {path.indefinite}: the solution may be unstable "
                "(past a limit point, or a nonconvex law)",
                flush=True,
            )


def searched_indefinite(result: Result) -> bool:
    """Return whether a failed solve was the energy search's and met an indefinite tangent.

    Whether a solve that failed was the energy search's and met a tangent that is not
    positive definite (``contact.solvers.energy_search``'s log).
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
