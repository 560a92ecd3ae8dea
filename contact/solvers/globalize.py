"""Globalization of Newton-min and of frictional Newton: plain steps until a cycle shows,
then backtracking.

Plain Newton on Φ = φ_min is the primal–dual active set method (PDAS, :mod:`.ncp`): with
an exact linear solve the point x_{k+1} solves the linear problem of the active set A_k
(:func:`.ncp.active_min`) at x_k alone (u_i = g_i on A_k, R_i = 0 elsewhere).  On an
M-matrix it ends in finitely many steps; on P-matrices of order ≥ 3 (Ben Gharbia & Gilbert, Math.
Program. 134, 2012), in elasticity and mortar couplings it may cycle — an active set seen
before, after which PDAS repeats its steps — and with inexact (Krylov) steps it may
near-cycle without ever repeating a set exactly.  Whether that happens can hinge on the
last bits of a residual: two_body_stack_2d converged on one CPU and 2-cycled (38 nodes
flipping) on another, when its touching cold start was decided by round-off signs
(:mod:`.ncp` now decides it as documented).

``solver.line_search: auto``, the default, for min is therefore

1. plain Newton steps (PDAS at full speed: one extra residual per step, to watch) until a
   cycle shows: the active set A_k equals an earlier one other than A_{k−1} (the same
   set twice in a row is PDAS's last step, with an inexact solve), or :data:`WATCHDOG`
   iterates in a row fail to lower the smallest ‖Φ‖ since the first step (the cold
   start's ‖Φ_0‖ is left out: a first PDAS step often raises ‖Φ‖ a hundredfold and is
   right);
2. from then on every step backtracks on the merit ½‖Φ‖²: x_{k+1} = x_k + t y_k with the
   largest t = 2^−j, j = 0, 1, …, such that

       ½‖Φ(x_k + t y_k)‖² ≤ (1 − 2 ARMIJO t) ½‖Φ(x_k)‖²

   (Armijo; t = 1 is tried first, so near the solution the steps are Newton's again), and
   if no t ≥ MIN_STEP decreases enough, the t with the smallest ‖Φ‖ of those tried.

Whether a cycle arises may depend on rounding; what is done about it depends on ‖Φ‖ only.
Measured on the stress cases of the stability map with min (30 cases, cold starts;
``contact study`` of configs/studies/stability.yaml's frictionless cases × line search):
plain steps (``basic``) converge in 28, ``auto`` in 29 with the same iteration counts
wherever plain steps converge (except k, f = 1 : 1e6 at 128²: 26 → 14), ``bt`` from the
first step in 25, with 514 Newton steps against 207 (level 7: 85 against 11; it fails on
c = 1e-6 and on κ = 1e4 with exact steps, where plain min takes 4): a full PDAS step that
raises ‖Φ‖ is usually the right one, and backtracking shortens exactly those.  ``auto``
rescues κ = 1e4 on inexact CG steps (plain: 100 steps, no convergence; ``auto`` 26) and the
P-matrix LCP (plain: a 3-cycle; ``auto`` 5 steps).  The one case it leaves failing is the
semi-coercive scene on CG + GAMG, whose first system has no solution.  ``basic`` keeps
plain Newton-min (PDAS, cycles included); ``bt`` is PETSc's backtracking from the first
step.  :func:`contact.solvers.lcp.newton_lcp` runs the same rules on a dense LCP.

Friction (:class:`contact.solvers.friction.GuardedFriction`; either tangential form, any
normal φ) gets the same rules with two changes.  The piece watched is every contact node's
state (separated, stick, slip).  A friction iterate is not fixed by its states (the slip
directions, and with Coulomb the bounds ρ, move within them), and Newton may pass a set
twice on its way to the solution, so a set seen before tells a cycle only if ‖Φ‖ has not
fallen below :data:`FRICTION_STALL` times its value at that visit.  The projection form's
2-cycle — every node sliding one way, then the other, its states unchanged — shows to the
watchdog.  Measured on the tangential forms × fb / min / blend, one step from a cold start
and from the frictionless solution (48 runs: the block stick- and slip-dominated, the
cylinder, the 3D box; demos/bench/bench_friction.py's forms): plain steps converge in 36
(the projection form's other 12 2-cycle for 100 steps), ``auto`` in 48 with the plain
iteration counts in all 36 (11–18 steps in the other 12), ``bt`` in 45 (changing 13 of the
36 counts; it stops on hsw's cylinder from the frictionless start), a fixed damping t = ½
from the cycle on in 44 (up to 54 steps).  Without the ‖Φ‖ condition a revisited set on
friction_cylinder_2d (hsw, MUMPS, step 9: 43 stick nodes at iterations 1 and 3, ‖Φ‖
4.9e-5 then 7.1e-6) shortened a right step of a converging run (8 → 9 steps).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..base.norms import norm2
from ..base.timing import Timer

if TYPE_CHECKING:
    from .newton import Complementarity

ARMIJO = 1e-4  # sufficient decrease of ½‖Φ‖² per unit step
MIN_STEP = 2.0**-30  # the backtracking stops below this step length
WATCHDOG = 5  # iterates in a row without a new smallest ‖Φ‖ that count as a cycle
#: friction: a state set seen before is a cycle unless ‖Φ‖ fell below this times its value then
FRICTION_STALL = 0.5


def backtrack(merit: Callable[[float], float], merit0: float) -> float:
    """The step length t of the Armijo rule above: ``merit(t)`` = ½‖Φ(x + t y)‖²,
    ``merit0`` = ½‖Φ(x)‖²; the largest t = 2^−j ≥ MIN_STEP with
    merit(t) ≤ (1 − 2 ARMIJO t) merit0, else the t tried with the smallest merit."""
    t, best, best_t = 1.0, np.inf, 1.0
    while t >= MIN_STEP:
        m = merit(t)
        if m <= (1.0 - 2.0 * ARMIJO * t) * merit0:
            return t
        if m < best:
            best, best_t = m, t
        t *= 0.5
    return best_t


class CycleGuard:
    """The active sets and residual norms of one solve, to tell a cycle of PDAS: an active
    set seen before (other than the previous iterate's), or :data:`WATCHDOG` iterates in a
    row that do not lower the smallest ‖Φ‖ since the first step (a near-cycle of inexact
    steps, which never repeats a set).  With ``stall`` > 0 a set seen before tells a cycle
    only if ‖Φ‖ is at least ``stall`` times its value at the set's last visit (friction's
    rule, module doc)."""

    def __init__(self, comm: MPI.Comm | None = None, stall: float = 0.0):
        self.comm, self.stall = comm, stall
        self.seen: dict[tuple, float] = {}  # piece → ‖Φ‖ at its last visit
        self.engaged_at: int | None = None  # the iteration at which a cycle was told
        self.why = ""  # "repeat" or "stagnation"
        self.iteration = 0
        self.best, self.since_best = np.inf, 0
        self.last: tuple | None = None

    def visit(self, active: np.ndarray, fnorm: float) -> bool:
        """Record the active set (a boolean mask; this rank's part under MPI, collective)
        and ‖Φ‖ of the next iterate; True from the first sign of a cycle on (backtrack)."""
        digest = hashlib.blake2b(
            np.packbits(np.asarray(active, dtype=bool)).tobytes(),
            digest_size=16,
            person=len(active).to_bytes(8, "little"),
        ).digest()
        key = tuple(self.comm.allgather(digest)) if self.comm is not None else (digest,)
        if self.iteration > 0:  # not the cold start's ‖Φ‖: a first PDAS step often raises it
            self.since_best = 0 if fnorm < self.best else self.since_best + 1
            self.best = min(self.best, fnorm)
        # the previous iterate's set again is PDAS's last step (its linear problem solved
        # once more), not a cycle: a cycle returns to a set left behind
        repeat = key != self.last and key in self.seen and fnorm >= self.stall * self.seen[key]
        if self.engaged_at is None and (repeat or self.since_best >= WATCHDOG):
            self.engaged_at = self.iteration
            self.why = "repeat" if repeat else "stagnation"
        self.seen[key] = fnorm
        self.last = key
        self.iteration += 1
        return self.engaged_at is not None


class Guarded:
    """``line_search: auto`` in SNES: a line-search pre-check of the Newton step x → x − y
    (PETSc's sign) that shows the piece of Φ at x (:meth:`piece`) and ‖Φ(x)‖ to a
    :class:`CycleGuard` and, from the first sign of a cycle on, shortens y to t y with t of
    :func:`backtrack` on ½‖Φ‖² of ``method`` (the line search proper stays ``basic``).
    ``backtracked`` counts the steps it shortened; residual evaluations are added to
    ``timers['assembly']``.  Subclasses say what the piece is: :class:`GuardedMin`,
    :class:`GuardedFriction`."""

    #: the verbose line's names: the solve, and what a repeated piece is
    label, seen = "", "its piece was seen before"
    #: a piece seen before is a cycle unless ‖Φ‖ fell below this times its value then
    stall = 0.0

    def __init__(
        self, cp: Complementarity, method: str, mu: float, timers: dict, verbose: bool = False
    ):
        self.cp, self.method, self.mu, self.timers = cp, method, mu, timers
        self.verbose = verbose
        self.W, self.F = cp.p.b.duplicate(), cp.p.b.duplicate()
        self.backtracked = 0
        self.restart()

    def restart(self) -> None:
        """Forget the pieces seen: a new solve begins."""
        self.guard = CycleGuard(self.cp.p.b.getComm().tompi4py(), self.stall)

    def piece(self, x: PETSc.Vec) -> np.ndarray:
        """A boolean mask naming the smooth piece of Φ at x (collective); ``self.F`` holds
        Φ(x) on return."""
        raise NotImplementedError

    def __call__(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        with Timer(self.timers, "assembly"):
            self._guard(x, y)

    def _guard(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """The pre-check: record the piece; once a cycle shows, backtrack the step y."""
        piece = self.piece(x)
        fnorm = norm2(self.F)
        first = self.guard.engaged_at is None
        if self.guard.visit(piece, fnorm):
            if first and self.verbose and x.getComm().getRank() == 0:
                what = (
                    self.seen
                    if self.guard.why == "repeat"
                    else f"{WATCHDOG} iterates without a new smallest |Phi|"
                )
                print(
                    f"  {self.label}: a cycle at iteration {self.guard.engaged_at} ({what}): "
                    "backtracking on |Phi|^2 from here",
                    flush=True,
                )
            t = backtrack(self._merit(x, y), 0.5 * fnorm**2)
            if t != 1.0:
                y.scale(t)
                self.backtracked += 1

    def _merit(self, x: PETSc.Vec, y: PETSc.Vec) -> Callable[[float], float]:
        def merit(t: float) -> float:
            x.copy(self.W)
            self.W.axpy(-t, y)
            self.cp.phi(self.W, self.F, self.method, self.mu)
            return 0.5 * norm2(self.F) ** 2

        return merit

    def destroy(self) -> None:
        for obj in (self.W, self.F):
            obj.destroy()
        self.cp = None  # type: ignore[assignment]  # released: unused after destroy


class GuardedMin(Guarded):
    """The guard of Newton-min: the piece is the active set (PDAS's linear problem)."""

    label, seen = "min", "its active set was seen before"

    def __init__(self, cp: Complementarity, mu: float, timers: dict, verbose: bool = False):
        super().__init__(cp, "min", mu, timers, verbose)

    def piece(self, x: PETSc.Vec) -> np.ndarray:
        a, b = self.cp.phi(x, self.F, "min", self.mu)
        return self.cp.active_set(a, b)
