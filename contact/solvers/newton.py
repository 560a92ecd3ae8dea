"""Semismooth Newton for the nodal complementarity problem (docs/theory.md §3–4).

With R(x) = K x − b and the constraint set of :class:`contact.solvers.problem.Constraint`, the
multiplier is eliminated (docs/theory.md §4, implementation note): on a constrained node i

    a_i = σ (g_i − x_i)  [gap],     b_i = −σ c_i R_i / w_i  [c × multiplier density],

and the nonsmooth equation is Φ(x) = 0 with

    Φ_i = −σ (w_i / c_i) φ(a_i, b_i)   on constrained rows,    Φ_i = R_i   elsewhere.

The factor −σ w_i / c_i is a constant row scaling of Φ_i = φ(a_i, b_i): it does
not change the zeros or the Newton steps, but it gives every row the units of R (a force),
so that ‖Φ‖ and the merit ½‖Φ‖² mix no units, and an inactive row is exactly R_i.  An
element of the generalized Jacobian is then

    H = diag(s) K + diag(d),   s_i = ∂_b φ,  d_i = (w_i / c_i) ∂_a φ  (constrained rows),
                               s_i = 1,      d_i = 0                  (other rows),

a diagonal law (s, d): :mod:`.linear` either assembles H from K (one ``MatDiagonalScale``
and one ``MatDiagonalSet`` per iteration; the sparsity pattern never changes, so a direct
solver reuses its symbolic factorization) or solves the equivalent symmetric positive
definite system of :mod:`.reduced`.  The Newton iteration itself is PETSc's SNES
``newtonls`` with these two callbacks (line search ``basic`` = plain Newton, or ``bt``;
``auto``, the default: plain Newton, and for min backtracking once a cycle shows,
:mod:`.globalize`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..base.timing import Timer
from . import ncp
from .globalize import GuardedMin
from .linear import attach_near_nullspace
from .options import SolverOptions
from .polish import Polisher
from .problem import DiscreteProblem, NodeBlockMatrix

if TYPE_CHECKING:
    from .block_system import BlockReducedSystem
    from .energy_search import EnergySearch


class Complementarity:
    """Vectorised nodal quantities a_i, b_i for an iterate (no loop over DoFs)."""

    def __init__(self, problem: DiscreteProblem):
        self.p = problem
        self.R = problem.b.duplicate()
        con = problem.constraint
        self.dofs, self.g, self.w, self.sign = con.dofs, con.g, con.w, con.sign
        self.s, self.d = problem.b.duplicate(), problem.b.duplicate()  # Jacobian scalings

    @property
    def c(self) -> np.ndarray | float:
        """The NCP scaling c_i of the problem (set by each solve, from its options)."""
        assert self.p.c is not None, "the NCP scaling is set by the solve"
        return self.p.c

    def pair(self, x: PETSc.Vec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a, b, R) at x: gap a = σ(g − u), scaled multiplier b = −σ c R / w, residual R."""
        self.p.residual(x, self.R)
        r = self.R.array_r
        u = x.array_r[self.dofs]
        a = self.sign * (self.g - u)
        b = -self.sign * self.c * r[self.dofs] / self.w
        return a, b, r

    def tie_tolerance(self, a: np.ndarray, b: np.ndarray) -> float:
        """τ = TIE_RTOL × max(max_i |a_i|, max_i |b_i|, s) over every rank (collective), s the
        constraint's :attr:`~contact.solvers.problem.Constraint.scale` (the coordinates' size for
        geometric gaps): kinks closer than τ take the documented element (:mod:`.ncp`), the
        same on any partition — also at a cold start where every a_i, b_i is round-off."""
        local = float(max(np.max(np.abs(a), initial=0.0), np.max(np.abs(b), initial=0.0)))
        scale = self.p.b.getComm().tompi4py().allreduce(local, op=MPI.MAX)
        return ncp.TIE_RTOL * max(scale, self.p.constraint.scale)

    def gap_roundoff(self, x: PETSc.Vec) -> float:
        """The round-off floor of the gap rows of ‖Φ(x)‖ beyond that of K x − b
        (:func:`contact.solvers.snes.roundoff_floor`): none for a gap given as a bound;
        :class:`contact.solvers.current.CurrentComplementarity` computes its gaps from
        coordinates (collective)."""
        return 0.0

    def active_set(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Active nodes: the scaled multiplier exceeds the gap, b_i − a_i > τ, or the node
        touches with zero pressure, |a_i|, |b_i| ≤ τ (other ties inactive; collective)."""
        return ncp.active_min(a, b, self.tie_tolerance(a, b))

    def active(self, x: PETSc.Vec) -> np.ndarray:
        """:meth:`active_set` at x (collective)."""
        a, b, _ = self.pair(x)
        return self.active_set(a, b)

    def phi(
        self, x: PETSc.Vec, f: PETSc.Vec, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """f = Φ(x): R on free rows, −σ (w/c) φ(a, b) on constrained rows; returns (a, b)."""
        a, b, _ = self.pair(x)
        self.R.copy(f)
        f.array_w[self.dofs] = -self.sign * (self.w / self.c) * ncp.phi(a, b, method, mu)
        return a, b

    def law(
        self, a: np.ndarray, b: np.ndarray, method: str, mu: float
    ) -> tuple[PETSc.Vec, PETSc.Vec]:
        """The diagonal law of the generalized-Jacobian element at the pair (a, b):
        H = diag(s) K + diag(d), s_i = ∂_b φ, d_i = (w_i / c_i) ∂_a φ on constrained rows,
        s_i = 1, d_i = 0 elsewhere (kinks within :meth:`tie_tolerance`: the documented
        element; collective).  Returns (s, d) (owned by this object)."""
        da, db = ncp.dphi(a, b, method, mu, self.tie_tolerance(a, b))
        self.s.set(1.0)
        self.d.set(0.0)
        self.s.array_w[self.dofs] = db
        self.d.array_w[self.dofs] = (self.w / self.c) * da
        return self.s, self.d

    def destroy(self) -> None:
        for obj in (self.R, self.s, self.d):
            obj.destroy()


#: a node's state under a friction law (:meth:`BlockComplementarity.status`)
SEPARATED, STICK, SLIP = 0, 1, 2


class BlockComplementarity(Complementarity):
    """A :class:`Complementarity` whose generalized-Jacobian element is a block law
    H = B K + D, B and D node-block matrices (one bs × bs block per node, identity / zero off
    the contact nodes) that ``block_jacobian(x, H, method, mu)`` fills at each iterate:
    friction (:mod:`.friction`), contact on the current configuration (:mod:`.current`).
    ``evaluate(x)`` returns the nodal quantities (a, b and, with friction, the law)."""

    def __init__(self, problem: DiscreteProblem):
        super().__init__(problem)
        self.bs = bs = problem.V.dofmap.index_map_bs
        self.B, self.D = NodeBlockMatrix(problem.K, bs), NodeBlockMatrix(problem.K, bs)

    def evaluate(self, x: PETSc.Vec) -> dict:
        raise NotImplementedError

    def phi_of(
        self, st: dict, f: PETSc.Vec, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """f = Φ at the iterate of ``st``, the :meth:`evaluate` just done; returns (a, b)."""
        raise NotImplementedError

    def block_jacobian(
        self, x: PETSc.Vec, H: PETSc.Mat, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """H = B K + D, the generalized-Jacobian element at x; returns the blocks of B and D,
        (local nodes, bs, bs) each."""
        raise NotImplementedError

    def status(self, x: PETSc.Vec, st: dict | None = None) -> np.ndarray:
        """Per node of a friction law: SEPARATED (normal inactive, :meth:`active_set`), STICK
        or SLIP (a node touching with zero pressure slips: ρ = 0; collective); ``st`` the
        :meth:`evaluate` of x if at hand."""
        st = self.evaluate(x) if st is None else st
        touching = self.active_set(st["a"], st["b"])
        return np.where(touching, np.where(st["law"].stick, STICK, SLIP), SEPARATED)

    def matrix(self) -> PETSc.Mat:
        """A Jacobian matrix with the pattern of B K (created by the product, for reuse)."""
        B = self.B.set(self.B.identity())
        return B.matMult(self.p.K)

    def destroy(self) -> None:
        super().destroy()
        for obj in (self.B.mat, self.D.mat):
            obj.destroy()


def setup_newton(
    snes: PETSc.SNES,
    cp: Complementarity,
    system,
    opts: SolverOptions,
    timers: dict,
    state: dict,
    petsc_opts: dict,
    verbose: bool = False,
) -> Polisher | GuardedMin | EnergySearch | None:
    """Make ``snes`` semismooth Newton on Φ of ``opts.method`` ∈ {fb, min, blend}:
    residual Φ and Jacobian callbacks (the Jacobian callback hands the law (s, d) to the
    Newton ``system`` of :mod:`.linear`, which builds its operator), the line search, and
    as the line-search pre-check either active-set polishing (fb / blend with
    ``opts.polish``) or, for min with line search ``auto``, the cycle guard of
    :mod:`.globalize`.  Time spent in the callbacks is added to ``timers['assembly']``;
    ``state['t_jac']`` is the linear solve's Timer, started at the end of the Jacobian.
    With ``opts.line_search`` energy the pre-check is :mod:`.energy_search`'s (``system`` a
    :class:`.curvature.CurvatureSystem`; polishing, if any, inside it).  Returns the
    pre-check object (Polisher, GuardedMin, EnergySearch) or None."""
    method, mu = opts.method, opts.mu

    def jacobian(x: PETSc.Vec, P: PETSc.Mat) -> None:
        cp.p.linearize(x)
        a, b, _ = cp.pair(x)
        system.set_law(*cp.law(a, b, method, mu))

    set_newton(
        snes,
        cp.p,
        system.J,
        lambda x, f: cp.phi(x, f, method, mu),
        jacobian,
        opts,
        timers,
        state,
        petsc_opts,
    )
    precheck: Polisher | GuardedMin | EnergySearch | None = None
    polisher = Polisher(cp, method, mu, system, timers) if opts.polish and method != "min" else None
    if opts.line_search == "energy":  # polishing first, then the energy's line search
        from .energy_search import EnergySearch

        precheck = EnergySearch(cp, method, mu, system, timers, body_size(cp.p), polisher)
    elif polisher is not None:
        precheck = polisher
    elif method == "min" and opts.line_search == "auto":
        precheck = GuardedMin(cp, mu, timers, verbose)
    if precheck is not None:
        snes.setLineSearchPreCheck(precheck)
    return precheck


def body_size(problem: DiscreteProblem) -> float:
    """The diagonal of the mesh's bounding box (collective): the length scale of the energy
    search's curvature steps."""
    X = problem.V.mesh.geometry.x
    comm = problem.V.mesh.comm
    lo = np.min(X, axis=0, initial=np.inf)
    hi = np.max(X, axis=0, initial=-np.inf)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    return float(np.linalg.norm(hi - lo))


def setup_block_newton(
    snes: PETSc.SNES,
    problem: DiscreteProblem,
    cp: BlockComplementarity,
    opts: SolverOptions,
    timers: dict,
    state: dict,
    petsc_opts: dict,
    system: BlockReducedSystem | None = None,
) -> PETSc.Mat:
    """Make ``snes`` semismooth Newton on the Φ of ``cp`` with a block law H = B K + D:
    ``cp.matrix()`` gives a matrix of the pattern of B K, ``cp.block_jacobian(x, H, method,
    mu)`` writes the element at x (friction, :mod:`.friction`; contact on the current
    configuration, :mod:`.current`) and returns the blocks of B and D.  Plain Newton or
    ``bt``, no polishing; returns the Jacobian matrix: a new one (the caller destroys it),
    or the ``system``'s H, which then builds its reduced operator from each Jacobian's
    blocks (:mod:`.block_system`, ``solver.linear: gmres``)."""
    method, mu = opts.method, opts.mu
    if system is None:
        J = cp.matrix()
        attach_near_nullspace(problem, J)

        def jacobian(x: PETSc.Vec, P: PETSc.Mat) -> None:
            cp.block_jacobian(x, P, method, mu)

    else:
        J, reduced = system.J, system

        def jacobian(x: PETSc.Vec, P: PETSc.Mat) -> None:
            reduced.set_block(*cp.block_jacobian(x, P, method, mu))

    set_newton(
        snes,
        problem,
        J,
        lambda x, f: cp.phi(x, f, method, mu),
        jacobian,
        opts,
        timers,
        state,
        petsc_opts,
    )
    return J


def set_newton(
    snes: PETSc.SNES,
    problem: DiscreteProblem,
    J: PETSc.Mat,
    phi,
    jacobian,
    opts: SolverOptions,
    timers: dict,
    state: dict,
    petsc_opts: dict,
) -> None:
    """Make ``snes`` PETSc's ``newtonls`` on Φ: ``phi(x, f)`` writes Φ(x) into f and
    ``jacobian(x, P)`` an element of its generalized Jacobian into P (the matrix J).  Time in
    both is added to ``timers['assembly']``; ``state['t_jac']`` is the linear solve's Timer
    (``timers['solve']``), started at the end of the Jacobian.  PETSc's line search
    ``opts.line_search`` (``auto``: ``basic``, the cycle guard being a pre-check) unless the
    PETSc options say otherwise."""

    def residual(snes, x, f):
        with Timer(timers, "assembly"):
            phi(x, f)

    def jac(snes, x, J_, P):
        with Timer(timers, "assembly"):
            jacobian(x, P)
        state["t_jac"] = Timer(timers, "solve").start()  # stopped after the linear solve

    snes.setType("newtonls")
    snes.setFunction(residual, problem.b.duplicate())
    snes.setJacobian(jac, J)
    # auto's cycle guard and the energy search are pre-checks of PETSc's basic line search
    line_search = "basic" if opts.line_search in ("auto", "energy") else opts.line_search
    petsc_opts.setdefault("snes_linesearch_type", line_search)
