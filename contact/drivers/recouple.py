"""Mortar pairs of finite-strain bodies on the current configuration: the coupling's fixed point.

The dual-mortar coupling of a pair (:mod:`contact.models.mortar`) — the segment search, the
projection of the slave facets onto the master surface, D, M, c_ij, the nodal normals n_i
and the gap — depends on where the surfaces are.  At finite strain they are where the
displacement puts them, x = X + u.  One load step solves the sequence

    u^{k+1} = the solution with the coupling frozen at x^k = X + ũ^k,     ũ^0 = u^0 the start,

each a semismooth Newton solve of R̃(x) = Qᵀ F(Q x) on the unknowns x = Q_k⁻¹ u with the
bound n_i^k · (u_i − Σ_j c_ij^k u_j) ≤ n_i^k · (Σ_j c_ij^k x_j^k − x_i^k) + (Q_k⁻¹ ũ^k)_{i,n}
(:func:`contact.models.contacts.mortar_set`; exact non-penetration of the current surfaces at
u = ũ^k, transmitted by the current c_ij along the current normals: action = reaction).  A
fixed point u^{k+1} = u^k solves the contact problem of the deformed bodies: its coupling
is that of its own configuration.  The Newton solves are quadratic in their own problem;
the derivative of c_ij, n_i and D_ii with respect to u is not in the Jacobian, so the outer
sequence converges linearly, at a rate set by how much the coupling moves per unit of u
(uniform stretching of flat surfaces: the projections move, the normals do not); ũ^k is
u^k, or a relaxation of it (below).

Relaxation.  The next coupling point is ũ^{k+1} = ũ^k + ω_k (u^{k+1} − ũ^k) (ũ^0 = u^0)
with Aitken's factor (as in partitioned fluid–structure coupling, Küttler & Wall 2008): with
the residuals r_k = u^{k+1} − ũ^k of the fixed-point equation,

    ω_k = −ω_{k−1} ⟨r_{k−1}, r_k − r_{k−1}⟩ / |r_k − r_{k−1}|²,    ω_0 = 1,

kept in :data:`OMEGA_RANGE` — a secant estimate of the multiplier of the slowest mode.  It
over-relaxes a slow monotone sequence (two cylinders pressed far) and under-relaxes an
oscillating one: where the contact zone of a body pressed against itself may shear, the
plain sequence can flip between two mirror-image states (a multiplier ≤ −1) and never
converge.  A fixed point of the relaxed sequence is one of the plain sequence.
``relaxation="none"`` keeps the plain sequence (ω = 1).

Criterion.  The outer sequence is stopped on the displacement it moves, relative to max|u|:
d_k = max|u^{k+1} − ũ^k| / max|u^{k+1}|.  Relaxed, the step is done when d_k ≤
:data:`COUPLING_RTOL`: the returned u^{k+1} is the solution of the coupling of a
configuration that close to its own.  Plain, with the observed contraction ρ_k =
d_k / d_{k−1}, the distance to the fixed point is about d_k ρ_k / (1 − ρ_k) (d_k itself
before a rate is known, or where ρ_k ≥ 1), and the step is done when that is ≤
:data:`COUPLING_RTOL`.  (A residual test is blind here: every solve starts by polishing its
guess on the guess's active set, so its first ‖Φ‖ is already that of the new coupling's
solution.)  Every solve is run to its own tolerance, from the previous solve's solution,
and the last one's result is returned.  At most :data:`MAX_COUPLINGS` couplings per solve
(then not converged, reason ``diverged_couplings``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from ..models.discrete import Problem
from ..solvers.result import Result

#: the couplings of one load step at most (the outer fixed point's iterations)
MAX_COUPLINGS = 60
#: the fixed point's relative displacement error at which a solve's coupling is final
COUPLING_RTOL = 1e-9
#: how the next coupling point follows a solve (:func:`solve_recoupled`)
RELAXATIONS = ("aitken", "none")
RELAXATION = "aitken"
#: the range Aitken's relaxation factor is kept in (over-relaxation accelerates a slow
#: monotone fixed point, under-relaxation damps an oscillating one)
OMEGA_RANGE = (0.05, 4.0)


def solve_recoupled(
    build: Callable[[np.ndarray | None], Problem],
    solve: Callable[[Problem, fem.Function | None], Result],
    u0: fem.Function | None = None,
    max_couplings: int = MAX_COUPLINGS,
    relaxation: str = RELAXATION,
    rtol: float = COUPLING_RTOL,
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
        relaxation: ``aitken``: the next coupling at ũ^{k+1} = ũ^k + ω_k (u^{k+1} − ũ^k)
            with Aitken's ω_k (module doc); ``none``: at u^{k+1} (the plain fixed point).
        rtol: the fixed point's relative displacement error at which the coupling is final
            (module doc; a looser one for a guess, e.g. a coarse level of grid sequencing).

    Returns:
        The last solve's result, with ``couplings``: one row per coupling (its Newton
        iterations, its first (polished) and final ‖Φ‖, d_k, the error estimate and the
        relaxation ω_k); its ``history`` every solve's Newton iterates (a ``coupling``
        column), ``iterations`` their sum.  Superseded problems are destroyed.
    """
    if relaxation not in RELAXATIONS:
        choices = ", ".join(RELAXATIONS)
        raise ValueError(f"relaxation: expected one of {choices}, got {relaxation!r}")
    at = None if u0 is None else u0.x.array.copy()
    log: list[dict] = []
    histories: list[list[dict]] = []
    result = None
    residual = None  # r_{k-1} = u^k − ũ^{k−1} (owned entries)
    omega = 1.0
    for k in range(max_couplings):
        problem = build(at)
        guess = None
        if at is not None:  # from the last solution (the coupling point when not relaxed)
            guess = fem.Function(problem.V)
            guess.x.array[:] = at if result is None else result.u_h.x.array
        if result is not None:
            result.problem.destroy()
        result = solve(problem, guess)
        histories.append(result.history)
        u = result.u_h.x.array
        comm = problem.V.mesh.comm
        size = comm.allreduce(float(np.max(np.abs(u), initial=0.0)), op=MPI.MAX)
        moved = np.inf if at is None else float(np.max(np.abs(u - at), initial=0.0))
        change = comm.allreduce(moved, op=MPI.MAX) / size if size > 0 else 0.0
        if relaxation == "none":
            rate = change / log[-1]["change"] if k > 1 and log[-1]["change"] > 0 else np.nan
            error = change * rate / (1.0 - rate) if 0.0 <= rate < 1.0 else change
        else:  # the returned u was solved with the coupling of a configuration this close
            error = change
        log.append(
            {
                "coupling": k,
                "newton": result.iterations,
                "first": result.history[0]["residual"],
                "final": result.history[-1]["residual"],
                "change": change,
                "error": error,
                "omega": 1.0,  # the relaxation of the next coupling point (below)
            }
        )
        if not result.converged or (k > 0 and error <= rtol):
            return _whole(result, log, histories)
        if relaxation == "none" or at is None:
            at = u.copy()
            continue
        n_owned = problem.V.dofmap.index_map.size_local * problem.V.dofmap.index_map_bs
        r = (u - at)[:n_owned]
        if residual is not None:
            dr = r - residual
            num, den = (comm.allreduce(float(x), op=MPI.SUM) for x in (residual @ dr, dr @ dr))
            omega = float(np.clip(-omega * num / den, *OMEGA_RANGE)) if den > 0 else 1.0
        residual = r
        log[-1]["omega"] = omega
        at = at + omega * (u - at)  # ghosts too: the same combination on every rank
    assert result is not None  # max_couplings ≥ 1
    result.converged, result.reason = False, "diverged_couplings"
    return _whole(result, log, histories)


def _whole(result: Result, log: list[dict], histories: list[list[dict]]) -> Result:
    """The last solve's result as the whole fixed point's: its couplings, every solve's
    Newton history (rows with their ``coupling``) and their iterations summed."""
    result.couplings = log
    result.history = [{"coupling": k, **row} for k, rows in enumerate(histories) for row in rows]
    result.iterations = sum(row["newton"] for row in log)
    return result
