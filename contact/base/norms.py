"""The Euclidean norm of a PETSc vector as a float.

``PETSc.Vec.norm()`` returns one float for every norm type but ``NORM_1_AND_2`` (a pair);
petsc4py's stubs declare the union for every call, so the solvers ask through
:func:`norm2`, whose type says what the default norm returns."""

from __future__ import annotations

from petsc4py import PETSc


def norm2(v: PETSc.Vec) -> float:
    """‖v‖₂ over all ranks (collective)."""
    return v.norm()  # type: ignore[return-value]  # NORM_2, the default: one float


def norm_inf(v: PETSc.Vec) -> float:
    """‖v‖_∞ over all ranks (collective)."""
    return v.norm(PETSc.NormType.INFINITY)  # type: ignore[arg-type,return-value]


def norm1(v: PETSc.Vec) -> float:
    """‖v‖₁ over all ranks (collective)."""
    return v.norm(PETSc.NormType.NORM_1)  # type: ignore[arg-type,return-value]
