"""Case (p) of the stability map: plain Newton-min cycles on a P-matrix LCP of order 3
(Ben Gharbia & Gilbert, Math. Program. 134, 2012), with the package's own φ and ∂φ
(contact.solvers.ncp) in the dense Newton loop of contact.solvers.lcp; Fischer–Burmeister,
the blend, min with backtracking and min with the default globalization (plain steps until
an active set repeats, then backtracking: contact.solvers.globalize) converge from the same
start.  The same globalization in the contact solver on two_body_stack_2d, whose plain
Newton-min cycled on one CPU and converged on another (issue 26)."""

from __future__ import annotations

from pathlib import Path

import contact
from contact.solvers import ncp
from contact.solvers.globalize import ARMIJO, MIN_STEP, WATCHDOG, CycleGuard, backtrack
from contact.solvers.lcp import cycling_lcp, is_p_matrix, lcp_residual, newton_lcp

import numpy as np
import pytest

STACK = Path(__file__).resolve().parents[1] / "configs" / "two_body_stack_2d.yaml"


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
    res = newton_lcp(M, q, x0, method="min", line_search="basic", max_it=30)
    # 30: the cap, reached because the iterates repeat exactly (steps off every kink, on
    # a 3×3 system whose solves are exact in binary: x has entries −1, 0, 1)
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


@pytest.mark.parametrize(
    "method, line_search",
    [("fb", "basic"), ("blend", "basic"), ("min", "bt"), ("fb", "bt"), ("min", "auto")],
)
def test_fb_blend_and_min_with_backtracking_converge(method: str, line_search: str) -> None:
    M, q, x0 = cycling_lcp()
    res = newton_lcp(M, q, x0, method=method, line_search=line_search, max_it=30)
    assert res.converged and res.iterations < 15
    assert np.allclose(res.x, _solution(M, q), atol=1e-10)
    assert np.linalg.norm(lcp_residual(M, q, res.x, method)) <= 1e-12


def test_min_auto_takes_plain_steps_until_the_active_set_repeats() -> None:
    """line search auto is plain Newton-min (the primal–dual active set method) up to the
    iterate whose active set was seen before — x3 = x0 here — and backtracks from there."""
    M, q, x0 = cycling_lcp()
    plain = newton_lcp(M, q, x0, method="min", line_search="basic", max_it=30)
    auto = newton_lcp(M, q, x0, method="min", line_search="auto", max_it=30)
    for k in range(4):
        assert np.array_equal(auto.iterates[k], plain.iterates[k])
    assert not np.array_equal(auto.iterates[4], plain.iterates[4])  # the first shortened step
    assert auto.converged and auto.period() == 0


def test_cycle_guard_and_backtracking() -> None:
    """CycleGuard answers True from the first active set seen before on, or from WATCHDOG
    iterates in a row without a new smallest ‖Φ‖ (counted from the first step: a cold
    start's ‖Φ_0‖ is no yardstick); backtrack takes the largest 2^−j with Armijo's
    decrease, else the trial with the smallest merit."""
    guard = CycleGuard()
    # twice in a row: no cycle
    sets = [[1, 0, 0], [0, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0], [1, 1, 1]]
    told = [guard.visit(np.array(a, bool), 1.0 / (k + 1)) for k, a in enumerate(sets)]
    assert told == [False] * 4 + [True] * 2
    assert (guard.engaged_at, guard.why) == (4, "repeat")
    stagnant = CycleGuard()
    norms = [1e-3, 1.0, 0.5] + [0.6] * WATCHDOG + [0.1]  # a new set every time
    told = [stagnant.visit(np.arange(8) < k, f) for k, f in enumerate(norms)]
    assert told == [False] * (2 + WATCHDOG) + [True] * 2
    assert (stagnant.engaged_at, stagnant.why) == (2 + WATCHDOG, "stagnation")
    assert backtrack(lambda t: (1 - t) ** 2 + 0.1, 1.0) == 1.0  # the full step decreases
    assert backtrack(lambda t: (4 * t - 1) ** 2, 1.0) == 0.25  # 9, 1, 0 at t = 1, ½, ¼
    # never a sufficient decrease: the trial with the smallest merit (the full step or the last)
    assert backtrack(lambda t: 2.0 - t, 1.0) == 1.0
    assert backtrack(lambda t: 2.0 + t, 1.0) == MIN_STEP
    # less than Armijo asks: best trial
    assert backtrack(lambda t: 1.0 - 1.5 * ARMIJO * t, 1.0) == 1.0


def test_stack_min_converges_by_default_and_plain_steps_come_first() -> None:
    """two_body_stack_2d with method min on the defaults converges to vinewtonrsls's answer;
    until its guard engages (an active set repeats) its iterates are plain Newton-min's, and
    plain Newton-min either converges to the same answer or cycles (an active set repeats:
    it is then the run the guard would have shortened)."""
    scene = contact.load_scene(STACK, ["output.verbose=false"])
    ref = contact.solve(scene, method="vinewtonrsls", verbose=False)
    auto = contact.solve(scene, method="min", verbose=False)
    plain = contact.solve(scene, method="min", line_search="basic", verbose=False)
    assert auto.converged and auto.options["line_search"] == "auto"
    scale = np.max(np.abs(ref.u_h.x.array))
    assert np.max(np.abs(auto.u_h.x.array - ref.u_h.x.array)) <= 1e-8 * scale
    shared = (
        len(auto.history)
        if auto.backtracked == 0
        else next(k for k, row in enumerate(auto.history) if k > 0 and row["step"] < 1.0)
    )
    residuals = [[r["residual"] for r in run.history[:shared]] for run in (auto, plain)]
    assert residuals[0] == residuals[1]
    if plain.converged:
        assert np.max(np.abs(plain.u_h.x.array - ref.u_h.x.array)) <= 1e-8 * scale
    else:
        assert plain.reason == "diverged_max_it" and auto.backtracked > 0


def test_newton_min_converges_on_an_m_matrix_from_the_same_start() -> None:
    """The same start on an M-matrix LCP (the 1D Laplacian, q = −1): plain Newton-min ends
    in at most n steps, as the theory for M-matrices says."""
    n = 3
    M = 2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    q = -np.ones(n)
    res = newton_lcp(M, q, cycling_lcp()[2], method="min", max_it=30)  # plain: line search basic
    assert res.converged and res.iterations <= n
    assert np.allclose(res.x, _solution(M, q), atol=1e-12)
