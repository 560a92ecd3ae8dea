"""PETSc's variational-inequality solvers as baselines (docs/theory.md §4).

``vinewtonrsls`` (reduced-space active set) and ``vinewtonssls`` (semismooth, FB) solve
the same discrete problem as the bound-constrained VI  l ≤ x ≤ u_max,  F(x) = K x − b,
with ``PETSc.INFINITY`` / ``PETSc.NINFINITY`` where a component is unbounded (large
finite stand-ins make the FB merit cancel catastrophically).  They keep PETSc's own
linear algebra: the Jacobian is K.
"""

from __future__ import annotations

from petsc4py import PETSc

from ..base.timing import Timer
from .linear import attach_near_nullspace
from .problem import DiscreteProblem

METHODS = ("vinewtonrsls", "vinewtonssls")


def setup_vi(
    snes: PETSc.SNES, problem: DiscreteProblem, method: str, timers: dict, state: dict
) -> PETSc.Mat:
    """Make ``snes`` PETSc's VI solver ``method`` on F(x) = K x − b with the constraint
    set's bounds; returns the Jacobian matrix."""

    def residual(snes, x, f):
        with Timer(timers, "assembly"):
            problem.residual(x, f)

    def jacobian(snes, x, J_, P):
        # vinewtonssls scales the Jacobian in place: hand it a fresh copy of K each time
        with Timer(timers, "assembly"):
            problem.linearize(x)
            same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
            problem.K.copy(P, structure=same)  # type: ignore[arg-type]
        state["t_jac"] = Timer(timers, "solve").start()  # stopped after the linear solve

    snes.setType(method)
    snes.setFunction(residual, problem.b.duplicate())
    J = problem.K.duplicate(copy=True)
    attach_near_nullspace(problem, J)
    snes.setJacobian(jacobian, J)
    lower, upper = problem.b.duplicate(), problem.b.duplicate()
    lower.set(PETSc.NINFINITY)
    upper.set(PETSc.INFINITY)
    con = problem.constraint
    (upper if con.sign > 0 else lower).array_w[con.dofs] = con.g
    snes.setVariableBounds(lower, upper)
    return J
