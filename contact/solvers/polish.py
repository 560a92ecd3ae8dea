"""Active-set polishing of fb / blend Newton steps (``solver.polish``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..base.norms import norm2
from ..base.timing import Timer

if TYPE_CHECKING:
    from .newton import Complementarity


#: the first look at a polishing step from a guess: the Krylov solve stops at this relative
#: residual, and goes on to the exact one only if the step keeps the guess's active set
STAGE_RTOL = 1e-3
#: a Newton step that changes the status of at most this fraction of the active nodes (and
#: of at least one) is polished on the active set it reaches (:meth:`Polisher.__call__`)
FEW_CHANGES = 1e-3
#: True: polish a step that changes a handful of statuses on the set it reaches; False: only
#: a step that keeps the active set (old path)
POLISH_FEW = True


class Polisher:
    """Active-set polishing, a line-search pre-check of the Newton step x → W = x − y.

    When the step leaves the active set A = {i : b_i > a_i} unchanged, the linear problem
    that A defines,  u_i = g_i on A,  R_i(u) = 0 on every other row,  is solved as well: it
    is one Newton step of φ_min from x (one primal–dual active-set step), landing on the
    point P.  If ‖Φ(P)‖ < ‖Φ(W)‖ the step is replaced by x → P.  Then once the Newton
    iterates of φ_FB have identified A, one extra linear solve finishes the job, instead of
    FB's slow approach to nodes with a small gap and a small multiplier (from (a, b) with
    |b| = a/2, a Newton step of φ_FB on one node only shrinks b to 0.15 b).  The idea is the
    active-set identification of Facchinei, Fischer and Kanzow (SIAM J. Optim. 9, 1998),
    and the solution polishing of QP solvers (OSQP).  Φ, and so the solution, are those of
    φ; each attempt costs one linear solve, counted in ``solves``.  A step that changes the
    status of a handful of nodes is polished on the set W reaches, from W (``_where``).  No
    attempt is made when W already meets SNES's stopping test (``done``).  The solve is the
    Newton system's (:mod:`.linear`) with the law of φ_min: the assembled path borrows
    SNES's KSP and gives it back its operators (one factorization alive at a time), the
    reduced path rebuilds its SPD operator.
    """

    def __init__(self, cp: Complementarity, method: str, mu: float, system, timers: dict):
        problem = cp.p
        self.cp, self.method, self.mu, self.system, self.timers = cp, method, mu, system, timers
        # the trial point, Φ there (then the step: only ‖Φ‖ is needed once it is solved
        # for, so the step takes its vector), Φ_min at x (then at the polished point)
        self.W, self.FW, self.FP = (problem.b.duplicate() for _ in range(3))
        self.solves, self.accepted = 0, False
        self.taken: float | None = None  # ‖step‖ of the last attempt, None if none was made
        self.initial_accepted = False
        self.done = 0.0  # ‖Φ‖ at which SNES stops: a Newton point below it needs no polishing

    def __call__(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        cp, W = self.cp, self.W
        self.accepted, self.taken = False, None
        x.copy(W)
        W.axpy(-1.0, y)
        assembly, solve = Timer(self.timers, "assembly"), Timer(self.timers, "solve")
        with assembly:
            a_w, b_w = cp.phi(W, self.FW, self.method, self.mu)  # one residual per point
            a, b = cp.phi(x, self.FP, "min", self.mu)
            f_w = norm2(self.FW)
            where = self._where(cp.active_set(a, b), cp.active_set(a_w, b_w), x)
            if where is None or f_w <= self.done:
                return
            if where == "reached":  # the set W reaches: the step solved from W
                del a, b
                a, b = cp.phi(W, self.FP, "min", self.mu)
            del a_w, b_w  # not held through the solve
            self.taken = norm2(y)
            s, d = cp.law(a, b, "min", self.mu)
        step = self.FW
        with solve:
            self.system.solve_law(s, d, self.FP, step)
        self.solves += 1
        with assembly:
            if where == "reached":  # x → P = W − step, a step y + step
                step.axpy(1.0, y)
            x.copy(W)
            W.axpy(-1.0, step)  # W = P
            cp.phi(W, self.FP, self.method, self.mu)
            if norm2(self.FP) < f_w:
                step.copy(y)
                self.accepted, self.taken = True, norm2(step)

    def _where(self, at_x: np.ndarray, at_w: np.ndarray, x: PETSc.Vec) -> str | None:
        """Which active set the step x → W is polished on (collective): ``"kept"`` — the
        step keeps x's; ``"reached"`` — it changes the status of a handful of nodes
        (at most :data:`FEW_CHANGES` of the active ones, :data:`POLISH_FEW`; a linear
        residual, whose K is W's tangent too), the set W reaches; None — no polishing (the
        active set still moves).

        A handful of changes is the end of a receding (or advancing) free boundary: a
        nested guess's polishing step leaves the last ring of nodes that the finer mesh
        releases, one Newton step releases them, and the set it reaches is the final one
        more often than not.  Polished on it at once, the solve ends there, where otherwise
        a further Newton step (with its own preconditioner set-up) would be spent to confirm
        the set; where the set still moves, the polished point is taken only if it lowers
        ‖Φ‖ below W's, and else its exact solve is lost."""
        comm = x.getComm().tompi4py()
        if comm.allreduce(bool(np.array_equal(at_x, at_w)), op=MPI.LAND):
            return "kept"
        if not POLISH_FEW or self.cp.p.nonlinear:  # (the tangent is x's, not W's)
            return None
        counts = np.array([np.count_nonzero(at_x != at_w), np.count_nonzero(at_x)])
        changed, total = comm.allreduce(counts, op=MPI.SUM)
        return "reached" if changed <= FEW_CHANGES * total else None

    def initial(self, x: PETSc.Vec, stop: float) -> float:
        """Polish the initial guess x itself (a nested or sequenced guess already has nearly
        the final active set): one primal–dual active-set step from x, taken if it lowers
        ‖Φ‖.  Then a guess whose active set is right ends in this one solve, where a Newton
        step of φ would first be spent just to confirm the active set.  Returns ‖Φ(x)‖ of
        the guess (SNES's relative tolerance refers to it); ``stop`` is SNES's stopping
        value of ‖Φ‖, below which nothing is done.

        With an iterative Newton system the solve is staged: it stops at the relative
        residual :data:`STAGE_RTOL` first and is resumed to the exact tolerance only if that
        step keeps the guess's active set; otherwise the active set still moves, the exact
        solve would be wasted, and the loose step goes to Newton (hertz_3d at 865k DoFs on
        2 ranks: 9 CG iterations instead of 77)."""
        cp = self.cp
        assembly, solve = Timer(self.timers, "assembly"), Timer(self.timers, "solve")
        with assembly:
            a, b = cp.phi(x, self.FW, self.method, self.mu)
            f0 = norm2(self.FW)
            self.initial_accepted = False
            if f0 <= stop:
                return f0
            cp.phi(x, self.FP, "min", self.mu)
            s, d = cp.law(a, b, "min", self.mu)
            self.system.stop = stop
        step = self.FW  # Φ(x) is needed no more: its norm is f0
        with solve:  # (the staged solve's look at the active set counts as solving)
            if self.system.resumable:  # a first look at the step, finished if it keeps the set
                self.system.solve_law(s, d, self.FP, step, rtol=STAGE_RTOL)
                x.copy(self.W)
                self.W.axpy(-1.0, step)
                a_w, b_w, _ = cp.pair(self.W)
                same = np.array_equal(cp.active_set(a, b), cp.active_set(a_w, b_w))
                del a_w, b_w  # not held through the solve
                if x.getComm().tompi4py().allreduce(bool(same), op=MPI.LAND):
                    self.system.solve_law(s, d, self.FP, step, resume=True)
            else:
                self.system.solve_law(s, d, self.FP, step)
        self.solves += 1
        with assembly:
            x.copy(self.W)
            self.W.axpy(-1.0, step)
            cp.phi(self.W, self.FP, self.method, self.mu)
            if norm2(self.FP) < f0:
                self.W.copy(x)
                self.initial_accepted = True
        return f0

    def destroy(self) -> None:
        for obj in (self.W, self.FW, self.FP):
            obj.destroy()
        self.system = self.cp = None  # type: ignore[assignment]  # released: unused after destroy
