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
increment into the free rows.

The held set is then corrected on the linearized problem itself, up to
:data:`ACTIVE_SET_ROUNDS` times: at x + δ the linearized gap σ(g_i − x_i − δ_i) and the
linearized force R_k(x) + K_T δ give the NCP pair of each constrained node, and the active
set of φ_min there (penetrating nodes join, nodes pulled off the obstacle leave) is held for
the next solve — primal–dual active-set steps on the tangent at x, one linear solve each and
no assembly, until the set stops changing.  δ then solves the contact problem linearized at
x: the small-strain contact of the step's increment, which a load step from a point contact
(a sphere touching a plane) needs — held at its single node, the first step's linear δ
would flatten the cells around it.  For a linear problem δ is the whole step; for a nonlinear
one it is the start of the active-set method from the linearization at a valid state.  The
start x + δ is taken if it is admissible (no inverted matter, a finite residual), else the
plain start.  MUMPS LU, one factorization per solve (a small system on several ranks
factorized whole on every rank, :func:`.linear.mumps_ksp`) — or, where the Newton steps are
iterative, CG + GAMG.

With friction the held nodes stick in the predictor: their tangential unknowns keep their
values (δ_t = 0, the slip increment of the trial state is zero, as the elastic trial of a
return mapping).  The linearized problem knows no friction law: left free, those rows would
solve R_t + K_T δ = 0, a frictionless slide that throws away the tangential traction the start
carries (a start that already solves the problem — a mortar pair re-coupled at its previous
solution — would be moved back to where a cold start begins).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .linear import mumps_ksp

if TYPE_CHECKING:
    from .newton import Complementarity

#: the relative residual of the predictor's CG + GAMG solve (``krylov``)
KRYLOV_RTOL = 1e-8
#: the active set of the linearized problem is updated this many times at most (primal–dual
#: active set steps on the tangent at x, one linear solve each; 0: the held set of x alone)
ACTIVE_SET_ROUNDS = 8


def tangent_predictor(cp: Complementarity, x: PETSc.Vec, krylov: bool = False) -> bool:
    """x += δ of the module doc when x + δ is admissible (True), else x unchanged (False).
    The problem's Dirichlet conditions carry the step's values; the NCP scaling ``cp.c``
    must be set (collective).  ``krylov``: solve by CG + GAMG (rigid-body near-nullspace,
    relative residual :data:`KRYLOV_RTOL`) instead of MUMPS LU — where the Newton steps are
    iterative too (:mod:`.krylov_curvature`)."""
    p = cp.p
    a, b, r = cp.pair(x)  # r = R_k(x); Dirichlet rows x_i − g_i
    active = cp.active_set(a, b)
    dirichlet = np.zeros(x.getLocalSize(), dtype=bool)
    dirichlet[p.dirichlet_rows()] = True
    K = p.full_tangent(x)
    tdim = p.V.mesh.topology.dim
    delta, trial, lin = x.duplicate(), x.duplicate(), x.duplicate()
    delta.set(0.0)
    comm = x.getComm().tompi4py()
    try:
        for k in range(1 + ACTIVE_SET_ROUNDS):
            _solve(K, r, x, delta, dirichlet, cp, active, krylov, p.near_nullspace, tdim)
            if k == ACTIVE_SET_ROUNDS:
                break
            # the linearized problem's NCP pair at x + δ: gap and force R(x) + K_T δ
            x.copy(trial)
            trial.axpy(1.0, delta)
            K.mult(delta, lin)
            lin.array_w[:] += r
            u = trial.array_r[cp.dofs]
            a_lin = cp.sign * (cp.g - u)
            b_lin = -cp.sign * cp.c * lin.array_r[cp.dofs] / cp.w
            new = cp.active_set(a_lin, b_lin)
            if not comm.allreduce(bool(np.any(new != active)), op=MPI.LOR):
                break
            active = new
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
        for obj in (K, delta, trial, lin):
            obj.destroy()


def _solve(
    K: PETSc.Mat,
    r: np.ndarray,
    x: PETSc.Vec,
    delta: PETSc.Vec,
    dirichlet: np.ndarray,
    cp: Complementarity,
    active: np.ndarray,
    krylov: bool,
    near_nullspace: PETSc.NullSpace | None,
    tdim: int,
) -> None:
    """δ of the linearized problem with the constrained rows of ``active`` held on their
    bounds (module doc): K_T's copy with those rows and the Dirichlet rows eliminated,
    one MUMPS LU or CG + GAMG solve (``krylov``; from the last δ).  With friction the
    tangential unknowns of the held nodes are held too, unchanged."""
    fixed = dirichlet.copy()
    values = np.where(dirichlet, -r, 0.0)
    rows = cp.dofs[active]
    values[rows] = cp.g[active] - x.array_r[rows]
    fixed[rows] = True
    friction = cp.p.friction
    if friction is not None:  # the held nodes stick (module doc): δ_t = 0
        fixed[friction.tangent[active]] = True
    delta.array_w[fixed] = values[fixed]
    rhs = x.duplicate()
    rhs.array_w[:] = -r
    A = K.duplicate(copy=True)
    lo = A.getOwnershipRange()[0]
    rows_global = (np.flatnonzero(fixed) + lo).astype(PETSc.IntType)
    A.zeroRowsColumns(rows_global, 1.0, delta, rhs)  # type: ignore[arg-type]
    try:
        if krylov:
            from .krylov_curvature import GamgSolver

            with GamgSolver(A, near_nullspace, tdim, "contact_predictor_", KRYLOV_RTOL) as gs:
                gs.ksp.setInitialGuessNonzero(True)  # δ holds the fixed rows' values
                gs.ksp.solve(rhs, delta)
        else:
            ksp = mumps_ksp(A)
            try:
                ksp.solve(rhs, delta)
            finally:
                ksp.destroy()
    finally:
        A.destroy()
        rhs.destroy()
