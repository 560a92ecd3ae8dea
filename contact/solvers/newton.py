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
:mod:`.globalize`), set up by :mod:`.strategies`.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..base.lifetime import matches, record
from . import ncp
from .problem import DiscreteProblem, NodeBlockMatrix


class Complementarity:
    """Vectorised nodal quantities a_i, b_i for an iterate (no loop over DoFs)."""

    def __init__(self, problem: DiscreteProblem):
        self.p = problem
        self.R = problem.b.duplicate()
        con = problem.constraint
        self.dofs, self.g, self.w, self.sign = con.dofs, con.g, con.w, con.sign
        self.s, self.d = problem.b.duplicate(), problem.b.duplicate()  # Jacobian scalings
        # (:meth:`remember`) the iterate whose (a, b) ``self.R`` and ``_pair`` hold
        # (a record, :func:`~contact.base.lifetime.record`: a digest, not a copy)
        self._memo: bytes | tuple | None = None
        self._pair: tuple[np.ndarray, np.ndarray] | None = None
        self.remembering = False
        self.residuals = 0  # evaluations of R (the products K x of a linear residual)

    @property
    def c(self) -> np.ndarray | float:
        """The NCP scaling c_i of the problem (set by each solve, from its options)."""
        assert self.p.c is not None, "the NCP scaling is set by the solve"
        return self.p.c

    def pair(self, x: PETSc.Vec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a, b, R) at x: gap a = σ(g − u), scaled multiplier b = −σ c R / w, residual R.

        While :meth:`remember` is on, an x equal (entry for entry, on every rank) to that of
        the last call returns that call's arrays: SNES evaluates Φ, the monitor the active
        set, the Jacobian its law and min's cycle guard the piece, all at the same iterate,
        and each needs R(x) = K x − b (collective)."""
        if self.remembering:
            local = matches(self._memo, x.array_r)
            if self.p.b.getComm().tompi4py().allreduce(local, op=MPI.LAND):
                assert self._pair is not None
                return (*self._pair, self.R.array_r)
        self.p.residual(x, self.R)
        self.residuals += 1
        r = self.R.array_r
        u = x.array_r[self.dofs]
        a = self.sign * (self.g - u)
        b = -self.sign * self.c * r[self.dofs] / self.w
        if self.remembering:
            self._memo, self._pair = record(x.array_r), (a, b)
        return a, b, r

    def remember(self, on: bool) -> None:
        """Reuse R(x), a and b while x does not change (:meth:`pair`), or stop (``on``
        False; the remembered iterate is forgotten either way).  For one SNES solve of a
        linear residual: K, b, g and c must not change while it is on."""
        self.remembering = on
        self._memo = self._pair = None

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
