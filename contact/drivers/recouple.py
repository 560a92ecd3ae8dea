"""Mortar pairs of finite-strain bodies on the current configuration: the coupling's fixed point.

The dual-mortar coupling of a pair (:mod:`contact.models.mortar`) — the segment search, the
projection of the slave facets onto the master surface, D, M, c_ij, the nodal normals n_i
and the gap — depends on where the surfaces are.  At finite strain they are where the
displacement puts them, x = X + u.  One load step solves the sequence

    u^{k+1} = the solution with the coupling frozen at x^k = X + u^k,     u^0 = the start,

each a semismooth Newton solve of R̃(x) = Qᵀ F(Q x) on the unknowns x = Q_k⁻¹ u with the
bound n_i^k · (u_i − Σ_j c_ij^k u_j) ≤ n_i^k · (Σ_j c_ij^k x_j^k − x_i^k) + (Q_k⁻¹ u^k)_{i,n}
(:func:`contact.models.contacts.mortar_set`; exact non-penetration of the current surfaces at
u = u^k, transmitted by the current c_ij along the current normals: action = reaction).  A
fixed point u^{k+1} = u^k solves the contact problem of the deformed bodies: its coupling
is that of its own configuration.  The Newton solves are quadratic in their own problem;
the derivative of c_ij, n_i and D_ii with respect to u is not in the Jacobian, so the outer
sequence converges linearly, at a rate set by how much the coupling moves per unit of u
(uniform stretching of flat surfaces: the projections move, the normals do not).

Criterion.  The k-th solve starts from u^k with the coupling of u^k, so its first residual
‖Φ_0^{(k)}‖ is the residual of u^k in its own current configuration.  The step is done when

    ‖Φ_0^{(k)}‖ ≤ max(rtol ‖Φ_0^{(0)}‖, ROUNDOFF ‖Φ^{(0)}_final‖),

the relative tolerance one Newton solve of the step is held to, or (within the round-off
noise of a residual at its floor, :data:`ROUNDOFF`) the residual the first solve itself
reached — a load step identical to the previous one starts at that floor: u^k then solves
the current-configuration problem as well as a single solve solves its own; the k-th solve
(run to its tolerance anyway) is returned.  At most :data:`MAX_COUPLINGS` couplings per
solve (then not converged, reason ``diverged_couplings``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from ..models.discrete import Problem
from ..solvers.result import Result

#: the couplings of one load step at most (the outer fixed point's iterations)
MAX_COUPLINGS = 30
#: a residual at its round-off floor varies by this factor from one evaluation to the next
ROUNDOFF = 10.0


def solve_recoupled(
    build: Callable[[np.ndarray | None], Problem],
    solve: Callable[[Problem, fem.Function | None], Result],
    u0: fem.Function | None = None,
    max_couplings: int = MAX_COUPLINGS,
) -> Result:
    """Solve a problem of mortar pairs on the current configuration (module doc).

    Args:
        build: The problem with its pairs coupled on the current configuration of the
            given nodal displacements (V's function values, owned and ghost; None: the
            reference configuration).
        solve: One solve of a problem from a guess on its space (None: the cold start).
        u0: The start u^0 (the previous load step's solution), or None (a cold start; the
            first coupling is then that of the reference configuration).
        max_couplings: The couplings at most.

    Returns:
        The last solve's result, with ``couplings``: one row per coupling (its Newton
        iterations, ‖Φ_0‖, the final ‖Φ‖ and max |u^{k+1} − u^k| / max |u^{k+1}|).
        Superseded problems are destroyed.
    """
    at = None if u0 is None else u0.x.array.copy()
    log: list[dict] = []
    threshold = None
    result = None
    for k in range(max_couplings):
        problem = build(at)
        guess = None
        if at is not None:
            guess = fem.Function(problem.V)
            guess.x.array[:] = at
        if result is not None:
            result.problem.destroy()
        result = solve(problem, guess)
        first, final = result.history[0]["residual"], result.history[-1]["residual"]
        u = result.u_h.x.array
        comm = problem.V.mesh.comm
        size = comm.allreduce(float(np.max(np.abs(u), initial=0.0)), op=MPI.MAX)
        moved = 0.0 if at is None else float(np.max(np.abs(u - at), initial=0.0))
        change = comm.allreduce(moved, op=MPI.MAX) / size if size > 0 else 0.0
        log.append(
            {
                "coupling": k,
                "newton": result.iterations,
                "first": first,
                "final": final,
                "change": change,
            }
        )
        result.couplings = log
        if not result.converged:
            return result
        if threshold is None:
            threshold = max(result.options.get("rtol", 0.0) * first, ROUNDOFF * final)
        elif first <= threshold:
            return result
        at = u.copy()
    assert result is not None  # max_couplings ≥ 1
    result.converged, result.reason = False, "diverged_couplings"
    return result
