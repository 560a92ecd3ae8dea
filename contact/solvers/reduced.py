"""The Newton system of a diagonal law as a symmetric positive definite system (docs/theory.md §8).

For fb, min and blend the generalized Jacobian is  H = diag(s) K + diag(d)  with s, d ≥ 0
(:mod:`.newton`; never s_i = d_i = 0).  The step y of  H y = F  splits by rows:

* s_i = 0 ("fixed" rows: the law fixes the unknown):  d_i y_i = F_i,  so  y_i = F_i / d_i;
* s_i > 0 ("free" rows), divided by s_i:  (K y)_i + (d_i / s_i) y_i = F_i / s_i.

Moving the known fixed values to the right-hand side, as for Dirichlet rows, gives with
P = diag(free) and y_X the vector of the fixed values (zero on free rows)

    A y = r,   A = P K P + diag(d / s on free rows, 1 on fixed rows),
               r = P (F / s − K y_X) + y_X,

and A is K restricted to the free rows plus a non-negative diagonal: symmetric, and
positive definite wherever K is on the free rows.  A keeps K's sparsity pattern (the
eliminated couplings are stored zeros), so it is rebuilt each Newton step by one copy,
one ``MatDiagonalScale`` and one ``MatDiagonalSet``, and an algebraic multigrid
preconditioner can keep its hierarchy: CG + GAMG (with the rigid-body near-nullspace for
elasticity) and ``pc_gamg_reuse_interpolation``, so that later Newton steps only recompute
the Galerkin coarse operators.  A is stored in the matrix P that GAMG is built from: one copy
of K's pattern beside K, and a second only while a lagged hierarchy (below) needs P's values
and the new A at once (``reduced_share_matrix false``: A and P apart throughout).

A hierarchy may also be kept across Newton steps (lagged, ``reduced_lag_pc``): by the
rule ``active_set`` (``reduced_lag_rule``, the default) only while A has the fixed rows it
was built with, so that A and the preconditioning matrix differ in the diagonal d/s alone,
and while the rate test of :meth:`ReducedSystem._krylov` holds; by the rule ``rate`` the
rate test alone.  A set-up with the interpolation reused costs about 5–6 CG iterations of
the system (0.115 s against 0.021 s per iteration at 263k DoFs), and a solve on a hierarchy
lagged across a change of the active set about as many more than a fresh one (7.3 against
2.3 iterations on the cold step-41 path), so the rate rule alternated between fresh and
lagged set-ups at no gain; the rule ``active_set`` sets up once per change of the active
set and lags where only the values change (fb and blend near the solution).

Rows with s_i ≤ ``FIXED`` · d_i / K_ii are treated as fixed: there d_i / s_i ≥ K_ii / FIXED,
and dropping their couplings changes y_i by a relative O(FIXED), below round-off.

Inexact Newton: the Krylov solve of step k stops at the relative residual η_k of
Eisenstat and Walker (SIAM J. Sci. Comput. 17, 1996, choice 2), bounded by the Newton
residual itself,

    η_k = min(γ (‖Φ_k‖ / ‖Φ_{k−1}‖)^α, ETA_MAX, ‖Φ_k‖ / ‖Φ_0‖),   γ = 0.9, α = 2,
    η_0 = ETA_MAX (from a guess — nested or sequenced — that is not polished first, η_0 as
    for an exact solve: the guess usually has the final active set, so the first step ends
    the iteration; a polished guess has had that exact solve),
    safeguard η_k ≥ γ η_{k−1}^α when that exceeds 0.1,

and η_k ≤ η_{k−1} / 10 after a step that did not halve ‖Φ‖: a semismooth Newton method
whose loose steps do not pay (fb can wander on them) becomes the exact method step by step,

but for the rule ``active_set`` (``solver.forcing``, the default of the frictionless
Newton system): after a Newton step that changed the status (active or not) of any node
and lowered ‖Φ‖, η_k = min(max(η_k^EW, ETA_SET), ETA_MAX), without the ‖Φ_k‖ / ‖Φ_0‖
bound and the tightening after poor progress.  From a cold start the active set moves
across the contact zone a band of nodes per step while ‖Φ‖ falls slowly, and the
tightening would ask ever more accurate solutions of steps that the next change of the
active set discards, while the active sets the iteration visits hardly depend on it.
Once the statuses stay, the rule is Eisenstat–Walker's and the same-law rule below, so the
last steps are as tight as with it.  After ‖Φ‖ rose at two steps past the first
(``MAX_RISES``) the rule is Eisenstat–Walker's for the rest of the solve: the active set
cycles there (with a large NCP scaling κ, loose steps can keep fb between two active
sets).  The Krylov solve of a loose step starts from the fixed rows' known values and, on
the free rows, from the multiple α z of the last step's direction z closest to the
solution in A's norm, α = (r, z) / (z, A z), never farther from it than the zero start
(PETSc's option ``reduced_warm_start false`` starts from zero),

and never below what SNES's stopping test needs: the residual of the linear model is the
next ‖Φ‖ (when the law does not change), so the solve stops once ‖r‖ ≤ ``stop`` / 20
(``stop`` = max(atol, rtol ‖Φ_0‖), set by the solver).  When a Newton step has the law of
the step before (min's active set settled), Φ is linear on the piece the iterates are in,
and the step is solved to that stopping value at once: one more step ends the iteration.  With
``forcing=False`` every solve runs to ``rtol`` (:data:`EXACT_RTOL`, or the user's ``ksp_rtol``).

This applies to diagonal laws only; a block law (friction, H = B K + D) uses the
assembled system of :mod:`.linear`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..base.errors import ConfigError
from ..base.lifetime import matches, record
from ..base.norms import norm2
from ..base.timing import Stopwatch

if TYPE_CHECKING:
    from .stopping import AdaptiveStopping

# s_i ≤ FIXED d_i / K_ii: the row is eliminated (changes y_i by a relative ≤ ~1e-8)
FIXED = 1e-8
ETA_MAX = 0.1  # the loosest forcing term
ETA_SET = 1e-2  # the forcing term of a step after one that changed statuses
MAX_RISES = 1  # active_set: loose steps end after this many rises of ‖Φ‖ (a cycle)
POOR_PROGRESS = 0.5  # ‖Φ_k‖ > 0.5 ‖Φ_{k−1}‖: the next forcing term is at most a tenth of the last
GAMMA, ALPHA = 0.9, 2.0
EXACT_RTOL = 1e-10
LAG_MIN_ITS = 5  # a lagged preconditioner may always take this many iterations more
#: what one GAMG set-up costs, in CG iterations of the system it preconditions (measured:
#: 5.6-6.8 on the 512² square, 10 on hertz_3d, 12 on hertz_2d after the first set-up).  A
#: constant, not a clock reading: the lagging decisions, hence the Newton path, must be the
#: same in every run and on every rank
SETUP_ITERATIONS = 8

#: PETSc options of the inner solve (``solver.petsc_options`` override them)
#: (``pc_use_amat false``: GAMG's smoothers use P, not the operator A that changes under a
#: lagged preconditioner — with A their Chebyshev bounds would not fit and CG breaks down)
REDUCED_PETSC_OPTIONS = {
    "ksp_type": "cg",
    "ksp_norm_type": "unpreconditioned",
    "pc_type": "gamg",
    "pc_gamg_reuse_interpolation": True,
    "pc_use_amat": False,
    "ksp_rtol": EXACT_RTOL,
}


class ReducedSystem:
    """Solves H y = F, H = diag(s) K + diag(d), through the SPD system A y = r (module doc)
    with a Krylov solver of its own (options prefix ``prefix``, CG + GAMG by default).

    :meth:`set_law` builds A for a law (s, d); :meth:`solve` solves for one right-hand
    side.  ``J`` is a matrix-free H (y = s ⊙ K x + d ⊙ x) for SNES, whose own KSP is a
    single application of :meth:`solve` (:meth:`configure`)."""

    def __init__(
        self,
        K: PETSc.Mat,
        near_nullspace: PETSc.NullSpace | None,
        prefix: str,
        forcing: bool = True,
        pattern: PETSc.Mat | None = None,
        dirichlet: np.ndarray | None = None,
    ):
        self.K = K
        pattern = K if pattern is None else pattern  # the pattern of H (block laws: B K's)
        # the matrix GAMG was last built from: the same object for the KSP's life (GAMG's
        # reused interpolation keeps the finest level's matrix object)
        self.P = pattern.duplicate(copy=True)
        if near_nullspace is not None:
            self.P.setNearNullSpace(near_nullspace)
        # the reduced operator: P itself (one matrix) unless a lagged GAMG needs P's values
        # while A takes a new law (``reduced_share_matrix``, :meth:`_begin_law`)
        self.A = self.P
        self.share = self.SHARE
        self.Kdiag = K.getDiagonal()
        self.s, self.d = K.createVecLeft(), K.createVecLeft()
        self.y_fixed, self.r, self.work = (K.createVecLeft() for _ in range(3))
        self.ksp = PETSc.KSP().create(K.getComm())
        self.ksp.setOptionsPrefix(prefix)
        self.ksp.setOperators(self.A, self.P)
        self.forcing = forcing
        self.stop = 0.0  # SNES's stopping value of ‖Φ‖ (set by the solver)
        self.previous: tuple[float, float] | None = None  # ‖Φ‖ and η of the last Newton solve
        # the forcing rule (module doc): "eisenstat_walker", or "active_set" (the frictionless
        # Newton system's default, ``solver.forcing``)
        self.policy = "eisenstat_walker"
        self.warm = True  # active_set: warm-started Krylov solves (``reduced_warm_start``)
        self.changed: int | None = None  # statuses the last Newton step changed (the monitor's)
        self._rises = 0  # Newton steps after the first of this solve that raised ‖Φ‖
        self._forced = 0  # Newton steps of this solve that took a forcing term
        self._loose = False  # the current Newton step is a loose one of ``active_set``
        self._direction: PETSc.Vec | None = None  # the last Newton step's y (warm starts)
        self.guess = False  # the iteration starts from a guess: first step exact
        # adaptive stopping (.stopping): the Krylov tolerance
        self.stopping: AdaptiveStopping | None = None
        # the law A holds, the law of the last Newton solve: records of (s, d)
        # (:func:`~contact.base.lifetime.record`: digests, not copies)
        self._held: bytes | tuple | None = None
        self._newton: bytes | tuple | None = None
        self.krylov_iterations = 0
        self.log: list[dict] = []  # one entry per inner solve: rtol, iterations, seconds
        self.fixed_rows = 0
        self.fixed = np.zeros(K.getLocalSize()[0], dtype=bool)
        # Dirichlet rows: identity rows and columns of K, fixed rows of every law
        self.dirichlet = decoupled_rows(
            K, np.zeros(0, np.int32) if dirichlet is None else dirichlet
        )
        self._rtol, self._max_it = EXACT_RTOL, 10000
        self.last_reason: int = 0
        self.lag = True
        self.lag_rule = self.LAG_RULES[0]
        self.exact_law = False  # the next law is solved exactly (polishing): no lagging
        self.polishing = False  # the law being set is a polishing solve's, not J's
        self.newton_law = False  # J has applied a Newton step's law since :meth:`restart`
        self._built_fixed: np.ndarray | None = None  # the fixed rows GAMG's P was built with
        self._fresh_rate: float | None = None
        self._lag_ok, self._lagged = False, False
        self.setups = 0  # GAMG set-ups (fresh solves, rebuilds midway, restarts)
        self.rebuilds = 0  # lagged solves that had to rebuild GAMG midway
        self.restarts = 0  # solves started over with a new GAMG after a breakdown
        # sets the inner PC up in place of the options' (``solver.linear: hp_patch``), again
        # after each reset
        self.pc_setup: Callable[[PETSc.PC], None] | None = None
        self.J = self._jacobian()

    def _jacobian(self) -> PETSc.Mat:
        """SNES's Jacobian: H applied matrix-free (y = s ⊙ K x + d ⊙ x)."""
        K = self.K
        J = PETSc.Mat().createPython(K.getSizes(), context=_MatrixFreeH(self), comm=K.getComm())  # type: ignore[arg-type]
        J.setUp()
        return J

    #: lag GAMG across Newton steps unless ``reduced_lag_pc`` says otherwise
    LAG = True
    #: A is stored in P's matrix except while GAMG lags (``reduced_share_matrix false``: A
    #: and P are two copies of K's pattern throughout, the path before)
    SHARE = True
    #: when a lagged GAMG is kept (``reduced_lag_rule``): ``active_set`` — while the fixed
    #: rows are those it was built with and the rate test holds; ``rate`` — the rate test
    #: alone (:meth:`_krylov`)
    LAG_RULES = ("active_set", "rate")

    def set_options(self) -> None:
        """Take the inner KSP's tolerance after it has read the options database, and the
        lagging switch ``reduced_lag_pc`` (default :attr:`LAG`)."""
        self._rtol, _, _, self._max_it = self.ksp.getTolerances()
        prefix = self.ksp.getOptionsPrefix()
        self.lag = PETSc.Options(prefix).getBool("reduced_lag_pc", self.LAG)
        rule = PETSc.Options(prefix).getString("reduced_lag_rule", self.LAG_RULES[0])
        if rule not in self.LAG_RULES:
            raise ConfigError(
                f"solver.petsc_options.reduced_lag_rule: must be one of "
                f"{', '.join(self.LAG_RULES)}, got {rule!r}"
            )
        self.lag_rule = rule
        self.warm = PETSc.Options(prefix).getBool("reduced_warm_start", True)
        self.share = PETSc.Options(prefix).getBool("reduced_share_matrix", self.SHARE)
        if not self.share and self.A is self.P:  # the path before: A and P stored apart
            self.A = self.P.duplicate(copy=True)
        if self.pc_setup is not None:
            self.pc_setup(self.ksp.getPC())
        # adaptive stopping measures CG's natural norm, which the lagging's rates do not use
        self.lag = self.lag and self.stopping is None

    def configure(self, snes: PETSc.SNES, prefix: str) -> None:
        """Make SNES's KSP one application of :meth:`solve` (preonly + a Python PC); its
        options prefix becomes ``prefix`` so the user's ksp/pc options reach the inner KSP."""
        outer = snes.getKSP()
        outer.setOptionsPrefix(prefix)
        outer.setType("preonly")
        pc = outer.getPC()
        pc.setType(PETSc.PC.Type.PYTHON)
        pc.setPythonContext(_ApplyInverse(self))

    def set_law(self, s: PETSc.Vec, d: PETSc.Vec) -> None:
        """Build A for the law (s, d) (the Newton step's or a polishing step's).  A law
        equal to the one A holds leaves A, and so GAMG's setup, untouched."""
        self.newton_law = self.newton_law or not self.polishing
        s.copy(self.s)
        d.copy(self.d)
        sa, da = self.s.array_r, self.d.array_r
        if self._same(self._held, sa, da):
            return
        self._held = record(sa, da)
        fixed = sa <= FIXED * da / np.maximum(np.abs(self.Kdiag.array_r), np.finfo(float).tiny)
        fixed |= self.dirichlet
        self.fixed = fixed
        self.fixed_rows = int(fixed.sum())
        self._begin_law()
        self.K.copy(self.A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)  # type: ignore[arg-type]
        diag = self.work.array_w
        diag[:] = np.where(fixed, 0.0, 1.0)  # P = diag(free), in the work vector
        self.A.diagonalScale(L=self.work, R=self.work)
        with np.errstate(divide="ignore", invalid="ignore"):
            diag[:] = np.where(fixed, 1.0, da / np.where(fixed, 1.0, sa))
        self.A.setDiagonal(self.work, addv=PETSc.InsertMode.ADD_VALUES)  # type: ignore[arg-type]
        self._operator_changed()

    def _begin_law(self) -> None:
        """Before A takes a new law (``fixed`` set, collective): whether the preconditioner
        lags — GAMG of an earlier A, kept in P, while it converges well and, by the rule
        ``active_set``, while the fixed rows are those P was built with.  A lagged step needs
        P's values and the new A at once: A then gets storage of its own (P's pattern)."""
        self._lagged = (
            self.lag and not self.exact_law and self._fresh_rate is not None and self._lag_ok
        )
        if self._lagged and self.lag_rule == "active_set":
            same = self._built_fixed is not None and np.array_equal(self.fixed, self._built_fixed)
            self._lagged = bool(self.K.getComm().tompi4py().allreduce(same, op=MPI.LAND))
        if self._lagged and self.A is self.P:
            self.A = self.P.duplicate(copy=False)

    def _operator_changed(self) -> None:
        """After A changed (:meth:`_begin_law` first): lag the preconditioner or rebuild it."""
        if not self._lagged:
            self._rebuild()
        self.ksp.setOperators(self.A, self.P)

    def _take_operator(self) -> None:
        """P = A, and A stored in P again (shared): the matrix GAMG is built from next."""
        if self.A is self.P:
            return
        self.A.copy(self.P, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)  # type: ignore[arg-type]
        if self.share:
            self.A.destroy()
            self.A = self.P

    def _rebuild(self) -> None:
        """P = A: GAMG is set up again at the next solve (Galerkin products; the
        interpolation is reused with ``pc_gamg_reuse_interpolation``)."""
        self._take_operator()
        self._built_fixed = self.fixed.copy()
        self.ksp.setOperators(self.A, self.P)
        self.ksp.getPC().setReusePreconditioner(False)
        self._lagged = False

    def solve(
        self,
        F: PETSc.Vec,
        y: PETSc.Vec,
        newton: bool = False,
        rtol: float | None = None,
        resume: bool = False,
    ) -> None:
        """y = H⁻¹ F for the current law; ``newton`` marks a Newton step (forcing applies).
        ``rtol`` loosens a solve that is not a Newton step (a first look, :meth:`resume`
        may finish it); ``resume`` goes on from y, the last solve's result for this F and
        law, to the exact tolerance (the Krylov method restarts from y: no iteration is
        lost but the Krylov space)."""
        fixed = self.fixed
        yx = self._right_hand_side(F)
        rtol = self._rtol if rtol is None else max(rtol, self._rtol)
        self._loose = False
        if newton and self.forcing and self.stopping is None:
            # the law of the last Newton step again: the linear model is exact on this piece
            # of Φ, so solve to SNES's stopping value at once (atol below) instead of forcing
            law = self._law()
            same = self._same(self._newton, *law)
            rtol = self._rtol if same else self._forcing(norm2(F))
            self._newton = record(*law)
        atol = 0.05 * self.stop  # ‖Φ_new‖ ≤ 2 ‖r_A‖ (s ≤ 2)
        if self.stopping is not None:  # natural norm: η_alg ≤ γ_alg (η_disc + η_lin)
            atol = self.stopping.krylov_atol()
        watch = Stopwatch()
        r0 = norm2(self.r)
        setups = self.setups
        if not newton and not resume and self._lagged:
            # an exact solve (polishing) on a lagged preconditioner: its rate is only known
            # for loose Newton solves, which overrate it (hertz_3d's 865k-DoF level on 2 ranks:
            # the final polish took 115 iterations with a rebuild midway, 61 on a fresh set-up)
            self._rebuild()
        if resume:  # the exact solve's target, reached from y
            atol, rtol = max(atol, self._rtol * r0), 0.0
            self.ksp.setInitialGuessNonzero(True)
        elif newton and self._warm_start(y, yx):
            self.ksp.setInitialGuessNonzero(True)
        try:
            its = self._krylov(y, rtol, atol, r0)
        finally:
            self.ksp.setInitialGuessNonzero(False)
        if newton and self.policy == "active_set" and self.warm:
            if self._direction is None:
                self._direction = y.duplicate()
            y.copy(self._direction)
        # the fixed rows are identity rows of A: their values are known exactly, whatever the
        # Krylov solve did (it stops at once when ‖r‖ ≤ atol, leaving y = 0 there too, and a
        # large d makes r = F/d on those rows small while Φ = F is not)
        y.array_w[fixed] = yx[fixed]
        if self.stopping is not None:
            self.stopping.krylov_done(self.ksp.getResidualNorm())
        self.krylov_iterations += its
        self.log.append(
            {
                "rtol": rtol,
                "iterations": its,
                "seconds": watch.seconds,
                "reason": self.last_reason,
                "fixed_rows": self.fixed_rows,
                "resume": resume,
                "setups": self.setups - setups,
            }
        )

    def restart(self) -> None:
        """Forget the last solve's Newton steps (a new solve starts): its last ‖Φ‖ and η,
        on which the next forcing term would otherwise build (a new load step's first
        step would be compared with the last one's converged ‖Φ‖, and a guess would not
        get its exact first step), and the law of its last step."""
        self.changed = None
        self.previous = None
        self._newton = None
        self.newton_law = False
        self._rises = self._forced = 0
        self._loose = False
        if self._direction is not None:
            self._direction.destroy()
            self._direction = None

    def _warm_start(self, y: PETSc.Vec, yx: np.ndarray) -> bool:
        """Put the Krylov start of a Newton step into y: the fixed rows' known values and, on
        the free rows, the multiple α z of the last step's direction z (restricted to the
        free rows) that is closest to the solution in the A-norm,
        α = (r, z) / (z, A z) — never farther from it than the zero start.  Returns whether
        there is such a start (a loose step of ``active_set`` with ``warm``, after a first
        step)."""
        z = self._direction
        if not self._loose or not self.warm or z is None:
            return False
        free = ~self.fixed
        z.array_w[self.fixed] = 0.0
        self.A.mult(z, self.work)
        zaz, rz = float(z.dot(self.work).real), float(self.r.dot(z).real)
        alpha = rz / zaz if zaz > 0 else 0.0
        ya = y.array_w
        ya[:] = yx
        ya[free] = alpha * z.array_r[free]
        return True

    def _right_hand_side(self, F: PETSc.Vec) -> np.ndarray:
        """r of A y = r for the right-hand side F (module doc): y_X = F / d on the fixed rows
        (F / (s K_ii + d) on the Dirichlet rows, whose row of H is that diagonal entry alone),
        F / s − K y_X on the free ones; returns y_X (an array of ``y_fixed``)."""
        fixed = self.fixed
        sa, da, fa = self.s.array_r, self.d.array_r, F.array_r
        yx = self.y_fixed.array_w
        pivot = np.where(self.dirichlet, sa * self.Kdiag.array_r + da, da)
        yx[:] = np.where(fixed, fa / np.where(fixed, pivot, 1.0), 0.0)
        self.K.mult(self.y_fixed, self.work)  # K y_X
        r = self.r.array_w
        with np.errstate(divide="ignore", invalid="ignore"):
            r[:] = np.where(fixed, yx, fa / np.where(fixed, 1.0, sa) - self.work.array_r)
        return yx

    def _law(self) -> tuple[np.ndarray, np.ndarray]:
        """The law A was built from, as two arrays ((s, d) here)."""
        return self.s.array_r, self.d.array_r

    def _krylov(self, y: PETSc.Vec, rtol: float, atol: float, r0: float) -> int:
        """The Krylov solve A y = r; returns the iterations.

        A lagged preconditioner (GAMG of an earlier A) is worth its extra iterations while
        they cost less than rebuilding it: with S = :data:`SETUP_ITERATIONS` the cost of a
        set-up in iterations and ρ the convergence rate per iteration of the last fresh
        setup, a lagged solve may take the iterations a fresh one would
        (log(target/‖r‖)/log ρ) plus S.  Past that GAMG is rebuilt and the solve goes on from where
        it stopped; a lagged solve that used more than half of that margin ends the lagging."""
        ksp = self.ksp
        lagged = self._lagged
        ksp.getPC().setReusePreconditioner(lagged)
        max_it, expected = self._max_it, 0.0
        if lagged and r0 > 0:
            assert self._fresh_rate is not None  # a lagged solve follows a fresh one
            target = max(rtol * r0, atol, np.finfo(float).tiny)
            expected = np.log(min(target / r0, 1.0)) / np.log(self._fresh_rate)
            max_it = int(np.ceil(expected + SETUP_ITERATIONS)) + LAG_MIN_ITS
        ksp.setTolerances(rtol=rtol, atol=atol, max_it=max_it)
        if not lagged:
            ksp.setUp()
            self.setups += 1
        ksp.solve(self.r, y)
        its = ksp.getIterationNumber()
        self.last_reason = ksp.getConvergedReason()  # type: ignore[assignment]
        if not lagged:
            self._fresh(its, r0)
        elif self.last_reason == PETSc.KSP.ConvergedReason.DIVERGED_MAX_IT:
            start = ksp.getResidualNorm()
            self._rebuild()
            self.rebuilds += 1
            ksp.setInitialGuessNonzero(True)
            ksp.setTolerances(rtol=rtol, atol=atol, max_it=self._max_it)
            try:
                ksp.setUp()
                self.setups += 1
                ksp.solve(self.r, y)
            finally:
                ksp.setInitialGuessNonzero(False)
            n = ksp.getIterationNumber()
            self.last_reason = ksp.getConvergedReason()  # type: ignore[assignment]
            self._fresh(n, start)
            its += n
        elif its - expected > 0.5 * SETUP_ITERATIONS:
            self._lag_ok = False
        if self.last_reason < 0 and self.last_reason != PETSc.KSP.ConvergedReason.DIVERGED_MAX_IT:
            its += self._start_over(y, rtol, atol, r0)
        self._lagged = self.lag and self._lag_ok  # the next solve with this A may lag too
        return its

    def _start_over(self, y: PETSc.Vec, rtol: float, atol: float, r0: float) -> int:
        """After a breakdown (CG sees an indefinite preconditioner: a hierarchy whose reused
        interpolation and smoother bounds no longer fit A), set GAMG up from scratch — new
        aggregates, interpolation and Chebyshev bounds — and solve again from zero."""
        ksp = self.ksp
        self._take_operator()
        self._built_fixed = self.fixed.copy()
        ksp.getPC().reset()
        if self.pc_setup is not None:
            self.pc_setup(ksp.getPC())
        ksp.setOperators(self.A, self.P)
        ksp.getPC().setReusePreconditioner(False)
        ksp.setTolerances(rtol=rtol, atol=atol, max_it=self._max_it)
        ksp.setInitialGuessNonzero(False)
        ksp.solve(self.r, y)
        self.restarts += 1
        self.setups += 1
        n = ksp.getIterationNumber()
        self.last_reason = ksp.getConvergedReason()  # type: ignore[assignment]
        self._fresh(n, r0)
        return n

    def _fresh(self, its: int, r0: float) -> None:
        """Record the convergence rate per iteration of a freshly set up preconditioner."""
        if its > 0 and r0 > 0:
            rate = (self.ksp.getResidualNorm() / r0) ** (1.0 / its)
            self._fresh_rate = min(max(rate, 1e-6), 0.99)
        self._lag_ok = self._fresh_rate is not None

    def _same(self, law, sa: np.ndarray, da: np.ndarray) -> bool:
        """Whether (sa, da) equals the recorded ``law`` on every rank (collective)."""
        local = matches(law, sa, da)
        return bool(self.K.getComm().tompi4py().allreduce(local, op=MPI.LAND))

    def _forcing(self, fnorm: float) -> float:
        """η_k of this Newton step (module doc)."""
        if self.previous is None:  # a good guess (nested, sequenced) is on its final piece of Φ
            eta, self._f0 = (self._rtol if self.guess else ETA_MAX), fnorm
        else:
            f_old, eta_old = self.previous
            ratio = fnorm / f_old if f_old > 0 else 1.0
            eta = GAMMA * ratio**ALPHA
            safe = GAMMA * eta_old**ALPHA
            if safe > 0.1:
                eta = max(eta, safe)
            if ratio >= 1.0 and self._forced > 1:  # the first step from a cold start may
                self._rises += 1  # raise ‖Φ‖ by design; later ones count
            self._loose = bool(
                self.policy == "active_set"
                and self.changed
                and ratio < 1.0
                and self._rises <= MAX_RISES
            )
            if self._loose:
                eta = min(max(eta, ETA_SET), ETA_MAX)
            else:
                eta = min(eta, ETA_MAX, fnorm / self._f0 if self._f0 > 0 else ETA_MAX)
                if ratio > POOR_PROGRESS:  # inexact steps that do not pay: towards exact Newton
                    eta = min(eta, eta_old * 0.1)
        eta = max(eta, self._rtol)
        self.previous = (fnorm, eta)
        self._forced += 1
        return eta

    def destroy(self) -> None:
        if self.A is not self.P:
            self.A.destroy()
        for obj in (
            self.P,
            self.Kdiag,
            self.s,
            self.d,
            self.y_fixed,
            self.r,
            self.work,
            self.ksp,
            self.J,
        ):
            obj.destroy()
        self.restart()


class _MatrixFreeH:
    """H x = s ⊙ (K x) + d ⊙ x for the current law (SNES's Jacobian; line searches use it)."""

    def __init__(self, system: ReducedSystem):
        self.system = system

    def mult(self, mat, x, y):
        sy = self.system
        sy.K.mult(x, y)
        y.pointwiseMult(y, sy.s)
        _add_product(y, sy.d, x)


def _add_product(y: PETSc.Vec, d: PETSc.Vec, x: PETSc.Vec) -> None:
    """y += d ⊙ x."""
    y.array_w[:] += d.array_r * x.array_r  # type: ignore[arg-type]


class _ApplyInverse:
    """Python PC of SNES's preonly KSP: one solve of the reduced system per Newton step."""

    def __init__(self, system: ReducedSystem):
        self.system = system

    def apply(self, pc, x, y):
        self.system.solve(x, y, newton=True)
        if self.system.last_reason < 0:  # SNES then stops: diverged_linear_solve
            pc.setFailedReason(PETSc.PC.FailedReason.SUBPC_ERROR)


def decoupled_rows(K: PETSc.Mat, rows: np.ndarray) -> np.ndarray:
    """The mask (owned rows of K) of ``rows`` (local indices, e.g. the Dirichlet DoFs) if
    each is an identity row and column of K — then y_i = F_i / H_ii exactly, whatever a
    Krylov solve left there (a loose solve of adaptive stopping moved u_D by 2e-5 relative
    on hertz_2d) — else no rows (one product K e; collective)."""
    e = K.createVecRight()
    mask = np.zeros(e.getLocalSize(), dtype=bool)
    mask[rows] = True
    e.array_w[:] = mask
    Ke = K.createVecLeft()
    K.mult(e, Ke)
    ok = bool(np.all(np.abs(Ke.array_r - e.array_r) <= 1e-12))
    e.destroy()
    Ke.destroy()
    if not K.getComm().tompi4py().allreduce(ok, op=MPI.LAND):
        return np.zeros_like(mask)
    return mask
