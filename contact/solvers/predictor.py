"""The tangent predictor of a nonlinear solve's start (``solver.predictor``, issue 31).

A load step k starts from the previous step's solution x (an equilibrium at t_{k−1}). Putting
the step's new Dirichlet values into x moves the Dirichlet nodes alone: the first layer of
cells takes the whole increment, and for a finite-strain body a large step inverts them
(ln J undefined — the step fails at iteration 0 and must be cut).  The predictor lifts the
increment into the body with the tangent at x instead, one linear solve:

    K_T(x) δ = −R_k(x)              on the free rows,
    δ_i = g_i(t_k) − x_i            on the Dirichlet rows (the new values) and on the
                                    constrained rows of the active set at x,

R_k the residual with the step's loads, the active set that of the NCP pair at x with the
step's bounds (nodes in contact stay on the obstacle, which moved; nodes it now penetrates
join them).  K_T keeps its Dirichlet columns here
(:meth:`contact.models.forms.ResidualProblem.full_tangent`): their couplings carry the
increment into the free rows.  For a linear problem whose active
set does not change δ is the whole step; for a nonlinear one it is the first Newton step of
the active-set method from the linearization at a valid state.  The start x + δ is taken if
it is admissible (no inverted matter, a finite residual), else the plain start.  MUMPS LU,
one factorization per solve.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .linear import mumps_ksp

if TYPE_CHECKING:
    from .newton import Complementarity


def tangent_predictor(cp: Complementarity, x: PETSc.Vec) -> bool:
    """x += δ of the module doc when x + δ is admissible (True), else x unchanged (False).
    The problem's Dirichlet conditions carry the step's values; the NCP scaling ``cp.c``
    must be set (collective)."""
    p = cp.p
    a, b, r = cp.pair(x)  # r = R_k(x); Dirichlet rows x_i − g_i
    active = cp.active_set(a, b)
    fixed = np.zeros(x.getLocalSize(), dtype=bool)
    fixed[p.dirichlet_rows()] = True
    delta = x.duplicate()
    delta.array_w[:] = np.where(fixed, -r, 0.0)
    rows = cp.dofs[active]
    delta.array_w[rows] = cp.g[active] - x.array_r[rows]
    fixed[rows] = True
    rhs = x.duplicate()
    rhs.array_w[:] = -r
    A = p.full_tangent(x)
    lo = A.getOwnershipRange()[0]
    rows_global = (np.flatnonzero(fixed) + lo).astype(PETSc.IntType)
    A.zeroRowsColumns(rows_global, 1.0, delta, rhs)  # type: ignore[arg-type]
    ksp = mumps_ksp(A)
    trial = x.duplicate()
    try:
        ksp.solve(rhs, delta)
        x.copy(trial)
        trial.axpy(1.0, delta)
        finite = bool(np.all(np.isfinite(trial.array_r)))
        ok = x.getComm().tompi4py().allreduce(finite, op=MPI.LAND) and p.admissible(trial)
        if ok:
            f = x.duplicate()
            p.residual(trial, f)
            ok = bool(np.isfinite(f.norm()))
            f.destroy()
        if ok:
            trial.copy(x)
        return ok
    finally:
        for obj in (ksp, A, delta, rhs, trial):
            obj.destroy()
