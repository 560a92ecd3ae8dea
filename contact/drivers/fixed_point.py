"""The Coulomb fixed point (``friction.coulomb: fixed_point``): Coulomb friction solved as a
sequence of Tresca problems, each an ordinary solve (:func:`contact.drivers.solve.solve`);
the full Coulomb law in one semismooth Newton solve is :mod:`contact.solvers.friction`'s."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from ..solvers.problem import DiscreteProblem, FrictionSet
from ..solvers.result import Result


def with_threshold(fs: FrictionSet, rho: np.ndarray) -> FrictionSet:
    """The Tresca problem with threshold ρ (one step of the Coulomb fixed point)."""
    return dataclasses.replace(fs, law="tresca", threshold=np.asarray(rho, dtype=float))


def coulomb_fixed_point(
    problem: DiscreteProblem,
    u0: fem.Function | None,
    verbose: bool,
    assembly: float,
    solve: Callable[[fem.Function | None], Result],
) -> Result:
    """Coulomb friction as a sequence of Tresca problems (``friction.coulomb: fixed_point``):

        ρ^0 = F·max(0, μ_n(u_0)),   u^k = the Tresca solution with threshold ρ^{k−1},
        ρ^k = F·max(0, μ_n(u^k)),    until  max_i |ρ^k_i − ρ^{k−1}_i| ≤ rtol · max_i ρ^k_i,

    each Tresca problem solved by semismooth Newton from the previous u^k (``solve(u0)``,
    the problem's friction set to the Tresca one meanwhile).  A contraction for small F; an
    independent check of the full Newton method (same solution).  The returned
    :class:`~contact.solvers.result.Result` is the last Tresca solve's, with ``iterations``
    the Newton steps of all of them and ``friction['fixed_point_iterations']``;
    ``assembly``: the seconds spent building the problem for this solve."""
    fs = problem.friction
    assert fs is not None and fs.coefficient is not None  # a Coulomb problem
    comm = problem.V.mesh.comm
    x = problem.b.duplicate()
    if u0 is not None:
        problem.to_unknowns(u0.x.petsc_vec, x)
    r = x.duplicate()
    problem.residual(x, r)
    rho = fs.coefficient * np.maximum(
        -problem.constraint.sign * r.array_r[problem.constraint.dofs] / problem.constraint.w, 0.0
    )
    for obj in (x, r):
        obj.destroy()
    total, result, t0, converged = 0, None, time.perf_counter(), False
    timers = {"assembly": 0.0, "solve": 0.0}
    try:
        for k in range(1, fs.options.fixed_point_max_it + 1):
            problem.friction = with_threshold(fs, rho)
            result = solve(u0)
            total += result.iterations
            for key in timers:
                timers[key] += result.timings[key]
            if not result.converged:
                break
            assert result.friction is not None  # a frictional solve's
            rho_new = fs.coefficient * np.maximum(-result.friction["lambda_n"], 0.0)
            change = comm.allreduce(float(np.max(np.abs(rho_new - rho), initial=0.0)), op=MPI.MAX)
            scale = comm.allreduce(float(np.max(rho_new, initial=0.0)), op=MPI.MAX)
            rho, u0 = rho_new, result.u_h
            if verbose and comm.rank == 0:
                print(
                    f"  fixed point it {k:3d}  max|rho - rho_prev| = {change:10.3e}  "
                    f"({result.iterations} Newton its)",
                    flush=True,
                )
            if change <= fs.options.fixed_point_rtol * scale:
                converged = True
                break
    finally:
        problem.friction = fs
    timers["assembly"] += assembly
    timers["total"] = time.perf_counter() - t0 + assembly
    timers["other"] = max(timers["total"] - timers["assembly"] - timers["solve"], 0.0)
    assert result is not None  # the loop solved at least once
    result.timings = timers
    result.iterations = total
    assert result.friction is not None  # a frictional solve's
    result.friction["fixed_point_iterations"] = k
    if result.converged and not converged:
        result.converged, result.reason = False, "fixed_point_max_it"
    return result
