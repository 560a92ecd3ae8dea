"""Semismooth Newton on a small dense linear complementarity problem (a test bed for φ, ∂φ).

The LCP   0 ≤ x ⟂ w = M x + q ≥ 0   is the nonsmooth equation Φ(x) = φ(x, M x + q) = 0
for each NCP function φ of :mod:`.ncp` (a = x, b = w), with the generalized Jacobian

    H = diag(∂_a φ) + diag(∂_b φ) M,

the same diagonal law (s, d) = (∂_b φ, ∂_a φ) as the contact solver's H = diag(s) K + diag(d)
with K = M.  :func:`newton_lcp` is that Newton iteration, dense (NumPy), with the contact
solver's line searches (:mod:`.globalize`): ``basic`` (plain Newton), ``bt`` (Armijo
backtracking on the merit ½‖Φ‖² from the first step) or ``auto`` (plain steps until an
active set repeats, then ``bt``).  For φ = min with ``basic`` it is the plain Newton-min
algorithm, i.e. the primal–dual active set method: each step solves w_i = 0 on the rows
where w_i < x_i and x_i = 0 on the others.

Plain Newton-min converges on every LCP whose M is an M-matrix (in at most n steps) — the
contact problems of this package have stiffness matrices close to that — but not on every
P-matrix (all principal minors positive, which still makes the LCP uniquely solvable for
every q).  Ben Gharbia & Gilbert (Math. Program. 134, 2012) show it may cycle for P-matrices
of order n ≥ 3 (never for n ≤ 2).  :func:`cycling_lcp` is such a problem of order 3, built
from that description (their published matrices were not at hand; the cycle is verified
numerically in tests/test_newton_min_cycle.py): a cyclic matrix with unit diagonal and one
off-diagonal 2 per row, q = −(1, 1, 1); from x = (−1, 1, 0) each step moves the one negative
entry one place along, and after three steps the iterate is back (a 3-cycle, no step at a
kink), while the solution is x* = (1, 1, 1)/3.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import ncp
from .globalize import CycleGuard, backtrack


@dataclass
class LCPResult:
    """The outcome of :func:`newton_lcp`: the last iterate, the iteration count, whether
    ‖Φ‖ ≤ tol was reached, and every iterate (x_0 first)."""

    x: np.ndarray
    iterations: int
    converged: bool
    iterates: list[np.ndarray] = field(repr=False)

    def period(self, tol: float = 1e-12) -> int:
        """The smallest p > 0 with x_k = x_{k−p} (to ``tol``) for the last iterate, 0 if the
        last iterate repeats none before it."""
        last = self.iterates[-1]
        for p in range(1, len(self.iterates)):
            if np.max(np.abs(self.iterates[-1 - p] - last)) <= tol:
                return p
        return 0


def is_p_matrix(M: np.ndarray) -> bool:
    """Whether every principal minor of M is positive (2^n determinants: small n only)."""
    n = len(M)
    for mask in range(1, 2**n):
        idx = [i for i in range(n) if mask >> i & 1]
        if np.linalg.det(M[np.ix_(idx, idx)]) <= 0:
            return False
    return True


def lcp_residual(
    M: np.ndarray, q: np.ndarray, x: np.ndarray, method: str, mu: float = 0.5
) -> np.ndarray:
    """Φ(x) = φ(x, M x + q) componentwise."""
    return ncp.phi(x, M @ x + q, method, mu)


def newton_lcp(
    M: np.ndarray,
    q: np.ndarray,
    x0: np.ndarray,
    method: str = "min",
    line_search: str = "basic",
    mu: float = 0.5,
    tol: float = 1e-12,
    max_it: int = 50,
) -> LCPResult:
    """Semismooth Newton on Φ(x) = φ(x, M x + q) = 0 from ``x0`` (module doc): each step
    solves H y = −Φ with H = diag(∂_a φ) + diag(∂_b φ) M and goes to x + t y, t = 1
    (``basic``), t of :func:`~contact.solvers.globalize.backtrack` (``bt``), or ``auto``:
    t = 1 until a cycle shows (:class:`~contact.solvers.globalize.CycleGuard`: the active
    set {w_i − x_i > 0} of an iterate repeats an earlier one, or ‖Φ‖ stagnates), then
    backtracking (min only; the other φ take plain steps).  Stops when ‖Φ‖ ≤ ``tol`` or
    after ``max_it`` steps."""
    if line_search not in ("basic", "bt", "auto"):
        raise ValueError(f"unknown line search {line_search!r}; expected basic, bt or auto")
    x = np.array(x0, dtype=float)
    iterates = [x.copy()]
    guard = CycleGuard() if line_search == "auto" and method == "min" else None
    for k in range(max_it + 1):
        F = lcp_residual(M, q, x, method, mu)
        merit = 0.5 * F @ F
        if np.sqrt(2.0 * merit) <= tol:
            return LCPResult(x, k, True, iterates)
        if k == max_it:
            break
        w = M @ x + q
        da, db = ncp.dphi(x, w, method, mu)
        y = np.linalg.solve(np.diag(da) + db[:, None] * M, -F)
        t = 1.0
        cycle = guard is not None and guard.visit(ncp.active_min(x, w), np.sqrt(2.0 * merit))
        if line_search == "bt" or cycle:

            def merit_at(t: float, x: np.ndarray = x, y: np.ndarray = y) -> float:
                return 0.5 * float(np.sum(lcp_residual(M, q, x + t * y, method, mu) ** 2))

            t = backtrack(merit_at, merit)
        x = x + t * y
        iterates.append(x.copy())
    return LCPResult(x, max_it, False, iterates)


def cycling_lcp() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, q, x0) of an order-3 P-matrix LCP on which plain Newton-min cycles from x0
    (module doc): M = I + 2 P with P the cyclic shift (M_01 = M_12 = M_20 = 2), q = −1,
    x0 = (−1, 1, 0)."""
    M = np.eye(3) + 2.0 * np.roll(np.eye(3), 1, axis=1)
    return M, -np.ones(3), np.array([-1.0, 1.0, 0.0])
