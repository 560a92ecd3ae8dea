"""One solve of a discrete problem from an initial guess: :class:`SemismoothNewton`, in the
spirit of ``dolfinx.fem.petsc.NonlinearProblem``, owns a PETSc SNES (semismooth Newton on
an NCP function, or one of PETSc's VI solvers), its options prefix, its Newton system and
line-search pre-check, and a monitor that records the history; :meth:`~SemismoothNewton.solve`
returns the :class:`~contact.solvers.result.Result`.  :func:`solve_problem` is one solve
with one solver.  The scene's part of a solve (its problem, options and initial guess) is
:func:`contact.drivers.solve.solve`."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base import progress
from ..base.errors import ConfigError
from ..base.lifetime import Owner
from ..base.norms import norm1, norm2, norm_inf
from ..base.timing import Stopwatch
from . import ncp
from .krylov_curvature import KrylovCurvatureSystem
from .newton import BlockComplementarity, Complementarity
from .options import SolverOptions, check_petsc_options, petsc_value, set_from_options
from .predictor import tangent_predictor
from .problem import DiscreteProblem, newton_max_it, nodal_scaling
from .reduced import ReducedSystem
from .result import Result, finish
from .stopping import STOPPED_REASON, AdaptiveStopping, energy_norm
from .strategies import choose, complementarity, energy_linear

_counter = itertools.count()


def solve_problem(
    problem: DiscreteProblem,
    u0: fem.Function,
    opts: SolverOptions,
    comm: MPI.Comm,
    verbose: bool,
    guess: bool,
    timers: dict,
    clock: Stopwatch,
    check_options: bool = False,
    stopping: AdaptiveStopping | None = None,
    alternatives: tuple[fem.Function, ...] = (),
) -> Result:
    """Solve ``problem`` from ``u0`` (a function of ``problem.V`` holding the Dirichlet values;
    ``guess``: a real initial guess, given or from coarser levels, not a cold start) with
    the :class:`~.options.SolverOptions` ``opts``; return a :class:`Result` (never raises on
    divergence).  ``timers`` holds the seconds counted so far (``assembly``, ``solve``,
    ``coarse``), ``clock`` runs since the start of the whole solve; ``check_options``: the PETSc
    options were given for this solve and are checked first (a scene's were checked
    when it was loaded); ``stopping``: adaptive stopping (:mod:`.stopping`), consulted by
    the Newton monitor and the reduced system's Krylov solves; ``alternatives``: other
    guesses (a load path's predictor), the one of smallest ‖Φ‖ is taken
    (:meth:`SemismoothNewton.solve`)."""
    with SemismoothNewton(
        problem,
        opts,
        comm,
        verbose=verbose,
        timers=timers,
        check_options=check_options,
        stopping=stopping,
    ) as solver:
        return solver.solve(u0, guess=guess, clock=clock, alternatives=alternatives)


class SemismoothNewton:
    """The solver of a :class:`~.problem.DiscreteProblem` with :class:`~.options.SolverOptions`:
    semismooth Newton on Φ of ``options.method`` ∈ {fb, min, blend} (:mod:`.newton`; the
    frictional block law of :mod:`.friction` when the problem has friction), or PETSc's VI
    solver vinewtonrsls / vinewtonssls (:mod:`.vi`), through one PETSc SNES.

    It owns the SNES (options prefix ``prefix``, default ``contact<n>_``), the Newton system
    (:mod:`.linear`), the pre-check (polishing or the cycle guard) and its work vectors, and
    destroys them in :meth:`close` (or on leaving a ``with`` block); the problem stays the
    caller's.  ``timers`` (``assembly``, ``solve``; default new) receive the seconds of the
    callbacks and linear solves; ``check_options``: check ``options.petsc_options`` on a tiny
    system first (one ConfigError line); ``stopping``: adaptive stopping (:mod:`.stopping`),
    consulted by the monitor and the reduced system's Krylov solves.  Each :meth:`solve` is
    one Newton solve from a guess.
    """

    def __init__(
        self,
        problem: DiscreteProblem,
        options: SolverOptions,
        comm: MPI.Comm | None = None,
        prefix: str | None = None,
        verbose: bool = False,
        timers: dict | None = None,
        check_options: bool = False,
        stopping: AdaptiveStopping | None = None,
    ):
        user = {str(k): v for k, v in options.petsc_options.items()}
        options = energy_line_search(problem, options, user)
        self.problem, self.opts, self.verbose = problem, options, verbose
        self.stopping = stopping
        self.comm = comm = problem.V.mesh.comm if comm is None else comm
        self.timers = {"assembly": 0.0, "solve": 0.0} if timers is None else timers
        self.method = method = options.method
        # what runs the solve, chosen once from the problem's parts (.strategies)
        kind = choose(problem, options)
        self.linear = kind.linear_kind(problem, options, user)
        defaults = kind.defaults(problem, options, self.linear)
        if stopping is not None and self.linear == "gamg":  # η_alg: CG's natural residual norm
            defaults["ksp_norm_type"] = "natural"
            # a solve to γ_alg η_disc takes a few CG iterations (problem A: 3 a level), so GAMG's
            # set-up is most of its cost: the plain aggregation of 3D (options.default_options)
            # sets up in about half the time, and its few more iterations stay cheaper
            # (demos/RESULTS.md §12)
            defaults["pc_gamg_agg_nsmooths"] = 0
        self.petsc_options = {**defaults, **user}
        if check_options:
            check_petsc_options(options.petsc_options, defaults, comm)

        self._owner = owner = Owner()  # the solver's PETSc objects, destroyed by close()
        self.cp: Complementarity = owner.own(complementarity(problem))
        strategy = kind(problem, self.cp, options)
        self.snes = snes = owner.own(PETSc.SNES().create(comm))  # type: ignore[arg-type]
        self.prefix = f"contact{next(_counter)}_" if prefix is None else prefix
        snes.setOptionsPrefix(self.prefix)
        self.state: dict[str, Any] = {"t_jac": None, "dir_norm": np.nan}
        strategy.configure(
            snes,
            owner,
            self.prefix,
            self.linear,
            self.timers,
            self.state,
            self.petsc_options,
            verbose,
        )
        self.system = strategy.system
        self.polisher, self.guard, self.search = strategy.polisher, strategy.guard, strategy.search
        self.J = strategy.J
        if isinstance(self.system, ReducedSystem):
            self.system.stopping = stopping
        snes.getKSP().setPostSolve(self._post_solve)
        # semismooth Newton may raise ‖Φ‖ on its way: no dtol stop
        snes.setDivergenceTolerance(PETSc.UNLIMITED)
        if self.search is not None:
            # at least one Newton step, so its factorization tests the tangent's inertia: a
            # start that is already an equilibrium (the predictor's straight strip past its
            # buckling load) may be a saddle that the energy search leaves (.energy_search)
            snes.setForceIteration(True)
        snes.setMonitor(self._monitor)
        progress.watch(
            self.system.ksp if isinstance(self.system, ReducedSystem) else snes.getKSP(),
            f"{method} linear solve",
        )
        # the tangent predictor (.predictor): a nonlinear problem's start, by default where
        # the problem has an energy (a hyperelastic body)
        # (a bound constraint: not contact on the current configuration, .current)
        self.predict = (
            problem.nonlinear
            and problem.current is None
            and (
                options.predictor == "tangent"
                or (options.predictor == "auto" and problem.has_energy)
            )
        )
        self.predicted: bool | None = None  # whether the last solve took the predictor's start
        self._prev = owner.own(problem.b.duplicate())  # the previous iterate (step lengths)
        self.history: list[dict] = []
        self._prev_active: np.ndarray | None = None  # the active set of the previous iterate
        self.solves = 0  # solves done by this object
        self.max_it = 0  # the step limit of the current solve (solver.max_it, auto resolved)
        self._auto_max_it = False  # max_it auto on a Newton solve: the monitor stops it
        self._auto_resolved = False  # … and has computed the limit by the mesh
        self._snes_max_it = 0  # SNES's own limit

    def solve(
        self,
        u0: fem.Function,
        guess: bool = False,
        clock: Stopwatch | None = None,
        alternatives: tuple[fem.Function, ...] = (),
    ) -> Result:
        """Solve from ``u0`` (a function of ``problem.V``; the Dirichlet values are put in);
        ``guess``: a real initial guess, given or from coarser levels, not a cold start (it is
        polished first, and the gamg path takes an exact first step); ``clock``: the
        :class:`~contact.base.timing.Stopwatch` of the whole solve (default: one from now);
        ``alternatives``: other guesses (functions of ``problem.V``): the solve starts from
        the one of u0 and these whose ‖Φ‖ is smallest (``Result.predictor``: whether an
        alternative won; a linear problem's only: a nonlinear one keeps u0).  Returns the
        :class:`Result` (never raises on divergence)."""
        problem, opts, snes, cp, method = self.problem, self.opts, self.snes, self.cp, self.method
        clock = Stopwatch() if clock is None else clock
        polisher, guard, system = self.polisher, self.guard, self.system
        counts = (
            polisher.solves if polisher else 0,
            guard.backtracked if guard else 0,
            system.krylov_iterations if system else 0,
            len(getattr(system, "log", [])),
        )
        if polisher is not None:
            polisher.initial_accepted = False
        if self.solves and method not in ncp.METHODS:
            # the VI solvers leave the KSP with the operators of the last reduced space
            snes.getKSP().reset()
        self.solves += 1
        if guard is not None:
            guard.restart()
        if self.search is not None:
            self.search.restart()
        x = problem.b.duplicate()
        try:
            problem.to_unknowns(u0.x.petsc_vec, x)
            self.predicted = None
            if self.predict:  # the step's increments lifted by the tangent at u0
                problem.linearize(x)
                self._scaling()
                krylov = isinstance(self.system, KrylovCurvatureSystem)
                self.predicted = tangent_predictor(cp, x, krylov=krylov)
            set_dirichlet(x, problem.bcs)
            if guess:
                self._admissible(x)
            problem.linearize(x)
            self._scaling()
            # solver.atol is relative to the data's force scale (force_scale), rtol to ‖Φ(x_0)‖
            scale, self._total = force_scale(
                cp, problem, method if method in ncp.METHODS else "fb", opts.mu
            )
            self.atol = opts.atol * scale
            chosen = None
            if alternatives and not problem.nonlinear:
                x, chosen = self._best_guess(x, alternatives)
            # ``auto``: the floor first; the limit by the nodes across the constrained set is
            # computed (collectively, from the node coordinates) only if a Newton solve gets
            # there, and the monitor stops at it; SNES's own limit, which PETSc reads once,
            # is then the number of constrained nodes, never fewer than the nodes across.
            # (PETSc's VI solvers: the limit at once)
            self._auto_max_it = opts.max_it == "auto" and method in ncp.METHODS
            self._auto_resolved = False
            self.max_it = newton_max_it(
                opts.max_it, 0.0 if self._auto_max_it else problem.nodes_across()
            )
            self._snes_max_it = self.max_it
            if self._auto_max_it:
                nodes = problem.constraint.global_size(self.comm)
                self._snes_max_it = max(self.max_it, nodes + 1)
            snes.setTolerances(rtol=opts.rtol, atol=self.atol, stol=0.0, max_it=self._snes_max_it)
            # for the round-off floor of ‖Φ‖
            # the Mat's infinity norm is one float (the stubs: a pair for every norm type)
            self._k_norm: float = problem.K.norm(PETSc.NormType.INFINITY)  # type: ignore[arg-type,assignment]
            self.history, self._prev_active = [], None
            self.state.update(t_jac=None, dir_norm=np.nan, stop=None)
            result = self._run(x, guess, clock, counts)
            result.predictor = None if chosen is None else chosen > 0
            return result
        finally:
            x.destroy()

    def _scaling(self) -> None:
        """The NCP scaling c of the problem at its current K (it follows the solve's options)."""
        problem, opts = self.problem, self.opts
        con = problem.constraint
        problem.c = (
            nodal_scaling(problem.K, con.dofs, con.w, opts.kappa)
            if opts.c == "auto"
            else float(opts.c)
        )

    def _admissible(self, x: PETSc.Vec) -> None:
        """Project a guess onto the bound: x_i ← g_i on the constrained nodes with a
        negative gap σ (g_i − x_i) < 0 (:data:`ADMISSIBLE_GUESS`), the Dirichlet values
        kept.  Only where the constraint is a bound on one body's x (not on the current
        configuration, no friction, no mortar pairs: a pair's gap couples two bodies'
        displacements, and a node moved onto the bound on one side spoils a coupled guess
        that was already balanced) and the residual linear (a nonlinear body's cells may not
        be moved)."""
        problem, cp = self.problem, self.cp
        if (
            not ADMISSIBLE_GUESS
            or self.method not in ncp.METHODS
            or problem.nonlinear
            or problem.data.couplings
            or type(cp) is not Complementarity  # a block law (friction, current gaps)
        ):
            return
        dofs, g = cp.dofs, np.broadcast_to(cp.g, cp.dofs.shape)
        below = cp.sign * (g - x.array_r[dofs]) < 0
        x.array_w[dofs[below]] = g[below]
        set_dirichlet(x, problem.bcs)

    def _best_guess(
        self, x: PETSc.Vec, alternatives: tuple[fem.Function, ...]
    ) -> tuple[PETSc.Vec, int]:
        """The guess of smallest ‖Φ‖ among x and ``alternatives`` (their Dirichlet values put
        in; ties keep the earlier one) and its index (0: x); the others are destroyed."""
        problem, cp, opts = self.problem, self.cp, self.opts
        method = self.method if self.method in ncp.METHODS else "fb"
        best, norm, which = x, cp_norm(cp, x, method, opts.mu), 0
        for k, u in enumerate(alternatives, start=1):
            check_guess(u, problem)
            y = problem.b.duplicate()
            problem.to_unknowns(u.x.petsc_vec, y)
            set_dirichlet(y, problem.bcs)
            self._admissible(y)
            value = cp_norm(cp, y, method, opts.mu)
            if value < norm:
                best.destroy()
                best, norm, which = y, value, k
            else:
                y.destroy()
        return best, which

    def _run(self, x: PETSc.Vec, guess: bool, clock: Stopwatch, counts: tuple) -> Result:
        problem, opts, snes, cp, method = self.problem, self.opts, self.snes, self.cp, self.method
        polisher, guard, system, prefix = self.polisher, self.guard, self.system, self.prefix
        popts = PETSc.Options()
        try:  # the options stay until the solve is done: some are read at set-up (GAMG's
            # mg_levels_*, MUMPS's mat_mumps_*), which happens in the first linear solve
            for key, val in self.petsc_options.items():
                popts.setValue(prefix + key, petsc_value(val))
            set_from_options(snes, *([system.ksp] if isinstance(system, ReducedSystem) else []))
            if system is not None:
                system.set_options()
            if isinstance(system, ReducedSystem):
                system.restart()
                # the first Newton step from a guess is exact — unless the guess is polished
                # first: that exact solve on the guess's active set is then done, and a Newton
                # step still needed means the active set moves, where a loose step does as well.
                # A frictional guess (the previous load step, a coarse level) seldom has the
                # final stick and slip sets: its first step is loose too
                system.guess = guess and polisher is None and problem.friction is None
            if self.stopping is not None:
                self.stopping.start(cp.active(x))
            # SNES tests its stop at iteration 0 before the monitor raises it to the round-off
            # floor: the floor is put in here, or a start at the floor (a converged guess, a
            # polished one) would cost a Newton step (and a second polishing solve)
            floor = self._floor(x)
            if polisher is not None and guess:
                # polish the guess first; SNES's relative tolerance still refers to the guess's ‖Φ‖
                stop = max(self.atol, opts.rtol * cp_norm(cp, x, method, opts.mu), floor)
                polisher.initial(x, stop)
                self.state["stop"] = stop
                snes.setTolerances(rtol=0.0, atol=stop, stol=0.0, max_it=self._snes_max_it)
            elif floor > snes.getTolerances()[1]:
                snes.setTolerances(atol=floor)
            # SNES, its monitor, the Jacobian and min's cycle guard all evaluate R at each
            # iterate: a linear residual's is computed once per iterate (old path:
            # ``solver.petsc_options.reuse_residual: false``)
            cp.remember(self._reuse_residual(popts))
            try:
                snes.solve(None, x)
            finally:
                cp.remember(False)
            reason_code = snes.getConvergedReason()
            result = finish(
                self.comm,
                problem,
                cp,
                x,
                snes,
                self.history,
                method,
                opts,
                self.timers,
                clock,
                reason_code,
                inexact=self.stopping is not None,
            )
            result.linear = self.linear
            result.max_it = self.max_it
            if self.stopping is not None:
                result.stopping = self.stopping
                result.reason = "converged_adaptive" if self.stopping.stopped else result.reason
            if problem.friction is not None:
                from .friction import friction_fields

                assert isinstance(cp, BlockComplementarity)  # a frictional problem's
                result.friction = friction_fields(problem, cp, x)
            if polisher is not None:
                result.polish_solves = polisher.solves - counts[0]
            if guard is not None:
                result.backtracked = guard.backtracked - counts[1]
            if self.search is not None:
                result.tangent_log = list(self.search.log)
            result.predicted = self.predicted
            if system is not None:
                result.krylov_iterations = system.krylov_iterations - counts[2]
                result.krylov_log = getattr(system, "log", [])[counts[3] :]
            else:
                result.krylov_iterations = snes.getLinearSolveIterations()
        finally:
            for key in self.petsc_options:
                popts.delValue(prefix + key)
        return result

    def _reuse_residual(self, popts: PETSc.Options) -> bool:
        """Whether :meth:`Complementarity.pair` may reuse R(x) within this solve: a linear
        residual (K and b fixed) of a diagonal law, unless ``reuse_residual`` is false."""
        cp = self.cp
        if self.problem.nonlinear or isinstance(cp, BlockComplementarity):
            return False
        return bool(popts.getBool(self.prefix + "reuse_residual", True))

    def _post_solve(self, ksp: PETSc.KSP, rhs: PETSc.Vec, sol: PETSc.Vec) -> None:
        """After each linear solve: its Krylov count and seconds, the direction's norm."""
        state = self.state
        if self.system is not None:
            self.system.count(ksp)
        if state["t_jac"] is not None:  # the linear solve's Timer, started after the Jacobian
            state["t_jac"].stop()
            state["t_jac"] = None
        state["dir_norm"] = sol.norm()

    def _floor(self, x: PETSc.Vec) -> float:
        """The round-off floor of ‖Φ(x)‖ (:func:`roundoff_floor`) that SNES's stopping test
        never asks to go below, capped at atol · F₁ (F₁ the total force of the data).

        Also where a body floats (nothing but contact holds it): ‖x‖ may grow there along a
        free rigid motion r, but then so does the round-off of K x − b (K r = 0 holds only
        to ε ‖K‖ ‖x‖), and the cap keeps the test at a fraction atol of the data's force, so
        a drifting iterate is never accepted for its size.  The floor decides where atol · F
        (F the largest nodal force, ∝ h^d) lies below the round-off of ‖Φ‖: fine meshes, P2's
        small nodal forces, and a start that is the discrete solution already."""
        return max(
            min(roundoff_floor(self._k_norm, x), self.opts.atol * self._total),
            self.cp.gap_roundoff(x),  # gaps of coordinates: bounded by the data, not by x
        )

    def _monitor(self, snes: PETSc.SNES, its: int, fnorm: float) -> None:
        """One row of the history per iterate (‖Φ‖, step length, active set, changes), the
        round-off floor of the stopping test, the verbose line or the progress note."""
        comm, cp, opts, method = self.comm, self.cp, self.opts, self.method
        polisher, system, prev = self.polisher, self.system, self._prev
        xk = snes.getSolution()
        if self._auto_max_it and its >= self.max_it:  # max_it auto: the floor reached
            if not self._auto_resolved:
                self._auto_resolved = True
                self.max_it = newton_max_it("auto", self.problem.nodes_across())
            if its >= self.max_it and snes.getConvergedReason() == 0:
                snes.setConvergedReason(PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT)  # type: ignore[arg-type]
        floor = self._floor(xk)
        if floor > snes.getTolerances()[1]:  # atol · F out of reach: stop at the floor
            snes.setTolerances(atol=floor)
            if polisher is not None:
                polisher.done = max(polisher.done, floor)
            if isinstance(system, ReducedSystem):
                system.stop = max(system.stop, floor)
        active = cp.active(xk)
        n_active = comm.allreduce(int(active.sum()), op=MPI.SUM)
        changed = (
            0
            if self._prev_active is None
            else comm.allreduce(int((active != self._prev_active).sum()), op=MPI.SUM)
        )
        if isinstance(system, ReducedSystem):  # the next step's forcing term (.reduced)
            system.changed = changed if its > 0 else None
        step, energy = np.nan, np.inf
        stopping = self.stopping
        if its > 0:
            prev.axpy(-1.0, xk)
            # the direction actually taken: the polished one, or Newton's
            taken = polisher.taken if polisher is not None else None
            dn = taken if taken is not None else self.state["dir_norm"]
            step = norm2(prev) / dn if dn > 0 else 0.0
            energy = energy_norm(self.problem.K, prev) if stopping is not None else np.inf
        else:  # SNES's stopping test, newtonls: ‖Φ‖ ≤ max(atol, rtol ‖Φ_0‖)
            done = self.state.get("stop") or max(self.atol, opts.rtol * fnorm)
            if polisher is not None:
                polisher.done = done
            if system is not None:
                system.stop = done
        xk.copy(prev)
        self._prev_active = active
        polished = polisher is not None and (
            polisher.accepted if its > 0 else polisher.initial_accepted
        )
        row = {
            "iteration": its,
            "residual": float(fnorm),
            "step": float(step),
            "active": n_active,
            "changed": changed,
            "polished": polished,
        }
        extra = ""
        if self.problem.friction is not None:
            from .friction import status_counts

            counts = status_counts(comm, cp.status(xk))  # type: ignore[attr-defined]
            row.update(stick=counts["stick"], slip=counts["slip"])
            extra = f"  stick {counts['stick']:6d}  slip {counts['slip']:6d}"
        search = self.search
        if search is not None:
            search.fnorm = float(fnorm)  # ‖Φ(x_k)‖ for the next step's line search
        if its > 0 and search is not None and search.log and search.log[-1]["iteration"] == its - 1:
            extra += "  " + step_note(search.log[-1])
        if search is not None and search.stalled:  # no admissible step: stop here
            snes.setConvergedReason(PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH)  # type: ignore[arg-type]
        self.history.append(row)
        if stopping is not None:
            # an active-set step (min's, or polishing) that kept its active set: η_lin = 0
            same = (
                changed == 0 and (method == "min" or polished)
                if its > 0
                else polished and stopping.guess_kept(active)
            )
            if stopping.newton_done(its, comm.allreduce(bool(same), op=MPI.LAND), energy):
                snes.setConvergedReason(STOPPED_REASON)  # type: ignore[arg-type]
        if self.verbose and comm.rank == 0:
            st = "    -" if its == 0 else f"{step:5.2f}"
            print(
                f"  {method:>12s} it {its:3d}  |Phi| = {fnorm:10.3e}  step {st}  "
                f"active {n_active:7d}  changed "
                f"{changed:6d}{extra}{'  polished' if row['polished'] else ''}",
                flush=True,
            )
            progress.heard()
        else:
            progress.note(lambda: f"{method} Newton iteration {its}, |Phi| = {fnorm:.3e}")

    def close(self) -> None:
        """Destroy the solver's PETSc objects (SNES, Newton system, work vectors); the
        problem's stay (:meth:`~.problem.DiscreteProblem.destroy`).  Twice is harmless."""
        self._owner.close()

    def __enter__(self) -> SemismoothNewton:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def step_note(event: dict) -> str:
    """What the energy search did at one Newton step (:mod:`.energy_search`), one phrase:
    'K_T: 1 neg. eig., shift 1e-04, t 0.5 (energy), curvature step 0.02'."""
    parts = []
    if event["negative"]:
        parts.append(f"K_T: {event['negative']} neg. eig., shift {event['shift']:.0e}")
    parts.append(f"t {event['t']:.3g} ({event['merit']})")
    if event.get("along"):
        parts.append(f"curvature step {event['along']:.3g}")
    return ", ".join(parts)


def energy_line_search(
    problem: DiscreteProblem, options: SolverOptions, user: dict
) -> SolverOptions:
    """``options`` with ``line_search: auto`` resolved to ``energy`` where the energy search
    applies (:mod:`.energy_search`: a problem with an energy, fb / min / blend, a diagonal
    law — no friction, a constraint that is a bound: not contact on the current
    configuration, whose block law :mod:`.current` solves — and the direct solver its
    inertia needs); an explicit ``energy`` where it does not is a ConfigError naming the
    key."""
    applies = (
        problem.has_energy
        and options.method in ncp.METHODS
        and problem.friction is None
        and problem.current is None
    )
    linear = energy_linear(problem, options, user)
    if options.line_search == "energy" and not (applies and linear):
        why = (
            "a direct solver (its tangent's inertia) or CG + GAMG (its indefiniteness "
            "test): solver.linear direct or gamg"
            if applies
            else "a body with an energy (model.type hyperelastic) against a plane, without "
            "friction, and method fb, min or blend"
        )
        raise ConfigError(f"solver.line_search: energy needs {why}")
    if options.line_search == "auto" and applies and linear:
        return options.model_copy(update={"line_search": "energy"})
    return options


def cp_norm(cp: Complementarity, x: PETSc.Vec, method: str, mu: float) -> float:
    """‖Φ(x)‖."""
    f = x.duplicate()
    cp.phi(x, f, method, mu)
    out = norm2(f)
    f.destroy()
    return out


def force_scale(
    cp: Complementarity, problem: DiscreteProblem, method: str, mu: float
) -> tuple[float, float]:
    """(F, F₁).  F = ‖Φ(x_D)‖_∞, the largest entry of the residual at the start x_D that
    holds the Dirichlet values and zero elsewhere: the largest nodal force of the scene's
    loads, prescribed displacements and gaps (the units of Φ, :mod:`.newton`; the maximum
    does not overflow where the 2-norm of huge data would).  ``solver.atol`` is relative to
    it, a tolerance of atol · F on ‖Φ‖, so that a scene may be written in any units: with an
    absolute 1e-12, E = 1e-12 made ‖Φ_0‖ = 8e-14 "converged" before the first step.
    F₁ = ‖Φ(x_D)‖₁ is the total force, which does not shrink with h: it caps the round-off
    floor (:func:`roundoff_floor`)."""
    x, f = problem.b.duplicate(), problem.b.duplicate()
    x.set(0.0)
    set_dirichlet(x, problem.bcs)
    cp.phi(x, f, method, mu)
    peak = total = norm_inf(f)
    # a nonlinear residual undefined at x_D (cells a finite-strain body's prescribed
    # displacement inverts while the rest stays): no atol (F = 0, rtol decides), but the
    # round-off floor's cap F₁ is the total force at the largest fraction 2^-k x_D where Φ
    # is defined — with a cap of 0 a start near the solution (a repeated load step, a
    # re-coupled mortar problem) was asked for rtol ‖Φ_0‖, below round-off, and ran to
    # max_it (decided on every rank alike: a maximum over ranks with a NaN is not)
    comm = problem.V.mesh.comm
    undefined = comm.allreduce(bool(np.isnan(f.array_r).any()), op=MPI.LOR)
    for _ in range(FORCE_SCALE_HALVINGS if undefined else 0):
        x.scale(0.5)
        cp.phi(x, f, method, mu)
        if not comm.allreduce(bool(np.isnan(f.array_r).any()), op=MPI.LOR):
            peak = total = norm_inf(f)
            break
    else:
        if undefined:  # at every fraction tried: rtol alone
            peak = total = 0.0
    if 0.0 < peak < np.inf:  # ‖f‖₁ as ‖f‖_∞ ‖f / ‖f‖_∞‖₁: huge data do not overflow
        f.scale(1.0 / peak)
        total = peak * norm1(f)
    if undefined:
        peak = 0.0
    x.destroy()
    f.destroy()
    return peak, total


#: halvings of the prescribed displacement x_D tried for the force scale (force_scale)
FORCE_SCALE_HALVINGS = 20
#: a real initial guess (given: the nested iteration's prolonged solution, grid sequencing's,
#: a load step's) is made admissible on a bound constraint before the solve, u ← max(u, ψ)
#: (min(u, g) for an upper bound) node by node: prolonged onto refined cells, a solution
#: resting on a concave obstacle lies below it at the new nodes (the chord under the arc) and
#: there, with a gap < 0, even a node with a negative multiplier starts active, and the free
#: boundary recedes a ring of nodes per Newton step; from the projected guess the first
#: active-set step finds the contact set nearly at once.  False: the guess as given (old path)
ADMISSIBLE_GUESS = True
ROUNDOFF = 16.0  # the floor below: measured 0.7 ε ‖K‖_∞ ‖x‖ reached at 256² (Laplace, P1)


def roundoff_floor(k_norm: float, x: PETSc.Vec) -> float:
    """The round-off floor of ‖Φ(x)‖ = ‖K x − b‖ (and of the NCP rows, which are no larger):
    ROUNDOFF · ε · ‖K‖_∞ · ‖x‖₂.  Rows of K x sum terms of size K_ij x_j that cancel to a
    force h^d times smaller, so ‖Φ‖ cannot be computed below this, whatever the solver
    does.  The stopping test uses max(atol · F, rtol ‖Φ_0‖, this floor): on fine meshes,
    where atol · F (F the largest nodal force, shrinking like h^d) falls below the floor,
    every method used to run to max_it (256² cells, issue 26).  The caller caps it at
    atol · F₁ (the total force of the data, :func:`force_scale`): the floor grows with ‖x‖,
    and a body that nothing holds drifts to ‖x‖ ~ 1e13 (singular K), which must stay a
    failure, not a "converged" at ‖Φ‖ = 1e-2."""
    return ROUNDOFF * np.finfo(float).eps * k_norm * norm2(x)


def check_guess(u0: Any, problem: DiscreteProblem) -> None:
    """An initial guess must be a function in the problem's space (same mesh object,
    element and layout); else one ValueError line on every rank."""
    V = problem.V
    if not isinstance(u0, fem.Function):
        raise ValueError(
            f"u0: expected a dolfinx.fem.Function on the scene's mesh, got {type(u0).__name__}"
        )
    W = u0.function_space
    local = (
        W.mesh is not V.mesh
        or W.ufl_element() != V.ufl_element()
        or W.dofmap.index_map.size_local * W.dofmap.index_map_bs
        != V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    )
    if V.mesh.comm.allreduce(bool(local), op=MPI.LOR):
        where = "another mesh" if W.mesh is not V.mesh else "another function space"
        raise ValueError(
            f"u0: lives on {where} than the scene's problem; interpolate it first "
            "(contact.refine returns the guess on the refined mesh)"
        )


def set_dirichlet(x: PETSc.Vec, bcs: list) -> None:
    """Insert Dirichlet values into the owned entries of x."""
    for bc in bcs:
        bc.set(x.array_w)
