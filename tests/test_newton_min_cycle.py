"""Case (p) of the stability map: plain Newton-min cycles on a P-matrix LCP of order 3
(Ben Gharbia & Gilbert, Math. Program. 134, 2012), with the package's own φ and ∂φ
(contact.solvers.ncp) in the dense Newton loop of contact.solvers.lcp; Fischer–Burmeister,
the blend, and min with backtracking converge from the same start."""
from __future__ import annotations

import numpy as np
import pytest

from contact.solvers import ncp
from contact.solvers.lcp import cycling_lcp, is_p_matrix, lcp_residual, newton_lcp


def _solution(M: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The LCP's solution by enumeration of the 2^n complementary index sets (independent
    of any Newton method): x_J = −M_JJ⁻¹ q_J, x = 0 elsewhere, with x ≥ 0 and Mx + q ≥ 0."""
    n = len(q)
    found = []
    for mask in range(2**n):
        J = [i for i in range(n) if mask >> i & 1]
        x = np.zeros(n)
        if J:
            x[J] = np.linalg.solve(M[np.ix_(J, J)], -q[J])
        if np.all(x >= -1e-14) and np.all(M @ x + q >= -1e-14):
            found.append(x)
    assert len(found) == 1  # a P-matrix: exactly one solution
    return found[0]


def test_the_matrix_is_a_p_matrix_but_not_an_m_matrix() -> None:
    M, q, _ = cycling_lcp()
    assert is_p_matrix(M)
    assert np.any(M - np.diag(np.diag(M)) > 0)  # positive off-diagonals: not an M-matrix (nor Z)
    assert not is_p_matrix(M - np.diag([0.0, 0.0, 1.0]))  # the property is not vacuous


def test_plain_newton_min_cycles() -> None:
    """From x0 the iterates return to x0 after three steps and repeat forever; no step sits
    at a kink of min (the cycle does not depend on the tie rule)."""
    M, q, x0 = cycling_lcp()
    res = newton_lcp(M, q, x0, method="min", line_search=False, max_it=30)
    assert not res.converged and res.iterations == 30
    assert res.period() == 3
    first = res.iterates[:4]
    assert np.allclose(first[3], first[0], atol=1e-14) and not np.allclose(first[1], first[0])
    norms = [np.linalg.norm(lcp_residual(M, q, x, "min")) for x in res.iterates]
    assert min(norms) > 0.5  # never near the solution
    for x in first[:3]:
        a, b = x, M @ x + q
        assert np.min(np.abs(a - b)) > 0.5  # strictly on one branch of min at every node
        da, db = ncp.dphi(a, b, "min")
        assert np.array_equal(da, (b - a > 0).astype(float)) and np.array_equal(db, 1.0 - da)


@pytest.mark.parametrize("method, line_search", [("fb", False), ("blend", False), ("min", True), ("fb", True)])
def test_fb_blend_and_min_with_backtracking_converge(method: str, line_search: bool) -> None:
    M, q, x0 = cycling_lcp()
    res = newton_lcp(M, q, x0, method=method, line_search=line_search, max_it=30)
    assert res.converged and res.iterations < 15
    assert np.allclose(res.x, _solution(M, q), atol=1e-10)
    assert np.linalg.norm(lcp_residual(M, q, res.x, method)) <= 1e-12


def test_newton_min_converges_on_an_m_matrix_from_the_same_start() -> None:
    """The same start on an M-matrix LCP (the 1D Laplacian, q = −1): plain Newton-min ends
    in at most n steps, as the theory for M-matrices says."""
    n = 3
    M = 2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    q = -np.ones(n)
    res = newton_lcp(M, q, cycling_lcp()[2], method="min", max_it=30)
    assert res.converged and res.iterations <= n
    assert np.allclose(res.x, _solution(M, q), atol=1e-12)
